"""The paper's Tables I-III and the annotation ablation, as CSV and paste-ready LaTeX.

Every table compares two sides metric by metric: ours against the paper's published numbers
(Tables I-III), or revised against original labels (ablation). A table is a long frame with one
row per (model, metric): ``left_mean, left_std, right_mean, right_std, diff`` (left - right) and
``folds``.

The LaTeX (``to_latex``) is laid out as the paper's Table I: one column per model, one block of
rows per metric (the two sides and their difference, or ours alone with ``ours_only``), metrics
grouped by task. Its width grows with the models, not the metrics, so Table I (10 models) fits an
IEEE two-column page's text width (``table*``) at footnote size and the smaller tables a column,
without scaling. Cells are ``mean (std)`` with true minus signs; the best value of each row is
bold (highest, lowest for MAE; the paper's rows keep the paper's own bold), as a note under the
table says. Each file starts with a comment naming the packages it needs (booktabs).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from itertools import groupby

import pandas as pd

from ..runs.collect import CONVERGENCE_COUNTS, LOWER_IS_BETTER, METRICS, finite, lookup
from .latex import bold, escape, mean_std, number, requires
from .paper_results import TABLE_1, TABLE_2, TABLE_2_RELATED, TABLE_3, Number

#: Metric -> the paper's name for it, after the letter of its task ("A" gestures, "P" progress).
METRIC_LABELS = {"gesture_accuracy": "A Accuracy", "gesture_edit": "A Edit",
                 "gesture_f1@10": "A F1@10", "progress_mae": "P MAE",
                 "progress_mae_raw": "P MAE (raw)",
                 "progress_accuracy": "P Accuracy", "progress_edit": "P Edit",
                 "progress_f1@10": "P F1@10"}
#: Task of a metric (its name's prefix) -> the heading of its rows (the paper's letter for it).
TASK_HEADINGS = {"gesture": "Gesture recognition (A)", "progress": "Progress estimation (P)"}
CONFIG_LABELS = {"A-fixed": "A", "APr-fixed": "APr (w1=w2=1)", "APr-gradnorm": "APr (alpha=1.5)",
                 "APc-fixed": "APc (w1=w2=1)", "APc-gradnorm": "APc (alpha=1.5)",
                 "APoc-fixed": "APoc (w1=w2=1)", "APoc-gradnorm": "APoc (alpha=1.5)",
                 "Pr-fixed": "Pr", "Pc-fixed": "Pc", "Poc-fixed": "Poc"}
#: An LSTM's architecture name (``pooling.architecture_name``), e.g. ``LSTM-128``.
_LSTM_NAME = re.compile(r"LSTM-\d+")
#: Parenthesised detail of a model label -> its LaTeX in the column header's second line.
_LATEX_DETAILS = {"w1=w2=1": "$w_1{=}w_2{=}1$", "alpha=1.5": r"$\alpha{=}1.5$"}
#: Model columns up to which a table fits one IEEE column; wider ones span the page (table*).
COLUMN_TABLE_MODELS = 4
PACKAGES = ("booktabs",)


@dataclass(frozen=True)
class PaperTable:
    """One of the paper's tables: which runs it reads and the published numbers."""

    name: str
    title: str                  # LaTeX: what it shows; the caption adds comparison and budget
    source: str                 # the paper's name for it
    annotations: str
    direction: str
    paper: dict[str, dict[str, Number]]
    metrics: tuple[str, ...]
    labels: dict[str, str] = field(default_factory=dict)       # config -> row label override
    related: dict[str, dict[str, Number]] = field(default_factory=dict)   # paper-only rows
    note: str = ""              # added to the caption when the paper's columns are shown
    rows_name_encoder: bool = False     # its rows name architectures (BiLSTM, TCN), not models


PAPER_TABLES = (
    PaperTable("table1", "Gesture recognition (A) and progress estimation (P), revised annotations",
               "Table I", "revised", "bidirectional", TABLE_1, tuple(METRICS)),
    PaperTable("table2", "Gesture recognition with the original JIGSAWS annotations "
               "($w_1{=}w_2{=}1$)",
               "Table II", "original", "bidirectional", TABLE_2,
               ("gesture_accuracy", "gesture_edit"),
               labels={"A-fixed": "BiLSTM (A)", "APoc-fixed": "APoc", "APc-fixed": "APc"},
               related=TABLE_2_RELATED,
               note="Paper's BiLSTM: DiPietro et al.'s published result; TCN, TCN+RL: the "
                    "related work it lists, not reproduced here.", rows_name_encoder=True),
    PaperTable("table3", "Online gesture recognition with a forward LSTM, revised annotations",
               "Table III", "revised", "forward", TABLE_3, ("gesture_accuracy", "gesture_edit"),
               labels={"A-fixed": "LSTM (A)", "APc-fixed": "APc"},
               note="Paper's LSTM: DiPietro et al.'s published result.", rows_name_encoder=True),
)


def encoder_label(label: str, name: str) -> str:
    """A row label of ``table.labels`` or ``CONFIG_LABELS`` for runs of the encoder ``name``
    (``pooling.architecture_name``): an LSTM's width joins the paper's encoder (``BiLSTM (A)``
    -> ``BiLSTM-128 (A)``), another encoder replaces it (-> ``ED-TCN (A)``), and a model's
    label names the encoder after it (``APc`` -> ``APc (ED-TCN)``)."""
    for paper in ("BiLSTM", "LSTM"):
        if label.startswith(paper):
            return label.replace("LSTM", name, 1) if _LSTM_NAME.fullmatch(name) \
                else name + label[len(paper):]
    return f"{label} ({name})"


def encoder_labels(table: PaperTable, name: str) -> dict[str, str]:
    """``encoder_label`` of every configuration ``table`` publishes."""
    return {config: encoder_label(table.labels.get(config, CONFIG_LABELS[config]), name)
            for config in table.paper}


def of_encoder(table: PaperTable, name: str) -> PaperTable:
    """``table`` for runs of another encoder than the paper's LSTM (``name``, e.g. ``ED-TCN``).
    A table whose rows name architectures (Tables II and III) labels ours by the encoder and
    shows them alone: the paper has no such row, and its BiLSTM's numbers beside our ED-TCN's
    would read as the paper's ED-TCN; its quoted rows stay, its title names the encoder. A table
    of models (Table I) keeps the paper's numbers, which its caption says are its LSTM's."""
    if not table.rows_name_encoder:
        return replace(table, note=f"The paper's numbers are its LSTM's: the difference "
                                   f"compares our {name} with them.")
    quoted = (f" {', '.join(table.related)}: the related work the paper lists, not reproduced "
              "here." if table.related else "")
    return replace(table, title=table.title.replace("LSTM", escape(name)),
                   paper={config: {} for config in table.paper},
                   labels=encoder_labels(table, name),
                   note=f"Ours: {name}, which the paper did not run.{quoted}")


def paper_caption(table: PaperTable, budget: str, ours_only: bool = False) -> str:
    """The caption (LaTeX) of ``table``: what it shows, the comparison and the runs' budget.

    Args:
        table: the paper's table.
        budget: plain text (escaped here): data, folds, width, epochs, seeds
            (``captions.RunsDescription.sentence``).
        ours_only: the table shows our numbers alone, without the paper's columns.
    """
    if ours_only:
        return f"{table.title}: mean (std) over folds. {escape(budget)}"
    note = f" {escape(table.note)}" if table.note else ""
    if not any(table.paper.values()):            # ours alone beside the quoted rows
        return (f"{table.title}: ours beside the paper's {table.source}, mean (std) over "
                f"folds.{note} {escape(budget)}")
    return (f"{table.title}: ours against the paper's {table.source}, mean (std) over folds; "
            rf"$\Delta$ = ours $-$ paper.{note} {escape(budget)}")


def ablation_caption(budget: str) -> str:
    """The caption (LaTeX) of the annotation ablation, with the runs' ``budget`` (plain text)."""
    return ("Annotation versions: each configuration trained on both, revised against original "
            rf"labels, mean (std) over folds; $\Delta$ = revised $-$ original. {escape(budget)}")


def table_runs(runs: pd.DataFrame, frame: pd.DataFrame, annotations: tuple[str, ...],
               direction: str) -> pd.DataFrame:
    """The rows of ``runs`` behind a comparison table: its configurations with the given
    annotation versions and direction.

    Args:
        runs: one row per run (``collect.run_rows``).
        frame: the comparison table (``paper_comparison``, ``annotation_ablation``); its
            ``config`` column names the configurations.
        annotations: the annotation versions compared, e.g. ``("revised", "original")``.
        direction: the encoder's, ``"bidirectional"`` or ``"forward"``.
    """
    configs = set(frame.config)
    return runs[runs.annotations.isin(annotations) & (runs.direction == direction)
                & (runs.variant + "-" + runs.weighting).isin(configs)]


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
    rows += related_rows(table) if rows else []
    return pd.DataFrame(rows, columns=_COLUMNS)


def related_rows(table: PaperTable) -> list[dict]:
    """The paper-only rows of ``table`` (``paper_comparison``'s columns): the related work it
    quotes (Table II's TCN, TCN+RL), the published numbers on the right, nothing on our side."""
    return [_row(name, "", metric, (None, None), published[metric], 0)
            for name, published in table.related.items()
            for metric in table.metrics if metric in published]


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
    """``label``, followed by what its summary rows say against the evidence: "(incomplete: n/m
    runs)" when a configuration lacks runs (``multitask-tables paper --allow-incomplete``), "(still
    falling: n runs)" and "(undecided: n runs)" for its runs of those three-way convergence
    verdicts (``rnn_seg.convergence``), in one parenthesis separated by "; "."""
    notes = []
    if not all(row.get("complete", True) for row in summary_rows):
        runs = sum(int(row["runs"]) for row in summary_rows)
        expected = sum(int(row["runs_expected"]) for row in summary_rows)
        notes.append(f"incomplete: {runs}/{expected} runs")
    for column, state in CONVERGENCE_COUNTS.items():
        count = sum(int(row.get(column, 0)) for row in summary_rows)
        if count:
            notes.append(f"{state}: {count} run{'s' if count > 1 else ''}")
    return f"{label} ({'; '.join(notes)})" if notes else label


def paper_best(table: PaperTable) -> dict[str, float]:
    """The value the paper prints in bold for each metric: best over its whole table."""
    published = [*table.paper.values(), *table.related.values()]
    return {m: _best(pd.Series([p[m][0] for p in published if m in p], dtype=float), m)
            for m in table.metrics}


def to_latex(frame: pd.DataFrame, caption: str, label: str, sides: tuple[str, str],
             right_best: dict[str, float] | None = None, ours_only: bool = False) -> str:
    """A booktabs table of ``frame``: one column per model, per metric the rows ``sides[0]``,
    ``sides[1]`` and Delta (``ours_only``: ``sides[0]`` alone, models without it left out).

    Args:
        frame: a comparison table (``paper_comparison``, ``annotation_ablation``).
        caption: LaTeX (plain text goes through ``latex.escape``).
        label: ``\\label{tab:<label>}``.
        sides: the names of the left and right side (``("Ours", "Paper")``).
        right_best: the value bold in the right side's rows, per metric (the paper's bold over
            its whole table); default: the best of the row, as for the left side.
        ours_only: leave out the right side and the difference.
    """
    if ours_only:
        frame = frame[frame.left_mean.notna()]
    models = list(dict.fromkeys(frame.model))
    rows = [("left", sides[0])] if ours_only else [("left", sides[0]), ("right", sides[1]),
                                                    ("diff", r"$\Delta$")]
    labels = 1 if ours_only else 2          # metric (and side) label columns
    wide = len(models) > COLUMN_TABLE_MODELS
    env = "table*" if wide else "table"
    note = ("Bold: the best value of each row (lowest MAE, highest otherwise)"
            + ("" if ours_only or right_best is None else
               f"; in the {sides[1]} rows, as the paper prints it (best of its table)") + ".")
    marked = [(name, evidence) for name, evidence in map(_split_evidence, models) if evidence]
    flagged = [(name, e) for name, e in marked if _flagged(e)]
    if flagged:
        note += (r" $^\dagger$\," + "; ".join(f"{_latex_model(name)}: {escape(evidence)}"
                                              for name, evidence in flagged) + ".")
    undecided = [(name, e) for name, e in marked if not _flagged(e)]
    if undecided:
        note += (" Runs of undecided convergence (the 95\\,\\% interval of the final loss "
                 "drop holds the tolerance): " + "; ".join(
                     f"{_latex_model(name)}: {escape(evidence.removeprefix('undecided: '))}"
                     for name, evidence in undecided) + ".")
    return "".join([
        requires(*PACKAGES),
        f"\\begin{{{env}}}[t]\n\\centering\n\\footnotesize\n",
        f"\\caption{{{caption}}}\n\\label{{tab:{label}}}\n",
        f"\\setlength{{\\tabcolsep}}{{{2 if wide else 4}pt}}\n",
        f"\\begin{{tabular}}{{@{{}}{'l' * labels}@{{\\hspace{{6pt}}}}"
        f"{'c' * len(models)}@{{}}}}\n\\toprule\n",
        *(line + "\n" for line in _header(models, labels)), "\\midrule\n",
        *(line + "\n" for line in _body(frame, models, rows, labels, right_best)),
        "\\bottomrule\n\\end{tabular}\n",
        f"\\par\\smallskip\n\\parbox{{\\linewidth}}{{\\footnotesize {note}}}\n",
        f"\\end{{{env}}}\n"])


def _body(frame: pd.DataFrame, models: list[str], rows: list[tuple[str, str]], labels: int,
          right_best: dict[str, float] | None) -> list[str]:
    """The table's rows: per task a heading, per metric one row per side."""
    metrics = [m for m in METRICS if m in set(frame.metric)]
    metrics += [m for m in dict.fromkeys(frame.metric) if m not in metrics]
    cells = {(r.model, r.metric): r for r in frame.itertuples(index=False)}
    best = {(m, side): _best(frame[frame.metric == m][f"{side}_mean"], m)
            for m in metrics for side in ("left", "right")}
    best.update({(m, "right"): v for m, v in (right_best or {}).items()})
    lines = []
    for k, (task, group) in enumerate(groupby(metrics, key=lambda m: m.split("_", 1)[0])):
        heading = TASK_HEADINGS.get(task, escape(task))
        lines += [r"\midrule"] * bool(k) + [
            rf"\multicolumn{{{labels + len(models)}}}{{@{{}}l}}{{\emph{{{heading}}}}} \\"]
        for i, metric in enumerate(group):
            lines += [r"\addlinespace"] * bool(i and len(rows) > 1)
            for j, (side, side_label) in enumerate(rows):
                row = [_metric_label(metric) if j == 0 else ""] + [side_label] * (labels - 1)
                row += [_cell(cells.get((model, metric)), side, best) for model in models]
                lines.append(" & ".join(row) + r" \\")
    return lines


#: What ``_marked`` appends to a model's label about its evidence, split off for LaTeX.
_EVIDENCE = re.compile(r"(.*) \(((?:incomplete|still falling|undecided): [^()]*)\)")


def _split_evidence(model: str) -> tuple[str, str]:
    """``"APc (w1=w2=1) (still falling: 2 runs)"`` -> ``("APc (w1=w2=1)", "still falling: 2
    runs")``; an unmarked label -> ``(label, "")``."""
    match = _EVIDENCE.fullmatch(model)
    return (match.group(1), match.group(2)) if match else (model, "")


def _flagged(evidence: str) -> bool:
    """Whether ``_marked``'s evidence calls for a dagger: runs missing or still falling (runs
    that are only undecided are named in the note alone)."""
    return evidence.startswith(("incomplete", "still falling")) or "; still falling" in evidence


def _name_and_detail(model: str) -> tuple[str, str]:
    """``"APr (w1=w2=1)"`` -> ``("APr", "w1=w2=1")``."""
    match = re.fullmatch(r"(.*?) \((.*)\)", model)
    return (match.group(1), match.group(2)) if match else (model, "")


def _latex_detail(detail: str) -> str:
    return _LATEX_DETAILS.get(detail, f"({escape(detail)})" if detail else "")


def _latex_model(model: str) -> str:
    """A model label in running LaTeX text: ``APr ($w_1{=}w_2{=}1$)``."""
    name, detail = _name_and_detail(model)
    return escape(name) + (f" {_latex_detail(detail)}" if detail else "")


def _header(models: list[str], labels: int) -> list[str]:
    """The column headers: model names (a dagger where ``_marked`` noted the evidence), and a
    second line for the details in parentheses (``APr (w1=w2=1)`` -> ``APr`` over
    ``w_1 = w_2 = 1``)."""
    names, details = [], []
    for model in models:
        base, evidence = _split_evidence(model)
        name, detail = _name_and_detail(base)
        names.append(escape(name) + (r"$^\dagger$" if _flagged(evidence) else ""))
        details.append(_latex_detail(detail))
    blank = [""] * labels
    header = [" & ".join(blank + names) + r" \\"]
    if any(details):
        header.append(" & ".join(blank + details) + r" \\")
    return header


def _metric_label(metric: str) -> str:
    """A metric's row label within its task's rows: ``METRIC_LABELS`` without the task's letter
    (``gesture_f1@10`` -> ``F1@10``), an unknown metric's name in words."""
    if metric in METRIC_LABELS:
        return METRIC_LABELS[metric].split(" ", 1)[1]
    return escape(metric.split("_", 1)[1].replace("_", " "))


def _cell(cell, side: str, best: dict) -> str:
    if cell is None:
        return "--"
    if side == "diff":
        return number(finite(cell.diff), signed=True)
    mean = finite(getattr(cell, f"{side}_mean"))
    text = mean_std(mean, finite(getattr(cell, f"{side}_std")))
    return bold(text) if mean is not None and mean == best[(cell.metric, side)] else text


def _best(values: pd.Series, metric: str) -> float | None:
    values = values.dropna()
    if values.empty:
        return None
    return float(values.min() if metric in LOWER_IS_BETTER else values.max())
