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
- a command that fails or is interrupted leaves the folder as it was (but for a hidden
  ``.partial-*`` folder if the process is killed outright), never half old and half new, and a
  folder it created for the output is removed again.

Between the moves the manifest lists the old and the new files together, so a process killed
there leaves a folder whose files the next call may still replace.
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
        staging = Path(tempfile.mkdtemp(prefix=f"{PARTIAL}{Path(manifest).stem}-", dir=out))
        try:
            yield staging
            _publish(staging, out, manifest, command, overwrite, record or {}, kept)
        finally:
            shutil.rmtree(staging, ignore_errors=True)


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


def _publish(staging: Path, out: Path, manifest: str, command: str, overwrite: bool,
             record: dict[str, Any], kept: tuple[str, ...]) -> None:
    """Move every file of ``staging`` to the same place in ``out``, then list them (and the
    listed files under ``kept``) alone."""
    new = sorted(p.relative_to(staging).as_posix() for p in staging.rglob("*") if p.is_file())
    old = listed(out, manifest)
    for name in new:
        _check_place(out, name, manifest, command)
        if (out / name).is_symlink() or (out / name).exists():
            if name not in old and not overwrite:
                raise OutputFolderError(f"{out / name} exists and is not an output of {command} "
                                        f"({out / manifest} does not list it); move it, choose "
                                        "another output folder, or replace it (--overwrite)")
    left = [name for name in old if name not in new and name.startswith(kept)]
    stale = [name for name in old if name not in new and name not in left]
    for name in stale:
        _check_place(out, name, manifest, command)
    _write_manifest(out, manifest, command, sorted({*old, *new}), record)
    for name in new:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        os.replace(staging / name, out / name)
    for name in stale:
        _remove(out, name)
    _write_manifest(out, manifest, command, sorted({*new, *left}), record)


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


def _write_manifest(out: Path, manifest: str, command: str, files: list[str],
                    record: dict[str, Any]) -> None:
    write_json(out / manifest, {"written_by": command, **record, "files": files})


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
