"""Where akdctl keeps state between invocations: the simulated drives' files and the axes' owner locks.

Why here and not in the simulator: a client talking to a real drive takes the owner lock in this
directory too, and must not import the simulator to learn where it is (issue 22, item 9).
"""

from __future__ import annotations

import os
from pathlib import Path


def state_dir() -> Path:
    """``$AKDCTL_STATE_DIR``, else ``$XDG_STATE_HOME/akdctl`` (``~/.local/state/akdctl``)."""
    env = os.environ.get("AKDCTL_STATE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(base) / "akdctl"
