"""``python -m rnn_seg.kernels``: build the fused LSTM loops now (``build.main``)."""
import sys

from .build import main

sys.exit(main())
