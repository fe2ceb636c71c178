"""A method scored elsewhere beside archived baselines, paired by fold (``multitask-tables
score``).

The method's per-fold scores (``runs.method``: one prediction folder per seed) become one side of
a contrast whose other side is a configuration of a grid or scores archive (``Baseline``: e.g.
``A-fixed`` of ``results/grid``, ``A-fixed`` of ``results/tcn/ms-tcn``), on the method's labels,
bidirectional. Each comparison is ``method - baseline`` per fold, each side the mean over its
seeds within the fold, tested as ``claims.csv`` tests a claim (``paired.paired_sides``: exact
two-sided sign-flip test over the folds both sides have, the 95 % interval that inverts it);
Holm's correction runs over every comparison of the call (baselines x metrics). Verdict at the
adjusted p: ``<method> above`` / ``<method> below`` (p <= alpha), else ``no difference
detected``; when the comparisons are too many for the folds' smallest p to pass Holm at alpha
(``claims.smallest_adjusted_p``) the caption says that no other verdict is possible. Baselines of
one name (model A of two LSTM-128 grids) are named apart by their grids.

A grid is compared only when its runs were tested on the method's trials: per fold both must
name the same trials (a grid records them in its kept predictions or its archive's
``archive.json``), else the grid is refused (another release, task or subset); and only when its
runs were scored at the samples the method is scored at (5 Hz: a 3 Hz ED-TCN grid is refused).

Files (``write_method``): ``score_folds.csv`` (the method's scores per seed and fold),
``score_summary.csv`` (per metric, mean and sd over folds of the per-fold seed means) and, with
baselines, ``score.csv`` (one row per comparison: ``COLUMNS``), ``score.tex`` and ``score.md``
(the comparisons under a caption naming seeds, folds and labels).
"""
from __future__ import annotations

import sys
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from rnn_seg.runs.folder import write_atomic
from rnn_seg.runs.outputs import GRID_RECORD

from ...grid.archive import archived_test_trials
from ...grid.kept_predictions import kept_trials
from ..render.latex import escape, number, requires
from ..render.markdown import markdown_table
from ..runs.collect import run_records
from ..runs.pooling import architecture, architecture_name
from ..statistics.paired import (ConfigId, NotPaired, StatsConfig, config_labels, fold_values,
                                 holm, paired_sides, seed_values)
from .claims import smallest_adjusted_p

#: The configurations a grid named without any is compared by: these variants' (any weighting).
DEFAULT_VARIANTS = ("A", "APc", "APoc")
#: The metrics compared by default.
METRICS = ("gesture_accuracy", "gesture_edit", "gesture_f1@10")
#: The columns of ``score.csv``.
COLUMNS = ["method", "baseline", "grid", "metric", "folds", "method_seeds", "baseline_seeds",
           "method_mean", "baseline_mean", "diff", "ci_low", "ci_high", "p_value", "p_holm",
           "verdict"]


@dataclass(frozen=True)
class Baseline:
    """A configuration of a grid (or scores archive) the method is compared with; ``name``:
    its architecture and configuration, e.g. ``MS-TCN A-fixed``."""

    grid: Path
    config: ConfigId
    name: str


def parse_against(text: str, annotations: str) -> tuple[Path, list[ConfigId]]:
    """``GRID[:CONFIG[,CONFIG...]]`` -> the grid and its configurations on ``annotations``
    labels (none named: ``[]``, the defaults); a configuration of other labels is refused."""
    grid, _, names = text.partition(":")
    configs = []
    for name in filter(None, names.split(",")):
        config = ConfigId.parse(name if "/" in name else f"{annotations}/{name}")
        if config.annotations != annotations:
            raise ValueError(f"--against {text}: {name} is on {config.annotations} labels, the "
                             f"predictions are scored on {annotations} labels (--annotations)")
        configs.append(config)
    return Path(grid), configs


def read_baselines(against: Sequence[tuple[Path, list[ConfigId]]], annotations: str,
                   trials: dict[str, list[str]], sample_hz: float
                   ) -> tuple[list[Baseline], pd.DataFrame]:
    """The baselines of ``against`` (``parse_against``' pairs) and their runs (one table, a
    ``grid`` column naming each run's grid), every grid's runs checked (``collect.run_records``),
    tested on ``trials`` (fold -> the method's trials) and scored at the method's samples
    (``sample_hz``, the rate its predictions are scored at: 5 Hz)."""
    chosen, tables = [], []
    for grid, configs in against:
        _check_grid(grid)
        runs, _, records = run_records(grid)
        _check_trials(grid, records, trials)
        _check_rate(grid, records, sample_hz)
        kinds = sorted({architecture(record) for record in records.values()})
        kind = architecture_name(kinds[0]) if len(kinds) == 1 else grid.name
        configs = configs or [c for c in map(ConfigId.parse, config_labels(runs))
                              if c.variant in DEFAULT_VARIANTS and c.annotations == annotations
                              and c.direction == "bidirectional"]
        if not configs:
            raise ValueError(f"{grid}: none of {', '.join(DEFAULT_VARIANTS)} on {annotations} "
                             f"labels; it holds {', '.join(config_labels(runs))} (name them: "
                             f"{grid}:CONFIG,...)")
        for config in configs:
            config = ConfigId(config.variant, config.weighting, annotations, config.direction)
            if config.select(runs).empty:
                raise ValueError(f"{grid}: no run of {config.label}; it holds "
                                 f"{', '.join(config_labels(runs))}")
            if any(b.grid.resolve() == grid.resolve() and b.config == config for b in chosen):
                raise ValueError(f"--against {grid}: {config.label} named twice (each baseline "
                                 "once: Holm counts every comparison)")
            chosen.append(Baseline(grid, config, f"{kind} {config.label}"))
        tables.append(runs.assign(grid=str(grid)))
    runs = pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()
    return _named_apart(chosen), runs


def _named_apart(baselines: list[Baseline]) -> list[Baseline]:
    """``baselines``, a name that two of them share followed by its grid (``LSTM-128 A-fixed
    (results/reference/grid)`` beside ``LSTM-128 A-fixed (results/grid)``), so that a table's rows
    and caption tell them apart."""
    shared = Counter(b.name for b in baselines)
    return [replace(b, name=f"{b.name} ({b.grid})") if shared[b.name] > 1 else b
            for b in baselines]


def _check_grid(grid: Path) -> None:
    """A ``ValueError`` when ``grid`` is no grid folder or scores archive (no ``grid.json``),
    naming its ``grid/`` subfolder when that is one (``results/reference`` for
    ``results/reference/grid``)."""
    if not grid.is_dir():
        raise ValueError(f"--against {grid}: no such folder (a grid folder or scores archive)")
    if not (grid / GRID_RECORD).is_file():
        inner = grid / "grid"
        hint = f"; {inner} is one" if (inner / GRID_RECORD).is_file() else ""
        raise ValueError(f"--against {grid}: not a grid folder or scores archive (no "
                         f"{GRID_RECORD}){hint}")


def _check_trials(grid: Path, records: dict, trials: dict[str, list[str]]) -> None:
    """A ``ValueError`` when a fold of ``grid`` was tested on other trials than ``trials``'."""
    tested = archived_test_trials(grid)
    for run in records:
        tested.setdefault(Path(run).name, kept_trials(run))
    for fold, names in sorted(tested.items()):
        if names and fold in trials and sorted(names) != sorted(trials[fold]):
            raise ValueError(f"{grid}: fold {fold} was tested on {', '.join(sorted(names))}, the "
                             f"predictions are scored on {', '.join(trials[fold])}: another "
                             "release or task (--data-dir, --task)")


def _check_rate(grid: Path, records: dict, sample_hz: float) -> None:
    """A ``ValueError`` when a run of ``grid`` was scored at other samples than ``sample_hz``
    (its model's rate: a 3 Hz ED-TCN's scores are not the 5 Hz samples' the method gets)."""
    for run, record in sorted(records.items()):
        rate = record.config.data.preprocessing.sample_hz
        if abs(rate - sample_hz) > 1e-9 * sample_hz:
            raise ValueError(f"--against {grid}: its run {run} was scored at its {rate:g} Hz "
                             f"samples, the predictions are scored at {sample_hz:g} Hz; pair "
                             f"with grids of {sample_hz:g} Hz models")


def compare(scores: pd.DataFrame, name: str, baselines: Sequence[Baseline],
            runs: pd.DataFrame, metrics: Sequence[str],
            config: StatsConfig = StatsConfig()) -> pd.DataFrame:
    """One row per baseline and metric (``COLUMNS``): ``name - baseline`` paired by fold.

    Args:
        scores: the method's rows (``seed``, ``fold``, metrics; ``runs.method.method_scores``).
        name: the method's name in the table.
        baselines: what it is compared with.
        runs: the baselines' runs (``read_baselines``).
        metrics: the metric columns compared; a baseline without one (model A has no progress
            scores) is left out of that metric's rows, with a note.
        config: the test's level.
    """
    rows = []
    for metric in metrics:
        mine = fold_values(scores, metric, name)
        for baseline in baselines:
            try:
                theirs = seed_values(runs[runs.grid == str(baseline.grid)], baseline.config,
                                     metric)
            except NotPaired as error:
                print(f"note: {error}: not compared on {metric}", file=sys.stderr)
                continue
            result = paired_sides(f"{name} - {baseline.name}", metric,
                                  {name: (1, mine), baseline.name: (-1, theirs)}, config)
            rows.append({
                "method": name, "baseline": baseline.name, "grid": str(baseline.grid),
                "metric": metric, "folds": " ".join(result.folds),
                "method_seeds": len(scores.seed.unique()),
                "baseline_seeds": _seeds(runs, baseline),
                "method_mean": float(np.mean([mine[f].mean() for f in result.folds])),
                "baseline_mean": float(np.mean([theirs[f].mean() for f in result.folds])),
                "diff": result.mean, "ci_low": result.ci_low, "ci_high": result.ci_high,
                "p_value": result.p_value})
    table = pd.DataFrame(rows, columns=COLUMNS)
    table["p_holm"] = holm(table.p_value.to_numpy(float))
    table["verdict"] = [f"{name} {'above' if d > 0 else 'below'}" if p <= config.alpha
                        else "no difference detected" for d, p in zip(table["diff"],
                                                                      table.p_holm)]
    return table


def _seeds(runs: pd.DataFrame, baseline: Baseline) -> int:
    return len(baseline.config.select(runs[runs.grid == str(baseline.grid)]).seed.unique())


def summary(scores: pd.DataFrame, metrics: Sequence[str]) -> pd.DataFrame:
    """Per metric the mean and sd over folds of the method's per-fold seed means."""
    folds = scores.groupby("fold")[list(metrics)].mean()
    return pd.DataFrame({"metric": list(metrics), "mean": folds.mean().to_numpy(),
                         "sd": folds.std(ddof=1).to_numpy(), "folds": len(folds),
                         "seeds": len(scores.seed.unique())})


def summary_markdown(scores: pd.DataFrame, metrics: Sequence[str], name: str,
                     annotations: str, task: str) -> str:
    """``summary`` as Markdown under a line naming the method, task, labels, folds and seeds:
    what ``score`` prints without baselines."""
    table = summary(scores, metrics)
    lines = markdown_table(["Metric", "Mean", "SD over folds"],
                           [[row.metric, f"{row.mean:.2f}", f"{row.sd:.2f}"]
                            for row in table.itertuples(index=False)])
    head = (f"{name} on {task}, {annotations} labels: mean and sample SD over "
            f"{table.folds.iloc[0]} leave-one-user-out folds of the per-fold mean over "
            f"{table.seeds.iloc[0]} seed(s).")
    return "\n".join([head, "", *lines]) + "\n"


def caption(table: pd.DataFrame, name: str, annotations: str, task: str,
            config: StatsConfig = StatsConfig()) -> str:
    """What the comparison table says, its seeds, folds and labels."""
    folds = sorted({f for row in table.folds for f in row.split()})
    seeds = "; ".join(f"{b} {n}" for b, n in
                      table[["baseline", "baseline_seeds"]].drop_duplicates().itertuples(
                          index=False))
    return (f"{name} against archived baselines on {task}, {annotations} labels, "
            f"leave-one-user-out over {len(folds)} folds ({', '.join(folds)}); seeds: {name} "
            f"{table.method_seeds.iloc[0]}; {seeds}. A baseline run scores as archived: the mean "
            f"over its evaluation points. Per fold each side is the mean over its "
            f"seeds; diff = {name} - baseline (points; lower is better for MAE), its "
            f"{config.confidence:.0%} interval and p from the exact sign-flip test over the "
            f"folds (as claims.csv), p Holm-adjusted over the {len(table)} comparisons."
            f"{_unreachable(table, config)}")


def _unreachable(table: pd.DataFrame, config: StatsConfig) -> str:
    """A sentence saying that no verdict but "no difference detected" is possible when the
    smallest adjusted p the comparisons can reach (``claims.smallest_adjusted_p``, at the most
    folds any row has) is above the level; else ``""``."""
    folds = max((len(row.split()) for row in table.folds), default=0)
    floor = smallest_adjusted_p(len(table), folds)
    if floor <= config.alpha:
        return ""
    return (f" With {folds} folds no p Holm-adjusted over {len(table)} comparisons can fall "
            f"below {floor:.3f}: every verdict is 'no difference detected' whatever the data "
            f"(at most {_reachable(folds, config)} comparisons can reach p <= "
            f"{config.alpha:g}: name fewer baselines or --metrics).")


def _reachable(folds: int, config: StatsConfig) -> int:
    """The most comparisons whose Holm-adjusted p can reach the level over ``folds`` folds."""
    return int(config.alpha * 2 ** folds / 2 + 1e-9)


def _cells(row, fmt) -> list[str]:
    """A comparison's cells, numbers written by ``fmt(value, signed)``."""
    return [row.baseline, row.metric, fmt(row.method_mean, False), fmt(row.baseline_mean, False),
            f"{fmt(row.diff, True)} [{fmt(row.ci_low, True)}, {fmt(row.ci_high, True)}]",
            f"{row.p_value:.4f}", f"{row.p_holm:.4f}", row.verdict]


HEADER = ["Baseline", "Metric", "Method", "Baseline score", "Diff [95% CI]", "p", "p (Holm)",
          "Verdict"]


def comparison_markdown(table: pd.DataFrame, caption_text: str) -> str:
    """``table`` as Markdown under its caption."""
    lines = markdown_table(HEADER, [_cells(row, lambda v, s: f"{v:+.2f}" if s else f"{v:.2f}")
                                    for row in table.itertuples(index=False)])
    return "\n".join([caption_text, "", *lines]) + "\n"


def comparison_latex(table: pd.DataFrame, caption_text: str) -> str:
    """``table`` as a booktabs table under its caption."""
    body = [" & ".join(escape(c) if i in (0, 1, 7) else c for i, c in enumerate(
        _cells(row, lambda v, s: number(v, 2, s)))) + r" \\"
        for row in table.itertuples(index=False)]
    return "".join([requires("booktabs"), "\\begin{table}[t]\n\\centering\\small\n",
                    f"\\caption{{{escape(caption_text)}}}\n",
                    "\\begin{tabular}{llrrlrrl}\n\\toprule\n",
                    " & ".join(escape(h) for h in HEADER), r" \\", "\n\\midrule\n",
                    "\n".join(body), "\n\\bottomrule\n\\end{tabular}\n\\end{table}\n"])


def write_method(scores: pd.DataFrame, table: pd.DataFrame | None, metrics: Sequence[str],
                 caption_text: str, out: Path) -> list[Path]:
    """The study's files (module docstring) into ``out``; the paths written."""
    paths = [out / "score_folds.csv", out / "score_summary.csv"]
    columns = ["seed", "fold", *(c for c in scores.columns if c not in ("seed", "fold"))]
    write_atomic(paths[0], scores[columns].to_csv(index=False, float_format="%.4f"))
    write_atomic(paths[1], summary(scores, metrics).to_csv(index=False, float_format="%.4f"))
    if table is not None:
        paths += [out / "score.csv", out / "score.tex", out / "score.md"]
        write_atomic(paths[2], table.to_csv(index=False, float_format="%.4f"))
        write_atomic(paths[3], comparison_latex(table, caption_text))
        write_atomic(paths[4], comparison_markdown(table, caption_text))
    return paths


def check_metrics(scores: pd.DataFrame, metrics: Sequence[str]) -> None:
    """A ``ValueError`` naming a metric the method's scores lack (e.g. a progress metric
    without progress predictions)."""
    for metric in metrics:
        if metric not in scores.columns:
            known = [c for c in scores.columns if c not in ("seed", "fold")]
            raise ValueError(f"--metrics {metric}: not a score of the predictions; known: "
                             f"{', '.join(known)}")
