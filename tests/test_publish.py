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
    call, before anything else: the old output or the new one, never a mix. A reader who never
    calls again sees the old output with its manifest, the new one with its own, or files of
    one of them without a manifest: never a manifest describing files of another output, nor
    old files beside new ones."""
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
    assert steps[:2] == ["journal", "unlist"] and steps[-2:] == ["list", "clear"]
    assert {"move a.csv", "move added.csv", "remove gone.csv", "remove a.csv"} <= set(steps)
    assert max(i for i, s in enumerate(steps) if s.startswith("remove")) < min(
        i for i, s in enumerate(steps) if s.startswith("move"))
    assert json.loads(new["t.json"])["files"] == sorted(NEW)
    for k in range(len(steps)):
        out = tmp_path / f"killed-{k}"
        earlier(out)
        assert killed_at(k, lambda: _publish_files(out)) == KILLED
        seen = visible(out)
        if "t.json" in seen:                            # what a reader who never calls sees
            assert seen in (old, new), steps[k]
        else:
            assert seen.items() <= old.items() or seen.items() <= new.items(), steps[k]
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


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.parametrize("journal, refusal", [
    ({"manifest": {"files": []}, "remove": ["grid/grid.json"]}, "grid folder"),
    ({"manifest": {"files": []}, "remove": ["../outside.csv"]},
     "not the journal of an interrupted publish"),
    ({"manifest": {"files": ["/etc/passwd"]}, "remove": []},
     "not the journal of an interrupted publish"),
    ({"remove": []}, "not the journal of an interrupted publish")])
def test_a_forged_journal_moves_and_removes_nothing_outside_the_outputs_places(
        tmp_path, journal, refusal):
    """The journal is read as any input: a removal in a grid held in the folder, a file
    outside it or a manifest of another shape is refused, naming the journal, and nothing is
    touched."""
    out = tmp_path / "out"
    (out / "grid").mkdir(parents=True)
    (out / "grid" / "grid.json").write_text('{"runs": []}')
    (out / "t.json").write_text('{"written_by": "cmd", "files": []}')
    (tmp_path / "outside.csv").write_text("mine")
    work = publish.own_folder(out, ".partial-t-", "", "t.json")
    (work / "journal.json").write_text(json.dumps(journal))
    with pytest.raises(ValueError, match=refusal):
        _publish_files(out)
    assert (out / "grid" / "grid.json").exists() and (tmp_path / "outside.csv").exists()
    assert (out / "t.json").exists() and work.is_dir()


def _users_lookalikes(parent: Path, name: str) -> dict[str, bytes]:
    """Beside the output ``name`` in ``parent``: the user's own entries whose names a publish's
    hidden folders could have (``.A.mynotes1.tmp/``, ``.A.backup_1.old.tmp/``,
    ``.partial-t-notes/``), a file of such a name, a link to a folder of the user's, and a
    folder whose marker names another output or is a link; returns what they hold."""
    parent.mkdir(parents=True, exist_ok=True)
    elsewhere = parent.parent / "elsewhere"
    _files(elsewhere, {"kept.txt": "mine"})
    for folder in (f".{name}.mynotes1.tmp", f".{name}.backup_1.old.tmp", ".partial-t-notes",
                   f".{name}.old_copy.tmp"):
        _files(parent / folder, {"notes.txt": "mine", "new/a.csv": "mine",
                                 "journal.json": '{"remove": []}'})
    (parent / f".{name}.abcdefgh.tmp").write_text("a file of mine")
    (parent / f".{name}.linked00.tmp").symlink_to(elsewhere)
    other = publish.own_folder(parent, f".{name}.", ".tmp", "another-output")
    (other / "notes.txt").write_text("mine")
    linked = parent / f".{name}.markedln.tmp"
    _files(linked, {"notes.txt": "mine"})
    (linked / publish.MARKER).symlink_to(other / publish.MARKER)
    return _hidden(parent, elsewhere)


def _hidden(parent: Path, elsewhere: Path) -> dict[str, bytes]:
    return {p.relative_to(parent.parent).as_posix(): p.read_bytes()
            for folder in (parent, elsewhere) for p in sorted(folder.rglob("*"))
            if p.is_file() and (p.relative_to(folder).parts[0].startswith(".")
                                or folder == elsewhere) and not p.name.endswith(".lock")}


@pytest.mark.parametrize("can_exchange", [True, False], ids=["exchange", "set-aside"])
def test_a_publish_never_removes_a_users_folder_that_looks_like_its_own(tmp_path, monkeypatch,
                                                                       can_exchange):
    """Recovery removes only the hidden folders a publish made (its marker inside): the user's
    folders, files and links of like names beside the output stay as they were, through
    publishes, interrupted ones and their recovery."""
    if not can_exchange:
        monkeypatch.setattr(publish, "exchange", lambda a, b: False)
    folder = tmp_path / "place" / "out"
    users = _users_lookalikes(folder.parent, "out")
    for k in range(3):
        assert killed_at(k, lambda: _replace_folder(folder)) in (KILLED, 0)
        _replace_folder(folder)
    assert visible(folder) == _as_bytes(NEW)
    shared = tmp_path / "shared"
    users_shared = _users_lookalikes(shared, "t")
    for k in range(6):
        assert killed_at(k, lambda: _publish_files(shared)) in (KILLED, 0)
        _publish_files(shared)
    assert _hidden(folder.parent, tmp_path / "elsewhere") == users
    assert _hidden(shared, tmp_path / "elsewhere") == users_shared
    assert not [p for p in [*folder.parent.iterdir(), *shared.iterdir()]
                if publish.is_own(p, "out") or publish.is_own(p, "t.json")]


@pytest.mark.slow
def test_an_archive_leaves_the_users_folders_of_its_hidden_names(fake_grid, tmp_path):
    """Issue 66: ``.A.mynotes1.tmp/`` and ``.A.backup_1.old.tmp/`` beside an archive ``A`` are
    the user's: the next archive into ``A`` leaves them (and the other look-alikes) whole."""
    dest = tmp_path / "place" / "A"
    assert tables_main(["archive", str(fake_grid), str(dest)]) == 0
    users = _users_lookalikes(dest.parent, "A")
    assert tables_main(["archive", str(fake_grid), str(dest)]) == 0
    assert _hidden(dest.parent, tmp_path / "elsewhere") == users


def test_a_study_of_many_files_prints_their_count_and_its_manifest(tmp_path, capsys):
    """Up to ``LISTED`` files a study's publish names each; past it (a release's trial files),
    one line with their count and the manifest that lists every one of them."""
    from multitask.evidence.commands.common import LISTED, publish as publish_study

    def write(count):
        def files(staging: Path) -> list[Path]:
            written = [staging / "trials" / f"t{i:04d}.csv" for i in range(count)]
            for path in written:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text("frame,gesture\n1,G1\n")
            return written
        return files

    publish_study(tmp_path / "few", "few.json", False, write(LISTED))
    assert len(capsys.readouterr().out.splitlines()) == LISTED
    publish_study(tmp_path / "many", "many.json", False, write(LISTED + 1))
    out = capsys.readouterr().out.splitlines()
    assert out == [f"{tmp_path / 'many'}: {LISTED + 1} files written, listed in "
                   f"{tmp_path / 'many' / 'many.json'}"]
    listed = json.loads((tmp_path / "many" / "many.json").read_text())["files"]
    assert len(listed) == LISTED + 1 and all((tmp_path / "many" / f).is_file() for f in listed)
