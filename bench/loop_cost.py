"""Per-step cost of the LSTM's loops over time: TensorFlow ops step by step, XLA, fused C++ ops.

Times, on one core, one direction's forward loop (``h W_h`` and the cell, recording every
step's activations) and backward loop (the per-step factors, then ``dz W_h^T`` and the chain
rule step by step), each as ``graph`` (TensorFlow ops, as ``--loops graph`` runs them) and
``xla`` (one compiled kernel, as ``--loops xla``) and ``fused`` (the C++ ops of
``rnn_seg.kernels``, as ``--loops fused``; left out, saying why, where they cannot be built), plus
a loop of the bare product ``h W_h`` alone: what a step would cost without the cell's other ops.
B=5, T=900 (a sweep of the real data), float32; median of 7 calls after a warm-up (that
compiles). Prints microseconds per step and each path's speed-up over ``graph``.

    python bench/loop_cost.py [--hidden 128 256 512 1024] [--steps 900]
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

B = 5


def per_step(function, steps: int, repeats: int = 7) -> float:
    """Microseconds per step of ``function()``: median of ``repeats`` calls after a warm-up."""
    from jigsaws_tools.cli.common import import_tensorflow
    tf = import_tensorflow()

    tf.nest.flatten(function())[0].numpy()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        tf.nest.flatten(function())[0].numpy()
        times.append(time.perf_counter() - start)
    return statistics.median(times) / steps * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hidden", type=int, nargs="+", default=[128, 256, 512, 1024])
    parser.add_argument("--steps", type=int, default=900)
    args = parser.parse_args()
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
    import numpy as np
    from jigsaws_tools.cli.common import import_tensorflow
    tf = import_tensorflow()

    from rnn_seg import lstm
    from rnn_seg.kernels.build import unavailable

    paths = list(lstm._LOOP_FUNCTIONS)
    if (reason := unavailable("fp32")) is not None:
        print(f"fused loops left out: {reason}")
        paths.remove("fused")

    tf.config.threading.set_intra_op_parallelism_threads(1)
    tf.config.threading.set_inter_op_parallelism_threads(1)
    T = args.steps
    print(f"one direction, B={B}, T={T}, float32, one core; us per step")
    columns = [f"{phase} {path}" for phase in ("forward", "backward") for path in paths]
    print(f"{'H':>5s} {'bare product':>12s} " + " ".join(f"{c:>14s}" for c in columns))
    rng = np.random.default_rng(0)
    for H in args.hidden:
        x_proj = tf.constant(rng.normal(size=(T, B, 4 * H)).astype(np.float32))
        keep = tf.ones([T, B, 1])
        W_h = tf.constant((rng.normal(size=(H, 4 * H)) * 0.1).astype(np.float32))
        peep = tf.constant((rng.normal(size=(3, H)) * 0.1).astype(np.float32))
        dh_out = tf.constant(rng.normal(size=(T, B, H)).astype(np.float32))
        state = lstm._forward_loop(x_proj, keep, W_h, peep, T)
        c_prev = keep * lstm._shift(state[1])

        @tf.function
        def bare():
            return tf.while_loop(lambda t, h: t < T,
                                 lambda t, h: (t + 1, tf.matmul(h, W_h)[:, :H]),
                                 (0, dh_out[0]), parallel_iterations=1)[1]

        costs = {"bare": per_step(bare, T)}
        for loops in paths:
            forward, backward = lstm._LOOP_FUNCTIONS[loops]
            forward = tf.function(forward) if loops == "graph" else forward
            backward = tf.function(backward) if loops == "graph" else backward
            costs["forward", loops] = per_step(
                lambda f=forward: f(x_proj, keep, W_h, peep, T), T)
            costs["backward", loops] = per_step(
                lambda b=backward: b(dh_out, keep, state, c_prev, W_h, peep, T), T)
        cells = []
        for phase in ("forward", "backward"):
            for path in paths:
                cost, speed_up = costs[phase, path], costs[phase, "graph"] / costs[phase, path]
                cells.append(f"{cost:.1f}" + ("" if path == "graph" else f" ({speed_up:.2f}x)"))
        print(f"{H:5d} {costs['bare']:12.1f} " + " ".join(f"{c:>14s}" for c in cells), flush=True)


if __name__ == "__main__":
    main()
