"""One writer per folder: an advisory lock on ``<folder>/.lock`` while a process writes there.

``fcntl.flock`` locks belong to the open file, so the operating system releases them when the
holder exits, however it exits: the lock of a dead process is simply taken by the next one. The
file holds the holder's pid, host and start time for the message of a second writer. A process may
take a lock it already holds (nested ``hold_folder`` calls count). On network file systems flock
works where the server supports it (NFSv4 and most cluster file systems); where it does not, a
warning says so and the folder is used unlocked, as on systems without ``fcntl`` (Windows).
"""
from __future__ import annotations

import logging
import os
import socket
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from .folder import RunFolderError
from .provenance import now

try:
    import fcntl
except ImportError:              # pragma: no cover - Windows
    fcntl = None

LOCK_FILE = ".lock"
log = logging.getLogger(__name__)

#: Folders locked by this process: resolved path -> [file descriptor, nesting depth].
_held: dict[Path, list[int]] = {}


class FolderLockedError(RunFolderError):
    """Another process writes in the folder."""


@contextmanager
def hold_folder(folder: Path | str, what: str = "run folder") -> Iterator[None]:
    """Hold ``folder``'s lock for the block (creating the folder); raise ``FolderLockedError``
    naming the folder and the holder at once if another process holds it."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    key = folder.resolve()
    if key in _held:
        _held[key][1] += 1
    else:
        _held[key] = [_acquire(folder, what), 1]
    try:
        yield
    finally:
        _held[key][1] -= 1
        if not _held[key][1]:
            os.close(_held.pop(key)[0])      # closing the file releases the lock


def _acquire(folder: Path, what: str) -> int:
    path = folder / LOCK_FILE
    try:        # never through a symbolic link: a file elsewhere would be truncated
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o666)
    except OSError as error:
        problem = "a symbolic link" if path.is_symlink() else f"unusable ({error.strerror})"
        raise RunFolderError(f"{path}: the lock file of the {what} is {problem}; remove it "
                             "(nothing else holds it)") from None
    if fcntl is None:
        return fd
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        fields = os.read(fd, 200).decode(errors="replace").split()     # pid host time
        os.close(fd)
        holder = "another process"
        if len(fields) == 3:
            holder = f"pid {fields[0]} on {fields[1]} since {fields[2]}"
        raise FolderLockedError(f"{what} {folder} is in use by {holder}; wait for it to finish "
                                "or stop it first") from None
    except OSError as error:              # e.g. ENOLCK: a file system without flock
        log.warning("cannot lock %s (%s); continuing without a lock", folder, error)
        return fd
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()} {socket.gethostname()} {now()}\n".encode())
    return fd
