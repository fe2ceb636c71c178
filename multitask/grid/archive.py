"""A grid's scores archive: its evidence, small enough to commit, carried from machine to machine.

An archive is itself a grid folder: the grid's record (``grid.json``) and, for every finished
run, the files that say what the run was and what it scored: ``config.json`` (its settings and
settings hash), ``metrics.json``, ``finished.json``, ``timing.json``, its loss logs
(``history.csv``, ``gradnorm.csv``) and ``test_predictions.json``, its predicted labels (and
regression outputs) of every test trial at its last evaluation point, compressed
(``kept_predictions``; a run whose archive holds it already is copied, not encoded again). It
leaves out what is heavy or holds the data's values: checkpoints (the weights), ``eval/`` (whose
predictions CSVs carry the release's labels), any other file of a run folder, ``train.log`` and
lock files. ``archive.json`` says where and when it was archived, each fold's test trials (their
names only, for the tables' captions) and, per annotation version, the per-fold scores of the
time-only progress model (``time_only``: derived numbers, ``multitask.models.time_baseline``),
computed from the grid's release (``data_dir``, else the one its spec records; when it cannot be
read, those of the archive the grid was copied from, else none, with a note). So

- ``multitask-tables paper ARCHIVE`` tabulates it like the grid, its time-only rows included,
  with the data absent or elsewhere; its example-trial figures need the trial's true labels,
  read from the data (``--data-dir``), and are left out, saying so, without them or in an archive
  written before predictions were kept;
- a grid continues from it on another machine: ``cp -r ARCHIVE NEW_FOLDER``, then the grid's
  command with ``--out NEW_FOLDER``; its finished runs count as finished, and every launch still
  checks each run's ``config.json`` against the spec (``record.prepare_grid``), so an
  archived run of other settings is never taken for one of the spec's.

An archive is written into a new or empty folder, or replaces a folder that holds nothing but an
archive of the same grid: its ``grid.json`` records the same spec (``folder.comparable_spec``),
and every run finished there is finished in the grid too (so that a grid recording a part of an
archived spec never thins out the archive). Anything else there (weights, predictions, tables, a
lock, another spec's archive, runs the grid lacks) stops it before any work, as does a
destination inside the grid or the grid inside it, or one inside any run folder or grid folder
(whose folders are theirs). An archive holds only each run's own regular files: a file or run
folder that is a symbolic link, or any other non-regular file, stops it, naming the path. The
archive is published whole (``rnn_seg.runs.publish.staged_folder``): at every instant the
destination holds the old archive or the new one.
"""
from __future__ import annotations

import os
import shutil
import stat
import sys
from pathlib import Path

import pandas as pd

from rnn_seg.runs.folder import (CONFIG, FINISHED, GRADNORM_LOG, HISTORY, RunFolderError,
                                 is_finished, read_json, write_json)
from rnn_seg.runs.outputs import recorded_kind
from rnn_seg.runs.provenance import now
from rnn_seg.runs.publish import claimed, staged_folder

from .folder import GRID_RECORD, comparable_spec, grid_release, read_record
from .kept_predictions import FILE as KEPT, kept_record, kept_trials
from .spec import RunKey

ARCHIVE_RECORD = "archive.json"
#: The files of a finished run an archive keeps; the first two must be there; the last it
#: writes from the run's predictions CSVs when the run does not hold it (``kept_predictions``).
RUN_FILES = (CONFIG, "metrics.json", FINISHED, "timing.json", HISTORY, GRADNORM_LOG, KEPT)
REQUIRED = RUN_FILES[:2]
#: Path parts of a run folder in a grid: runs/<annotations>/<direction>/<config>/seed<k>/<fold>.
RUN_DEPTH = len(RunKey("a", "d", "v", "w", 0, "f").path().parts)


def archive_grid(grid_dir: Path | str, dest: Path | str, data_dir: Path | str | None = None,
                 notes: bool = True) -> tuple[int, int]:
    """Write the scores archive of ``grid_dir`` to ``dest``, replacing an earlier archive there.

    The archive is written to a hidden folder beside ``dest`` and renamed into place once it is
    complete; a call that fails removes that folder again and leaves ``dest`` as it was.

    Args:
        grid_dir: a grid folder (``multitask-grid --out``) with its ``grid.json``.
        dest: a new or empty folder, or one holding only an archive's files.
        data_dir: the grid's release, for the time-only scores (None: where its spec records).
        notes: say on standard error when the time-only scores cannot be computed.

    Returns:
        ``(finished runs archived, runs the grid records)``.

    Raises:
        RunFolderError: ``grid_dir`` is no grid, a finished run lacks a required file, or
            ``dest`` may not be written (see the module docstring); each names the path.
    """
    source = Path(grid_dir).resolve()
    record = read_record(source)
    if record is None:
        raise RunFolderError(f"{source}: no {GRID_RECORD}: not a grid folder to archive")
    resolved = check_destination(source, dest, record)
    with claimed(resolved):                    # checked again, as no other process may change it
        check_destination(source, dest, record)
        finished = _finished_runs(source, record)
        with staged_folder(resolved, overwrite=True) as staging:
            _copy_file(source / GRID_RECORD, staging / GRID_RECORD, source)
            for run in finished:
                _copy_run(source, run, staging / run, resolved / run)
            time_only = _time_only(source, record, data_dir, notes)
            write_json(staging / ARCHIVE_RECORD, {
                "source": _origin(source), "archived": now(), "runs_finished": len(finished),
                "runs_recorded": len(record["runs"]), "run_files": list(RUN_FILES),
                "test_trials": _test_trials(source, record["runs"]),
                **({TIME_ONLY: time_only} if time_only else {})})
    return len(finished), len(record["runs"])


def _origin(source: Path) -> str:
    """The grid folder an archive's runs were trained in: ``source`` itself, or, when
    ``source`` is an archive (an archive of an archive), the folder that archive records."""
    path = source / ARCHIVE_RECORD
    earlier = read_json(path) if path.is_file() else {}
    origin = earlier.get("source") if isinstance(earlier, dict) else None
    return origin if isinstance(origin, str) and origin else str(source)


#: archive.json's entry of the time-only progress model's per-fold scores.
TIME_ONLY = "time_only"


def archived_time_only(grid_dir: Path | str, annotations: str) -> pd.DataFrame | None:
    """The time-only progress model's per-fold scores on ``annotations`` that the archive in
    ``grid_dir`` keeps (``time_baseline.fold_scores``' frame: ``fold``, ``progress_<metric>``),
    or None (no archive, or one that keeps none on them)."""
    path = Path(grid_dir) / ARCHIVE_RECORD
    record = read_json(path) if path.is_file() else {}
    kept = record.get(TIME_ONLY, {}).get(annotations) if isinstance(record, dict) else None
    return pd.DataFrame(kept) if isinstance(kept, list) and kept else None


def _time_only(source: Path, record: dict, data_dir: Path | str | None, notes: bool
               ) -> dict[str, list[dict]]:
    """Per annotation version of the grid's runs, the time-only model's per-fold scores
    (``{"revised": [{"fold": "B", "progress_accuracy": ...}, ...]}``), from the grid's release
    (``data_dir``, else its spec's); when it cannot be read, those the archive ``source`` was
    copied from keeps, else none, with a note unless ``notes`` is False. None for a grid of
    inner runs (``spec.inner_validation``): their folds are validation users, and the outer
    folds' users are scored by no one (results/tcn/PLAN_factors.md, section A)."""
    from ..models.time_baseline import release_fold_scores

    if (record.get("spec") or {}).get("inner_validation") is not None:
        return {}
    try:
        release = grid_release(record, data_dir)
        return {version: release_fold_scores(release, version).to_dict("records")
                for version in release.annotations}
    except (OSError, ValueError) as error:
        kept = {version: frame.to_dict("records") for version in
                sorted({Path(run).parts[1] for run in record["runs"]})
                if (frame := archived_time_only(source, version)) is not None}
        if not kept and notes:
            print(f"note: the archive keeps no time-only progress scores: the grid's data cannot "
                  f"be read ({error}); give it with --data-dir", file=sys.stderr)
        return kept


def archived_test_trials(grid_dir: Path | str) -> dict[str, list[str]]:
    """Each fold's test trials as the archive in ``grid_dir`` recorded them (``{}`` when it is
    no archive, or the copy of one, or its record has none)."""
    path = Path(grid_dir) / ARCHIVE_RECORD
    record = read_json(path) if path.is_file() else {}
    trials = record.get("test_trials") if isinstance(record, dict) else None
    return trials if isinstance(trials, dict) else {}


def check_destination(grid_dir: Path | str, dest: Path | str, record: dict | None = None
                      ) -> Path:
    """``dest`` resolved, once it is known that the archive of the grid ``grid_dir`` (whose
    record is ``record``, read unless given) may be written there (see the module docstring; a
    grid without its record yet has no finished runs); writes nothing.

    Raises:
        RunFolderError: naming ``dest`` and why not.
    """
    source, dest = Path(grid_dir).resolve(), Path(dest)
    if dest.is_symlink():
        raise RunFolderError(f"{dest}: a symbolic link; archive into a folder")
    resolved = dest.resolve()
    if resolved == source or source in resolved.parents or resolved in source.parents:
        raise RunFolderError(f"{dest}: the grid {source} and its archive must be separate "
                             "folders, neither inside the other")
    enclosing = next(((parent, kind) for parent in resolved.parents
                      if (kind := recorded_kind(parent))), None)
    if enclosing:
        raise RunFolderError(f"{dest}: lies inside the {enclosing[1]} {enclosing[0]}, whose "
                             "folders are its own; archive into a folder outside every run and "
                             "grid folder")
    if resolved.exists() and not resolved.is_dir():
        raise RunFolderError(f"{dest}: not a folder; archive a grid into a folder")
    foreign = _foreign_path(resolved) if resolved.is_dir() else None
    if foreign is not None:
        raise RunFolderError(f"{dest}: holds {foreign}, which no scores archive holds; nothing "
                             "written. Archive into a new folder.")
    record = read_record(source) if record is None else record
    _check_same_spec(dest, resolved, source, record)
    dropped = sorted(set(_archived_runs(resolved)) - set(_finished_runs(source, record)))
    if dropped:
        raise RunFolderError(
            f"{dest}: its archive holds {len(dropped)} finished run(s) that {source} does not "
            f"record as finished (first: {dropped[0]}); replacing it would lose them, so nothing "
            "is written. Archive into a new folder, or first give the grid a spec that records "
            "them (multitask-grid --spec ... --restart; their runs must be in the grid folder).")
    return resolved


def _check_same_spec(dest: Path, resolved: Path, source: Path, record: dict | None) -> None:
    """Refuse an archive in ``resolved`` whose grid.json records another spec than the grid's
    ``record`` (where the data lies and how the runs compute aside): another grid's evidence.
    A grid without its record yet (a dry run before its first launch) has nothing to compare."""
    if record is None or not (resolved / GRID_RECORD).exists():
        return
    theirs, ours = (comparable_spec(r.get("spec") or {})
                    for r in (read_record(resolved) or {}, record))
    if theirs != ours:
        changed = sorted(key for key in {*theirs, *ours} if theirs.get(key) != ours.get(key))
        raise RunFolderError(f"{dest}: holds the archive of another grid ({resolved / GRID_RECORD} "
                             f"records another spec than {source / GRID_RECORD}: "
                             f"{', '.join(changed)} differ); nothing written. Archive into a "
                             "new folder.")


def _finished_runs(grid: Path, record: dict | None = None) -> list[str]:
    """The runs the grid record of ``grid`` (read unless given; none without one) lists that
    are finished in ``grid``, as ``runs/<annotations>/<direction>/<config>/seed<k>/<fold>``."""
    record = read_record(grid) if record is None else record
    return [run for run in (record or {}).get("runs", []) if is_finished(grid / run)]


def _archived_runs(folder: Path) -> list[str]:
    """The finished runs of the archive in ``folder`` (none for a new folder), as a grid
    records them: ``runs/<annotations>/<direction>/<config>/seed<k>/<fold>``."""
    return [marker.parent.relative_to(folder).as_posix()
            for marker in folder.glob("runs/*/*/*/*/*/" + FINISHED)]


def _foreign_path(folder: Path) -> Path | None:
    """The first path in ``folder`` that an archive would not have written, or None."""
    for path in sorted(folder.rglob("*")):
        relative = path.relative_to(folder)
        if path.is_symlink():
            return relative
        if len(relative.parts) == 1 and relative.name in (GRID_RECORD, ARCHIVE_RECORD, "runs"):
            continue
        in_runs = relative.parts[0] == "runs"
        if in_runs and path.is_dir() and len(relative.parts) <= RUN_DEPTH:
            continue
        if in_runs and path.is_file() and len(relative.parts) == RUN_DEPTH + 1 \
                and path.name in RUN_FILES:
            continue
        return relative
    return None


def _copy_run(grid: Path, run: str, to: Path, earlier: Path) -> None:
    """The archived files of the finished run ``grid/run``, its kept predictions encoded from
    its CSVs unless the run holds them, or the archive it replaces (``earlier``) holds them for
    this very run (the same ``finished.json``); a missing required file is an error, as is a run
    folder that is (or lies behind) a symbolic link."""
    run_dir = grid / run
    if run_dir.resolve() != run_dir:
        raise RunFolderError(f"{run_dir}: a symbolic link (or behind one), not a folder of the "
                             f"grid {grid}; an archive holds only the grid's own runs")
    missing = [name for name in REQUIRED if not (run_dir / name).is_file()]
    if missing:
        raise RunFolderError(f"{run_dir}: finished but without {', '.join(missing)}; "
                             "nothing archived")
    to.mkdir(parents=True)
    for name in RUN_FILES:
        if (run_dir / name).exists() or (run_dir / name).is_symlink():
            _copy_file(run_dir / name, to / name, grid)
    if (to / KEPT).exists():
        return
    if _same_file(earlier / FINISHED, run_dir / FINISHED) and (earlier / KEPT).is_file():
        _copy_file(earlier / KEPT, to / KEPT, earlier.parents[RUN_DEPTH - 1])
    elif (kept := kept_record(run_dir)) is not None:
        write_json(to / KEPT, kept)


def _same_file(a: Path, b: Path) -> bool:
    """Whether the regular files ``a`` and ``b`` hold the same bytes (False if one is not)."""
    return a.is_file() and b.is_file() and a.read_bytes() == b.read_bytes()


def _copy_file(source: Path, to: Path, grid: Path) -> None:
    """Copy the regular file ``source`` of the grid ``grid`` to the new file ``to``; a symbolic
    link or any other non-regular file is a ``RunFolderError`` naming it; a failed write an
    ``OSError`` naming ``to``."""
    try:
        fd = os.open(source, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | os.O_NONBLOCK)
    except OSError as error:
        if source.is_symlink():
            raise RunFolderError(f"{source}: a symbolic link, not a file of the grid {grid}; an "
                                 "archive holds only the runs' own files") from None
        raise RunFolderError(f"{source}: unreadable ({error.strerror})") from None
    with os.fdopen(fd, "rb") as reader:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise RunFolderError(f"{source}: not a regular file; an archive holds only the "
                                 "runs' own files")
        os.set_blocking(fd, True)
        try:
            with open(to, "xb") as writer:
                shutil.copyfileobj(reader, writer)
        except OSError as error:           # named: the file written, not the one read
            raise OSError(error.errno, error.strerror, str(to)) from None


def _test_trials(root: Path, runs: list[str]) -> dict[str, list[str]]:
    """Each fold's test trials (names), from the predictions of the first of its runs that kept
    them, else from the archive ``root`` was copied from."""
    found: dict[str, list[str]] = {}
    for run in runs:
        fold = Path(run).name
        found[fold] = found.get(fold) or kept_trials(root / run)
    kept = {fold: names for fold, names in found.items() if names}
    return dict(sorted({**archived_test_trials(root), **kept}.items()))


