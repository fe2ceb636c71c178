"""``multitask-tables GRID_DIR``: the paper's tables (CSV + LaTeX) and figures from a grid's runs.

Writes to ``--out`` (default ``GRID_DIR/tables``): ``runs.csv`` (one row per finished run),
``per_fold.csv`` (mean over seeds per configuration and fold), ``summary.csv`` (mean and std over
folds), ``table1|2|3.csv/.tex`` (ours against the paper), ``ablation_annotations.csv/.tex``
(revised against original labels), ``claims.csv/.tex`` (the paper's claims tested with paired
statistics over folds and seeds, settings in ``claims_config.json``), ``per_gesture.csv`` and
``figures/confusion.png|pdf`` (per-gesture precision, recall, F1 and confusion matrices of A and
APoc, ``confusion``; runs finished before these were saved get a one-line note instead),
``figures/*.png|pdf`` and, with ``--curves``, ``figures/curves/*.png|pdf`` (training curves). The
paper's tables, the annotation ablation and its claims are Suturing's: a grid of another task gets
instead the claims of the paper's conjecture (multi-task against model A on that task,
``claims.CONJECTURE_CLAIMS``).

    multitask-tables runs/converged --out results --example-trial Suturing_D003 --curves

``--out`` may hold other files (a README, the grid itself): ``tables.json`` there lists the files
the last call wrote, which the next replaces (and removes those it no longer writes, e.g. a figure
the grid cannot draw; the figures, or the training curves, of a call with ``--no-figures``, or
without ``--curves``, stay as they were); a file of an output's name that it does not list,
yours, is never written over unless ``--overwrite``. ``--widths``
keeps its own list, ``width.json``. The files are written together at the end (``rnn_seg.runs.manifest``):
a call that fails leaves ``--out`` as it was.

A grid with missing or unfinished runs, NaN metrics, unreadable or self-contradicting files, runs
whose config.json records another place, or stray folders is an error naming them
(``multitask.evidence.collect``); with ``--allow-incomplete`` they are listed, and the
configurations concerned are marked incomplete in the tables (``runs``, ``runs_expected`` and
``complete`` columns of summary.csv; "(incomplete: n/m runs)" after the model's name). Runs of
one configuration that differ in a setting that changes a result are refused, always: no table
pools them (``pooling``).

While a grid runs, ``--finished-only`` writes the tables of its finished part: every
configuration with a run not finished yet is left out (and listed), the rest are complete;
``--seeds 0`` restricts the evidence to those seeds' runs (the grid runs every configuration's
seed 0 first). The captions state the seeds and folds the tables hold.

    multitask-tables runs/converged --out results --seeds 0 --finished-only

``--archive DIR`` writes the grid's scores archive instead (``multitask.grid.archive``): grid.json
and every finished run's configuration, metrics and loss logs, without weights or predictions;
small enough to commit, a grid folder that ``multitask-tables`` tabulates and ``multitask-grid``
continues after a copy, on any machine.

    multitask-tables runs/converged --archive results/grid

``--widths GRID ...`` writes the width study instead (``width``): model A against APoc
(GradNorm) in GRID_DIR and each further grid, one LSTM width each, as ``width.csv`` and
``width.png/.pdf`` in ``--out``; with ``--seeds``, only those seeds' runs of every grid (e.g.
``--seeds 0``: one seed at every width). The grids of one width join by ``+`` into one entry
(GRID_DIR too): each is checked as a grid on its own, then their runs are pooled, refused unless
they agree on every setting (the schedule too) and hold no seed twice; ``width.csv`` then names
each width's grids and their seeds (``grids``).

    multitask-tables results/grid --widths results/width/h256 results/width/h512 results/paper/grid \\
        --out results/width
    multitask-tables results/grid --widths results/width/h256 \\
        results/width/h512-a180+results/confirm/h512 results/paper/grid --out results/width/a180

``--architectures GRID ...`` writes the architectures side by side instead (``architectures``):
one scores archive per architecture (LSTM at each width, ED-TCN, MS-TCN; read from the runs),
each configuration's seeds finished on every fold; ``architectures.csv/.tex/.md`` (model A, APc
and APoc per architecture, the time-only progress row, the cost per run), the claims "progress
heads help TCN backbones" (``claims.csv/.tex``, Holm over their 12) and Table II with our
measured rows (``table2.csv/.tex``) in ``--out``.

    multitask-tables --architectures results/grid results/paper/grid results/tcn/ed-tcn \\
        results/tcn/ms-tcn --out results/tcn

``--confirm PLAN`` runs a pre-registered confirmatory analysis instead, exactly as the plan
file says (``confirm``): its grids, seeds, endpoints, families and decision rules are the plan's;
a part whose grid has not finished every run of its seeds is not analysed (no interim looks).
The exploratory analyses the plan's text names, in an ``exploratory.toml`` beside the plan file,
go to ``exploratory.csv`` (``exploratory``), never into the plan's rows; ``confirm.md`` reports
it all in the plan's words and order (``confirm_report``). It takes ``--out`` (and
``--overwrite``, to replace files of its names it did not write) alone.

    multitask-tables --confirm results/confirm/plan.toml --out results/confirm

``--reference GRID --margin POINTS`` compares an execution path instead (``execution``):
GRID_DIR, every run finished, repeats configurations of the reference GRID on another path (the
fused loops, bfloat16), all else equal; per configuration and score, the option minus the
reference paired by fold, equivalent / different / inconclusive against the margin, and whether
each model's comparison with A reads the same; ``execution*.csv`` in ``--out``, listed in
``execution.json`` with the two grids and the margin.

    multitask-tables results/precision/bf16 --reference results/grid --margin 2.0 \\
        --out results/precision/bf16-vs-fp32

A folder of runs trained one by one (``multitask-train``, ``baseline-train``; no grid.json) gets
``runs.csv`` (with each run's folder), ``per_fold.csv`` and ``summary.csv``, and ``--compare``;
each run's configuration, seed and fold come from its config.json (``standalone``).

    multitask-tables runs/ --out runs/tables

``--compare X Y --metric M`` prints the paired statistics of one comparison instead, e.g.
``multitask-tables GRID --compare APc-fixed A-fixed --metric gesture_edit``; a configuration is
``[annotations/][direction/]<variant>-<weighting>`` as in the grid's run folders
(``original/APoc-gradnorm``, ``forward/A-fixed``), and ``--minus X2 Y2`` makes it a difference of
differences, ``(X - Y) - (X2 - Y2)``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from jigsaws_tools.cli.arg_types import non_negative_int, positive_float
from jigsaws_tools.cli.common import command_parser, run_command
from rnn_seg.runs.manifest import staged_outputs
from rnn_seg.runs.outputs import check_output_folder

if TYPE_CHECKING:
    import pandas as pd

PROG = "multitask-tables"
#: The list of the files the last call wrote into ``--out`` (``rnn_seg.runs.manifest``).
MANIFEST = "tables.json"
#: The same for the width study (``--widths``), which may share a folder with tables.
WIDTH_MANIFEST = "width.json"
#: The same for a confirmatory analysis (``--confirm``).
CONFIRM_MANIFEST = "confirm.json"
#: The same for an execution path's comparison (``--reference``); it names the two grids and the
#: margin too.
EXECUTION_MANIFEST = "execution.json"
#: The same for the architectures side by side (``--architectures``).
ARCHITECTURES_MANIFEST = "architectures.json"


def write_tables(grid_dir: Path, out: Path, figures: bool = True, ours_only: bool = False,
                 example_trial: str | None = None, curves: bool = False,
                 allow_incomplete: bool = False, seeds: tuple[int, ...] | None = None,
                 finished_only: bool = False) -> list[Path]:
    """Everything ``multitask-tables`` writes; returns the paths.

    Args:
        grid_dir: output folder of ``multitask-grid``.
        out: where to write.
        figures: also draw the figures.
        ours_only: LaTeX tables without the paper's columns (the CSVs keep them).
        example_trial: the test trial of the example figures (default: the first).
        curves: also draw every configuration's training curves.
        allow_incomplete: mark configurations with missing runs instead of refusing
            (``collect.run_rows``).
        seeds: only the runs of these seeds (None: all).
        finished_only: leave out the configurations with a run not finished yet.
    """
    from .collect import per_fold
    from .confusion import write_per_class
    from .standalone import is_run_collection

    if is_run_collection(grid_dir):
        return _run_collection_tables(grid_dir, out, allow_incomplete or finished_only, seeds)
    runs, foreign = _runs(grid_dir, allow_incomplete, seeds, finished_only)
    folds = per_fold(runs)
    if foreign and (figures or curves):      # these read run folders, not the checked table
        print("note: no example-trial, GradNorm-weight or training-curve figures: they read run "
              "folders, and folders of other settings were left out (above)", file=sys.stderr)
    example = _example(Path(grid_dir), folds, example_trial) if figures and not foreign else None
    written = _evidence_tables(Path(grid_dir), runs, folds, out, seeds, ours_only)
    written += write_per_class(Path(grid_dir), runs, folds, out, figures)
    if figures:
        from .figures import all_figures

        written += all_figures(Path(grid_dir), folds, out / "figures", example,
                               gradnorm=not foreign)
    if curves and not foreign:
        from .curves import training_curves

        written += training_curves(grid_dir, out / "figures" / "curves")
    return written


def _evidence_tables(grid_dir: Path, runs: pd.DataFrame, folds: pd.DataFrame, out: Path,
                     seeds: tuple[int, ...] | None, ours_only: bool) -> list[Path]:
    """``runs.csv``, ``per_fold.csv``, ``summary.csv`` (with each configuration's completeness),
    then the paper's tables and claims for Suturing, the conjecture's claims for another task."""
    from jigsaws_tools.task_definition import PAPER_TASK

    from .captions import describe_runs
    from .claims import CONJECTURE_CLAIMS
    from .claims_table import write_claims
    from .collect import (CONFIG_COLUMNS, completeness, expected_runs, grid_task_name, of_seeds,
                          recorded_runs, summary)

    expected = expected_runs(grid_dir, of_seeds(grid_dir, recorded_runs(grid_dir)[0], seeds))
    stats = summary(folds).merge(completeness(runs, expected), on=CONFIG_COLUMNS, how="left")
    written = [_csv(runs, out / "runs.csv"), _csv(folds, out / "per_fold.csv"),
               _csv(stats, out / "summary.csv")]
    budget = describe_runs(grid_dir, runs).sentence()
    if grid_task_name(grid_dir) == PAPER_TASK:
        written += _paper_tables(grid_dir, runs, stats, out, ours_only)
        written += write_claims(runs, out, budget=budget)
    else:
        written += write_claims(runs, out, claims=CONJECTURE_CLAIMS, budget=budget)
    return written


def _example(grid_dir: Path, folds: pd.DataFrame, example_trial: str | None
             ) -> tuple[str, str] | None:
    """The example figures' trial (``figures.example_trial``), chosen before anything is written
    (an unknown ``example_trial`` is an error); None, with a note, when no run kept predictions."""
    from .figures import example_trial as choose_example

    example = choose_example(grid_dir, folds, example_trial)
    if example is None:
        print("note: no example-trial figures (figures/segmentation_example, progress_example): "
              "no seed-0 A-fixed run of the grid kept its predictions (a scores archive keeps "
              "none)", file=sys.stderr)
    return example


def _runs(grid_dir: Path, allow_incomplete: bool, seeds: tuple[int, ...] | None,
          finished_only: bool):
    """``collect.run_rows``, each problem and configuration left out reported on stderr; and
    whether a run folder of other settings than the grid's was left out."""
    from .checks import OTHER_SETTINGS
    from .collect import LEFT_OUT, MISPLACED, run_rows
    from .standalone import is_run_collection, standalone_rows

    if is_run_collection(grid_dir):
        runs, problems = standalone_rows(grid_dir, allow_incomplete or finished_only, seeds)
    else:
        runs, problems = run_rows(grid_dir, allow_incomplete, seeds, finished_only)
    for problem in problems:
        print(problem if problem.startswith(LEFT_OUT) else f"incomplete: {problem}",
              file=sys.stderr)
    return runs, any(problem.startswith((OTHER_SETTINGS, MISPLACED)) for problem in problems)


def _run_collection_tables(folder: Path, out: Path, allow_incomplete: bool,
                           seeds: tuple[int, ...] | None) -> list[Path]:
    """``runs.csv`` (with each run's folder), ``per_fold.csv`` and ``summary.csv`` of runs
    trained one by one (``standalone``)."""
    from .collect import per_fold, summary
    from .standalone import RUN_COLUMN

    runs, _ = _runs(folder, allow_incomplete, seeds, finished_only=False)
    folds = per_fold(runs.drop(columns=RUN_COLUMN))
    print(f"note: {folder} holds runs trained one by one, not a grid: runs, per-fold and summary "
          "tables only (the paper's tables, the claims and the figures pair configurations over "
          "the folds and seeds of a grid: multitask-grid)", file=sys.stderr)
    return [_csv(runs, out / "runs.csv"), _csv(folds, out / "per_fold.csv"),
            _csv(summary(folds), out / "summary.csv")]


def _paper_tables(grid_dir: Path, runs, stats, out: Path, ours_only: bool) -> list[Path]:
    """Tables I-III against the paper and the annotation ablation (Suturing grids only)."""
    from .captions import describe_runs
    from .tables import (PAPER_TABLES, ablation_caption, annotation_ablation, paper_best,
                         paper_caption, paper_comparison, table_runs, to_latex)
    from .time_baseline import with_time_baseline

    written = []
    for table in PAPER_TABLES:
        frame = paper_comparison(stats, table)
        if frame.empty:
            continue
        frame = with_time_baseline(frame, grid_dir, table)
        budget = describe_runs(grid_dir, table_runs(runs, frame, (table.annotations,),
                                                    table.direction)).sentence()
        written.append(_csv(frame, out / f"{table.name}.csv"))
        written.append(_tex(to_latex(frame, paper_caption(table, budget, ours_only), table.name,
                                     ("Ours", "Paper"), paper_best(table), ours_only),
                            out / f"{table.name}.tex"))
    ablation = annotation_ablation(stats)
    if not ablation.empty:
        budget = describe_runs(grid_dir, table_runs(runs, ablation, ("revised", "original"),
                                                    "bidirectional")).sentence()
        written.append(_csv(ablation, out / "ablation_annotations.csv"))
        written.append(_tex(to_latex(ablation, ablation_caption(budget), "ablation_annotations",
                                     ("Revised", "Original")), out / "ablation_annotations.tex"))
    return written


def _compare(grid_dir: Path, compare: list[str], minus: list[str] | None, metric: str,
             allow_incomplete: bool, seeds: tuple[int, ...] | None, finished_only: bool) -> str:
    """The paired statistics of one comparison, as text."""
    from .paired import ConfigId, Contrast, NotPaired, config_labels, paired

    x, y = map(ConfigId.parse, compare)
    contrast = Contrast(x, y, tuple(map(ConfigId.parse, minus)) if minus else None)
    runs, _ = _runs(grid_dir, allow_incomplete, seeds, finished_only)
    try:
        return paired(runs, contrast, metric).describe()
    except NotPaired as error:
        raise NotPaired(f"{error}; {grid_dir} holds {', '.join(config_labels(runs))}") from None


def _csv(frame, path: Path) -> Path:
    from rnn_seg.runs.folder import write_atomic

    write_atomic(path, frame.to_csv(index=False, float_format="%.4f"))
    return path


def _tex(text: str, path: Path) -> Path:
    from rnn_seg.runs.folder import write_atomic

    write_atomic(path, text)
    return path


def build_parser() -> argparse.ArgumentParser:
    parser = command_parser(PROG, __doc__)
    parser.add_argument("grid_dir", type=Path, metavar="GRID_DIR", nargs="?",
                        help="output folder of multitask-grid, or a folder of runs trained one "
                             "by one (multitask-train, baseline-train: runs, per-fold and "
                             "summary tables only)")
    parser.add_argument("--out", type=Path, metavar="DIR",
                        help="where to write (default: GRID_DIR/tables)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace files of the output's names in --out that its tables.json "
                             "does not list (default: refuse; files it lists, an earlier "
                             "output's, are always replaced)")
    parser.add_argument("--no-figures", action="store_true", help="write the tables only")
    parser.add_argument("--example-trial", metavar="TRIAL",
                        help="test trial of the example figures, e.g. Suturing_D003 (default: "
                             "the first test trial of the first fold)")
    parser.add_argument("--curves", action="store_true",
                        help="also draw training curves from every run's history.csv: per "
                             "configuration the losses and test accuracies, a line per fold")
    parser.add_argument("--ours-only", action="store_true",
                        help="LaTeX tables with our numbers alone, without the paper's columns "
                             "(the CSVs keep them)")
    parser.add_argument("--archive", type=Path, metavar="DIR",
                        help="write the grid's scores archive to DIR instead of tables: "
                             "grid.json and every finished run's config, metrics and logs, no "
                             "weights or predictions (a new folder, or an earlier archive to "
                             "replace; default: none, write the tables)")
    parser.add_argument("--compare", nargs=2, metavar=("X", "Y"),
                        help="print the paired statistics of X - Y instead of writing tables "
                             "(default: write the tables)")
    parser.add_argument("--minus", nargs=2, metavar=("X2", "Y2"),
                        help="with --compare: (X - Y) - (X2 - Y2), paired per fold "
                             "(default: X - Y alone)")
    parser.add_argument("--metric",
                        help="with --compare: a metric column of runs.csv, e.g. gesture_edit "
                             "(required with --compare)")
    parser.add_argument("--widths", nargs="+", metavar="GRID[+GRID...]",
                        help="the width study instead of tables: A against APoc (GradNorm) in "
                             "GRID_DIR and these grids, one width each; the grids of one width "
                             "join by +, e.g. results/width/h512-a180+results/confirm/h512, "
                             "their runs pooled; writes width.csv and "
                             "width.png/.pdf to --out (default: none, write the tables)")
    parser.add_argument("--architectures", type=Path, nargs="+", metavar="GRID",
                        help="the architectures side by side instead of tables: one scores "
                             "archive per architecture (LSTM widths, ed-tcn, ms-tcn; no "
                             "GRID_DIR); writes architectures.csv/.tex/.md, the TCN claims and "
                             "Table II with measured rows to --out (default: none)")
    parser.add_argument("--confirm", type=Path, metavar="PLAN",
                        help="a pre-registered confirmatory analysis instead of tables, as the "
                             "plan file says (results/confirm/plan.toml; its grids are named "
                             "in it, so no GRID_DIR): writes confirm.csv, "
                             "confirm_per_fold.csv and the report confirm.md to --out "
                             "(default: none), and exploratory.csv when an exploratory.toml "
                             "lies beside the plan")
    parser.add_argument("--reference", type=Path, metavar="GRID",
                        help="compare GRID_DIR's execution path (fused loops, bfloat16) with this "
                             "grid's, paired by fold; needs --margin and --out; writes "
                             "execution*.csv (default: none, write the tables)")
    parser.add_argument("--margin", type=positive_float, metavar="POINTS",
                        help="with --reference: the equivalence margin in percentage points, "
                             "e.g. 2.0 (required with --reference)")
    parser.add_argument("--allow-incomplete", action="store_true",
                        help="write tables although runs are missing, unfinished or unreadable, "
                             "marking the configurations concerned incomplete (default: refuse)")
    parser.add_argument("--finished-only", action="store_true",
                        help="for a grid still running: leave out every configuration with a run "
                             "not finished yet, and list them (default: refuse)")
    parser.add_argument("--seeds", type=non_negative_int, nargs="+", metavar="K",
                        help="only the runs of these seeds, e.g. --seeds 0 (default: every "
                             "recorded run)")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if bool(args.compare) != bool(args.metric) or (args.minus and not args.compare):
        parser.error("--compare needs --metric, and --metric and --minus need --compare")
    extra = (["--compare"] if args.compare else []) + _table_options(args)
    if args.confirm:
        if (args.grid_dir or args.archive or args.widths or args.architectures
                or args.reference or args.margin is not None or "--out" not in extra
                or set(extra) - {"--out", "--overwrite"}):
            parser.error("--confirm reads its grids from the plan: give it --out (and "
                         "--overwrite) alone, without GRID_DIR")
        return run_command(PROG, args.verbose, lambda: _confirm(args))
    if args.architectures:
        if args.grid_dir or args.archive or args.widths or args.compare or args.reference \
                or args.margin is not None or "--out" not in extra or set(extra) - {"--out", "--overwrite"}:
            parser.error("--architectures reads the grids it names: give it --out (and "
                         "--overwrite) alone, without GRID_DIR")
        return run_command(PROG, args.verbose, lambda: _architectures(args))
    if args.grid_dir is None:
        parser.error("GRID_DIR is required (but with --confirm or --architectures)")
    if (args.reference is None) != (args.margin is None):
        parser.error("--reference needs --margin, and --margin needs --reference")
    if args.reference and (args.archive or args.widths or "--out" not in extra
                           or set(extra) - {"--out", "--overwrite"}):
        parser.error("--reference needs --out and takes no other option but --margin and "
                     "--overwrite")
    if args.archive and extra:
        parser.error(f"--archive writes the archive alone: leave out {', '.join(extra)}")
    if args.widths and (args.archive or args.compare or "--out" not in extra
                        or set(extra) - {"--out", "--overwrite", "--seeds"}):
        parser.error("--widths needs --out and takes no other option but --overwrite and --seeds")
    return run_command(PROG, args.verbose, lambda: _run(args))


def _table_options(args: argparse.Namespace) -> list[str]:
    """The options given that only the tables use."""
    given = {"--out": args.out, "--overwrite": args.overwrite, "--no-figures": args.no_figures,
             "--example-trial": args.example_trial, "--curves": args.curves,
             "--ours-only": args.ours_only, "--allow-incomplete": args.allow_incomplete,
             "--finished-only": args.finished_only, "--seeds": args.seeds}
    return [option for option, value in given.items() if value]


def _left_alone(args: argparse.Namespace) -> tuple[str, ...]:
    """The folders of --out whose files a call told not to draw them leaves as they are."""
    if args.no_figures:
        return ("figures/",)
    return () if args.curves else ("figures/curves/",)


def _confirm(args: argparse.Namespace) -> None:
    """``--confirm``: the plan's analysis into ``--out``, all files or none; the plan and its
    exploratory file are checked before ``--out``'s lock is taken."""
    from .confirm import read_plan
    from .confirm_report import write_confirmatory
    from .exploratory import EXPLORATORY_FILE, read_exploratory

    read_exploratory(args.confirm.parent / EXPLORATORY_FILE, read_plan(args.confirm))
    check_output_folder(args.out, PROG, may_hold=True)
    with staged_outputs(args.out, CONFIRM_MANIFEST, PROG, args.overwrite) as staging:
        written, skipped = write_confirmatory(args.confirm, staging)
    for line in skipped:
        print(f"note: {line}", file=sys.stderr)
    for path in written:
        print(args.out / path.relative_to(staging))


def _architectures(args: argparse.Namespace) -> None:
    """``--architectures``: the grids side by side into ``--out``, all files or none."""
    from .architectures import write_architectures

    for grid in args.architectures:
        if not grid.is_dir():
            raise FileNotFoundError(f"{grid}: no such folder (a grid's scores archive, e.g. "
                                    "results/tcn/ed-tcn)")
    check_output_folder(args.out, PROG, may_hold=True)
    with staged_outputs(args.out, ARCHITECTURES_MANIFEST, PROG, args.overwrite) as staging:
        written = write_architectures(args.architectures, staging)
    for path in written:
        print(args.out / path.relative_to(staging))


def _width_entries(args: argparse.Namespace) -> list[tuple[Path, ...]]:
    """``--widths``: the grids of each width, GRID_DIR's first (``width.width_entry``)."""
    from .width import width_entry

    return [width_entry(str(entry)) for entry in (args.grid_dir, *args.widths)]


def _run(args: argparse.Namespace) -> None:
    entries = _width_entries(args) if args.widths else []
    folders = ([grid for entry in entries for grid in entry] if entries
               else [args.grid_dir, *([args.reference] if args.reference else [])])
    for grid in folders:
        if not grid.is_dir():
            raise FileNotFoundError(f"{grid}: no such folder (a grid folder, a scores archive "
                                    "or a folder of runs)")
    seeds = tuple(args.seeds) if args.seeds else None
    if args.archive:
        from ..grid.archive import archive_grid

        finished, recorded = archive_grid(args.grid_dir, args.archive)
        print(f"{args.archive}: {finished} of {recorded} runs archived (finished ones)")
        return
    if args.compare:
        print(_compare(args.grid_dir, args.compare, args.minus, args.metric,
                       args.allow_incomplete, seeds, args.finished_only))
        return
    from . import drawing

    out = args.out or args.grid_dir / "tables"
    check_output_folder(out, PROG, may_hold=True)   # beside grids, never in a run or grid's runs
    manifest = (WIDTH_MANIFEST if args.widths else EXECUTION_MANIFEST if args.reference
                else MANIFEST)
    kept = () if args.widths or args.reference else _left_alone(args)
    record = ({"option": str(args.grid_dir), "reference": str(args.reference),
               "margin": args.margin} if args.reference else None)
    with staged_outputs(out, manifest, PROG, args.overwrite, record=record, kept=kept) \
            as staging, drawing.shown(PROG):
        if args.widths:
            from .width import write_width

            written = write_width(entries, staging, seeds)
        elif args.reference:
            from .execution import write_execution

            written, notes = write_execution(args.grid_dir, args.reference, args.margin,
                                             staging)
            for line in notes:
                print(f"note: {line}", file=sys.stderr)
        else:
            written = write_tables(args.grid_dir, staging, figures=not args.no_figures,
                                   ours_only=args.ours_only, example_trial=args.example_trial,
                                   curves=args.curves, allow_incomplete=args.allow_incomplete,
                                   seeds=seeds, finished_only=args.finished_only)
    for path in written:
        print(out / path.relative_to(staging))


if __name__ == "__main__":
    sys.exit(main())
