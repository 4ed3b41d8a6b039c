"""What the ``ecat`` commands share: the user's files read and written bounded, and numbers as typed (a plan's
consent and dry run are :mod:`akdctl.cli.consent`'s, as for every command).

Why a module of its own: ``ecat`` (SII, registers, alias), ``ecat foe`` and ``ecat pdo`` are split by job
(cli/ecat.py, cli/ecat_foe.py, cli/ecat_pdo.py) and must phrase these the same way.
"""

from __future__ import annotations


from akdctl.errors import UsageError


def read_user_file(path: str, limit: int) -> bytes:
    """A file from the user, bounded; a one-line UsageError for anything but a readable regular file."""
    from akdctl.io.safe_read import FileRefused, read_bounded

    try:
        return read_bounded(path, limit)
    except FileRefused as exc:
        raise UsageError(f"{path}: {exc}") from None
    except OSError as exc:
        raise UsageError(f"{path}: cannot read it ({exc.strerror or exc})") from None


def write_user_file(path: str, data: bytes) -> None:
    from pathlib import Path

    from akdctl.io.atomic import write_user_file

    try:
        write_user_file(Path(path), data)
    except OSError as exc:
        raise UsageError(f"{path}: cannot write it ({exc.strerror or exc})") from None


def parse_int(text: str, what: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise UsageError(f"{what} {text!r} is not a number (decimal or 0x hex)") from None
