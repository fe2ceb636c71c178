"""A command's files in a folder it shares with others (tables beside a README and a grid).

``staged_outputs`` holds the output folder's lock (``lock.hold_folder``) and gives the command a
hidden staging folder inside it; when the command's block ends normally its files are moved into
place together, and the folder's *manifest* (a JSON file named by the command, e.g.
``tables.json``) lists them. So

- the folder holds the last call's output: the files the last manifest listed and this output
  lacks (a figure the grid can no longer draw) are removed, and nothing else is, but for those
  under the folders the call leaves alone (``kept``: the figures of a call told to write the
  tables only), which stay listed;
- a file of an output's name that the manifest does not list (the user's own ``table1.csv``, a
  file of another command) is never written over: the whole output is refused before anything
  is moved, unless ``overwrite`` says to replace such files;
- every file written or removed lies in the folder itself, never behind a symbolic link, in a
  run or grid folder it holds, or at a path that is a folder (refused before anything moves);
- a command that fails or is interrupted leaves the folder as it was, and a folder it created
  for the output is removed again; the publish itself is journalled (``publish``): the
  manifest, marked ``pending``, names the complete staging folder and the files to remove
  before the first file moves, and a call killed among the moves is finished by the next call
  writing that output (``finish_pending``), before it looks at the folder. Meanwhile the
  manifest lists the old and the new files together, and says ``pending``.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import Any, Iterator

from .folder import RunFolderError, read_json, write_json
from .lock import hold_folder
from .outputs import OutputFolderError, folder_kind
from .publish import naming_full_disk, step

#: In the names of the hidden staging folders (a killed process may leave one; git ignores it).
PARTIAL = ".partial-"


@contextmanager
def staged_outputs(out: Path, manifest: str, command: str, overwrite: bool = False,
                   record: dict[str, Any] | None = None,
                   kept: tuple[str, ...] = ()) -> Iterator[Path]:
    """Write a command's files into the staging folder yielded; publish them in ``out``.

    Args:
        out: the output folder (created if needed, and removed again if the command fails).
        manifest: the manifest's file name in ``out``, e.g. ``"tables.json"``.
        command: the command's name, for messages and the manifest.
        overwrite: replace files of the output's names that the manifest does not list.
        record: more to say in the manifest (e.g. the run a prediction used), beside its
            ``written_by`` and ``files``.
        kept: folders of ``out`` (relative, e.g. ``"figures/"``) whose listed files this call
            does not write and leaves as they are.

    Raises:
        OutputFolderError: a file to be written exists in ``out`` and the manifest does not
            list it (without ``overwrite``), or a path to write or remove is not a plain place
            of ``out`` (module docstring); nothing is moved then.
    """
    out = Path(out)
    with hold_folder(out, "output folder"):
        finish_pending(out, manifest)
        staging = Path(tempfile.mkdtemp(prefix=_staging_prefix(manifest), dir=out))
        try:
            with naming_full_disk(staging, out):
                yield staging
            plan = _plan(staging, out, manifest, command, overwrite, kept)
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            raise
        _journal(out, manifest, command, record or {}, staging, plan)
        finish_pending(out, manifest)


def finish_pending(out: Path, manifest: str) -> None:
    """Finish the publish that the manifest in ``out`` records as ``pending`` (a call killed
    among its moves): move the files still in its staging folder into place, remove the files
    it names, and list the new output alone; then remove the staging folders of calls killed
    before they published. Call it holding ``out``'s lock."""
    out = Path(out)
    path = out / manifest
    record = read_json(path) if path.is_file() else None
    pending = record.get("pending") if isinstance(record, dict) else None
    if pending is not None:
        staging, remove, files = _pending(path, pending)
        for file in sorted(p for p in staging.rglob("*") if p.is_file()):
            name = file.relative_to(staging).as_posix()
            _check_place(out, name, manifest, record.get("written_by", "a command"))
            step(f"move {name}")
            (out / name).parent.mkdir(parents=True, exist_ok=True)
            os.replace(file, out / name)
        for name in remove:
            _check_place(out, name, manifest, record.get("written_by", "a command"))
            step(f"remove {name}")
            _remove(out, name)
        step("list")
        write_json(path, {**{k: v for k, v in record.items() if k != "pending"}, "files": files})
    for leftover in sorted(out.glob(f"{_staging_prefix(manifest)}*")):
        if leftover.is_dir() and not leftover.is_symlink():
            step("clear")
            shutil.rmtree(leftover)


def listed(out: Path, manifest: str) -> list[str]:
    """The files (paths relative to ``out``) the manifest in ``out`` lists; none without one,
    or when it predates lists (a record without ``files``)."""
    path = Path(out) / manifest
    if not path.is_file():
        return []
    record = read_json(path)
    files = record.get("files", []) if isinstance(record, dict) else None
    if not isinstance(files, list) or not all(isinstance(f, str) and _relative(f) for f in files):
        raise RunFolderError(f"{path}: not a manifest: no 'files' list of relative paths "
                             "inside its folder")
    return files


def _plan(staging: Path, out: Path, manifest: str, command: str, overwrite: bool,
          kept: tuple[str, ...]) -> tuple[list[str], list[str], list[str]]:
    """``(old, new, stale)``: the files the manifest lists now, those of ``staging`` (to move to
    the same place in ``out``), and the listed files to remove (those neither new nor under
    ``kept``); every place checked, nothing moved."""
    new = sorted(p.relative_to(staging).as_posix() for p in staging.rglob("*") if p.is_file())
    old = listed(out, manifest)
    for name in new:
        _check_place(out, name, manifest, command)
        if (out / name).is_symlink() or (out / name).exists():
            if name not in old and not overwrite:
                raise OutputFolderError(f"{out / name} exists and is not an output of {command} "
                                        f"({out / manifest} does not list it); move it, choose "
                                        "another output folder, or replace it (--overwrite)")
    stale = [name for name in old if name not in new and not name.startswith(kept)]
    for name in stale:
        _check_place(out, name, manifest, command)
    return old, new, stale


def _journal(out: Path, manifest: str, command: str, record: dict[str, Any], staging: Path,
             plan: tuple[list[str], list[str], list[str]]) -> None:
    """Write the manifest of a publish about to start: the old and new files together, and
    ``pending``: the staging folder, the files to remove and the files of the new output (the
    new ones and the listed ones under ``kept``)."""
    old, new, stale = plan
    files = sorted({*new, *(name for name in old if name not in stale)})
    step("journal")
    write_json(out / manifest, {"written_by": command, **record, "files": sorted({*old, *new}),
                                "pending": {"staging": staging.name, "remove": stale,
                                            "files": files}})


def _pending(path: Path, pending: Any) -> tuple[Path, list[str], list[str]]:
    """The staging folder, the files to remove and the new files of a manifest's ``pending``
    record; a record of another shape is a ``RunFolderError`` naming the manifest."""
    ok = (isinstance(pending, dict) and isinstance(pending.get("staging"), str)
          and pending["staging"].startswith(_staging_prefix(path.name))
          and "/" not in pending["staging"]
          and all(isinstance(pending.get(key), list)
                  and all(isinstance(f, str) and _relative(f) for f in pending[key])
                  for key in ("remove", "files")))
    if not ok:
        raise RunFolderError(f"{path}: pending: not the record of an interrupted publish "
                             f"(value: {str(pending)[:80]!r}); remove the manifest's 'pending' "
                             "entry and run the command again")
    return path.parent / pending["staging"], pending["remove"], pending["files"]


def _staging_prefix(manifest: str) -> str:
    """The name prefix of the staging folders of the output listed by ``manifest``."""
    return f"{PARTIAL}{Path(manifest).stem}-"


def _check_place(out: Path, name: str, manifest: str, command: str) -> None:
    """Refuse ``name`` unless it is a plain place of ``out``: every folder on its way a real
    folder of ``out`` (not a symbolic link, a file, or a run or grid folder), itself not a
    folder."""
    place = out
    for part in PurePosixPath(name).parts[:-1]:
        place = place / part
        obstacle = _obstacle(place)
        if obstacle:
            raise OutputFolderError(f"{place} is {obstacle}; {command} does not write or remove "
                                    f"{name} there (from {out / manifest}); move it or choose "
                                    "another output folder")
    if (out / name).is_dir() and not (out / name).is_symlink():
        raise OutputFolderError(f"{out / name} is a folder; {command} writes a file of that "
                                "name (move it or choose another output folder)")


def _obstacle(place: Path) -> str | None:
    """What keeps ``place`` from being a plain folder of the output, or None."""
    if place.is_symlink():
        return "a symbolic link"
    if place.exists() and not place.is_dir():
        return "a file"
    kind = folder_kind(place)
    return f"a {kind}" if kind else None


def _remove(out: Path, name: str) -> None:
    """Remove the file ``name`` from ``out``, and its folders up to ``out`` once empty."""
    path = out / name
    path.unlink(missing_ok=True)
    for folder in path.parents:
        if folder == out or not folder.is_dir() or any(folder.iterdir()):
            break
        folder.rmdir()


def _relative(name: str) -> bool:
    """Whether ``name`` is a relative path that stays inside its folder."""
    path = PurePosixPath(name)
    return bool(path.parts) and not path.is_absolute() and ".." not in path.parts
