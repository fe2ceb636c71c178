"""Publishing a command's output: complete before it is visible, never half old and half new.

Every command that replaces an earlier output (``multitask-tables``' tables, figures and scores
archives, ``multitask-predict``, ``multitask-evaluate``, ``multitask-export``) writes the new
output into a hidden staging place first and publishes it only once it is complete, here. A
publish holds the lock of its place throughout and starts by recovering whatever a publish
killed there (SIGKILL, a power cut) left, so an interrupted publish is finished or undone by the
next one, before it looks at the place.

Each hidden folder a publish makes beside its output (``own_folder``:
``.<name>.<random>.tmp``, ``.partial-<manifest>-<random>``) holds first of all a marker file it
wrote, ``publish.json``, naming the output it serves: recovery removes a folder only when it
holds that marker (``is_own``), so a folder of the user's that happens to match the pattern
(``.A.mynotes1.tmp/``, ``.A.backup_1.old.tmp/``) is never touched. Two forms:

- a folder written whole (``staged_folder``: an evaluation, a SavedModel, a scores archive) is
  written into ``new/`` of such a folder and exchanged with the visible folder in one system
  call (Linux ``renameat2(RENAME_EXCHANGE)``; a folder that is not there yet by one
  ``rename``): at every instant the visible folder is the old one or the new one, whole. The old
  one, now in the hidden folder, is removed with it (a leftover the next publish removes).
  Where the system or file system cannot exchange, the old folder is moved into the hidden
  folder (``old/``) before the new one is renamed in, and the next publish puts it back if the
  process died in between;
- files among others in a shared folder (``manifest.staged_outputs``: tables beside a README,
  predictions) are published after a *journal* in the hidden folder; their manifest is removed
  first, then the old files, and written again once the new ones are in place, so that a
  manifest never describes files of another output; a publish killed midway is finished (rolled
  forward) by the next call writing that output (``manifest.finish_pending``).

``step_hook`` is called with the name of every step that changes what is visible, just before
it: tests set it to kill the process there (``tests/test_publish.py``).
"""
from __future__ import annotations

import ctypes
import errno
import functools
import os
import re
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator

from jigsaws_tools.errors import NO_SPACE, WriteFailed

from .folder import RunFolderError, read_json, require_empty, write_json
from .lock import hold_folder

#: Fault injection for tests: called with each step's name just before the step.
step_hook: Callable[[str], None] = lambda step: None
_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
#: The marker file in each hidden folder a publish makes (module docstring).
MARKER = "publish.json"
#: In a staging folder of ``staged_folder``: the new output, and the old one set aside.
NEW, OLD = "new", "old"


def step(name: str) -> None:
    """Mark the next step of a publish (``step_hook``)."""
    step_hook(name)


@contextmanager
def claimed(target: Path | str) -> Iterator[None]:
    """Hold the lock of the place ``target`` (``.<name>.lock`` beside it) for the block, after
    recovering what publishes of ``target`` killed before left beside it (``recover_folder``)."""
    target = Path(target)
    with hold_folder(target.parent, f"output {target.name} in the folder", f".{target.name}.lock"):
        recover_folder(target)
        yield


@contextmanager
def staged_folder(target: Path | str, overwrite: bool = False) -> Iterator[Path]:
    """A fresh folder in a hidden sibling of ``target`` (``own_folder``) to write into; it
    replaces ``target`` when the block ends normally (module docstring) and is removed when it
    fails, so ``target`` is never seen half-written, nor missing once it existed.

    An existing non-empty ``target`` is an error (``FileExistsError``) unless ``overwrite``; it is
    then replaced only once the new folder is complete. A full disk while the block writes is a
    ``WriteFailed`` naming the file at its place in ``target`` (or ``target``).
    """
    target = Path(target)
    with claimed(target):
        if not overwrite:
            require_empty(target)
        work = own_folder(target.parent, f".{target.name}.", ".tmp", target.name)
        staging = work / NEW
        try:
            staging.mkdir()
            with naming_full_disk(staging, target):
                yield staging
            _swap_in(staging, target)
        finally:
            shutil.rmtree(work, ignore_errors=True)


def own_folder(parent: Path, prefix: str, suffix: str, serves: str) -> Path:
    """A new hidden folder ``<prefix><random><suffix>`` in ``parent`` holding the marker file
    that proves it a publish's (``is_own``), for the output named ``serves``."""
    folder = Path(tempfile.mkdtemp(dir=parent, prefix=prefix, suffix=suffix))
    try:
        write_json(folder / MARKER, _marker(serves))
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)   # no marker: no later recovery could remove it
        raise
    return folder


def is_own(folder: Path, serves: str) -> bool:
    """Whether ``folder`` (a real folder, not a link) holds the marker ``own_folder`` writes for
    the output ``serves``: only then may a recovery remove it."""
    if folder.is_symlink() or not folder.is_dir() or (folder / MARKER).is_symlink():
        return False
    try:
        return read_json(folder / MARKER) == _marker(serves)
    except RunFolderError:
        return False


def _marker(serves: str) -> dict[str, str]:
    return {"written_by": __name__, "serves": serves}


@contextmanager
def naming_full_disk(staging: Path, visible: Path) -> Iterator[None]:
    """Turn an ``OSError`` of a full disk (``NO_SPACE``) raised in the block into a
    ``WriteFailed`` naming the file being written at its visible place (its path under
    ``staging`` moved to ``visible``), or ``visible`` when the error names no file of
    ``staging``."""
    try:
        yield
    except OSError as error:
        if error.errno not in NO_SPACE:
            raise
        named = Path(error.filename) if error.filename else None
        place = (visible / named.relative_to(staging)
                 if named is not None and named.is_relative_to(staging) else visible)
        raise WriteFailed(place, error.strerror or str(error)) from None


def _swap_in(staging: Path, target: Path) -> None:
    """Put the complete folder ``staging`` at ``target``; an old ``target`` ends up at
    ``staging`` (exchanged) or beside it (``OLD``, moved aside first where exchange is not
    available), to be removed with their hidden folder."""
    step("swap")
    try:
        os.rename(staging, target)          # no folder there, or an empty one: in one step
        return
    except OSError as error:
        if error.errno not in (errno.ENOTEMPTY, errno.EEXIST):
            raise
    if exchange(staging, target):
        step("remove old")
        return
    aside = staging.parent / OLD
    os.rename(target, aside)
    step("swap aside")
    try:
        os.rename(staging, target)
    except OSError:
        os.rename(aside, target)            # the old one back at once
        raise
    step("remove old")


def exchange(a: Path, b: Path) -> bool:
    """Swap the paths ``a`` and ``b`` in one system call (both exist); False where the system or
    the file system cannot (nothing done then)."""
    renameat2 = _renameat2()
    if renameat2 is None:
        return False
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP):
        return False
    raise OSError(code, os.strerror(code), str(b))


@functools.cache
def _renameat2() -> Callable | None:
    """The C library's ``renameat2`` (glibc 2.28+), None elsewhere."""
    try:
        function = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError, TypeError):
        return None
    function.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                         ctypes.c_uint]
    function.restype = ctypes.c_int
    return function


def recover_folder(target: Path) -> None:
    """Clear what publishes of ``target`` killed before left beside it (call under the lock of
    ``claimed``): each hidden folder of theirs (``is_own``; a folder of the user's of a like
    name stays) is removed, after putting the old folder it holds back at ``target`` if
    ``target`` is missing (the process died before the new one took its place)."""
    target = Path(target)
    leftover = re.compile(rf"^\.{re.escape(target.name)}\.[0-9a-z_]{{8}}\.tmp$")
    if not target.parent.is_dir():
        return
    for path in sorted(target.parent.iterdir()):
        if not leftover.match(path.name) or not is_own(path, target.name):
            continue
        aside = path / OLD
        if aside.is_dir() and not aside.is_symlink() and not (target.exists()
                                                              or target.is_symlink()):
            os.rename(aside, target)
        shutil.rmtree(path)
