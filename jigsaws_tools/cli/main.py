"""``jigsaws-tools``: write a synthetic release, inspect a release, check its progress stages,
list amendments, plot labels.

Every subcommand reads one task's release: ``--task`` (Suturing, the default; Knot_Tying;
Needle_Passing) or ``--task-file`` (your own definition); inspect, stages and plot read a folder
of recordings in another layout with ``--format FILE.toml`` (amendments are the release's).

    jigsaws-tools synth --out /tmp/synth/Suturing
    jigsaws-tools inspect --data-dir /path/to/Knot_Tying --task Knot_Tying
    jigsaws-tools inspect --data-dir my_data --format my_robot.toml
    jigsaws-tools stages --data-dir /path/to/Needle_Passing --task Needle_Passing
    jigsaws-tools amendments --data-dir /path/to/Suturing
    jigsaws-tools plot --synthetic --out labels.png
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..recording_format import RELEASE_LAYOUT_ONLY
from .common import (HelpFormatter, add_verbose_argument, command_parser, deprecated_alias,
                     deprecated_positional, run_command)
from .format_options import add_format_option, format_from_options
from .options import add_data_arguments, add_synthetic_seed_argument, data_dir_from_args
from .task_options import add_task_options, task_from_options

PROG = "jigsaws-tools"


def _synth(args: argparse.Namespace) -> None:
    from ..synth import SynthConfig, write_release

    if args.out is None:
        raise ValueError("synth needs --out DIR, the folder to write the release into")
    task = task_from_options(args)
    out = write_release(args.out, SynthConfig(seed=args.synthetic_seed), task)
    print(f"wrote a synthetic {task.name} release (seed {args.synthetic_seed}) to {out}")


def _inspect(args: argparse.Namespace) -> None:
    import pandas as pd

    from ..annotations import labels_named
    from ..release import discover
    from ..summary import release_summary

    task, fmt = task_from_options(args), format_from_options(args)
    index = discover(data_dir_from_args(args, task), task, fmt)
    table = release_summary(index, args.annotations)
    print(task.describe() + "\n")
    with pd.option_context("display.max_rows", None, "display.width", 200):
        print(table.to_string())
    print(f"\n{len(table)} complete trials, {table['frames'].sum()} frames at {fmt.rate_hz:g} Hz, "
          f"{table['labelled'].sum()} labelled ({labels_named(args.annotations, index)})")
    print("gestures:", _histogram(table[list(task.gestures)].sum()))
    print("progress:", _histogram(table[list(task.stage_names)].sum()))
    print("missing kinematics:", ", ".join(index.missing_kinematics) or "none")
    print("missing transcription:", ", ".join(index.missing_transcription) or "none")
    print("unusable files:", "; ".join(index.unusable) or "none")


def _stages(args: argparse.Namespace) -> None:
    import pandas as pd

    from ..annotations import labels_named
    from ..release import discover
    from ..stage_order import IN_ORDER, KINDS, stage_order

    task = task_from_options(args)
    index = discover(data_dir_from_args(args, task), task, format_from_options(args))
    table, breaks = stage_order(index, args.annotations)
    print("stages: " + " -> ".join(f"{i} {name}" for i, name in enumerate(task.stage_names))
          + f" ({labels_named(args.annotations, index)})\n")
    with pd.option_context("display.max_rows", None, "display.width", 200):
        print(table.to_string())
    totals = table[list(KINDS)].sum()
    in_order = int(totals[list(IN_ORDER)].sum())
    print(f"\n{int(table['in_order'].sum())} of {len(table)} trials follow the stage order; "
          f"{in_order} of {int(totals.sum())} transitions in order "
          f"({', '.join(f'{kind} {int(n)}' for kind, n in totals.items())})")
    print("out of order:", ", ".join(f"{pair} x{n}" for pair, n in breaks.most_common())
          or "none")


def _histogram(counts) -> str:
    """``G1 4102 (3.2%), G2 ...``: frame counts (a pandas Series) and shares."""
    total = counts.sum()
    return ", ".join(f"{k} {int(v)} ({100 * v / total:.1f}%)" for k, v in counts.items())


def _amendments(args: argparse.Namespace) -> None:
    from ..annotations import amendment_report
    from ..release import discover

    task = task_from_options(args)
    report = amendment_report(discover(data_dir_from_args(args, task), task), args.annotations)
    total = 0
    print(f"{'trial':15} {'start':>6} {'end':>6} {'new':>4} {'changed':>8}  "
          "previous labels / status")
    for name, e in report:
        a = e.amendment
        previous = ", ".join(f"{k}:{v}" for k, v in e.previous.items())
        print(f"{name:15} {a.start:6d} {a.end:6d} {a.gesture:>4} {e.frames_changed:8d}  "
              f"{previous}  [{e.status}]")
        total += e.frames_changed
    print(f"{len(report)} amendments, {total} frames relabelled")


def _plot(args: argparse.Namespace) -> None:
    from ..dataset import DataConfig, check_format_fits, load_dataset
    from ..plots import plot_dataset
    from ..preprocessing import PreprocessConfig

    task, fmt = task_from_options(args), format_from_options(args)
    check_format_fits(fmt, DataConfig.feature_set, PreprocessConfig(), args.format or "")
    config = DataConfig(str(data_dir_from_args(args, task)), annotations=args.annotations,
                        task=task, recording_format=fmt)
    dataset = load_dataset(config)
    out = plot_dataset(dataset.trials, args.out, config.preprocessing.sample_hz, task.gestures,
                       task.stage_names)
    print(f"wrote {out}")


def build_parser() -> argparse.ArgumentParser:
    parser = command_parser(PROG, __doc__)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = _subcommand(sub, "synth", _synth, "write a deterministic synthetic release of a task")
    out = p.add_argument("--out", type=Path, metavar="DIR",
                         help="folder to write the release into (required)")
    seed = add_synthetic_seed_argument(p)
    add_task_options(p)
    deprecated_positional(p, out)
    deprecated_alias(p, "--seed", seed)

    p = _subcommand(sub, "inspect", _inspect, "per-trial frames and gesture / progress histograms")
    _release_arguments(p, recording_format=True)

    p = _subcommand(sub, "stages", _stages,
                    "how each trial's labels follow the task's progress stages")
    _release_arguments(p, recording_format=True)

    p = _subcommand(sub, "amendments", _amendments, "what an annotation version changes")
    annotations = _release_arguments(p, recording_format=False)     # the release's frames
    deprecated_alias(p, "--version", annotations)

    p = _subcommand(sub, "plot", _plot, "PNG of gesture and progress ribbons for every trial")
    _release_arguments(p, recording_format=True)
    p.add_argument("--out", type=Path, default=Path("labels.png"), metavar="PNG",
                   help="image to write")
    return parser


def _subcommand(sub, name: str, run, summary: str) -> argparse.ArgumentParser:
    parser = sub.add_parser(name, help=summary, description=summary,
                            formatter_class=HelpFormatter)
    add_verbose_argument(parser, default=argparse.SUPPRESS)
    parser.set_defaults(run=run)
    return parser


def _release_arguments(parser: argparse.ArgumentParser, recording_format: bool
                       ) -> argparse.Action:
    """The release options (with ``--format`` if ``recording_format``), with the old positional
    folder as a deprecated alias; returns the ``--annotations`` action."""
    data = add_data_arguments(parser)
    if recording_format:
        add_format_option(data, "the data folder's recordings")
    actions = {a.dest: a for a in data._group_actions}
    deprecated_positional(parser, actions["data_dir"])
    return actions["annotations"]


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return run_command(PROG, args.verbose, lambda: args.run(args),
                       layout_advice=None if "format" in args else RELEASE_LAYOUT_ONLY, argv=argv)


if __name__ == "__main__":
    sys.exit(main())
