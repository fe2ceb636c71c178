"""Training curves of a grid's runs, from each run's ``history.csv``: one figure per
configuration, one line per run (a colour per fold, a line style per seed).

``history.csv`` holds ``unit, n, sweep, lr``, the loss of every task (``loss_<task>``), a time
column and score columns (``train_*``, ``test_*``) that may be filled only every few epochs. Each
figure has a panel per task loss and a panel per test accuracy column (``test_<task>_acc`` or
``test_<task>_accuracy``), the scores drawn as points joined over the rows that have them.
Unfinished runs are drawn too, as far as they got.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from jigsaws_tools.plots import PAGE_INCHES, figure_style  # noqa: E402
from rnn_seg.config import unit_name  # noqa: E402
from rnn_seg.runs.logs import read_log  # noqa: E402

from ...grid.spec import RunKey  # noqa: E402
from ..runs.collect import key_from_path  # noqa: E402
from . import drawing  # noqa: E402
from .figures import save  # noqa: E402

#: Test accuracy columns of history.csv, with the task as group 1.
TEST_ACCURACY = re.compile(r"test_(\w+?)_acc(?:uracy)?")
LINE_STYLES = ("-", "--", ":", "-.")


@figure_style
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
    drawing.say(f"drawing the training curves of {len(configs)} configurations")
    for (labels, direction, config), runs in configs.items():
        fig = curves_figure(runs, f"{config}, {labels} annotations, {direction}")
        written += save(fig, out_dir, f"{labels}-{direction}-{config}")
    return written


@figure_style
def curves_figure(runs: list[tuple[RunKey, pd.DataFrame]], title: str) -> plt.Figure:
    """Loss and test accuracy panels of ``runs`` (their keys and histories) of one
    configuration, two panels a row across a page, the legend beneath them."""
    columns = list(dict.fromkeys(c for _, history in runs for c in history.columns))
    panels = ([c for c in columns if c.startswith("loss_")]
              + [c for c in columns if TEST_ACCURACY.fullmatch(c)])
    folds = sorted({key.fold for key, _ in runs})
    seeds = sorted({key.seed for key, _ in runs})
    columns = min(2, len(panels))
    rows = math.ceil(len(panels) / columns)
    fig, axes = plt.subplots(rows, columns, figsize=(PAGE_INCHES, 2.1 * rows + 0.8),
                             squeeze=False)
    for ax in axes.flat[len(panels):]:
        ax.remove()
    colours = plt.get_cmap("tab10" if len(folds) <= 10 else "tab20")
    for ax, column in zip(axes.flat, panels):
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
                     else f"{column.removeprefix('loss_')} loss")
        ax.set_xlabel(_unit(runs))
    for k, fold in enumerate(folds):
        axes[0][0].plot([], [], color=colours(k), label=f"test user {fold}")
    for k, seed in enumerate(seeds if len(seeds) > 1 else []):
        axes[0][0].plot([], [], color="0.4", linestyle=LINE_STYLES[k % len(LINE_STYLES)],
                        label=f"seed {seed}")
    fig.suptitle(title)
    entries = len(folds) + (len(seeds) if len(seeds) > 1 else 0)
    legend_rows = math.ceil(entries / 6)
    fig.tight_layout(rect=(0, 0.2 * legend_rows / fig.get_figheight(), 1, 1))
    fig.legend(loc="lower center", ncol=min(entries, 6), frameon=False,
               bbox_to_anchor=(0.5, 0.0), handlelength=1.6, columnspacing=1.0)
    return fig


def _unit(runs: list[tuple[RunKey, pd.DataFrame]]) -> str:
    """``epoch`` or ``sweep``: the histories' unit, singular."""
    units = {str(u) for _, history in runs
             for u in (history["unit"].unique() if "unit" in history else ["epochs"])}
    return "/".join(sorted(unit_name(u) for u in units))
