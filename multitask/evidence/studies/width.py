"""The width study: model A and APoc (GradNorm) across LSTM widths, one entry per width.

An entry is one grid, or several grids of one width joined by ``+``
(``results/width/h512-a180+results/confirm/h512``: seed 0 from the first, seeds 1-5 from the
second); each grid is checked on its own, as a grid of a one-grid entry, then their runs are
pooled as one grid's: they must be of one width, on the same data and folds, each model's runs
agreeing on every setting (``pooling.pool``: a grid of another schedule is refused, naming the
setting), and no seed of a model may come from two of them. The width's fold means are then
over the union of their seeds. A folder whose own name holds ``+`` cannot be named in an entry
(link it under another name).

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
* ``seeds``: the seeds used, space-separated (of every grid of the width's entry);
  ``folds``: how many folds are paired;
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
  the real Suturing release; empty otherwise;
* ``grids``, only when some width pools several grids (a table of one grid per width has the
  columns above alone): each grid of the width's entry, as given, and the seeds it contributes,
  e.g. ``results/width/h512-a180: 0; results/confirm/h512: 1 2 3 4 5``.

``width.png`` / ``.pdf`` draws score against width (log2 axis) for both models, the paper's
values marked at 1024, each width's seed count under its tick (and its count of grids, when it
pools several); below each metric, APoc - A with its 95 % interval against width, the paper's
difference marked at 1024.
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

from ...models.run_record import RunRecord  # noqa: E402

from ..render.captions import describe_runs, is_synthetic, task_name  # noqa: E402
from ..render.figures import save  # noqa: E402
from ..render.paper_results import TABLE_1  # noqa: E402
from ..runs.checks import OTHER_SETTINGS, other_settings  # noqa: E402
from ..runs.collect import key_from_path, recorded_runs, run_row  # noqa: E402
from ..runs.pooling import pool  # noqa: E402
from ..statistics.paired import ConfigId, Contrast, holm, paired  # noqa: E402

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
#: Joins the grids of one width in an entry: ``results/width/h512-a180+results/confirm/h512``.
JOIN = "+"


@dataclass(frozen=True)
class WidthEvidence:
    """One width's part of the study, from one grid or several: its width, data, seeds and the
    runs of A and APoc."""

    hidden: int
    data: dict                    # A's first run's ``config.json`` ``run.data``, not where it was
    paper: bool                   # trained on the real release of the paper's task
    seeds: tuple[int, ...]
    runs: pd.DataFrame            # one row per run of A and APoc (``collect.run_rows``' columns)
    epochs: dict[str, int]        # model name (``MODELS``) -> its schedule's length in epochs
    records: dict[Path, RunRecord]  # each run's folder -> its config.json
    grids: dict[Path, tuple[int, ...]]  # each grid of the entry, as given -> the seeds it gives

    @property
    def name(self) -> str:
        """The entry as given: its grids joined by ``JOIN``."""
        return JOIN.join(map(str, self.grids))


def width_entry(text: str) -> tuple[Path, ...]:
    """The grids of one entry of the study: ``text`` split at ``JOIN`` (``results/width/h256``
    is one grid, ``results/width/h512-a180+results/confirm/h512`` two of one width).

    Raises:
        ValueError: one line: an empty part (``a+``, ``a++b``), a grid named twice, or ``text``
            naming an existing folder although it holds ``JOIN`` (it would be read as several).
    """
    parts = text.split(JOIN)
    if len(parts) > 1 and Path(text).is_dir():
        raise ValueError(f"{text}: a folder whose name holds {JOIN!r}, which joins grids of one "
                         "width; name it through a link without it")
    if not all(parts):
        raise ValueError(f"{text}: an empty grid name; join the grids of one width as "
                         f"GRID{JOIN}GRID")
    grids = tuple(Path(part) for part in parts)
    twice = sorted({str(grid) for grid in grids if grids.count(grid) > 1})
    if twice:
        raise ValueError(f"{text}: {twice[0]} is named twice")
    return grids


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


def _lacking(where: Path | str, seeds: tuple[int, ...]) -> str:
    """The error of a grid (or entry) without a run of ``seeds``."""
    return f"{where}: no run of A-fixed or APoc-gradnorm of seed(s) {', '.join(map(str, seeds))}"


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
        raise ValueError(_lacking(grid, seeds))
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
                         epochs, records, {grid: chosen})


def entry_evidence(grids: tuple[Path, ...], seeds: tuple[int, ...] | None = None
                   ) -> WidthEvidence:
    """One width's evidence from the grids of its entry: each grid's (``width_evidence``),
    pooled when there are several; the seeds are then the union of theirs. With ``seeds``, a
    grid of several that holds none of them gives nothing (``--seeds 0`` takes seed 0 from the
    grid that has it); one that holds some is checked as alone.

    Raises:
        ValueError: one line: a grid's own problem (``width_evidence``), the grids of other
            widths, one seed of a model in two of them (naming both and the seed), other data
            or folds, or a model's runs differing in a setting (``pooling.MixedSettings``, naming
            it, e.g. the schedule).
    """
    where = JOIN.join(map(str, grids))
    if seeds and len(grids) > 1:
        grids = tuple(grid for grid in grids if _model_runs(grid, seeds))
        if not grids:
            raise ValueError(_lacking(where, seeds))
    parts = [width_evidence(grid, seeds) for grid in grids]
    if len(parts) == 1:
        return parts[0]
    widths = {part.hidden for part in parts}
    if len(widths) > 1:
        raise ValueError(f"{where}: the grids of one entry are of different widths ("
                         + ", ".join(f"{grid}: {part.hidden}" for grid, part in zip(grids, parts))
                         + "); give each width an entry of its own")
    _check_disjoint(grids, seeds)
    _check_alike(parts)
    records = {run: record for part in parts for run, record in part.records.items()}
    pool(records, where)
    first = parts[0]
    return WidthEvidence(first.hidden, first.data, first.paper,
                         tuple(sorted(seed for part in parts for seed in part.seeds)),
                         pd.concat([part.runs for part in parts], ignore_index=True),
                         first.epochs, records, {grid: part.seeds
                                                 for grid, part in zip(grids, parts)})


def _check_disjoint(grids: tuple[Path, ...], seeds: tuple[int, ...] | None) -> None:
    """No seed of a model recorded in two of ``grids`` (finished or not: two runs of one seed
    would be counted twice, or one silently dropped); a one-line ``ValueError`` naming both."""
    owner: dict[tuple[int, str], Path] = {}
    for grid in grids:
        for seed, models in sorted(_model_runs(grid, seeds).items()):
            for name in models:
                first = owner.setdefault((seed, name), grid)
                if first != grid:
                    raise ValueError(f"{first} and {grid} both hold seed {seed} of "
                                     f"{MODELS[name].label}; a seed of one width comes from one "
                                     "grid only")


def _check_comparable(evidence: list[WidthEvidence]) -> None:
    """One entry per width, every entry on the same data and folds, each model's runs of every
    entry alike but in their width and schedule (``pooling.pool``); a one-line ``ValueError``."""
    widths = [part.hidden for part in evidence]
    if len(set(widths)) < len(widths):
        raise ValueError(f"one entry per width, got widths {sorted(widths)}; join the grids "
                         f"of one width in one entry, GRID{JOIN}GRID")
    _check_alike(evidence)
    pool({run: record for part in evidence for run, record in part.records.items()},
         "the grids of the width study", varying=STUDIED)


def _check_alike(parts: list[WidthEvidence]) -> None:
    """Every part on the first's data settings and folds; a one-line ``ValueError`` naming the
    parts (their entries) that differ."""
    first = parts[0]
    for part in parts[1:]:
        differing = sorted(k for k in first.data.keys() | part.data.keys()
                           if first.data.get(k) != part.data.get(k))
        if differing:
            raise ValueError(f"the grids differ in their data settings ({', '.join(differing)}): "
                             f"{first.name} and {part.name}")
    folds = {part.name: " ".join(sorted(set(part.runs.fold))) for part in parts}
    if len(set(folds.values())) > 1:
        raise ValueError("the grids differ in their folds: "
                         + "; ".join(f"{name}: {value}" for name, value in folds.items()))


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
    if any(len(part.grids) > 1 for part in evidence):
        sources = {part.hidden: "; ".join(f"{grid}: {' '.join(map(str, seeds))}"
                                          for grid, seeds in part.grids.items())
                   for part in evidence}
        table["grids"] = table.hidden.map(sources)
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
    sources = ticks["grids"] if "grids" in ticks else [None] * len(ticks)
    labels = [f"{hidden}\n{_seed_count(seeds)}{_grid_count(grids)}" for hidden, seeds, grids
              in zip(ticks.hidden, ticks.seeds.astype(str), sources)]
    for ax in axes[1]:
        ax.set_xscale("log", base=2)
        ax.set_xticks(ticks.hidden, labels)
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


def _grid_count(grids: str | None) -> str:
    """``\n2 grids`` under the tick of a width pooled from two grids (the ``grids`` column's
    ``a: 0; b: 1 2``); nothing for one grid, or a table without the column (None)."""
    count = len(grids.split("; ")) if grids else 1
    return f"\n{count} grids" if count > 1 else ""


def write_width(entries: list[Path | tuple[Path, ...]], out: Path,
                seeds: tuple[int, ...] | None = None) -> list[Path]:
    """``width.csv`` and the figure from one entry per width, a grid or the grids of one width
    (``width_entry``; only ``seeds``' runs, if given); returns the paths written."""
    evidence = [entry_evidence(tuple(map(Path, entry)) if isinstance(entry, tuple)
                               else (Path(entry),), seeds) for entry in entries]
    _check_comparable(evidence)
    table = width_table(evidence)
    out.mkdir(parents=True, exist_ok=True)
    csv = out / "width.csv"
    table.to_csv(csv, index=False, float_format="%.4f")
    return [csv, *width_figure(table, out)]
