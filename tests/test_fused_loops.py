"""The fused C++ loops (``loops = "fused"``, and ``"auto"``, the default, where they build): a run
trains as on the graph loops; where they cannot be built, the graph loops run after one line saying
why, and a failed build leaves nothing."""
import functools
import json
import os
import shutil
import sys
from dataclasses import replace

import pytest

from baseline.builder import train_baseline
from baseline.config import RunConfig
from jigsaws_tools.dataset import DataConfig
from rnn_seg import lstm
from rnn_seg.kernels import build
from rnn_seg.lstm import EncoderConfig, RecurrentEncoder
from rnn_seg.optim import OptimConfig
from rnn_seg.trainer import TrainConfig, Trainer
from tests.fused_loops import needs_fused

import tensorflow as tf


def _run(data_dir, out, loops, ran=None):
    config = RunConfig(data=DataConfig(str(data_dir)), test_user="B",
                       encoder=EncoderConfig(hidden=32, loops=loops),
                       optim=OptimConfig(total=6, decay_start=4, decay_every=100),
                       train=TrainConfig(seed=0, eval_points=()))
    train_baseline(config, out, log=lambda m: None)
    recorded = json.loads((out / "config.json").read_text())
    assert recorded["provenance"]["loops"] == (ran or loops)      # those the process ran
    return (json.loads((out / "metrics.json").read_text())["mean"]["gesture"],
            recorded["run"]["encoder"]["loops"])


@needs_fused
@pytest.mark.slow
def test_a_seeded_run_on_the_fused_loops_scores_as_on_the_graph_loops(synth_dir, tmp_path):
    """Model A, 6 epochs on the synthetic release, same seed: the two paths differ only in
    float32 rounding, so the held-out scores agree closely; the run's config names its loops."""
    graph, graph_loops = _run(synth_dir, tmp_path / "graph", "graph")
    fused, fused_loops = _run(synth_dir, tmp_path / "fused", "fused")
    assert (graph_loops, fused_loops) == ("graph", "fused")
    for metric in ("accuracy", "edit", "f1@10"):
        assert fused[metric] == pytest.approx(graph[metric], abs=1.0), metric


@pytest.mark.skipif(shutil.which(os.environ.get("CXX") or "g++") is None,
                    reason="no C++ compiler: the fused loops' tests are skipped")
def test_the_fused_loops_build_wherever_a_compiler_is():
    """With a compiler present, a failing build is a bug, not a reason to skip (CI checks it)."""
    assert build.unavailable("fp32") is None
    if lstm.native_bf16() and "avx512_bf16" in lstm.cpu_flags():
        assert build.unavailable("bf16") is None


@needs_fused
@pytest.mark.skipif(lstm._fused_slower() is not None, reason="a generic fused library: auto "
                    "runs the graph loops (test_auto_passes_over_a_generic_fused_library)")
@pytest.mark.slow
def test_the_default_loops_run_the_fused_ones_where_they_build(synth_dir, tmp_path):
    """``auto``, the default, is the fused loops here: the run computes what a ``fused`` run
    does, records ``auto`` as configured and ``fused`` as what ran."""
    assert EncoderConfig().loops == "auto"
    auto, configured = _run(synth_dir, tmp_path / "auto", "auto", ran="fused")
    fused, _ = _run(synth_dir, tmp_path / "fused", "fused")
    assert configured == "auto" and auto == fused


@pytest.mark.parametrize("loops", ["fused", "auto"])
def test_unbuildable_fused_loops_fall_back_to_the_graph_loops_after_one_line(monkeypatch, capsys,
                                                                              loops):
    reason = f"no C++ compiler: 'g++' not found (a test's reason, loops {loops})"
    monkeypatch.setattr(lstm, "_fused_unavailable", lambda precision: reason)
    config = EncoderConfig(hidden=8, loops=loops)
    encoders = [RecurrentEncoder(3, config, tf.random.Generator.from_seed(0)) for _ in range(2)]
    assert [e.config for e in encoders] == [replace(config, loops="graph")] * 2
    lines = capsys.readouterr().err.splitlines()
    assert lines == [f"fused LSTM loops unavailable ({reason}): running the graph loops"]


@pytest.mark.parametrize("product, auto", [("AVX2", "fused"), ("AVX-512", "fused"),
                                           ("generic (compiler vectors, no AVX2)", "graph"),
                                           (None, "graph")])
def test_auto_passes_over_a_generic_fused_library(monkeypatch, capsys, product, auto):
    """A library built without AVX2 (``RNN_SEG_MARCH=x86-64``, an old processor) runs slower than
    the graph loops: ``auto`` takes the graph loops and says why, in one line and in the run's
    record; ``fused`` asked for by name still runs."""
    record = {} if product is None else {"product": product}
    monkeypatch.setattr(lstm, "_fused_unavailable", lambda precision: None)
    monkeypatch.setattr(lstm.fused_build, "built_record", lambda: record)
    monkeypatch.setattr(lstm.fused_build, "describe", lambda: f"{product} product (a test's)")
    lstm._fused_slower.cache_clear()
    monkeypatch.setattr(lstm, "_say_once", functools.lru_cache(maxsize=None)(
        lambda line: print(line, file=sys.stderr)))
    try:
        assert lstm.runnable("auto", "fp32") == auto
        assert lstm.runnable("fused", "fp32") == "fused"
        said = capsys.readouterr().err.splitlines()
        why = lstm.loops_reason("auto", auto, "fp32")
    finally:
        lstm._fused_slower.cache_clear()
    if auto == "graph":
        assert len(said) == 1 and said[0].startswith("auto: the fused loops here run the ")
        assert "slower than the graph loops" in why and "Which loops auto runs" in why
    else:
        assert said == [] and why.startswith("auto: the fused loops build and load here")


@pytest.mark.parametrize("compiler, message", [("no-such-compiler-49", r"no C\+\+ compiler"),
                                               ("false", "failed: false exited with status 1")])
def test_a_failed_build_says_why_and_leaves_nothing(tmp_path, monkeypatch, compiler, message):
    monkeypatch.setenv("CXX", compiler)
    with pytest.raises(build.KernelUnavailable, match=message):
        build.build(tmp_path / "kernels" / "lstm_loops-x.so")
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []


@pytest.mark.slow
def test_a_cpu_with_avx512_fp16_builds_the_loops_without_it(tmp_path, monkeypatch):
    """``-march=native`` on a CPU with AVX512-FP16 (Sapphire Rapids and later) turns on Eigen's
    half-precision code, which TensorFlow 2.21's headers do not compile under with g++ 12; the
    loops never use it, so the build switches it off. Any x86 machine plays such a CPU with a
    compiler that adds ``-mavx512fp16`` to every command."""
    compiler = shutil.which(os.environ.get("CXX") or "g++")
    if compiler is None:
        pytest.skip("no C++ compiler")
    fp16 = tmp_path / "cxx-with-avx512fp16"
    fp16.write_text(f'#!/bin/sh\nexec "{compiler}" -mavx512fp16 "$@"\n')
    fp16.chmod(0o755)
    if "__AVX512FP16__" not in build.native_macros(str(fp16)):
        pytest.skip(f"{compiler} cannot target AVX512-FP16")
    monkeypatch.setenv("CXX", str(fp16))
    library = tmp_path / "kernels" / "lstm_loops-fp16.so"
    build.build(library)
    assert library.is_file()


@pytest.mark.slow
@pytest.mark.parametrize("target", ["x86-64", "haswell"])
def test_the_loops_build_for_a_processor_without_avx_and_for_avx2(tmp_path, monkeypatch, target):
    """The generic build (``RNN_SEG_MARCH=x86-64``: no AVX, a vector of 8 floats spans two
    registers) and the AVX2 one compile on any x86 machine: register hints that only AVX
    registers can meet once broke the first."""
    if shutil.which(os.environ.get("CXX") or "g++") is None:
        pytest.skip("no C++ compiler")
    monkeypatch.setenv("RNN_SEG_MARCH", target)
    library = tmp_path / "kernels" / f"lstm_loops-{target}.so"
    build.build(library)
    assert library.is_file()


def test_the_cache_is_kept_per_tensorflow_version(tmp_path, monkeypatch):
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(tmp_path))
    path = build.library_path()
    assert path.parent == tmp_path / "kernels" / f"tf-{tf.__version__}"


def test_a_grid_refuses_to_stack_fused_loops(tmp_path, capsys):
    from multitask.grid.cli import main as grid_main

    code = grid_main(["--preset", "quick", "--data-dir", "synthetic", "--out", str(tmp_path),
                      "--loops", "fused", "--stack", "2"])
    assert code == 2 and "--stack 1 with loops fused" in capsys.readouterr().err


def test_loops_stay_as_given_when_not_fused_or_auto(monkeypatch):
    """Asking whether the kernels build is for ``fused`` and ``auto`` only."""
    monkeypatch.setattr(lstm, "_fused_unavailable", lambda precision: pytest.fail("asked"))
    assert [lstm.runnable(loops, "fp32") for loops in ("graph", "xla")] == ["graph", "xla"]


class _Interrupt(Exception):
    pass


@pytest.mark.parametrize("asked, ran", [("auto", "graph"), ("graph", "graph"),
                                        pytest.param("fused", "fused", marks=needs_fused)])
@pytest.mark.slow
def test_a_run_resumed_with_the_default_loops_keeps_those_it_started_on(synth_dir, tmp_path,
                                                                         monkeypatch, asked, ran):
    """A run started on the graph loops (e.g. before ``auto`` was the default) resumes on them
    with ``auto``: one path per run, the one its provenance names (what ``load_run`` and the
    execution comparisons read); explicit loops are a run's to change."""
    def config(loops):
        return RunConfig(data=DataConfig(str(synth_dir)), test_user="B",
                         encoder=EncoderConfig(hidden=8, loops=loops),
                         optim=OptimConfig(total=3, decay_start=2, decay_every=100),
                         train=TrainConfig(seed=0, eval_points=()))

    original = Trainer._log_progress

    def stop_in_epoch_2(self, done, *args):
        original(self, done, *args)
        if done == 2 * self.sweeps_per_epoch:       # before its checkpoint: resumes from 1
            raise _Interrupt

    run = tmp_path / "run"
    with monkeypatch.context() as patch:
        patch.setattr(Trainer, "_log_progress", stop_in_epoch_2)
        with pytest.raises(_Interrupt):
            train_baseline(config("graph"), run, log=lambda m: None)
    messages = []
    train_baseline(config(asked), run, log=messages.append)
    assert [m for m in messages if "resuming" in m][0].endswith(f"with {ran} loops")
    assert json.loads((run / "config.json").read_text())["provenance"]["loops"] == "graph"
