"""Time one training sweep (forward, backward, SGD update) of the bidirectional LSTM model.

Compares ``rnn_seg``'s layer in float32 (``rnn_seg``), with bfloat16 products (``rnn_seg_bf16``,
when the CPU has native bfloat16), with XLA-compiled loops (``rnn_seg_xla``) and with the fused
C++ loops of ``rnn_seg.kernels`` (``rnn_seg_fused``, ``rnn_seg_fused_bf16``) with a per-gate
reference written like the original code and with two peers doing the same workload, PyTorch's
``nn.LSTM`` (``torch``, ``torch_bf16``: CPU autocast) and Keras's ``Bidirectional(LSTM)`` in our
TensorFlow (``keras``, ``keras_bf16``: the ``mixed_bfloat16`` policy), at paper size (H=1024,
B=5, 14 inputs, T=800) and H=256, in the same run. The peers' cells have no peepholes
(``lstm_peers.py`` lists what else differs); a peer not installed is skipped (``pip install -e
".[bench]"`` installs PyTorch). Each (implementation, H) runs in its own process so its peak
resident memory is its own; ``rnn_seg`` uses its own thread plan (rnn_seg.threads), the
reference TensorFlow's default (its fastest here), the peers every core in each op and as many
ops at once (intra = inter = cores). Also times the bare float32 recurrent product on this
machine, which gives the float32 floor: T steps x 2 directions x 3 products. Prints medians,
ratios to the floor, the reference and the peers, and peak memory.

    python bench/lstm_sweep.py [--hidden 1024 256] [--repeats 5] [--steps 800]
    python bench/lstm_sweep.py --threads 1,2     # force a thread plan (intra, inter) on rnn_seg
                                                 # and the peers
    python bench/lstm_sweep.py --impl rnn_seg torch keras     # a subset
    python bench/lstm_sweep.py --batch 6       # another batch (sequences per sweep; default 5)
    python bench/lstm_sweep.py --isa avx2      # the AVX2 contest on an AVX-512 machine: the fused
                                               # loops built for haswell, oneDNN (TensorFlow's
                                               # and PyTorch's) limited to AVX2

It prints the processor, its vector width and, for the fused loops, which product the library
runs (``rnn_seg.kernels``: AVX-512 or AVX2), and which loops ``auto`` (the default) runs here
beside the fastest of ours measured.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "bench")]
from jigsaws_tools.cli.arg_types import positive_int  # noqa: E402 (on the path above)
from jigsaws_tools.cli.common import import_tensorflow  # noqa: E402
from jigsaws_tools.cores import usable_cores  # noqa: E402

F, K, B = 14, 10, 5
IMPLEMENTATIONS = ("rnn_seg", "rnn_seg_bf16", "rnn_seg_xla", "rnn_seg_fused",
                   "rnn_seg_fused_bf16", "per_gate", "torch", "torch_bf16", "keras", "keras_bf16")
#: Each peer's package (the first part of its name) and how to install it.
PEERS = {"torch": "pip install -e '.[bench]'", "keras": "pip install keras"}
#: ``--isa`` -> the environment every worker gets: the fused loops' build target and oneDNN's.
ISA_LIMITS = {"native": {}, "avx2": {"RNN_SEG_MARCH": "haswell", "ONEDNN_MAX_CPU_ISA": "AVX2"}}
#: Our implementations by the loops they run (``auto`` is one of them: which, ``rnn_seg.lstm``).
OUR_LOOPS = {"rnn_seg": "graph", "rnn_seg_xla": "xla", "rnn_seg_fused": "fused"}
#: (label, slower, faster): each prints ``slower``'s median over ``faster``'s when both ran.
RATIOS = (("rnn_seg vs per_gate", "per_gate", "rnn_seg"),
          ("bf16 vs fp32", "rnn_seg", "rnn_seg_bf16"),
          ("xla loops vs graph", "rnn_seg", "rnn_seg_xla"),
          ("fused loops vs graph", "rnn_seg", "rnn_seg_fused"),
          ("fused bf16 vs graph bf16", "rnn_seg_bf16", "rnn_seg_fused_bf16"),
          ("fused vs torch (fp32)", "torch", "rnn_seg_fused"),
          ("fused bf16 vs torch (bf16)", "torch_bf16", "rnn_seg_fused_bf16"),
          ("rnn_seg vs torch (fp32)", "torch", "rnn_seg"),
          ("rnn_seg vs torch (bf16)", "torch_bf16", "rnn_seg_bf16"),
          ("rnn_seg vs keras (fp32)", "keras", "rnn_seg"),
          ("rnn_seg vs keras (bf16)", "keras_bf16", "rnn_seg_bf16"))


def _step_function(impl: str, hidden: int):
    tf = import_tensorflow()

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
        loops = next((name for name in ("xla", "fused") if f"_{name}" in impl), "graph")
        model = SegmentationModel(F, EncoderConfig(hidden=hidden, precision=precision,
                                                   loops=loops), [task], seed=0)
        if model.encoder.config.loops != loops:
            from lstm_peers import Unsupported
            raise Unsupported(f"{loops} loops unavailable here (the line above says why)")

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


def worker(impl: str, hidden: int, steps: int, repeats: int, plan: str | None = None,
           batch: int = B) -> dict:
    """Time ``repeats`` sweeps of ``impl`` over ``batch`` sequences after one warm-up, in this
    process.

    ``plan`` is ``"intra,inter"`` or None (``rnn_seg``: its own plan; ``per_gate``: TensorFlow's
    default). Returns seconds per sweep, peak resident MB and the threads used, or, where the
    peer cannot run the variant here, why it was skipped.
    """
    from lstm_peers import Unsupported

    x, r, y = _batch(steps, batch)
    build = _torch_sweep if impl.startswith("torch") else _tensorflow_sweep
    try:
        sweep, threads = build(impl, hidden, x, r, y, plan)
    except Unsupported as reason:
        return {"impl": impl, "hidden": hidden, "skipped": str(reason)}
    sweep()                                             # trace and warm up
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        sweep()
        times.append(time.perf_counter() - start)
    result = {"impl": impl, "hidden": hidden, "times": times, "peak_mb": _peak_mb(),
              "threads": threads}
    if "fused" in impl:
        from rnn_seg.kernels.build import describe
        from rnn_seg.lstm import weight_gradient_path
        result["product"] = (f"{describe()}; "
                             f"{weight_gradient_path('bf16' if 'bf16' in impl else 'fp32')}")
    return result


def _peak_mb() -> float:
    """This process's peak resident memory in MB (Linux: ``VmHWM``). Not ``ru_maxrss``: a worker
    spawned by the parent inherits the parent's (TensorFlow imported, ~600 MB) across ``exec``."""
    status = Path("/proc/self/status").read_text()
    return int(re.search(r"^VmHWM:\s+(\d+) kB", status, re.M).group(1)) / 1024


def _batch(steps: int, batch: int = B) -> tuple:
    """One batch as NumPy: inputs ``[batch, T, F]`` float32 normal, resets ``[batch, T]`` bool
    (step 0 only), one-hot targets ``[batch, T, K]`` float32."""
    import numpy as np

    rng = np.random.default_rng(0)
    x = rng.normal(size=(batch, steps, F)).astype(np.float32)
    r = np.eye(1, steps, dtype=bool).repeat(batch, 0)
    y = np.eye(K, dtype=np.float32)[rng.integers(0, K, (batch, steps))]
    return x, r, y


def _tensorflow_sweep(impl: str, hidden: int, x, r, y, plan: str | None):
    """``rnn_seg*``, ``per_gate`` or ``keras*``: (a call running one sweep, threads used)."""
    tf = import_tensorflow()

    from lstm_peers import keras_step
    from rnn_seg.threads import configure_threads

    if plan:
        intra, inter = _threads(plan)
        tf.config.threading.set_intra_op_parallelism_threads(intra)
        tf.config.threading.set_inter_op_parallelism_threads(inter)
        threads = (intra, inter)
    else:
        threads = (configure_threads(0, hidden, _precision(impl)) if impl.startswith("rnn_seg")
                   else "TF default")
    if impl.startswith("keras"):
        return keras_step(hidden, _precision(impl), x, y), threads
    step = _step_function(impl, hidden)
    x, r, y = tf.constant(x), tf.constant(r), tf.constant(y)
    return (lambda: step(x, r, y).numpy()), threads


def _torch_sweep(impl: str, hidden: int, x, r, y, plan: str):
    """``torch*``: (a call running one sweep, threads used); no TensorFlow in this process.
    PyTorch's LSTM takes no resets: the batch's only one is at step 0, its zero initial state."""
    from lstm_peers import torch_step

    threads = _threads(plan)
    return torch_step(hidden, _precision(impl), x, y, threads), threads


def _threads(plan: str) -> tuple[int, int]:
    """``"intra,inter"`` -> (intra, inter)."""
    intra, inter = (int(v) for v in plan.split(","))
    return intra, inter


def _precision(impl: str) -> str:
    return "bf16" if impl.endswith("bf16") else "fp32"


def product_time(hidden: int, repeats: int, batch: int = B) -> float:
    """Seconds for one recurrent product ``[batch, H] x [H, 4H]``: fastest of ``repeats`` loops of
    800, all cores inside each product."""
    tf = import_tensorflow()

    tf.config.threading.set_intra_op_parallelism_threads(usable_cores())
    tf.config.threading.set_inter_op_parallelism_threads(1)

    steps = 800
    h, W = tf.random.normal([batch, hidden]), tf.random.normal([hidden, 4 * hidden]) * 0.01

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
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--hidden", type=int, nargs="+", default=[1024, 256])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--steps", type=int, default=800)
    parser.add_argument("--batch", type=positive_int, default=B,
                        help=f"sequences per sweep (default {B}, model A's batch)")
    parser.add_argument("--impl", nargs="+", choices=IMPLEMENTATIONS,
                        default=list(IMPLEMENTATIONS))
    parser.add_argument("--threads", help="thread plan 'intra,inter' for rnn_seg and the peers "
                                          "(default: rnn_seg its own plan, rnn_seg.threads; the "
                                          "peers every core, intra = inter = cores)")
    parser.add_argument("--isa", choices=ISA_LIMITS, default="native",
                        help="instruction sets for ours and the peers: native (default), or avx2: "
                             "the fused loops built for haswell and oneDNN limited to AVX2")
    parser.add_argument("--worker", nargs=2, metavar=("IMPL", "HIDDEN"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        impl, hidden = args.worker[0], int(args.worker[1])
        result = (product_time(hidden, args.repeats, args.batch) if impl == "product"
                  else worker(impl, hidden, args.steps, args.repeats, args.threads, args.batch))
        print(json.dumps(result))
        return
    os.environ.update(ISA_LIMITS[args.isa])
    import_tensorflow()     # before rnn_seg imports it: its start-up lines filtered out
    impls = _runnable(args.impl)
    print(f"training sweep: bidirectional LSTM, B={args.batch}, F={F}, T={args.steps}, "
          f"{args.repeats} timed repeats after one warm-up; {usable_cores()} usable cores")
    print(_processor(args.isa))
    if any(impl.split("_")[0] in PEERS for impl in impls):
        print("peers (torch, keras): LSTM cells without peepholes, one input dropout mask for "
              "both directions (bench/lstm_peers.py)")
    for hidden in args.hidden:
        _sweep_size(hidden, impls, args)


def _runnable(impls: list[str]) -> list[str]:
    """``impls`` less those this machine cannot run, with one line per reason naming them."""
    native = _native_bf16()
    reasons = {impl: _skip_reason(impl, native) for impl in impls}
    for reason in dict.fromkeys(r for r in reasons.values() if r):
        print(f"{reason}: {', '.join(i for i, r in reasons.items() if r == reason)} skipped")
    return [impl for impl, reason in reasons.items() if not reason]


def _skip_reason(impl: str, native_bf16: bool) -> str | None:
    """Why ``impl`` cannot run here (its peer not installed, no native bfloat16), or None."""
    package = impl.split("_")[0]
    if package in PEERS and importlib.util.find_spec(package) is None:
        return f"{package} not installed ({PEERS[package]})"
    if impl.endswith("bf16") and not native_bf16:
        return "no native bfloat16 on this CPU"
    return None


def _sweep_size(hidden: int, impls: list[str], args: argparse.Namespace) -> None:
    """Time the floor and every implementation at ``hidden`` units; print them and the ratios."""
    product = _run_worker("product", hidden, None, args)
    floor = product * args.steps * 2 * 3        # 2 directions; 1 product forward, 2 backward
    print(f"H={hidden:5d} recurrent product {product * 1e6:.0f} us -> floor "
          f"{args.steps} x 2 x 3 x product = {floor:.3f} s per sweep")
    medians = {}
    for impl in impls:
        res = _run_worker(impl, hidden, _plan(impl, args.threads), args)
        if "skipped" in res:
            print(f"H={hidden:5d} {impl:12s} skipped: {res['skipped']}")
            continue
        medians[impl] = statistics.median(res["times"])
        print(f"H={hidden:5d} {impl:12s} median {medians[impl]:7.3f} s  "
              f"(min {min(res['times']):.3f}, max {max(res['times']):.3f})  "
              f"{medians[impl] / floor:.2f}x floor  peak RSS {res['peak_mb']:6.0f} MB  "
              f"threads (intra, inter) {res['threads']}"
              + (f"  product: {res['product']}" if "product" in res else ""))
    for label, slower, faster in RATIOS:
        if {slower, faster} <= set(medians):
            print(f"H={hidden:5d} speed-up {label}: {medians[slower] / medians[faster]:.2f}x")
    _auto_line(hidden, medians)


def _processor(isa: str) -> str:
    """One line: the processor, its widest float vectors, and any ``--isa`` limit."""
    from rnn_seg.config import cpu_flags
    from rnn_seg.runs.provenance import cpu_model

    flags = cpu_flags()
    width = ("512-bit (AVX-512)" if "avx512f" in flags else
             "256-bit (AVX2)" if "avx2" in flags else "128-bit or less (no AVX2)")
    limit = "" if isa == "native" else (
        f"; limited to {isa.upper()}: " + ", ".join(f"{k}={v}" for k, v in ISA_LIMITS[isa].items()))
    return f"processor: {cpu_model()}, {width} vectors{' + bf16' if 'avx512_bf16' in flags else ''}{limit}"


def _auto_line(hidden: int, medians: dict[str, float]) -> None:
    """Which of our loops ``auto`` runs here, beside the fastest of ours measured (float32)."""
    ours = {OUR_LOOPS[impl]: medians[impl] for impl in OUR_LOOPS if impl in medians}
    if len(ours) < 2:
        return
    from rnn_seg.lstm import runnable
    chosen = runnable("auto", "fp32")
    fastest = min(ours, key=ours.get)
    if chosen not in ours:
        print(f"H={hidden:5d} auto runs the {chosen} loops (not measured here)")
        return
    print(f"H={hidden:5d} auto runs the {chosen} loops: {ours[chosen]:.3f} s; the fastest of ours "
          f"measured, {fastest}: {ours[fastest]:.3f} s ({ours[chosen] / ours[fastest] - 1:+.0%})")


def _plan(impl: str, threads: str | None) -> str | None:
    """The thread plan ``impl``'s worker gets: ``--threads`` for ``rnn_seg`` (None: its own) and
    the peers (None: every core), never for the per-gate reference (TensorFlow's default)."""
    if impl == "per_gate":
        return None
    cores = usable_cores()
    return threads or (None if impl.startswith("rnn_seg") else f"{cores},{cores}")


def _native_bf16() -> bool:
    from rnn_seg.lstm import native_bf16
    return native_bf16()


def _run_worker(impl: str, hidden: int, plan: str | None, args: argparse.Namespace) -> dict:
    command = [sys.executable, __file__, "--worker", impl, str(hidden), "--steps",
               str(args.steps), "--repeats", str(args.repeats), "--batch", str(args.batch)]
    if plan:
        command += ["--threads", plan]
    out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


if __name__ == "__main__":
    main()
