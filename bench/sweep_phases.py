"""Where a training sweep's time goes: ``rnn_seg``'s phases beside PyTorch's, same invocation.

Workload as ``lstm_sweep.py`` (model A's sweep: B=5 sequences of T steps, 14 inputs, one
bidirectional layer of H units, float32; ``--batch`` sets B). Each side runs in its own process
with the thread plan it trains with (``rnn_seg``: ``rnn_seg.threads``; PyTorch: every core in
each op).

``rnn_seg`` phases, each a ``tf.function`` over random inputs of the right shapes:

- ``forward loops``: both directions' recurrent loops (``[B, H] x [H, 4H]`` a step each),
  ``together`` (independent, as the encoder runs them: TensorFlow interleaves their steps) and
  ``in turn`` (the reverse loop starts when the forward loop has ended);
- ``backward loops``: both directions' backward loops (``[B, 4H] x [4H, H]`` a step), with the
  per-step factors computed before them, together and in turn;
- ``weight gradients``: both directions' ``dW_h = h_prev^T dz`` (``[H, T B] x [T B, 4H]``), as
  the loops sum it (``rnn_seg.lstm._weight_gradient``);
- ``forward products alone``: the 2 T recurrent products of the forward loops with a tanh
  between them and nothing else (a step's input is the tanh of the previous product's first H
  columns): the products' share of ``forward loops``;
- ``sweep``: the whole training sweep (``lstm_sweep.py``'s).

``rnn_seg_fused`` runs them with the fused C++ loops (``--loops fused``, ``rnn_seg.kernels``;
skipped where they cannot be built). ``rnn_seg_eigen`` runs the same phases with TensorFlow's
oneDNN rewrites off (``TF_ENABLE_ONEDNN_OPTS=0``): its ``MatMul`` is then Eigen's contraction.

PyTorch phases: ``forward`` (the bidirectional ``nn.LSTM`` alone, no autograd), ``forward +
backward`` (the LSTM and the gradient of a sum of its outputs), ``forward products alone``
(``torch.mm``, as ``rnn_seg``'s) and its ``sweep``.

Run on a quiet machine; medians of ``--repeats`` after a warm-up::

    python bench/sweep_phases.py --hidden 1024 --steps 800 --repeats 5
    python bench/sweep_phases.py --hidden 256 --batch 6 --peers rnn_seg_fused   # one side
"""
from __future__ import annotations

import argparse
import functools
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from jigsaws_tools.cli.arg_types import positive_int  # noqa: E402 (on the path above)
from jigsaws_tools.cli.common import import_tensorflow  # noqa: E402
from jigsaws_tools.cores import usable_cores  # noqa: E402
from lstm_sweep import B, F  # noqa: E402 (model A's sweep, as lstm_sweep.py times it)


def _median_time(call: Callable[[], object], repeats: int) -> float:
    """Median seconds of ``repeats`` calls after one warm-up call."""
    call()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def rnn_seg_phases(hidden: int, steps: int, repeats: int, batch: int = B, loops: str = "graph"
                   ) -> dict[str, float]:
    """Seconds per phase of ``rnn_seg``'s float32 sweep of ``batch`` sequences with ``loops``
    (module docstring)."""
    tf = import_tensorflow()

    from lstm_sweep import _batch, _step_function
    from rnn_seg.lstm import _LOOP_FUNCTIONS, _shift, _weight_gradient
    from rnn_seg.threads import configure_threads

    _forward_loop, _backward_loop = _LOOP_FUNCTIONS[loops]

    threads = configure_threads(0, hidden, "fp32")
    rng = tf.random.Generator.from_seed(0)
    directions = [
        {"x_proj": rng.normal([steps, batch, 4 * hidden]), "keep": tf.ones([steps, batch, 1]),
         "W": rng.uniform([hidden, 4 * hidden], -0.1, 0.1),
         "peep": rng.uniform([3, hidden], -0.1, 0.1), "dh": rng.normal([steps, batch, hidden])}
        for _ in range(2)]

    def forward(d):
        return _forward_loop(d["x_proj"], d["keep"], d["W"], d["peep"], steps)

    def backward(d, state):
        c_prev = _shift(state[1])
        return _backward_loop(d["dh"], d["keep"], state, c_prev, d["W"], d["peep"], steps)

    def in_turn(run, args_of):
        """``run`` for both directions, the reverse one after the forward one has ended."""
        first = run(*args_of(0))
        with tf.control_dependencies(tf.nest.flatten(first)):
            return first, run(*args_of(1))

    states = [forward(d) for d in directions]
    h_prev = [tf.reshape(_shift(s[0]), [-1, hidden]) for s in states]
    dz = [tf.reshape(backward(d, s), [-1, 4 * hidden]) for d, s in zip(directions, states)]
    calls = {
        "forward loops, together": tf.function(lambda: [forward(d) for d in directions]),
        "forward loops, in turn": tf.function(
            lambda: in_turn(forward, lambda k: (directions[k],))),
        "backward loops, together": tf.function(
            lambda: [backward(d, s) for d, s in zip(directions, states)]),
        "backward loops, in turn": tf.function(
            lambda: in_turn(backward, lambda k: (directions[k], states[k]))),
        "weight gradients": tf.function(
            lambda: [_weight_gradient(h, g, tf.float32, loops) for h, g in zip(h_prev, dz)]),
        "forward products alone": tf.function(lambda: [
            tf.while_loop(lambda t, h: t < steps,
                          lambda t, h: (t + 1, tf.tanh(tf.matmul(h, d["W"])[:, :hidden])),
                          (0, d["dh"][0]), parallel_iterations=1)[1] for d in directions]),
    }
    times = {name: _median_time(lambda c=call: tf.nest.map_structure(
        lambda t: t.numpy(), c()), repeats) for name, call in calls.items()}
    step = _step_function("rnn_seg" if loops == "graph" else f"rnn_seg_{loops}", hidden)
    x, r, y = (tf.constant(v) for v in _batch(steps, batch))
    times["sweep"] = _median_time(lambda: step(x, r, y).numpy(), repeats)
    return {"threads": list(threads), **times}


def torch_phases(hidden: int, steps: int, repeats: int, batch: int = B) -> dict[str, float]:
    """Seconds per phase of PyTorch's float32 sweep of ``batch`` sequences (module docstring)."""
    import torch

    from lstm_peers import torch_step
    from lstm_sweep import _batch

    cores = usable_cores()
    x, _, y = _batch(steps, batch)
    sweep = torch_step(hidden, "fp32", x, y, (cores, cores))   # sets the threads first
    lstm = torch.nn.LSTM(F, hidden, batch_first=True, bidirectional=True)
    inputs = torch.from_numpy(x)

    def forward():
        with torch.no_grad():
            return lstm(inputs)[0]

    def forward_backward():
        lstm.zero_grad()
        lstm(inputs)[0].sum().backward()

    weights = [torch.rand(hidden, 4 * hidden) * 0.2 - 0.1 for _ in range(2)]

    def products():
        for W in weights:
            h = inputs.new_ones(batch, hidden)
            for _ in range(steps):
                h = torch.tanh(torch.mm(h, W)[:, :hidden])

    return {"threads": [cores, cores], "forward": _median_time(forward, repeats),
            "forward + backward": _median_time(forward_backward, repeats),
            "forward products alone": _median_time(products, repeats),
            "sweep": _median_time(sweep, repeats)}


#: name -> (phases, environment it runs in). ``rnn_seg_eigen``: TensorFlow with its oneDNN
#: rewrites off (``TF_ENABLE_ONEDNN_OPTS=0``), so ``MatMul`` runs Eigen's contraction.
PEERS = {"rnn_seg": (rnn_seg_phases, {}),
         "rnn_seg_fused": (functools.partial(rnn_seg_phases, loops="fused"), {}),
         "rnn_seg_eigen": (rnn_seg_phases, {"TF_ENABLE_ONEDNN_OPTS": "0"}),
         "torch": (torch_phases, {})}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--hidden", type=int, default=1024)
    parser.add_argument("--steps", type=int, default=800)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--batch", type=positive_int, default=B,
                        help=f"sequences per sweep (default {B}, model A's batch)")
    parser.add_argument("--peers", nargs="+", choices=PEERS, default=list(PEERS),
                        help="the sides to time (default: all)")
    parser.add_argument("--worker", choices=PEERS, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        phases, _ = PEERS[args.worker]
        print(json.dumps(phases(args.hidden, args.steps, args.repeats, args.batch)))
        return
    import_tensorflow()     # before rnn_seg imports it: its start-up lines filtered out
    print(f"H={args.hidden}, B={args.batch}, T={args.steps}, float32, median of {args.repeats}")
    for peer in args.peers:
        environment = PEERS[peer][1]
        command = [sys.executable, __file__, "--worker", peer, "--hidden", str(args.hidden),
                   "--steps", str(args.steps), "--repeats", str(args.repeats),
                   "--batch", str(args.batch)]
        done = subprocess.run(command, capture_output=True, text=True,
                              env={**os.environ, **environment})
        if done.returncode:
            last = (done.stderr.strip().splitlines() or ["no output"])[-1]
            print(f"{peer}: skipped ({last})")
            continue
        result = json.loads(done.stdout.strip().splitlines()[-1])
        print(f"{peer} (threads intra, inter {tuple(result.pop('threads'))})")
        for phase, seconds in result.items():
            print(f"  {phase:<26} {seconds:8.3f} s")


if __name__ == "__main__":
    main()
