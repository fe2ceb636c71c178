"""bench/lstm_sweep.py and bench/sweep_phases.py: ``--batch`` sets the sequences per sweep."""
import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"
_spec = importlib.util.spec_from_file_location("lstm_sweep", BENCH / "lstm_sweep.py")
lstm_sweep = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(lstm_sweep)


@pytest.mark.parametrize("batch", [1, 6])
def test_batch_has_the_asked_sequences(batch):
    x, r, y = lstm_sweep._batch(9, batch)
    assert x.shape == (batch, 9, lstm_sweep.F) and x.dtype == np.float32
    assert r.shape == (batch, 9) and r[:, 0].all() and not r[:, 1:].any()
    assert y.shape == (batch, 9, lstm_sweep.K) and (y.sum(-1) == 1).all()


def test_default_batch_is_model_a_s():
    assert lstm_sweep._batch(4)[0].shape[0] == lstm_sweep.B == 5


@pytest.mark.parametrize("script", ["lstm_sweep.py", "sweep_phases.py"])
@pytest.mark.parametrize("value", ["0", "-2", "six"])
def test_a_batch_that_is_not_a_positive_whole_number_is_refused(script, value):
    done = subprocess.run([sys.executable, str(BENCH / script), "--batch", value],
                          capture_output=True, text=True)
    assert done.returncode == 2
    assert "--batch" in done.stderr and "Traceback" not in done.stderr
