"""One error hierarchy for the whole tool, mapped to documented exit codes.

Every failure a user can meet is one of these. Each carries the words a
technician needs (what was asked, of which target, what came back) and, where
there is one, the raw code from the wire. The CLI's single handler prints
``akdctl: error: <message>`` and exits with ``exit_code``; only ``--debug``
shows a traceback.

Exit codes (README "Exit codes" lists the same table; a test keeps them equal):

====  ==========================================================================
0     success
1     the drive refused: negative PROFIdrive response, SDO abort, record-layer
      error, CIP error status, drive fault
2     usage or input error: bad argument, unknown PNU/object, bad value, bad
      target, bad config or recipe file
3     communication: no answer, timeout, malformed or inconsistent reply,
      link down
4     safety refusal: no consent, a limit exceeded, the drive cannot obey safely
5     check failed: a value read back or expected differs (verify, recipes)
130   interrupted (Ctrl-C; SIGTERM 143, SIGHUP 129: 128 + the signal); motion was stopped first
====  ==========================================================================
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_DRIVE = 1
EXIT_USAGE = 2
EXIT_COMM = 3
EXIT_SAFETY = 4
EXIT_CHECK = 5
EXIT_INTERRUPTED = 130

EXIT_CODES: dict[int, str] = {
    EXIT_OK: "success",
    EXIT_DRIVE: "the drive refused (negative PROFIdrive response, SDO abort, record error, drive fault)",
    EXIT_USAGE: "usage or input error (arguments, values, target, config or recipe file)",
    EXIT_COMM: "communication error (no answer, timeout, malformed reply)",
    EXIT_SAFETY: "safety refusal (no consent, limit exceeded, drive cannot obey safely)",
    EXIT_CHECK: "check failed (read-back or expected value differs)",
    EXIT_INTERRUPTED: "interrupted by Ctrl-C (motion stopped first)",
}


class AkdError(Exception):
    """Base of every error akdctl reports to a user.

    ``message`` is one line in words. ``target`` names the drive it concerns,
    ``code`` is the raw code from the wire (abort code, PROFIdrive error value,
    PNIO status), ``details`` is a JSON-friendly dict for ``--json`` output.
    """

    exit_code = EXIT_DRIVE
    kind = "error"
    #: True when the command already printed its result (--json included);
    #: the handler then only writes the one-line message to stderr.
    reported = False

    def __init__(
        self,
        message: str,
        *,
        target: str | None = None,
        code: int | None = None,
        details: dict[str, object] | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.target = target
        self.code = code
        self.details = dict(details or {})

    def with_target(self, target: str) -> "AkdError":
        """Attach the target name if the raiser did not know it."""
        if self.target is None:
            self.target = target
        return self

    def to_json(self) -> dict[str, object]:
        data: dict[str, object] = {"kind": self.kind, "message": self.message, "exit_code": self.exit_code}
        if self.target is not None:
            data["target"] = self.target
        if self.code is not None:
            data["code"] = self.code
        if self.details:
            data["details"] = self.details
        return data

    def __str__(self) -> str:
        return self.message


class UsageError(AkdError):
    """Bad input from the user: arguments, values, files, target strings."""

    exit_code = EXIT_USAGE
    kind = "usage"


class CommError(AkdError):
    """The link failed: nothing came back in time, or what came back is not valid."""

    exit_code = EXIT_COMM
    kind = "communication"


class NoAnswer(CommError):
    """No reply within the timeout (a silent, vanished or unplugged drive)."""

    kind = "timeout"


class UnknownOutcome(CommError):
    """A write whose reply never came and whose effect could not be confirmed: the drive may or may not
    have applied it. Never repeated blindly (a repeat could apply it twice); the user checks and decides."""

    kind = "unknown-outcome"


class MalformedReply(CommError):
    """A reply arrived but does not decode or does not match the request."""

    kind = "malformed-reply"


class DriveError(AkdError):
    """The drive answered, and refused."""

    exit_code = EXIT_DRIVE
    kind = "drive"


class ParameterRefused(DriveError):
    """A negative PROFIdrive parameter response (format 0x44 error value)."""

    kind = "profidrive-error"


class SdoAborted(DriveError):
    """An SDO abort from the drive (CiA 301 / ETG.1000.6 abort code)."""

    kind = "sdo-abort"


class CipRefused(DriveError):
    """A CIP error reply (general status, with additional status) from an EtherNet/IP target."""

    kind = "cip-status"


class RecordError(DriveError):
    """A PROFINET record-layer refusal (PNIOStatus error)."""

    kind = "record-error"


class DriveFault(DriveError):
    """The drive reports a fault that prevents or ended the operation."""

    kind = "drive-fault"


class SafetyRefusal(AkdError):
    """akdctl will not do this: no consent, a limit, or the drive cannot obey safely."""

    exit_code = EXIT_SAFETY
    kind = "safety"


class CheckFailed(AkdError):
    """A verification failed: a value read back or expected is not what it should be."""

    exit_code = EXIT_CHECK
    kind = "check-failed"


class Interrupted(AkdError):
    """The user pressed Ctrl-C; any motion was stopped before this is raised."""

    exit_code = EXIT_INTERRUPTED
    kind = "interrupted"


class InternalError(AkdError):
    """A bug in akdctl (an exception no rule above expected): one line, exit 70, a traceback with ``--debug``."""

    exit_code = 70
    kind = "internal"


class CommandRefused(DriveError):
    """An ``Error:`` reply of the AKD's ASCII command channel (akd://): the drive's own words (issue 24)."""

    kind = "akd-error"


class ModbusRefused(DriveError):
    """A Modbus exception response (function code + 0x80, exception code) from an mb:// target (issue 24)."""

    kind = "modbus-exception"


class TriggerTimeout(CommError):
    """A scope's trigger did not fire, or the drive's recorder did not finish, within ``--timeout`` (exit 3)."""

    kind = "trigger-timeout"
