"""Where a command may write: never over a run or a grid it was not asked to replace.

A *run folder* holds ``config.json``, ``finished.json`` or ``checkpoints/``; a *grid folder*
holds ``grid.json`` (the record ``multitask-grid`` writes) and its runs under ``runs/``.
``check_output_folder`` refuses an output folder that is one of them, holds one, lies inside a
run folder (but for the one place a command owns there, ``multitask-evaluate``'s
``evaluate/``) or inside a grid's ``runs/``, so that no command mixes its files with a run's or
a grid's, and ``--overwrite`` can only ever replace an earlier output of the same command. Paths
are resolved first (``..``, symbolic links), so the check is of the place written, not of its
spelling.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Iterator

from jigsaws_tools.files import read_regular

from .folder import CHECKPOINTS, CONFIG, FINISHED, require_empty

#: The record a grid folder holds (``multitask.grid.folder``).
GRID_RECORD = "grid.json"
#: The folder of a grid that holds its runs (``runs/<annotations>/<direction>/...``).
GRID_RUNS = "runs"
#: The file that makes a folder a TensorFlow SavedModel (``multitask-export``'s output).
SAVED_MODEL = "saved_model.pb"


class OutputFolderError(ValueError):
    """An output folder a command may not write: it would overwrite a run or a grid."""


def folder_kind(folder: Path) -> str | None:
    """``"run folder"``, ``"grid folder"`` or None for any other folder."""
    folder = Path(folder)
    if (folder / GRID_RECORD).is_file():
        return "grid folder"
    if any((folder / name).exists() for name in (CONFIG, FINISHED, CHECKPOINTS)):
        return "run folder"
    return None


def check_output_folder(out: Path, command: str, *, run_place: str | None = None,
                        may_be_run: bool = False, may_be_grid: bool = False,
                        may_hold: bool = False) -> None:
    """Raise ``OutputFolderError`` (naming the folders) when ``command`` may not write ``out``.

    Refused: ``out`` is a file; ``out`` is a grid folder (unless ``may_be_grid``:
    ``multitask-grid`` resumes one) or a run folder (unless ``may_be_run``: training resumes
    one); ``out`` holds a run or grid folder anywhere below it (unless it is that grid, or ``may_hold``: tables written beside the
    grids they summarise); ``out`` lies inside a run folder, except below its folder
    ``run_place`` (``multitask-evaluate`` writes into ``RUN/evaluate``), or inside a grid's
    ``runs/`` (the grid's runs are ``multitask-grid``'s to train).

    Args:
        out: the output folder asked for (existing or not).
        command: the command's name, for the message.
        run_place: the one folder of a run where ``command`` writes its outputs, if any.
        may_be_run: ``out`` may itself be a run folder.
        may_be_grid: ``out`` may itself be a grid folder.
        may_hold: ``out`` may hold run and grid folders (``command`` writes only its own named
            files and folders into it).
    """
    out = Path(out)
    try:
        place = out.resolve()
    except RuntimeError:                      # Python < 3.13: a symbolic link loop
        raise OutputFolderError(f"{out}: a loop of symbolic links, not a folder (choose "
                                "another output folder)") from None
    if place.exists() and not place.is_dir():
        raise OutputFolderError(f"{out} is a file, not a folder; {command} writes a folder "
                                "(choose another output folder)")
    kind = folder_kind(place)
    if kind and not {"run folder": may_be_run, "grid folder": may_be_grid}[kind]:
        raise OutputFolderError(f"{out} is a {kind}; {command} does not write into it (choose "
                                "another output folder)")
    _check_enclosing(out, place, command, run_place)
    held = (_run_or_grid_below(place)
            if place.is_dir() and not may_hold and kind != "grid folder" else None)
    if held:
        raise OutputFolderError(f"{out} holds a {folder_kind(held)} ({held}); {command} does "
                                "not write over it (choose another output folder)")


def _check_enclosing(out: Path, place: Path, command: str, run_place: str | None) -> None:
    """Refuse ``place`` (``out`` resolved) inside a run folder, unless below the run's
    ``run_place``, or inside a grid's ``runs/``; the nearest enclosing run folder decides (a
    run's ``evaluate/`` is writable for ``multitask-evaluate`` in a grid's run too)."""
    for parent in place.parents:
        first = place.relative_to(parent).parts[0]
        kind = recorded_kind(parent)
        if kind == "run folder":
            if first != run_place:
                only = f" (only under its {run_place}/)" if run_place else ""
                raise OutputFolderError(f"{out} lies inside the run folder {parent}; {command} "
                                        f"does not write into a run{only} (choose another "
                                        "output folder)")
            return
        if kind == "grid folder" and first == GRID_RUNS:
            raise OutputFolderError(f"{out} lies among the runs of the grid folder {parent} "
                                    f"({GRID_RUNS}/), which only multitask-grid trains; {command} "
                                    "does not write there (choose another output folder)")


def recorded_kind(folder: Path) -> str | None:
    """``folder_kind`` of a folder above an output, known by its records, not their names: a
    grid's ``grid.json`` lists its ``runs``, a run's ``config.json`` or ``finished.json`` holds
    its ``settings_hash`` (so a project folder holding a config.json of its own is no run)."""
    if _holds_key(folder / GRID_RECORD, "runs"):
        return "grid folder"
    if any(_holds_key(folder / name, "settings_hash") for name in (CONFIG, FINISHED)):
        return "run folder"
    return None


def _holds_key(path: Path, key: str) -> bool:
    """Whether ``path`` is a JSON object with ``key`` (unreadable or absent: no)."""
    try:
        record = json.loads(read_regular(path).decode("utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return False
    return isinstance(record, dict) and key in record


def _run_or_grid_below(folder: Path) -> Path | None:
    """The first run or grid folder strictly below ``folder`` (``folders_below``)."""
    return next((path for path, _ in folders_below(folder)), None)


def folders_below(folder: Path) -> Iterator[tuple[Path, str]]:
    """``(path, kind)`` of the run and grid folders strictly below ``folder``, top down and in
    name order; neither they nor a SavedModel (whose ``assets.extra/`` holds a copy of its run's
    config.json) are entered, and symbolic links are not followed."""
    for root, dirs, files in os.walk(folder):
        if SAVED_MODEL in files:
            dirs.clear()
            continue
        dirs.sort()
        for name in list(dirs):
            kind = folder_kind(Path(root) / name)
            if kind:
                dirs.remove(name)
                yield Path(root) / name, kind


def check_new_output(out: Path, command: str, entries: frozenset[str], overwrite: bool,
                     run_place: str | None = None) -> None:
    """Check a folder ``command`` writes whole (``folder.staged_folder``) before any work:
    ``check_output_folder``; without ``overwrite`` an existing ``out`` must be empty
    (``FileExistsError``), with it an earlier output of ``command``: a folder holding only
    ``entries`` at its top (``OutputFolderError`` naming the first other entry)."""
    check_output_folder(out, command, run_place=run_place)
    out = Path(out)
    if out.is_symlink():
        raise OutputFolderError(f"{out} is a symbolic link; {command} writes its output folder "
                                "whole, in place of the link (choose another output folder)")
    if not overwrite:
        require_empty(out)
    elif out.is_dir():
        _check_replaceable(out, command, entries)


def _check_replaceable(target: Path, command: str, entries: frozenset[str]) -> None:
    foreign = sorted(p.name for p in Path(target).iterdir() if p.name not in entries)
    if foreign:
        raise OutputFolderError(f"{target} holds {foreign[0]!r}, which is not an output of "
                                f"{command}: --overwrite replaces only an earlier output of the "
                                "same command (choose another output folder)")
