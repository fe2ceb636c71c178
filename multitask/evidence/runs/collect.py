"""Gather a grid's finished runs into tables: one row per run, per fold, per configuration.

Tables refuse incomplete evidence. Against the grid's own record of its runs (grid.json), every
recorded run must be finished, with a config.json that records the run its folder's place names
(``pooling.misplaced``; checked against the grid's spec too, ``checks``) and a ``metrics.json``
that agrees with itself and its run (``metrics_file``) whose metrics are finite (NaN is
allowed only for a per-class score, ``<task>_<kind>_<class>`` with a kind of ``PER_CLASS``: the
class is absent from that fold's test trials, or never predicted), and every folder under ``runs/``
must be a recorded run (a stray copy such as ``C.old`` is not a fold). The runs of one
configuration must agree on every setting that changes a result (``pooling.pool``), or no table
is written at all (``pooling.MixedSettings``). Otherwise
``IncompleteEvidence`` names every problem; with ``allow_incomplete`` the problems are returned
instead and the configurations they touch are marked incomplete (``completeness``), never silently
averaged over fewer runs. For a grid still running, ``finished_only`` leaves out whole
configurations with an unfinished run (and says which); ``seeds`` restricts the evidence to some
seeds' runs.

Metric columns are ``<task>_<metric>``: ``gesture_accuracy``, ``gesture_edit``, ``gesture_f1@10``,
``gesture_accuracy_G1`` ... (and, for runs finished since they were saved, ``gesture_precision_G1``,
``gesture_recall_G1``, ``gesture_f1_G1`` ...), ``progress_accuracy``, ``progress_edit``,
``progress_f1@10``, ``progress_mae`` (normalised MAE of the regression output rounded to the nearest
stage and clipped, in % of the stage range: the 4-stage span for Suturing, the paper's metric) and
``progress_mae_raw`` (the same of the raw output). Each run's value is the mean over its evaluation
points. Each run also has ``convergence``, ``converged``, ``loss_drop`` and ``loss_drop_se``
(``rnn_seg.convergence``: the three-way verdict converged / undecided / still falling from every
task's 95 % interval, the point verdict, the relative fall of its worst task's training loss over
the last 10 % of its schedule, and that estimate's standard error; runs finished before the standard
error or the three-way verdict was saved get them from their ``history.csv`` and their saved
``loss_drop``).
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, fields
from pathlib import Path

import numpy as np
import pandas as pd

from jigsaws_tools.files import resolved
from jigsaws_tools.task_definition import PAPER_TASK
from rnn_seg.convergence import ConvergenceCriterion, history_convergence, verdict
from rnn_seg.runs.folder import HISTORY, RunFolderError, is_finished, read_json
from rnn_seg.runs.logs import read_log

from ...grid.folder import GRID_RECORD, record_runs, run_key
from ...grid.spec import RunKey
from ...models.run_record import RunRecord, read_run_record
from .checks import OTHER_SETTINGS, other_settings
from .metrics_file import METRICS_FILE, read_metrics
from .pooling import misplaced, pool, record_key

KEY_COLUMNS = [f.name for f in fields(RunKey)]
CONFIG_COLUMNS = ["annotations", "direction", "variant", "weighting"]
#: The paper's metrics, in its table order.
METRICS = ["gesture_accuracy", "gesture_edit", "gesture_f1@10", "progress_mae",
           "progress_mae_raw", "progress_accuracy", "progress_edit", "progress_f1@10"]
LOWER_IS_BETTER = {"progress_mae", "progress_mae_raw"}
_RENAME = {"mae_normalised_rounded": "mae", "mae_normalised": "mae_raw"}
#: First words of the problem line of a grid's run folder whose config.json records another run.
MISPLACED = "a run of another configuration, seed or fold than its folder's:"
#: How a line of ``run_rows``' problems that names a configuration left out starts.
LEFT_OUT = "left out:"
#: Per-class scores: ``<kind>_<class>`` in metrics.json (``rnn_seg.tasks.task_metrics``).
PER_CLASS = ("accuracy", "precision", "recall", "f1")
#: Per-run columns that are not metrics (not averaged over seeds).
CONVERGENCE_COLUMNS = ["convergence", "converged", "loss_drop", "loss_drop_se"]
#: Per fold and configuration: how many runs have each three-way verdict but "converged".
CONVERGENCE_COUNTS = {"still_falling": "still falling", "undecided": "undecided"}


def key_from_path(run_dir: Path, root: Path) -> RunKey:
    """Inverse of ``RunKey.path``:
    ``runs/<annotations>/<direction>/<variant>-<weighting>/seed<k>/<fold>`` (``run_key``)."""
    return run_key(Path(run_dir).relative_to(root).as_posix())


class IncompleteEvidence(ValueError):
    """A grid's runs do not support complete tables; the message names every problem."""


def run_rows(grid_dir: Path | str, allow_incomplete: bool = False,
             seeds: tuple[int, ...] | None = None, finished_only: bool = False
             ) -> tuple[pd.DataFrame, list[str]]:
    """One row per usable run (key columns + metrics), and the problems found (see the module
    docstring): ``IncompleteEvidence`` unless ``allow_incomplete``. ``run_records`` with the
    same arguments also returns each run's record."""
    rows, problems, _ = run_records(grid_dir, allow_incomplete, seeds, finished_only)
    return rows, problems


def refuse_repeated(folders: Iterable[Path | str], why: str,
                    error: type[ValueError] = ValueError) -> None:
    """An ``error`` naming the first of ``folders`` (paths as given) that is another's folder,
    however spelled (resolved: links, ``..``, relative), and saying ``why`` each counts once; or
    naming one in a loop of symbolic links."""
    seen: dict[Path, Path] = {}
    for folder in map(Path, folders):
        place = resolved(folder, error)
        if place in seen:
            spelled = f" (as {seen[place]})" if str(seen[place]) != str(folder) else ""
            raise error(f"{folder}: given twice{spelled}; {why}")
        seen[place] = folder


def run_records(grid_dir: Path | str, allow_incomplete: bool = False,
                seeds: tuple[int, ...] | None = None, finished_only: bool = False,
                varying: tuple[str, ...] = ()
                ) -> tuple[pd.DataFrame, list[str], dict[Path, RunRecord]]:
    """``run_rows``' rows and problems, and the record (config.json) of each run in the rows,
    keyed by the run's folder (``grid_dir / run``).

    Args:
        grid_dir: output folder of ``multitask-grid``.
        allow_incomplete: return the usable runs and the problems instead of refusing.
        seeds: only the recorded runs of these seeds (None: every recorded run).
        finished_only: leave out every configuration with a run not (yet) finished, instead of
            counting that run a problem; a line per configuration left out, starting with
            ``LEFT_OUT``, is added to the returned problems. For a grid still running: tables of
            its finished part.
        varying: settings the runs of one configuration may differ in (``pooling.pool``).
    """
    root = Path(grid_dir)
    every_run, problems = recorded_runs(root)
    problems += [f"stray folder, not a run of this grid: {path}"
                 for path in _stray_folders(root, every_run)]
    recorded = of_seeds(root, every_run, seeds)
    mismatched = other_settings(root, {run: key_from_path(root / run, root) for run in recorded})
    problems += [f"{OTHER_SETTINGS} {root / run}: {details}" for run, details in mismatched.items()]
    unfinished = _unfinished_configs(root, recorded) if finished_only else {}
    left_out = [f"{LEFT_OUT} {_config_label(config)}, {done} of {total} runs finished"
                for config, (done, total) in sorted(unfinished.items())]
    left_out += [f"{LEFT_OUT} {_config_label(config)}, no run of seed(s) "
                 f"{', '.join(map(str, seeds))}" for config in _configs_without(root, every_run,
                                                                               recorded)]
    rows, records = [], {}
    for run in recorded:
        if run in mismatched or _config_of(key_from_path(root / run, root)) in unfinished:
            continue
        found = run_row(root, run, problems)
        if found is not None:
            rows.append(found[0])
            records[run] = found[1]
    pool(records, root, varying)
    if problems and not allow_incomplete:
        raise IncompleteEvidence(
            f"{root}: incomplete evidence, no tables written:\n  " + "\n  ".join(problems)
            + "\nFinish the runs (re-run multitask-grid), remove stray folders, or pass "
              "--allow-incomplete to mark the configurations concerned incomplete.")
    if not rows:
        which = "" if seeds is None else f" of seed(s) {', '.join(map(str, seeds))}"
        none = (f"no configuration{which} has finished all its runs (each enters only once "
                "complete)" if unfinished and not problems
                else f"no finished runs{which} under {root / 'runs'}")
        raise IncompleteEvidence(f"{root}: {none}" + "".join(f"\n  {line}" for line in left_out))
    return pd.DataFrame(rows), problems + left_out, {root / run: record
                                                     for run, record in records.items()}


def recorded_runs(root: Path) -> tuple[list[Path], list[str]]:
    """The run folders (relative to ``root``) grid.json records, and problems: without a record,
    the folders found that look like runs, and a problem saying so. A record that cannot be read
    is a ``RunFolderError`` naming it."""
    runs = record_runs(root)
    if runs is not None:
        return [Path(run) for run in runs], []
    found = [p.relative_to(root) for p in sorted((root / "runs").glob("*/*/*/seed*/*"))
             if p.is_dir()]
    return found, [f"{root / GRID_RECORD} missing: which runs the grid should have is unknown"]


def of_seeds(root: Path, runs: list[Path], seeds: tuple[int, ...] | None) -> list[Path]:
    """The ``runs`` (relative to ``root``) of ``seeds``; all of them when ``seeds`` is None."""
    if seeds is None:
        return runs
    return [run for run in runs if key_from_path(root / run, root).seed in seeds]


def _config_of(key: RunKey) -> tuple[str, ...]:
    """``key``'s configuration: its ``CONFIG_COLUMNS`` values."""
    return tuple(getattr(key, column) for column in CONFIG_COLUMNS)


def _config_label(config: tuple[str, ...]) -> str:
    """``revised/bidirectional/APc-fixed``: a configuration's ``CONFIG_COLUMNS`` values."""
    return f"{'/'.join(config[:2])}/{'-'.join(config[2:])}"


def _configs_without(root: Path, every_run: list[Path], chosen: list[Path]) -> list[tuple]:
    """The configurations of ``every_run`` with no run among ``chosen`` (e.g. none of the
    requested seeds), sorted."""
    def configs(runs: list[Path]) -> set[tuple]:
        return {_config_of(key_from_path(root / run, root)) for run in runs}
    return sorted(configs(every_run) - configs(chosen))


def _unfinished_configs(root: Path, recorded: list[Path]) -> dict[tuple, tuple[int, int]]:
    """Configurations with a recorded run not finished: ``{config: (finished, recorded)}``."""
    counts: dict[tuple, list[int]] = {}
    for run in recorded:
        count = counts.setdefault(_config_of(key_from_path(root / run, root)), [0, 0])
        count[0] += is_finished(root / run)
        count[1] += 1
    return {config: (done, total) for config, (done, total) in counts.items() if done < total}


def expected_runs(root: Path | str, recorded: list[Path]) -> pd.DataFrame:
    """Key columns of the runs ``recorded`` (the grid's record), for ``completeness``."""
    return pd.DataFrame([asdict(key_from_path(Path(root) / run, Path(root))) for run in recorded],
                        columns=KEY_COLUMNS)


def completeness(runs: pd.DataFrame, expected: pd.DataFrame) -> pd.DataFrame:
    """Per configuration: ``runs`` usable, ``runs_expected`` by the record, and ``complete``."""
    usable = runs.groupby(CONFIG_COLUMNS).size().rename("runs")
    wanted = expected.groupby(CONFIG_COLUMNS).size().rename("runs_expected")
    table = pd.concat([usable, wanted], axis=1).fillna(0).astype(int).reset_index()
    table["complete"] = table["runs"] == table["runs_expected"]
    return table


def run_row(root: Path, run: Path, problems: list[str]) -> tuple[dict, RunRecord] | None:
    """Key columns and mean metrics of the finished run ``root / run`` of a grid, and its
    record; None (and a problem) when it is missing, unfinished, unreadable, has a NaN metric or
    its config.json records another run than its place (``pooling.misplaced``)."""
    run_dir = root / run
    record = finished_record(run_dir, problems)
    if record is None:
        return None
    wrong = misplaced(record, key_from_path(run_dir, root))
    if wrong:
        problems.append(f"{MISPLACED} {run_dir}: its config.json records {wrong}")
        return None
    metrics = run_metrics(run_dir, record, problems)
    return None if metrics is None else ({**asdict(record_key(record)), **metrics}, record)


def finished_record(run_dir: Path, problems: list[str]) -> RunRecord | None:
    """The checked config.json of the finished run ``run_dir``; None (and a problem appended to
    ``problems``) when it is missing, unfinished or its config.json cannot be used."""
    if not is_finished(run_dir):
        problems.append(f"not finished: {run_dir}")
        return None
    try:
        return read_run_record(run_dir)
    except RunFolderError as error:
        problems.append(f"unreadable configuration: {error}")
        return None


def run_metrics(run_dir: Path, record: RunRecord, problems: list[str]) -> dict | None:
    """The convergence columns and mean metrics (``<task>_<metric>``) of the finished run
    ``run_dir`` of config.json ``record``; None (and a problem appended to ``problems``) when
    its metrics.json cannot be used (``metrics_file``) or has a NaN metric."""
    path = run_dir / METRICS_FILE
    try:
        metrics = read_metrics(run_dir, record)
    except RunFolderError as error:
        problems.append(f"unreadable metrics: {error}")
        return None
    convergence = _convergence(run_dir, metrics.get("convergence") or {})
    row = dict(convergence=convergence.get("verdict"), converged=convergence.get("converged"),
               loss_drop=convergence.get("max_loss_drop"),
               loss_drop_se=convergence.get("max_loss_drop_se"))
    for task, values in metrics["mean"].items():
        for name, value in values.items():
            value = math.nan if value is None else value
            if math.isnan(value) and not per_class(name):
                problems.append(f"{task}_{name} is {value!r}, not a number: {path}")
                return None
            row[f"{task}_{_RENAME.get(name, name)}"] = value
    return row


def _convergence(run_dir: Path, saved: dict) -> dict:
    """The run's saved diagnostic. One saved before ``max_loss_drop_se`` existed gets the standard
    error from its loss history and the saved criterion; its saved point verdict and
    ``loss_drop`` are kept. One saved before the three-way ``verdict`` existed gets it from its
    tasks' ``loss_drop`` and standard errors. A history that cannot give the standard error leaves
    it and the three-way verdict unknown (absent)."""
    drops = saved.get("loss_drop") or {}
    if not drops or None in drops.values():
        return saved
    criterion = ConvergenceCriterion(**saved.get("criterion", {}))
    if "max_loss_drop_se" not in saved:
        try:
            total = read_json(run_dir / "config.json")["run"]["optim"]["total"]
            recomputed = history_convergence(read_log(run_dir / HISTORY), list(drops),
                                             total, criterion)
        except (RunFolderError, KeyError, TypeError, OSError, ValueError):
            return saved
        worst = max(drops, key=drops.get)
        saved = {**saved, "loss_drop_se": recomputed["loss_drop_se"],
                 "max_loss_drop_se": recomputed["loss_drop_se"][worst]}
    errors = saved.get("loss_drop_se") or {}
    if "verdict" in saved or set(errors) != set(drops) or None in errors.values():
        return saved
    return {**saved, "verdict": verdict([(drops[t], errors[t]) for t in drops],
                                        criterion.tolerance)}


def per_class(metric: str) -> bool:
    """Whether ``metric`` (without its task, e.g. ``precision_G2``) is a per-class score (NaN
    when the class is absent or, for precision, never predicted)."""
    kind, _, name = metric.partition("_")
    return kind in PER_CLASS and bool(name) and metric != "accuracy_pooled"


def _stray_folders(root: Path, recorded: list[Path]) -> list[Path]:
    """Folders under ``root/runs`` that are neither a recorded run nor on the way to one."""
    runs = set(recorded)
    ancestors = {parent for run in recorded for parent in run.parents}
    stray, todo = [], [root / "runs"] if (root / "runs").is_dir() else []
    while todo:
        for child in sorted(p for p in todo.pop().iterdir() if p.is_dir()):
            relative = child.relative_to(root)
            if relative in ancestors:
                todo.append(child)
            elif relative not in runs:
                stray.append(child)
    return sorted(stray)


def grid_task_name(grid_dir: Path | str) -> str:
    """The task a grid's runs were trained on (the config.json of its first recorded run that has
    a readable one); runs written before tasks existed are Suturing's."""
    root = Path(grid_dir)
    recorded = record_runs(root)
    runs = ([root / run for run in recorded] if recorded is not None
            else [config.parent for config in sorted(root.glob("runs/*/*/*/seed*/*/config.json"))])
    for run in runs:
        try:
            return read_run_record(run).config.data.task.name
        except RunFolderError:          # not trained yet, or refused by the tables already
            continue
    return PAPER_TASK


def per_fold(runs: pd.DataFrame) -> pd.DataFrame:
    """Mean over seeds for every configuration and fold (the numbers the tables summarise), with
    ``seeds``, ``still_falling`` and ``undecided`` (runs of that three-way convergence verdict)
    per fold."""
    metric_cols = [c for c in runs.columns if c not in KEY_COLUMNS + CONVERGENCE_COLUMNS]
    grouped = runs.groupby(CONFIG_COLUMNS + ["fold"], sort=True)
    table = grouped[metric_cols].mean()
    keys = [runs[c] for c in CONFIG_COLUMNS + ["fold"]]
    for column, state in reversed(CONVERGENCE_COUNTS.items()):
        table.insert(0, column, runs["convergence"].eq(state).groupby(keys).sum().astype(int))
    table.insert(0, "seeds", grouped.size())
    return table.reset_index()


def summary(folds: pd.DataFrame) -> pd.DataFrame:
    """Mean and sample standard deviation over folds: columns ``<metric>_mean``, ``<metric>_std``,
    plus ``folds`` (how many folds each configuration has), ``still_falling`` and ``undecided``
    (its runs of that three-way convergence verdict)."""
    counts = ["fold", "seeds", *CONVERGENCE_COUNTS]
    metric_cols = [c for c in folds.columns if c not in CONFIG_COLUMNS + counts]
    grouped = folds.groupby(CONFIG_COLUMNS, sort=True)
    mean = grouped[metric_cols].mean().add_suffix("_mean")
    std = grouped[metric_cols].std(ddof=1).add_suffix("_std")
    table = pd.concat([mean, std], axis=1)
    for column in reversed(CONVERGENCE_COUNTS):
        table.insert(0, column, grouped[column].sum())
    table.insert(0, "folds", grouped.size())
    return table.reset_index()


def lookup(summary_table: pd.DataFrame, annotations: str, direction: str, config: str
           ) -> pd.Series | None:
    """The summary row of one configuration, or None if the grid did not run it.

    Args:
        summary_table: one row per configuration (``summary``).
        annotations: the annotation version, ``"revised"`` or ``"original"``.
        direction: the encoder's, ``"bidirectional"`` or ``"forward"``.
        config: ``<variant>-<weighting>``, e.g. ``"APc-gradnorm"``.
    """
    variant, weighting = config.rsplit("-", 1)
    rows = summary_table[(summary_table.annotations == annotations)
                         & (summary_table.direction == direction)
                         & (summary_table.variant == variant)
                         & (summary_table.weighting == weighting)]
    return rows.iloc[0] if len(rows) else None


def finite(value) -> float | None:
    """``value`` as a float, or None for missing / NaN."""
    if value is None:
        return None
    value = float(value)
    return None if np.isnan(value) else value
