"""What reading a grid's run records costs, as every table command reads them, against the same
reading with the two per-process lookups it keeps undone (the reference: each record resolving
its dataclasses' annotations, and looking its shipped task definition up, anew, as before
68d978e).

``multitask.evidence.runs.collect.run_records`` of ``--grid`` (default ``results/grid``, 416
runs, committed) in this process, alternating the two ways ``--repeats`` times after one
uncounted read; prints the median CPU seconds of each and the ratio ours / reference (below 1:
ours is cheaper), and checks that both read the same rows.

    python bench/record_reading.py [--repeats 5] [--grid results/grid]
"""
from __future__ import annotations

import argparse
import statistics
import time
import typing
from contextlib import contextmanager, nullcontext
from pathlib import Path

from jigsaws_tools import toml_files
from multitask.evidence.runs.collect import run_records
from rnn_seg.runs import folder

ROOT = Path(__file__).resolve().parent.parent


@contextmanager
def uncached():
    """Each record's lookups done anew, as before they were kept per process."""
    kept = folder._field_types, toml_files._read_builtin
    folder._field_types = typing.get_type_hints
    toml_files._read_builtin = lambda kind, name, read: read(toml_files.builtin_path(kind, name))
    try:
        yield
    finally:
        folder._field_types, toml_files._read_builtin = kept


def timed_read(grid: Path):
    """(CPU seconds, rows) of one ``run_records`` of ``grid``."""
    start = time.process_time()
    rows = run_records(grid, allow_incomplete=True)[0]
    return time.process_time() - start, rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--grid", type=Path, default=ROOT / "results" / "grid")
    args = parser.parse_args()
    _, expected = timed_read(args.grid)                 # not counted: imports, first reads
    seconds: dict[str, list[float]] = {"ours": [], "reference (uncached)": []}
    for _ in range(args.repeats):
        for name in seconds:
            with nullcontext() if name == "ours" else uncached():
                cpu, rows = timed_read(args.grid)
            if not rows.equals(expected):
                raise SystemExit(f"record_reading: {name} read other rows")
            seconds[name].append(cpu)
    print(f"run_records({args.grid}): {len(expected)} runs, {args.repeats} alternating repeats "
          f"(median CPU s):")
    medians = {name: statistics.median(values) for name, values in seconds.items()}
    for name, median in medians.items():
        print(f"  {name:22s} {median:7.3f} s   (min {min(seconds[name]):.3f}, "
              f"max {max(seconds[name]):.3f})")
    ours, reference = medians.values()
    print(f"  ours / reference: {ours / reference:.3f}x")


if __name__ == "__main__":
    main()
