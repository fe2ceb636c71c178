"""Where a result came from: package and library versions, git commit, command line, host, CPU,
times.

``provenance()`` is recorded in every run's config.json (the process that started it) and
finished.json (the one that finished it), and in a grid's grid.json. A grid worker records the
grid's command line (``set_command``), not its own.
"""
from __future__ import annotations

import platform
import shlex
import socket
import subprocess
import sys
from datetime import datetime, timezone
from functools import lru_cache
from importlib import metadata
from pathlib import Path

from jigsaws_tools.cli.common import DISTRIBUTION

_command: list[str] | None = None


def now() -> str:
    """The current time, ISO 8601 with the UTC offset, to the second."""
    return datetime.now(timezone.utc).astimezone().isoformat(timespec="seconds")


def set_command(argv: list[str]) -> None:
    """Record ``argv`` as this process's command line (instead of ``sys.argv``): a CLI's name and
    arguments, or in a grid worker the grid's."""
    global _command
    _command = list(argv)


def command() -> list[str]:
    """This process's command line: the one ``set_command`` recorded, else ``sys.argv``."""
    return list(_command or sys.argv)


def provenance() -> dict:
    """Versions, git commit (None outside a git checkout), command line, host and CPU model.

    The CPU is recorded because the same code, seed and data can train different weights on
    different processors: their float32 kernels may sum in another order (docs/REPRODUCTION.md,
    "Seeds and machines")."""
    return {"package": _version(DISTRIBUTION), **_git(), "python": platform.python_version(),
            "tensorflow": _version("tensorflow") or _version("tensorflow-cpu"),
            "numpy": _version("numpy"), "command": shlex.join(command()),
            "host": socket.gethostname(), "cpu": cpu_model()}


def started_loops(record: dict) -> str | None:
    """The LSTM loops a run started on, as its config.json ``record`` says (``provenance.loops``,
    ``auto`` resolved: ``fused``, ``graph`` or ``xla``); None in a record without that entry."""
    ran = record.get("provenance", {})
    ran = ran.get("loops") if isinstance(ran, dict) else None
    return ran if isinstance(ran, str) else None


@lru_cache(maxsize=1)
def cpu_model() -> str | None:
    """This machine's processor, e.g. "AMD EPYC": Linux /proc/cpuinfo's first ``model
    name``, else ``platform.processor()``; None when neither says."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        lines = []
    for line in lines:
        name, _, value = line.partition(":")
        if name.strip() == "model name" and value.strip():
            return value.strip()
    return platform.processor() or None


def _version(distribution: str) -> str | None:
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return None


@lru_cache(maxsize=1)
def _git() -> dict:
    """``git_commit`` of the source tree this package runs from, and ``git_dirty`` (uncommitted
    changes to tracked files); None when it is not a git checkout or git is missing."""
    root = Path(__file__).resolve().parents[2]

    def git(*args: str) -> str | None:
        try:
            # --no-optional-locks: status must not take the index lock, which a status killed
            # by the timeout (a loaded machine) would leave behind in the user's checkout
            result = subprocess.run(["git", "--no-optional-locks", "-C", str(root), *args],
                                    capture_output=True, text=True, timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            return None
        return result.stdout.strip() if result.returncode == 0 else None

    commit = git("rev-parse", "HEAD") if (root / ".git").exists() else None
    status = git("status", "--porcelain", "--untracked-files=no") if commit else None
    return {"git_commit": commit, "git_dirty": None if status is None else bool(status)}
