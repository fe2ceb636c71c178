"""Label ribbons: one coloured bar per label sequence, the way segmentations are usually shown."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from .task_definition import TaskDefinition  # noqa: E402

GESTURE_CMAP = "tab10"
PROGRESS_CMAP = "viridis"


def draw_ribbon(ax: plt.Axes, labels: np.ndarray, num_classes: int, cmap: str,
                label: str = "") -> None:
    """Draw ``labels`` ``[T]`` (ints in ``0..num_classes-1``) as a one-row colour strip."""
    ax.imshow(labels[None, :], aspect="auto", cmap=cmap, vmin=-0.5, vmax=num_classes - 0.5,
              interpolation="nearest")
    ax.set_yticks([0])
    ax.set_yticklabels([label])
    ax.tick_params(axis="y", length=0)
    for side in ("top", "right", "left"):
        ax.spines[side].set_visible(False)


def legend_handles(names: Sequence[str], cmap: str) -> list[Patch]:
    colours = plt.get_cmap(cmap)(np.linspace(0, 1, len(names)) if cmap != GESTURE_CMAP
                                 else np.arange(len(names)))
    return [Patch(color=c, label=n) for c, n in zip(colours, names)]


def plot_ribbon_rows(rows: Sequence[tuple[str, np.ndarray, int, str]], path: Path | str,
                     legends: Sequence[tuple[Sequence[str], str]], title: str = "",
                     sample_hz: float | None = None) -> Path:
    """Save a figure of stacked ribbons.

    Args:
        rows: ``(name, labels [T], num_classes, cmap)`` per ribbon, top to bottom.
        path: the image file to write.
        legends: ``(class names, cmap)`` per legend group, e.g. a task's gestures and stages.
        title: figure title.
        sample_hz: sampling rate of the labels, for the x-axis label.
    """
    fig, axes = plt.subplots(len(rows), 1, figsize=(10, 0.45 * len(rows) + 1.2), sharex=True,
                             squeeze=False)
    for ax, (name, labels, num_classes, cmap) in zip(axes[:, 0], rows):
        draw_ribbon(ax, labels, num_classes, cmap, name)
    axes[0, 0].set_xlim(-0.5, max(len(r[1]) for r in rows) - 0.5)
    axes[-1, 0].set_xlabel(f"sample ({sample_hz:g} Hz)" if sample_hz else "sample")
    if title:
        axes[0, 0].set_title(title, fontsize=9)
    handles = [h for names, cmap in legends for h in legend_handles(names, cmap)]
    fig.legend(handles=handles, loc="lower center", ncol=15, fontsize=7, frameon=False,
               bbox_to_anchor=(0.5, 0.0))
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    return _save(fig, path)


def _save(fig: plt.Figure, path: Path | str) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_dataset(trials, path: Path | str, sample_hz: float, task: TaskDefinition) -> Path:
    """Gesture and progress ribbons of every trial of ``task`` (two rows per trial) in one PNG."""
    rows = []
    for t in trials:
        rows.append((f"{t.name} gesture", t.gestures, task.num_gestures, GESTURE_CMAP))
        rows.append(("progress", t.progress, task.num_stages, PROGRESS_CMAP))
    legends = [(task.gestures, GESTURE_CMAP), (task.stage_labels, PROGRESS_CMAP)]
    return plot_ribbon_rows(rows, path, legends, sample_hz=sample_hz)
