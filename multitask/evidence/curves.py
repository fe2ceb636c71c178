"""Training curves of a grid's runs, from each run's ``history.csv``: one figure per
configuration, one line per run (a colour per fold, a line style per seed).

``history.csv`` holds ``unit, n, sweep, lr``, the loss of every task (``loss_<task>``), a time
column and score columns (``train_*``, ``test_*``) that may be filled only every few epochs. Each
figure has a panel per task loss and a panel per test accuracy column (``test_<task>_acc`` or
``test_<task>_accuracy``), the scores drawn as points joined over the rows that have them.
Unfinished runs are drawn too, as far as they got.
"""
from __future__ import annotations

import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from rnn_seg.config import unit_name  # noqa: E402
from rnn_seg.runs.logs import read_log  # noqa: E402

from .collect import key_from_path  # noqa: E402
from .figures import save  # noqa: E402
from ..grid.spec import RunKey  # noqa: E402

#: Test accuracy columns of history.csv, with the task as group 1.
TEST_ACCURACY = re.compile(r"test_(\w+?)_acc(?:uracy)?")
LINE_STYLES = ("-", "--", ":", "-.")


def training_curves(grid_dir: Path | str, out_dir: Path) -> list[Path]:
    """Write ``<annotations>-<direction>-<variant>-<weighting>.png|pdf`` to ``out_dir`` for
    every configuration with a history; returns the paths."""
    root = Path(grid_dir)
    configs: dict[tuple[str, str, str], list[tuple[RunKey, pd.DataFrame]]] = {}
    for path in sorted((root / "runs").glob("*/*/*/seed*/*/history.csv")):
        key = key_from_path(path.parent, root)
        configs.setdefault((key.annotations, key.direction, key.config_name), []).append(
            (key, read_log(path)))
    written = []
    for (labels, direction, config), runs in configs.items():
        fig = curves_figure(runs, f"{config}, {labels} annotations, {direction}")
        written += save(fig, out_dir, f"{labels}-{direction}-{config}")
    return written


def curves_figure(runs: list[tuple[RunKey, pd.DataFrame]], title: str) -> plt.Figure:
    """Loss and test accuracy panels of ``runs`` (their keys and histories) of one
    configuration."""
    columns = list(dict.fromkeys(c for _, history in runs for c in history.columns))
    panels = ([c for c in columns if c.startswith("loss_")]
              + [c for c in columns if TEST_ACCURACY.fullmatch(c)])
    folds = sorted({key.fold for key, _ in runs})
    seeds = sorted({key.seed for key, _ in runs})
    fig, axes = plt.subplots(1, len(panels), figsize=(3.2 * len(panels), 2.8), squeeze=False)
    colours = plt.get_cmap("tab10" if len(folds) <= 10 else "tab20")
    for ax, column in zip(axes[0], panels):
        for key, history in runs:
            if column not in history:
                continue
            rows = history[history[column].notna()]
            scored = column.startswith("test_")
            ax.plot(rows.n, rows[column], color=colours(folds.index(key.fold)),
                    linestyle=LINE_STYLES[seeds.index(key.seed) % len(LINE_STYLES)],
                    marker="o" if scored else None, markersize=3, lw=1)
        match = TEST_ACCURACY.fullmatch(column)
        ax.set_title(f"{match.group(1)} test accuracy [%]" if match
                     else f"{column.removeprefix('loss_')} loss", fontsize=9)
        ax.set_xlabel(_unit(runs))
    for k, fold in enumerate(folds):
        axes[0][0].plot([], [], color=colours(k), label=f"test user {fold}")
    for k, seed in enumerate(seeds if len(seeds) > 1 else []):
        axes[0][0].plot([], [], color="0.4", linestyle=LINE_STYLES[k % len(LINE_STYLES)],
                        label=f"seed {seed}")
    fig.suptitle(title, fontsize=9)
    fig.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=7, frameon=False)
    fig.tight_layout()
    return fig


def _unit(runs: list[tuple[RunKey, pd.DataFrame]]) -> str:
    """``epoch`` or ``sweep``: the histories' unit, singular."""
    units = {str(u) for _, history in runs
             for u in (history["unit"].unique() if "unit" in history else ["epochs"])}
    return "/".join(sorted(unit_name(u) for u in units))
