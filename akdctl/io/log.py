"""The package's logger, ``logging`` imported on first use.

Why: ``logging`` (and ``traceback`` with it) costs a cold start about 2 ms, and a command that goes well logs
nothing; the SDO client and server log only what they ignore or retry. ``log.debug(...)`` and friends behave as
``logging.getLogger("akdctl")``'s.
"""

from __future__ import annotations

from typing import Any


class _Logger:
    def __getattr__(self, name: str) -> Any:
        import logging

        return getattr(logging.getLogger("akdctl"), name)


log: Any = _Logger()
