"""Per-sequence figure of every task: truth and prediction ribbons, plus a stage line if ordered."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from jigsaws_tools.plots import (LEGEND_ROW_INCHES, Ribbon, draw_ribbon,  # noqa: E402
                                 figure_style, layout_with_legends, legend_rows, save_png,
                                 task_colours)

from .tasks import Task  # noqa: E402


@figure_style
def plot_sequence(title: str, tasks: Sequence[Task], true: dict[str, np.ndarray],
                  pred: dict[str, np.ndarray], path: Path | str, sample_hz: float) -> Path:
    """Save truth/prediction ribbons and ordered tasks' stage lines, over time in seconds, with
    the tasks' class names.

    Args:
        title: the figure's title, e.g. ``"<sequence> - epoch 120"``.
        tasks: the tasks drawn, top to bottom.
        true: ``{task name: [T] int64 true labels}``.
        pred: ``{task name: [T] int64 predicted labels}``.
        path: the PNG written (folders created).
        sample_hz: rate of the labels' samples in Hz (5 Hz after the default preprocessing).

    Returns:
        ``path``.
    """
    times = np.arange(len(next(iter(true.values())))) / sample_hz
    ribbons = [Ribbon(f"{task.name} {kind}", labels[task.name], times, task.class_names,
                      task_colours(task.num_classes, task.ordered))
               for task in tasks for kind, labels in (("truth", true), ("pred", pred))]
    lines = [t for t in tasks if t.ordered]
    heights = [0.35] * len(ribbons) + [1.6] * len(lines)
    fig, axes = plt.subplots(len(heights), 1, sharex=True, squeeze=False,
                             figsize=(10, sum(heights) + 0.9
                                      + LEGEND_ROW_INCHES * legend_rows(ribbons)),
                             gridspec_kw={"height_ratios": heights})
    axes = axes[:, 0]
    for ax, ribbon in zip(axes, ribbons):
        draw_ribbon(ax, ribbon)
    for ax, task in zip(axes[len(ribbons):], lines):
        ax.step(times, true[task.name], where="post", color="tab:blue", label="truth")
        ax.step(times, pred[task.name], where="post", color="tab:red", label="prediction",
                alpha=0.8)
        ax.set_yticks(range(task.num_classes), task.class_names)
        ax.set_ylabel(task.name)
        ax.legend(loc="upper left", ncol=2)
    axes[0].set_title(title)
    axes[-1].set_xlabel("time [s]")
    layout_with_legends(fig, ribbons)
    return save_png(fig, path, dpi=100)
