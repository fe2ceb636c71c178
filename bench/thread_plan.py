"""Which thread plan holds up on a shared machine: each plan with and without a competing load.

For each LSTM width and precision, times a training sweep (``bench/lstm_sweep.py``'s worker,
one process per measurement) under every thread plan ``(intra_op, inter_op)`` of this machine's
cores: both cores inside each product ``(2, 1)``, one core per direction ``(1, 2)``, both pools
at 2 ``(2, 2)``, and one core ``(1, 1)``; once on a quiet machine and once next to a competing
process that keeps one core busy (another tenant). Prints the median and the spread (max / min)
of the timed sweeps of every plan, all measured in the same invocation; the plan to keep is the
one with the best median under load and the smallest spread.

    python bench/thread_plan.py [--hidden 1024 256] [--precision fp32 bf16] [--repeats 5]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

SWEEP = Path(__file__).resolve().parent / "lstm_sweep.py"
PLANS = ("2,1", "1,2", "2,2", "1,1")


@contextmanager
def competing_load(busy: bool) -> Iterator[None]:
    """A process spinning on one core while the block runs (nothing when ``busy`` is False)."""
    process = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None
    try:
        yield
    finally:
        if process:
            process.kill()
            process.wait()


def sweep_times(hidden: int, precision: str, plan: str, args) -> list[float]:
    impl = "rnn_seg_bf16" if precision == "bf16" else "rnn_seg"
    out = subprocess.run([sys.executable, str(SWEEP), "--worker", impl, str(hidden), "--steps",
                          str(args.steps), "--repeats", str(args.repeats), "--threads", plan],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])["times"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hidden", type=int, nargs="+", default=[1024, 256])
    parser.add_argument("--precision", nargs="+", default=["fp32", "bf16"])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--steps", type=int, default=800)
    args = parser.parse_args()
    print(f"training sweep, B=5, T={args.steps}, {args.repeats} timed sweeps per plan; "
          f"{os.cpu_count()} cores; plans (intra, inter)")
    for hidden in args.hidden:
        for precision in args.precision:
            for busy in (False, True):
                with competing_load(busy):
                    for plan in PLANS:
                        times = sweep_times(hidden, precision, plan, args)
                        print(f"H={hidden:5d} {precision} {'load ' if busy else 'quiet'} "
                              f"plan ({plan}): median {statistics.median(times):7.3f} s  "
                              f"spread {max(times) / min(times):5.2f}x  "
                              f"(min {min(times):.3f}, max {max(times):.3f})", flush=True)


if __name__ == "__main__":
    main()
