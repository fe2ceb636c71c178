"""How a training process spreads over its cores (TensorFlow's two thread pools).

The recurrent loops are sequences of small operations. Measured on 2 cores (docs/PERFORMANCE.md):

* large layers (the paper's H=1024): each recurrent product is big enough to share between cores,
  and two directions' weights (2 x 16 MB) running side by side evict each other from the cache,
  so one op at a time with every core inside it is fastest;
* small layers (H=256 and below): one product cannot use two cores well, so the two directions'
  independent loops run side by side, one core each.
"""
from __future__ import annotations

import os

SHARED_PRODUCT_FROM = 512      # hidden size from which products share the cores


def thread_plan(cores: int, hidden: int) -> tuple[int, int]:
    """``(intra_op, inter_op)`` thread counts for ``cores`` cores and LSTM width ``hidden``."""
    cores = max(1, cores)
    return (cores, 1) if hidden >= SHARED_PRODUCT_FROM else (1, cores)


def configure_threads(cores: int, hidden: int) -> tuple[int, int]:
    """Apply ``thread_plan`` (``cores`` 0 = all of this machine's) and return it.

    TensorFlow fixes its pools when the first op runs; called later in the same process (a
    notebook, a test) this keeps the pools as they are and returns their sizes (0 = default).
    """
    import tensorflow as tf

    intra, inter = thread_plan(cores or os.cpu_count() or 1, hidden)
    try:
        tf.config.threading.set_intra_op_parallelism_threads(intra)
        tf.config.threading.set_inter_op_parallelism_threads(inter)
    except RuntimeError:
        return (tf.config.threading.get_intra_op_parallelism_threads(),
                tf.config.threading.get_inter_op_parallelism_threads())
    return intra, inter
