"""Label ribbons: one coloured bar per label sequence over time in seconds, class names on it.

A class's colour comes from ``class_colours`` alone, for ribbons and legends alike, so a class
looks the same in every figure of the package: a qualitative colour map (``tab10``, ``tab20``
beyond ten classes) gives the classes its first colours in order; a continuous one (``viridis``,
for progress stages) is sampled evenly from end to end. Class names and counts are arguments
(the task's vocabulary), never constants of this module.

Every figure of the package is drawn in ``FIGURE_STYLE`` (``figure_style``): text of
``MIN_TEXT_PT`` or larger and TrueType (Type 42) fonts in PDF and PostScript, which publishers'
checks (IEEE PDF eXpress) accept where matplotlib's default Type 3 fonts are refused; figures
meant for a paper are at most ``COLUMN_INCHES`` or ``PAGE_INCHES`` wide, so that they print at
their own size.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence, TypeVar

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

#: Colour map of progress stages (ordered: a continuous map).
STAGE_CMAP = "viridis"
#: Narrowest run of one class, as a fraction of the ribbon's duration, that gets its name, if
#: the name fits: ``NAME_WIDTH_EM`` font sizes a character (DejaVu Sans is narrower, with room).
NAMED_RUN, NAME_WIDTH_EM = 0.035, 0.8
#: Height of a legend row under a ribbon figure, and the most classes in one row.
LEGEND_ROW_INCHES, LEGEND_COLUMNS = 0.3, 10
#: A journal's column and text widths (IEEE), in inches, and the smallest text, in points.
COLUMN_INCHES, PAGE_INCHES, MIN_TEXT_PT = 3.5, 7.16, 8
#: The matplotlib settings of every figure: TrueType fonts (``fonttype`` 42, not Type 3), and
#: every text at least ``MIN_TEXT_PT`` (titles one point more).
FIGURE_STYLE = {"pdf.fonttype": 42, "ps.fonttype": 42, "svg.fonttype": "none",
                "font.size": MIN_TEXT_PT, "axes.titlesize": MIN_TEXT_PT + 1,
                "axes.labelsize": MIN_TEXT_PT, "xtick.labelsize": MIN_TEXT_PT,
                "ytick.labelsize": MIN_TEXT_PT, "legend.fontsize": MIN_TEXT_PT,
                "legend.title_fontsize": MIN_TEXT_PT, "figure.titlesize": MIN_TEXT_PT + 1}

Draw = TypeVar("Draw", bound=Callable)


def figure_style(draw: Draw) -> Draw:
    """Decorate a function that draws and saves figures: it runs in ``FIGURE_STYLE`` (and the
    user's own matplotlib settings are as they were afterwards)."""
    @functools.wraps(draw)
    def styled(*args, **kwargs):
        with matplotlib.rc_context(FIGURE_STYLE):
            return draw(*args, **kwargs)
    return styled


def class_colours(num_classes: int, cmap: str | None = None) -> np.ndarray:
    """``[num_classes, 4]`` RGBA colour of each class under ``cmap``; None = ``tab10`` (or
    ``tab20`` for more than ten classes). A qualitative map (fewer than 256 colours) must have a
    colour per class."""
    name = cmap or ("tab10" if num_classes <= 10 else "tab20")
    colormap = matplotlib.colormaps[name]
    if colormap.N >= 256:
        return colormap(np.linspace(0.0, 1.0, num_classes))
    if colormap.N < num_classes:
        raise ValueError(f"colour map {name} has {colormap.N} colours for {num_classes} classes")
    return colormap(np.arange(num_classes))


def runs(labels: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` sample ranges of the runs of equal labels in ``labels`` ``[T]``."""
    if len(labels) == 0:
        return []
    edges = np.flatnonzero(np.diff(labels)) + 1
    bounds = np.concatenate([[0], edges, [len(labels)]])
    return list(zip(bounds[:-1].tolist(), bounds[1:].tolist()))


def sample_edges(times: np.ndarray) -> np.ndarray:
    """``[T + 1]`` start of every sample at ``times`` ``[T]`` (seconds) and the end of the last,
    one median step after it."""
    step = float(np.median(np.diff(times))) if len(times) > 1 else 1.0
    return np.append(times, times[-1] + step)


@dataclass(frozen=True)
class Ribbon:
    """One row of a ribbon figure."""

    label: str                   # the row's name, left of the bar
    labels: np.ndarray           # [T] class indices, 0..len(names)-1
    times: np.ndarray            # [T] seconds of each sample
    names: tuple[str, ...]       # the task's class names, in index order
    colours: np.ndarray          # [len(names), 4] RGBA, from class_colours


def task_colours(num_classes: int, ordered: bool) -> np.ndarray:
    """The colours of a task's classes: ordered stages on ``STAGE_CMAP``, other classes (gestures)
    on the default qualitative map."""
    return class_colours(num_classes, STAGE_CMAP if ordered else None)


def draw_ribbon(ax: plt.Axes, ribbon: Ribbon) -> None:
    """Draw ``ribbon`` on ``ax`` (x in seconds): a bar per run of one class, its class name
    written on runs wide enough for it (at the axes' width when drawn); unlabelled samples
    (negative labels) stay blank."""
    edges = sample_edges(ribbon.times)
    spans = [(edges[a], edges[b] - edges[a], ribbon.labels[a]) for a, b in runs(ribbon.labels)
             if ribbon.labels[a] >= 0]
    ax.broken_barh([(x, w) for x, w, _ in spans], (0, 1),
                   facecolors=[ribbon.colours[k] for *_, k in spans], edgecolor="none")
    duration = edges[-1] - edges[0]
    points_per_second = ax.get_position().width * ax.figure.get_figwidth() * 72 / duration
    for x, width, k in spans:
        if (width >= NAMED_RUN * duration and width * points_per_second
                >= NAME_WIDTH_EM * plt.rcParams["font.size"] * len(ribbon.names[k])):
            dark = np.dot(ribbon.colours[k][:3], (0.299, 0.587, 0.114)) < 0.5
            ax.text(x + width / 2, 0.5, ribbon.names[k], ha="center", va="center",
                    color="white" if dark else "black", clip_on=True)
    ax.set_xlim(edges[0], edges[-1])
    ax.set_ylim(0, 1)
    ax.set_yticks([0.5], [ribbon.label])
    ax.tick_params(axis="y", length=0)
    for side in ("top", "right", "left"):
        ax.spines[side].set_visible(False)


def legend_handles(names: Sequence[str], colours: np.ndarray) -> list[Patch]:
    """One legend patch per class, in the colours the ribbons use."""
    return [Patch(facecolor=c, label=n) for n, c in zip(names, colours)]


def _vocabularies(ribbons: Sequence[Ribbon]) -> dict[tuple[str, ...], np.ndarray]:
    """Each class vocabulary of ``ribbons`` once, in order, with its colours."""
    vocabularies: dict[tuple[str, ...], np.ndarray] = {}
    for r in ribbons:
        vocabularies.setdefault(r.names, r.colours)
    return vocabularies


def legend_rows(ribbons: Sequence[Ribbon]) -> int:
    """Rows the legends of ``layout_with_legends`` take: ``LEGEND_COLUMNS`` classes a row."""
    return sum(-(-len(names) // LEGEND_COLUMNS) for names in _vocabularies(ribbons))


def layout_with_legends(fig: plt.Figure, ribbons: Sequence[Ribbon]) -> None:
    """Lay out ``fig``'s axes above the legends of the class vocabularies of ``ribbons`` (each
    vocabulary once, in order, in rows of at most ``LEGEND_COLUMNS`` classes, text of
    ``MIN_TEXT_PT``), then draw the legends."""
    row = LEGEND_ROW_INCHES / fig.get_figheight()
    below = legend_rows(ribbons)
    fig.tight_layout(rect=(0, row * below, 1, 1))
    for names, colours in _vocabularies(ribbons).items():
        below -= -(-len(names) // LEGEND_COLUMNS)
        fig.legend(handles=legend_handles(names, colours), loc="lower center",
                   ncol=min(len(names), LEGEND_COLUMNS), fontsize=MIN_TEXT_PT, frameon=False,
                   bbox_to_anchor=(0.5, row * below))


@figure_style
def plot_ribbons(ribbons: Sequence[Ribbon], path: Path | str, title: str = "") -> Path:
    """Save a figure of stacked ribbons (time in seconds) with a legend of their classes.

    Args:
        ribbons: the label sequences, top to bottom.
        path: the PNG written (folders created).
        title: the figure's title; empty = none.

    Returns:
        ``path``.
    """
    fig, axes = plt.subplots(len(ribbons), 1, sharex=True, squeeze=False,
                             figsize=(10, 0.4 * len(ribbons) + 0.8
                                      + LEGEND_ROW_INCHES * legend_rows(ribbons)))
    for ax, ribbon in zip(axes[:, 0], ribbons):
        draw_ribbon(ax, ribbon)
    axes[-1, 0].set_xlim(0, max(sample_edges(r.times)[-1] for r in ribbons))
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        axes[0, 0].set_title(title)
    layout_with_legends(fig, ribbons)
    return save_png(fig, path)


def save_png(fig: plt.Figure, path: Path | str, dpi: int = 110) -> Path:
    """Write ``fig`` to ``path`` (folders created) and close it.

    Args:
        fig: the figure.
        path: the PNG written.
        dpi: resolution, in dots per inch.

    Returns:
        ``path`` as a ``Path``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def plot_dataset(trials, path: Path | str, sample_hz: float, gesture_names: Sequence[str],
                 stage_names: Sequence[str]) -> Path:
    """Gesture and progress ribbons of every trial (two rows per trial) in one PNG.

    Args:
        trials: ``jigsaws_tools.dataset.Trial`` objects (labels at ``sample_hz``).
        path: the PNG to write.
        sample_hz: rate of the trials' samples (5 Hz after preprocessing).
        gesture_names: the task's gesture classes, in index order.
        stage_names: the progress stages, in order.
    """
    gestures = (tuple(gesture_names), task_colours(len(gesture_names), ordered=False))
    stages = (tuple(stage_names), task_colours(len(stage_names), ordered=True))
    ribbons = []
    for t in trials:
        times = np.arange(len(t)) / sample_hz
        ribbons.append(Ribbon(f"{t.name} gesture", t.gestures, times, *gestures))
        ribbons.append(Ribbon("progress", t.progress, times, *stages))
    return plot_ribbons(ribbons, path)
