"""``multitask-tables score PREDICTIONS ... --rate HZ --out DIR``: another method's predictions
scored as our runs are, and paired with archived baselines.

PREDICTIONS: one folder per seed of the method, each holding one file per trial of the release,
``<trial>.csv`` (columns ``frame,gesture[,progress]``) or ``<trial>.txt`` (one gesture name per
line): docs/YOUR_METHOD.md. Rows come at ``--rate`` Hz, a divisor of the recordings' 30 Hz: row i
is the prediction at frame ``i * 30 / rate + 1`` and holds until the next (30: one row per frame;
5: one per 6 frames from the first). Our runs are scored at their 5 Hz samples (the labelled
frames, every 6th from the first): each sample takes the row holding its frame. Every file is
checked first (a missing, extra or other task's trial, a wrong length, an unknown label: one
line naming it, exit 2, nothing written; ``runs.method`` lists every check: also a trial's
name in another case, a CSV column named twice or not exactly, progress predictions in some
files or seeds only, a folder given twice). A folder of a ``multitask-tables release`` is noted:
it scores its runs' last evaluation point, its grid's tables the mean over their evaluation
points (``studies.release.LAST_POINT``). Scores per LOUO fold as ``rnn_seg.metrics`` gives a
run's (accuracy, edit, F1@{10,25,50}; progress with a ``progress`` column).

``--against GRID[:CONFIG,...]``: compare with configurations of grids or scores archives (default
configurations: their A, APc and APoc); per fold each side is the mean over its seeds, the exact
sign-flip test and interval of ``claims.csv``, Holm over every comparison of the call. Writes
``score_folds.csv``, ``score_summary.csv`` (printed without ``--against``) and, with
``--against``, ``score.csv|.tex|.md`` (printed) into ``--out``, listed in ``score.json``
(``studies.method``).

    multitask-tables score my_method/seed0 my_method/seed1 --rate 30 \\
        --against results/grid:A-fixed,APoc-gradnorm results/tcn/ms-tcn:A-fixed --out my_tables
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from jigsaws_tools.cli.format_options import add_format_option
from jigsaws_tools.cli.options import add_data_arguments
from jigsaws_tools.files import resolved

from .common import add_out_options, publish
from .release import MANIFEST as RELEASE_MANIFEST

SUMMARY = "another method's predictions scored beside archived baselines"
#: The list of the files the last call wrote into ``--out``; it names the folders and grids.
MANIFEST = "score.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folders", type=Path, nargs="+", metavar="PREDICTIONS",
                        help="a folder of prediction files per seed of the method")
    parser.add_argument("--rate", type=float, required=True, metavar="HZ",
                        help="the predictions' rate in Hz, a divisor of the recordings' (30: "
                             "one row per frame; 5: one per 6 frames) (required)")
    parser.add_argument("--name", default="method",
                        help="the method's name in the tables (default: method)")
    parser.add_argument("--against", nargs="+", default=[], metavar="GRID[:CONFIG,...]",
                        help="grids or scores archives to compare with, each with its "
                             "configurations (default: its A, APc and APoc), e.g. "
                             "results/tcn/ms-tcn:A-fixed")
    parser.add_argument("--metrics", nargs="+", metavar="METRIC",
                        default=["gesture_accuracy", "gesture_edit", "gesture_f1@10"],
                        help="the scores compared (default: gesture_accuracy gesture_edit "
                             "gesture_f1@10)")
    data = add_data_arguments(parser)
    add_format_option(data, "the release")
    add_out_options(parser, MANIFEST)


def run(args: argparse.Namespace) -> None:
    from jigsaws_tools.cli.format_options import format_from_options
    from jigsaws_tools.cli.options import data_dir_from_args
    from jigsaws_tools.cli.task_options import task_from_options
    from jigsaws_tools.dataset import DataConfig

    from ..runs.method import method_scores
    from ..studies.method import (caption, check_metrics, compare, comparison_markdown,
                                  parse_against, read_baselines, summary_markdown, write_method)

    check_out_outside(args.out, args.folders)
    task = task_from_options(args)
    config = DataConfig(str(data_dir_from_args(args, task)), annotations=args.annotations,
                        task=task, recording_format=format_from_options(args))
    against = [parse_against(text, args.annotations) for text in args.against]
    scores, trials = method_scores(args.folders, config, args.rate)
    for folder in args.folders:
        release = released_from(folder)
        if release is not None:
            note = release_note(folder, release, config.preprocessing.sample_hz,
                                args.annotations)
            print(f"note: {note}", file=sys.stderr)
    check_metrics(scores, args.metrics)
    table, text = None, ""
    if against:
        baselines, runs = read_baselines(against, args.annotations, trials,
                                         config.preprocessing.sample_hz)
        table = compare(scores, args.name, baselines, runs, args.metrics)
        text = caption(table, args.name, args.annotations, task.name)
    publish(args.out, MANIFEST, args.overwrite,
            lambda staging: write_method(scores, table, args.metrics, text, staging),
            record={"predictions": [str(f) for f in args.folders], "rate_hz": args.rate,
                    "annotations": args.annotations, "against": args.against})
    print(comparison_markdown(table, text) if table is not None else summary_markdown(
        scores, args.metrics, args.name, args.annotations, task.name), end="")


def check_out_outside(out: Path, folders: list[Path]) -> None:
    """A ``ValueError`` when ``out`` is one of the prediction ``folders`` or inside one: its
    files would join the predictions, and the next call would refuse the folder."""
    where = resolved(out)
    for folder in folders:
        inside = resolved(folder)
        if where == inside or inside in where.parents:
            raise ValueError(f"--out {out}: inside the prediction folder {folder}, which must "
                             "hold trial files only; write the tables elsewhere")


def release_note(folder: Path, release: dict, sample_hz: float, annotations: str) -> str:
    """What scoring ``folder``, a seed folder of a release (``released_from``'s ``release``), at
    ``sample_hz`` samples on ``annotations`` labels gives beside its grid's own tables."""
    labels = Path(folder).resolve().parents[2].name
    other = (f"; trained on {labels} labels, scored on {annotations} labels (--annotations)"
             if labels != annotations else "")
    rates = release.get("sample_hz", [sample_hz])     # releases before 2026-12-03: 5 Hz runs
    if rates is None:
        return (f"{folder}: released predictions of {release['grid']}, whose release.json "
                "records no readable rate (sample_hz): its runs may have predicted at other "
                f"samples than the {sample_hz:g} Hz ones scored here, and these then are not "
                f"its runs' scores (the release's README.md){other}")
    if rates != [sample_hz]:
        return (f"{folder}: released predictions of {release['grid']}, whose runs predicted at "
                f"{' / '.join(f'{r:g}' for r in rates)} Hz: scored here at {sample_hz:g} Hz "
                f"samples, these are not its runs' scores (the release's README.md){other}")
    return (f"{folder}: released predictions of {release['grid']}, scored at its runs' last "
            "evaluation point; its tables and --against score a run as the mean over its "
            f"evaluation points, about 1 point apart per run (the release's README.md){other}")


def released_from(folder: Path) -> dict | None:
    """The manifest record of the ``multitask-tables release`` that wrote ``folder`` (a seed
    folder, ``<release>/<annotations>/<direction>/<config>/seed<k>``, whose release folder holds
    the release's manifest): its ``grid`` and the rates its runs predicted at (``sample_hz``,
    Hz; absent from a release before 2026-12-03, None when not a list of positive numbers),
    else None."""
    parents = Path(folder).resolve().parents
    manifest = parents[3] / RELEASE_MANIFEST if len(parents) > 3 else None
    if manifest is None or not manifest.is_file():
        return None
    try:
        record = json.loads(manifest.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or "grid" not in record:
        return None
    if "sample_hz" in record and not _readable_rates(record["sample_hz"]):
        record["sample_hz"] = None          # recorded but unreadable: the note says so
    return record


def _readable_rates(value) -> bool:
    """Whether ``value`` (read from JSON) lists rates in Hz: one or more finite positive
    numbers."""
    return isinstance(value, list) and bool(value) and all(
        isinstance(r, (int, float)) and not isinstance(r, bool) and math.isfinite(r) and r > 0
        for r in value)
