"""A command's files in a folder it shares with others (tables beside a README and a grid).

``staged_outputs`` holds the output folder's lock (``lock.hold_folder``) and gives the command a
hidden staging folder inside it; when the command's block ends normally its files are moved into
place together, and the folder's *manifest* (a JSON file named by the command, e.g.
``tables.json``) lists them. So

- the folder holds the last call's output: the files the last manifest listed and this output
  lacks (a figure the grid can no longer draw) are removed, and nothing else is, but for those
  under the folders the call leaves alone (``kept``: the figures of a call told to write the
  tables only, or figures that need data this machine lacks), which stay listed;
- a file of an output's name that the manifest does not list (the user's own ``table1.csv``, a
  file of another command) is never written over: the whole output is refused before anything
  is moved, unless ``overwrite`` says to replace such files;
- every file written or removed lies in the folder itself, never behind a symbolic link, in a
  run or grid folder it holds, or at a path that is a folder (refused before anything moves);
- a command that fails or is interrupted leaves the folder as it was, and a folder it created
  for the output is removed again; the publish itself is journalled (``publish``): a journal in
  the hidden staging folder names the new output's files and the files to remove before
  anything visible changes; then the manifest is removed, then the old files, then the new ones
  are moved in and the manifest is written again. So a reader who never calls the command again
  sees the old output with its manifest, or the new one with its own, or, after a call killed
  midway, files of the new output and no manifest: never a manifest describing files of another
  output, nor old and new files mixed. The next call writing that output finishes the publish
  (``finish_pending``) before it looks at the folder.
"""
from __future__ import annotations

import os
import shutil
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import Any, Iterator, Sequence

from .folder import RunFolderError, read_json, write_json
from .lock import hold_folder
from .outputs import OutputFolderError, folder_kind
from .publish import is_own, naming_full_disk, own_folder, step

#: In the names of the hidden staging folders (a killed process may leave one; git ignores it).
PARTIAL = ".partial-"
#: In a staging folder: the output's files, and the journal of their publish.
FILES, JOURNAL = "files", "journal.json"


@contextmanager
def staged_outputs(out: Path, manifest: str, command: str, overwrite: bool = False,
                   record: dict[str, Any] | None = None,
                   kept: Sequence[str] = ()) -> Iterator[Path]:
    """Write a command's files into the staging folder yielded; publish them in ``out``.

    Args:
        out: the output folder (created if needed, and removed again if the command fails).
        manifest: the manifest's file name in ``out``, e.g. ``"tables.json"``.
        command: the command's name, for messages and the manifest.
        overwrite: replace files of the output's names that the manifest does not list.
        record: more to say in the manifest (e.g. the run a prediction used), beside its
            ``written_by`` and ``files``.
        kept: folders of ``out`` (relative, e.g. ``"figures/"``) or file-name prefixes whose
            listed files this call does not write and leaves as they are; read after the
            command's block, so the command may add to a list given here while it writes.

    Raises:
        OutputFolderError: a file to be written exists in ``out`` and the manifest does not
            list it (without ``overwrite``), or a path to write or remove is not a plain place
            of ``out`` (module docstring); nothing is moved then.
    """
    out = Path(out)
    with hold_folder(out, "output folder"):
        finish_pending(out, manifest)
        work = own_folder(out, _staging_prefix(manifest), "", manifest)
        staging = work / FILES
        try:
            staging.mkdir()
            with naming_full_disk(staging, out):
                yield staging
            plan = _plan(staging, out, manifest, command, overwrite, tuple(kept))
        except BaseException:
            shutil.rmtree(work, ignore_errors=True)
            raise
        _journal(work, command, record or {}, plan)
        finish_pending(out, manifest)


def finish_pending(out: Path, manifest: str) -> None:
    """Finish the publish of the output ``manifest`` lists in ``out`` that a call killed midway
    left (the journal in its staging folder): remove the manifest, the files to remove and the
    old files of the names still to move, move those in, write the manifest; then remove the
    staging folders of calls killed before they published. Only the staging folders the
    publish made (``publish.is_own``) are read or removed: a folder of the user's of a like name
    stays. Call it holding ``out``'s lock."""
    out = Path(out)
    for work in sorted(out.glob(f"{_staging_prefix(manifest)}*")):
        if not is_own(work, manifest):
            continue
        if (work / JOURNAL).exists():
            _roll_forward(out, manifest, work)
        step("clear")
        shutil.rmtree(work)


def _roll_forward(out: Path, manifest: str, work: Path) -> None:
    """The publish the journal in ``work`` records, from wherever it stopped (each step may be
    done again): the manifest unlisted, the old files removed, the new moved in, listed."""
    record, remove = _journal_of(work / JOURNAL)
    staging, writer = work / FILES, record.get("written_by", "a command")
    moving = sorted(p.relative_to(staging).as_posix() for p in staging.rglob("*")
                    if p.is_file())
    for name in [*remove, *moving]:
        _check_place(out, name, manifest, writer)
    step("unlist")
    (out / manifest).unlink(missing_ok=True)
    for name in [*remove, *(name for name in moving if (out / name).is_symlink()
                            or (out / name).exists())]:
        step(f"remove {name}")
        _remove(out, name)
    for name in moving:
        step(f"move {name}")
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        os.replace(staging / name, out / name)
    step("list")
    write_json(out / manifest, record)


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


def _journal(work: Path, command: str, record: dict[str, Any],
             plan: tuple[list[str], list[str], list[str]]) -> None:
    """Write the journal of a publish about to start into its staging folder ``work``: the
    manifest to write (``files``: the new files and the listed ones under ``kept``) and the
    listed files to remove."""
    old, new, stale = plan
    files = sorted({*new, *(name for name in old if name not in stale)})
    step("journal")
    write_json(work / JOURNAL, {"manifest": {"written_by": command, **record, "files": files},
                                "remove": stale})


def _journal_of(path: Path) -> tuple[dict[str, Any], list[str]]:
    """The manifest to write and the files to remove of a publish's journal; a journal of
    another shape is a ``RunFolderError`` naming it (nothing is moved or removed then)."""
    journal = read_json(path)
    record = journal.get("manifest") if isinstance(journal, dict) else None
    remove = journal.get("remove") if isinstance(journal, dict) else None
    ok = (isinstance(record, dict) and isinstance(remove, list)
          and isinstance(record.get("files"), list)
          and all(isinstance(f, str) and _relative(f) for f in [*remove, *record["files"]]))
    if not ok:
        raise RunFolderError(f"{path}: not the journal of an interrupted publish (value: "
                             f"{str(journal)[:80]!r}); remove its folder and run the command "
                             "again")
    return record, remove


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
