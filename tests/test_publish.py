"""Publishes that are all-or-nothing (``rnn_seg.runs.publish``): killed at each of its steps, a
publish leaves the old output or the new one, whole, once the next start has recovered; a folder
published whole is never seen otherwise, not even before that.

The mechanism is killed for real (a forked child ``os._exit``s at the k-th step); the commands
are observed at each step instead: ``step_hook`` copies their output's place as a SIGKILL there
would leave it, and the next start's recovery runs on each copy."""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from fake_grid import write_fake_grid
from multitask.evidence.cli import main as tables_main
from multitask.grid.spec import PAPER_EXPERIMENTS
from rnn_seg.runs import publish
from rnn_seg.runs.lock import hold_folder
from rnn_seg.runs.manifest import finish_pending, staged_outputs

KILLED = 9
OLD = {"a.csv": "old a", "sub/b.csv": "old b", "gone.csv": "only in the old output"}
NEW = {"a.csv": "new a", "sub/b.csv": "new b", "added.csv": "only in the new output"}


def visible(folder: Path) -> dict[str, bytes]:
    """The files a reader sees in ``folder``: all but hidden ones (staging, locks)."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not any(part.startswith(".")
                                       for part in p.relative_to(folder).parts)}


def killed_at(k: int, body) -> int:
    """Run ``body`` in a forked child that dies (``os._exit``, no clean-up) just before the
    k-th step of its publish; its exit code (``KILLED`` when it died there)."""
    pid = os.fork()
    if pid == 0:
        steps = iter(range(10**6))

        def die(step: str) -> None:
            if next(steps) == k:
                os._exit(KILLED)

        publish.step_hook = die
        try:
            body()
        except BaseException:
            os._exit(3)
        os._exit(0)
    return os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])


def steps_of(body) -> list[str]:
    """The steps of ``body``'s publish, in order (run for real)."""
    seen: list[str] = []
    publish.step_hook = seen.append
    try:
        body()
    finally:
        publish.step_hook = lambda step: None
    return seen


def _unlocked(folder: Path) -> list[str]:
    """What ``folder`` holds but lock files (a killed holder's stays, free: ``lock``)."""
    return sorted(p.name for p in folder.iterdir() if not p.name.endswith(".lock"))


def _files(folder: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text)


def _as_bytes(files: dict[str, str]) -> dict[str, bytes]:
    return {name: text.encode() for name, text in files.items()}


def _replace_folder(target: Path) -> None:
    with publish.staged_folder(target, overwrite=True) as staging:
        _files(staging, NEW)


@pytest.mark.parametrize("can_exchange", [True, False], ids=["exchange", "set-aside"])
def test_a_folder_killed_at_any_step_of_its_publish_is_the_old_or_the_new(tmp_path, monkeypatch,
                                                                        can_exchange):
    """With ``renameat2`` the visible folder is the old one or the new one at every instant;
    where a file system cannot exchange, the next start puts the old one back if the process
    died between its two renames. Either way no hidden folder stays."""
    if not can_exchange:
        monkeypatch.setattr(publish, "exchange", lambda a, b: False)
    scratch = tmp_path / "scratch" / "out"
    _files(scratch, OLD)
    steps = steps_of(lambda: _replace_folder(scratch))
    assert steps == ["swap", "remove old"] if can_exchange else [
        "swap", "swap aside", "remove old"]
    for k in range(len(steps)):
        target = tmp_path / f"killed-{k}" / "out"
        _files(target, OLD)
        assert killed_at(k, lambda: _replace_folder(target)) == KILLED
        if can_exchange or steps[k] != "swap aside":
            assert visible(target) in (_as_bytes(OLD), _as_bytes(NEW)), steps[k]
        with publish.claimed(target):                    # the next start
            pass
        assert visible(target) in (_as_bytes(OLD), _as_bytes(NEW)), steps[k]
        assert _unlocked(target.parent) == ["out"], steps[k]
    _replace_folder(target)
    assert visible(target) == _as_bytes(NEW)


def _publish_files(out: Path) -> None:
    with staged_outputs(out, "t.json", "cmd") as staging:
        _files(staging, NEW)


def test_files_killed_at_any_step_of_their_publish_are_finished_by_the_next_call(tmp_path):
    """Among a user's files, the moves of a publish killed midway are finished by the next
    call, before anything else: the old output or the new one, never a mix; the journal
    (``pending``) says so meanwhile."""
    def earlier(out: Path) -> None:
        (out / "README.md").parent.mkdir(parents=True)
        (out / "README.md").write_text("mine")
        with staged_outputs(out, "t.json", "cmd") as staging:
            _files(staging, OLD)

    scratch = tmp_path / "scratch"
    earlier(scratch)
    old = visible(scratch)
    steps = steps_of(lambda: _publish_files(scratch))
    new = visible(scratch)
    assert steps[0] == "journal" and steps[-2:] == ["list", "clear"]
    assert {"move a.csv", "move added.csv", "remove gone.csv"} <= set(steps)
    assert json.loads(new["t.json"])["files"] == sorted(NEW)
    for k in range(len(steps)):
        out = tmp_path / f"killed-{k}"
        earlier(out)
        assert killed_at(k, lambda: _publish_files(out)) == KILLED
        if steps[k] not in ("journal", "clear"):
            assert "pending" in json.loads((out / "t.json").read_text())
        with hold_folder(out, "output folder"):         # what the next call does first
            finish_pending(out, "t.json")
        assert visible(out) in (old, new), steps[k]
        assert not [name for name in _unlocked(out) if name.startswith(".")], steps[k]
    _publish_files(out)
    assert visible(out) == new


@pytest.fixture(scope="module")
def fake_grid(tmp_path_factory):
    return write_fake_grid(tmp_path_factory.mktemp("fake") / "grid", seeds=(0,),
                           experiments=PAPER_EXPERIMENTS[:2])


def observed_steps(monkeypatch, place: Path, copies: Path) -> list[tuple[str, Path]]:
    """Copy ``place`` as a SIGKILL would leave it at each step of the publishes to come."""
    taken: list[tuple[str, Path]] = []

    def copy(step: str) -> None:
        to = copies / f"{len(taken):03d}" / place.name
        shutil.copytree(place, to, symlinks=True)
        taken.append((step, to))

    monkeypatch.setattr(publish, "step_hook", copy)
    return taken


def test_tables_killed_at_any_step_over_an_earlier_output_are_all_old_or_all_new(
        fake_grid, tmp_path, monkeypatch):
    """``multitask-tables --out`` over the tables of another call (the grid's 15 files; now
    the 3 of its runs one by one, 12 to remove): at every step, once the next call has
    recovered, the folder holds one call's tables, whole, beside the user's README."""
    out = tmp_path / "results"
    out.mkdir()
    (out / "README.md").write_text("mine")
    assert tables_main(["paper", str(fake_grid), "--out", str(out), "--no-figures"]) == 0
    old = visible(out)
    taken = observed_steps(monkeypatch, out, tmp_path / "killed")
    assert tables_main(["runs", str(fake_grid / "runs"), "--out", str(out)]) == 0
    new = visible(out)
    assert len(old) == 17 and len(new) == 5 and old != new
    assert len(taken) > 12
    for step, copy in taken:
        with hold_folder(copy, "output folder"):
            finish_pending(copy, "tables.json")
        assert visible(copy) in (old, new), step
    assert visible(taken[-1][1]) == new


def test_an_archive_killed_at_any_step_over_an_earlier_one_is_the_old_or_the_new(
        fake_grid, tmp_path, monkeypatch):
    """``--archive`` over an earlier archive of the same grid: the destination holds the old
    archive or the new one at every instant, and the next call leaves nothing hidden beside
    it."""
    grid = tmp_path / "grid"
    shutil.copytree(fake_grid, grid)
    dest = tmp_path / "place" / "archive"
    unfinished = next((grid / "runs").glob("*/*/*/*/B"))
    (unfinished / "finished.json").rename(unfinished / "later.json")
    assert tables_main(["archive", str(grid), str(dest)]) == 0
    old = visible(dest)
    (unfinished / "later.json").rename(unfinished / "finished.json")
    taken = observed_steps(monkeypatch, dest.parent, tmp_path / "killed")
    assert tables_main(["archive", str(grid), str(dest)]) == 0
    new = visible(dest)
    assert len(new) > len(old)
    assert [step for step, _ in taken] == ["swap", "remove old"]
    for step, copy in taken:
        assert visible(copy / "archive") in (old, new), step
        with publish.claimed(copy / "archive"):
            pass
        assert visible(copy / "archive") in (old, new), step
        assert _unlocked(copy) == ["archive"], step


@pytest.mark.parametrize("pending, refusal", [
    ({"staging": ".partial-t-x", "remove": ["grid/grid.json"], "files": []}, "grid folder"),
    ({"staging": "../elsewhere", "remove": [], "files": []}, "not the record of an interrupted"),
    ({"staging": ".partial-t-x", "remove": ["../outside.csv"], "files": []},
     "not the record of an interrupted")])
def test_a_forged_journal_moves_and_removes_nothing_outside_the_outputs_places(
        tmp_path, pending, refusal):
    """The journal is read as any input: a removal in a grid held in the folder, a staging
    folder or a file outside it is refused, naming the manifest, and nothing is touched."""
    out = tmp_path / "out"
    (out / "grid").mkdir(parents=True)
    (out / "grid" / "grid.json").write_text('{"runs": []}')
    (tmp_path / "outside.csv").write_text("mine")
    (out / "t.json").write_text(json.dumps({"written_by": "cmd", "files": [],
                                            "pending": pending}))
    with pytest.raises(ValueError, match=refusal):
        _publish_files(out)
    assert (out / "grid" / "grid.json").exists() and (tmp_path / "outside.csv").exists()
    assert "pending" in json.loads((out / "t.json").read_text())
