"""Architectures side by side: the paper's heads on the LSTM at each width, ED-TCN and MS-TCN.

One scores archive (a grid folder) per architecture; which architecture a grid holds is read
from its runs' ``config.json`` (``pooling.architecture``: ``lstm-128``, ``lstm-1024``,
``ed-tcn``, ``ms-tcn``). Each grid is pooled by the one rule of ``pooling``, its runs tagged
with its architecture, and nothing is paired across grids; two grids of one architecture, a grid
of several, or grids on other data are refused (``pooling.apart``).

**What enters, per grid and configuration**: the seeds whose runs have finished on every fold
the grid records for them. A seed still training is left out and named in the table's ``note``
(e.g. ``seed 1: 3 of 8 folds finished, left out``), never averaged over fewer folds; the
``seeds``, ``folds`` and ``runs`` columns say what entered. Any other problem of a grid (a NaN
metric, a run of other settings or another place, a stray folder) is an error, as for its own
tables (``collect``). A configuration whose folds' settings a nested selection chose (e.g.
``results/tcn/retest/ed-tcn``) names the settings in its ``selection`` column, as its own
captions do.

    multitask-tables architectures results/grid results/paper/grid results/tcn/ed-tcn \\
        results/tcn/ms-tcn --out results/tcn

writes into ``--out``:

* ``architectures.csv`` / ``.tex`` / ``.md``: per architecture, model A, APc (w1 = w2 = 1) and
  APoc (GradNorm, alpha 1.5), revised labels, offline: gesture and progress accuracy, edit and
  F1@10, mean and std over folds of each fold's mean over its seeds; the time-only progress
  row (``time_baseline``: as the first grid's archive keeps it, else when its release can be
  read here); each configuration's cost
  per run (``seconds_*``: the seconds its runs' ``timing.json`` records, every phase of every
  session, on the machine and with the workers that ran it: compare within a grid, or across
  grids run alike);
* ``claims.csv`` / ``.tex``, ``claims_note.tex``, ``claims_config.json``: "progress heads help
  TCN backbones" (``claims.TCN_CLAIMS``, 12 claims in three families of 4, one per score, Holm
  within each) on the ED-TCN and
  MS-TCN grids given (a backbone not given: its claims untested, p = 1);
* ``table2.csv`` / ``.tex``: the paper's Table II (original labels) with our measured rows:
  model A, APc and APoc of an LSTM grid that ran them, model A of each TCN grid, beside the
  published numbers and the quoted TCN and TCN+RL rows.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import pandas as pd

from rnn_seg.runs.folder import RunFolderError, is_finished, read_json

from ...grid.folder import GRID_RECORD
from ...grid.spec import RunKey
from ...models.run_record import RunRecord, read_run_record
from ..render.captions import describe_runs, selected_names, selection_phrase
from ..render.latex import escape, mean_std, requires
from ..render.markdown import markdown_table
from ..runs.collect import (finite, key_from_path, per_fold, recorded_runs, refuse_repeated,
                            run_rows)
from ..runs.pooling import apart, architecture_name
from ..statistics.paired import ConfigId

#: The models compared on every architecture (revised labels, offline).
MODELS = {"A": ConfigId("A"), "APc (w1=w2=1)": ConfigId("APc"),
          "APoc (alpha=1.5)": ConfigId("APoc", "gradnorm")}
#: Score column -> its name in the tables (gestures, then progress).
SCORES = {"gesture_accuracy": "Accuracy", "gesture_edit": "Edit", "gesture_f1@10": "F1@10",
          "progress_accuracy": "P Accuracy", "progress_edit": "P Edit",
          "progress_f1@10": "P F1@10"}
#: The time-only progress row's label (``time_baseline.LABELS``).
TIME_ONLY = "Time only (t/T)"
TIMING = "timing.json"
#: How a run still training shows in a problem line of ``collect.run_rows``.
_UNFINISHED = "not finished:"


@dataclass(frozen=True)
class ArchitectureEvidence:
    """One grid's part: its architecture and the runs that entered (module docstring)."""

    grid: Path
    architecture: str               # pooling.architecture, e.g. "ed-tcn"
    runs: pd.DataFrame              # collect.run_rows' columns, "architecture" and "seconds"
    left_out: dict[str, str]        # configuration label -> what of it was left out and why
    recorded: dict[str, int]        # configuration label -> runs the grid records
    records: dict[Path, RunRecord]  # each run's folder -> its config.json

    @property
    def name(self) -> str:
        return architecture_name(self.architecture)


def architecture_evidence(grid: Path) -> ArchitectureEvidence:
    """The finished seeds of every configuration of ``grid`` (module docstring).

    Raises:
        FileNotFoundError: ``grid`` is no folder.
        ValueError: one line: no grid.json (not a grid or scores archive), no configuration
            with a seed finished on every fold, a problem of the grid other than a run still to
            finish, runs of one configuration of other settings (``pooling``).
    """
    grid = Path(grid)
    if not grid.is_dir():
        raise FileNotFoundError(f"{grid}: no such folder (a grid's scores archive, e.g. "
                                "results/tcn/ed-tcn)")
    if not (grid / GRID_RECORD).is_file():
        raise ValueError(f"{grid}: not a grid or scores archive (no {GRID_RECORD}); "
                         "multitask-tables architectures takes one grid per architecture")
    recorded, _ = recorded_runs(grid)
    complete, left_out, counts = _finished_seeds(grid, recorded)
    if not complete:
        raise ValueError(f"{grid}: no configuration has a seed finished on every fold ("
                         + "; ".join(f"{c}: {why}" for c, why in left_out.items()) + ")")
    runs, problems = run_rows(grid, allow_incomplete=True)
    serious = [problem for problem in problems if not problem.startswith(_UNFINISHED)]
    if serious:
        first = "; ".join(line.strip() for line in serious[0].splitlines())
        raise ValueError(f"{grid}: {len(serious)} problem(s) with its runs, the first: {first}")
    labels = _labels(runs)
    runs = runs[[seed in complete.get(label, ()) for label, seed in zip(labels, runs.seed)]]
    runs = runs.reset_index(drop=True)
    records = {grid / _path(row): read_run_record(grid / _path(row))
               for row in runs.itertuples(index=False)}
    kinds = apart({grid: records})
    runs.insert(0, "architecture", kinds[grid])
    runs["seconds"] = [_seconds(run) for run in records]
    return ArchitectureEvidence(grid, kinds[grid], runs, left_out, counts, records)


def _path(row) -> Path:
    """The run folder (relative to its grid) of a row of ``collect.run_rows``."""
    return RunKey(row.annotations, row.direction, row.variant, row.weighting, int(row.seed),
                  row.fold).path()


def _labels(runs: pd.DataFrame) -> list[str]:
    """The configuration label (``ConfigId.label``) of every row of ``runs``."""
    return [ConfigId(r.variant, r.weighting, r.annotations, r.direction).label
            for r in runs.itertuples(index=False)]


def _finished_seeds(grid: Path, recorded: list[Path]
                    ) -> tuple[dict[str, tuple[int, ...]], dict[str, str], dict[str, int]]:
    """Per configuration label: the seeds finished on every fold recorded for them, what was
    left out (``seed 1: 3 of 8 folds finished``) and how many runs the grid records."""
    done: dict[str, dict[int, list[bool]]] = {}
    for run in recorded:
        key = key_from_path(grid / run, grid)
        label = ConfigId(key.variant, key.weighting, key.annotations, key.direction).label
        done.setdefault(label, {}).setdefault(key.seed, []).append(is_finished(grid / run))
    complete, left_out = {}, {}
    for label, seeds in done.items():
        complete[label] = tuple(sorted(s for s, runs in seeds.items() if all(runs)))
        partial = [f"seed {s}: {sum(runs)} of {len(runs)} folds finished"
                   for s, runs in sorted(seeds.items()) if not all(runs)]
        if partial:
            left_out[label] = ", ".join(partial) + ", left out"
    counts = {label: sum(map(len, seeds.values())) for label, seeds in done.items()}
    return {k: v for k, v in complete.items() if v}, left_out, counts


def _seconds(run_dir: Path) -> float:
    """The seconds a run's ``timing.json`` records over its phases; NaN without one."""
    try:
        return float(sum(read_json(run_dir / TIMING).values()))
    except (RunFolderError, OSError, ValueError, TypeError, AttributeError):
        return math.nan


def read_architectures(grids: list[Path]) -> list[ArchitectureEvidence]:
    """``architecture_evidence`` of every grid, checked to be one architecture each, on one data
    set (``pooling.apart``)."""
    refuse_repeated(grids, "one grid per architecture")
    evidence = [architecture_evidence(Path(grid)) for grid in grids]
    apart({part.grid: part.records for part in evidence})
    return evidence


def runs_of(evidence: list[ArchitectureEvidence]) -> pd.DataFrame:
    """Every grid's runs in one table with its ``architecture`` column (``paired.ConfigId``
    selects a configuration of one architecture from it)."""
    return pd.concat([part.runs.drop(columns="seconds") for part in evidence],
                     ignore_index=True)


# --- The cross-architecture table -----------------------------------------------------------

COLUMNS = ["architecture", "model", "config", "seeds", "folds", "runs", "runs_recorded",
           *(f"{score}_{stat}" for score in SCORES for stat in ("mean", "std")),
           "seconds_mean", "seconds_min", "seconds_max", "selection", "note"]


def architecture_table(evidence: list[ArchitectureEvidence],
                       time_only: pd.DataFrame | None) -> pd.DataFrame:
    """One row per architecture and model (``MODELS``), in the order of the grids, then the
    time-only progress row (``time_only``: its per-fold scores, ``time_baseline.fold_scores``;
    None: no row)."""
    rows = []
    for part in evidence:
        for model, config in MODELS.items():
            rows.append(_model_row(part, model, config))
    if time_only is not None:
        row = {"architecture": "", "model": TIME_ONLY, "config": "time-offline", "seeds": "",
               "folds": len(time_only), "runs": 0, "runs_recorded": 0,
               "note": "fitted per fold on the training users' labels alone"}
        for score in SCORES:
            if score in time_only:
                row |= {f"{score}_mean": float(time_only[score].mean()),
                        f"{score}_std": float(time_only[score].std(ddof=1))}
        rows.append(row)
    return pd.DataFrame(rows, columns=COLUMNS)


def _model_row(part: ArchitectureEvidence, model: str, config: ConfigId) -> dict:
    runs = config.select(part.runs)
    row = {"architecture": part.name, "model": model, "config": config.label,
           "seeds": " ".join(map(str, sorted(set(runs.seed)))), "folds": runs.fold.nunique(),
           "runs": len(runs), "runs_recorded": part.recorded.get(config.label, 0),
           "note": part.left_out.get(config.label, "")}
    if runs.empty:
        row["note"] = row["note"] or "not in this grid"
        return row
    records = [part.records[part.grid / _path(run)] for run in runs.itertuples(index=False)]
    selected = selected_names(name for record in records if record.selection is not None
                              for name in record.selection.common)
    if selected:
        row["selection"] = selection_phrase(selected)
    folds = per_fold(runs.drop(columns=["architecture", "seconds"]))
    for score in SCORES:
        if score in folds and folds[score].notna().any():
            row |= {f"{score}_mean": folds[score].mean(), f"{score}_std": folds[score].std(ddof=1)}
    seconds = runs.seconds.dropna()
    if not seconds.empty:
        row |= {"seconds_mean": seconds.mean(), "seconds_min": seconds.min(),
                "seconds_max": seconds.max()}
    if len(seconds) < len(runs):
        row["note"] = "; ".join(filter(None, [row["note"], f"{len(runs) - len(seconds)} run(s) "
                                              "without timing.json"]))
    return row


def duration(seconds: float) -> str:
    """``2 min 16 s``, ``41 s``, ``1 h 05 min``; ``--`` when unknown."""
    if seconds is None or math.isnan(seconds):
        return "--"
    total = round(seconds)
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    if hours:
        return f"{hours} h {minutes:02d} min"
    return f"{minutes} min {secs:02d} s" if minutes else f"{secs} s"


def _cell(row: pd.Series, score: str, formatter) -> str:
    mean, std = finite(row.get(f"{score}_mean")), finite(row.get(f"{score}_std"))
    if mean is None:
        return "--" if row.runs or row.model == TIME_ONLY else "not run yet"
    return formatter(mean, std)


def _evidence(row: pd.Series, times: str = "x") -> str:
    """``3 x 8`` (seeds ``times`` folds) and, when runs were left out, ``(24 of 72 runs)``."""
    if row.model == TIME_ONLY:
        return f"{row.folds} folds"
    if not row.runs:
        return f"0 of {row.runs_recorded} runs"
    seeds = len(str(row.seeds).split())
    counted = "" if row.runs == row.runs_recorded else f" ({row.runs} of {row.runs_recorded} runs)"
    return f"{seeds} {times} {row.folds}{counted}"


def architecture_markdown(table: pd.DataFrame) -> str:
    """The table as Markdown (for ``results/tcn/README.md``): mean (std) over folds per score,
    seeds x folds, cost per run, and what was left out."""
    header = ["architecture", "model", *SCORES.values(), "seeds x folds", "per run", "note"]
    rows = [[row.architecture, row.model,
             *(_cell(row, score, lambda m, s: f"{m:.1f} ({s:.1f})" if s is not None
                     else f"{m:.1f}") for score in SCORES),
             _evidence(row), duration(row.seconds_mean), _notes(row)]
            for _, row in table.iterrows()]
    return "\n".join(markdown_table(header, rows)) + "\n"


def _notes(row: pd.Series) -> str:
    """The Markdown table's note of a row: its nested selection, then what was left out."""
    return "; ".join(text for text in (row.get("selection"), row.note)
                     if isinstance(text, str) and text)


def architecture_latex(table: pd.DataFrame, caption: str) -> str:
    """The table as a booktabs ``table*``: one row per architecture and model, a column per
    score (mean (std) over folds), seeds x folds and cost per run."""
    header = ["Architecture", "Model", *(escape(name) for name in SCORES.values()),
              r"Seeds$\times$folds", "Per run"]
    lines = [requires("booktabs").rstrip("\n"), r"\begin{table*}[t]", r"\centering",
             r"\footnotesize", r"\setlength{\tabcolsep}{3pt}", rf"\caption{{{caption}}}",
             r"\label{tab:architectures}",
             rf"\begin{{tabular}}{{@{{}}ll{'c' * len(SCORES)}rr@{{}}}}", r"\toprule",
             " & ".join(header) + r" \\", r"\midrule"]
    previous = None
    for _, row in table.iterrows():
        if previous is not None and row.architecture != previous:
            lines.append(r"\addlinespace")
        previous = row.architecture
        cells = [_cell(row, score, mean_std) for score in SCORES]
        lines.append(" & ".join([escape(row.architecture), escape(row.model), *cells,
                                 escape(_evidence(row, "TIMES")).replace("TIMES", r"$\times$"),
                                 escape(duration(row.seconds_mean))])
                     + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}", r"\end{table*}"]
    return "\n".join(lines) + "\n"


def architecture_caption(table: pd.DataFrame) -> str:
    """What the table shows and what entered it (plain text, escaped)."""
    notes = [f"{row.architecture} {row.model}: {row.note}" for _, row in table.iterrows()
             if isinstance(row.note, str) and row.note and row.model != TIME_ONLY]
    selections = {row.architecture: row.selection for _, row in table.iterrows()
                  if isinstance(row.get("selection"), str) and row.selection}
    return escape(
        "Model A and the paper's progress heads (APc with w1=w2=1, APoc with GradNorm alpha=1.5) "
        "on each architecture, revised labels, offline: mean (std) over LOUO folds of each "
        "fold's mean over its seeds; P: progress. Per run: the seconds its timing.json records "
        "(every phase of every session), mean over the configuration's runs, on the machine "
        "that ran its grid. Only seeds finished on every fold enter"
        + (f" ({'; '.join(notes)})." if notes else ".")
        + "".join(f" {name}: {text}." for name, text in selections.items())
        + (f" {TIME_ONLY}: a trial's progress stage read from its relative time alone, fitted "
           "on each fold's training users." if (table.model == TIME_ONLY).any() else ""))


# --- Table II with measured rows ------------------------------------------------------------

def measured_table2(evidence: list[ArchitectureEvidence]) -> tuple[pd.DataFrame, str]:
    """Table II (``tables.PAPER_TABLES``' ``table2``) with our measured rows: each LSTM grid's
    configurations of the paper's Table II, ours against the paper; each TCN grid's model A on
    the original labels, ours alone; then the quoted related-work rows. Returns the frame
    (``tables.paper_comparison``'s columns) and the caption's LaTeX (empty frame: no grid ran
    the original labels)."""
    from ..render.tables import (PAPER_TABLES, encoder_labels, of_encoder, paper_caption,
                                 paper_comparison, related_rows)
    from ..runs.collect import summary

    table = next(t for t in PAPER_TABLES if t.name == "table2")
    parts, measured, budgets = [], [], []
    for part in evidence:
        runs = part.runs.drop(columns=["architecture", "seconds"])
        runs = runs[(runs.annotations == table.annotations) & (runs.direction == table.direction)]
        lstm = part.architecture.startswith("lstm-")
        if not lstm:
            runs = runs[(runs.variant == "A") & (runs.weighting == "fixed")]
        if runs.empty:
            continue
        stats = summary(per_fold(runs))
        if lstm:
            labels = encoder_labels(table, part.name)
            shown = replace(table, labels=labels, related={})
        else:
            shown = replace(of_encoder(table, part.name), related={})
            labels = shown.labels
        frame = paper_comparison(stats, shown)
        frame["config"] = part.architecture + "/" + frame.config
        parts.append(frame)
        measured += [labels[config] for config in dict.fromkeys(frame.config.str.split("/")
                                                                .str[-1])]
        budgets.append(f"{part.name}: {describe_runs(part.grid, runs).sentence()}")
    if not parts:
        return pd.DataFrame(), ""
    rows = [row for frame in parts for row in frame.to_dict("records")] + related_rows(table)
    frame = pd.DataFrame(rows, columns=parts[0].columns).astype({"folds": int})
    note = ("Measured here, on this protocol (ours): " + ", ".join(measured) + ". Paper's "
            "BiLSTM: DiPietro et al.'s published result; TCN, TCN+RL: the related work the "
            "paper quotes (other features, sample rates, labels and metric code), not run here.")
    return frame, paper_caption(replace(table, note=note), " ".join(budgets))


# --- The files ------------------------------------------------------------------------------

def write_architectures(grids: list[Path], out: Path, data_dir: Path | None = None
                        ) -> list[Path]:
    """Every file of the module docstring from one grid per architecture into ``out``; returns
    the paths written (no claims without a TCN grid, no Table II without original labels).
    ``data_dir``: the first grid's release, for the time-only row (None: as its archive keeps
    it, else where it records)."""
    from rnn_seg.runs.folder import write_atomic

    from ..render.tables import PAPER_TABLES, paper_best, to_latex
    from ..statistics.time_baseline import grid_fold_scores
    from .claims import TCN_BACKBONES, TCN_CLAIMS
    from .claims_table import write_claims

    evidence = read_architectures(grids)
    time_only = grid_fold_scores(evidence[0].grid, "revised", "architectures", data_dir)
    table = architecture_table(evidence, time_only)
    written = [out / "architectures.csv", out / "architectures.tex", out / "architectures.md"]
    write_atomic(written[0], table.to_csv(index=False, float_format="%.4f"))
    write_atomic(written[1], architecture_latex(table, architecture_caption(table)))
    write_atomic(written[2], architecture_markdown(table))
    backbones = [part for part in evidence if part.architecture in TCN_BACKBONES]
    if backbones:
        budget = " ".join(f"{part.name}: {describe_runs(part.grid, part.runs).sentence()}"
                          for part in backbones)
        written += write_claims(runs_of(evidence), out, claims=TCN_CLAIMS, budget=budget)
    else:
        print("note: no claims: none of the grids is a TCN's (ed-tcn, ms-tcn)", file=sys.stderr)
    frame, caption = measured_table2(evidence)
    if frame.empty:
        print("note: no table2: no grid ran the original labels", file=sys.stderr)
        return written
    table2 = next(t for t in PAPER_TABLES if t.name == "table2")
    written += [out / "table2.csv", out / "table2.tex"]
    write_atomic(written[-2], frame.to_csv(index=False, float_format="%.4f"))
    write_atomic(written[-1], to_latex(frame, caption, "table2", ("Ours", "Paper"),
                                       paper_best(table2)))
    return written
