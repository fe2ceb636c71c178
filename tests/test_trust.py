"""Issue #16, engine and grid side: each numbered case of items 1-4 and 6, replayed.

Every case ends in a clear error (non-zero exit, no traceback, the culprit named) or in a correct
recovery; none exits 0 with wrong or partial results. Tiny models on a small synthetic release.
"""
from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tensorflow as tf

from baseline.builder import build_trainer, gesture_task
from baseline.cli import main as baseline_main
from baseline.config import RunConfig
from jigsaws_tools.cli.common import run_command
from jigsaws_tools.dataset import DataConfig
from jigsaws_tools.errors import WriteFailed
from jigsaws_tools.synth import SynthConfig, write_release
from multitask.grid.cli import main as grid_main
from multitask.grid.folder import run_key
from multitask.grid.record import prepare_grid
from multitask.grid.spec import expand, load_spec, with_budget
from multitask.evidence.cli import main as tables_main
from multitask.train_cli import main as multitask_main
from rnn_seg.runs.checkpoints import (CheckpointStore, checkpoint_prefix, checkpoint_sweeps,
                                      restore_weights)
from rnn_seg.runs import lock
from rnn_seg.runs.lock import hold_folder
from rnn_seg.lstm import EncoderConfig
from rnn_seg.model import SegmentationModel
from rnn_seg.optim import OptimConfig
from rnn_seg.runs.provenance import cpu_model
from rnn_seg.runs.folder import RunFolderError, read_json, write_atomic, write_json
from rnn_seg.stack import TrainerStack
from rnn_seg.tasks import SoftmaxClassification
from rnn_seg.trainer import TrainConfig, Trainer, TrainingDiverged
from test_stack import F, _data, _trainer, _weights
from tests.fake_grid import write_fake_run

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "TF_CPP_MIN_LOG_LEVEL": "3"}
TINY = ["--variant", "A", "--hidden", "8", "--epochs", "2", "--no-plots"]


@pytest.fixture(scope="module")
def small_dir(tmp_path_factory) -> Path:
    """Three users x three trials: a fold trains on 6 trials, 2 sweeps per epoch."""
    return write_release(tmp_path_factory.mktemp("small") / "Suturing",
                         SynthConfig(users=("B", "C", "D"), trials_per_user=3))


def _cli(main, argv: list[str], capsys) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of a CLI's ``main`` (argparse errors exit via SystemExit)."""
    try:
        code = main(argv)
    except SystemExit as exit_:
        code = exit_.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _assert_clean_error(code: int, err: str, *named: str) -> None:
    assert code != 0 and "Traceback" not in err, err
    for text in named:
        assert text in err, (text, err)


def _strict(path: Path):
    def reject(constant):
        raise ValueError(f"{path}: {constant}")
    return json.loads(path.read_text(), parse_constant=reject)


# -- 1. a run folder always matches its weights -----------------------------------------------
@pytest.fixture(scope="module")
def finished_run(small_dir, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("run") / "x"
    assert multitask_main([*TINY, "--data-dir", str(small_dir), "--test-user", "B",
                           "--keep-checkpoints", "eval_points", "--eval-at", "1,2",
                           "--out", str(out)]) == 0
    return out


def _snapshot(run: Path) -> dict[str, bytes]:
    return {str(p.relative_to(run)): p.read_bytes() for p in sorted(run.rglob("*"))
            if p.is_file() and p.name != ".lock"}


@pytest.mark.slow
def test_relaunch_with_other_settings_stops_before_any_work(finished_run, small_dir, capsys):
    before = _snapshot(finished_run)
    code, out, err = _cli(multitask_main, [*TINY, "--data-dir", str(small_dir), "--test-user",
                                           "C", "--lr", "0.1", "--out", str(finished_run)], capsys)
    _assert_clean_error(code, err, str(finished_run), 'run.test_user: "B" -> "C"',
                        "run.optim.learning_rate: 1.0 -> 0.1", "--restart")
    assert "done" not in out
    assert _snapshot(finished_run) == before           # config.json and results untouched


@pytest.mark.slow
def test_unfinished_run_relaunched_for_another_fold_does_not_resume(small_dir, tmp_path, capsys):
    """The test user must never leak into training through another fold's weights."""
    out = tmp_path / "x"
    assert multitask_main([*TINY, "--data-dir", str(small_dir), "--test-user", "B",
                           "--out", str(out)]) == 0
    (out / "finished.json").unlink()                  # as if killed before the end
    before = _snapshot(out)
    code, _, err = _cli(multitask_main, [*TINY, "--data-dir", str(small_dir), "--test-user", "C",
                                         "--out", str(out)], capsys)
    _assert_clean_error(code, err, 'run.test_user: "B" -> "C"')
    assert _snapshot(out) == before


@pytest.mark.slow
def test_restart_trains_afresh_and_output_settings_may_change(small_dir, tmp_path, capsys):
    out = tmp_path / "x"
    assert multitask_main([*TINY, "--data-dir", str(small_dir), "--test-user", "B",
                           "--out", str(out)]) == 0
    # plots / checkpoint keeping are output settings: the finished run is simply reported
    code, stdout, _ = _cli(multitask_main, [*TINY[:-1], "--data-dir", str(small_dir),
                                            "--test-user", "B", "--out", str(out)], capsys)
    assert code == 0 and "already finished" in stdout
    code, _, _ = _cli(multitask_main, [*TINY, "--data-dir", str(small_dir), "--test-user", "C",
                                       "--restart", "--out", str(out)], capsys)
    assert code == 0
    config = _strict(out / "config.json")
    assert config["run"]["test_user"] == "C"
    predictions = sorted(p.stem for p in (out / "eval/epoch0002/predictions").glob("*.csv"))
    assert predictions == [f"Suturing_C00{i}" for i in (1, 2, 3)]


@pytest.mark.slow
def test_changed_data_is_a_changed_setting(small_dir, tmp_path, capsys):
    data = shutil.copytree(small_dir, tmp_path / "Suturing")
    out = tmp_path / "x"
    argv = [*TINY, "--data-dir", str(data), "--out", str(out)]
    assert multitask_main(argv) == 0
    capsys.readouterr()
    kinematics = data / "kinematics/AllGestures/Suturing_C001.txt"
    lines = kinematics.read_text().splitlines(keepends=True)
    kinematics.write_text("".join(lines[1:] + lines[:1]))     # same size, other content
    code, _, err = _cli(multitask_main, argv, capsys)
    _assert_clean_error(code, err, "data_fingerprint:")


@pytest.mark.slow
def test_the_same_data_at_another_path_is_the_same_setting(finished_run, small_dir, tmp_path,
                                                           capsys):
    """The fingerprint holds the data; its folder (moved, a relative path) is not a setting."""
    moved = shutil.copytree(small_dir, tmp_path / "elsewhere" / "Suturing")
    before = _snapshot(finished_run)
    code, out, err = _cli(multitask_main, [*TINY, "--data-dir", str(moved), "--test-user", "B",
                                           "--keep-checkpoints", "eval_points", "--eval-at", "1,2",
                                           "--out", str(finished_run)], capsys)
    assert code == 0 and "already finished" in out, err
    assert _snapshot(finished_run) == before


@pytest.mark.slow
def test_settings_hash_in_config_checkpoints_and_finished(finished_run):
    config = _strict(finished_run / "config.json")
    finished = _strict(finished_run / "finished.json")
    assert {"run", "tasks", "variant", "weighting"} <= set(config)        # existing layout kept
    assert config["settings_hash"] == finished["settings_hash"]
    sweeps = finished["sweeps"]
    reader = tf.train.load_checkpoint(str(checkpoint_prefix(finished_run, sweeps)))
    assert reader.get_tensor("settings/.ATTRIBUTES/VARIABLE_VALUE").decode() == \
        config["settings_hash"]


def test_trainer_constructor_writes_nothing(small_dir, tmp_path):
    config = RunConfig(DataConfig(str(small_dir)), encoder=EncoderConfig(hidden=8),
                       optim=OptimConfig(total=1), train=TrainConfig(eval_points=()))
    build_trainer(config, [gesture_task()], tmp_path / "run", log=lambda m: None)
    assert not (tmp_path / "run").exists()


# -- 1 + 2 + 3. the grid -------------------------------------------------------------------------
GRID = """
preset = "quick"
data_dir = "{data}"
test_users = ["B"]
seeds = [0]
hidden = {hidden}
epochs = {epochs}

[[experiments]]
variants = ["A"]
"""


def _spec(folder: Path, data: Path, hidden: int = 8, epochs: int = 2) -> Path:
    path = folder / f"grid-h{hidden}-e{epochs}.toml"
    path.write_text(GRID.format(data=data, hidden=hidden, epochs=epochs))
    return path


@pytest.fixture(scope="module")
def finished_grid(small_dir, tmp_path_factory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("grid")
    spec = _spec(folder, small_dir)
    assert grid_main(["--spec", str(spec), "--out", str(folder / "out")]) == 0
    return folder, folder / "out"


@pytest.mark.slow
@pytest.mark.parametrize("change,named", [({"hidden": 16}, "spec.hidden: 8 -> 16"),
                                          ({"epochs": 3}, "spec.epochs: 2 -> 3")])
def test_another_budget_over_a_grid_is_not_already_finished(finished_grid, small_dir, capsys,
                                                            change, named):
    folder, out = finished_grid
    record = (out / "grid.json").read_bytes()
    code, stdout, err = _cli(grid_main, ["--spec", str(_spec(folder, small_dir, **change)),
                                         "--out", str(out)], capsys)
    _assert_clean_error(code, err, named, "--restart")
    assert "already finished" not in stdout
    assert (out / "grid.json").read_bytes() == record


@pytest.mark.slow
def test_a_record_from_before_a_spec_key_existed_is_the_same_grid(finished_grid, small_dir,
                                                                   tmp_path, capsys):
    """grid.json written before ``schedule_factors`` existed meant no factors: the same spec
    resumes over it; a spec with factors names the difference."""
    _, out = finished_grid
    copy = shutil.copytree(out, tmp_path / "out")
    record = json.loads((copy / "grid.json").read_text())
    del record["spec"]["schedule_factors"]
    (copy / "grid.json").write_text(json.dumps(record))
    spec = _spec(tmp_path, small_dir)
    code, stdout, err = _cli(grid_main, ["--spec", str(spec), "--out", str(copy)], capsys)
    assert code == 0 and "1 already finished" in stdout, err
    spec.write_text(spec.read_text().replace("[[experiments]]",
                                             "schedule_factors = {A = 2}\n[[experiments]]"))
    code, _, err = _cli(grid_main, ["--spec", str(spec), "--out", str(copy)], capsys)
    _assert_clean_error(code, err, "schedule_factors", "--restart")


@pytest.mark.slow
def test_a_grid_resumes_on_its_data_moved_but_not_changed(finished_grid, small_dir, tmp_path,
                                                          capsys):
    folder, out = finished_grid
    record = (out / "grid.json").read_bytes()
    moved = shutil.copytree(small_dir, tmp_path / "elsewhere" / "Suturing")
    spec = str(_spec(folder, small_dir))
    code, stdout, err = _cli(grid_main, ["--spec", spec, "--data-dir", str(moved),
                                         "--out", str(out)], capsys)
    assert code == 0 and "1 already finished" in stdout, err
    assert (out / "grid.json").read_bytes() == record
    transcription = next((moved / "transcriptions").glob("*.txt"))
    transcription.write_text(transcription.read_text().replace(" G2 ", " G3 ", 1))
    code, _, err = _cli(grid_main, ["--spec", spec, "--data-dir", str(moved), "--out", str(out)],
                        capsys)
    _assert_clean_error(code, err, "data_fingerprint:", "--restart")


@pytest.mark.slow
def test_grid_checks_every_run_folder_and_restart_retrains_only_those(finished_grid, small_dir,
                                                                      tmp_path, capsys):
    _, out = finished_grid
    copy = shutil.copytree(out, tmp_path / "out")
    (copy / "grid.json").unlink()               # no record: the runs' own config.json still says
    spec_file = _spec(tmp_path, small_dir, hidden=16)
    code, _, err = _cli(grid_main, ["--spec", str(spec_file), "--out", str(copy)], capsys)
    _assert_clean_error(code, err, "run.encoder.hidden: 8 -> 16")
    spec = with_budget(load_spec(spec_file))
    keys = expand(spec, ("B", "C", "D"))
    prepare_grid(copy, spec, keys, restart=True, log=lambda m: None)
    run = copy / keys[0].path()
    assert not (run / "config.json").exists() and not (run / "checkpoints").exists()
    assert _strict(copy / "grid.json")["spec"]["hidden"] == 16


def test_a_record_listing_the_runs_in_another_order_is_the_same_grid(small_dir, tmp_path):
    spec = with_budget(replace(load_spec(_spec(tmp_path, small_dir)), test_users=("B", "C")))
    keys = expand(spec, ("B", "C", "D"))
    assert len(keys) == 2
    prepare_grid(tmp_path / "out", spec, keys, log=lambda m: None)
    record = _strict(tmp_path / "out" / "grid.json")
    write_json(tmp_path / "out" / "grid.json", {**record, "runs": sorted(record["runs"])[::-1]})
    prepare_grid(tmp_path / "out", spec, keys, log=lambda m: None)       # no mismatch raised


@pytest.mark.slow
def test_a_spec_listing_its_experiments_in_another_order_is_the_same_grid(finished_grid,
                                                                         small_dir, tmp_path,
                                                                         capsys):
    """Reordering a spec's experiments changes which runs go first, not the grid: it resumes
    (the dry run, which refuses what the launch refuses, lists its finished run as finished);
    changing an experiment still names the difference."""
    _, out = finished_grid
    copy = shutil.copytree(out, tmp_path / "out")
    one = '[[experiments]]\nvariants = ["A"]\nannotations = ["revised"]\n'
    two = '[[experiments]]\nvariants = ["A"]\nannotations = ["original"]\n'
    spec = _spec(tmp_path, small_dir)
    head = spec.read_text()[:spec.read_text().index("[[experiments]]")]
    spec.write_text(head + one + two)
    both = with_budget(load_spec(spec))            # the grid's record, as --restart writes it
    prepare_grid(copy, both, expand(both, ("B", "C", "D")), restart=True, log=lambda m: None)
    spec.write_text(head + two + one)
    code, stdout, err = _cli(grid_main, ["--spec", str(spec), "--out", str(copy), "--dry-run"],
                             capsys)
    assert code == 0 and "2 runs, 1 already finished, 1 to run" in stdout, err
    spec.write_text(head + two + one + 'directions = ["forward"]\n')
    code, _, err = _cli(grid_main, ["--spec", str(spec), "--out", str(copy)], capsys)
    _assert_clean_error(code, err, "spec.experiments", "--restart")


@pytest.mark.slow
def test_grid_record_carries_provenance(finished_grid):
    _, out = finished_grid
    record = _strict(out / "grid.json")
    assert record["spec"]["hidden"] == 8 and record["spec"]["seeds"] == [0]
    assert record["runs"] == ["runs/revised/bidirectional/A-fixed/seed0/B"]
    assert record["provenance"]["command"].startswith("multitask-grid --spec")


@pytest.mark.parametrize("line,named", [
    ("epochs = -4", "epochs must be an integer >= 1 (got -4)"),
    ("epochs = 0", "epochs must be an integer >= 1 (got 0)"),
    ("hidden = 0", "hidden must be an integer >= 1 (got 0)"),
    ("hidden = -16", "hidden must be an integer >= 1 (got -16)"),
    ("seeds = []", "seeds must be a non-empty list"),
    ("seeds = 0", "seeds must be a non-empty list"),
    ('epochs = "four"', "epochs must be an integer >= 1 (got 'four')"),
    ('seeds = [0, "../../../../ESCAPED"]', "seeds must be a list of integers >= 0"),
    ('preset = {name = "quick"}', "preset must be one of 'converged', 'paper', 'quick'"),
    ('feature_set = [["all"]]', "feature_set must be one of"),
])
def test_bad_spec_values_fail_at_load_time(tmp_path, small_dir, capsys, line, named):
    spec = tmp_path / "bad.toml"
    spec.write_text(f'data_dir = "{small_dir}"\ntest_users = ["B"]\n{line}\n')
    code, _, err = _cli(grid_main, ["--spec", str(spec), "--out", str(tmp_path / "out")], capsys)
    _assert_clean_error(code, err, str(spec), named)
    assert not (tmp_path / "out").exists()
    assert not list(tmp_path.parent.glob("ESCAPED"))


# -- 2. one writer per folder ---------------------------------------------------------------------
@pytest.fixture()
def foreign_lock(tmp_path):
    """Another process holding the lock of ``tmp_path / "x"``; yields (folder, pid)."""
    folder = tmp_path / "x"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom rnn_seg.runs.lock import hold_folder\n"
         "with hold_folder(sys.argv[1]):\n    print('locked', flush=True)\n    time.sleep(600)",
         str(folder)], stdout=subprocess.PIPE, text=True, env=ENV)
    assert holder.stdout.readline().strip() == "locked"
    yield folder, holder
    holder.kill()
    holder.wait()


def test_second_writer_fails_at_once_and_a_dead_holder_is_taken_over(foreign_lock, small_dir,
                                                                     tmp_path, capsys):
    folder, holder = foreign_lock
    code, _, err = _cli(multitask_main, [*TINY, "--data-dir", str(small_dir),
                                         "--out", str(folder)], capsys)
    _assert_clean_error(code, err, str(folder), f"pid {holder.pid}")
    code, _, err = _cli(grid_main, ["--spec", str(_spec(tmp_path, small_dir)),
                                    "--out", str(folder)], capsys)
    _assert_clean_error(code, err, "grid folder", str(folder), f"pid {holder.pid}")
    holder.kill()
    holder.wait()
    with hold_folder(folder):                      # the dead holder's lock is free
        pass


def _damaged(release: Path, tmp_path: Path, file: str, line: int, text: str) -> Path:
    """A copy of ``release`` whose ``file`` has ``text`` as its 1-based ``line``."""
    copy = shutil.copytree(release, tmp_path / "release" / release.name)
    lines = (copy / file).read_text().splitlines(keepends=True)
    lines[line - 1] = text + "\n"
    (copy / file).write_text("".join(lines))
    return copy


@pytest.mark.parametrize("damage,options,named", [
    (None, ["--test-user", "Z"], "unknown test user 'Z'"),
    (None, ["--task", "Knot_Tying"], "no Knot_Tying trial found"),
    (("kinematics/AllGestures/Suturing_C002.txt", 5, "abc"), [], "Suturing_C002.txt:5"),
    (("transcriptions/Suturing_C002.txt", 1, "100 50 G3"), [], "Suturing_C002.txt:1")])
def test_a_launch_refused_by_its_data_leaves_no_trace(small_dir, tmp_path, capsys, damage,
                                                      options, named):
    """No folder where there was none (its new parent included), a folder of the user's as it
    was: no lock file left behind, nothing of the user's removed."""
    data = _damaged(small_dir, tmp_path, *damage) if damage else small_dir
    new, mine = tmp_path / "new" / "run", tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("the user's")
    for out in (new, mine):
        code, _, err = _cli(multitask_main, [*TINY, "--data-dir", str(data), *options,
                                             "--out", str(out)], capsys)
        _assert_clean_error(code, err, named)
    assert not (tmp_path / "new").exists()
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]
    assert (mine / "notes.txt").read_text() == "the user's"


def test_a_lock_file_its_holder_removed_meanwhile_is_not_held(tmp_path, monkeypatch):
    """A holder removes its lock file when it ends: a process that opened the file just before
    must not hold the removed file while a third process locks a new one at the same path."""
    folder = tmp_path / "x"
    folder.mkdir()
    (folder / ".lock").write_text("")                   # a lock file found in place
    flock, calls = lock.fcntl.flock, []

    def released_meanwhile(fd: int, operation: int) -> None:
        if not calls:
            (folder / ".lock").unlink()                 # its holder ends between open and flock
        calls.append(fd)
        flock(fd, operation)

    monkeypatch.setattr(lock.fcntl, "flock", released_meanwhile)
    with hold_folder(folder):
        assert len(calls) == 2                          # locked the removed file, then again
        assert (folder / ".lock").read_text().split()[0] == str(os.getpid())
    assert list(folder.iterdir()) == []                 # the file this process created removed


def test_a_folder_its_holder_removed_meanwhile_is_made_again(tmp_path, monkeypatch):
    """Another holder's release may remove an empty folder it made between our mkdir and our
    open: the lock is taken in the folder made again, and both are gone at the end."""
    folder = tmp_path / "new" / "x"
    make, calls = lock._make_folders, []

    def removed_meanwhile(path: Path) -> list[Path]:
        made = make(path)
        if not calls:
            folder.rmdir()                              # the other holder ends now
            folder.parent.rmdir()
        calls.append(made)
        return made

    monkeypatch.setattr(lock, "_make_folders", removed_meanwhile)
    with hold_folder(folder):
        assert len(calls) == 2 and (folder / ".lock").is_file()
    assert list(tmp_path.iterdir()) == []


def test_a_folder_no_folder_can_be_made_in_is_an_error_not_a_hang(tmp_path, monkeypatch):
    """``mkdir`` says ENOENT where a race removed a parent, and also where no folder can ever be
    made (``/proc``): taking the lock looped forever there (``multitask-train --out /proc/x``
    hung); now the race is retried a bounded number of times and the error is raised."""
    from test_archive_and_inputs import at_most

    def refused(self, *args, **kwargs):
        raise FileNotFoundError(2, "No such file or directory", str(self))

    monkeypatch.setattr(Path, "mkdir", refused)
    with at_most(60), pytest.raises(FileNotFoundError, match="No such file or directory"):
        with hold_folder(tmp_path / "never" / "x"):
            pass
    monkeypatch.undo()
    if Path("/proc/self").is_dir():
        with at_most(60), pytest.raises(FileNotFoundError):
            with hold_folder("/proc/mtrnn-jigsaws-probe"):
                pass


def test_a_folder_no_lock_file_can_be_made_in_is_an_error_not_a_hang(tmp_path, monkeypatch):
    """The other half: a folder that exists but takes no file (``/proc`` for a publish's
    ``.<name>.lock`` beside ``--out /proc/x``: ``multitask-tables archive``, ``-evaluate``,
    ``-export`` hung) is one error naming the lock file; the folders made for it are removed."""
    from test_archive_and_inputs import at_most

    real_open = os.open

    def no_files(path, flags, *args):
        if str(path).startswith(str(tmp_path)) and flags & os.O_CREAT:
            raise FileNotFoundError(2, "No such file or directory", str(path))
        return real_open(path, flags, *args)

    monkeypatch.setattr(lock.os, "open", no_files)
    with at_most(60), pytest.raises(FileNotFoundError, match="no file can be created there"):
        with hold_folder(tmp_path / "new" / "x", "grid folder"):
            pass
    assert list(tmp_path.iterdir()) == []
    if Path("/proc/self").is_dir():
        monkeypatch.undo()
        with at_most(60), pytest.raises(FileNotFoundError, match=r"/proc/\.mtrnn-x\.lock"):
            with hold_folder("/proc", "output", ".mtrnn-x.lock"):
                pass


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="no /proc")
def test_an_output_folder_in_proc_is_one_line_and_exit_2(capsys):
    from test_archive_and_inputs import at_most

    with at_most(300):
        code = multitask_main(["--synthetic", "--variant", "A", "--hidden", "8", "--epochs", "1",
                               "--test-user", "C", "--no-plots", "--out", "/proc/mtrnn-x"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1] == ("multitask-train: error: /proc/mtrnn-x: cannot create this "
                                     "folder (No such file or directory)")
    assert "Traceback" not in "\n".join(err)


def test_an_output_under_a_file_is_one_line_naming_the_file(tmp_path, capsys):
    """The operating system's errors on a file read ``<file>: <reason>``, never ``[Errno 17]
    File exists: '...'``."""
    (tmp_path / "notes.txt").write_text("mine")
    code = multitask_main(["--synthetic", "--out", str(tmp_path / "notes.txt" / "run")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err == (f"multitask-train: error: {tmp_path / 'notes.txt'}: a file, "
                                 "not a folder")
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_an_output_in_a_read_only_place_says_it_cannot_be_created(tmp_path, monkeypatch,
                                                                    capsys):
    """A folder or lock file the operating system refuses to create (/sys, a read-only mount:
    EPERM, EROFS, EACCES) reads ``<path>: cannot create this folder (<reason>)`` like /proc's,
    and a lock file that could not be made is never called an unusable one to remove."""
    read_only = tmp_path / "ro"
    real_mkdir, real_open = Path.mkdir, os.open

    def mkdir(path, *args, **kwargs):
        if str(path).startswith(str(read_only)):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return real_mkdir(path, *args, **kwargs)

    def open_(path, flags, *args):
        if str(path).endswith(".out.lock") and flags & os.O_CREAT:
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        return real_open(path, flags, *args)

    monkeypatch.setattr(Path, "mkdir", mkdir)
    code = tables_main(["ladder", str(Path(__file__).resolve().parents[1]
                                      / "results/tcn/factors/grids/T-5hz-k15"),
                        "--lengths", "100", "--out", str(read_only / "out")])
    assert code == 2 and capsys.readouterr().err.strip() == (
        f"multitask-tables: error: {read_only}: cannot create this folder "
        f"({os.strerror(errno.EROFS)})")
    assert not read_only.exists()
    monkeypatch.setattr(lock.os, "open", open_)
    with pytest.raises(PermissionError) as refused:
        with hold_folder(tmp_path, "output out in the folder", ".out.lock"):
            pass
    assert refused.value.filename == str(tmp_path / ".out.lock")
    assert refused.value.strerror.startswith("no file can be created there")
    assert "remove it" not in str(refused.value)


def _wait_for(condition, what: str, timeout: float = 300) -> None:
    deadline = time.time() + timeout
    while not condition():
        assert time.time() < deadline, f"timed out waiting for {what}"
        time.sleep(0.2)


def _children(pid: int) -> list[int]:
    """Pids of the grid's worker processes (children running multiprocessing's spawn_main)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            ppid = int(stat.read_text().rsplit(")", 1)[1].split()[1])
            cmdline = (stat.parent / "cmdline").read_bytes()
        except (OSError, IndexError, ValueError):
            continue
        if ppid == pid and b"spawn_main" in cmdline:
            found.append(int(stat.parent.name))
    return found


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _checkpointed(out: Path) -> bool:
    return any(out.glob("runs/**/checkpoints/ckpt-*.index"))


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_grid_workers_die_with_their_parent(tmp_path, small_dir):
    out = tmp_path / "out"
    grid = subprocess.Popen([sys.executable, "-m", "multitask.grid.cli", "--spec",
                             str(_spec(tmp_path, small_dir, epochs=200)), "--out", str(out)],
                            env=ENV, start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        _wait_for(lambda: _checkpointed(out), "a first checkpoint")
        workers = _children(grid.pid)
        assert workers
        grid.kill()                                      # the parent only
        grid.wait()
        _wait_for(lambda: not any(_alive(w) for w in workers), "the workers to end", 60)
    finally:
        try:
            os.killpg(grid.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _default_sigint() -> None:
    """In a child, before it starts: Ctrl-C's default action, which Python needs to install its
    KeyboardInterrupt handler. A test runner started as a background job of a shell without job
    control (``cmd &`` in a script, CI wrappers) ignores SIGINT, and its children inherit that."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.slow
def test_ctrl_c_stops_a_grid_cleanly_and_it_resumes(tmp_path, small_dir):
    """Ctrl-C to the command's process group ends it with 130; the same command again (here
    called from Python: the resuming needs no process of its own) resumes the run."""
    out = tmp_path / "out"
    command = ["--spec", str(_spec(tmp_path, small_dir, epochs=12)), "--out", str(out)]
    grid = subprocess.Popen([sys.executable, "-m", "multitask.grid.cli", *command], env=ENV,
                            start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=_default_sigint)
    _wait_for(lambda: _checkpointed(out), "a first checkpoint")
    os.killpg(grid.pid, signal.SIGINT)                   # as a terminal's Ctrl-C does
    _, err = grid.communicate(timeout=120)
    assert grid.returncode == 130, err
    assert "Traceback" not in err and err.count("multitask-grid: interrupted") == 1, err
    _wait_for(lambda: not _group_alive(grid.pid), "the grid's processes to end", 60)
    assert grid_main(command) == 0
    log = next(out.glob("runs/**/train.log")).read_text()
    assert "resuming from sweep" in log and (next(out.glob("runs/**/finished.json"))).is_file()


@pytest.mark.slow
def test_ctrl_c_stops_training_cleanly_and_it_resumes(tmp_path, small_dir, capsys):
    """Ctrl-C ends the command with 130; the same command again (called from Python: the
    resuming needs no process of its own) resumes the run."""
    command = [*TINY[:-3], "--epochs", "20", "--no-plots", "--data-dir", str(small_dir),
               "--out", str(tmp_path / "x")]
    train = subprocess.Popen([sys.executable, "-m", "multitask.train_cli", *command], env=ENV,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             preexec_fn=_default_sigint)
    for line in train.stdout:
        if line.startswith("[x] epoch 2/20"):
            break
    train.send_signal(signal.SIGINT)
    out, err = train.communicate(timeout=120)
    assert train.returncode == 130, err
    assert "Traceback" not in err and err.count("multitask-train: interrupted") == 1, err
    capsys.readouterr()
    assert multitask_main(command) == 0
    again = capsys.readouterr().out
    assert "resuming from sweep" in again and "done:" in again


@pytest.mark.slow
def test_ctrl_c_in_a_command_called_from_python_reaches_the_caller(tmp_path, small_dir, capsys,
                                                                  monkeypatch):
    """``main(argv)`` called from Python (a test, a notebook): Ctrl-C during training leaves the
    run resumable and says so once, then reaches the caller, so that one Ctrl-C ends a test run
    (the same command as a program exits with 130, above)."""
    from rnn_seg.trainer import Trainer

    def ctrl_c(self, sweep, lr, out):
        if sweep == 2:
            raise KeyboardInterrupt
        return after_sweep(self, sweep, lr, out)

    after_sweep = Trainer.after_sweep
    monkeypatch.setattr(Trainer, "after_sweep", ctrl_c)
    out = tmp_path / "x"
    command = [*TINY, "--data-dir", str(small_dir), "--out", str(out)]
    with pytest.raises(KeyboardInterrupt):
        multitask_main(command)
    err = capsys.readouterr().err
    assert err.count("multitask-train: interrupted; run the same command again to resume") == 1
    assert checkpoint_sweeps(out) == [2] and not (out / "finished.json").exists()
    monkeypatch.setattr(Trainer, "after_sweep", after_sweep)
    assert multitask_main(command) == 0 and (out / "finished.json").is_file()


# -- 3. values validated before any work -----------------------------------------------------------
EPOCHS = ["--epochs", "2"]


@pytest.mark.parametrize("options,named", [
    (["--epochs", "0"], "--epochs: expected an integer >= 1, got '0'"),
    (["--sweeps", "0"], "--sweeps: expected an integer >= 1, got '0'"),
    (["--hidden", "0", *EPOCHS], ">= 1"),
    (["--hidden", "-4", *EPOCHS], ">= 1"),
    (["--layers", "0", *EPOCHS], ">= 1"),
    (["--keep-prob", "1.5", *EPOCHS], "(0, 1]"),
    (["--lr", "nan", *EPOCHS], "--lr: expected a finite number > 0, got 'nan'"),
    (["--batch-size", "0", *EPOCHS], ">= 1"),
    (["--eval-at", "0", *EPOCHS], ">= 1"),
    (["--eval-at", "3", *EPOCHS], "beyond the 2 epochs"),
    (["--eval-at", "two", *EPOCHS], "--eval-at"),
    (["--momentum", "1", *EPOCHS], "momentum"),
])
def test_bad_option_values_fail_before_any_work(small_dir, tmp_path, capsys, options, named):
    out = tmp_path / "x"
    code, stdout, err = _cli(baseline_main, ["--hidden", "8", *options, "--data-dir",
                                             str(small_dir), "--out", str(out)], capsys)
    _assert_clean_error(code, err, named)
    assert code == 2 and "done" not in stdout and not out.exists()


def _nan_data() -> tuple:
    inputs = [np.ones((12, 4), np.float32) for _ in range(6)]
    inputs[2][5, 1] = np.nan
    labels = {"gesture": [np.zeros(12, int) for _ in range(6)]}
    from rnn_seg.trainer import SequenceSet
    return SequenceSet([f"s{i}" for i in range(6)], inputs, labels)


def test_a_non_finite_loss_stops_the_run_resumably(tmp_path):
    tasks = [SoftmaxClassification("gesture", ["a", "b"])]
    data = _nan_data()
    trainer = Trainer(SegmentationModel(4, EncoderConfig(hidden=8), tasks, 0), tasks,
                      OptimConfig(unit="sweeps", total=4, decay_start=4), TrainConfig(
                          batch_size=2, eval_points=(4,), plots="none"), data, data,
                      tmp_path / "run", {}, 5.0, log=lambda m: None)
    with pytest.raises(TrainingDiverged, match=r"loss gesture nan"):
        trainer.run()
    run = tmp_path / "run"
    assert not (run / "finished.json").exists() and not (run / "metrics.json").exists()
    assert (run / "config.json").is_file()


def test_cli_reports_divergence_without_done(small_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(SoftmaxClassification, "loss",
                        lambda self, outputs, targets, mask=None: tf.reduce_sum(outputs) * np.nan)
    code, stdout, err = _cli(multitask_main, [*TINY, "--data-dir", str(small_dir),
                                              "--out", str(tmp_path / "x")], capsys)
    _assert_clean_error(code, err, "diverged", "nan")
    assert code == 1 and "done" not in stdout


# -- 4. checkpoints and --stack resume ----------------------------------------------------------
def _train_until(trainer: Trainer, sweeps: int) -> None:
    """Train ``sweeps`` sweeps and stop, as if killed right after the checkpoint."""
    start = trainer.resume()
    for sweep in range(start, sweeps):
        lr = trainer.optim.learning_rate_at(sweep, trainer.sweeps_per_epoch)
        trainer.after_sweep(sweep, lr, trainer.step(sweep, lr))


@pytest.mark.slow
def test_stack_members_at_far_apart_checkpoints_resume_and_catch_up(tmp_path):
    lone = [_trainer(tmp_path / f"lone{s}", s, False) for s in (0, 1)]
    for t in lone:
        t.run()
    first = [_trainer(tmp_path / f"m{s}", s, False) for s in (0, 1)]
    for t, reached in zip(first, (5, 2)):
        _train_until(t, reached)
    assert [t.checkpoint_sweeps() for t in first] == [[4, 5], [1, 2]]   # 2 is not common
    again = [_trainer(tmp_path / f"m{s}", s, False) for s in (0, 1)]
    metrics = TrainerStack(again).run()
    for a, b in zip(lone, again):
        for wa, wb in zip(_weights(a), _weights(b)):
            np.testing.assert_allclose(wb, wa, atol=2e-5)
    done = [_trainer(tmp_path / f"m{s}", s, False) for s in (0, 1)]
    assert TrainerStack(done).run() == metrics                 # finished: nothing to train


@pytest.mark.slow
def test_truncated_checkpoint_falls_back_and_leftovers_are_removed(tmp_path):
    lone = _trainer(tmp_path / "lone", 0, False)
    lone.run()
    run = tmp_path / "cut"
    _train_until(_trainer(run, 0, False), 4)
    data = next((run / "checkpoints").glob("ckpt-4.data-*"))
    data.write_bytes(data.read_bytes()[:50])
    leftovers = [run / "checkpoints/ckpt-5_temp/part-00000-of-00001.data-00000-of-00001",
                 run / "eval/.metrics.json.1a2b3c4d.tmp", run / ".history.csv.5e6f7a8b.tmp"]
    for path in leftovers:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("partial")
    messages = []
    resumed = _trainer(run, 0, False)
    resumed.log = messages.append
    resumed.run()
    assert any("cannot read checkpoint" in m and "ckpt-4" in m for m in messages), messages
    assert any("resuming from sweep 3" in m for m in messages), messages
    assert not any(p.exists() for p in leftovers)
    assert not (run / "checkpoints/ckpt-5_temp").exists()
    for wa, wb in zip(_weights(lone), _weights(resumed)):
        np.testing.assert_allclose(wb, wa, atol=2e-5)


def _tiny(run_dir: Path, eval_points: tuple[int, ...] = (6,), keep: str = "final") -> Trainer:
    tasks = [SoftmaxClassification("gesture", ["a", "b", "c"])]
    data = _data(0)
    return Trainer(SegmentationModel(F, EncoderConfig(hidden=8), tasks, 0), tasks,
                   OptimConfig(unit="sweeps", total=6, decay_start=3, decay_every=2),
                   TrainConfig(eval_points=eval_points, plots="none", keep_checkpoints=keep),
                   data, data, run_dir, {}, 5.0, log=lambda m: None)


@pytest.mark.parametrize("keep,kept", [("final", [6]), ("eval_points", [2, 4, 6]),
                                       ("all", [1, 2, 3, 4, 5, 6])])
def test_finished_runs_keep_what_they_are_asked_to(tmp_path, keep, kept):
    trainer = _tiny(tmp_path / keep, eval_points=(2, 4, 6), keep=keep)
    trainer.run()
    assert trainer.checkpoint_sweeps() == kept


@pytest.mark.slow
def test_keep_checkpoints_option_keeps_the_evaluation_points(finished_run):
    points = sorted(_strict(p)["sweep"] for p in finished_run.glob("eval/*/metrics.json"))
    kept = sorted(int(p.name.split("-")[1].split(".")[0])
                  for p in (finished_run / "checkpoints").glob("*.index"))
    assert kept == points and len(points) == 2
    assert points[-1] == _strict(finished_run / "finished.json")["sweeps"]


@pytest.mark.slow
def test_restore_weights_of_the_final_and_an_evaluation_point(finished_run, tmp_path):
    config = _strict(finished_run / "config.json")["run"]
    tasks = [gesture_task()]

    def model():
        return SegmentationModel(14, EncoderConfig(hidden=config["encoder"]["hidden"]), tasks, 99)
    final, point1, sweep2 = model(), model(), model()
    assert restore_weights(final, finished_run) == _strict(finished_run / "finished.json")["sweeps"]
    assert restore_weights(point1, finished_run, point=1) == 2
    assert restore_weights(sweep2, finished_run, sweep=2) == 2
    assert not np.allclose(final.variables[0].numpy(), point1.variables[0].numpy())
    for a, b in zip(point1.variables, sweep2.variables, strict=True):
        np.testing.assert_array_equal(a.numpy(), b.numpy())
    with pytest.raises(ValueError, match="not both"):
        restore_weights(model(), finished_run, sweep=2, point=1)
    final_only = _tiny(tmp_path / "final", eval_points=(3, 6))
    final_only.run()
    assert final_only.checkpoint_sweeps() == [6]
    with pytest.raises(RunFolderError, match="were not kept"):
        restore_weights(final_only.model, final_only.run_dir, point=3)


@pytest.mark.slow
def test_restore_weights_names_the_folder_of_every_failure(tmp_path):
    trainer = _tiny(tmp_path / "run")
    trainer.run()
    run, tasks = trainer.run_dir, trainer.tasks
    model = SegmentationModel(F, EncoderConfig(hidden=8), tasks, 0)
    with pytest.raises(RunFolderError, match=rf"{tmp_path / 'run'}: no checkpoint after sweep 5 "
                                             r"\(checkpoints after sweeps 6;"):
        restore_weights(model, run, sweep=5)
    with pytest.raises(RunFolderError, match="no evaluation point 4"):
        restore_weights(model, run, point=4)
    with pytest.raises(RunFolderError, match=rf"{tmp_path / 'empty'}: no checkpoint in"):
        restore_weights(model, tmp_path / "empty")
    wider = SegmentationModel(F, EncoderConfig(hidden=16), tasks, 0)
    with pytest.raises(RunFolderError, match=rf"{checkpoint_prefix(run, 6)}: its weights do not "
                                             "fit the model"):
        restore_weights(wider, run)
    other_task = [SoftmaxClassification("progress", ["p0", "p1"])]
    with pytest.raises(RunFolderError, match=rf"{checkpoint_prefix(run, 6)}: its weights do not "
                                             "fit the model"):
        restore_weights(SegmentationModel(F, EncoderConfig(hidden=8), other_task, 0), run)
    for data in run.glob("checkpoints/ckpt-6.data-*"):
        data.write_bytes(data.read_bytes()[:40])                 # cut short, as by a full disk
    with pytest.raises(RunFolderError, match=rf"{checkpoint_prefix(run, 6)}: unreadable"):
        restore_weights(model, run)


# -- 6. provenance, strict JSON, umask ----------------------------------------------------------
@pytest.mark.slow
def test_every_json_of_a_finished_run_is_strict_with_provenance(finished_run):
    files = sorted(finished_run.rglob("*.json"))
    assert len(files) >= 5
    for path in files:
        _strict(path)
    started = _strict(finished_run / "config.json")["provenance"]
    finished = _strict(finished_run / "finished.json")
    for record in (started, finished["provenance"]):
        assert {"package", "git_commit", "python", "tensorflow", "numpy", "command",
                "cpu"} <= set(record)
        assert record["cpu"] == cpu_model()
        assert record["command"].startswith("multitask-train --variant A")
    assert record["tensorflow"] == tf.__version__ and record["numpy"] == np.__version__
    assert finished["started"] == started["started"] <= finished["finished"]


def test_json_is_strict_and_files_follow_the_umask(tmp_path):
    write_json(tmp_path / "m.json", {"a": float("nan"), "b": np.float32("inf"), "c": (1.5,)})
    assert _strict(tmp_path / "m.json") == {"a": None, "b": None, "c": [1.5]}
    for umask in (0o022, 0o077):
        old = os.umask(umask)
        try:
            write_atomic(tmp_path / f"f{umask}", "x")
        finally:
            os.umask(old)
        assert (tmp_path / f"f{umask}").stat().st_mode & 0o777 == 0o666 & ~umask


# -- 6 (issue). tables refuse incomplete evidence ----------------------------------------------
def _fake_grid(root: Path) -> Path:
    """A finished two-fold grid of A-fixed, written by hand (no training)."""
    runs = [f"runs/revised/bidirectional/A-fixed/seed0/{fold}" for fold in "BC"]
    write_json(root / "grid.json", {"runs": runs})
    for k, run in enumerate(runs):
        metrics = {"accuracy": 80.0 + k, "edit": 70.0 + k, "f1@10": 75.0 + k, "accuracy_G7": None}
        write_fake_run(root / run, run_key(run), {"gesture": metrics})
    return root / runs[0]


def _nan_accuracy(run: Path) -> None:
    """The run's gesture accuracy NaN at its evaluation point, and so in their mean."""
    metrics = read_json(run / "metrics.json")
    for scores in [metrics["mean"], *metrics["points"].values()]:
        scores["gesture"]["accuracy"] = None
    write_json(run / "metrics.json", metrics)


def _tables(root: Path, capsys, *flags: str) -> tuple[int, str]:
    code, _, err = _cli(tables_main, ["paper", str(root), "--no-figures", *flags], capsys)
    return code, err


def test_tables_of_a_complete_grid(tmp_path, capsys):
    _fake_grid(tmp_path)
    code, err = _tables(tmp_path, capsys)
    assert code == 0, err
    summary = pd.read_csv(tmp_path / "tables/summary.csv")
    assert list(summary.folds) == [2] and bool(summary.complete[0])


@pytest.mark.parametrize("damage,named", [
    (lambda run: shutil.rmtree(run), "not finished"),
    (lambda run: (run / "finished.json").unlink(), "not finished"),
    (lambda run: shutil.copytree(run, run.with_name("C.old")), "C.old"),
    (_nan_accuracy, "gesture_accuracy is nan"),
    (lambda run: (run / "metrics.json").write_text('{"mean": {"gesture": {"accuracy": NaN}}}'),
     "metrics.json"),
    (lambda run: (run / "metrics.json").write_text('{"mean": {"gest'), "metrics.json"),
    (lambda run: write_json(run / "metrics.json", {"metrics": {}}),
     "metrics.json: mean: no metrics per task"),
])
def test_tables_refuse_incomplete_evidence(tmp_path, capsys, damage, named):
    run = _fake_grid(tmp_path)
    damage(run)
    code, err = _tables(tmp_path, capsys)
    _assert_clean_error(code, err, named)
    assert not (tmp_path / "tables").exists()


def test_a_malformed_grid_record_is_one_line_naming_it(tmp_path, capsys):
    _fake_grid(tmp_path)
    write_json(tmp_path / "grid.json", {"spec": {}, "run": []})
    code, err = _tables(tmp_path, capsys)
    _assert_clean_error(code, err, f"{tmp_path / 'grid.json'}: not a grid record: no 'runs' list")
    assert code == 2 and err.count("\n") == 1


def test_collecting_results_imports_no_tensorflow():
    script = "import sys, multitask.evidence.runs.collect\nprint('tensorflow' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", script], env=ENV, capture_output=True,
                            text=True, check=True)
    assert result.stdout.strip() == "False"


def _running_grid(root: Path) -> None:
    """A-fixed bidirectional and forward, seeds 0-1, folds B-C; one forward seed-1 run is still
    training (no finished.json)."""
    runs = [f"runs/revised/{direction}/A-fixed/seed{seed}/{fold}"
            for direction in ("bidirectional", "forward") for seed in (0, 1) for fold in "BC"]
    write_json(root / "grid.json", {"runs": runs})
    for k, run in enumerate(runs):
        metrics = {"accuracy": 80.0 + k, "edit": 70.0 + k, "f1@10": 75.0 + k}
        write_fake_run(root / run, run_key(run), {"gesture": metrics})
    (root / runs[-1] / "finished.json").unlink()


def test_finished_only_leaves_out_the_configurations_still_running(tmp_path, capsys):
    _running_grid(tmp_path)
    code, err = _tables(tmp_path, capsys)
    _assert_clean_error(code, err, "not finished")
    code, err = _tables(tmp_path, capsys, "--finished-only")
    assert code == 0 and "left out: revised/forward/A-fixed, 3 of 4 runs finished" in err, err
    assert "incomplete" not in err
    summary = pd.read_csv(tmp_path / "tables/summary.csv")
    assert list(summary.direction) == ["bidirectional"] and bool(summary.complete[0])
    assert not (tmp_path / "tables/table3.csv").exists()


def test_seeds_restrict_the_evidence_to_those_seeds_runs(tmp_path, capsys):
    _running_grid(tmp_path)
    code, err = _tables(tmp_path, capsys, "--seeds", "0")
    assert code == 0, err                            # the running run is seed 1's: not asked for
    runs = pd.read_csv(tmp_path / "tables/runs.csv")
    assert set(runs.seed) == {0} and len(runs) == 4
    summary = pd.read_csv(tmp_path / "tables/summary.csv")
    assert summary.complete.all() and set(summary.direction) == {"bidirectional", "forward"}
    code, err = _tables(tmp_path, capsys, "--seeds", "1", "--finished-only")
    assert code == 0 and "left out: revised/forward/A-fixed, 1 of 2 runs finished" in err, err
    code, err = _tables(tmp_path, capsys, "--seeds", "7")
    _assert_clean_error(code, err, "no finished runs of seed(s) 7")


def test_compare_reports_what_finished_only_left_out(tmp_path, capsys):
    _running_grid(tmp_path)
    code, out, err = _cli(tables_main, ["pair", str(tmp_path), "forward/A-fixed",
                                        "A-fixed", "--finished-only", "--metric", "gesture_edit"],
                          capsys)
    assert code != 0 and "left out: revised/forward/A-fixed" in err, err
    assert "Traceback" not in err


def test_allow_incomplete_marks_the_configuration(tmp_path, capsys):
    shutil.rmtree(_fake_grid(tmp_path))
    code, err = _tables(tmp_path, capsys, "--allow-incomplete")
    assert code == 0 and "not finished" in err
    summary = pd.read_csv(tmp_path / "tables/summary.csv")
    assert list(summary.folds) == [1] and not summary.complete[0]
    table = pd.read_csv(tmp_path / "tables/table1.csv")
    assert (table.model == "A (incomplete: 1/2 runs)").all()


class _RefusingCheckpoint:
    """A ``tf.train.Checkpoint`` stand-in whose write fails with TensorFlow's error ``reason``."""

    def __init__(self, reason: str):
        self.reason = reason

    def write(self, prefix: str) -> None:
        Path(prefix + ".index").write_bytes(b"partial")
        raise tf.errors.UnknownError(None, None, f"{prefix}.index; {self.reason}")


@pytest.mark.parametrize("reason,refusal", [(os.strerror(errno.ENOSPC), WriteFailed),
                                            ("Permission denied", OSError)])
def test_a_refused_checkpoint_names_its_file_and_leaves_no_part(tmp_path, reason, refusal):
    """Lack of space is a failure naming the checkpoint and the space of the run's own disk;
    any other refusal is an error naming the checkpoint; neither leaves a partial checkpoint."""
    (tmp_path / "checkpoints").mkdir()
    store = CheckpointStore(tmp_path, _RefusingCheckpoint(reason), "final", (), print)
    with pytest.raises(refusal) as raised:
        store.save(7, {"phases": {}, "elapsed_seconds": 0.0})
    assert f"checkpoint {checkpoint_prefix(tmp_path, 7)}" in str(raised.value)
    assert isinstance(raised.value, WriteFailed) == (refusal is WriteFailed)
    assert not list((tmp_path / "checkpoints").iterdir())


def test_an_output_folder_in_a_loop_of_symbolic_links_is_one_line(tmp_path, capsys):
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    code = multitask_main(["--synthetic", "--out", str(tmp_path / "a" / "run")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert str(tmp_path / "a") in err and "symbolic links" in err


def test_an_input_in_a_loop_of_symbolic_links_is_one_line_in_every_command(tmp_path, capsys):
    """Wherever a command resolves a path it reads (here a prediction folder), a loop is one line
    naming it (``run_command``, shared by every command), as an output folder's is."""
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    code = tables_main(["score", str(tmp_path / "a"), "--rate", "30", "--synthetic", "--out",
                        str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f"{tmp_path / 'a'}: a loop of symbolic links" in err and not (tmp_path / "o").exists()
    code = run_command("prog", False, lambda: (tmp_path / "b" / "x").resolve() and 0)
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("prog: error: ") and "symbolic links" in err
    with pytest.MonkeyPatch.context() as patch:              # a relative path as given
        patch.chdir(tmp_path)
        code = tables_main(["score", "a", "--rate", "30", "--synthetic", "--out", "o"])
    assert "error: a: a loop of symbolic links" in capsys.readouterr().err
    (tmp_path / "preds").mkdir()                              # --out in the loop, as given
    code = tables_main(["score", str(tmp_path / "preds"), "--rate", "30", "--synthetic", "--out",
                        str(tmp_path / "a" / "x")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f"{tmp_path / 'a' / 'x'}: a loop of symbolic links" in err
    with pytest.raises(RuntimeError, match="other"):        # any other RuntimeError is a bug
        run_command("prog", False, lambda: (_ for _ in ()).throw(RuntimeError("other")))
