"""The experiment grid: spec parsing, end-to-end runs, resume after a kill, Dask, tables."""
from __future__ import annotations

import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jigsaws_tools.cores import usable_cores
from multitask.evidence.cli import main as tables_main
from multitask.grid.cli import main as grid_main
from multitask.grid.executors import run_grid
from multitask.grid.spec import (Experiment, GridSpec, RunKey, expand, job_groups, load_spec,
                                 run_config, spec_from_dict, spec_payload, stack_groups,
                                 with_budget)
from multitask.models.variants import get_variant

TINY = """
preset = "quick"
data_dir = "{data}"
test_users = ["B", "C"]
seeds = [0]
hidden = 16
epochs = 3

[[experiments]]
variants = ["A", "APc"]
"""


@pytest.fixture(scope="module")
def tiny_spec(tmp_path_factory, synth_dir) -> Path:
    """TINY without the runs' per-trial figures, which no test here reads (the grids of
    test_trust, test_cli and the documented smoke test draw theirs)."""
    path = tmp_path_factory.mktemp("spec") / "tiny.toml"
    path.write_text('plots = "none"' + TINY.format(data=synth_dir))
    return path


@pytest.fixture(scope="module")
def tiny_grid(tmp_path_factory, tiny_spec) -> Path:
    out = tmp_path_factory.mktemp("grid")
    assert grid_main(["--spec", str(tiny_spec), "--out", str(out), "--workers", "2"]) == 0
    return out


def _metrics(grid: Path) -> dict[str, dict]:
    return {str(p.parent.relative_to(grid)): json.loads(p.read_text())["mean"]
            for p in sorted(grid.glob("runs/*/*/*/*/*/metrics.json"))}


def test_a_specs_plots_reach_its_runs_and_are_no_setting(synth_dir):
    """``plots`` is each run's ``TrainConfig.plots``; like the loops it changes neither a run's
    settings hash nor what the grid's record compares, so a grid may resume with another."""
    from multitask.grid.folder import comparable_spec
    from multitask.grid.spec import run_arguments
    from multitask.models.run_record import variant_configs
    from rnn_seg.runs.settings import settings_hash

    specs = [spec_from_dict({"data_dir": str(synth_dir), "plots": plots}) for plots in
             ("none", "last")]
    key = expand(specs[0], ("B",))[0]
    assert [run_config(spec, key).train.plots for spec in specs] == ["none", "last"]
    hashes = {settings_hash(variant_configs(**run_arguments(spec, key), fingerprint="f"))
              for spec in specs}
    assert len(hashes) == 1
    assert comparable_spec(spec_payload(specs[0])) == comparable_spec(spec_payload(specs[1]))
    with pytest.raises(ValueError, match="s.toml: plots"):
        spec_from_dict({"plots": "first"}, source="s.toml")


def test_spec_errors_name_the_file_and_key(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('preset = "quick"\nhiden = 64\n')
    with pytest.raises(ValueError, match=r"bad\.toml.*hiden"):
        load_spec(bad)
    bad.write_text('[[experiments]]\nvariants = ["APx"]\n')
    with pytest.raises(ValueError, match="APx"):
        load_spec(bad)


def _no_spec_file(kind: str, tmp_path: Path, monkeypatch) -> Path:
    """A --spec path that is no spec file: missing, a folder, unreadable (reading refused as for
    a file without read permission, also as root, whom chmod does not stop), not UTF-8, not
    TOML."""
    path = tmp_path / "spec.toml"
    if kind == "folder":
        path.mkdir()
    elif kind == "not UTF-8":
        path.write_bytes(b"hidden = 8\n\xff\n")
    elif kind == "not valid TOML":
        path.write_text("hidden = = 8\n")
    elif kind == "permission denied":
        path.write_text('preset = "quick"\n')
        import jigsaws_tools.files

        opened = os.open

        def refuse(name, *args, **kwargs):
            if Path(name) == path:
                raise PermissionError(13, "Permission denied", str(path))
            return opened(name, *args, **kwargs)

        monkeypatch.setattr(jigsaws_tools.files.os, "open", refuse)
    return path


@pytest.mark.parametrize("kind,words", [
    ("missing", "no such spec file"), ("folder", "a folder, not a spec file"),
    ("permission denied", "permission denied"), ("not UTF-8", "not UTF-8"),
    ("not valid TOML", "not valid TOML")])
def test_a_spec_path_that_is_no_spec_file_is_one_line_naming_it(kind, words, tmp_path,
                                                                 monkeypatch, capsys):
    spec = _no_spec_file(kind, tmp_path, monkeypatch)
    out = tmp_path / "grid"
    assert grid_main(["--spec", str(spec), "--out", str(out), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"multitask-grid: error: {spec}: ")
    assert len(err.splitlines()) == 1, err
    assert words in err and "Errno" not in err
    assert not out.exists()


def test_expand_skips_gradnorm_for_single_task_and_checks_folds():
    spec = GridSpec(test_users=("B",), seeds=(0, 1),
                    experiments=(Experiment(("A", "APc", "Pc"), ("fixed", "gradnorm")),))
    keys = expand(spec, ("B", "C"))
    assert {k.config_name for k in keys} == {"A-fixed", "APc-fixed", "APc-gradnorm", "Pc-fixed"}
    assert len(keys) == 4 * 2
    with pytest.raises(ValueError, match="Z"):
        expand(GridSpec(test_users=("Z",)), ("B", "C"))


def test_paper_preset_run_configs(synth_dir):
    spec = GridSpec(preset="paper", data_dir=str(synth_dir))
    keys = expand(spec, ("B", "C", "D", "E", "F", "G", "H", "I"))
    assert len(keys) == 22 * 8 * 3
    online_apc = run_config(spec, RunKey("revised", "forward", "APc", "fixed", 2, "G"))
    assert online_apc.encoder.hidden == 1024 and not online_apc.encoder.bidirectional
    assert (online_apc.optim.total, online_apc.optim.learning_rate) == (120, 1.0)
    assert online_apc.train.eval_points == (100, 110, 120) and online_apc.train.seed == 2
    pr = run_config(spec, RunKey("original", "bidirectional", "Pr", "fixed", 0, "B"))
    assert (pr.optim.total, pr.optim.momentum, pr.data.annotations) == (80, 0.9, "original")


def test_presets_and_schedule_scaling():
    assert GridSpec(preset="paper").budget.hidden == 1024
    assert GridSpec(preset="paper").budget.seeds == (0, 1, 2)
    optim, points = get_variant("A").schedule(0.25)
    assert (optim.total, optim.decay_start, optim.decay_every, points) == (30, 20, 10, (25, 28, 30))
    optim, points = get_variant("Pc").schedule(0.25)
    assert (optim.total, points) == (20, (15, 18, 20))


def test_schedule_factors_lengthen_only_their_variants(tmp_path):
    path = tmp_path / "longer.toml"
    path.write_text('preset = "quick"\nschedule_factors = {APoc = 2, Poc = 1.5}\n')
    spec = load_spec(path)
    apoc, a, poc = (run_config(spec, RunKey("revised", "bidirectional", v, "fixed", 0, "B"))
                    for v in ("APoc", "A", "Poc"))
    assert (apoc.optim.total, apoc.optim.decay_start, apoc.train.eval_points) == (
        60, 40, (50, 55, 60))                                   # quick x0.25, then x2
    assert (a.optim.total, a.train.eval_points) == (30, (25, 28, 30))
    assert (poc.optim.total, poc.train.eval_points) == (30, (23, 26, 30))   # P: 20 x1.5
    assert spec.budget.describe_schedule() == "x0.25 (APoc x0.5; Poc x0.375)"
    recorded = with_budget(spec)
    assert recorded.schedule_factors == {"APoc": 2, "Poc": 1.5}
    assert with_budget(GridSpec(preset="quick")).schedule_factors == {}
    assert run_config(recorded, RunKey("revised", "bidirectional", "APoc", "fixed", 0, "B")
                      ).optim.total == 60
    for bad, named in (("{APx = 2}", "APx"), ("{APoc = 0}", "schedule_factors.APoc"),
                       ('"long"', "schedule_factors")):
        path.write_text(f"schedule_factors = {bad}\n")
        with pytest.raises(ValueError, match=named):
            load_spec(path)


@pytest.mark.slow
def test_tiny_grid_end_to_end(tiny_grid):
    metrics = _metrics(tiny_grid)
    assert len(metrics) == 4
    assert all(m["gesture"]["accuracy"] > 0 for m in metrics.values())
    assert tables_main(["paper", str(tiny_grid)]) == 0
    tables = tiny_grid / "tables"
    for name in ("runs.csv", "per_fold.csv", "summary.csv", "table1.csv", "table1.tex"):
        assert (tables / name).stat().st_size > 0
    assert (tables / "figures" / "per_gesture_accuracy.pdf").exists()
    assert (tables / "figures" / "fold_accuracy.png").exists()


@pytest.mark.slow
def test_table_csv_matches_the_per_fold_numbers(tiny_grid):
    tables_main(["paper", str(tiny_grid), "--no-figures"])
    folds = pd.read_csv(tiny_grid / "tables" / "per_fold.csv")
    table = pd.read_csv(tiny_grid / "tables" / "table1.csv")
    baseline = table[table.config == "time-offline"]            # the time-only progress row
    assert set(baseline.metric) == {"progress_mae", "progress_accuracy", "progress_edit",
                                    "progress_f1@10"} and set(baseline.folds) == {2}
    for row in table[table.config != "time-offline"].itertuples():
        variant, weighting = row.config.rsplit("-", 1)
        values = folds[(folds.variant == variant) & (folds.weighting == weighting)][row.metric]
        assert len(values) == row.folds == 2
        assert row.left_mean == pytest.approx(values.mean(), abs=1e-3)
        assert row.left_std == pytest.approx(values.std(ddof=1), abs=1e-3)
        assert row.diff == pytest.approx(row.left_mean - row.right_mean, abs=1e-3)


@pytest.mark.slow
def test_latex_table_shape(tiny_grid):
    tables_main(["paper", str(tiny_grid), "--no-figures"])
    tex = (tiny_grid / "tables" / "table1.tex").read_text()
    for env in ("table", "tabular"):
        assert tex.count(rf"\begin{{{env}}}") == tex.count(rf"\end{{{env}}}") == 1
    assert tex.count("{") == tex.count("}")
    header = tex.split("\\toprule\n")[1].split(r"\midrule")[0].splitlines()
    assert [c.strip() for c in header[0].removesuffix(r"\\").split("&")] == [
        "", "", "A", "APc", "Time only"]
    columns = 2 + 3            # metric and side labels, the models A and APc, the time-only row
    rows = [line for line in tex.split(r"\midrule", 1)[1].split(r"\bottomrule")[0].splitlines()
            if line.endswith(r"\\") and r"\multicolumn" not in line]
    assert [row.split(" & ")[1] for row in rows[:3]] == ["Ours", "Paper", r"$\Delta$"]
    assert all(row.count(" & ") == columns - 1 for row in rows)


def _one_configuration(tiny_spec: Path, folder: Path) -> Path:
    """The tiny grid's spec with its multi-task configuration only (APc on folds B and C)."""
    path = folder / "apc.toml"
    path.write_text(tiny_spec.read_text().replace('variants = ["A", "APc"]', 'variants = ["APc"]'))
    return path


@pytest.mark.slow
def test_killed_grid_resumes_without_redoing_finished_runs(tmp_path, tiny_spec, capsys):
    """Killed (SIGKILL, the whole process group) after its first run finished; the same command
    again trains only the other."""
    spec, out = _one_configuration(tiny_spec, tmp_path), tmp_path / "grid"
    command = ["--spec", str(spec), "--out", str(out), "--workers"]
    process = subprocess.Popen([sys.executable, "-m", "multitask.grid.cli", *command, "1"],
                               start_new_session=True, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    deadline = time.time() + 300
    while not list(out.glob("runs/**/finished.json")) and time.time() < deadline:
        time.sleep(0.5)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    finished = {p: p.stat().st_mtime_ns for p in out.glob("runs/**/finished.json")}
    assert len(finished) == 1
    capsys.readouterr()
    assert grid_main([*command, "2"]) == 0
    assert "2 runs, 1 already finished, 1 to run" in capsys.readouterr().out
    assert len(list(out.glob("runs/**/finished.json"))) == 2
    assert all(p.stat().st_mtime_ns == t for p, t in finished.items())


@pytest.mark.slow
def test_a_run_does_not_depend_on_the_jobs_before_it_in_its_worker(tmp_path, tiny_spec,
                                                                    tiny_grid, monkeypatch):
    """One worker runs two runs in turn, then a fresh worker the third (more jobs than one
    pool's workers take); two workers split them: the same numbers."""
    import multitask.grid.executors as executors

    monkeypatch.setattr(executors, "JOBS_PER_WORKER", 2)
    cores = max(1, usable_cores() // 2)                        # as tiny_grid's two workers
    spec = load_spec(tiny_spec)
    keys = expand(spec, ("B", "C"))[:3]                # two in one worker, the third in another
    assert run_grid(spec, keys, tmp_path, workers=1, cores_per_job=cores,
                    log=lambda message: None) == []
    expected = _metrics(tiny_grid)
    assert _metrics(tmp_path) == {str(key.path()): expected[str(key.path())] for key in keys}


@pytest.mark.slow
def test_workers_run_several_jobs_only_when_the_jobs_share_a_thread_plan(tiny_spec):
    from multitask.grid.executors import JOBS_PER_WORKER, jobs_per_worker

    spec = replace(load_spec(tiny_spec), experiments=(
        Experiment(("A",)), Experiment(("A",), directions=("forward",))))
    groups = job_groups(expand(spec, ("B", "C")), 1)
    assert jobs_per_worker(spec, groups, cores=1) == JOBS_PER_WORKER    # (1, 1) both
    assert jobs_per_worker(spec, groups, cores=2) == 1                  # (1, 2) vs (2, 1)
    bidirectional = [g for g in groups if g[0].direction == "bidirectional"]
    assert jobs_per_worker(spec, bidirectional, cores=2) == JOBS_PER_WORKER


def _assert_same_metrics(got: dict, expected: dict, **tolerance) -> None:
    """Every run's mean metrics (``_metrics``) equal within ``tolerance``; ``null`` (a per-class
    score a fold leaves undefined) only where the other is ``null`` too."""
    for run, values in expected.items():
        for task, scores in values.items():
            for name, value in scores.items():
                np.testing.assert_allclose(*(np.nan if v is None else v
                                             for v in (got[run][task][name], value)),
                                           err_msg=f"{run} {task} {name}", **tolerance)


@pytest.mark.slow
def test_dask_cluster_gives_the_local_pool_metrics(tmp_path, tiny_spec, tiny_grid):
    distributed = pytest.importorskip("dask.distributed")
    spec = load_spec(tiny_spec)
    keys = [key for key in expand(spec, ("B", "C")) if key.variant == "APc"]
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        failed = run_grid(spec, keys, tmp_path, scheduler=cluster.scheduler_address,
                          log=lambda message: None)
    assert failed == []
    local, dask = _metrics(tiny_grid), _metrics(tmp_path)
    assert dask.keys() == {str(key.path()) for key in keys} and len(dask) == 2
    _assert_same_metrics(dask, {name: local[name] for name in dask}, rtol=1e-6)


@pytest.mark.slow
def test_a_grid_in_this_process_gives_the_worker_processes_metrics(tmp_path, tiny_spec,
                                                                   tiny_grid, capsys):
    """``--workers 0`` runs each job in the grid's own process, one after another, with the
    same runs as the worker processes of ``tiny_grid``, and starts no process."""
    import multiprocessing
    out = tmp_path / "grid"
    assert grid_main(["--spec", str(_one_configuration(tiny_spec, tmp_path)), "--out", str(out),
                      "--workers", "0"]) == 0
    assert "2 to run in this process" in capsys.readouterr().out
    assert multiprocessing.active_children() == []
    lone, here = _metrics(tiny_grid), _metrics(out)
    assert here.keys() == {name for name in lone if "APc-fixed" in name} and len(here) == 2
    _assert_same_metrics(here, {name: lone[name] for name in here}, rtol=1e-6)


def test_a_job_that_fails_in_this_process_is_a_failed_run_and_the_next_one_runs(
        tmp_path, tiny_spec, monkeypatch):
    """In this process as in a worker, a job's exception fails its runs, named with it, and the
    grid goes on with the next job."""
    from multitask.grid import executors
    spec = load_spec(tiny_spec)
    keys = [key for key in expand(spec, ("B", "C")) if key.variant == "APc"]
    ran = []

    def job(spec_payload, group, out, cores, command):
        ran.append(group[0]["fold"])
        if group[0]["fold"] == "B":
            raise RuntimeError("a job's own error")
        return []
    monkeypatch.setattr(executors, "run_job", job)
    failed = run_grid(spec, keys, tmp_path, workers=0, log=lambda message: None)
    assert ran == ["B", "C"]
    assert failed == [(keys[0], "RuntimeError: a job's own error")]


def test_a_failed_job_reaches_the_grid_as_its_error_s_words_alone(tmp_path, tiny_spec):
    """A worker's exception is unpickled in the grid's process, which would import the module
    that defines it (the trainer's, TensorFlow's); a job raises ``JobFailed`` with its words."""
    from multitask.grid.job import JobFailed, run_job

    spec = load_spec(tiny_spec)
    gone = replace(spec, data_dir=str(tmp_path / "gone"))        # its data removed since
    with pytest.raises(JobFailed) as raised:
        run_job(spec_payload(gone), [asdict(expand(spec, ("B", "C"))[0])], str(tmp_path / "g"),
                1)
    back = pickle.loads(pickle.dumps(raised.value))
    assert type(back) is JobFailed and str(back) == str(raised.value)
    assert str(back).startswith("ReleaseNotFoundError: ") and str(tmp_path / "gone") in str(back)
    assert "ReleaseNotFoundError" in next((tmp_path / "g").rglob("train.log")).read_text()


@pytest.mark.slow
def test_stacked_grid_gives_the_lone_runs_metrics(tmp_path, tiny_spec, tiny_grid):
    """``--stack 2`` trains folds B and C of a configuration (the multi-task APc) in one
    vectorised step, on the graph loops when the spec leaves the loops to ``auto``."""
    out = tmp_path / "grid"
    assert grid_main(["--spec", str(_one_configuration(tiny_spec, tmp_path)), "--out", str(out),
                      "--stack", "2"]) == 0
    run = out / RunKey("revised", "bidirectional", "APc", "fixed", 0, "B").path()
    assert "resuming" not in (run / "train.log").read_text()
    assert json.loads((run / "config.json").read_text())["provenance"]["loops"] == "graph"
    lone, stacked = _metrics(tiny_grid), _metrics(out)
    assert stacked.keys() == {name for name in lone if "APc-fixed" in name} and len(stacked) == 2
    _assert_same_metrics(stacked, {name: lone[name] for name in stacked}, rtol=1e-3, atol=0.05)


@pytest.mark.slow
def test_a_grid_resumed_with_the_default_loops_keeps_those_it_was_launched_with(
        tmp_path, tiny_spec, tiny_grid, capsys):
    """A grid whose grid.json records ``graph`` (launched before ``auto`` was the default, or
    with ``--stack``) trains its remaining runs on ``graph`` under ``auto``: one path per grid."""
    grid = tmp_path / "grid"
    shutil.copytree(tiny_grid, grid)
    record = json.loads((grid / "grid.json").read_text())
    record["spec"]["loops"] = "graph"
    (grid / "grid.json").write_text(json.dumps(record))
    run = grid / RunKey("revised", "bidirectional", "A", "fixed", 0, "C").path()
    shutil.rmtree(run)                                      # a run the grid had not started
    capsys.readouterr()
    assert grid_main(["--spec", str(tiny_spec), "--out", str(grid), "--workers", "0"]) == 0
    assert "loops auto: graph" in capsys.readouterr().out
    assert json.loads((run / "config.json").read_text())["provenance"]["loops"] == "graph"


@pytest.mark.parametrize("stack", ["1", "2"])
def test_a_convolutional_grid_may_stack_and_read_older_records(tmp_path, synth_dir, stack):
    """A TCN grid has no LSTM loops: ``auto`` (its default), or ``graph`` as older grid.json and
    stacked grids record, are accepted; compiled loops are refused."""
    spec = tmp_path / "tcn.toml"
    spec.write_text(f'preset = "quick"\ndata_dir = "{synth_dir}"\nencoder = "ed-tcn"\n')
    assert grid_main(["--spec", str(spec), "--out", str(tmp_path / "grid"), "--stack", stack,
                      "--dry-run"]) == 0
    assert spec_from_dict({"encoder": "ed-tcn", "loops": "graph"}).loops == "graph"
    with pytest.raises(ValueError, match="loops is an LSTM setting"):
        spec_from_dict({"encoder": "ed-tcn", "loops": "fused"})


def test_stack_groups_hold_one_configuration():
    keys = [RunKey("revised", "bidirectional", v, "fixed", s, f)
            for v in ("A", "APc") for s in (0, 1) for f in "BCD"]
    groups = stack_groups(keys, 4)
    assert [len(g) for g in groups] == [4, 2, 4, 2]
    assert all(len({k.config_name for k in g}) == 1 for g in groups)
    assert sorted(k for g in groups for k in g) == sorted(keys)
    assert stack_groups(keys, 1) == [[k] for k in keys]


def test_run_key_paths_are_unique():
    a = RunKey("revised", "bidirectional", "APc", "fixed", 0, "B")
    b = RunKey("revised", "bidirectional", "APc", "gradnorm", 0, "B")
    assert a.path() != b.path() and a.path().parts[-1] == "B"


def test_annotation_ablation_reports_revised_minus_original():
    from multitask.evidence.render.tables import annotation_ablation, to_latex

    summary = pd.DataFrame([
        {"annotations": a, "direction": "bidirectional", "variant": v, "weighting": "fixed",
         "folds": 8, "gesture_accuracy_mean": acc, "gesture_accuracy_std": 1.0}
        for a, v, acc in (("revised", "A", 85.0), ("original", "A", 83.0),
                          ("revised", "APc", 86.0))])
    table = annotation_ablation(summary)
    assert list(table.config) == ["A-fixed"]            # APc ran on one version only
    assert table.iloc[0]["diff"] == pytest.approx(2.0)
    tex = to_latex(table, "caption", "ablation", ("Revised", "Original"))
    assert r"Accuracy & Revised & \textbf{85.0 (1.0)} \\" in tex
    assert r" & Original & \textbf{83.0 (1.0)} \\" in tex and r" & $\Delta$ & $+$2.0 \\" in tex


@pytest.mark.slow
def test_runs_table_records_convergence(tiny_grid):
    tables_main(["paper", str(tiny_grid), "--no-figures"])
    runs = pd.read_csv(tiny_grid / "tables" / "runs.csv")
    assert {"convergence", "converged", "loss_drop", "loss_drop_se"} <= set(runs.columns)
    assert (runs["loss_drop_se"].isna() == runs["loss_drop"].isna()).all()
    assert set(runs["convergence"].dropna()) <= {"converged", "undecided", "still falling"}
    assert (runs["convergence"].isna() == runs["loss_drop_se"].isna()).all()
    summary = pd.read_csv(tiny_grid / "tables" / "summary.csv")
    assert (summary["still_falling"] >= 0).all() and (summary["undecided"] >= 0).all()
    assert summary["still_falling"].sum() == (runs["convergence"] == "still falling").sum()


def test_runs_saved_before_the_standard_error_get_it_from_their_history(tmp_path):
    """A run finished by older code saved the diagnostic without ``max_loss_drop_se``; runs.csv
    takes the standard error from history.csv with the saved criterion, and keeps the saved
    verdict and loss_drop; a history that cannot give it leaves it blank, never an error."""
    from fake_grid import write_fake_grid
    from multitask.evidence.runs.collect import run_rows
    from rnn_seg.convergence import history_convergence
    from rnn_seg.runs.folder import read_json, write_json

    grid = write_fake_grid(tmp_path / "grid", seeds=(0,), epochs=40)
    run_dirs = [grid / f"runs/revised/bidirectional/APc-fixed/seed0/{fold}" for fold in "BC"]
    full = history_convergence(pd.read_csv(run_dirs[0] / "history.csv"),
                               ["gesture", "progress"], 40)
    old = {**{k: v for k, v in full.items() if "_se" not in k and k != "verdict"},
           "converged": True}
    for run in run_dirs:
        write_json(run / "metrics.json", {**read_json(run / "metrics.json"), "convergence": old})
    pd.read_csv(run_dirs[1] / "history.csv").drop(columns="loss_progress").to_csv(
        run_dirs[1] / "history.csv", index=False)
    runs, _ = run_rows(grid)
    rows = runs.set_index(["annotations", "direction", "variant", "weighting", "fold"])
    row = rows.loc[("revised", "bidirectional", "APc", "fixed", "B")]
    worst = max(full["loss_drop"], key=full["loss_drop"].get)
    assert row["loss_drop_se"] == pytest.approx(full["loss_drop_se"][worst])
    assert row["loss_drop"] == pytest.approx(full["max_loss_drop"])
    assert bool(row["converged"])                                    # the saved verdict
    assert row["convergence"] == full["verdict"]           # three-way, from drops and errors
    unreadable = rows.loc[("revised", "bidirectional", "APc", "fixed", "C")]
    assert np.isnan(unreadable["loss_drop_se"]) and bool(unreadable["converged"])
    assert pd.isna(unreadable["convergence"])


def test_tables_carry_rounded_and_raw_mae():
    from multitask.evidence.render.tables import PAPER_TABLES, paper_comparison

    summary = pd.DataFrame([{"annotations": "revised", "direction": "bidirectional",
                             "variant": "APr", "weighting": "fixed", "folds": 8, "still_falling": 0,
                             "progress_mae_mean": 5.0, "progress_mae_std": 1.0,
                             "progress_mae_raw_mean": 7.0, "progress_mae_raw_std": 1.0}])
    table = paper_comparison(summary, PAPER_TABLES[0]).set_index("metric")
    assert table.loc["progress_mae", "right_mean"] == 5.3            # the paper's, rounded output
    assert table.loc["progress_mae", "left_mean"] == 5.0
    assert table.loc["progress_mae_raw", "left_mean"] == 7.0
    assert pd.isna(table.loc["progress_mae_raw", "right_mean"])       # the paper has no raw MAE


def test_experiments_may_name_their_own_seeds_first_seeds_run_first_then_by_configuration(tmp_path):
    spec = GridSpec(seeds=(0,), experiments=(
        Experiment(("A", "APc"), annotations=("revised",), seeds=(0, 1, 2)),
        Experiment(("A",), annotations=("original",))))
    keys = expand(spec, ("B", "C"))
    seeds = {(k.annotations, k.variant): sorted({x.seed for x in keys if
                                                 (x.annotations, x.variant) == (k.annotations,
                                                                                k.variant)})
             for k in keys}
    assert seeds == {("revised", "A"): [0, 1, 2], ("revised", "APc"): [0, 1, 2],
                     ("original", "A"): [0]}
    assert GridSpec().preset == "converged" and GridSpec().budget.schedule_scale == 1.0
    with pytest.raises(ValueError, match="experiments.seeds"):
        Experiment(("A",), seeds=(0, 0))
    groups = job_groups(keys, 2)
    configs = [(g[0].annotations, g[0].variant, g[0].seed) for g in groups]
    assert configs == [("revised", "A", 0), ("revised", "APc", 0), ("original", "A", 0),
                       ("revised", "A", 1), ("revised", "A", 2),
                       ("revised", "APc", 1), ("revised", "APc", 2)]
    # resumed after the first seeds finished: still configuration by configuration
    pending = [k for k in keys if k.seed > 0]
    assert job_groups(pending, 2, grid=keys) == groups[3:]


def test_tables_mark_runs_still_falling_and_name_undecided_ones_in_the_note():
    from multitask.evidence.render.tables import PAPER_TABLES, paper_comparison, to_latex

    row = {"annotations": "revised", "direction": "bidirectional", "weighting": "fixed",
           "folds": 8, "gesture_accuracy_mean": 85.0, "gesture_accuracy_std": 5.0}
    summary = pd.DataFrame([{**row, "variant": "A", "still_falling": 0, "undecided": 0},
                            {**row, "variant": "APc", "still_falling": 2, "undecided": 1},
                            {**row, "variant": "APoc", "still_falling": 0, "undecided": 3}])
    table = paper_comparison(summary, PAPER_TABLES[0])
    assert set(table.model) == {"A", "APc (w1=w2=1) (still falling: 2 runs; undecided: 1 run)",
                                "APoc (w1=w2=1) (undecided: 3 runs)"}
    tex = to_latex(table, "caption", "table1", ("Ours", "Paper"))
    header = tex.split(r"\toprule")[1].split(r"\midrule")[0]
    assert r"APc$^\dagger$" in header and "falling" not in header
    assert r"APoc$^\dagger$" not in header and "APoc" in header
    assert (r"$^\dagger$\,APc $w_1{=}w_2{=}1$: still falling: 2 runs; undecided: 1 run."
            in tex)
    assert r"holds the tolerance): APoc $w_1{=}w_2{=}1$: 3 runs." in tex


def test_eta_weighs_the_runs_left_by_their_schedules():
    """After an 80-epoch run took 10 s, two 160-epoch runs left take 40 s, not 20."""
    from multitask.grid.executors import Progress
    from multitask.grid.spec import schedule_epochs

    spec = GridSpec(preset="converged")
    keys = [RunKey("revised", "bidirectional", variant, "fixed", 0, "B")
            for variant in ("Pr", "Poc", "APoc")]
    assert [schedule_epochs(spec, key) for key in keys] == [80, 160, 180]
    times, lines = iter([0.0, 10.0]), []
    progress = Progress(3, 0, lines.append, {keys[0]: 80, keys[1]: 160, keys[2]: 160},
                        clock=lambda: next(times))
    progress.finished(keys[0])
    assert lines == [f"[grid] 1/3 done, ETA 0:00:40 | {keys[0].path()} finished"]


def test_eta_is_unknown_while_only_runs_with_nothing_left_to_train_finished():
    """A run trained to the end but killed before it was marked finished has no epochs left: its
    finishing says nothing of the time per epoch."""
    from multitask.grid.executors import Progress

    keys = [RunKey("revised", "bidirectional", "A", "fixed", 0, fold) for fold in ("B", "C")]
    lines = []
    progress = Progress(2, 0, lines.append, {keys[0]: 0.0, keys[1]: 80.0}, clock=lambda: 1.0)
    progress.finished(keys[0])
    assert lines == [f"[grid] 1/2 done, ETA unknown | {keys[0].path()} finished"]


def test_eta_counts_only_the_epochs_a_resumed_run_has_left(tmp_path):
    """A run interrupted after 30 of its 80 epochs weighs 50 in the ETA; a fresh one 80."""
    from multitask.grid.executors import _epochs_left

    spec = GridSpec(preset="converged")
    resumed, fresh = (RunKey("revised", "bidirectional", "Pr", "fixed", 0, fold)
                      for fold in ("B", "C"))
    run = tmp_path / resumed.path()
    (run / "checkpoints").mkdir(parents=True)
    for sweep in (203, 210):                                 # 7 sweeps an epoch: epochs 29, 30
        (run / "checkpoints" / f"ckpt-{sweep}.index").touch()
    (run / "history.csv").write_text("unit,n,sweep,lr\nepochs,1.0,7,1.0\nepochs,2.0,14,1.0\n")
    assert _epochs_left(spec, resumed, tmp_path) == pytest.approx(50)
    assert _epochs_left(spec, fresh, tmp_path) == 80


@pytest.mark.slow
def test_scores_archive_tabulates_and_continues_like_its_grid(tmp_path, tiny_spec, tiny_grid,
                                                                capsys):
    """An archive keeps each finished run's config, metrics, logs and predicted labels (no
    weights, no predictions CSVs): its tables are the grid's, and a copy of it resumes with
    nothing to train."""
    archive = tmp_path / "archive"
    assert tables_main(["archive", str(tiny_grid), str(archive)]) == 0
    assert "4 of 4 runs archived" in capsys.readouterr().out
    runs = sorted(p.parent for p in archive.glob("runs/*/*/*/*/*/finished.json"))
    assert len(runs) == 4
    for run in runs:
        assert {"config.json", "metrics.json", "history.csv"} <= {p.name for p in run.iterdir()}
        assert not {"checkpoints", "eval", "train.log"} & {p.name for p in run.iterdir()}
    tables = {grid: tmp_path / "tables" / grid.name for grid in (tiny_grid, archive)}
    for grid, out in tables.items():
        assert tables_main(["paper", str(grid), "--out", str(out), "--no-figures"]) == 0
    for name in ("runs.csv", "summary.csv", "claims.csv"):
        pd.testing.assert_frame_equal(pd.read_csv(tables[tiny_grid] / name),
                                      pd.read_csv(tables[archive] / name))
    assert (tables[tiny_grid] / "table1.tex").read_text() == (tables[archive]
                                                              / "table1.tex").read_text()
    copy = tmp_path / "continued"
    shutil.copytree(archive, copy)
    finished = {p: p.stat().st_mtime_ns for p in copy.glob("runs/**/finished.json")}
    capsys.readouterr()
    assert grid_main(["--spec", str(tiny_spec), "--out", str(copy)]) == 0
    assert "4 already finished, 0 to run" in capsys.readouterr().out
    assert {p: p.stat().st_mtime_ns for p in copy.glob("runs/**/finished.json")} == finished


@pytest.mark.slow
def test_tables_of_an_archive_draw_its_examples_from_the_kept_predictions(
        tmp_path, tiny_grid, capsys):
    """An archive keeps the runs' predictions: its tables draw the grid's figures, the example
    trial's among them; without its kept predictions (an earlier archive) they are left out, and
    --example-trial is refused."""
    archive, out = tmp_path / "archive", tmp_path / "tables"
    assert tables_main(["archive", str(tiny_grid), str(archive)]) == 0
    assert tables_main(["paper", str(tiny_grid), "--out", str(out)]) == 0
    figures = {p.name: p.read_bytes() for p in (out / "figures").iterdir()}
    assert "segmentation_example.png" in figures
    assert tables_main(["paper", str(archive), "--out", str(out)]) == 0
    assert {p.name: p.read_bytes() for p in (out / "figures").iterdir()} == figures
    for kept in archive.glob("runs/*/*/*/*/*/test_predictions.json"):
        kept.unlink()
    capsys.readouterr()
    assert tables_main(["paper", str(archive), "--out", str(out)]) == 0
    assert "no example-trial figures" in capsys.readouterr().err
    redrawn = {p.name for p in (out / "figures").iterdir()}
    assert redrawn == {n for n in figures if "_example." not in n}
    assert tables_main(["paper", str(archive), "--out", str(out),
                        "--example-trial", "Suturing_B001"]) == 2
    assert "kept its predictions" in capsys.readouterr().err


@pytest.mark.slow
def test_an_archived_run_of_other_settings_is_never_taken_for_the_specs(tmp_path, tiny_spec,
                                                                         tiny_grid, capsys):
    copy = tmp_path / "continued"
    assert tables_main(["archive", str(tiny_grid), str(copy)]) == 0
    config = copy / RunKey("revised", "bidirectional", "A", "fixed", 0, "C").path() / "config.json"
    saved = json.loads(config.read_text())
    saved["run"]["encoder"]["hidden"] = 32
    config.write_text(json.dumps(saved))
    capsys.readouterr()
    assert grid_main(["--spec", str(tiny_spec), "--out", str(copy)]) == 2
    error = capsys.readouterr().err
    assert "other settings" in error and "A-fixed/seed0/C" in error and "hidden" in error


@pytest.mark.slow
def test_a_grid_keeps_its_archive_up_to_date(tmp_path, tiny_spec, tiny_grid, capsys,
                                             monkeypatch):
    """--archive writes the archive before training (refusing a place it may not go, before any
    work) and after each finished job; a later failure to write it is a warning."""
    grid, archive = tmp_path / "grid", tmp_path / "archive"
    shutil.copytree(tiny_grid, grid)
    marker = grid / RunKey("revised", "bidirectional", "APc", "fixed", 0, "B").path() / "finished.json"
    marker.unlink()                                        # one run to finish again
    command = ["--spec", str(tiny_spec), "--out", str(grid), "--workers", "0"]
    assert grid_main([*command, "--archive", str(grid / "archive")]) == 2
    assert "neither inside the other" in capsys.readouterr().err and not marker.exists()
    assert grid_main([*command, "--archive", str(archive)]) == 0
    out = capsys.readouterr().out
    assert f"archive {archive}: 3 of 4 runs" in out and f"archive {archive}: 4 of 4 runs" in out
    assert len(list(archive.glob("runs/**/finished.json"))) == 4

    import multitask.grid.archive as archive_module
    original, calls = archive_module.archive_grid, []

    def full_disk_after_the_first(grid_dir, dest, **options):
        calls.append(dest)
        if len(calls) > 1:
            raise OSError(f"{dest}: No space left on device")
        return original(grid_dir, dest, **options)

    marker.unlink()
    monkeypatch.setattr(archive_module, "archive_grid", full_disk_after_the_first)
    assert grid_main([*command, "--archive", str(tmp_path / "second")]) == 0
    out = capsys.readouterr().out
    assert "warning: the archive in" in out and "No space left" in out and marker.exists()


@pytest.mark.slow
def test_a_dry_run_checks_the_archive_folder_and_writes_nothing(tmp_path, tiny_spec, tiny_grid,
                                                                capsys):
    grid, archive = tmp_path / "grid", tmp_path / "archive"
    shutil.copytree(tiny_grid, grid)
    command = ["--spec", str(tiny_spec), "--out", str(grid), "--dry-run"]
    assert grid_main([*command, "--archive", str(grid / "archive")]) == 2
    assert "neither inside the other" in capsys.readouterr().err
    assert grid_main([*command, "--archive", str(archive)]) == 0
    assert "not written in a dry run" in capsys.readouterr().out and not archive.exists()
    assert tables_main(["archive", str(grid), str(archive)]) == 0       # 4 finished runs
    fresh = ["--spec", str(tiny_spec), "--out", str(tmp_path / "fresh"), "--dry-run"]
    assert grid_main([*fresh, "--archive", str(archive)]) == 2           # would lose them
    assert "replacing it would lose them" in capsys.readouterr().err


@pytest.mark.slow
def test_archive_leaves_out_unfinished_runs_and_replaces_only_an_archive(tmp_path, tiny_grid,
                                                                         capsys):
    grid = tmp_path / "grid"
    shutil.copytree(tiny_grid, grid)
    run = grid / RunKey("revised", "bidirectional", "APc", "fixed", 0, "B").path()
    (run / "finished.json").unlink()
    archive = tmp_path / "archive"
    assert tables_main(["archive", str(grid), str(archive)]) == 0
    assert "3 of 4 runs archived" in capsys.readouterr().out
    assert tables_main(["archive", str(tiny_grid), str(archive)]) == 0    # replaces it
    assert len(list(archive.glob("runs/**/finished.json"))) == 4
    assert tables_main(["archive", str(grid), str(archive)]) == 2         # would lose a run
    assert f"1 finished run(s) that {grid} does not" in capsys.readouterr().err
    assert len(list(archive.glob("runs/**/finished.json"))) == 4
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "todo.txt").write_text("mine")
    link = tmp_path / "link"
    link.symlink_to(archive)
    for dest, says in ((notes, "holds todo.txt"), (grid, "neither inside the other"),
                       (grid / "archive", "neither inside the other"), (link, "symbolic link")):
        assert tables_main(["archive", str(grid), str(dest)]) == 2
        assert says in capsys.readouterr().err
    assert tables_main(["archive", str(archive), str(grid)]) == 2         # a grid, not an archive
    assert "holds" in capsys.readouterr().err and (run / "checkpoints").is_dir()
    assert [p.name for p in notes.iterdir()] == ["todo.txt"]
    (run / "finished.json").write_text("{}")
    (run / "metrics.json").unlink()
    assert tables_main(["archive", str(grid), str(tmp_path / "new")]) == 2
    assert "without metrics.json" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["archive", "grid", "link", "notes"]
    with pytest.raises(SystemExit):
        tables_main(["archive", str(grid), str(archive), "--out", str(notes)])
    assert "takes no --out" in capsys.readouterr().err


def _snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    """Every entry of ``folder`` with its size and modification time: what a dry run leaves."""
    return {str(p.relative_to(folder)): (p.lstat().st_size, p.lstat().st_mtime_ns)
            for p in sorted(folder.rglob("*"))}


def _other_settings(grid: Path) -> None:
    """One run folder holding a run of another width than the spec's."""
    config = grid / RunKey("revised", "bidirectional", "A", "fixed", 0, "C").path() / "config.json"
    data = json.loads(config.read_text())
    data["run"]["encoder"]["hidden"] = 8
    config.write_text(json.dumps(data))


#: Folder states of a grid, and the words of the launch's refusal (None: it goes ahead).
FOLDER_STATES = {
    "finished": (lambda grid, spec: None, None),
    "another spec": (lambda grid, spec: spec.write_text(spec.read_text().replace(
        "hidden = 16", "hidden = 8")), "records another grid"),
    "a run of other settings": (lambda grid, spec: _other_settings(grid),
                                "1 run folder(s) hold runs with other settings"),
    "a stale lock": (lambda grid, spec: (grid / ".lock").write_text(
        f"{_dead_pid()} {os.uname().nodename} 2026-12-01T10:00\n"), None),
}


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


@pytest.mark.slow
@pytest.mark.parametrize("state", FOLDER_STATES)
def test_a_dry_run_refuses_what_the_launch_refuses_and_writes_nothing(
        tmp_path, tiny_spec, tiny_grid, capsys, state):
    """Issue 66: the dry run listed runs over a folder whose record is another spec's, or whose
    run folders hold other settings, which the launch refuses. Both now refuse in the same
    words, or both go ahead (a stale lock is taken); the dry run writes nothing."""
    grid, spec = tmp_path / "grid", tmp_path / "spec.toml"
    shutil.copytree(tiny_grid, grid)
    shutil.copy(tiny_spec, spec)
    change, refusal = FOLDER_STATES[state]
    change(grid, spec)
    before = _snapshot(grid)
    command = ["--spec", str(spec), "--out", str(grid)]
    dry = grid_main([*command, "--dry-run"])
    said = capsys.readouterr()
    assert _snapshot(grid) == before
    if refusal is None:
        assert dry == 0 and "4 runs, 4 already finished, 0 to run" in said.out
        assert grid_main(command) == 0
        assert "grid complete" in capsys.readouterr().out
        return
    assert dry == 2 and refusal in said.err
    assert grid_main(command) == 2
    assert capsys.readouterr().err == said.err


@pytest.mark.parametrize("place", ["new/grid", "/proc/mtrnn-jigsaws-grid"])
@pytest.mark.slow
def test_a_dry_run_of_a_folder_not_there_yet_agrees_with_the_launch_and_leaves_none(
        tmp_path, tiny_spec, capsys, place):
    """Issue 66: a dry run listed "4 to run" for ``--out /proc/x``, where the launch cannot make
    its folder; now both refuse in the same words. A folder that can be made is not left."""
    if place.startswith("/proc") and not Path("/proc/self").is_dir():
        pytest.skip("no /proc")
    out = Path(place) if place.startswith("/") else tmp_path / place
    command = ["--spec", str(tiny_spec), "--out", str(out)]
    dry = grid_main([*command, "--dry-run"])
    said = capsys.readouterr()
    if place.startswith("/proc"):
        assert dry == 2 and str(out) in said.err
        assert grid_main(command) == 2
        assert capsys.readouterr().err.splitlines()[-1] == said.err.splitlines()[-1]
    else:
        assert dry == 0 and "0 already finished" in said.out
        assert not out.parent.exists()


@pytest.mark.slow
def test_a_dry_run_says_which_runs_resume_and_which_are_trained_afresh(
        tmp_path, tiny_spec, tiny_grid, capsys):
    """Per run still to run: resumed from its checkpoint (its epochs done), trained afresh
    (with --restart, a folder of other settings), or trained; a live holder of the grid's lock
    stops it as it stops the launch; an archive's copy counts its finished runs."""
    grid = tmp_path / "grid"
    shutil.copytree(tiny_grid, grid)
    partial = grid / RunKey("revised", "bidirectional", "APc", "fixed", 0, "B").path()
    (partial / "finished.json").unlink()
    _other_settings(grid)
    command = ["--spec", str(tiny_spec), "--out", str(grid), "--dry-run", "--restart"]
    before = _snapshot(grid)
    assert grid_main(command) == 0
    out = capsys.readouterr().out
    assert f"{partial.relative_to(grid)} (resumes after 3 of its epochs)" in out
    assert "A-fixed/seed0/C (other settings: cleared, trained afresh)" in out
    assert ("4 runs, 2 already finished, 2 to run (1 resumed, 1 of other settings, trained "
            "afresh)") in out
    assert _snapshot(grid) == before
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time; from rnn_seg.runs.lock import hold_folder\n"
        f"with hold_folder({str(grid)!r}, 'grid folder'):\n"
        "    print('held', flush=True); time.sleep(120)")],
        stdout=subprocess.PIPE, text=True, cwd=Path(__file__).resolve().parents[1])
    try:
        assert holder.stdout.readline() == "held\n"
        assert grid_main(command) == 2
        assert f"grid folder {grid} is in use by pid {holder.pid}" in capsys.readouterr().err
    finally:
        holder.kill()
        holder.wait()
    archive, copy = tmp_path / "archive", tmp_path / "copy"
    assert tables_main(["archive", str(tiny_grid), str(archive)]) == 0
    shutil.copytree(archive, copy)
    capsys.readouterr()
    assert grid_main(["--spec", str(tiny_spec), "--out", str(copy), "--dry-run"]) == 0
    assert "4 runs, 4 already finished, 0 to run" in capsys.readouterr().out
