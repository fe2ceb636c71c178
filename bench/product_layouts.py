"""Per-step cost of the LSTM's two recurrent products in each operand layout and type.

A batch of 5 rows is far from what matrix kernels are tuned for, so the layout of the operands
matters as much as their type. Times one recurrent step's forward product ``h W_h`` ([5, H] x
[H, 4H]) and backward product ``dz W_h^T`` ([5, 4H] x [4H, H]) in three layouts each, float32
and bfloat16, as a loop of 400 steps (the minimum of 5 loops). ``rnn_seg.lstm.RecurrentProducts``
uses the fastest layout of each type.

    python bench/product_layouts.py [--hidden 1024] [--threads 1]
"""
from __future__ import annotations

import argparse
import os
import time

STEPS, B = 400, 5


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hidden", type=int, default=1024)
    parser.add_argument("--threads", type=int, default=1, help="intra-op threads per product")
    args = parser.parse_args()
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
    from jigsaws_tools.cli.common import import_tensorflow
    tf = import_tensorflow()

    tf.config.threading.set_intra_op_parallelism_threads(args.threads)
    tf.config.threading.set_inter_op_parallelism_threads(1)
    H = args.hidden

    def per_step(step, init) -> float:
        @tf.function
        def loop():
            return tf.while_loop(lambda t, a: t < STEPS, lambda t, a: (t + 1, step(a)),
                                 (0, init), parallel_iterations=1)[1]
        loop()
        times = []
        for _ in range(5):
            start = time.perf_counter()
            loop().numpy()
            times.append(time.perf_counter() - start)
        return min(times) / STEPS * 1e6

    print(f"H={H}, batch {B}, {args.threads} thread(s) per product; us per recurrent step")
    weights = tf.random.normal([H, 4 * H]) * 0.01
    h, dz = tf.random.normal([B, H]), tf.random.normal([B, 4 * H])
    for dtype in (tf.float32, tf.bfloat16):
        W = tf.cast(weights, dtype)
        W_t = tf.transpose(W)

        def f32(x):
            return tf.cast(x, tf.float32)

        def lo(x):
            return tf.cast(x, dtype)
        forward = {"h W": lambda a: f32(tf.matmul(lo(a), W)),
                   "(W^T h^T)^T": lambda a: tf.transpose(f32(tf.matmul(W_t, lo(a),
                                                                       transpose_b=True))),
                   "h (W^T)^T, transpose_b": lambda a: f32(tf.matmul(lo(a), W_t,
                                                                     transpose_b=True))}
        backward = {"dz W^T, W^T stored": lambda a: f32(tf.matmul(lo(a), W_t)),
                    "dz W^T, transpose_b": lambda a: f32(tf.matmul(lo(a), W, transpose_b=True)),
                    "(W dz^T)^T": lambda a: tf.transpose(f32(tf.matmul(W, lo(a),
                                                                       transpose_b=True)))}
        for name, product in forward.items():        # loop h -> tanh(h W)[:, :H]
            cost = per_step(lambda a, p=product: tf.tanh(p(a))[:, :H], h)
            print(f"{dtype.name:8s} forward  {name:26s} {cost:7.1f}")
        for name, product in backward.items():       # loop dz -> tile(tanh(dz W^T))
            cost = per_step(lambda a, p=product: tf.tile(tf.tanh(p(a)), [1, 4]), dz)
            print(f"{dtype.name:8s} backward {name:26s} {cost:7.1f}")


if __name__ == "__main__":
    main()
