"""Records say what ran: every session of a run records the loops and precision that trained its
sweeps and why (``rnn_seg.runs.segments``), a run resumed on other loops reads as mixed, and the
execution comparison refuses it as one path's run."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from baseline.builder import train_baseline
from baseline.config import RunConfig
from jigsaws_tools.dataset import DataConfig
from multitask.evidence.studies.execution import _path
from multitask.models.run_record import read_run_record
from rnn_seg import lstm
from rnn_seg.lstm import EncoderConfig
from rnn_seg.optim import OptimConfig
from rnn_seg.trainer import Trainer, TrainConfig
from tests.fused_loops import needs_fused


def _config(data_dir, loops: str) -> RunConfig:
    return RunConfig(data=DataConfig(str(data_dir)), test_user="B",
                     encoder=EncoderConfig(hidden=8, loops=loops),
                     optim=OptimConfig(total=4, decay_start=3, decay_every=100),
                     train=TrainConfig(seed=0, eval_points=(4,), plots="none"))


class _Interrupt(Exception):
    pass


def _interrupted(config: RunConfig, run: Path, monkeypatch, epoch: int = 2) -> None:
    """Train into ``run`` and stop after ``epoch``'s checkpoint, as a killed process would."""
    original = Trainer.after_sweep

    def stop(self, sweep, *args):
        original(self, sweep, *args)
        if sweep + 1 == epoch * self.sweeps_per_epoch:
            raise _Interrupt

    with monkeypatch.context() as patch:
        patch.setattr(Trainer, "after_sweep", stop)
        with pytest.raises(_Interrupt):
            train_baseline(config, run, log=lambda m: None)


def _segments(run: Path) -> list[dict]:
    return json.loads((run / "finished.json").read_text())["segments"]


@pytest.mark.slow
def test_a_run_trained_in_one_session_records_one_segment(synth_dir, tmp_path):
    run = tmp_path / "run"
    train_baseline(_config(synth_dir, "graph"), run, log=lambda m: None)
    (segment,) = _segments(run)
    total = json.loads((run / "finished.json").read_text())["sweeps"]
    assert (segment["from_sweep"], segment["to_sweep"]) == (0, total)
    assert (segment["loops"], segment["precision"], segment["why"]) == ("graph", "fp32",
                                                                        "asked for")
    assert read_run_record(run).loops() == "graph"


@pytest.mark.parametrize("first, then", [("xla", "graph"), ("graph", "xla")])
@pytest.mark.slow
def test_a_run_resumed_on_other_loops_records_both_and_reads_as_mixed(synth_dir, tmp_path,
                                                                      monkeypatch, first, then):
    """Today config.json kept the loops the run started on, and finished.json none: a run begun
    on one path and finished on another read as the first."""
    run = tmp_path / "run"
    _interrupted(_config(synth_dir, first), run, monkeypatch)
    train_baseline(_config(synth_dir, then), run, log=lambda m: None)
    first_part, second_part = _segments(run)
    assert first_part["loops"] == first and second_part["loops"] == then
    assert first_part["to_sweep"] == second_part["from_sweep"] > 0
    assert read_run_record(run).loops() == f"mixed ({', '.join(sorted([first, then]))})"
    with pytest.raises(ValueError, match="more than one execution path"):
        _path(tmp_path, {run: read_run_record(run)})


@needs_fused
@pytest.mark.slow
def test_a_run_whose_fused_loops_vanish_records_the_fallback_and_why(synth_dir, tmp_path,
                                                                     monkeypatch):
    run = tmp_path / "run"
    _interrupted(_config(synth_dir, "auto"), run, monkeypatch)
    monkeypatch.setattr(lstm, "_fused_unavailable", lambda precision: "no compiler here")
    train_baseline(_config(synth_dir, "auto"), run, log=lambda m: None)
    first_part, second_part = _segments(run)
    assert first_part["loops"] == "fused" and first_part["why"].startswith("auto: ")
    assert second_part["loops"] == "graph"
    assert second_part["why"] == "fused loops unavailable: no compiler here"
    assert read_run_record(run).loops() == "mixed (fused, graph)"


@needs_fused
@pytest.mark.slow
def test_a_resumed_auto_run_keeps_the_loops_it_started_on_and_says_why(synth_dir, tmp_path,
                                                                       monkeypatch):
    """Begun where the fused loops could not be built, an ``auto`` run resumed where they can
    stays on the graph loops it started on (one path per run), and says so."""
    run = tmp_path / "run"
    with monkeypatch.context() as patch:
        patch.setattr(lstm, "_fused_unavailable", lambda precision: "no compiler then")
        _interrupted(_config(synth_dir, "auto"), run, monkeypatch)
    train_baseline(_config(synth_dir, "auto"), run, log=lambda m: None)
    first_part, second_part = _segments(run)
    assert first_part["why"] == "fused loops unavailable: no compiler then"
    assert second_part["why"] == "auto: the loops the run started on (graph)"
    assert read_run_record(run).loops() == "graph"


@needs_fused
def test_an_auto_run_says_why_it_runs_the_fused_loops(synth_dir, tmp_path, monkeypatch):
    run = tmp_path / "run"
    _interrupted(_config(synth_dir, "auto"), run, monkeypatch)
    train_baseline(_config(synth_dir, "auto"), run, log=lambda m: None)
    for segment in _segments(run):
        assert segment["loops"] == "fused"
        assert segment["why"].startswith("auto: the fused loops build and load here (")
    assert read_run_record(run).loops() == "fused"


@pytest.mark.slow
def test_a_checkpoint_older_than_segment_records_counts_from_the_provenance(synth_dir, tmp_path,
                                                                            monkeypatch):
    run = tmp_path / "run"
    _interrupted(_config(synth_dir, "xla"), run, monkeypatch)
    for clock in (run / "checkpoints").glob("ckpt-*.clock.json"):
        saved = json.loads(clock.read_text())
        saved.pop("segments")
        clock.write_text(json.dumps(saved))                  # as an older version saved it
    train_baseline(_config(synth_dir, "graph"), run, log=lambda m: None)
    earlier, later = _segments(run)
    assert earlier["loops"] == "xla" and "predates segment records" in earlier["why"]
    assert later["loops"] == "graph"
