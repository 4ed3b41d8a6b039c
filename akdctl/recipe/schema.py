"""What a recipe step may say, and the check of every step before anything is written.

Why a separate validator: "nothing is written before the whole recipe validated".
Each step is checked against the catalogues (PNUs, objects, PDOs, signals,
telegrams), the data types and ranges, and the config profile's motion limits,
without touching the drive; every problem is reported with file, line, step and
what was expected. The result is a list of :class:`PlannedStep` whose
``params`` hold already-resolved values, so the runner never re-parses text.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from akdctl.errors import AkdError, UsageError
from akdctl.recipe.loader import RawRecipe, RawStep, display_path, inside

if TYPE_CHECKING:
    from akdctl.connection import Connection
    from akdctl.profiles.vocabulary import Channel

COMMON = {"action": str, "name": str}
NUMBER = (int, float)

# action -> {key: accepted types}; required keys listed separately. Documented in docs/commissioning.md.
ACTIONS: dict[str, dict[str, Any]] = {
    "set": {"pnu": (str, int), "object": str, "value": (int, float, str, list), "pnus": dict, "objects": dict,
            "verify": bool},
    "expect": {"pnu": (str, int), "object": str, "value": (int, float, str, list), "min": NUMBER, "max": NUMBER,
               "mask": int, "tolerance": NUMBER},
    "map": {"rx": (list, str), "tx": (list, str), "define": (list, str), "opmode": (int, str), "cycle_time": str,
            "setpoint": (list, str), "actual": (list, str)},
    "telegram": {"telegram": int},
    "enable": {"timeout": NUMBER},
    "disable": {"timeout": NUMBER},
    "stop": {"quick": bool},
    "acknowledge": {},
    "home": {"mode": int, "timeout": NUMBER},
    "move": {"target": NUMBER, "unit": str, "relative": bool, "velocity": NUMBER, "accel": NUMBER, "decel": NUMBER,
             "timeout": NUMBER},
    "wait": {"seconds": NUMBER, "pnu": (str, int), "object": str, "value": (int, float, str, list), "min": NUMBER,
             "max": NUMBER, "mask": int, "tolerance": NUMBER, "timeout": NUMBER},
    "check_faults": {"allow_warnings": bool},
    "save": {},
    "backup": {"file": str, "source": str, "groups": list, "only": list},
    "restore": {"file": str, "force": bool},
    "param": {"set": dict, "raw": bool},   # AKD parameters by name (issue 24, drive/names.py)
    "scope": {"signals": list, "for": NUMBER, "samples": int, "rate": NUMBER, "source": str, "trigger": str,
              "pretrigger": NUMBER, "timeout": NUMBER, "jog": NUMBER, "jog_for": NUMBER, "accel": NUMBER,
              "csv": str, "svg": str, "json": str, "max_following_error": NUMBER, "max_settle_time": NUMBER,
              "settle_band": NUMBER, "ring": int},
}
REQUIRED = {"telegram": ("telegram",), "move": ("target",), "backup": ("file",), "restore": ("file",),
            "scope": ("signals",), "param": ("set",)}
MOTION = {"enable", "home", "move"}
MAX_WAIT_S = 3600.0


@dataclass
class PlannedStep:
    """A validated step: what the runner does and how the plan/report names it."""

    number: int
    action: str
    name: str
    file: str
    line: int | None
    params: dict[str, Any]
    plan: str
    motion: bool = False
    gated: list[Any] = field(default_factory=list)  # gate.Gated addresses a set step writes (akdctl.drive.gate)

    @property
    def where(self) -> str:
        return f"{self.file}:{self.line}" if self.line is not None else self.file

    def to_json(self) -> dict[str, Any]:
        return {"step": self.number, "action": self.action, "name": self.name, "file": self.file, "line": self.line,
                "plan": self.plan, "motion": self.motion}


@dataclass
class Context:
    """What validation may consult: the recipe's folder, the include/restore policy, the connection
    (its config profile — limits, units — and target: the axis profile and the channels it offers;
    nothing is read from the drive)."""

    folder: Path
    allow_outside: bool = False
    conn: "Connection | None" = None


class StepProblem(Exception):
    """One validation failure of a step; ``key`` points the line finder at the offending key."""

    def __init__(self, message: str, key: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.key = key


# ---------------------------------------------------------------------------- helpers
def _number(data: dict[str, Any], key: str, *, positive: bool = False, maximum: float | None = None,
            default: float | None = None) -> float | None:
    if key not in data:
        return default
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, NUMBER) or not math.isfinite(float(value)):
        raise StepProblem(f"'{key}' must be a number, got {value!r}", key)
    if positive and value <= 0:
        raise StepProblem(f"'{key}' must be greater than 0, got {value!r}", key)
    if maximum is not None and value > maximum:
        raise StepProblem(f"'{key}' must be at most {maximum:g}, got {value!r}", key)
    return float(value)


def _pnu_target(text: Any, *, write: bool) -> Any:
    from akdctl.drive.params import parse_pnu_spec

    try:
        spec = parse_pnu_spec(str(text))  # the one resolver: numbers, PNU[SUB], names ("STW1", "Operating mode")
    except UsageError as exc:
        raise StepProblem(exc.message + " — expected a PNU of the catalogue (see 'akdctl pnu list')", "pnu") from None
    if spec.info is None:
        raise StepProblem(f"unknown PNU {spec.pnu}: not in the AKD catalogue (see 'akdctl pnu list')", "pnu")
    if write:
        if spec.pnu == 1:
            raise StepProblem("STW1 (PNU 1) is never written by a set step; use enable/disable/stop/acknowledge "
                              "steps, which run the state machine safely", "pnu")
        if not spec.info.writable:
            raise StepProblem(f"PNU {spec.pnu} ({spec.info.name}) is read-only", "pnu")
    return spec


def _pnu_values(spec: Any, value: Any, key: str = "value", ranged: bool = True) -> list[int]:
    """The values of a PNU step, checked by the commands' one rule (drive/params.fit_values)."""
    from akdctl.drive.params import fit_values

    info = spec.info
    values = value if isinstance(value, list) else [value]
    for v in values:
        if isinstance(v, bool) or not isinstance(v, int):
            raise StepProblem(f"PNU {spec.label} ({info.name}) takes integers ({info.type}); got {v!r}", key)
    try:
        fit_values(spec, values, ranged=ranged)
    except UsageError as exc:
        raise StepProblem(exc.message, key) from None
    return values


def _object_target(text: Any, *, write: bool) -> Any:
    from akdctl.catalog.objects import lookup, subentries
    from akdctl.drive.objects import parse_address

    if not isinstance(text, str):
        raise StepProblem(f"'object' must be text such as \"0x6060:0\", got {text!r}", "object")
    try:
        address = parse_address(text)
    except UsageError as exc:
        raise StepProblem(exc.message, "object") from None
    entry = lookup(address.index, address.subindex)
    if entry is None:
        what = "subindex" if subentries(address.index) else "object"
        raise StepProblem(f"unknown {what} {address.label}: not in the AKD object dictionary (see 'akdctl sdo')",
                          "object")
    if write:
        if address.index == 0x6040:
            raise StepProblem("the controlword (0x6040) is never written by a set step; use enable/disable/stop/"
                              "acknowledge steps", "object")
        if not entry.writable:
            raise StepProblem(f"object {address.label} ({entry.name}) is read-only", "object")
    elif not entry.readable:
        raise StepProblem(f"object {address.label} ({entry.name}) is write-only; it cannot be read", "object")
    return entry


def _object_value(entry: Any, value: Any, key: str = "value") -> Any:
    from akdctl.drive.snapshot import encode_object

    kind = entry.short_type
    if kind.startswith(("u", "i")) and (isinstance(value, bool) or not isinstance(value, int)):
        raise StepProblem(f"object 0x{entry.index:04X}:{entry.subindex} ({entry.name}) takes an integer ({kind}); "
                          f"got {value!r}", key)
    try:
        encode_object(entry, value)
    except UsageError as exc:
        message = exc.message.split(": bad value ", 1)[-1]
        raise StepProblem(f"object 0x{entry.index:04X}:{entry.subindex} ({entry.name}): value {message}; "
                          f"expected type {kind}", key) from None
    return value


def _targets(data: dict[str, Any], *, write: bool, multi: bool) -> list[dict[str, Any]]:
    """The quantities a set/expect/wait step addresses: [{'kind','spec'|'entry','label','value'}]."""
    forms = [k for k in ("pnu", "object", "pnus", "objects") if k in data and (multi or k in ("pnu", "object"))]
    if len(forms) != 1:
        allowed = "'pnu' or 'object'" + (" (or a 'pnus'/'objects' table)" if multi else "")
        if not forms:
            raise StepProblem(f"missing key: give {allowed}")
        raise StepProblem(f"give only one of {allowed}, not {' and '.join(forms)}", forms[1])
    form = forms[0]
    out = []
    if form in ("pnu", "object"):
        if write and "value" not in data:
            raise StepProblem("missing key 'value' (the value to write)")
        pairs = [(data[form], data.get("value"))]
    else:
        table = data[form]
        if not table:
            raise StepProblem(f"'{form}' is empty", form)
        if "value" in data:
            raise StepProblem(f"'value' does not go with a '{form}' table; put the values into the table", "value")
        pairs = list(table.items())
    for target, value in pairs:
        if form in ("pnu", "pnus"):
            spec = _pnu_target(target, write=write)
            ranged = ".." in str(target)  # as pnu set reads PNU[FROM..TO]=...: only a range fixes the count
            values = _pnu_values(spec, value, "value" if form == "pnu" else form, ranged) \
                if value is not None and write else None
            if values is not None:
                from akdctl.drive.params import fit_values

                spec = fit_values(spec, values, ranged=ranged)
            out.append({"kind": "pnu", "spec": spec, "label": f"PNU {spec.label} ({spec.info.name})", "ranged": ranged,
                        "value": values if values is None or isinstance(value, list) else values[0]})
        else:
            entry = _object_target(target, write=write)
            if value is not None and write:
                _object_value(entry, value, "value" if form == "object" else form)
            out.append({"kind": "object", "entry": entry,
                        "label": f"0x{entry.index:04X}:{entry.subindex} ({entry.name})", "value": value})
    return out


def _set_request(targets: list[dict[str, Any]], verify: bool) -> Any:
    """The set step's request for the one raw-write operation (drive/raw_write.py), as ``pnu set``/``sdo write``
    build it: PNU values as integers, object values as their type decodes the bytes sent."""
    from akdctl.drive import raw_write
    from akdctl.drive.values import decode, encode_object

    out = []
    for t in targets:
        if t["kind"] == "pnu":
            out.append(raw_write.pnu_target(t["spec"], t["value"] if isinstance(t["value"], list) else [t["value"]]))
        else:
            entry = t["entry"]
            data = encode_object(entry, t["value"])
            out.append(raw_write.object_target(entry.index, entry.subindex, entry.short_type,
                                               decode(entry.short_type, data), data, entry.name))
    return raw_write.SetRequest(out, verify)


def _comparison(data: dict[str, Any], target: dict[str, Any]) -> dict[str, Any]:
    """expect/wait: value (optionally under mask), min/max, tolerance."""
    has_value, has_range = "value" in data, "min" in data or "max" in data
    if not has_value and not has_range:
        raise StepProblem("missing key: give 'value' (optionally with 'mask' or 'tolerance') or 'min'/'max'")
    if has_value and has_range:
        raise StepProblem("give either 'value' or 'min'/'max', not both", "min")
    comparison: dict[str, Any] = {}
    if has_value:
        value = data["value"]
        if target["kind"] == "pnu":
            values = _pnu_values(target["spec"], value, ranged=target.get("ranged", True))
            comparison["value"] = values if isinstance(value, list) else values[0]
        else:
            comparison["value"] = _object_value(target["entry"], value)
    for key in ("min", "max", "tolerance"):
        if key in data:
            comparison[key] = _number(data, key)
    if "mask" in data:
        if not has_value or isinstance(data["value"], (list, float, str)):
            raise StepProblem("'mask' needs an integer 'value' to compare the masked bits with", "mask")
        comparison["mask"] = data["mask"]
    if "min" in comparison and "max" in comparison and comparison["min"] > comparison["max"]:
        raise StepProblem(f"'min' {comparison['min']:g} is greater than 'max' {comparison['max']:g}", "min")
    return comparison


def _describe_comparison(label: str, comparison: dict[str, Any]) -> str:
    if "value" in comparison:
        text = f"{label} == {comparison['value']}"
        if "mask" in comparison:
            text = f"{label} & 0x{comparison['mask']:X} == {comparison['value']}"
        if "tolerance" in comparison:
            text += f" ± {comparison['tolerance']:g}"
        return text
    parts = []
    if "min" in comparison:
        parts.append(f"{comparison['min']:g} <=")
    parts.append(label)
    if "max" in comparison:
        parts.append(f"<= {comparison['max']:g}")
    return " ".join(parts)


def _string_list(data: dict[str, Any], key: str) -> list[str]:
    value = data.get(key, [])
    if isinstance(value, str):
        value = [value]
    if not all(isinstance(v, (str, int)) and not isinstance(v, bool) for v in value):
        raise StepProblem(f"'{key}' must be a list of strings such as \"0x1701\"", key)
    return [str(v) for v in value]


def _file_in_folder(data: dict[str, Any], ctx: Context, *, must_exist: bool) -> Path:
    text = data["file"]
    path = Path(text)
    full = ctx.folder / path
    if must_exist:
        if not ctx.allow_outside and (path.is_absolute() or not inside(full, ctx.folder)):
            raise StepProblem(f"{text!r} is outside the recipe's folder; recipes may only read files from their own "
                              "folder (use --allow-outside-includes to permit it)", "file")
        if not full.is_file():
            raise StepProblem(f"{text!r}: no such file next to the recipe", "file")
        return full
    return path


# ---------------------------------------------------------------------------- per action
def _check(action: str, data: dict[str, Any], ctx: Context) -> tuple[dict[str, Any], str]:
    if action == "param":
        return _check_param(data)
    if action == "set":
        targets = _targets(data, write=True, multi=True)
        verify = data.get("verify", True)
        plan = "write " + ", ".join(f"{t['label']} = {t['value']}" for t in targets) + (" and read back" if verify else "")
        return {"targets": targets, "verify": verify, "request": _set_request(targets, verify)}, plan
    if action in ("expect", "wait") and (action == "expect" or "seconds" not in data):
        targets = _targets(data, write=False, multi=False)
        comparison = _comparison(data, targets[0])
        params = {"target": targets[0], "comparison": comparison}
        text = _describe_comparison(targets[0]["label"], comparison)
        if action == "wait":
            params["timeout"] = _number(data, "timeout", positive=True, maximum=MAX_WAIT_S, default=10.0)
            return params, f"wait until {text} (at most {params['timeout']:g} s)"
        return params, f"check {text}"
    if action == "wait":
        for key in ("pnu", "object", "value", "min", "max", "mask", "tolerance", "timeout"):
            if key in data:
                raise StepProblem(f"'{key}' does not go with 'seconds' (a plain wait); remove one of them", key)
        seconds = _number(data, "seconds", positive=True, maximum=MAX_WAIT_S)
        return {"seconds": seconds}, f"wait {seconds:g} s"
    if action == "map":
        return _check_map(data)
    if action == "telegram":
        from akdctl.drive import telegram as dt

        number = data["telegram"]
        try:
            request = dt.select_request(number)  # the rule 'telegram set' applies
        except UsageError as exc:
            raise StepProblem(exc.message, "telegram") from None
        return {"telegram": number, "request": request}, f"select telegram {number} (PNU 922) and read it back"
    if action == "enable":
        timeout = _number(data, "timeout", positive=True, maximum=MAX_WAIT_S)
        return _motion(ctx, {"kind": "enable"}, {"timeout": timeout})
    if action == "disable":
        timeout = _number(data, "timeout", positive=True, maximum=MAX_WAIT_S)
        return {"timeout": timeout}, "disable the power stage (ramp to standstill first)"
    if action == "stop":
        quick = data.get("quick", False)
        return {"quick": quick}, "stop the axis" + (" (quick stop)" if quick else " (ramp)")
    if action == "acknowledge":
        return {}, "acknowledge faults"
    if action == "home":
        return _motion(ctx, {"kind": "home", "home_mode": data.get("mode"), "timeout_s": data.get("timeout")})
    if action == "move":
        return _motion(ctx, {"kind": "move", "target": data["target"], "unit": data.get("unit"),
                             "relative": data.get("relative", False), "velocity": data.get("velocity"),
                             "accel": data.get("accel"), "decel": data.get("decel"),
                             "timeout_s": data.get("timeout")})
    if action == "check_faults":
        allow = data.get("allow_warnings", True)
        return {"allow_warnings": allow}, "check that no fault" + ("" if allow else " or warning") + " is active"
    if action == "save":
        return {}, "save parameters to non-volatile memory (DRV.NVSAVE, 0x1010:1)"
    if action == "backup":
        from akdctl.drive import snapshot

        path = _file_in_folder(data, ctx, must_exist=False)
        if path.is_absolute() or ".." in path.parts:
            raise StepProblem(f"{data['file']!r}: a backup file is written below the output directory; give a "
                              "relative path without '..'", "file")
        if path.suffix.lower() not in (".toml", ".json"):
            raise StepProblem(f"{data['file']!r}: expected a .toml or .json file name", "file")
        source = data.get("source", "auto")
        if source not in snapshot.SOURCES:
            raise StepProblem(f"'source' {source!r}: expected one of {', '.join(snapshot.SOURCES)}", "source")
        groups = _string_list(data, "groups")
        only = _string_list(data, "only")
        try:
            snapshot.select_items(["pnu", "objects"], groups, only)
        except UsageError as exc:
            raise StepProblem(exc.message, "only" if only else "groups") from None
        return {"file": str(path), "source": source, "groups": groups, "only": only}, f"back up parameters to {path}"
    if action == "restore":
        from akdctl.drive import snapshot

        full = _file_in_folder(data, ctx, must_exist=True)
        try:
            snap = snapshot.load_file(full)
        except UsageError as exc:
            raise StepProblem(exc.message, "file") from None
        return {"file": str(full), "snapshot": snap, "force": data.get("force", False)}, \
            f"restore parameters from {data['file']} (write differences, verify)"
    if action == "scope":
        return _check_scope(data, ctx)
    raise StepProblem(f"unknown action {action!r}")  # pragma: no cover - filtered before


def _check_map(data: dict[str, Any]) -> tuple[dict[str, Any], str]:
    pdo_keys = [k for k in ("rx", "tx", "define", "opmode", "cycle_time") if k in data]
    tel_keys = [k for k in ("setpoint", "actual") if k in data]
    if pdo_keys and tel_keys:
        raise StepProblem("a map step maps either EtherCAT PDOs (rx/tx/define) or the PROFIdrive free telegram "
                          "(setpoint/actual), not both", tel_keys[0])
    if not pdo_keys and not tel_keys:
        raise StepProblem("missing key: give 'rx'/'tx' (EtherCAT PDOs, e.g. rx = [\"0x1701\"]) or "
                          "'setpoint'/'actual' (PROFIdrive telegram 0 signals)")
    if tel_keys:
        from akdctl.drive import telegram as dt

        lists = {}
        for key in ("setpoint", "actual"):
            if key in data:
                try:
                    lists[key] = dt.parse_signals(",".join(_string_list(data, key)))
                except UsageError as exc:
                    raise StepProblem(exc.message, key) from None
        problems = dt.validate_free_map(lists.get("setpoint", []), lists.get("actual", []))
        if problems:
            raise StepProblem("; ".join(problems), tel_keys[0])
        try:
            request = dt.map_request(lists.get("setpoint"), lists.get("actual"))
        except UsageError as exc:
            raise StepProblem(exc.message, tel_keys[0]) from None
        return {"telegram_map": lists, "request": request}, ("map the free telegram: " + "; ".join(
            f"{k} signals {', '.join(str(s) for s in v)}" for k, v in lists.items()))
    from akdctl.drive import pdo as dp

    try:
        opmode = data.get("opmode")
        plan = dp.build_plan(_string_list(data, "rx"), _string_list(data, "tx"), _string_list(data, "define"),
                             str(opmode) if opmode is not None else None, data.get("cycle_time"))
    except UsageError as exc:
        raise StepProblem(exc.message, pdo_keys[0]) from None
    problems = dp.validate(plan)
    if problems:
        raise StepProblem("; ".join(problems), pdo_keys[0])
    parts = [f"{d} {', '.join(f'0x{n:04X}' for n in plan.assign[d] or [])}" for d in ("rx", "tx")
             if plan.assign[d] is not None]
    return {"pdo": plan, "request": dp.map_request(plan)}, "map process data: " + ("; ".join(parts) or "mode/cycle only") + " (manual's sequence, verify)"


# Which recipe key a planner refusal points at (for FILE:LINE).
_PROBLEM_KEYS = (("velocity", "velocity"), ("deceleration", "decel"), ("acceleration", "accel"),
                 ("homing mode", "mode"), ("timeout", "timeout"), ("unit", "unit"), ("travel", "target"),
                 ("target", "target"))


def _motion(ctx: Context, fields: dict[str, Any], extra: dict[str, Any] | None = None) -> tuple[dict[str, Any], str]:
    """enable/home/move: the motion planner's drive-free stage (the same as the commands'), so a recipe
    step is refused exactly when the command line would be."""
    from akdctl.drive import motion_plan
    from akdctl.drive.axis.choice import axis_class

    request = motion_plan.MotionRequest(**fields)
    if ctx.conn is None:
        return {"request": request, **(extra or {})}, request.kind
    try:
        accepted = motion_plan.check_request(ctx.conn, request, axis_class(ctx.conn))
    except AkdError as exc:
        key = next((k for word, k in _PROBLEM_KEYS if word in exc.message), None)
        raise StepProblem(exc.message, key) from None
    text = accepted.what + ("" if request.kind == "enable" else ", wait until it ends")
    return {"request": request, **(extra or {})}, text


# ---------------------------------------------------------------------------- the whole recipe
def validate_step(raw: RawStep, ctx: Context) -> PlannedStep:
    data = raw.data
    action = data.get("action")
    shown = display_path(raw.file, ctx.folder)
    if action is None:
        raise StepProblem("missing key 'action': expected one of " + ", ".join(list(ACTIONS) + ["include"]))
    if not isinstance(action, str) or action not in ACTIONS:
        raise StepProblem(f"unknown action {action!r}: expected one of " + ", ".join(list(ACTIONS) + ["include"]),
                          "action")
    allowed = {**COMMON, **ACTIONS[action]}
    for key, value in data.items():
        if key not in allowed:
            raise StepProblem(f"unknown key {key!r} for a {action} step; allowed: "
                              + ", ".join(k for k in allowed if k != "action"), key)
        types = allowed[key]
        ok = isinstance(value, types) and not (isinstance(value, bool) and bool not in (
            types if isinstance(types, tuple) else (types,)))
        if not ok:
            names = " or ".join(_type_word(t) for t in (types if isinstance(types, tuple) else (types,)))
            raise StepProblem(f"'{key}' must be {names}, got {_type_word(type(value))} {value!r}", key)
    for key in REQUIRED.get(action, ()):
        if key not in data:
            raise StepProblem(f"missing key {key!r} for a {action} step")
    params, plan = _check(action, data, ctx)
    _check_channels(action, params, ctx)
    name = data.get("name") or plan
    step = PlannedStep(raw.number, action, name, shown, raw.line, params, plan,
                       motion=action in MOTION or bool(params.get("moves")),
                       gated=_gated(action, params))
    return step


def _needed_channels(action: str, params: dict[str, Any], ctx: Context) -> "set[Channel]":
    """The channels a step uses on the drive, known from the step and the target alone."""
    from akdctl.profiles.vocabulary import Channel

    if action in ("set", "expect", "wait"):
        targets = params.get("targets") or ([params["target"]] if "target" in params else [])
        return {Channel.PARAMETERS if t["kind"] == "pnu" else Channel.OBJECTS for t in targets}
    if action == "map":
        return {Channel.PARAMETERS if "telegram_map" in params else Channel.OBJECTS}
    if action == "telegram":
        return {Channel.PARAMETERS}
    if action in ("enable", "disable", "stop", "acknowledge", "home", "move"):
        return {ctx.conn.axis_profile.channel}
    return set()


def _check_channels(action: str, params: dict[str, Any], ctx: Context) -> None:
    """Each step's channel must exist on the selected target — checked before the first write, dry runs too."""
    if ctx.conn is None:
        return
    offered = ctx.conn.declared_channels
    if offered is None:
        return
    for channel in sorted(_needed_channels(action, params, ctx) - offered):
        offers = " and ".join(c.words for c in sorted(offered)) or "no channel"
        raise StepProblem(f"this step needs {channel.words}, which target {ctx.conn.target.display} does "
                          f"not offer (it has {offers})")


def _gated(action: str, params: dict[str, Any]) -> list[Any]:
    """The gated addresses a set/telegram/map step writes, as each operation classifies them (drive/raw_write,
    drive/telegram, drive/pdo ``gated``): the recipe may then need consent."""
    if action == "telegram" or (action == "map" and "telegram_map" in params):
        from akdctl.drive import telegram as dt

        return dt.gated(params["request"]) if params.get("request") is not None else []
    if action == "map":
        from akdctl.drive import pdo as dp

        return dp.gated(params["request"]) if params.get("request") is not None else []
    if action == "param":
        from akdctl.drive import names

        return [g for g in (names.classify(names.resolve(n)) for n, _ in params["assignments"]) if g is not None]
    if action != "set":
        return []
    from akdctl.drive import raw_write

    return raw_write.gated(params["request"])


def _type_word(t: type) -> str:
    return {int: "an integer", float: "a number", str: "text", bool: "true/false", list: "a list",
            dict: "a table"}.get(t, t.__name__)


def validate(recipe: RawRecipe, ctx: Context, structural: list[str]) -> list[PlannedStep]:
    """Every step checked; RecipeError with every problem (file:line: step n (action): what) if any."""
    from akdctl.recipe.loader import RecipeError

    problems = list(structural)
    planned: list[PlannedStep] = []
    for raw in recipe.steps:
        action = raw.data.get("action")
        label = f"step {raw.number}" + (f" ({action})" if isinstance(action, str) else "")
        try:
            planned.append(validate_step(raw, ctx))
        except StepProblem as exc:
            problems.append(f"{raw.where(exc.key, ctx.folder)}: {label}: {exc.message}")
        except AkdError as exc:
            problems.append(f"{raw.where(None, ctx.folder)}: {label}: {exc.message}")
    if problems:
        raise RecipeError(problems)
    return planned


def _check_param(data: dict[str, Any]) -> tuple[dict[str, Any], str]:
    """A ``param`` step: ``set = {"VL.KP" = 0.5, ...}`` checked offline by the rules ``param set`` uses (names,
    class, value, published range); reachability and the wire form are planned on the drive (drive/names.py)."""
    from akdctl.drive import names
    from akdctl.profiles.akd_values import format_value

    raw = bool(data.get("raw", False))
    assignments: list[tuple[str, str]] = []
    for name, value in dict(data["set"]).items():
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise StepProblem(f"set.{name}: a number or a text, got {value!r}", "set")
        try:
            row = names.resolve(str(name))
            text = format_value(row.kind, value) if isinstance(value, float) else str(value)
            names.check_value(row, text, raw)
        except AkdError as exc:
            raise StepProblem(exc.message, "set") from None
        assignments.append((row.name, text))
    if not assignments:
        raise StepProblem("'set' names no parameter", "set")
    return {"assignments": assignments, "raw": raw}, "param set " + " ".join(f"{n}={v}" for n, v in assignments)


def _check_scope(data: dict[str, Any], ctx: Context) -> tuple[dict[str, Any], str]:
    """A scope step: the request the command line would build (drive/scope.build_request: CLI-recipe parity),
    its drive-free checks, the bounds, and the motion planner's drive-free stage for a recorded jog."""
    from akdctl.drive import scope as op

    signals = data["signals"]
    if not signals or not all(isinstance(s, str) for s in signals):
        raise StepProblem("'signals' must be a non-empty list of signal names", "signals")
    for key in ("csv", "svg", "json"):
        if key in data:
            path = Path(data[key])
            if path.is_absolute() or ".." in path.parts:
                raise StepProblem(f"{data[key]!r}: a scope file is written below the output directory; give a "
                                  "relative path without '..'", key)
    try:
        request = op.build_request(signals, duration_s=data.get("for"), samples=data.get("samples"),
                                   rate_hz=data.get("rate"), source=data.get("source", "auto"),
                                   trigger=data.get("trigger"), pretrigger=float(data.get("pretrigger", 0.0)),
                                   timeout_s=float(data.get("timeout", op.DEFAULT_TIMEOUT_S)),
                                   jog_rpm=data.get("jog"), jog_s=data.get("jog_for"), accel=data.get("accel"),
                                   ring=data.get("ring"))
        op.check(request)
        bounds = op.Bounds(data.get("max_following_error"), data.get("max_settle_time"), data.get("settle_band"))
        bounds.check_request(request)
    except UsageError as exc:
        raise StepProblem(exc.message) from None
    text = f"record {', '.join(signals)}"
    if request.move is not None:
        _motion(ctx, {"kind": "jog", "velocity": request.move.velocity, "duration_s": request.move.duration_s,
                      "accel": request.move.accel})
        text += f" during a jog at {request.move.velocity:g} rpm for {request.move.duration_s:g} s"
    if bounds.any:
        text += " and check " + ", ".join(f"{k} <= {v:g}" for k, v in (("following error", bounds.max_following_error),
                                                                      ("settle time", bounds.max_settle_time))
                                         if v is not None)
    files = {key: data[key] for key in ("csv", "svg", "json") if key in data}
    return {"request": request, "bounds": bounds, "files": files, "moves": request.move is not None}, text
