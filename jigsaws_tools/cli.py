"""``jigsaws-tools``: write a synthetic release, inspect a release, list amendments, plot labels.

Every subcommand reads one task's release: ``--task`` (Suturing, the default; Knot_Tying;
Needle_Passing) or ``--task-file`` (your own definition).
"""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

import pandas as pd

from .annotations import ANNOTATION_VERSIONS, amendment_report
from .dataset import DataConfig, load_dataset
from .errors import JigsawsError
from .plots import plot_dataset
from .release import discover
from .summary import release_summary
from .synth import SynthConfig, write_release
from .task_options import add_task_options, task_from_options


def _synth(args: argparse.Namespace) -> None:
    task = task_from_options(args)
    out = write_release(args.out, SynthConfig(seed=args.seed), task)
    print(f"wrote a synthetic {task.name} release (seed {args.seed}) to {out}")


def _inspect(args: argparse.Namespace) -> None:
    task = task_from_options(args)
    index = discover(args.dir, task)
    table = release_summary(index, args.annotations)
    print(task.describe() + "\n")
    with pd.option_context("display.max_rows", None, "display.width", 200):
        print(table.to_string())
    print(f"\n{len(table)} complete trials, {table['frames'].sum()} frames at 30 Hz, "
          f"{table['labelled'].sum()} labelled ({args.annotations} annotations)")
    print("gestures:", _histogram(table[list(task.gestures)].sum()))
    print("progress:", _histogram(table[list(task.stage_labels)].sum()))
    print("missing kinematics:", ", ".join(index.missing_kinematics) or "none")
    print("missing transcription:", ", ".join(index.missing_transcription) or "none")
    print("unusable files:", "; ".join(index.unusable) or "none")


def _histogram(counts: pd.Series) -> str:
    """``G1 4102 (3.2%), G2 ...``: frame counts and shares."""
    total = counts.sum()
    return ", ".join(f"{k} {int(v)} ({100 * v / total:.1f}%)" for k, v in counts.items())


def _amendments(args: argparse.Namespace) -> None:
    report = amendment_report(discover(args.dir, task_from_options(args)), args.version)
    total = 0
    print(f"{'trial':15} {'start':>6} {'end':>6} {'new':>4} {'changed':>8}  previous labels / status")
    for name, e in report:
        a = e.amendment
        previous = ", ".join(f"{k}:{v}" for k, v in e.previous.items())
        print(f"{name:15} {a.start:6d} {a.end:6d} {a.gesture:>4} {e.frames_changed:8d}  "
              f"{previous}  [{e.status}]")
        total += e.frames_changed
    print(f"{len(report)} amendments, {total} frames relabelled")


def _plot(args: argparse.Namespace) -> None:
    config = DataConfig(str(args.dir), annotations=args.annotations, task=task_from_options(args))
    dataset = load_dataset(config)
    out = plot_dataset(dataset.trials, args.out, config.preprocessing.sample_hz, config.task)
    print(f"wrote {out}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="jigsaws-tools", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("synth", help="write a deterministic synthetic Suturing release")
    p.add_argument("out", type=Path)
    p.add_argument("--seed", type=int, default=0)
    add_task_options(p)
    p.set_defaults(run=_synth)
    p = sub.add_parser("inspect", help="per-trial frames and gesture / progress histograms")
    p.add_argument("dir", type=Path)
    p.add_argument("--annotations", choices=ANNOTATION_VERSIONS, default="revised")
    add_task_options(p)
    p.set_defaults(run=_inspect)
    p = sub.add_parser("amendments", help="what an annotation version changes")
    p.add_argument("dir", type=Path)
    p.add_argument("--version", choices=ANNOTATION_VERSIONS, default="revised")
    add_task_options(p)
    p.set_defaults(run=_amendments)
    p = sub.add_parser("plot", help="PNG of gesture and progress ribbons for every trial")
    p.add_argument("dir", type=Path)
    p.add_argument("--out", type=Path, default=Path("labels.png"))
    p.add_argument("--annotations", choices=ANNOTATION_VERSIONS, default="revised")
    add_task_options(p)
    p.set_defaults(run=_plot)
    return parser


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(format="%(levelname)s: %(message)s", level=logging.WARNING)
    args = build_parser().parse_args(argv)
    try:
        args.run(args)
    except JigsawsError as error:
        print(f"jigsaws-tools: error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
