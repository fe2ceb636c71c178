"""The convergence ladders of ``results/tcn/PLAN_factors.md``, section E: per run, the project's
convergence check (``rnn_seg.convergence``) applied to its training loss cut at each length of a
ladder, as if the schedule had ended there; per backbone, the shortest length at which no run is
still falling.

With a constant learning rate a run's first E epochs do not depend on its schedule's length, so
one run trained for the ladder's longest length answers every shorter one from its
``history.csv`` (``n`` <= E, the schedule's length taken as E). Only the ``loss_<task>`` columns
are read: the runs' validation scores are not. Lengths are in the history's unit (epochs for
the TCNs' schedules).
"""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Sequence

import pandas as pd

from rnn_seg.convergence import drop_interval, history_convergence
from rnn_seg.runs.folder import HISTORY, write_atomic
from rnn_seg.runs.logs import read_log

from ..render.markdown import markdown_table
from ..runs.collect import CONFIG_COLUMNS, refuse_repeated, run_records
from ..runs.pooling import INNER_SETTING, architecture, architecture_name, record_key

#: Per run and length (``ladder_runs``), per grid, configuration and length (``ladder``), per
#: grid (``ladder_choice``).
RUNS_FILE, SUMMARY_FILE, CHOICE_FILE, REPORT_FILE = ("ladder_runs.csv", "ladder.csv",
                                                     "ladder_choice.csv", "ladder.md")
#: A run's verdict at a length whose last fifth holds too few epochs to fit a line
#: (``rnn_seg.convergence.MIN_POINTS``).
TOO_SHORT = "too short"
_COUNTS = {"converged": "converged", "undecided": "undecided", "still_falling": "still falling",
           "too_short": TOO_SHORT}


class LadderError(ValueError):
    """A ladder that the grid's runs cannot answer (a grid not finished, a run whose learning
    rate decays, a length beyond a run's schedule, a unit that is not the history's, no length
    long enough to judge every run)."""


def ladder_runs(grid: Path, lengths: Sequence[int]) -> pd.DataFrame:
    """One row per finished run of ``grid`` and ladder length: the run's key columns, ``length``,
    the worst task's ``loss_drop`` over the last tenth of epochs 1..length, its 95 % interval
    (``drop_low``, ``drop_high``) and the three-way ``verdict`` (``TOO_SHORT`` where the length
    is too short to judge).

    Raises:
        LadderError: a grid with a problem (a run not finished, a stray folder: the first named,
            in one line), a run whose learning rate decays (its first epochs depend on its
            schedule's length), a length longer than a run's schedule, or a run whose history
            counts another unit than epochs.
    """
    _, problems, records = run_records(grid, allow_incomplete=True, varying=(INNER_SETTING,))
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise LadderError(f"{grid}: {problems[0]}{more}: a ladder reads a finished grid")
    out = []
    for run_dir, record in sorted(records.items()):
        optim = record.config.optim
        total = optim.total
        if optim.decay_start < total:
            raise LadderError(f"{run_dir}: its learning rate decays from epoch "
                              f"{optim.decay_start} of {total}: a ladder needs a constant rate")
        history = read_log(run_dir / HISTORY)
        unit = str(history["unit"].iloc[0]) if "unit" in history and len(history) else "epochs"
        if unit != "epochs":
            raise LadderError(f"{run_dir / HISTORY}: unit {unit!r}: a ladder is in epochs")
        for length in lengths:
            if length > total:
                raise LadderError(f"{run_dir}: length {length} is beyond its schedule of "
                                  f"{total:g} epochs: train the pilot runs for the longest")
            cut = history[history["n"] <= length]
            check = history_convergence(cut, record.tasks, length)
            drop, se = check["max_loss_drop"], check["max_loss_drop_se"]
            low, high = (None, None) if drop is None else drop_interval(drop, se)
            out.append({"grid": str(grid), "architecture": architecture_name(architecture(record)),
                        **asdict(record_key(record)), "length": int(length),
                        "loss_drop": drop, "drop_low": low, "drop_high": high,
                        "verdict": check["verdict"] or TOO_SHORT})
    return pd.DataFrame(out)


def ladder_summary(runs: pd.DataFrame) -> pd.DataFrame:
    """Per grid, configuration and length: the runs and how many have each verdict."""
    keys = ["grid", "architecture", *CONFIG_COLUMNS, "length"]
    return runs.groupby(keys, sort=False).agg(
        runs=("verdict", "size"),
        **{name: ("verdict", lambda v, kind=kind: int((v == kind).sum()))
           for name, kind in _COUNTS.items()}).reset_index()


def ladder_choice(summary: pd.DataFrame) -> pd.DataFrame:
    """Per grid (a backbone's pilot runs): among the lengths that judge every run (none too
    short), the shortest at which no run is still falling, else the longest, with ``reason``
    saying which.

    Raises:
        LadderError: a grid whose every length leaves a run too short to judge.
    """
    out = []
    for grid, rows in summary.groupby("grid", sort=False):
        per_length = rows.groupby("length")[["still_falling", "too_short"]].sum().sort_index()
        judged = per_length[per_length.too_short == 0]
        if not len(judged):
            raise LadderError(f"{grid}: every length ({', '.join(map(str, per_length.index))}) "
                              f"is too short to judge a run: give a longer one")
        clear = judged[judged.still_falling == 0]
        if len(clear):
            length, reason = int(clear.index[0]), "the shortest length with no run still falling"
        else:
            length = int(judged.index[-1])
            falling = int(judged.still_falling.iloc[-1])
            reason = (f"every length leaves a run still falling ({falling} at the longest): "
                      f"the longest taken")
        out.append({"grid": grid, "architecture": rows["architecture"].iloc[0],
                    "length": length, "still_falling": int(per_length.still_falling.loc[length]),
                    "runs": int(rows[rows["length"] == length]["runs"].sum()), "reason": reason})
    return pd.DataFrame(out)


def write_ladder(grids: Sequence[Path], lengths: Sequence[int], out: Path) -> list[Path]:
    """``RUNS_FILE``, ``SUMMARY_FILE``, ``CHOICE_FILE`` and ``REPORT_FILE`` of the ladders of
    ``grids`` (each a backbone's pilot runs, or its scores archive) at ``lengths`` into
    ``out``; returns the paths written."""
    lengths = sorted(set(int(n) for n in lengths))
    refuse_repeated(grids, "its runs would be counted twice", LadderError)
    runs = pd.concat([ladder_runs(Path(grid), lengths) for grid in grids], ignore_index=True)
    summary = ladder_summary(runs)
    choice = ladder_choice(summary)
    files = {RUNS_FILE: runs.to_csv(index=False, float_format="%.6g"),
             SUMMARY_FILE: summary.to_csv(index=False),
             CHOICE_FILE: choice.to_csv(index=False),
             REPORT_FILE: _report(summary, choice, lengths)}
    paths = []
    for name, text in files.items():
        write_atomic(out / name, text)
        paths.append(out / name)
    return paths


def _report(summary: pd.DataFrame, choice: pd.DataFrame, lengths: list[int]) -> str:
    """The ladders as Markdown: still falling / undecided / converged runs per configuration
    and length, then each backbone's length and why."""
    table = summary.assign(
        configuration=summary["variant"] + "-" + summary["weighting"] + ", "
        + summary["annotations"],
        counts=[f"{r.still_falling} / {r.undecided} / {r.converged}"
                + (f" ({r.too_short} too short to judge)" if r.too_short else "")
                for r in summary.itertuples()])
    wide = table.pivot_table(index=["grid", "architecture", "configuration"], columns="length",
                             values="counts", aggfunc="first", sort=False).reset_index()
    header = ["grid", "backbone", "configuration", *[f"{n} epochs" for n in lengths]]
    body = [[row["grid"], row["architecture"], row["configuration"],
             *[row.get(n, "") for n in lengths]] for _, row in wide.iterrows()]
    chosen = [[row.grid, row.architecture, str(row.length), f"{row.still_falling} of {row.runs}",
               row.reason] for row in choice.itertuples()]
    lines = ["Runs still falling / undecided / converged (`rnn_seg.convergence`, training loss "
             "only) when the schedule is cut at each length:", "",
             *markdown_table(header, body), "",
             *markdown_table(["grid", "backbone", "length", "still falling", "why"], chosen)]
    return "\n".join(lines) + "\n"
