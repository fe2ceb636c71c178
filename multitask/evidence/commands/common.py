"""What the studies' commands share: the ``--out`` and ``--overwrite`` options, the options that
choose a grid's runs (``--allow-incomplete``, ``--finished-only``, ``--seeds``), and
``publish``, which writes a study's files into ``--out`` all together.

``publish`` checks ``--out`` (beside grids, never in a run or a grid's runs:
``rnn_seg.runs.outputs``), gives the study a hidden staging folder inside it, and moves the files
into place once all are made (``rnn_seg.runs.manifest``): a call that fails leaves ``--out`` as it
was. The study's manifest (``tables.json``, ``width.json``, ...) lists them; the next call
replaces the files it lists and never writes over a file of an output's name that it does not
list, unless ``--overwrite``. While it works, each figure drawn and each slow step is named on
standard output (``render.drawing``); at the end, every file written is printed.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, Callable, Sequence

from jigsaws_tools.cli.arg_types import non_negative_int

#: The command's name in its messages and in every manifest's ``written_by``.
PROG = "multitask-tables"


def add_out_options(parser: argparse.ArgumentParser, manifest: str,
                    default: str | None = None) -> None:
    """``--out DIR`` (required unless ``default`` says where it goes) and ``--overwrite``."""
    parser.add_argument("--out", type=Path, metavar="DIR", required=default is None,
                        help=f"where to write (default: {default})" if default else
                        "where to write (required); it may hold other files")
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace files of the output's names in --out that its {manifest} "
                             "does not list (default: refuse; files it lists, an earlier "
                             "output's, are always replaced)")


def add_run_options(parser: argparse.ArgumentParser) -> None:
    """``--allow-incomplete``, ``--finished-only`` and ``--seeds``: which of a grid's runs enter."""
    parser.add_argument("--allow-incomplete", action="store_true",
                        help="go on although runs are missing, unfinished or unreadable, marking "
                             "the configurations concerned incomplete (default: refuse)")
    parser.add_argument("--finished-only", action="store_true",
                        help="for a grid still running: leave out every configuration with a run "
                             "not finished yet, and list them (default: refuse)")
    add_seeds_option(parser)


def add_data_option(parser: argparse.ArgumentParser, reads: str) -> None:
    """``--data-dir DIR``: the grid's release, where its archive or its spec does not say enough
    (``reads``: what the command reads there)."""
    parser.add_argument("--data-dir", type=Path, metavar="DIR",
                        help=f"the grid's release, for {reads} (default: the numbers its scores "
                             "archive keeps, else the folder its grid.json records; without "
                             "either they are left out, saying so)")


def add_seeds_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seeds", type=non_negative_int, nargs="+", metavar="K",
                        help="only the runs of these seeds, e.g. --seeds 0 (default: every "
                             "recorded run)")


def seeds_of(args: argparse.Namespace) -> tuple[int, ...] | None:
    """``--seeds`` as a tuple, None when not given (every seed)."""
    return tuple(args.seeds) if args.seeds else None


def check_folders(folders: Sequence[Path], what: str) -> None:
    """A ``FileNotFoundError`` naming the first of ``folders`` that is no folder (missing, or a
    file), and ``what`` it should be (e.g. ``a grid folder, a scores archive or a folder of
    runs``)."""
    for folder in folders:
        if not folder.is_dir():
            found = "a file, not a folder" if folder.exists() else "no such folder"
            raise FileNotFoundError(f"{folder}: {found} ({what})")


#: How many written files ``publish`` names one by one.
LISTED = 100


def publish(out: Path, manifest: str, overwrite: bool, write: Callable[[Path], list[Path]],
            record: dict[str, Any] | None = None, kept: Sequence[str] = ()) -> None:
    """``write(staging)`` (the study: returns the paths it wrote under ``staging``), published
    into ``out`` and listed in ``manifest`` (module docstring); then every path printed, or, past
    ``LISTED`` paths (a release's trial files), their count and where the manifest lists them.

    Args:
        out: the output folder (``--out``).
        manifest: the study's list of its files in ``out`` (e.g. ``width.json``).
        overwrite: ``--overwrite``.
        write: the study's work.
        record: more entries of the manifest (e.g. the grids compared); read when the files
            are published, so ``write`` may add to it (a release's rates).
        kept: folders (or file-name prefixes) of ``out`` whose listed files stay although this
            call did not write them (e.g. ``figures/`` after ``--no-figures``); read when the
            files are published, so ``write`` may add to a list given here.
    """
    from rnn_seg.runs.manifest import staged_outputs
    from rnn_seg.runs.outputs import check_output_folder

    from ..render import drawing

    check_output_folder(out, PROG, may_hold=True)   # beside grids, never in a run or grid's runs
    with staged_outputs(out, manifest, PROG, overwrite, record=record, kept=kept) as staging, \
            drawing.shown(PROG):
        written = write(staging)
    if len(written) > LISTED:
        print(f"{out}: {len(written)} files written, listed in {out / manifest}")
        return
    for path in written:
        print(out / path.relative_to(staging))


def publish_noted(out: Path, manifest: str, overwrite: bool,
                  work: Callable[[Path], tuple[list[Path], list[str]]],
                  record: dict[str, Any] | None = None) -> None:
    """``publish`` of a study whose ``work(staging)`` returns the paths it wrote and notes on
    what it read, each note printed to standard error as ``note: ...``."""
    def write(staging: Path) -> list[Path]:
        written, notes = work(staging)
        for line in notes:
            print(f"note: {line}", file=sys.stderr)
        return written

    publish(out, manifest, overwrite, write, record=record)
