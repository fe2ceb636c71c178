"""Where one run's wall time goes, and how much of it is not training.

Launches one ``multitask-train`` run at the ``quick`` preset's settings (APc, w1 = w2 = 1, H=128,
30 epochs, learning rate halved after 20, evaluated after epochs 25, 28 and 30, held-out user B,
one core; real data if present, else the synthetic release) in a fresh process and folder, and
splits its wall time into: process start and imports (timed on their own, in a separate process,
in the same invocation), then from the run's ``timing.json``: data loading, graph tracing,
training sweeps, monitoring (progress lines), evaluations (predictions, CSVs, plots) and
checkpoints; what is left is configuration, final writes and exit. Repeats and prints medians.
The LSTM runs the engine's default loops (``auto``: the fused ones where they build, since
2026-11-27; ``graph`` before) unless the extra options name ``--loops``.

    python bench/run_cost.py [--repeats 3] [--variant APc] [--hidden 128] [--epochs 30]
                             [--eval-at 25,28,30] [--threads 1] [-- extra multitask-train options]
"""
from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fold_time import data_source, run_parser  # noqa: E402

PHASES = ("data", "trace", "train", "monitor", "evaluate", "checkpoint")


def timed(command: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    return time.perf_counter() - start


def one_run(args, extra: list[str]) -> dict[str, float]:
    """Seconds per part of one fresh run."""
    data = data_source()
    source = ["--synthetic"] if data == "synthetic" else ["--data-dir", data]
    imports = timed([sys.executable, "-c", "import multitask.train_cli, tensorflow"])
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        total = timed([sys.executable, "-m", "multitask.train_cli", "--variant", args.variant,
                       "--hidden", str(args.hidden), "--epochs", str(args.epochs),
                       "--decay-start", str(2 * args.epochs // 3),
                       "--decay-every", str(max(1, args.epochs // 3)),
                       "--eval-at", args.eval_at, "--test-user", "B",
                       "--threads", str(args.threads), "--out", str(out), *source, *extra])
        phases = json.loads((out / "timing.json").read_text())
    parts = {"start+imports": imports, **{p: phases.get(p, 0.0) for p in PHASES}}
    parts["other"] = max(0.0, total - sum(parts.values()))
    parts["total"] = total
    return parts


def main() -> None:
    parser = run_parser(__doc__)
    parser.add_argument("--eval-at", default="25,28,30")
    parser.add_argument("--threads", type=int, default=1)
    args, extra = parser.parse_known_args()
    extra = [e for e in extra if e != "--"]
    print(f"one run: {args.variant}, H={args.hidden}, {args.epochs} epochs, evaluated at "
          f"{args.eval_at}, {args.threads} core(s), data {data_source()}; median of "
          f"{args.repeats}" + (f"; extra options {' '.join(extra)}" if extra else ""))
    runs = [one_run(args, extra) for _ in range(args.repeats)]
    median = {part: statistics.median(r[part] for r in runs) for part in runs[0]}
    for part, seconds in median.items():
        spread = [r[part] for r in runs]
        print(f"  {part:14s} {seconds:7.2f} s  {100 * seconds / median['total']:5.1f} %  "
              f"(min {min(spread):.2f}, max {max(spread):.2f})")
    shares = [1 - r["train"] / r["total"] for r in runs]
    print(f"non-training share: {100 * statistics.median(shares):.0f} % "
          f"(min {100 * min(shares):.0f}, max {100 * max(shares):.0f})")


if __name__ == "__main__":
    main()
