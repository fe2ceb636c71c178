"""A command's files in a folder it shares with others (tables beside a README and a grid).

``staged_outputs`` gives the command a hidden staging folder inside the output folder; when the
command's block ends normally its files are moved into place together, and the folder's
*manifest* (a JSON file named by the command, e.g. ``tables.json``) lists them. So

- a file of the same name that the manifest does not list (the user's own ``table1.csv``, or a
  file of another command) is never written over: the whole output is refused before anything
  is moved, unless ``overwrite`` says to replace such files;
- a file the last manifest listed and this output lacks (a figure the grid can no longer draw)
  is removed, and nothing else is: files the command did not write stay;
- a command that fails or is interrupted leaves the folder as it was (but for a hidden
  ``.partial-*`` folder if the process is killed outright), never half old and half new.

Between the moves the manifest lists the old and the new files together, so a process killed
there leaves a folder whose files the next call may still replace.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from .folder import RunFolderError, read_json, write_json
from .outputs import OutputFolderError

#: In the names of the hidden staging folders (a killed process may leave one; git ignores it).
PARTIAL = ".partial-"


@contextmanager
def staged_outputs(out: Path, manifest: str, command: str,
                   overwrite: bool = False) -> Iterator[Path]:
    """Write a command's files into the staging folder yielded; publish them in ``out``.

    Args:
        out: the output folder (created if needed; removed again if the command fails and it
            was created here).
        manifest: the manifest's file name in ``out``, e.g. ``"tables.json"``.
        command: the command's name, for messages and the manifest.
        overwrite: replace files of the output's names that the manifest does not list.

    Raises:
        OutputFolderError: a file to be written exists in ``out`` and the manifest does not
            list it (without ``overwrite``), or is a folder; nothing is moved then.
    """
    out = Path(out)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f"{PARTIAL}{Path(manifest).stem}-", dir=out))
    try:
        yield staging
        _publish(staging, out, manifest, command, overwrite)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        if created and not any(out.iterdir()):
            out.rmdir()


def listed(out: Path, manifest: str) -> list[str]:
    """The files (paths relative to ``out``) the manifest in ``out`` lists; none without one."""
    path = Path(out) / manifest
    if not path.is_file():
        return []
    record = read_json(path)
    files = record.get("files") if isinstance(record, dict) else None
    if not isinstance(files, list) or not all(isinstance(f, str) and _inside(f) for f in files):
        raise RunFolderError(f"{path}: not a manifest: no 'files' list of paths inside "
                             f"{out}")
    return files


def _publish(staging: Path, out: Path, manifest: str, command: str, overwrite: bool) -> None:
    """Move every file of ``staging`` to the same place in ``out``, then list them alone."""
    new = sorted(p.relative_to(staging).as_posix() for p in staging.rglob("*") if p.is_file())
    old = listed(out, manifest)
    for name in new:
        target = out / name
        if target.is_dir() and not target.is_symlink():
            raise OutputFolderError(f"{target} is a folder; {command} writes a file there "
                                    "(move it or choose another output folder)")
        if (target.exists() or target.is_symlink()) and name not in old and not overwrite:
            raise OutputFolderError(f"{target} exists and is not an output of {command} "
                                    f"({out / manifest} does not list it); move it, choose "
                                    "another output folder, or replace it (--overwrite)")
    _write_manifest(out, manifest, command, sorted({*old, *new}))
    for name in new:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        os.replace(staging / name, out / name)
    for name in sorted(set(old) - set(new)):
        _remove(out, name)
    _write_manifest(out, manifest, command, new)


def _write_manifest(out: Path, manifest: str, command: str, files: list[str]) -> None:
    write_json(out / manifest, {"written_by": command, "files": files})


def _remove(out: Path, name: str) -> None:
    """Remove the file ``name`` from ``out``, and its folders up to ``out`` once empty."""
    path = out / name
    path.unlink(missing_ok=True)
    for folder in path.parents:
        if folder == out or not folder.is_dir() or any(folder.iterdir()):
            break
        folder.rmdir()


def _inside(name: str) -> bool:
    """Whether ``name`` is a relative path that stays inside its folder."""
    parts = Path(name).parts
    return bool(parts) and not Path(name).is_absolute() and ".." not in parts
