"""What a grid's own process costs to plan: ``multitask-grid --dry-run``'s CPU time, wall time and
peak memory, against the same dry run in a process that has imported TensorFlow first.

The grid's process plans, launches, watches and archives; only its workers train, so it never
imports TensorFlow (``tests/test_cli.py`` checks that). The reference is the same command run
after ``import tensorflow`` in the same process: what the grid's process cost while planning
imported the trainers. After one uncounted dry run (which may fill the data cache), the two
alternate ``--repeats`` times in one invocation, each a fresh process measured by the operating
system's accounting of that child alone (``os.wait4``). Prints the medians of each and the
ratios ours / reference (below 1: ours is cheaper).

    python bench/grid_start.py [--repeats 5] [--spec results/smoke.toml]
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DRY_RUN = ("import sys; from multitask.grid.cli import main; "
           "sys.exit(main(['--spec', sys.argv[1], '--out', sys.argv[2], '--dry-run']))")
COMMANDS = {"grid": DRY_RUN, "reference (TensorFlow imported)": "import tensorflow; " + DRY_RUN}


def measure(code: str, spec: Path) -> tuple[float, float, float]:
    """One dry run of ``spec`` by the Python ``code``: (CPU seconds, wall seconds, peak MB)."""
    env = {**os.environ, "TF_CPP_MIN_LOG_LEVEL": "3"}
    with tempfile.TemporaryDirectory() as scratch, open(Path(scratch) / "stderr", "w+") as said:
        start = time.perf_counter()
        child = subprocess.Popen([sys.executable, "-c", code, str(spec), str(Path(scratch) / "g")],
                                 stdout=subprocess.DEVNULL, stderr=said, env=env)
        _, status, usage = os.wait4(child.pid, 0)      # this child's own accounting
        wall = time.perf_counter() - start
        exit_code = os.waitstatus_to_exitcode(status)
        child.returncode = exit_code                   # reaped here, not by Popen
        said.seek(0)
        if exit_code:
            raise SystemExit(f"grid_start: the dry run failed (exit {exit_code}): {said.read()}")
    return usage.ru_utime + usage.ru_stime, wall, usage.ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--spec", type=Path, default=ROOT / "results" / "smoke.toml")
    args = parser.parse_args()
    results: dict[str, list[tuple[float, float, float]]] = {name: [] for name in COMMANDS}
    measure(DRY_RUN, args.spec)            # not counted: may write the synthetic release's cache
    for _ in range(args.repeats):
        for name, code in COMMANDS.items():
            results[name].append(measure(code, args.spec))
    print(f"multitask-grid --spec {args.spec} --dry-run, {args.repeats} alternating repeats "
          f"(medians):")
    medians = {}
    for name, rows in results.items():
        medians[name] = [statistics.median(column) for column in zip(*rows)]
        cpu, wall, peak = medians[name]
        print(f"  {name:32s} CPU {cpu:6.2f} s   wall {wall:6.2f} s   peak {peak:7.1f} MB")
    ours, reference = medians.values()
    print("  ours / reference: " + "   ".join(
        f"{label} {a / b:.3f}x" for label, a, b in zip(("CPU", "wall", "peak"), ours, reference)))


if __name__ == "__main__":
    main()
