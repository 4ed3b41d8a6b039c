"""The PDO source: one sample per EtherCAT bus cycle from the mapped TxPDO, with this host as the master.

Why a separate source: the AKD refreshes its TxPDO inputs every cycle (FBUS.SAMPLEPERIOD 250 us .. 4 ms), so a
master gets position, velocity, following error and torque at the bus rate with no request per sample
(foe-alias-recorder.md §C2); only PDO-mappable objects can be recorded, and the master must keep writing outputs
each cycle (SAFE-OP/OP) to get fresh inputs [I]. Cyclic process data on ``ecat://`` is another engineer's work
(branch wip/ecat); until a Connection offers it, the CLI refuses ``--source pdo`` in one line (exit 2) rather than
pretend with polled values.

What is here is the decoding, against a small interface (:class:`CyclicInputs`): the TxPDO image of each cycle and
the mapped entries (catalog/objects.py :class:`~akdctl.catalog.objects.PdoEntry`) turn into one row per cycle, the
time axis being the cycle count times the cycle time (the bus clock, not the host's).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

from akdctl.drive.scope_model import Channel, Recording
from akdctl.drive.scope_trigger import Trigger
from akdctl.errors import AkdError, Interrupted, TriggerTimeout, UsageError


class CyclicInputs(Protocol):
    """What a cyclic EtherCAT master offers the scope: its cycle time and, per cycle, the slave's TxPDO bytes."""

    cycle_s: float

    def mapped_inputs(self) -> Sequence[Any]:
        """The TxPDO entries in image order (PdoEntry: index, subindex, bits)."""
        ...

    def next_inputs(self, timeout: float) -> bytes:
        """The input image of the next cycle (blocks at most ``timeout``; NoAnswer when the cycle stops)."""
        ...


def refuse_without_cyclic(conn: Any) -> None:
    """``--source pdo`` needs an ``ecat://`` target whose master runs cyclic process data."""
    if conn.target.scheme != "ecat":
        raise UsageError(f"--source pdo needs an EtherCAT master target (ecat://IFNAME); {conn.target.display} "
                         "is not one: use --source poll")
    raise UsageError("--source pdo needs cyclic process data on ecat://, which this build does not offer yet "
                     "(needs ecat:// cyclic master); use --source poll")


def columns_for(entries: Sequence[Any], names: Sequence[str]) -> list[tuple[int, Any, Channel]]:
    """(byte offset, entry, channel) of each requested signal (``0xINDEX[:SUB]``) in the TxPDO image;
    UsageError naming what is mapped when one is not."""
    from akdctl.catalog.objects import lookup

    offsets: dict[tuple[int, int], tuple[int, Any]] = {}
    bit = 0
    for entry in entries:
        offsets[(entry.index, entry.subindex)] = (bit // 8, entry)
        bit += entry.bits
    out = []
    for name in names:
        text = name.strip().lower().removeprefix("0x")
        index_text, _, sub_text = text.partition(":")
        try:
            key = (int(index_text, 16), int(sub_text or "0", 0))
        except ValueError:
            raise UsageError(f"signal {name!r}: the pdo source records mapped objects by address (0x606C:0)") from None
        if key not in offsets:
            mapped = ", ".join(f"0x{i:04X}:{s}" for i, s in offsets) or "nothing"
            raise UsageError(f"signal {name}: 0x{key[0]:04X}:{key[1]} is not in the mapped TxPDO ({mapped})")
        offset, entry = offsets[key]
        catalogued = lookup(*key)
        out.append((offset, entry, Channel(name, "", f"TxPDO 0x{key[0]:04X}:{key[1]}"
                                           + (f" ({catalogued.name})" if catalogued else ""))))
    return out


def record(inputs: CyclicInputs, names: Sequence[str], recording_target: str, *, cycles: int, trigger: Trigger,
           trigger_slot: int | None, stopped: Callable[[], bool], timeout_s: float) -> tuple[Recording, AkdError | None]:
    """``cycles`` rows after the trigger (immediate, or a signal/bit edge on a recorded column)."""
    from akdctl.catalog.objects import lookup
    from akdctl.drive.values import decode

    columns = columns_for(inputs.mapped_inputs(), names)
    recording = Recording(recording_target, "pdo", [c for _, _, c in columns], trigger=trigger.text,
                          rate_requested=1.0 / inputs.cycle_s)
    entries = [lookup(e.index, e.subindex) for _, e, _ in columns]
    types = [found.short_type if found is not None else f"i{e.bits}" for found, (_, e, _) in zip(entries, columns)]
    previous: float | None = None
    waited = 0
    count = 0
    try:
        while len(recording) < cycles:
            if stopped():
                raise Interrupted("interrupted while recording")
            image = inputs.next_inputs(timeout_s)
            row = [float(decode(t, image[o:o + e.bits // 8])) for (o, e, _), t in zip(columns, types)]
            count += 1
            if recording.trigger_index is None:
                value = row[trigger_slot] if trigger_slot is not None else 0.0
                if not trigger.fires(previous, value):
                    previous = value
                    waited += 1
                    if waited * inputs.cycle_s > timeout_s:
                        raise TriggerTimeout(f"the trigger ({trigger.text}) did not fire within {timeout_s:g} s")
                    continue
                recording.trigger_index = 0
            recording.add((count - 1 - waited) * inputs.cycle_s, row)
    except AkdError as exc:
        recording.mark_partial(f"stopped after {len(recording)} cycles: {exc.message}")
        return recording, exc
    return recording, None
