"""Time one training sweep (forward, backward, SGD update) of the bidirectional LSTM model.

Compares ``rnn_seg``'s layer in float32 (``rnn_seg``), with bfloat16 products (``rnn_seg_bf16``,
when the CPU has native bfloat16) and with XLA-compiled loops (``rnn_seg_xla``) with a per-gate
reference written like the original code, at paper size (H=1024, B=5, 14 inputs, T=800) and
H=256, in the same run. Each (implementation, H) runs in its own process so its peak resident memory is its own; ``rnn_seg``
uses its own thread plan (rnn_seg.threads), the reference TensorFlow's default (its fastest
here). Also times the bare float32 recurrent product on this machine, which gives the float32
floor: T steps x 2 directions x 3 products. Prints medians, ratios to the floor and the
reference, and peak memory.

    python bench/lstm_sweep.py [--hidden 1024 256] [--repeats 5] [--steps 800]
    python bench/lstm_sweep.py --threads 1,2     # force a thread plan (intra, inter) on rnn_seg
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "bench")]
F, K, B = 14, 10, 5
IMPLEMENTATIONS = ("rnn_seg", "rnn_seg_bf16", "rnn_seg_xla", "per_gate")


def _step_function(impl: str, hidden: int):
    import tensorflow as tf

    from rnn_seg.dense import Dense
    from rnn_seg.lstm import EncoderConfig
    from rnn_seg.model import SegmentationModel
    from rnn_seg.optim import SGD
    from rnn_seg.tasks import SoftmaxClassification

    task = SoftmaxClassification("gesture", [f"G{k}" for k in range(K)])
    rng = tf.random.Generator.from_seed(0)
    dropout_rng = tf.random.Generator.from_seed(1)
    if impl.startswith("rnn_seg"):
        precision = "bf16" if impl.endswith("bf16") else "fp32"
        loops = "xla" if impl.endswith("xla") else "graph"
        model = SegmentationModel(F, EncoderConfig(hidden=hidden, precision=precision,
                                                   loops=loops), [task], seed=0)

        def outputs(x, r):
            return model(x, r, tf.transpose(dropout_rng.make_seeds(model.dropout_calls)))["gesture"]
        variables = model.trainable_variables
    else:
        from per_gate_reference import PerGateLSTM
        fw, rv = PerGateLSTM(F, hidden, rng, "fw"), PerGateLSTM(F, hidden, rng, "rv")
        head = Dense(2 * hidden, K, 0.1, rng, "head")

        def drop(t):
            return tf.nn.experimental.stateless_dropout(t, 0.5, seed=dropout_rng.make_seeds(1)[:, 0])

        def outputs(x, r):
            xt = tf.transpose(x, [1, 0, 2])
            rt = tf.transpose(tf.cast(r, tf.float32))[:, :, None]
            h_fw = drop(fw(drop(xt), rt))
            h_rv = tf.reverse(drop(rv(drop(tf.reverse(xt, [0])), tf.reverse(rt, [0]))), [0])
            return head(tf.transpose(tf.concat([h_fw, h_rv], 2), [1, 0, 2]))
        variables = [*fw.trainable_variables, *rv.trainable_variables, *head.trainable_variables]
    sgd = SGD(variables, momentum=0.0, clip_norm=1.0)

    @tf.function
    def step(x, r, y):
        with tf.GradientTape() as tape:
            loss = task.loss(outputs(x, r), y)
        sgd.apply(tape.gradient(loss, variables), variables, tf.constant(1.0))
        return loss
    return step


def worker(impl: str, hidden: int, steps: int, repeats: int, plan: str | None = None) -> dict:
    import numpy as np
    import tensorflow as tf

    from rnn_seg.threads import configure_threads

    if plan:
        intra, inter = (int(v) for v in plan.split(","))
        tf.config.threading.set_intra_op_parallelism_threads(intra)
        tf.config.threading.set_inter_op_parallelism_threads(inter)
        threads = (intra, inter)
    else:
        precision = "bf16" if impl.endswith("bf16") else "fp32"
        threads = (configure_threads(0, hidden, precision) if impl.startswith("rnn_seg")
                   else "TF default")

    rng = np.random.default_rng(0)
    x = tf.constant(rng.normal(size=(B, steps, F)).astype(np.float32))
    r = tf.constant(np.eye(1, steps, dtype=bool).repeat(B, 0))
    y = tf.constant(np.eye(K, dtype=np.float32)[rng.integers(0, K, (B, steps))])
    step = _step_function(impl, hidden)
    step(x, r, y).numpy()                               # trace and warm up
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        step(x, r, y).numpy()
        times.append(time.perf_counter() - start)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"impl": impl, "hidden": hidden, "times": times, "peak_mb": peak_mb, "threads": threads}


def product_time(hidden: int, repeats: int) -> float:
    """Seconds for one recurrent product ``[B, H] x [H, 4H]``: fastest of ``repeats`` loops of 800,
    all cores inside each product."""
    import tensorflow as tf

    tf.config.threading.set_intra_op_parallelism_threads(os.cpu_count() or 1)
    tf.config.threading.set_inter_op_parallelism_threads(1)

    steps = 800
    h, W = tf.random.normal([B, hidden]), tf.random.normal([hidden, 4 * hidden]) * 0.01

    @tf.function
    def loop():
        return tf.while_loop(lambda t, a: t < steps,
                             lambda t, a: (t + 1, tf.tanh(tf.matmul(a, W)[:, :hidden])), (0, h))[1]
    loop().numpy()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        loop().numpy()
        times.append(time.perf_counter() - start)
    return min(times) / steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--hidden", type=int, nargs="+", default=[1024, 256])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--steps", type=int, default=800)
    parser.add_argument("--impl", nargs="+", default=list(IMPLEMENTATIONS))
    parser.add_argument("--threads", help="thread plan 'intra,inter' for rnn_seg (default: its "
                                          "own plan, rnn_seg.threads)")
    parser.add_argument("--worker", nargs=2, metavar=("IMPL", "HIDDEN"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        impl, hidden = args.worker[0], int(args.worker[1])
        result = (product_time(hidden, args.repeats) if impl == "product"
                  else worker(impl, hidden, args.steps, args.repeats,
                              args.threads if impl.startswith("rnn_seg") else None))
        print(json.dumps(result))
        return
    if not _native_bf16():
        args.impl = [i for i in args.impl if i != "rnn_seg_bf16"]
        print("no native bfloat16 on this CPU: rnn_seg_bf16 skipped")
    print(f"training sweep: bidirectional LSTM, B={B}, F={F}, T={args.steps}, "
          f"{args.repeats} timed repeats after one warm-up; {os.cpu_count()} cores")
    for hidden in args.hidden:
        product = _run_worker("product", hidden, args)
        floor = product * args.steps * 2 * 3        # 2 directions; 1 product forward, 2 backward
        print(f"H={hidden:5d} recurrent product {product * 1e6:.0f} us -> floor "
              f"{args.steps} x 2 x 3 x product = {floor:.3f} s per sweep")
        results = {impl: _run_worker(impl, hidden, args) for impl in args.impl}
        for impl, res in results.items():
            med = statistics.median(res["times"])
            print(f"H={hidden:5d} {impl:9s} median {med:7.3f} s  "
                  f"(min {min(res['times']):.3f}, max {max(res['times']):.3f})  "
                  f"{med / floor:.2f}x floor  peak RSS {res['peak_mb']:6.0f} MB  "
                  f"threads (intra, inter) {res['threads']}")
        medians = {impl: statistics.median(res["times"]) for impl, res in results.items()}
        if {"rnn_seg", "per_gate"} <= set(medians):
            print(f"H={hidden:5d} speed-up rnn_seg vs per_gate: "
                  f"{medians['per_gate'] / medians['rnn_seg']:.2f}x")
        if {"rnn_seg", "rnn_seg_bf16"} <= set(medians):
            print(f"H={hidden:5d} speed-up bf16 vs fp32: "
                  f"{medians['rnn_seg'] / medians['rnn_seg_bf16']:.2f}x")
        if {"rnn_seg", "rnn_seg_xla"} <= set(medians):
            print(f"H={hidden:5d} speed-up xla loops vs graph: "
                  f"{medians['rnn_seg'] / medians['rnn_seg_xla']:.2f}x")


def _native_bf16() -> bool:
    from rnn_seg.lstm import native_bf16
    return native_bf16()


def _run_worker(impl: str, hidden: int, args):
    command = [sys.executable, __file__, "--worker", impl, str(hidden), "--steps",
               str(args.steps), "--repeats", str(args.repeats)]
    if args.threads:
        command += ["--threads", args.threads]
    out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


if __name__ == "__main__":
    main()
