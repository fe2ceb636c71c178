"""Archives that never replace another grid's nor leak, and inputs and resources refused in one
line: a spec's archive compared by spec, destinations inside runs and grids, symbolic links and
FIFOs in a run, FIFOs where a file is read, --workers beyond the cores, a full disk."""
from __future__ import annotations

import errno
import json
import os
import re
import shutil
import signal
from contextlib import contextmanager
from pathlib import Path

import pytest

from fake_grid import write_fake_grid
from jigsaws_tools.cli.main import main as tools_main
from jigsaws_tools.cores import usable_cores
from multitask.evidence.cli import main as tables_main
from multitask.grid.cli import main as grid_main
from multitask.grid.spec import PAPER_EXPERIMENTS
from rnn_seg.runs.folder import RunFolderError, read_json
from rnn_seg.runs.logs import read_log
from test_publish import visible


@contextmanager
def at_most(seconds: int):
    """Fail instead of hanging: what refuses at once must not wait for a writer."""
    def hung(*_):
        raise AssertionError(f"still waiting after {seconds} s")

    previous = signal.signal(signal.SIGALRM, hung)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


@pytest.fixture(scope="module")
def fake_grid(tmp_path_factory):
    return write_fake_grid(tmp_path_factory.mktemp("fake") / "grid", seeds=(0,),
                           experiments=PAPER_EXPERIMENTS[1:2])


def _grid_with_spec(fake_grid: Path, to: Path, hidden: int) -> Path:
    shutil.copytree(fake_grid, to)
    record = json.loads((to / "grid.json").read_text())
    (to / "grid.json").write_text(json.dumps({"spec": {"hidden": hidden, "data_dir": str(to)},
                                              **record}))
    return to


def _one_line(err: str) -> str:
    """The one error line of a command (beside any note)."""
    lines = [line for line in err.strip().splitlines() if not line.startswith("note: ")]
    assert len(lines) == 1, err
    return lines[0]


def test_an_archive_never_replaces_the_archive_of_another_spec(fake_grid, tmp_path, capsys):
    """Same run paths, another width: refused, naming the differing key; the same spec over
    moved data replaces it."""
    narrow = _grid_with_spec(fake_grid, tmp_path / "narrow", hidden=8)
    wide = _grid_with_spec(fake_grid, tmp_path / "wide", hidden=16)
    dest = tmp_path / "archive"
    assert tables_main(["archive", str(narrow), str(dest)]) == 0
    before = visible(dest)
    capsys.readouterr()
    assert tables_main(["archive", str(wide), str(dest)]) == 2
    err = _one_line(capsys.readouterr().err)
    assert "holds the archive of another grid" in err and "hidden" in err
    assert visible(dest) == before
    moved = _grid_with_spec(fake_grid, tmp_path / "moved", hidden=8)      # only data_dir differs
    assert tables_main(["archive", str(moved), str(dest)]) == 0
    assert read_json(dest / "archive.json")["source"] == str(moved.resolve())


def test_an_archive_is_never_written_inside_a_run_or_a_grid(fake_grid, tmp_path, capsys):
    grid = tmp_path / "grid"
    shutil.copytree(fake_grid, grid)
    other = tmp_path / "other"
    shutil.copytree(fake_grid, other)
    run = next((grid / "runs").glob("*/*/*/*/B"))
    other_run = next((other / "runs").glob("*/*/*/*/B"))
    finished = json.loads((other_run / "finished.json").read_text())
    (other_run / "finished.json").write_text(json.dumps({**finished, "settings_hash": "0f"}))
    before = {folder: sorted(p.relative_to(folder) for p in folder.rglob("*"))
              for folder in (grid, other)}
    for dest, says in ((run / "archive", "neither inside the other"),
                       (other_run / "arc", "inside the run folder"),
                       (other / "archives" / "mine", "inside the grid folder")):
        assert tables_main(["archive", str(grid), str(dest)]) == 2
        assert says in _one_line(capsys.readouterr().err)
    assert before == {folder: sorted(p.relative_to(folder) for p in folder.rglob("*"))
                      for folder in (grid, other)}


@pytest.mark.parametrize("kind", ["symlink", "fifo"])
def test_an_archive_copies_only_the_runs_own_regular_files(fake_grid, tmp_path, capsys, kind):
    grid = tmp_path / "grid"
    shutil.copytree(fake_grid, grid)
    run = next((grid / "runs").glob("*/*/*/*/B"))
    secret = tmp_path / "secret.csv"
    secret.write_text("not the run's")
    (run / "history.csv").unlink()
    if kind == "symlink":
        (run / "history.csv").symlink_to(secret)
    else:
        os.mkfifo(run / "history.csv")
    with at_most(60):
        assert tables_main(["archive", str(grid), str(tmp_path / "archive")]) == 2
    err = _one_line(capsys.readouterr().err)
    assert f"{run / 'history.csv'}:" in err
    assert ("symbolic link" if kind == "symlink" else "not a regular file") in err
    assert not (tmp_path / "archive").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grid", "secret.csv"]


def test_a_full_disk_while_archiving_names_the_file_at_its_place(fake_grid, tmp_path, capsys,
                                                                monkeypatch):
    dest = tmp_path / "archive"
    assert tables_main(["archive", str(fake_grid), str(dest)]) == 0
    before = visible(dest)

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(shutil, "copyfileobj", full)
    capsys.readouterr()
    assert tables_main(["archive", str(fake_grid), str(dest)]) == 1
    err = _one_line(capsys.readouterr().err)
    assert f"cannot write {dest / 'grid.json'} (No space left on device)" in err
    assert "MB free" in err and "checkpoint" not in err and "Traceback" not in err
    assert visible(dest) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["archive"]


def test_a_full_disk_while_writing_tables_leaves_the_earlier_tables(fake_grid, tmp_path, capsys,
                                                                    monkeypatch):
    """The disk fills at the first file written: one line naming that file at its place in
    --out and the space left; the earlier tables stay, whole, and nothing hidden is left."""
    out = tmp_path / "tables"
    assert tables_main(["runs", str(fake_grid / "runs"), "--out", str(out)]) == 0
    before = visible(out)
    opened = os.fdopen

    def full_disk(fd, mode="r", *args, **kwargs):
        if "w" in mode:
            os.close(fd)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return opened(fd, mode, *args, **kwargs)

    monkeypatch.setattr(os, "fdopen", full_disk)
    capsys.readouterr()
    assert tables_main(["runs", str(fake_grid / "runs"), "--out", str(out)]) == 1
    err = _one_line(capsys.readouterr().err)
    assert re.search(rf"cannot write {re.escape(str(out))}/\S+ \(No space left on device\); "
                     r"\d+ MB free", err), err
    assert visible(out) == before
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_fifos_are_refused_at_once_where_a_file_is_read(synth_dir, tmp_path, capsys):
    fifo = tmp_path / "format.toml"
    os.mkfifo(fifo)
    with at_most(60):
        assert tools_main(["inspect", "--data-dir", str(synth_dir), "--format", str(fifo)]) == 2
        assert f"{fifo}: a FIFO (named pipe), not a recording format file" in _one_line(
            capsys.readouterr().err)
        assert grid_main(["--spec", str(fifo), "--out", str(tmp_path / "g"), "--dry-run"]) == 2
        assert "a FIFO (named pipe), not a spec file" in _one_line(capsys.readouterr().err)
        metrics = tmp_path / "metrics.json"
        os.mkfifo(metrics)
        with pytest.raises(RunFolderError, match="a FIFO"):
            read_json(metrics)
    assert not (tmp_path / "g").exists()


def test_workers_are_bounded_like_threads(tmp_path, capsys):
    cores = usable_cores()
    spec = Path(__file__).parents[1] / "results" / "smoke.toml"
    assert grid_main(["--spec", str(spec), "--out", str(tmp_path / "g"), "--workers",
                      str(cores + 1), "--dry-run"]) == 2
    err = _one_line(capsys.readouterr().err)
    assert f"--workers: expected at most the {cores} core" in err and "this process may" in err
    assert not (tmp_path / "g").exists()


@pytest.mark.parametrize("name", ["metrics.json", "config.json", "history.csv"])
def test_a_fifo_in_a_run_never_hangs_the_tables(fake_grid, tmp_path, capsys, name):
    """A FIFO among a run's files is refused at once where it is read (metrics.json always),
    naming it, with no tables written."""
    grid = tmp_path / "grid"
    shutil.copytree(fake_grid, grid)
    run = next((grid / "runs").glob("*/*/*/*/C"))
    (run / name).unlink()
    os.mkfifo(run / name)
    with at_most(60):
        code = tables_main(["paper", str(grid), "--out", str(tmp_path / "tables"), "--no-figures"])
    err = capsys.readouterr().err
    if name == "metrics.json":         # read by every table; the others where needed
        assert code == 2 and f"{run / name}: a FIFO (named pipe), not a regular file" in err
    if code:
        assert str(run / name) in err and "Traceback" not in err
        assert not (tmp_path / "tables").exists()
    if name == "history.csv":          # as the training curves and GradNorm figures read it
        with at_most(60), pytest.raises(RunFolderError, match="FIFO"):
            read_log(run / name)


def test_predict_refuses_a_fifo_as_input_at_once(tmp_path, capsys):
    from multitask.inference.predict_cli import kinematics_files

    fifo = tmp_path / "Suturing_B001.txt"
    os.mkfifo(fifo)
    with at_most(60), pytest.raises(ValueError, match="not a regular file or a folder"):
        kinematics_files([fifo])


def test_a_grid_keeps_training_when_its_archive_meets_a_full_disk(fake_grid, tmp_path,
                                                                  monkeypatch):
    """``multitask-grid --archive``: after a job, a full disk is a warning naming the file (the
    grid goes on); before training, a failure naming it."""
    from jigsaws_tools.errors import WriteFailed
    from multitask.grid.cli import _archive

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(shutil, "copyfileobj", full)
    said: list[str] = []
    _archive(fake_grid, tmp_path / "archive", said.append, warn=True)
    assert len(said) == 1 and "warning: the archive in" in said[0]
    assert f"cannot write {tmp_path / 'archive' / 'grid.json'}" in said[0]
    with pytest.raises(WriteFailed, match="MB free"):
        _archive(fake_grid, tmp_path / "archive", said.append)
    assert not list(tmp_path.iterdir())
