"""How a training process spreads over its cores (TensorFlow's two thread pools).

A bidirectional layer runs two independent recurrent loops, one per direction, each a sequence of
small products ``[5, H] x [H, 4H]``. Two plans (``bench/thread_plan.py``, docs/PERFORMANCE.md):

* one core per direction, ``(intra 1, inter cores)``: the two loops run side by side. Fastest
  whenever both directions' recurrent weights stay in the last-level cache together: on the
  2-core Xeon with a 480 MB L3 it beat the other plans at H=256 and H=1024, float32 and bfloat16,
  quiet and next to a competing load (1.92 s against 2.52 s per paper-size sweep);
* every core inside each product, ``(cores, 1)``: one op at a time. Fastest when the two
  directions' weights would evict each other: measured on a 2-core AMD EPYC with a 32 MB L3 at
  H=1024 in float32 (2 x 16 MB of weights).

``thread_plan`` picks by that criterion: one core per direction when both directions' weights
fill at most half of the last-level cache. A forward-only (online) model has one loop: every core
goes inside its products.
"""
from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

from jigsaws_tools.cores import usable_cores

#: Last-level cache assumed when the machine does not report it (the EPYC above).
DEFAULT_CACHE_BYTES = 32 * 2**20
_BYTES = {"fp32": 4, "bf16": 2}


def thread_plan(cores: int, hidden: int, precision: str = "fp32",
                cache_bytes: int | None = None, bidirectional: bool = True) -> tuple[int, int]:
    """``(intra_op, inter_op)`` thread counts for an LSTM layer.

    Args:
        cores: cores this process may use (>= 1).
        hidden: LSTM width H.
        precision: ``"fp32"`` or ``"bf16"``, the products' operand type (weight bytes).
        cache_bytes: last-level cache size; default: this machine's (``last_level_cache``).
        bidirectional: two directions' loops (else one, forward only).
    """
    cores = max(1, cores)
    if not bidirectional:
        return cores, 1
    cache = last_level_cache() if cache_bytes is None else cache_bytes
    weights = 2 * hidden * 4 * hidden * _BYTES[precision]             # both directions' W_h
    return (1, cores) if weights <= cache // 2 else (cores, 1)


@lru_cache(maxsize=1)
def last_level_cache() -> int:
    """Bytes of this CPU's largest cache level (Linux sysfs), else ``DEFAULT_CACHE_BYTES``."""
    sizes = []
    for index in Path("/sys/devices/system/cpu/cpu0/cache").glob("index*"):
        try:
            text = (index / "size").read_text().strip()
            number, unit = re.fullmatch(r"(\d+)([KMG]?)", text).groups()
        except (OSError, AttributeError):
            continue
        sizes.append(int(number) * {"": 1, "K": 2**10, "M": 2**20, "G": 2**30}[unit])
    return max(sizes, default=DEFAULT_CACHE_BYTES)


def configure_threads(cores: int, hidden: int, precision: str = "fp32",
                      bidirectional: bool = True) -> tuple[int, int]:
    """Apply ``thread_plan`` to TensorFlow's thread pools and return ``(intra_op, inter_op)``.

    Args:
        cores: cores this process may use: 0 = all of them (``usable_cores``), at most as many.
        hidden: LSTM width H.
        precision: ``"fp32"`` or ``"bf16"``, the products' operand type (weight bytes).
        bidirectional: two directions' loops (else one, forward only).

    TensorFlow fixes its pools when the first op runs; called later in the same process (a
    notebook, a test) this keeps the pools as they are and returns their sizes (0 = default).

    Raises:
        ValueError: ``cores`` negative or above those this process may use (a pool of
            100 000 threads would take the memory before it hangs).
    """
    import tensorflow as tf

    available = usable_cores()
    if not 0 <= cores <= available:
        raise ValueError(f"cores: expected 0 (all) up to the {available} this process may use, "
                         f"got {cores}")
    intra, inter = thread_plan(cores or available, hidden, precision,
                               bidirectional=bidirectional)
    try:
        tf.config.threading.set_intra_op_parallelism_threads(intra)
        tf.config.threading.set_inter_op_parallelism_threads(inter)
    except RuntimeError:
        return (tf.config.threading.get_intra_op_parallelism_threads(),
                tf.config.threading.get_inter_op_parallelism_threads())
    return intra, inter
