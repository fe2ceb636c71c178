"""The JIGSAWS tasks side by side: model A's gesture scores and each multi-task model minus A.

Reads the tables ``multitask-tables`` wrote for each task (``summary.csv``, ``claims.csv``): A's
mean over folds, and for APc and APoc with either weighting the paired difference to A over
folds with its 95 % interval and verdict (``claims``: the paper's claims on Suturing, the
conjecture's on the other tasks; both test the same contrasts of offline models on revised
labels). Nothing is recomputed, so the summary agrees with each task's own tables.

    multitask-tables tasks Suturing=results Knot_Tying=results/tasks/Knot_Tying \\
        Needle_Passing=results/tasks/Needle_Passing --out results/tasks

writes ``tasks.csv`` (one row per task, model and score) and ``tasks.md`` (the table of
``results/tasks/README.md``).
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from rnn_seg.runs.folder import write_atomic

from ..render.markdown import markdown_table
from ..statistics.paired import ConfigId

#: The multi-task models compared with A (``<variant>-<weighting>``).
MODELS = ("APc-fixed", "APc-gradnorm", "APoc-fixed", "APoc-gradnorm")
#: Score -> its name in the Markdown table.
SCORES = {"gesture_accuracy": "Accuracy", "gesture_edit": "Edit", "gesture_f1@10": "F1@10"}
BASELINE = "A-fixed"
COLUMNS = ["task", "model", "score", "value", "ci_low", "ci_high", "verdict", "folds", "seeds"]


def task_rows(task: str, tables: Path) -> list[dict]:
    """``COLUMNS`` rows of one task: A's mean scores, then each of ``MODELS`` minus A.

    Args:
        task: the task's name, e.g. ``"Knot_Tying"``.
        tables: the folder of its ``summary.csv`` and ``claims.csv``.

    Raises:
        ValueError: naming the file, when A or a contrast is missing from it.
    """
    summary, claims = (_read(tables / name) for name in ("summary.csv", "claims.csv"))
    a = ConfigId.parse(BASELINE).select(summary)
    if a.empty:
        raise ValueError(f"{tables / 'summary.csv'}: no revised bidirectional A-fixed row")
    rows = []
    for model in MODELS:
        for score in SCORES:
            found = claims[(claims.comparison == f"{model} - {BASELINE}")
                           & (claims.metric == score)]
            if found.empty:
                raise ValueError(f"{tables / 'claims.csv'}: no claim of {model} - {BASELINE} "
                                 f"on {score}")
            claim = found.iloc[0]
            rows.append({"task": task, "model": f"{model} - A", "score": score,
                         "value": claim.ours_diff, "ci_low": claim.ci_low,
                         "ci_high": claim.ci_high, "verdict": claim.verdict,
                         "folds": int(claim.folds), "seeds": int(claim.seeds)})
    return [{"task": task, "model": "A", "score": score, "value": a.iloc[0][f"{score}_mean"],
             "folds": int(a.iloc[0].folds), "seeds": rows[0]["seeds"]} for score in SCORES] + rows


def _read(path: Path) -> pd.DataFrame:
    try:
        return pd.read_csv(path)
    except (OSError, ValueError) as error:
        raise ValueError(f"{path}: unreadable ({error})") from None


def task_table(folders: dict[str, Path]) -> pd.DataFrame:
    """``COLUMNS`` rows of every task, in the order given (``task_rows``)."""
    return pd.DataFrame([row for task, tables in folders.items()
                         for row in task_rows(task, tables)], columns=COLUMNS)


def markdown(table: pd.DataFrame) -> str:
    """One line per task and model: A's scores, or a difference with its 95 % interval and
    verdict; the folds and seeds of each task's evidence."""
    header = ["task", "model", *SCORES.values(), "folds x seeds"]
    body = [[task.replace("_", " "), model, *(_cell(row) for row in rows.itertuples()),
             f"{rows.iloc[0].folds} x {rows.iloc[0].seeds}"]
            for (task, model), rows in table.groupby(["task", "model"], sort=False)]
    return "\n".join(markdown_table(header, body)) + "\n"


def _cell(row) -> str:
    if pd.isna(row.ci_low):
        return f"{row.value:.1f}"
    return f"{row.value:+.1f} [{row.ci_low:+.1f}, {row.ci_high:+.1f}] {row.verdict}"


def write_tasks(folders: dict[str, Path], out: Path) -> list[Path]:
    """``tasks.csv`` and ``tasks.md`` of the tasks in ``folders`` (task -> the folder of its
    tables) into ``out``; returns their paths."""
    table = task_table(folders)
    written = [out / "tasks.csv", out / "tasks.md"]
    write_atomic(written[0], table.to_csv(index=False, float_format="%.4f"))
    write_atomic(written[1], markdown(table))
    return written
