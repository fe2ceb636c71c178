"""The width study: model A and APoc (GradNorm) across LSTM widths, one grid per width.

Each grid holds runs of one width (their ``config.json`` says which), on the same data (every
recorded data setting but the folder it was read from) and folds as the others; a model's runs
agree on every setting but the width and the schedule across the grids, and on every setting
within one (``pooling``). A folder without grid.json is no grid of the study: which runs it
should hold, and so whether they are complete, is unknown. Per grid, the
evidence is every seed (of ``seeds``, if given) whose A and APoc runs (revised labels,
bidirectional) have all finished on every fold the grid records for them; a seed still training
is left out, the table says which seeds each width has and the figure how many. Widths
may differ in their seeds (the 128-unit grid has three, the wider ones fewer): a width with more
seeds has less seed noise in its fold means, so its std and interval are the narrower for it.

``width.csv``, one row per width and metric:

* ``hidden``: LSTM units per direction; ``metric``: ``gesture_accuracy``, ``gesture_edit`` or
  ``gesture_f1@10`` (``collect.run_rows``' columns, in percent);
* ``seeds``: the seeds used, space-separated; ``folds``: how many folds are paired;
* ``A_mean``, ``A_std``, ``APoc_mean``, ``APoc_std``: mean and sample standard deviation over
  folds of each fold's mean over its seeds;
* ``diff``, ``ci_low``, ``ci_high``, ``p_value``: APoc minus A paired over folds, each side
  averaged over its seeds within a fold, with the exact sign-flip test and its 95 % interval
  (``paired.paired``, the procedure of ``claims.csv``);
* ``p_holm``: ``p_value`` after Holm's correction over the widths of the table, within each
  metric (the family: "APoc - A on this metric differs from 0 at some width"; ``paired.holm``).
  With 8 folds no exact p is below 2/256, so with four widths no adjusted p is below 0.031;
* ``A_epochs``, ``APoc_epochs``: the schedule each model trained (the presets differ: APoc
  trains 180 epochs at the ``converged`` preset, 120 at ``paper``);
* ``A_runs``, ``A_converged``, ``A_undecided``, ``A_still_falling`` (and APoc's): the model's
  runs at that width and how many of them the three-way convergence verdict calls each
  (``rnn_seg.convergence``; a run whose verdict is unknown is in none of the three);
* ``paper_A``, ``paper_APoc``: the published values (Table I) at the paper's width, 1024, for
  the real Suturing release; empty otherwise.

``width.png`` / ``.pdf`` draws score against width (log2 axis) for both models, the paper's
values marked at 1024, each width's seed count under its tick; below each metric, APoc - A with
its 95 % interval against width, the paper's difference marked at 1024.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from jigsaws_tools.dataset import DataConfig  # noqa: E402
from jigsaws_tools.plots import PAGE_INCHES, figure_style  # noqa: E402
from jigsaws_tools.task_definition import PAPER_TASK  # noqa: E402
from rnn_seg.runs.folder import CONFIG, is_finished, read_json  # noqa: E402

from ..models.run_record import RunRecord  # noqa: E402

from .captions import describe_runs, is_synthetic, task_name  # noqa: E402
from .checks import OTHER_SETTINGS, other_settings  # noqa: E402
from .collect import key_from_path, recorded_runs, run_row  # noqa: E402
from .figures import save  # noqa: E402
from .paired import ConfigId, Contrast, holm, paired  # noqa: E402
from .paper_results import TABLE_1  # noqa: E402
from .pooling import pool  # noqa: E402

MODELS = {"A": ConfigId("A", "fixed"), "APoc": ConfigId("APoc", "gradnorm")}
#: The figure's name of each model.
LABELS = {"A": "A", "APoc": r"APoc (GradNorm, $\alpha = 1.5$)"}
COLOURS = ("tab:grey", "tab:blue")          # A, APoc
METRICS = {"gesture_accuracy": "Accuracy", "gesture_edit": "Edit", "gesture_f1@10": "F1@10"}
PAPER_WIDTH = 1024
#: The settings a model's runs may differ in across the grids: the width studied and the
#: schedule, which ``width.csv`` states per width (``A_epochs``, ``APoc_epochs``).
STUDIED = ("run.encoder.hidden", "run.optim.total", "run.optim.decay_start",
           "run.optim.decay_every", "run.train.eval_points")


@dataclass(frozen=True)
class WidthEvidence:
    """One grid's part of the study: its width, data, seeds and the runs of A and APoc."""

    hidden: int
    data: dict                    # A's first run's ``config.json`` ``run.data``, not where it was
    paper: bool                   # trained on the real release of the paper's task
    seeds: tuple[int, ...]
    runs: pd.DataFrame            # one row per run of A and APoc (``collect.run_rows``' columns)
    epochs: dict[str, int]        # model name (``MODELS``) -> its schedule's length in epochs
    records: dict[Path, RunRecord]  # each run's folder -> its config.json


def _model_runs(grid: Path, seeds: tuple[int, ...] | None) -> dict[int, dict[str, list[Path]]]:
    """Seed -> model name (``MODELS``) -> the run folders (relative to ``grid``) the grid records
    for it; only ``seeds``' when given."""
    recorded, unknown = recorded_runs(grid)
    if unknown:                     # no grid.json: which runs the grid should have is unknown
        raise ValueError(f"{grid}: not a grid: {unknown[0]}")
    names = {model: name for name, model in MODELS.items()}
    by_seed: dict[int, dict[str, list[Path]]] = {}
    for run in recorded:
        key = key_from_path(grid / run, grid)
        name = names.get(ConfigId(key.variant, key.weighting, key.annotations, key.direction))
        if name and (seeds is None or key.seed in seeds):
            by_seed.setdefault(key.seed, {}).setdefault(name, []).append(run)
    return by_seed


def _complete_seeds(grid: Path, by_seed: dict[int, dict[str, list[Path]]]) -> tuple[int, ...]:
    """The seeds whose runs of both models have all finished; a one-line ``ValueError`` saying
    what each seed lacks when there is none."""
    gaps = {}
    for seed, models in sorted(by_seed.items()):
        lacking = []
        for name, model in MODELS.items():
            runs = models.get(name, [])
            done = sum(is_finished(grid / run) for run in runs)
            if not runs:
                lacking.append(f"no run of {model.label}")
            elif done < len(runs):
                lacking.append(f"{model.label} {done} of {len(runs)} runs finished")
        gaps[seed] = ", ".join(lacking)
    seeds = tuple(seed for seed, gap in gaps.items() if not gap)
    if not seeds:
        lacking = "; ".join(f"seed {seed}: {gap}" for seed, gap in gaps.items()) or "no run"
        raise ValueError(f"{grid}: no seed with every run of A-fixed and APoc-gradnorm finished "
                         f"({lacking})")
    return seeds


def width_evidence(grid: Path, seeds: tuple[int, ...] | None = None) -> WidthEvidence:
    """The A and APoc runs of every seed (of ``seeds``, if given) of ``grid`` whose runs of both
    models have finished.

    Raises:
        ValueError: one line: ``grid`` holds no grid.json, no such seed (naming what each lacks),
            a run of them without usable metrics or with other settings than the grid's spec or
            its place, a model's runs differing in a setting (``pooling``) or of a schedule not in
            epochs, A and APoc at different widths.
    """
    by_seed = _model_runs(grid, seeds)
    if seeds and not by_seed:
        raise ValueError(f"{grid}: no run of A-fixed or APoc-gradnorm of seed(s) "
                         f"{', '.join(map(str, seeds))}")
    chosen = _complete_seeds(grid, by_seed)
    folders = [run for seed in chosen for runs in by_seed[seed].values() for run in runs]
    problems = [f"{OTHER_SETTINGS} {grid / run}: "
                + "; ".join(line.strip() for line in details.splitlines()[1:])
                for run, details in other_settings(grid, {run: key_from_path(grid / run, grid)
                                                          for run in folders}).items()]
    found = {run: row for run in folders if (row := run_row(grid, run, problems)) is not None}
    if problems:
        raise ValueError(f"{grid}: {len(problems)} problem(s) with the runs of A and APoc, "
                         f"the first: {problems[0]}")
    records = {grid / run: record for run, (_, record) in found.items()}
    pool(records, grid)
    runs = pd.DataFrame([row for row, _ in found.values()])
    described = {name: describe_runs(grid, model.select(runs)) for name, model in MODELS.items()}
    epochs = {}
    for name, description in described.items():
        if len(description.hidden) != 1 or len(description.lengths) != 1 \
                or description.unit != "epochs":
            raise ValueError(f"{grid}: the runs of {MODELS[name].label} are not of one width and "
                             f"one schedule in epochs (widths {list(description.hidden)}, "
                             f"lengths {sorted(description.lengths)} {description.unit})")
        epochs[name] = next(iter(description.lengths))
    widths = {description.hidden[0] for description in described.values()}
    if len(widths) > 1:
        raise ValueError(f"{grid}: A and APoc were trained at different widths {sorted(widths)}")
    data = read_json(grid / folders[0] / CONFIG)["run"]["data"]
    return WidthEvidence(widths.pop(),
                         {k: v for k, v in data.items() if k not in DataConfig.output_fields},
                         task_name(data) == PAPER_TASK and not is_synthetic(data), chosen, runs,
                         epochs, records)


def _check_comparable(grids: list[Path], evidence: list[WidthEvidence]) -> None:
    """One grid per width, every grid on the same data and folds, each model's runs of every
    grid alike but in their width and schedule (``pooling.pool``); a one-line ``ValueError``."""
    widths = [part.hidden for part in evidence]
    if len(set(widths)) < len(widths):
        raise ValueError(f"one grid per width, got widths {sorted(widths)}")
    first = evidence[0].data
    for grid, part in zip(grids[1:], evidence[1:]):
        differing = sorted(k for k in first.keys() | part.data.keys()
                           if first.get(k) != part.data.get(k))
        if differing:
            raise ValueError(f"the grids differ in their data settings ({', '.join(differing)}): "
                             f"{grids[0]} and {grid}")
    folds = {str(grid): " ".join(sorted(set(part.runs.fold)))
             for grid, part in zip(grids, evidence)}
    if len(set(folds.values())) > 1:
        raise ValueError("the grids differ in their folds: "
                         + "; ".join(f"{grid}: {value}" for grid, value in folds.items()))
    pool({run: record for part in evidence for run, record in part.records.items()},
         "the grids of the width study", varying=STUDIED)


def width_table(evidence: list[WidthEvidence]) -> pd.DataFrame:
    """One row per width and metric (the columns of the module docstring), widths ascending."""
    rows = []
    for part in sorted(evidence, key=lambda e: e.hidden):
        for metric in METRICS:
            row = {"hidden": part.hidden, "metric": metric,
                   "seeds": " ".join(map(str, part.seeds))}
            for name, model in MODELS.items():
                per_fold = model.select(part.runs).groupby("fold")[metric].mean()
                row |= {f"{name}_mean": per_fold.mean(), f"{name}_std": per_fold.std(ddof=1)}
            result = paired(part.runs, Contrast(MODELS["APoc"], MODELS["A"]), metric)
            row |= {"folds": result.pairs, "diff": result.mean, "ci_low": result.ci_low,
                    "ci_high": result.ci_high, "p_value": result.p_value}
            row |= {f"{name}_epochs": part.epochs[name] for name in MODELS}
            for name, model in MODELS.items():
                verdicts = model.select(part.runs).convergence
                row |= {f"{name}_runs": len(verdicts)}
                row |= {f"{name}_{verdict.replace(' ', '_')}": int((verdicts == verdict).sum())
                        for verdict in ("converged", "undecided", "still falling")}
            row |= {f"paper_{name}": _paper(name, metric, part) for name in MODELS}
            rows.append(row)
    table = pd.DataFrame(rows)
    adjusted = table.groupby("metric").p_value.transform(lambda p: holm(p.to_numpy(float)))
    table.insert(table.columns.get_loc("p_value") + 1, "p_holm", adjusted)
    return table


def _paper(model: str, metric: str, part: WidthEvidence) -> float | None:
    """The published Table I value of ``model`` on ``metric``, for a grid of the real Suturing
    release at the paper's width only."""
    if part.hidden != PAPER_WIDTH or not part.paper:
        return None
    return TABLE_1[MODELS[model].label][metric][0]


@figure_style
def width_figure(table: pd.DataFrame, out_dir: Path) -> list[Path]:
    """``width.png`` / ``.pdf``: one column per metric, against width (log2 axis, each width's
    seed count under its tick). Top row: mean and standard deviation over folds of A and APoc
    (side by side), the paper's values at 1024 as open diamonds. Bottom row: APoc - A paired
    over folds with its 95 % interval, the paper's difference at 1024 as an open diamond, and
    a line at zero. One legend above the panels."""
    fig, axes = plt.subplots(2, len(METRICS), figsize=(PAGE_INCHES, 4.4), sharex=True,
                             height_ratios=(3, 2))
    for column, (metric, title) in enumerate(METRICS.items()):
        rows = table[table.metric == metric]
        _draw_scores(axes[0, column], rows, title)
        _draw_difference(axes[1, column], rows)
    ticks = table.drop_duplicates("hidden").sort_values("hidden")
    for ax in axes[1]:
        ax.set_xscale("log", base=2)
        ax.set_xticks(ticks.hidden, [f"{hidden}\n{_seed_count(seeds)}" for hidden, seeds
                                     in zip(ticks.hidden, ticks.seeds.astype(str))])
        ax.minorticks_off()
        ax.set_xlabel("LSTM units per direction")
    fig.tight_layout()
    handles = sorted(zip(*axes[0, 0].get_legend_handles_labels()), key=lambda h: "paper" in h[1])
    fig.legend(*zip(*handles), loc="lower center", ncol=2, frameon=False,
               bbox_to_anchor=(0.5, 1.0))
    return save(fig, out_dir, "width")


def _draw_scores(ax: plt.Axes, rows: pd.DataFrame, title: str) -> None:
    """A's and APoc's mean (std over folds) of one metric per width, side by side on the log
    axis, and the paper's values where the table has them."""
    for offset, (name, colour) in zip((-0.04, 0.04), zip(MODELS, COLOURS)):
        shifted = rows.hidden * 2 ** offset          # side by side on the log axis
        ax.errorbar(shifted, rows[f"{name}_mean"], yerr=rows[f"{name}_std"], color=colour,
                    marker="o", ms=4, capsize=2, lw=1.2, label=LABELS[name])
        paper = rows[f"paper_{name}"].dropna()
        if not paper.empty:
            ax.plot(shifted[paper.index], paper, ls="none", marker="D", mfc="none", mec=colour,
                    ms=7, label=f"{LABELS[name]}: paper")
    ax.set_ylabel(f"{title} [%]")
    ax.grid(alpha=0.3)


def _draw_difference(ax: plt.Axes, rows: pd.DataFrame) -> None:
    """APoc - A of one metric per width, paired over folds, with its 95 % interval; the paper's
    difference (its APoc minus its A) where the table has both values."""
    interval = [rows["diff"] - rows.ci_low, rows.ci_high - rows["diff"]]
    ax.axhline(0, color="black", lw=0.8)
    ax.errorbar(rows.hidden, rows["diff"], yerr=interval, color=COLOURS[1], marker="o", ms=4,
                capsize=2, lw=1.2)
    paper = (rows.paper_APoc - rows.paper_A).dropna()
    if not paper.empty:
        ax.plot(rows.hidden[paper.index], paper, ls="none", marker="D", mfc="none",
                mec=COLOURS[1], ms=7)
    ax.set_ylabel("APoc $-$ A [points]")
    ax.grid(alpha=0.3)


def _seed_count(seeds: str) -> str:
    """``3 seeds`` for the ``seeds`` column's ``0 1 2``."""
    count = len(seeds.split())
    return f"{count} seed{'s' * (count != 1)}"


def write_width(grids: list[Path], out: Path, seeds: tuple[int, ...] | None = None
                ) -> list[Path]:
    """``width.csv`` and the figure from one grid per width (only ``seeds``' runs, if given);
    returns the paths written."""
    grids = [Path(grid) for grid in grids]
    evidence = [width_evidence(grid, seeds) for grid in grids]
    _check_comparable(grids, evidence)
    table = width_table(evidence)
    out.mkdir(parents=True, exist_ok=True)
    csv = out / "width.csv"
    table.to_csv(csv, index=False, float_format="%.4f")
    return [csv, *width_figure(table, out)]
