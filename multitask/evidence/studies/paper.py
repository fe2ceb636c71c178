"""A grid's evidence as the paper shows it (``multitask-tables paper``): ``runs.csv``,
``per_fold.csv``, ``summary.csv``, Tables I-III against the published numbers, the annotation
ablation, the claims tested with paired statistics, per-gesture scores, the figures and the
training curves; and the runs, per-fold and summary tables of runs trained one by one
(``multitask-tables runs``).

The paper's tables, the annotation ablation and its claims are Suturing's: a grid of another task
gets instead the claims of the paper's conjecture (multi-task against model A on that task,
``claims.CONJECTURE_CLAIMS``). A grid with missing or unfinished runs, NaN metrics, unreadable or
self-contradicting files, runs whose config.json records another place, or stray folders is an
error naming them (``runs.collect``); with ``allow_incomplete`` they are listed, and the
configurations concerned are marked incomplete in the tables (``runs``, ``runs_expected`` and
``complete`` columns of summary.csv; "(incomplete: n/m runs)" after the model's name);
``finished_only`` leaves out every configuration with a run not finished yet. Runs of one
configuration that differ in a setting that changes a result are refused, always: no table pools
them (``runs.pooling``). The captions state the seeds and folds the tables hold.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from jigsaws_tools.task_definition import PAPER_TASK
from rnn_seg.runs.folder import write_atomic

from ..render.captions import describe_runs
from ..render.confusion import write_per_class
from ..render.curves import training_curves
from ..render.figures import ExampleTrial, all_figures, example_truth
from ..render.figures import example_trial as choose_example
from ..render.tables import (PAPER_TABLES, ablation_caption, annotation_ablation, of_encoder,
                             paper_best, paper_caption, paper_comparison, table_runs, to_latex)
from ..runs.checks import OTHER_SETTINGS
from ..runs.collect import (CONFIG_COLUMNS, LEFT_OUT, MISPLACED, completeness, expected_runs,
                            grid_task_name, of_seeds, per_fold, recorded_runs, run_rows, summary)
from ..runs.standalone import RUN_COLUMN, is_run_collection, standalone_rows
from ..statistics.time_baseline import with_time_baseline
from .claims import CONJECTURE_CLAIMS
from .claims_table import write_claims

#: The example figures' files in ``--out`` (each a ``.pdf`` and a ``.png``): the figures that
#: need the data, which the scores archive never holds (true labels).
EXAMPLE_FIGURES = ("figures/segmentation_example.", "figures/progress_example.")


def write_tables(grid_dir: Path, out: Path, figures: bool = True, ours_only: bool = False,
                 example_trial: str | None = None, curves: bool = False,
                 allow_incomplete: bool = False, seeds: tuple[int, ...] | None = None,
                 finished_only: bool = False, data_dir: Path | None = None,
                 left_alone: list[str] | None = None) -> list[Path]:
    """Everything ``multitask-tables paper`` writes (the module docstring) into ``out``; returns
    the paths. A folder of runs trained one by one gets ``run_collection_tables``.

    Args:
        grid_dir: output folder of ``multitask-grid``.
        out: where to write.
        figures: also draw the figures.
        ours_only: LaTeX tables without the paper's columns (the CSVs keep them).
        example_trial: the test trial of the example figures (default: the first).
        curves: also draw every configuration's training curves.
        allow_incomplete: mark configurations with missing runs instead of refusing
            (``runs.collect.run_rows``).
        seeds: only the runs of these seeds (None: all).
        finished_only: leave out the configurations with a run not finished yet.
        data_dir: the grid's release (the time-only rows, the example figures' true labels);
            None: the folder the grid records, where the archive keeps no time-only scores.
        left_alone: where the names of files this call cannot redraw but must not remove are
            added (``EXAMPLE_FIGURES`` when the data cannot be read: the earlier call's example
            figures stay as they were; the publish's ``kept``).
    """
    if is_run_collection(grid_dir):
        return run_collection_tables(grid_dir, out, allow_incomplete or finished_only, seeds)
    runs, foreign = read_runs(grid_dir, allow_incomplete, seeds, finished_only)
    folds = per_fold(runs)
    if foreign and (figures or curves):      # these read run folders, not the checked table
        print("note: no example-trial, GradNorm-weight or training-curve figures: they read run "
              "folders, and folders of other settings were left out (above)", file=sys.stderr)
    example = (_example(Path(grid_dir), folds, example_trial, data_dir,
                        [] if left_alone is None else left_alone)
               if figures and not foreign else None)
    written = _evidence_tables(Path(grid_dir), runs, folds, out, seeds, ours_only, data_dir)
    written += write_per_class(Path(grid_dir), runs, folds, out, figures)
    if figures:
        written += all_figures(Path(grid_dir), folds, out / "figures", example,
                               gradnorm=not foreign)
    if curves and not foreign:
        written += training_curves(grid_dir, out / "figures" / "curves")
    return written


def _evidence_tables(grid_dir: Path, runs: pd.DataFrame, folds: pd.DataFrame, out: Path,
                     seeds: tuple[int, ...] | None, ours_only: bool,
                     data_dir: Path | None) -> list[Path]:
    """``runs.csv``, ``per_fold.csv``, ``summary.csv`` (with each configuration's completeness),
    then the paper's tables and claims for Suturing, the conjecture's claims for another task."""
    expected = expected_runs(grid_dir, of_seeds(grid_dir, recorded_runs(grid_dir)[0], seeds))
    stats = summary(folds).merge(completeness(runs, expected), on=CONFIG_COLUMNS, how="left")
    written = [_csv(runs, out / "runs.csv"), _csv(folds, out / "per_fold.csv"),
               _csv(stats, out / "summary.csv")]
    described = describe_runs(grid_dir, runs)
    budget = described.sentence()
    encoder = ", ".join(described.encoders)
    if grid_task_name(grid_dir) == PAPER_TASK:
        written += _paper_tables(grid_dir, runs, stats, out, ours_only, data_dir, encoder)
        other = (f"The paper's differences are its LSTM's; ours are {encoder}'s. " if encoder
                 else "")
        written += write_claims(runs, out, budget=other + budget)
    else:
        written += write_claims(runs, out, claims=CONJECTURE_CLAIMS, budget=budget)
    return written


def _example(grid_dir: Path, folds: pd.DataFrame, example_trial: str | None,
             data_dir: Path | None, left_alone: list[str]) -> ExampleTrial | None:
    """The example figures' trial (``render.figures.example_trial``), chosen before anything is
    written (an unknown ``example_trial`` is an error), with its true labels from the data
    (``render.figures.example_truth``); None, with a note, when no run kept predictions or the
    data cannot be read: then the grid cannot draw them and an earlier call's are removed, or
    only this machine cannot, and they are left as they were (``EXAMPLE_FIGURES`` added to
    ``left_alone``)."""
    skipped = "note: no example-trial figures (figures/segmentation_example, progress_example): "
    example = choose_example(grid_dir, folds, example_trial)
    if example is None:
        print(f"{skipped}no seed-0 A-fixed run of the grid kept its predictions (an archive "
              "written before predictions were kept has none)", file=sys.stderr)
        return None
    try:
        return example_truth(grid_dir, *example, data_dir)
    except (OSError, ValueError) as error:
        print(f"{skipped}their true labels are read from the data: {error} (--data-dir: the "
              "release); those an earlier call drew are left as they were", file=sys.stderr)
        left_alone.extend(EXAMPLE_FIGURES)
        return None


def read_runs(grid_dir: Path, allow_incomplete: bool, seeds: tuple[int, ...] | None,
              finished_only: bool) -> tuple[pd.DataFrame, bool]:
    """``runs.collect.run_rows`` (``runs.standalone.standalone_rows`` for runs trained one by
    one), each problem and configuration left out reported on stderr; and
    whether a run folder of other settings than the grid's was left out."""
    if is_run_collection(grid_dir):
        runs, problems = standalone_rows(grid_dir, allow_incomplete or finished_only, seeds)
    else:
        runs, problems = run_rows(grid_dir, allow_incomplete, seeds, finished_only)
    for problem in problems:
        print(problem if problem.startswith(LEFT_OUT) else f"incomplete: {problem}",
              file=sys.stderr)
    return runs, any(problem.startswith((OTHER_SETTINGS, MISPLACED)) for problem in problems)


def run_collection_tables(folder: Path, out: Path, allow_incomplete: bool,
                          seeds: tuple[int, ...] | None) -> list[Path]:
    """``runs.csv`` (with each run's folder), ``per_fold.csv`` and ``summary.csv`` of runs
    trained one by one (``runs.standalone``)."""
    runs, _ = read_runs(folder, allow_incomplete, seeds, finished_only=False)
    folds = per_fold(runs.drop(columns=RUN_COLUMN))
    print(f"note: {folder} holds runs trained one by one, not a grid: runs, per-fold and summary "
          "tables only (the paper's tables, the claims and the figures pair configurations over "
          "the folds and seeds of a grid: multitask-grid)", file=sys.stderr)
    return [_csv(runs, out / "runs.csv"), _csv(folds, out / "per_fold.csv"),
            _csv(summary(folds), out / "summary.csv")]


def _paper_tables(grid_dir: Path, runs: pd.DataFrame, stats: pd.DataFrame, out: Path,
                  ours_only: bool, data_dir: Path | None, encoder: str) -> list[Path]:
    """Tables I-III against the paper and the annotation ablation (Suturing grids only);
    ``encoder``: the grid's encoder when not the paper's LSTM (``tables.of_encoder``), else
    empty."""
    written = []
    for published in PAPER_TABLES:
        table = of_encoder(published, encoder) if encoder else published
        frame = paper_comparison(stats, table)
        if frame.empty:
            continue
        frame = with_time_baseline(frame, grid_dir, table, data_dir)
        budget = describe_runs(grid_dir, table_runs(runs, frame, (table.annotations,),
                                                    table.direction)).sentence()
        written.append(_csv(frame, out / f"{table.name}.csv"))
        written.append(_tex(to_latex(frame, paper_caption(table, budget, ours_only), table.name,
                                     ("Ours", "Paper"), paper_best(published), ours_only),
                            out / f"{table.name}.tex"))
    ablation = annotation_ablation(stats)
    if not ablation.empty:
        budget = describe_runs(grid_dir, table_runs(runs, ablation, ("revised", "original"),
                                                    "bidirectional")).sentence()
        written.append(_csv(ablation, out / "ablation_annotations.csv"))
        written.append(_tex(to_latex(ablation, ablation_caption(budget), "ablation_annotations",
                                     ("Revised", "Original")), out / "ablation_annotations.tex"))
    return written


def _csv(frame: pd.DataFrame, path: Path) -> Path:
    write_atomic(path, frame.to_csv(index=False, float_format="%.4f"))
    return path


def _tex(text: str, path: Path) -> Path:
    write_atomic(path, text)
    return path
