"""Issue #29: probes a careful or hostile user would try on run folders, outputs and values.

Each probe asserts the refusal (one line naming the file or value) or the preserved file; none
only checks that nothing crashed. Tiny models on small synthetic data.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jigsaws_tools.cores import usable_cores
from jigsaws_tools.errors import DefinitionError
from jigsaws_tools.synth import SynthConfig, write_release
from jigsaws_tools.task_definition import read_task_file
from multitask.evidence.cli import main as tables_main
from multitask.grid.cli import main as grid_main
from multitask.inference.evaluate_cli import main as evaluate_main
from multitask.inference.export_cli import main as export_main
from multitask.inference.predict_cli import main as predict_main
from multitask.train_cli import main as train_main
from rnn_seg.lstm import EncoderConfig
from rnn_seg.model import SegmentationModel
from rnn_seg.optim import OptimConfig
from rnn_seg.runs.folder import RunFolderError
from rnn_seg.tasks import SoftmaxClassification
from rnn_seg.trainer import TrainConfig, Trainer
from test_stack import F, _data
from test_tasks import TOY_TASK

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "TF_CPP_MIN_LOG_LEVEL": "3"}
TINY = ["--variant", "A", "--hidden", "8", "--epochs", "2", "--no-plots"]


def _trainer(run_dir: Path, messages: list | None = None, **train) -> Trainer:
    """Six sweeps of a tiny gesture model, a history row and a checkpoint after every sweep."""
    tasks = [SoftmaxClassification("gesture", ["a", "b", "c"])]
    data = _data(0)
    log = messages.append if messages is not None else (lambda m: None)
    return Trainer(SegmentationModel(F, EncoderConfig(hidden=8), tasks, 0), tasks,
                   OptimConfig(unit="sweeps", total=6, decay_start=3, decay_every=2),
                   TrainConfig(eval_points=(6,), plots="none", monitor_every=1, **train),
                   data, data, run_dir, {}, 5.0, log=log)


def _train_until(trainer: Trainer, sweeps: int) -> None:
    """Train ``sweeps`` sweeps and stop, as if killed right after the checkpoint."""
    start = trainer.resume()
    for sweep in range(start, sweeps):
        lr = trainer.optim.learning_rate_at(sweep, trainer.sweeps_per_epoch)
        trainer.after_sweep(sweep, lr, trainer.step(sweep, lr))


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """A run trained in one go, without monitoring the training set."""
    run = tmp_path_factory.mktemp("reference") / "run"
    _trainer(run).run()
    return run


def _metrics(run: Path) -> dict:
    return json.loads((run / "metrics.json").read_text())


# -- 1. resume and the files of a run folder besides its weights -------------------------------
@pytest.mark.parametrize("before,after", [(False, True), (True, False)])
@pytest.mark.slow
def test_monitor_train_may_change_at_resume(tmp_path, reference, before, after):
    run = tmp_path / "run"
    _train_until(_trainer(run, monitor_train=before), 3)
    _trainer(run, monitor_train=after).run()
    history = pd.read_csv(run / "history.csv")
    assert list(history["sweep"]) == [1, 2, 3, 4, 5, 6]
    assert list(history.columns) == list(pd.read_csv(reference / "history.csv").columns)
    monitored = history["train_gesture_acc"].notna().tolist()
    assert monitored == [before] * 3 + [after] * 3
    pd.testing.assert_series_equal(history["test_gesture_acc"],
                                   pd.read_csv(reference / "history.csv")["test_gesture_acc"])
    assert _metrics(run) == _metrics(reference)


def test_a_history_of_an_older_version_gets_the_new_columns_empty(tmp_path, reference):
    run = tmp_path / "run"
    _train_until(_trainer(run), 3)
    old = pd.read_csv(run / "history.csv").dropna(axis=1, how="all")   # no train_ columns
    old.to_csv(run / "history.csv", index=False)
    messages = []
    _trainer(run, messages).run()
    assert any("added the columns train_gesture_acc" in m for m in messages), messages
    assert list(pd.read_csv(run / "history.csv")["sweep"]) == [1, 2, 3, 4, 5, 6]
    assert _metrics(run) == _metrics(reference)


def test_resume_leaves_other_csv_files_alone(tmp_path):
    """A prediction CSV (``multitask-predict --out RUN``) and a user's CSV with a ``sweep``
    column are neither read nor cut back."""
    run = tmp_path / "run"
    _train_until(_trainer(run), 3)
    mine = {"notes.csv": "sweep,comment\n1,ok\n5,later\n", "Suturing_B001.csv": "frame,g\n0,G1\n"}
    for name, text in mine.items():
        (run / name).write_text(text)
    _trainer(run).run()
    assert all((run / name).read_text() == text for name, text in mine.items())


def test_a_torn_last_history_row_is_dropped_with_a_warning(tmp_path, reference):
    run = tmp_path / "run"
    _train_until(_trainer(run), 3)
    with open(run / "history.csv", "a") as history:
        history.write("sweeps,4.0,4,1.0,0.9")            # killed while appending
    messages = []
    _trainer(run, messages).run()
    assert any("history.csv: dropped its last line" in m for m in messages), messages
    assert _metrics(run) == _metrics(reference)


def test_an_empty_history_of_a_checkpointed_run_is_one_line_naming_it(tmp_path):
    run = tmp_path / "run"
    _train_until(_trainer(run), 3)
    (run / "history.csv").write_text("")
    with pytest.raises(RunFolderError, match=r"history\.csv: empty.*sweep 3.*--restart"):
        _trainer(run).run()
    assert (run / "history.csv").read_text() == ""                # reported, not rewritten


def test_a_history_with_a_garbled_header_is_one_line_naming_it(tmp_path):
    run = tmp_path / "run"
    _train_until(_trainer(run), 3)
    text = (run / "history.csv").read_text()
    (run / "history.csv").write_text("\0\0\0" + text)
    with pytest.raises(RunFolderError, match=r"history\.csv: .*unknown column '\\x00"):
        _trainer(run).run()
    assert (run / "history.csv").read_text() == "\0\0\0" + text


def test_a_malformed_history_row_is_one_line_naming_the_line(tmp_path):
    run = tmp_path / "run"
    _train_until(_trainer(run), 3)
    lines = (run / "history.csv").read_text().splitlines(keepends=True)
    lines[2] = lines[2].replace(",2,", ",two,", 1)
    (run / "history.csv").write_text("".join(lines))
    with pytest.raises(RunFolderError, match=r"history\.csv: line 3: sweep .*'two'"):
        _trainer(run).run()


def test_an_interrupted_evaluation_folder_does_not_stop_a_resume(tmp_path, reference):
    """``multitask-evaluate`` stages its output in a hidden ``evaluate/.NAME.XXXXXXXX.tmp``
    folder; a resume (even of a finished run) removes it instead of failing on it."""
    run = tmp_path / "run"
    _train_until(_trainer(run), 3)
    staging = run / "evaluate" / ".ckpt-6_B.k2j_8x0q.tmp"
    (staging / "predictions").mkdir(parents=True)
    (staging / "predictions" / "s0.csv").write_text("partial")
    _trainer(run).run()
    assert not staging.exists() and _metrics(run) == _metrics(reference)


def test_only_the_runs_own_temporary_files_are_removed(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    users = [run / "notes" / "draft.tmp", run / "scratch.tmp", run / ".mine.abcdef12.tmp"]
    for path in users:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("the user's")
    ours = run / ".metrics.json.1a2b3c4d.tmp"
    ours.write_text("partial")
    messages = []
    _trainer(run, messages).run()
    assert all(p.read_text() == "the user's" for p in users)
    assert not ours.exists()
    assert any("removed 1 temporary file(s)" in m for m in messages), messages


def test_restart_deletes_only_the_runs_own_files(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    mine = {"results.csv": "a,b\n1,2\n", "notes/todo.txt": "keep"}
    for name, text in mine.items():
        (run / name).parent.mkdir(parents=True, exist_ok=True)
        (run / name).write_text(text)
    _trainer(run).run(restart=True)
    _trainer(run).run(restart=True)
    assert all((run / name).read_text() == text for name, text in mine.items())
    assert (run / "finished.json").is_file()


def test_a_symlinked_output_of_a_run_is_unlinked_not_followed_by_restart(tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "precious.txt").write_text("keep")
    run = tmp_path / "run"
    run.mkdir()
    (run / "eval").symlink_to(elsewhere, target_is_directory=True)
    _trainer(run).run(restart=True)
    assert (elsewhere / "precious.txt").read_text() == "keep"
    assert np.isfinite(_metrics(run)["mean"]["gesture"]["accuracy"])


# -- 2. nothing deleted that the user did not ask to delete -------------------------------------
@pytest.fixture(scope="module")
def small_dir(tmp_path_factory) -> Path:
    return write_release(tmp_path_factory.mktemp("small") / "Suturing",
                         SynthConfig(users=("B", "C", "D"), trials_per_user=3))


@pytest.fixture(scope="module")
def trained(small_dir, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("trained") / "run"
    assert train_main([*TINY, "--data-dir", str(small_dir), "--test-user", "B",
                       "--out", str(out)]) == 0
    return out


def _cli(main, argv: list[str], capsys) -> tuple[int, str]:
    """Exit code and standard error of a command."""
    try:
        code = main(argv)
    except SystemExit as exit_:
        code = exit_.code
    return code, capsys.readouterr().err


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != ".lock"}


def _refused(code: int, err: str, *named: str) -> None:
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert all(text in err for text in named), (named, err)


@pytest.mark.parametrize("command,out", [(export_main, "."), (evaluate_main, "."),
                                         (evaluate_main, "eval"), (evaluate_main, "checkpoints"),
                                         (export_main, "..")])
def test_overwrite_cannot_replace_a_run_or_its_files(trained, capsys, command, out):
    before = _snapshot(trained.parent)
    code, err = _cli(command, [str(trained), "--out", str(trained / out), "--overwrite"], capsys)
    _refused(code, err, str(trained))
    assert _snapshot(trained.parent) == before


def test_overwrite_replaces_an_earlier_output_of_the_same_command_only(trained, tmp_path,
                                                                        capsys):
    out = tmp_path / "evaluation"
    assert evaluate_main([str(trained), "--out", str(out), "--no-plots"]) == 0
    assert evaluate_main([str(trained), "--out", str(out), "--no-plots", "--overwrite"]) == 0
    (out / "notes.txt").write_text("mine")
    before = _snapshot(out)
    code, err = _cli(evaluate_main, [str(trained), "--out", str(out), "--overwrite"], capsys)
    _refused(code, err, "'notes.txt'", "not an output of multitask-evaluate")
    assert _snapshot(out) == before
    default = trained / "evaluate"
    assert evaluate_main([str(trained), "--no-plots"]) == 0          # RUN/evaluate/ is its place
    assert evaluate_main([str(trained), "--no-plots", "--overwrite"]) == 0
    assert len(list(default.iterdir())) == 1


@pytest.mark.slow
def test_an_export_is_replaced_by_the_next_and_is_not_taken_for_a_run(trained, small_dir,
                                                                     tmp_path, capsys):
    """A SavedModel holds a copy of its run's config.json: a folder holding one is not taken for
    a folder of runs, so a training there is not refused for it."""
    holder = tmp_path / "holder"
    out = holder / "export"
    assert export_main([str(trained), "--out", str(out)]) == 0
    assert export_main([str(trained), "--out", str(out), "--overwrite"]) == 0
    code, err = _cli(train_main, [*TINY, "--data-dir", str(small_dir), "--test-user", "B",
                                  "--out", str(holder)], capsys)
    assert code == 0 and "Traceback" not in err, err
    assert (out / "saved_model.pb").is_file()


def test_a_project_folder_with_a_config_json_of_its_own_is_no_run(tmp_path):
    """Folders above an output count as runs or grids by their records, not by the names of
    their files: a project's own config.json and checkpoints/ do not block its subfolders."""
    from rnn_seg.runs.outputs import check_output_folder

    (tmp_path / "config.json").write_text(json.dumps({"lr": 0.1}))
    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "grid.json").write_text("{}")
    for command in ("multitask-train", "multitask-predict"):
        check_output_folder(tmp_path / "experiments" / "run1", command, may_be_run=True)


def _writing_to(command: str, out: str, trained: Path, grid: Path, small_dir: Path) -> tuple:
    """``(main, argv)`` of ``command`` writing its output to ``out``."""
    recording = next((small_dir / "kinematics" / "AllGestures").glob("*.txt"))
    return {"export": (export_main, [str(trained), "--out", out]),
            "predict": (predict_main, [str(trained), str(recording), "--out", out]),
            "tables": (tables_main, ["paper", str(grid), "--out", out, "--no-figures"]),
            "train": (train_main, [*TINY, "--data-dir", str(small_dir), "--out", out])}[command]


@pytest.mark.parametrize("command", ["export", "predict", "tables", "train"])
@pytest.mark.slow
def test_nothing_but_an_evaluation_writes_inside_a_run(trained, tiny_grid, small_dir, capsys,
                                                       command):
    """A folder inside a run (not one of the run's own names) is refused before any work, as
    the run's own files are: only multitask-evaluate writes into a run, under RUN/evaluate."""
    out = str(trained / "mine")
    before = _snapshot(trained)
    code, err = _cli(*_writing_to(command, out, trained, tiny_grid, small_dir), capsys)
    _refused(code, err, out, f"inside the run folder {trained}")
    assert _snapshot(trained) == before


@pytest.mark.parametrize("command", ["predict", "tables", "train"])
def test_nothing_writes_among_a_grids_runs(trained, tiny_grid, small_dir, tmp_path, capsys,
                                           command):
    """A grid's runs/ is multitask-grid's: a folder there would be a stray run of its tables."""
    grid = _copy_grid(tiny_grid, tmp_path / "grid")
    out = str(grid / "runs" / "mine")
    before = _snapshot(grid)
    code, err = _cli(*_writing_to(command, out, trained, grid, small_dir), capsys)
    _refused(code, err, out, f"among the runs of the grid folder {grid}")
    assert _snapshot(grid) == before


def test_predict_does_not_write_into_a_run_folder(trained, small_dir, capsys):
    before = _snapshot(trained)
    recording = next((small_dir / "kinematics" / "AllGestures").glob("*.txt"))
    code, err = _cli(predict_main, [str(trained), str(recording), "--out", str(trained)], capsys)
    _refused(code, err, str(trained), "run folder")
    assert _snapshot(trained) == before


@pytest.mark.parametrize("marker", ["grid.json", "runs/A/seed0/B/config.json"])
def test_training_refuses_a_grid_root_or_a_folder_of_runs(small_dir, tmp_path, capsys, marker):
    root = tmp_path / "grid"
    (root / marker).parent.mkdir(parents=True, exist_ok=True)
    (root / marker).write_text("{}")
    before = _snapshot(root)
    code, err = _cli(train_main, [*TINY, "--data-dir", str(small_dir), "--test-user", "B",
                                  "--out", str(root)], capsys)
    _refused(code, err, str(root))
    assert _snapshot(root) == before


@pytest.mark.parametrize("place", ["run", "inside", "holder"])
@pytest.mark.slow
def test_a_grid_writes_only_into_a_new_folder_or_its_own_grid(trained, tmp_path, capsys, place):
    """``multitask-grid --out``: a run folder, a place among a run's files, or a folder of the
    user's runs is refused before any work; the grid's own folder is resumed (tiny_grid)."""
    holder = tmp_path / "mine"
    shutil.copytree(trained, holder / "run")
    out = {"run": holder / "run", "inside": holder / "run" / "eval" / "grid", "holder": holder}
    before = _snapshot(holder)
    code, err = _cli(grid_main, ["--spec", str(ROOT / "results" / "smoke.toml"),
                                 "--out", str(out[place])], capsys)
    _refused(code, err, str(holder / "run"))
    assert _snapshot(holder) == before


def test_tables_never_write_over_a_file_they_did_not_write(tiny_grid, tmp_path, capsys):
    """--out may hold your files: one of a table's names is refused (nothing written) until
    --overwrite; the tables' own files, listed in tables.json, are replaced by the next call."""
    out = tmp_path / "paper"
    out.mkdir()
    (out / "runs.csv").write_text("mine")
    (out / "notes.txt").write_text("mine")
    before = _snapshot(out)
    code, err = _cli(tables_main, ["paper", str(tiny_grid), "--out", str(out), "--no-figures"],
                     capsys)
    _refused(code, err, f"{out / 'runs.csv'} exists and is not an output of multitask-tables")
    assert _snapshot(out) == before
    assert tables_main(["paper", str(tiny_grid), "--out", str(out), "--no-figures",
                        "--overwrite"]) == 0
    assert tables_main(["paper", str(tiny_grid), "--out", str(out), "--no-figures"]) == 0
    assert tables_main(["paper", str(tiny_grid), "--out", str(tmp_path / "fresh"),
                        "--no-figures"]) == 0
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "runs.csv").read_bytes() == (tmp_path / "fresh" / "runs.csv").read_bytes()


def test_tables_of_a_mistyped_grid_name_the_missing_folder(tmp_path, capsys):
    out = tmp_path / "tables"
    code, err = _cli(tables_main, ["paper", str(tmp_path / "gird"), "--out", str(out)], capsys)
    _refused(code, err, f"{tmp_path / 'gird'}: no such folder")
    assert not out.exists()


def test_tables_refuse_a_run_folder_and_write_beside_grids(tiny_grid, trained, tmp_path, capsys):
    before = _snapshot(trained)
    code, err = _cli(tables_main, ["paper", str(tiny_grid), "--out", str(trained), "--no-figures"],
                     capsys)
    _refused(code, err, str(trained), "run folder")
    assert _snapshot(trained) == before
    beside = tmp_path / "results"
    _copy_grid(tiny_grid, beside / "grid")
    assert tables_main(["paper", str(beside / "grid"), "--out", str(beside), "--no-figures"]) == 0
    assert (beside / "runs.csv").is_file()


@pytest.mark.slow
def test_an_evaluation_the_disk_refuses_is_one_line_and_exit_1(trained, tmp_path):
    """A file size limit refuses the evaluation's files: a failure (exit 1) naming the file and
    the space left, not a usage error (2); nothing left that looks finished."""
    out = tmp_path / "evaluation"
    limited = ("import resource, sys; resource.setrlimit(resource.RLIMIT_FSIZE, (200, 200)); "
               "from multitask.inference.evaluate_cli import main; sys.exit(main(sys.argv[1:]))")
    done = subprocess.run([sys.executable, "-c", limited, str(trained), "--out", str(out),
                           "--no-plots"], env=ENV, capture_output=True, text=True, timeout=600)
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "failed: cannot write" in lines[0] and "MB free" in lines[0]
    assert not out.exists()


def test_thread_counts_beyond_the_usable_cores_are_refused_by_the_python_api(monkeypatch):
    from rnn_seg.threads import configure_threads

    with pytest.raises(ValueError, match="this process may use"):
        configure_threads(usable_cores() + 1, hidden=8)
    with pytest.raises(ValueError, match="got -1"):
        configure_threads(-1, hidden=8)
    if hasattr(os, "sched_getaffinity"):                   # one core given, as a batch job may
        monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})
        with pytest.raises(ValueError, match="up to the 1 this process may use, got 2"):
            configure_threads(2, hidden=8)


# -- 4. writes outside the folder named, and values nobody checked ------------------------------
def test_a_lock_file_symlinked_elsewhere_is_refused_not_followed(small_dir, tmp_path, capsys):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    run = tmp_path / "run"
    run.mkdir()
    (run / ".lock").symlink_to(victim)
    code, err = _cli(train_main, [*TINY, "--data-dir", str(small_dir), "--test-user", "B",
                                  "--out", str(run)], capsys)
    _refused(code, err, str(run / ".lock"), "symbolic link")
    assert victim.read_text() == "precious"


def test_a_grid_record_cannot_lead_an_archive_outside_its_destination(tmp_path, capsys):
    grid = tmp_path / "grid"
    escaped = tmp_path / "escaped"               # a finished run folder outside the grid
    escaped.mkdir()
    for name in ("config.json", "metrics.json", "finished.json"):
        (escaped / name).write_text("{}")
    grid.mkdir()
    (grid / "grid.json").write_text(json.dumps({"runs": ["runs/../../escaped"]}))
    dest = tmp_path / "archives" / "a"
    code, err = _cli(tables_main, ["archive", str(grid), str(dest)], capsys)
    _refused(code, err, str(grid / "grid.json"), "runs/../../escaped")
    assert not (tmp_path / "archives").exists() or not any((tmp_path / "archives").rglob("*"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["escaped", "grid"]


def test_thread_counts_are_bounded_by_the_usable_cores(small_dir, tmp_path, capsys):
    code, err = _cli(train_main, [*TINY, "--data-dir", str(small_dir), "--threads", "100000",
                                  "--out", str(tmp_path / "run")], capsys)
    last = err.strip().splitlines()[-1]                 # argparse's usage, then the error
    assert code == 2 and "Traceback" not in err
    assert last.startswith("multitask-train: error: argument --threads:") and all(
        text in last for text in (f"the {usable_cores()} core", "this process may use",
                                  "'100000'")), err
    assert not (tmp_path / "run").exists()


def test_grid_threads_are_bounded_by_the_usable_cores_only_when_it_trains_them(small_dir,
                                                                              tmp_path, capsys):
    """Locally, more threads than cores is one line before any work; with ``--scheduler`` the
    runs train on the cluster's workers, so the head node's cores do not bound the count."""
    spec = ["--spec", str(ROOT / "results" / "smoke.toml"), "--data-dir", str(small_dir),
            "--threads", "100000"]
    code, err = _cli(grid_main, [*spec, "--out", str(tmp_path / "local")], capsys)
    _refused(code, err, "--threads", f"the {usable_cores()} core", "'100000'")
    assert not (tmp_path / "local").exists()
    code, err = _cli(grid_main, [*spec, "--scheduler", "tcp://head:8786", "--dry-run",
                                 "--out", str(tmp_path / "cluster")], capsys)
    assert code == 0 and "Traceback" not in err, err


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity") or usable_cores() < 2,
                    reason="needs CPU affinity and two cores")
def test_counts_are_bounded_by_the_cores_the_process_may_use_not_the_machine_s(tmp_path):
    """A batch job or ``taskset`` gives a process fewer cores than the machine has: its thread
    and worker counts are bounded by those (0 = all of those), not by ``os.cpu_count()``."""
    one_core = {min(os.sched_getaffinity(0))}
    script = ("import os, sys\n"
              f"os.sched_setaffinity(0, {one_core!r})\n"
              "from jigsaws_tools.cores import usable_cores\n"
              "from multitask.grid.cli import main\n"
              "print(usable_cores(), os.cpu_count() > 1, flush=True)\n"
              "sys.exit(main(sys.argv[1:]))\n")
    spec = ROOT / "results" / "smoke.toml"
    result = subprocess.run([sys.executable, "-c", script, "--spec", str(spec), "--out",
                             str(tmp_path / "g"), "--workers", "2", "--dry-run"],
                            capture_output=True, text=True, env=ENV)
    assert result.stdout.split() == ["1", "True"]
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "--workers: expected at most the 1 core this process may use, got '2'" in (
        result.stderr), result.stderr
    assert not (tmp_path / "g").exists()


def test_a_trial_too_short_for_the_filter_is_named_with_the_minimum(tmp_path, capsys):
    data = write_release(tmp_path / "Suturing", SynthConfig(users=("B", "C", "D"),
                                                            trials_per_user=2))
    kinematics = data / "kinematics" / "AllGestures" / "Suturing_C002.txt"
    kinematics.write_text("".join(kinematics.read_text().splitlines(keepends=True)[:10]))
    (data / "transcriptions" / "Suturing_C002.txt").write_bytes(b"1 10 G1 \r\n")
    code, err = _cli(train_main, [*TINY, "--data-dir", str(data), "--test-user", "B",
                                  "--out", str(tmp_path / "run")], capsys)
    _refused(code, err, "Suturing_C002", "10 frames", "the 16 ")


@pytest.mark.parametrize("weights", ["[nan, 1]", "[inf, 1]", "[1, -inf]"])
def test_task_file_weights_must_be_finite_and_positive(tmp_path, weights):
    path = tmp_path / "task.toml"
    path.write_text(TOY_TASK.replace('{ gesture = "A", p = 0.6 }',
                                     f'{{ gesture = ["A", "C"], weights = {weights}, p = 0.6 }}'))
    with pytest.raises(DefinitionError, match="synthetic.cycle.3..weights") as error:
        read_task_file(path)
    assert str(path) in str(error.value)


def test_an_interrupted_synth_leaves_no_release_and_can_write_again(tmp_path, monkeypatch):
    import jigsaws_tools.synth as synth

    out = tmp_path / "Suturing"
    real, calls = synth.synth_trial, []

    def killed(*args):
        calls.append(args)
        if len(calls) == 3:
            raise KeyboardInterrupt                 # as a kill in the middle of the users
        return real(*args)

    monkeypatch.setattr(synth, "synth_trial", killed)
    with pytest.raises(KeyboardInterrupt):
        write_release(out, SynthConfig(users=("B", "C", "D"), trials_per_user=2))
    assert not out.exists() and not list(tmp_path.iterdir())
    monkeypatch.setattr(synth, "synth_trial", real)
    write_release(out, SynthConfig(users=("B", "C", "D"), trials_per_user=2))
    assert len(list((out / "kinematics" / "AllGestures").iterdir())) == 6


def test_an_edited_synthetic_cache_is_detected_and_written_again(tmp_path, caplog):
    from jigsaws_tools.synth import ensure_release

    config = SynthConfig(seed=5, users=("B", "C"), trials_per_user=1)
    release = ensure_release(tmp_path, config)
    edited = release / "transcriptions" / "Suturing_B001.txt"
    original = edited.read_bytes()
    edited.write_bytes(original.replace(b"G1", b"G2", 1))
    with caplog.at_level("WARNING"):
        assert ensure_release(tmp_path, config) == release
    assert "Suturing_B001.txt changed" in caplog.text
    assert edited.read_bytes() == original
    assert sorted(p.name for p in tmp_path.iterdir()) == [release.parent.name]


def test_the_python_api_refuses_a_non_finite_recording(trained, small_dir):
    from jigsaws_tools.release import read_kinematics
    from multitask.inference.trained_run import load_run

    run = load_run(trained)
    kinematics = read_kinematics(next((small_dir / "kinematics" / "AllGestures").iterdir()))
    kinematics[7, 3] = np.nan
    with pytest.raises(ValueError, match=r"mine: frame 8, column 4: non-finite"):
        run.predict(kinematics, where="mine")
    kinematics[7, 3] = 1e39                 # finite, but infinite in the models' float32
    with pytest.raises(ValueError, match=r"mine: frame 8, column 4: kinematic value beyond "
                                         r"float32's range .* \(1e\+39\)"):
        run.predict(kinematics, where="mine")


@pytest.mark.parametrize("std,problem", [(float("nan"), "NaN is not strict JSON"),
                                         (-1.0, "std -1.0: expected finite values")])
def test_stream_normalisation_with_a_bad_std_is_refused(trained, std, problem):
    from multitask.inference.trained_run import load_run

    path = trained / "stream_normalisation.json"
    path.write_text(json.dumps({"normalisation": {"mean": [0.0, 0.0], "std": [1.0, std]}}))
    try:
        with pytest.raises(ValueError, match=r"stream_normalisation\.json.*" + problem):
            load_run(trained).stream_normalisation()
    finally:
        path.unlink()


@pytest.mark.slow
def test_a_checkpoint_that_does_not_fit_is_one_line_and_the_run_resumes(small_dir, tmp_path):
    """A file size limit (``ulimit -f``) refuses the first checkpoint: one line naming it and
    the space left, exit 1; without the limit the same command finishes the run."""
    out = tmp_path / "run"
    argv = ["--variant", "A", "--hidden", "64", "--epochs", "2", "--no-plots", "--data-dir",
            str(small_dir), "--test-user", "B", "--out", str(out)]
    limited = ("import resource, sys; resource.setrlimit(resource.RLIMIT_FSIZE, (60000, 60000)); "
               "from multitask.train_cli import main; sys.exit(main(sys.argv[1:]))")
    done = subprocess.run([sys.executable, "-c", limited, *argv], env=ENV, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    failed = [line for line in done.stderr.splitlines() if "failed" in line]
    assert len(failed) == 1 and "cannot write checkpoint" in failed[0] and "MB free" in failed[0]
    assert not (out / "finished.json").exists()
    assert train_main(argv) == 0 and (out / "finished.json").is_file()


# -- 3. tables that check what they tabulate ----------------------------------------------------
GRID = """
preset = "quick"
data_dir = "{data}"
test_users = ["B", "C"]
seeds = [0]
hidden = 8
epochs = 2

[[experiments]]
variants = ["A", "APc"]
"""


@pytest.fixture(scope="module")
def tiny_grid(small_dir, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("grid")
    (folder / "spec.toml").write_text(GRID.format(data=small_dir))
    assert grid_main(["--spec", str(folder / "spec.toml"), "--out", str(folder / "out"),
                      "--workers", "0"]) == 0
    return folder / "out"


def _copy_grid(grid: Path, to: Path) -> Path:
    shutil.copytree(grid, to, ignore=shutil.ignore_patterns("checkpoints", ".lock"))
    return to


def _run(grid: Path, variant: str, fold: str) -> Path:
    return grid / "runs" / "revised" / "bidirectional" / f"{variant}-fixed" / "seed0" / fold


@pytest.mark.slow
def test_tables_of_the_grid_as_trained(tiny_grid, tmp_path, capsys):
    code, err = _cli(tables_main, ["paper", str(tiny_grid), "--out", str(tmp_path / "tables"),
                                   "--no-figures"], capsys)
    assert code == 0, err
    assert len(pd.read_csv(tmp_path / "tables" / "runs.csv")) == 4


def test_tables_refuse_a_run_folder_retrained_by_hand_with_other_settings(
        tiny_grid, small_dir, tmp_path, capsys):
    """A run retrained with other settings by hand (training refuses a grid's runs/, so it is
    trained beside the grid and moved in)."""
    grid = _copy_grid(tiny_grid, tmp_path / "grid")
    retrained = _run(grid, "A", "C")
    by_hand = tmp_path / "by_hand"
    assert train_main([*TINY, "--hidden", "12", "--data-dir", str(small_dir), "--test-user", "C",
                       "--out", str(by_hand)]) == 0
    shutil.rmtree(retrained)
    by_hand.rename(retrained)
    code, err = _cli(tables_main, ["paper", str(grid), "--out", str(tmp_path / "tables")], capsys)
    assert code == 2 and "Traceback" not in err
    assert f"other settings than the grid's spec: {retrained}" in err
    assert "run.encoder.hidden: 12 -> 8" in err
    assert not (tmp_path / "tables").exists()


def test_tables_refuse_a_run_copied_into_another_configurations_folder(tiny_grid, tmp_path,
                                                                       capsys):
    grid = _copy_grid(tiny_grid, tmp_path / "grid")
    target = _run(grid, "APc", "B")
    shutil.rmtree(target)
    shutil.copytree(_run(grid, "A", "B"), target)
    code, err = _cli(tables_main, ["paper", str(grid), "--out", str(tmp_path / "tables")], capsys)
    assert code == 2 and f"other settings than the grid's spec: {target}" in err
    assert 'variant: "A" -> "APc"' in err


def test_allow_incomplete_leaves_a_run_of_other_settings_out_and_marks_it(tiny_grid, tmp_path,
                                                                           capsys):
    grid = _copy_grid(tiny_grid, tmp_path / "grid")
    target = _run(grid, "A", "C")
    shutil.rmtree(target)
    shutil.copytree(_run(grid, "A", "B"), target)             # fold B's run as fold C's
    code, err = _cli(tables_main, ["paper", str(grid), "--out", str(tmp_path / "tables"),
                                   "--allow-incomplete", "--no-figures"], capsys)
    assert code == 0 and 'run.test_user: "B" -> "C"' in err, err
    runs = pd.read_csv(tmp_path / "tables" / "runs.csv")
    assert sorted(zip(runs["variant"], runs["fold"])) == [("A", "B"), ("APc", "B"), ("APc", "C")]
    summary = pd.read_csv(tmp_path / "tables" / "summary.csv").set_index("variant")
    assert not summary.loc["A", "complete"] and summary.loc["APc", "complete"]


@pytest.mark.slow
def test_figures_never_read_a_run_folder_the_tables_left_out(tiny_grid, tmp_path, capsys):
    grid = _copy_grid(tiny_grid, tmp_path / "grid")
    target = _run(grid, "APc", "B")
    shutil.rmtree(target)
    shutil.copytree(_run(grid, "A", "B"), target)             # model A's run as APc's
    out = tmp_path / "tables"
    code, err = _cli(tables_main, ["paper", str(grid), "--out", str(out), "--allow-incomplete",
                                   "--curves"], capsys)
    assert code == 0 and "Traceback" not in err, err
    assert "no example-trial, GradNorm-weight or training-curve figures" in err
    drawn = {path.stem for path in (out / "figures").glob("*.png")}
    assert not drawn & {"segmentation_example", "progress_example", "gradnorm_weights"}
    assert not (out / "figures" / "curves").exists()
    assert "per_gesture_accuracy" in drawn                    # from the checked table


@pytest.mark.parametrize("text", ["{}", "[1, 2]", '{"run": 3}', "{"])
def test_a_malformed_config_of_a_grid_run_is_one_line_naming_it(tiny_grid, tmp_path, capsys,
                                                                text):
    grid = _copy_grid(tiny_grid, tmp_path / "grid")
    config = _run(grid, "A", "B") / "config.json"
    config.write_text(text)
    code, err = _cli(tables_main, ["paper", str(grid), "--out", str(tmp_path / "tables")], capsys)
    assert code == 2 and "Traceback" not in err and str(config.parent) in err, err


def test_a_malformed_history_read_back_for_the_curves_is_one_line_naming_it(tiny_grid, tmp_path,
                                                                            capsys):
    grid = _copy_grid(tiny_grid, tmp_path / "grid")
    history = _run(grid, "APc", "C") / "history.csv"
    history.write_text(history.read_text() + ",".join(["9"] * 40) + "\n")   # 40 fields
    code, err = _cli(tables_main, ["paper", str(grid), "--out", str(tmp_path / "tables"),
                                   "--no-figures", "--curves"], capsys)
    _refused(code, err, f"{history}: unreadable CSV log")
