"""The width study: model A and APoc (GradNorm) across LSTM widths, one grid per width.

Each grid holds runs of one width (their ``config.json`` says which). Per grid, the evidence
is every seed whose A and APoc runs (revised labels, bidirectional) have all finished on every
fold the grid records for them; a seed still training is left out, and the table says which
seeds each width has. Per width and metric (``width.csv``, one row each):

* ``A_mean``, ``A_std``, ``APoc_mean``, ``APoc_std``: mean and sample standard deviation over
  folds of each fold's mean over its seeds, in percent;
* ``diff``, ``ci_low``, ``ci_high``, ``p_value``: APoc minus A paired over folds
  (``paired.paired``, the procedure of ``claims.csv``);
* ``A_epochs``, ``APoc_epochs``: the schedule each model trained (the presets differ: APoc
  trains 180 epochs at the ``converged`` preset, 120 at ``paper``);
* ``paper_A``, ``paper_APoc``: the published values (Table I) at the paper's width, 1024.

``width.png`` / ``.pdf`` draws score against width (log2 axis) for both models, the paper's
values marked at 1024.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from rnn_seg.runs.folder import is_finished  # noqa: E402

from ..grid.spec import RunKey  # noqa: E402
from .collect import key_from_path, recorded_runs, run_rows  # noqa: E402
from .figures import save  # noqa: E402
from .paired import ConfigId, Contrast, paired  # noqa: E402
from .paper_results import TABLE_1  # noqa: E402

MODELS = {"A": ConfigId("A", "fixed"), "APoc": ConfigId("APoc", "gradnorm")}
METRICS = {"gesture_accuracy": "Accuracy", "gesture_edit": "Edit", "gesture_f1@10": "F1@10"}
PAPER_WIDTH = 1024


@dataclass(frozen=True)
class WidthEvidence:
    """One grid's part of the study: its width, the seeds used and their runs."""

    hidden: int
    seeds: tuple[int, ...]
    runs: pd.DataFrame            # one row per run of A and APoc (``collect.run_rows``)
    epochs: dict[str, int]        # model name (``MODELS``) -> its schedule's length in epochs


def _model_runs(grid: Path) -> dict[int, dict[ConfigId, list[Path]]]:
    """Seed -> model (``MODELS``) -> the run folders the grid records for it."""
    recorded, _ = recorded_runs(grid)
    by_seed: dict[int, dict[ConfigId, list[Path]]] = {}
    for run in recorded:
        key = key_from_path(grid / run, grid)
        model = ConfigId(key.variant, key.weighting, key.annotations, key.direction)
        if model in MODELS.values():
            by_seed.setdefault(key.seed, {}).setdefault(model, []).append(grid / run)
    return by_seed


def width_evidence(grid: Path) -> WidthEvidence:
    """The A and APoc runs of every seed of ``grid`` whose runs of both models have finished.

    Raises:
        ValueError: no such seed, or a finished run without usable metrics.
    """
    by_seed = _model_runs(grid)
    seeds = tuple(seed for seed, models in sorted(by_seed.items())
                  if len(models) == len(MODELS)
                  and all(is_finished(run) for runs in models.values() for run in runs))
    if not seeds:
        raise ValueError(f"{grid}: no seed with every run of A-fixed and APoc-gradnorm finished")
    every, problems = run_rows(grid, allow_incomplete=True, seeds=seeds)
    runs = pd.concat([model.select(every) for model in MODELS.values()], ignore_index=True)
    expected = sum(len(folders) for seed in seeds for folders in by_seed[seed].values())
    if len(runs) != expected:
        raise ValueError(f"{grid}: {expected - len(runs)} finished run(s) of A or APoc without "
                         "usable metrics:\n  " + "\n  ".join(problems))
    budgets = {name: _budget(grid, model.select(runs)) for name, model in MODELS.items()}
    widths = {hidden for hidden, _ in budgets.values()}
    if len(widths) > 1:
        raise ValueError(f"{grid}: A and APoc were trained at different widths {sorted(widths)}")
    return WidthEvidence(widths.pop(), seeds, runs,
                         {name: epochs for name, (_, epochs) in budgets.items()})


def _budget(grid: Path, runs: pd.DataFrame) -> tuple[int, int]:
    """The LSTM width and the schedule length (epochs) of ``runs``, one configuration's, read
    from their ``config.json``; a ``ValueError`` when they differ between its runs."""
    budgets = set()
    for row in runs.to_dict("records"):
        key = RunKey(**{name: row[name] for name in RunKey.__dataclass_fields__})
        run = json.loads((grid / key.path() / "config.json").read_text())["run"]
        budgets.add((int(run["encoder"]["hidden"]), int(run["optim"]["total"])))
    if len(budgets) > 1:
        raise ValueError(f"{grid}: the runs of one configuration differ in (width, epochs): "
                         f"{sorted(budgets)}")
    return budgets.pop()


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
            row |= {f"paper_{name}": _paper(name, metric, part.hidden) for name in MODELS}
            rows.append(row)
    return pd.DataFrame(rows)


def _paper(model: str, metric: str, hidden: int) -> float | None:
    """The published Table I value of ``model`` on ``metric``, at the paper's width only."""
    if hidden != PAPER_WIDTH:
        return None
    return TABLE_1[MODELS[model].label][metric][0]


def width_figure(table: pd.DataFrame, out_dir: Path) -> list[Path]:
    """``width.png`` / ``.pdf``: one panel per metric, score against width (log2 axis), mean and
    standard deviation over folds for A and APoc (side by side), the paper's values at 1024 as
    open diamonds; one legend above the panels."""
    fig, axes = plt.subplots(1, len(METRICS), figsize=(3.2 * len(METRICS), 2.8), sharex=True)
    for ax, (metric, title) in zip(axes, METRICS.items()):
        rows = table[table.metric == metric]
        for offset, (name, colour) in zip((-0.04, 0.04), zip(MODELS, ("tab:grey", "tab:blue"))):
            widths = rows.hidden * 2 ** offset          # side by side on the log axis
            ax.errorbar(widths, rows[f"{name}_mean"], yerr=rows[f"{name}_std"], color=colour,
                        marker="o", ms=4, capsize=2, lw=1.2, label=_legend(name))
            paper = rows[f"paper_{name}"].dropna()
            if not paper.empty:
                ax.plot(rows.hidden[paper.index] * 2 ** offset, paper, ls="none", marker="D",
                        mfc="none", mec=colour, ms=7, label=f"{_legend(name)}: paper")
        ax.set_xscale("log", base=2)
        widths = sorted(table.hidden.unique())
        ax.set_xticks(widths, [str(h) for h in widths])
        ax.minorticks_off()
        ax.set_xlabel("LSTM units per direction")
        ax.set_ylabel(f"{title} [%]")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    handles = sorted(zip(*axes[0].get_legend_handles_labels()), key=lambda h: "paper" in h[1])
    fig.legend(*zip(*handles), loc="lower center", ncol=4, fontsize=8, frameon=False,
               bbox_to_anchor=(0.5, 1.0))
    return save(fig, out_dir, "width")


def _legend(name: str) -> str:
    return "A" if name == "A" else r"APoc (GradNorm, $\alpha = 1.5$)"


def write_width(grids: list[Path], out: Path) -> list[Path]:
    """``width.csv`` and the figure from one grid per width; returns the paths written."""
    evidence = [width_evidence(Path(grid)) for grid in grids]
    widths = [part.hidden for part in evidence]
    if len(set(widths)) < len(widths):
        raise ValueError(f"one grid per width, got widths {sorted(widths)}")
    table = width_table(evidence)
    out.mkdir(parents=True, exist_ok=True)
    csv = out / "width.csv"
    table.to_csv(csv, index=False, float_format="%.4f")
    return [csv, *width_figure(table, out)]
