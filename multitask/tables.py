"""The paper's Tables I-III and the annotation ablation, as CSV and booktabs LaTeX.

Every table compares two sides metric by metric: ours against the paper's published numbers
(Tables I-III), or revised against original labels (ablation). A table is a long frame with one
row per (model, metric): ``left_mean, left_std, right_mean, right_std, diff`` (left - right) and
``folds``. LaTeX cells are ``mean (std)``; the best value of each side and metric is bold, as in the
paper (highest, lowest for MAE).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import pandas as pd

from .collect import LOWER_IS_BETTER, METRICS, finite, lookup
from .paper_results import TABLE_1, TABLE_2, TABLE_2_RELATED, TABLE_3, Number

METRIC_LABELS = {"gesture_accuracy": "A Accuracy", "gesture_edit": "A Edit",
                 "gesture_f1@10": "A F1@10", "progress_mae": "P MAE",
                 "progress_mae_raw": "P MAE (raw)",
                 "progress_accuracy": "P Accuracy", "progress_edit": "P Edit",
                 "progress_f1@10": "P F1@10"}
CONFIG_LABELS = {"A-fixed": "A", "APr-fixed": "APr (w1=w2=1)", "APr-gradnorm": "APr (alpha=1.5)",
                 "APc-fixed": "APc (w1=w2=1)", "APc-gradnorm": "APc (alpha=1.5)",
                 "APoc-fixed": "APoc (w1=w2=1)", "APoc-gradnorm": "APoc (alpha=1.5)",
                 "Pr-fixed": "Pr", "Pc-fixed": "Pc", "Poc-fixed": "Poc"}
_LATEX_LABELS = {"(w1=w2=1)": "($w_1{=}w_2{=}1$)", "(alpha=1.5)": r"($\alpha{=}1.5$)"}


@dataclass(frozen=True)
class PaperTable:
    """One of the paper's tables: which runs it reads and the published numbers."""

    name: str
    caption: str
    annotations: str
    direction: str
    paper: dict[str, dict[str, Number]]
    metrics: tuple[str, ...]
    labels: dict[str, str] = field(default_factory=dict)       # config -> row label override
    related: dict[str, dict[str, Number]] = field(default_factory=dict)   # paper-only rows


PAPER_TABLES = (
    PaperTable("table1", "Gesture recognition (A) and progress estimation (P), revised "
               "annotations: mean (std) over folds, ours against the paper's Table I.",
               "revised", "bidirectional", TABLE_1, tuple(METRICS)),
    PaperTable("table2", "Original JIGSAWS annotations: ours against the paper's Table II "
               "(w1 = w2 = 1; BiLSTM = our model A against DiPietro et al.'s published result).",
               "original", "bidirectional", TABLE_2, ("gesture_accuracy", "gesture_edit"),
               labels={"A-fixed": "BiLSTM (A)", "APoc-fixed": "APoc", "APc-fixed": "APc"},
               related=TABLE_2_RELATED),
    PaperTable("table3", "Online gesture recognition with a forward LSTM: ours against the "
               "paper's Table III.", "revised", "forward", TABLE_3,
               ("gesture_accuracy", "gesture_edit"),
               labels={"A-fixed": "LSTM (A)", "APc-fixed": "APc"}),
)


def paper_comparison(summary: pd.DataFrame, table: PaperTable) -> pd.DataFrame:
    """Ours (left) against the paper (right) for every configuration of ``table`` the grid ran,
    then the paper-only related-work rows."""
    rows = []
    for config, published in table.paper.items():
        ours = lookup(summary, table.annotations, table.direction, config)
        if ours is None:
            continue
        label = _marked(table.labels.get(config, CONFIG_LABELS[config]), ours)
        for metric in table.metrics:
            mean = finite(ours.get(f"{metric}_mean"))
            paper = published.get(metric)
            if mean is None and paper is None:
                continue
            rows.append(_row(label, config, metric, (mean, finite(ours.get(f"{metric}_std"))),
                             paper or (None, None), int(ours["folds"])))
    for name, published in table.related.items() if rows else ():
        rows.extend(_row(name, "", metric, (None, None), published[metric], 0)
                    for metric in table.metrics if metric in published)
    return pd.DataFrame(rows, columns=_COLUMNS)


def annotation_ablation(summary: pd.DataFrame, direction: str = "bidirectional") -> pd.DataFrame:
    """Revised (left) against original (right) labels for every configuration run with both."""
    rows = []
    bi = summary[summary.direction == direction]
    for (variant, weighting), group in bi.groupby(["variant", "weighting"], sort=False):
        versions = group.set_index("annotations")
        if not {"revised", "original"} <= set(versions.index):
            continue
        config = f"{variant}-{weighting}"
        revised, original = versions.loc["revised"], versions.loc["original"]
        for metric in METRICS:
            left = finite(revised.get(f"{metric}_mean"))
            right = finite(original.get(f"{metric}_mean"))
            if left is None and right is None:
                continue
            rows.append(_row(_marked(CONFIG_LABELS.get(config, config), revised, original),
                             config, metric,
                             (left, finite(revised.get(f"{metric}_std"))),
                             (right, finite(original.get(f"{metric}_std"))),
                             int(min(revised["folds"], original["folds"]))))
    frame = pd.DataFrame(rows, columns=_COLUMNS)
    order = {c: i for i, c in enumerate(CONFIG_LABELS)}
    return frame.sort_values("config", key=lambda s: s.map(order), kind="stable")


_COLUMNS = ["model", "config", "metric", "left_mean", "left_std", "right_mean", "right_std",
            "diff", "folds"]


def _row(label: str, config: str, metric: str, left: Number, right: Number, folds: int) -> dict:
    diff = None if left[0] is None or right[0] is None else left[0] - right[0]
    return dict(zip(_COLUMNS, (label, config, metric, left[0], left[1], right[0], right[1], diff,
                               folds)))


def _marked(label: str, *summary_rows: pd.Series) -> str:
    """``label``, followed by "(incomplete: n/m runs)" when a configuration's summary row says it
    lacks runs (``multitask-tables --allow-incomplete``)."""
    if all(row.get("complete", True) for row in summary_rows):
        return label
    runs = sum(int(row["runs"]) for row in summary_rows)
    expected = sum(int(row["runs_expected"]) for row in summary_rows)
    return f"{label} (incomplete: {runs}/{expected} runs)"


def paper_best(table: PaperTable) -> dict[str, float]:
    """The value the paper prints in bold for each metric: best over its whole table."""
    published = [*table.paper.values(), *table.related.values()]
    return {m: _best(pd.Series([p[m][0] for p in published if m in p], dtype=float), m)
            for m in table.metrics}


def to_latex(frame: pd.DataFrame, caption: str, label: str, sides: tuple[str, str],
             right_best: dict[str, float] | None = None) -> str:
    """A booktabs table: one row per model, per metric three columns ``sides[0] | sides[1] |
    Delta``; the best value per side and metric is bold (``right_best`` overrides the right
    side's, e.g. the paper's bold over its full table)."""
    metrics = [m for m in METRICS if m in set(frame.metric)]
    models = list(dict.fromkeys(frame.model))
    cells = {(r.model, r.metric): r for r in frame.itertuples(index=False)}
    best = {(m, side): _best(frame[frame.metric == m][f"{side}_mean"], m)
            for m in metrics for side in ("left", "right")}
    best.update({(m, "right"): v for m, v in (right_best or {}).items()})
    lines = [r"\begin{table*}[t]", r"\centering", rf"\caption{{{_escape(caption)}}}",
             rf"\label{{tab:{label}}}", r"\resizebox{\textwidth}{!}{%",
             r"\begin{tabular}{l" + "rrr" * len(metrics) + "}", r"\toprule",
             " & ".join(["Model"] + [rf"\multicolumn{{3}}{{c}}{{{METRIC_LABELS[m]}}}"
                                     for m in metrics]) + r" \\",
             " ".join(rf"\cmidrule(lr){{{2 + 3 * i}-{4 + 3 * i}}}" for i in range(len(metrics))),
             " & ".join([""] + [rf"{sides[0]} & {sides[1]} & $\Delta$"] * len(metrics)) + r" \\",
             r"\midrule"]
    for model in models:
        row = [_latex_label(model)]
        for m in metrics:
            cell = cells.get((model, m))
            if cell is None:
                row += ["--"] * 3
                continue
            row += [_cell(cell.left_mean, cell.left_std, cell.left_mean == best[(m, "left")]),
                    _cell(cell.right_mean, cell.right_std, cell.right_mean == best[(m, "right")]),
                    "--" if finite(cell.diff) is None else f"{cell.diff:+.1f}"]
        lines.append(" & ".join(row) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}}", r"\end{table*}"]
    return "\n".join(lines) + "\n"


def _latex_label(text: str) -> str:
    for plain, latex in _LATEX_LABELS.items():
        text = text.replace(plain, latex)
    return text


def _best(values: pd.Series, metric: str) -> float | None:
    values = values.dropna()
    if values.empty:
        return None
    return float(values.min() if metric in LOWER_IS_BETTER else values.max())


def _cell(mean, std, bold: bool) -> str:
    if finite(mean) is None:
        return "--"
    text = f"{mean:.1f}" + ("" if finite(std) is None else f" ({std:.1f})")
    return rf"\textbf{{{text}}}" if bold else text


def _escape(text: str) -> str:
    return text.replace("%", r"\%").replace("&", r"\&").replace("_", r"\_")
