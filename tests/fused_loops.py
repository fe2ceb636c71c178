"""The loop implementations tests run on: ``fused`` skipped with the reason it cannot run here."""
import pytest

from rnn_seg.kernels.build import unavailable

#: Why the fused loops cannot run float32 / bfloat16 here (None: they can); asking builds them.
FUSED_UNAVAILABLE = unavailable("fp32")
FUSED_BF16_UNAVAILABLE = FUSED_UNAVAILABLE or unavailable("bf16")
needs_fused = pytest.mark.skipif(FUSED_UNAVAILABLE is not None,
                                 reason=f"fused loops unavailable: {FUSED_UNAVAILABLE}")
needs_fused_bf16 = pytest.mark.skipif(
    FUSED_BF16_UNAVAILABLE is not None,
    reason=f"fused bfloat16 loops unavailable: {FUSED_BF16_UNAVAILABLE}")
#: Every implementation of the loops, for ``pytest.mark.parametrize("loops", LOOPS)``.
LOOPS = ["graph", "xla", pytest.param("fused", marks=needs_fused)]
