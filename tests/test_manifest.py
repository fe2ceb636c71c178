"""rnn_seg.runs.manifest: a command's files in a folder it shares, all at once, never over a
file it did not write."""
from __future__ import annotations

import fcntl
import json
import os
from pathlib import Path

import pytest

from rnn_seg.runs.folder import RunFolderError
from rnn_seg.runs.lock import FolderLockedError
from rnn_seg.runs.manifest import staged_outputs
from rnn_seg.runs.outputs import OutputFolderError

MANIFEST = "tables.json"


def _write(out: Path, files: dict[str, str], overwrite: bool = False) -> None:
    with staged_outputs(out, MANIFEST, "cmd", overwrite) as staging:
        for name, text in files.items():
            (staging / name).parent.mkdir(parents=True, exist_ok=True)
            (staging / name).write_text(text)


def _snapshot(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): p.read_text() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def _listed(out: Path) -> list[str]:
    return json.loads((out / MANIFEST).read_text())["files"]


def test_outputs_land_beside_other_files_and_are_listed(tmp_path):
    (tmp_path / "README.md").write_text("mine")
    _write(tmp_path, {"a.csv": "1", "figures/f.png": "2"})
    files = _snapshot(tmp_path)
    assert files.pop(MANIFEST) and files == {"README.md": "mine", "a.csv": "1",
                                             "figures/f.png": "2"}
    assert _listed(tmp_path) == ["a.csv", "figures/f.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [                # no staging, no lock
        "README.md", "a.csv", "figures", MANIFEST]


def test_a_file_the_manifest_does_not_list_is_never_written_over(tmp_path):
    (tmp_path / "a.csv").write_text("mine")
    with pytest.raises(OutputFolderError, match="a.csv exists and is not an output of cmd"):
        _write(tmp_path, {"b.csv": "new", "a.csv": "new"})
    assert _snapshot(tmp_path) == {"a.csv": "mine"}          # not even b.csv was moved in
    _write(tmp_path, {"b.csv": "new", "a.csv": "new"}, overwrite=True)
    assert (tmp_path / "a.csv").read_text() == "new"


def test_the_next_output_replaces_the_last_and_removes_what_it_no_longer_writes(tmp_path):
    _write(tmp_path, {"a.csv": "1", "figures/f.png": "2"})
    (tmp_path / "notes.txt").write_text("mine")
    _write(tmp_path, {"a.csv": "3"})
    files = _snapshot(tmp_path)
    assert files.pop(MANIFEST) and files == {"a.csv": "3", "notes.txt": "mine"}
    assert _listed(tmp_path) == ["a.csv"]
    assert not (tmp_path / "figures").exists()               # emptied by us, so removed


def test_a_call_leaves_the_folders_it_does_not_write_as_they_are(tmp_path):
    _write(tmp_path, {"a.csv": "1", "figures/f.png": "2", "figures/curves/c.png": "3"})
    with staged_outputs(tmp_path, MANIFEST, "cmd", kept=("figures/",)) as staging:
        (staging / "a.csv").write_text("4")
    assert (tmp_path / "figures" / "f.png").read_text() == "2"
    assert _listed(tmp_path) == ["a.csv", "figures/curves/c.png", "figures/f.png"]
    _write(tmp_path, {"a.csv": "5"})                                # no longer kept: removed
    assert _listed(tmp_path) == ["a.csv"] and not (tmp_path / "figures").exists()


def test_a_failing_command_leaves_the_folder_as_it_was(tmp_path):
    _write(tmp_path / "out", {"a.csv": "1"})
    before = _snapshot(tmp_path)
    with pytest.raises(RuntimeError):
        with staged_outputs(tmp_path / "out", MANIFEST, "cmd") as staging:
            (staging / "a.csv").write_text("half")
            raise RuntimeError("interrupted")
    assert _snapshot(tmp_path) == before
    with pytest.raises(RuntimeError):
        with staged_outputs(tmp_path / "new" / "deeper", MANIFEST, "cmd"):
            raise RuntimeError("interrupted")
    assert not (tmp_path / "new").exists()                   # created for us, removed again


def test_a_manifest_cannot_lead_outside_its_folder(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "out"
    out.mkdir()
    (out / MANIFEST).write_text(json.dumps({"files": ["../victim.txt"]}))
    with pytest.raises(RunFolderError, match="not a manifest"):
        _write(out, {"a.csv": "1"})
    assert victim.read_text() == "precious" and not (out / "a.csv").exists()


def test_nothing_is_written_or_removed_behind_a_link_a_file_or_in_a_grid(tmp_path):
    """Every place is checked before anything moves: a folder on the way that is a symbolic
    link, a file or a grid folder stops the whole output, as does a listed file turned folder."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "precious.txt").write_text("precious")
    out = tmp_path / "out"
    out.mkdir()
    (out / "figures").symlink_to(elsewhere)
    with pytest.raises(OutputFolderError, match="figures is a symbolic link"):
        _write(out, {"a.csv": "1", "figures/f.png": "2"})
    (out / MANIFEST).write_text(json.dumps({"files": ["figures/precious.txt"]}))
    with pytest.raises(OutputFolderError, match="figures is a symbolic link"):
        _write(out, {"a.csv": "1"})
    assert sorted(p.name for p in elsewhere.iterdir()) == ["precious.txt"]
    (out / "figures").unlink()
    (out / "figures").write_text("a file of yours")
    with pytest.raises(OutputFolderError, match="figures is a file"):
        _write(out, {"a.csv": "1", "figures/f.png": "2"})
    (out / "grid").mkdir()
    (out / "grid" / "grid.json").write_text(json.dumps({"runs": []}))
    (out / MANIFEST).write_text(json.dumps({"files": ["grid/grid.json"]}))
    with pytest.raises(OutputFolderError, match="grid is a grid folder"):
        _write(out, {"a.csv": "1"})
    (out / MANIFEST).write_text(json.dumps({"files": ["b.csv"]}))
    (out / "b.csv").mkdir()
    with pytest.raises(OutputFolderError, match="b.csv is a folder"):
        _write(out, {"a.csv": "1"})
    assert not (out / "a.csv").exists() and (out / "grid" / "grid.json").is_file()


def test_one_writer_at_a_time(tmp_path):
    """Another process holding the folder's lock stops the output before any work."""
    out = tmp_path / "out"
    out.mkdir()
    fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)       # flock locks belong to an open file: as another process
    try:
        with pytest.raises(FolderLockedError, match="output folder"):
            _write(out, {"a.csv": "1"})
    finally:
        os.close(fd)
    assert sorted(p.name for p in out.iterdir()) == [".lock"]
