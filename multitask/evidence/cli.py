"""``multitask-tables``: the evidence of a grid's runs, one subcommand per study.

    multitask-tables paper runs/converged --out results --curves
    multitask-tables pair results/grid APc-fixed A-fixed --metric gesture_edit
"""
from __future__ import annotations

import argparse
import importlib
import shlex
import sys
from pathlib import Path

from jigsaws_tools.cli.common import (HelpFormatter, add_verbose_argument, command_parser,
                                      run_command)

from .commands import STUDIES
from .commands.common import PROG


#: After the options in ``--help``: the flag forms of earlier versions.
OLD_FORMS = (f"Earlier versions' flag forms ({PROG} GRID --widths ...) still work for\n"
             "one release, each naming its new form in one line.")


def build_parser() -> argparse.ArgumentParser:
    """The parser of every study's subcommand (``commands.STUDIES``), listed in ``--help``."""
    studies = [importlib.import_module(f"{__package__}.commands.{module}")
               for module in STUDIES.values()]
    listing = "\n".join(f"  {name:<15}{study.SUMMARY}" for name, study in zip(STUDIES, studies))
    parser = command_parser(
        PROG, f"{__doc__}\nstudies (STUDY --help: its options and an example; all: "
              f"docs/COMMANDS.md):\n{listing}", epilog=OLD_FORMS,
        usage=f"{PROG} [-h] [--version] [-v] STUDY ...")
    sub = parser.add_subparsers(dest="study", required=True, metavar="STUDY",
                                help=argparse.SUPPRESS)
    for name, study in zip(STUDIES, studies):
        p = sub.add_parser(name, prog=f"{PROG} {name}", description=study.__doc__,
                           formatter_class=HelpFormatter)
        add_verbose_argument(p, default=argparse.SUPPRESS)
        study.add_arguments(p)
        p.set_defaults(run=study.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    return run_command(PROG, args.verbose, lambda: args.run(args), argv=argv)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line read, an earlier version's flag form as its subcommand (one warning
    line naming it, ``new_form``)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if is_old_form(argv) and not {"-h", "--help"} & set(argv):
        argv = new_form(argv)
        print(f"{PROG}: warning: this form is deprecated and goes in the next release; use: "
              f"{shlex.join([PROG, *argv])}", file=sys.stderr)
    return build_parser().parse_args(argv)


# -- the flag forms of earlier versions, for one release ----------------------------------------

#: The options a study's subcommand took in its flag form, as ``argparse`` destinations.
_OLD_MODES = ("confirm", "architectures", "archive", "compare", "widths", "reference")


def is_old_form(argv: list[str]) -> bool:
    """Whether ``argv`` is an earlier version's flag form: its first word that is not ``-v``
    names no study (``results/grid --widths ...``, ``--confirm PLAN``); help and version aside."""
    words = [word for word in argv if word not in ("-v", "--verbose")]
    return bool(words) and words[0] not in STUDIES and words[0] not in ("-h", "--help",
                                                                       "--version")


def new_form(argv: list[str]) -> list[str]:
    """``argv``, a flag form, as the subcommand it means; it is checked as it always was (one
    line ``multitask-tables: error: ...`` and exit 2 for a combination it never took)."""
    parser = _old_form_parser()
    args = parser.parse_args(argv)
    _check_old_form(parser, args)
    verbose = ["-v"] if args.verbose else []
    out = ["--out", str(args.out)] if args.out else []
    overwrite = ["--overwrite"] if args.overwrite else []
    seeds = ["--seeds", *map(str, args.seeds)] if args.seeds else []
    if args.confirm:
        return [*verbose, "confirm", str(args.confirm), *out, *overwrite]
    if args.architectures:
        return [*verbose, "architectures", *map(str, args.architectures), *out, *overwrite]
    grid = str(args.grid_dir)
    if args.archive:
        return [*verbose, "archive", grid, str(args.archive)]
    selection = (["--allow-incomplete"] if args.allow_incomplete else []) + (
        ["--finished-only"] if args.finished_only else []) + seeds
    if args.compare:
        minus = ["--minus", *args.minus] if args.minus else []
        return [*verbose, "pair", grid, *args.compare, "--metric", args.metric, *minus,
                *selection]
    if args.widths:
        return [*verbose, "width", grid, *args.widths, *out, *overwrite, *seeds]
    if args.reference:
        return [*verbose, "execution", grid, "--reference", str(args.reference), "--margin",
                str(args.margin), *out, *overwrite]
    from .runs.standalone import is_run_collection

    if is_run_collection(args.grid_dir):        # the flags of the paper's tables had no effect
        incomplete = ["--allow-incomplete"] if args.allow_incomplete or args.finished_only else []
        return [*verbose, "runs", grid, *out, *overwrite, *incomplete, *seeds]
    figures = (["--no-figures"] if args.no_figures else []) + (
        ["--example-trial", args.example_trial] if args.example_trial else []) + (
        ["--curves"] if args.curves else []) + (["--ours-only"] if args.ours_only else [])
    return [*verbose, "paper", grid, *out, *overwrite, *figures, *selection]


def _old_form_parser() -> argparse.ArgumentParser:
    parser = command_parser(PROG, None, usage=f"{PROG} STUDY ... (see {PROG} --help)")
    parser.add_argument("grid_dir", type=Path, metavar="GRID_DIR", nargs="?")
    parser.add_argument("--out", type=Path, metavar="DIR")
    for flag in ("--overwrite", "--no-figures", "--curves", "--ours-only", "--allow-incomplete",
                 "--finished-only"):
        parser.add_argument(flag, action="store_true")
    parser.add_argument("--example-trial", metavar="TRIAL")
    parser.add_argument("--archive", type=Path, metavar="DIR")
    parser.add_argument("--compare", nargs=2, metavar=("X", "Y"))
    parser.add_argument("--minus", nargs=2, metavar=("X2", "Y2"))
    parser.add_argument("--metric")
    parser.add_argument("--widths", nargs="+", metavar="GRID[+GRID...]")
    parser.add_argument("--architectures", type=Path, nargs="+", metavar="GRID")
    parser.add_argument("--confirm", type=Path, metavar="PLAN")
    parser.add_argument("--reference", type=Path, metavar="GRID")
    parser.add_argument("--margin", type=float, metavar="POINTS")
    parser.add_argument("--seeds", type=int, nargs="+", metavar="K")
    return parser


def _check_old_form(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """The combinations of options the flag form refused, refused as it refused them."""
    given = {"--out": args.out, "--overwrite": args.overwrite, "--no-figures": args.no_figures,
             "--example-trial": args.example_trial, "--curves": args.curves,
             "--ours-only": args.ours_only, "--allow-incomplete": args.allow_incomplete,
             "--finished-only": args.finished_only, "--seeds": args.seeds}
    extra = (["--compare"] if args.compare else []) + [o for o, v in given.items() if v]
    out_alone = "--out" in extra and not set(extra) - {"--out", "--overwrite"}
    if bool(args.compare) != bool(args.metric) or (args.minus and not args.compare):
        parser.error("--compare needs --metric, and --metric and --minus need --compare")
    if args.confirm:
        if (args.grid_dir or args.archive or args.widths or args.architectures
                or args.reference or args.margin is not None or not out_alone):
            parser.error("--confirm reads its grids from the plan: give it --out (and "
                         "--overwrite) alone, without GRID_DIR")
        return
    if args.architectures:
        if (args.grid_dir or args.archive or args.widths or args.compare or args.reference
                or args.margin is not None or not out_alone):
            parser.error("--architectures reads the grids it names: give it --out (and "
                         "--overwrite) alone, without GRID_DIR")
        return
    if args.grid_dir is None:
        parser.error("GRID_DIR is required (but with --confirm or --architectures)")
    if (args.reference is None) != (args.margin is None):
        parser.error("--reference needs --margin, and --margin needs --reference")
    if args.reference and (args.archive or args.widths or not out_alone):
        parser.error("--reference needs --out and takes no other option but --margin and "
                     "--overwrite")
    if args.archive and extra:
        parser.error(f"--archive writes the archive alone: leave out {', '.join(extra)}")
    if args.widths and (args.archive or args.compare or "--out" not in extra
                        or set(extra) - {"--out", "--overwrite", "--seeds"}):
        parser.error("--widths needs --out and takes no other option but --overwrite and --seeds")


if __name__ == "__main__":
    sys.exit(main())
