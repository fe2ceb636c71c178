"""Training cost of the temporal-convolution encoders against the LSTM's, per sweep and per run.

Builds APc (gestures + progress classification, w1 = w2 = 1) on one LOUO fold of the synthetic
release (user B held out) for each encoder at its own batch size, traces its training step, then
times ``--sweeps`` training sweeps (after one warm-up sweep) and prints the median seconds per
sweep, the sweeps of a full run at the encoder's reference schedule (the paper's 120 epochs for
the LSTM) and that run's estimated training time. The synthetic trials are as long as the real
ones (about 1-5 minutes at 5 Hz), so the costs carry over; evaluation and checkpoints are not
counted. Nothing is written outside a temporary folder.

    nice -n 19 python bench/tcn_training.py [--sweeps 20] [--hidden 128 1024] [--threads 0]
                                            [--loops auto]
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

ENCODERS = ("ed-tcn", "ms-tcn")


def _config(data_dir: str, encoder, optim, batch: int):
    from baseline.config import RunConfig
    from jigsaws_tools.dataset import DataConfig
    from rnn_seg.config import TrainConfig

    return RunConfig(data=DataConfig(data_dir), test_user="B", encoder=encoder, optim=optim,
                     train=TrainConfig(batch_size=batch, eval_points=(optim.total,),
                                       plots="none"))


def measure(config, sweeps: int, folder: Path) -> dict:
    """Trace time, median seconds per sweep and the full run's sweeps of ``config``'s APc."""
    from multitask.models.fold_run import variant_trainer
    from multitask.models.variants import get_variant

    trainer = variant_trainer(get_variant("APc"), "fixed", config, folder, log=lambda m: None)
    trainer.prepare()
    began = time.perf_counter()
    trainer.compile()
    trace = time.perf_counter() - began
    trainer.step(0, 1e-3)                                     # warm-up
    times = []
    for sweep in range(1, sweeps + 1):
        began = time.perf_counter()
        trainer.step(sweep, 1e-3)
        times.append(time.perf_counter() - began)
    per_sweep = statistics.median(times)
    return {"trace_s": trace, "sweep_s": per_sweep, "run_sweeps": trainer.total_sweeps,
            "run_min": per_sweep * trainer.total_sweeps / 60}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sweeps", type=int, default=20)
    parser.add_argument("--hidden", type=int, nargs="+", default=[128],
                        help="LSTM widths to time beside the TCNs")
    parser.add_argument("--threads", type=int, default=0)
    parser.add_argument("--loops", default="auto", choices=["auto", "graph", "xla", "fused"],
                        help="the LSTM's loops (default: the engine's default, auto; the "
                             "2026-11-27 numbers of docs/PERFORMANCE.md are graph's)")
    args = parser.parse_args()

    from jigsaws_tools.dataset import default_cache_dir
    from jigsaws_tools.synth import SynthConfig, ensure_release
    from multitask.models.variants import batch_size, get_variant
    from rnn_seg.config import EncoderConfig
    from rnn_seg.encoders.config import encoder_config
    from rnn_seg.lstm import runnable
    from rnn_seg.threads import configure_threads

    configure_threads(args.threads, max(args.hidden), "fp32")
    data = str(ensure_release(default_cache_dir(), SynthConfig()))
    variant = get_variant("APc")
    loops = runnable(args.loops, "fp32")                # what auto is here
    setups = [(f"lstm H={h} {loops}", EncoderConfig(hidden=h, loops=loops),
               variant.optim(), batch_size("lstm")) for h in args.hidden]
    setups += [(kind, encoder_config(kind), variant.optim(kind), batch_size(kind))
               for kind in ENCODERS]
    print(f"{'encoder':<20} {'batch':>5} {'trace s':>8} {'s/sweep':>8} {'sweeps/run':>10} "
          f"{'min/run':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, encoder, optim, batch in setups:
            config = _config(data, encoder, replace(optim), batch)
            m = measure(config, args.sweeps, Path(tmp) / name.replace(" ", "_"))
            print(f"{name:<20} {batch:>5} {m['trace_s']:>8.1f} {m['sweep_s']:>8.3f} "
                  f"{m['run_sweeps']:>10} {m['run_min']:>8.1f}", flush=True)


if __name__ == "__main__":
    main()
