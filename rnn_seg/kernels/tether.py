"""``python tether.py PARENT COMMAND...``: run ``COMMAND`` and end it, with everything it started,
when process ``PARENT`` ends (killed by any signal, SIGKILL included) or this process is
signalled.

``build`` starts the compiler through this script as the leader of a new session, so the
compiler (and its ``cc1plus``, ``as``, ``ld``) share this process's group: the parent's
death signal (``PR_SET_PDEATHSIG``, Linux) or a SIGTERM, SIGINT or SIGHUP sent here kills the
whole group. Python's ``preexec_fn`` could set the death signal without this script, but it is
unsafe in a process with threads (TensorFlow's); and the death signal set in the compiler itself
would end the driver only, not the compiler proper it waits for. Elsewhere than Linux a thread
polls for the parent instead. Standard library only: it runs as ``python -I -S``, before
anything of the project is importable.

Exit status: the command's, or 128 + the signal that ended it.
"""
from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import threading
import time

PR_SET_PDEATHSIG = 1
ENDING = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)


def _end_group(*_) -> None:
    """Kill this process's group: the command, what it started, and this process."""
    os.killpg(0, signal.SIGKILL)


def _watch(parent: int) -> None:
    """Where there is no death signal: end the group once ``parent`` is gone."""
    while os.getppid() == parent:
        time.sleep(0.5)
    _end_group()


def main(argv: list[str]) -> int:
    parent, command = int(argv[0]), argv[1:]
    if os.getpgrp() != os.getpid():               # never end the group of whoever started this
        os.setpgid(0, 0)
    for number in ENDING:
        signal.signal(number, _end_group)
    if not (sys.platform.startswith("linux")
            and ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM) == 0):
        threading.Thread(target=_watch, args=(parent,), daemon=True).start()
    if os.getppid() != parent:                    # the parent ended before the death signal was set
        _end_group()
    try:
        code = subprocess.call(command)
    except OSError as error:
        print(f"{command[0]}: {error.strerror}", file=sys.stderr)
        return 127
    return code if code >= 0 else 128 - code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
