"""One writer per folder: an advisory lock on ``<folder>/.lock`` while a process writes there
(or on ``<folder>/<name>`` for one place of the folder: ``publish`` locks the folder it replaces
by a lock file beside it, ``.<target>.lock``).

``fcntl.flock`` locks belong to the open file, so the operating system releases them when the
holder exits, however it exits: the lock of a dead process is simply taken by the next one. The
file holds the holder's pid, host and start time for the message of a second writer. A process may
take a lock it already holds (nested ``hold_folder`` calls count). On network file systems flock
works where the server supports it (NFSv4 and most cluster file systems); where it does not, a
warning says so and the folder is used unlocked, as on systems without ``fcntl`` (Windows).

The lock leaves no trace: a holder removes the lock file it created (still holding it) and then
each folder it created for it that is empty (``rmdir``, which removes nothing else), so a command
that fails before its first write leaves no folder, and a folder that existed as it was. A lock
file found in place stays. A process that opened the lock file before its removal finds, once it
holds the lock, that the path no longer names that file, and takes the lock again.
"""
from __future__ import annotations

import errno
import logging
import os
import socket
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from .folder import RunFolderError
from .provenance import now

try:
    import fcntl
except ImportError:              # pragma: no cover - Windows
    fcntl = None

LOCK_FILE = ".lock"
#: How many times taking a lock starts again after a folder or the lock file vanished on its way
#: (another process's release removing it) before the error is taken for what it says: a place
#: where no folder or file can be made (``/proc``: ENOENT every time).
RACES = 100
log = logging.getLogger(__name__)


@dataclass
class _Hold:
    """A folder locked by this process: the lock file's descriptor, whether taking the lock
    created that file, the folders created for it (top first) and the number of ``hold_folder``
    blocks holding it."""

    fd: int
    created_lock: bool
    made: list[Path]
    depth: int = 1


#: Lock files held by this process, by resolved folder and lock file name.
_held: dict[tuple[Path, str], _Hold] = {}


class FolderLockedError(RunFolderError):
    """Another process writes in the folder."""


@contextmanager
def hold_folder(folder: Path | str, what: str = "run folder",
                lock_file: str = LOCK_FILE) -> Iterator[None]:
    """Hold ``folder``'s lock for the block (creating the folder); raise ``FolderLockedError``
    naming the folder and the holder at once if another process holds it. At its end, the lock
    file and the folders the block created are removed, the folders only if empty.
    ``lock_file``: the lock file's name in ``folder`` (one lock per place of the folder)."""
    folder = Path(folder)
    key = (folder.resolve(), lock_file)
    if key in _held:
        _held[key].depth += 1
    else:
        _held[key] = _take(folder, what, lock_file)
    try:
        yield
    finally:
        _held[key].depth -= 1
        if not _held[key].depth:
            _release(folder / lock_file, _held.pop(key))


def appears_held(folder: Path | str) -> bool:
    """Whether a process seems to hold ``folder``'s lock, read without touching the lock (a
    flock taken to test it could refuse the holder-to-be): the lock file exists and names a
    process that lives, or one on another host (which cannot be asked). For progress displays,
    never for deciding who may write."""
    try:
        fields = (Path(folder) / LOCK_FILE).read_text(errors="replace").split()
    except OSError:
        return False
    if not fields:                            # just created, its holder not written yet
        return True
    if len(fields) != 3 or not fields[0].isdigit():
        return False
    if fields[1] != socket.gethostname():
        return True
    try:
        os.kill(int(fields[0]), 0)
    except ProcessLookupError:
        return False
    except OSError:                           # alive, owned by another user
        return True
    return True


def _take(folder: Path, what: str, lock_file: str) -> _Hold:
    """Create ``folder`` if need be and lock it; again while another process's release removes
    the lock file or a folder on its way (between our ``mkdir`` and ``open``, or ``open`` and
    ``flock``), at most ``RACES`` times."""
    made: dict[Path, None] = {}                        # in creation order, each once
    for _ in range(RACES):
        try:
            made.update(dict.fromkeys(_make_folders(folder)))
            taken = _acquire(folder, what, lock_file)
        except FileNotFoundError:                      # a folder made was removed meanwhile,
            continue                                   # or none can be made there (/proc)
        if taken is not None:
            return _Hold(*taken, list(made))
    made.update(dict.fromkeys(_make_folders(folder)))  # raises where no folder can be made;
    for path in reversed(made):                        # else no lock file can (removed again)
        if path.is_dir() and not any(path.iterdir()):
            path.rmdir()
    raise FileNotFoundError(errno.ENOENT, f"no file can be created there (the lock of the "
                            f"{what})", str(folder / lock_file))


def _make_folders(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; returns those this call created, top first.
    An error of the operating system reads ``<path>: a file, not a folder`` or ``<path>: cannot
    create this folder (<reason>)`` (``/sys/x``: Operation not permitted), of the same type
    (``FileNotFoundError``: a parent removed meanwhile, which ``_take`` tries again, or /proc)."""
    made = []
    for path in [*reversed(folder.parents), folder]:
        if path.is_dir():
            continue
        try:
            path.mkdir()
        except FileExistsError:
            if not path.is_dir():
                raise FileExistsError(errno.EEXIST, "a file, not a folder", str(path)) from None
            continue                        # created meanwhile by another process
        except OSError as error:
            raise type(error)(error.errno, f"cannot create this folder ({error.strerror})",
                              str(path)) from None
        made.append(path)
    return made


def _acquire(folder: Path, what: str, lock_file: str) -> tuple[int, bool] | None:
    """Open and lock ``folder``'s lock file: its descriptor and whether this call created the
    file; None if the file's last holder removed it before this process held the lock."""
    path = folder / lock_file
    fd, created = _open_lock_file(path, what)
    if fd is None:
        return None
    if fcntl is None:
        return fd, created
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        error = _in_use(folder, what, fd)
        os.close(fd)
        raise error from None
    except OSError as error:              # e.g. ENOLCK: a file system without flock
        log.warning("cannot lock %s (%s); continuing without a lock", folder, error)
        return fd, created
    if not _names(path, fd):
        os.close(fd)
        return None
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()} {socket.gethostname()} {now()}\n".encode())
    return fd, created


def _in_use(folder: Path, what: str, fd: int) -> FolderLockedError:
    """The error of a second writer of ``folder``, naming the holder its lock file ``fd``
    records."""
    fields = os.read(fd, 200).decode(errors="replace").split()     # pid host time
    holder = "another process"
    if len(fields) == 3:
        holder = f"pid {fields[0]} on {fields[1]} since {fields[2]}"
    return FolderLockedError(f"{what} {folder} is in use by {holder}; wait for it to finish or "
                             "stop it first")


def check_free(folder: Path | str, what: str = "run folder", lock_file: str = LOCK_FILE
               ) -> None:
    """Raise the error that ``hold_folder`` would raise now, leaving nothing behind (for a dry
    run): ``FolderLockedError`` (the lock file, if there is one, is locked and unlocked at once;
    a stale one, of a process gone, is free), or the ``OSError`` of a folder that cannot be
    made (``/proc/x``: ``hold_folder`` makes one not there yet and removes it again, as a
    launch's first step does) or written in."""
    folder = Path(folder)
    if not (folder.exists() or folder.is_symlink()):
        with hold_folder(folder, what, lock_file):
            return
    if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK):
        raise PermissionError(errno.EACCES, "the folder cannot be written", str(folder))
    if fcntl is None or not (folder / lock_file).is_file():
        return
    try:
        fd = os.open(folder / lock_file, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except OSError:
        return                                  # gone meanwhile, or unusable: hold_folder says
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        fcntl.flock(fd, fcntl.LOCK_UN)
    except BlockingIOError:
        raise _in_use(folder, what, fd) from None
    except OSError:
        pass                                    # a file system without flock: used unlocked
    finally:
        os.close(fd)


def _open_lock_file(path: Path, what: str) -> tuple[int | None, bool]:
    """Open ``path``, creating it if there is none: its descriptor (None if it vanished between
    two attempts) and whether this call created it. Never through a symbolic link: a file
    elsewhere would be truncated. ``FileNotFoundError`` when its folder is gone."""
    nofollow = getattr(os, "O_NOFOLLOW", 0)
    try:
        try:
            return os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL | nofollow, 0o666), True
        except FileExistsError:
            return os.open(path, os.O_RDWR | nofollow), False
    except FileNotFoundError:
        if not path.parent.is_dir():
            raise
        return None, False                              # removed by its holder: try again
    except OSError as error:
        if not (path.exists() or path.is_symlink()):   # none could be made (/sys, read-only)
            raise type(error)(error.errno, f"no file can be created there ({error.strerror}; "
                              f"the lock of the {what})", str(path)) from None
        problem = "a symbolic link" if path.is_symlink() else f"unusable ({error.strerror})"
        raise RunFolderError(f"{path}: the lock file of the {what} is {problem}; remove it "
                             "(nothing else holds it)") from None


def _names(path: Path, fd: int) -> bool:
    """Whether ``path`` still names the file open as ``fd``."""
    try:
        return os.path.samestat(os.stat(path, follow_symlinks=False), os.fstat(fd))
    except FileNotFoundError:
        return False


def _release(path: Path, hold: _Hold) -> None:
    """Unlock the lock file ``path``, first removing it if ``hold`` created it, then the
    folders made for it, deepest first, until one is not empty."""
    try:
        if hold.created_lock and _names(path, hold.fd):
            path.unlink()
            for made in reversed(hold.made):
                made.rmdir()
    except OSError:
        pass                                # a folder holding anything stays
    finally:
        os.close(hold.fd)
