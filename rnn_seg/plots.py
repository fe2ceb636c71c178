"""Per-sequence figure of every task: truth and prediction ribbons, plus a stage line if ordered."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from jigsaws_tools.plots import draw_ribbon, legend_handles  # noqa: E402

from .tasks import Task  # noqa: E402

_CMAPS = ("tab10", "viridis", "Set2")


def plot_sequence(title: str, tasks: Sequence[Task], true: dict[str, np.ndarray],
                  pred: dict[str, np.ndarray], path: Path | str, sample_hz: float) -> Path:
    """Save truth/prediction ribbons (``[T]`` labels per task) and ordered tasks' stage lines."""
    rows = [(task, kind, labels[task.name], _CMAPS[k % len(_CMAPS)])
            for k, task in enumerate(tasks) for kind, labels in (("truth", true), ("pred", pred))]
    lines = [t for t in tasks if t.ordered]
    heights = [0.35] * len(rows) + [1.6] * len(lines)
    fig, axes = plt.subplots(len(heights), 1, figsize=(10, sum(heights) + 1.3), sharex=True,
                             gridspec_kw={"height_ratios": heights}, squeeze=False)
    axes = axes[:, 0]
    for ax, (task, kind, labels, cmap) in zip(axes, rows):
        draw_ribbon(ax, labels, task.num_classes, cmap, f"{task.name} {kind}")
    for ax, task in zip(axes[len(rows):], lines):
        t = np.arange(len(true[task.name]))
        ax.step(t, true[task.name], where="post", color="tab:blue", label="truth")
        ax.step(t, pred[task.name], where="post", color="tab:red", label="prediction", alpha=0.8)
        ax.set_yticks(range(task.num_classes))
        ax.set_ylabel(task.name)
        ax.legend(fontsize=7, loc="upper left", ncol=2)
    axes[0].set_xlim(-0.5, len(next(iter(true.values()))) - 0.5)
    axes[0].set_title(title, fontsize=9)
    axes[-1].set_xlabel(f"sample ({sample_hz:g} Hz)")
    handles = [h for k, task in enumerate(tasks)
               for h in legend_handles(task.class_names, _CMAPS[k % len(_CMAPS)])]
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 15), fontsize=7,
               frameon=False)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
