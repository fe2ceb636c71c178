"""Issue 16, items 5 (the cache) and 7 (data safety): each reported case, replayed.

The cache is an optimisation only: keyed by content, verified on read, rebuilt when damaged, skipped
with one warning when it cannot be written. Input data is never overwritten, and every unusable
input file gets a clear message naming it.
"""
from __future__ import annotations

import errno
import logging
import os
import shutil
import tempfile

import numpy as np
import pytest

from jigsaws_tools import dataset as dataset_module
from jigsaws_tools.cli.main import main as tools_main
from jigsaws_tools.dataset import DataConfig, cache_key, load_dataset
from jigsaws_tools.errors import FormatError, JigsawsError
from jigsaws_tools.release import discover, read_kinematics, read_transcription
from jigsaws_tools.synth import SynthConfig, write_release
from multitask.train_cli import main as train_main

TRIAL = "Suturing_C002"


@pytest.fixture(scope="module")
def _pristine(tmp_path_factory):
    """A small synthetic release, written once: users B, C, D with two trials each."""
    return write_release(tmp_path_factory.mktemp("pristine") / "Suturing",
                         SynthConfig(users=("B", "C", "D"), trials_per_user=2))


@pytest.fixture
def release(_pristine, tmp_path):
    """A copy of the small release for one test to damage (copied: writing it costs ~1 CPU-s)."""
    return shutil.copytree(_pristine, tmp_path / "Suturing")


def _kinematics(root, name=TRIAL):
    return root / "kinematics/AllGestures" / f"{name}.txt"


def _transcription(root, name=TRIAL):
    return root / "transcriptions" / f"{name}.txt"


def _warnings(caplog):
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]


def _trial(dataset, name=TRIAL):
    return next(t for t in dataset.trials if t.name == name)


@pytest.mark.parametrize("value, problem", [("nan", "non-finite kinematic value"),
                                            ("-1e39", "kinematic value beyond float32's range")])
def test_a_value_the_models_cannot_take_is_refused_with_its_line_column_and_value(
        release, value, problem):
    """1e39 is finite, but infinite in the models' float32: refused as NaN is, not cast."""
    path = _kinematics(release)
    lines = path.read_text().splitlines(keepends=True)
    fields = lines[4].split()
    fields[2] = value
    lines[4] = " ".join(fields) + "\n"
    path.write_text("".join(lines))
    with pytest.raises(FormatError) as raised:
        read_kinematics(path)
    assert str(raised.value).startswith(f"{path}:5: {problem}")
    assert "in column 3" in str(raised.value) and f"(value: {float(value)!r})" in str(raised.value)


# -- item 5: the cache ------------------------------------------------------------------------------
def test_a_release_given_as_a_path_loads_caches_and_fingerprints_as_its_string(release,
                                                                                 tmp_path):
    """``DataConfig(Path(...))``, as Python users write it, is its string: the cache is written
    and read back, with the same fingerprint."""
    as_path, as_str = DataConfig(release), DataConfig(str(release))
    assert as_path == as_str and isinstance(as_path.data_dir, str)
    first = load_dataset(as_path, cache_dir=tmp_path / "cache")
    again = load_dataset(as_str, cache_dir=tmp_path / "cache")
    assert first.fingerprint == again.fingerprint
    assert len(list((tmp_path / "cache").glob("*.npz"))) == 1
    for a, b in zip(first.trials, again.trials):
        np.testing.assert_array_equal(a.inputs, b.inputs)


def test_same_size_edit_with_restored_mtime_is_not_served_stale(release, tmp_path):
    config = DataConfig(str(release))
    before = load_dataset(config, cache_dir=tmp_path / "cache")
    path = _kinematics(release)
    stat = path.stat()
    text = path.read_bytes()
    first = text.index(b"\n")
    line = text[:first].split()
    line[38] = (b"9" * len(line[38]))[:len(line[38])]          # PSM1 x of frame 1, same width
    path.write_bytes(b" ".join(line).ljust(first) + text[first:])
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert path.stat().st_size == stat.st_size and path.stat().st_mtime_ns == stat.st_mtime_ns
    after = load_dataset(config, cache_dir=tmp_path / "cache")
    assert not np.array_equal(_trial(before).inputs, _trial(after).inputs)
    assert len(list((tmp_path / "cache").glob("*.npz"))) == 2


def test_fingerprint_ignores_location_but_not_content(release, tmp_path):
    config = DataConfig(str(release))
    copy = shutil.copytree(release, tmp_path / "copy" / "Suturing")
    assert cache_key(config, discover(release)) == cache_key(DataConfig(str(copy)), discover(copy))
    _transcription(copy).write_bytes(_transcription(copy).read_bytes().replace(b" G2 ", b" G3 ", 1))
    assert cache_key(config, discover(release)) != cache_key(DataConfig(str(copy)), discover(copy))


def _cached(release, cache):
    config = DataConfig(str(release))
    load_dataset(config, cache_dir=cache)
    key = cache_key(config, discover(release))
    return config, cache / f"{key}.npz", cache / f"{key}.json"


def _truncate(path):
    path.write_bytes(path.read_bytes()[:len(path.read_bytes()) // 2])


def _drop_npz_key(path):
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files if k != "progress"}
    np.savez(path, **arrays)


def _flip_a_byte(path):
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("damage, damaged_file", [
    (_truncate, "npz"), (_drop_npz_key, "npz"), (_flip_a_byte, "npz"), (_truncate, "json"),
])
def test_damaged_cache_entry_is_rebuilt_with_one_warning(release, tmp_path, caplog, damage,
                                                         damaged_file):
    config, npz, meta = _cached(release, tmp_path / "cache")
    reference = load_dataset(config, use_cache=False)
    target = npz if damaged_file == "npz" else meta
    damage(target)
    with caplog.at_level(logging.WARNING):
        rebuilt = load_dataset(config, cache_dir=tmp_path / "cache")
    warned = _warnings(caplog)
    assert len(warned) == 1 and str(target) in warned[0] and "rebuilding" in warned[0]
    for a, b in zip(reference.trials, rebuilt.trials):
        np.testing.assert_array_equal(a.inputs, b.inputs)
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        load_dataset(config, cache_dir=tmp_path / "cache")          # repaired: silent again
    assert not _warnings(caplog)


def test_unwritable_cache_folder_is_one_warning(release, tmp_path, caplog, monkeypatch):
    config = DataConfig(str(release))

    def refuse(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(tempfile, "mkstemp", refuse)          # a read-only folder, even for root
    with caplog.at_level(logging.WARNING):
        dataset = load_dataset(config, cache_dir=tmp_path / "cache")
    assert len(dataset.trials) == 6
    warned = _warnings(caplog)
    assert len(warned) == 1 and "Permission denied" in warned[0] and "without it" in warned[0]


def test_cache_folder_below_a_file_is_one_warning(release, tmp_path, caplog):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with caplog.at_level(logging.WARNING):
        dataset = load_dataset(DataConfig(str(release)), cache_dir=blocker / "cache")
    assert len(dataset.trials) == 6 and len(_warnings(caplog)) == 1


def test_full_disk_leaves_no_partial_entry(release, tmp_path, caplog, monkeypatch):
    def full(file, **arrays):
        file.write(b"PK partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(dataset_module.np, "savez", full)
    with caplog.at_level(logging.WARNING):
        load_dataset(DataConfig(str(release)), cache_dir=tmp_path / "cache")
    assert len(_warnings(caplog)) == 1 and "No space left" in _warnings(caplog)[0]
    assert not list((tmp_path / "cache").iterdir())


def test_training_goes_on_without_a_writable_cache(release, tmp_path, monkeypatch, caplog):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(blocker / "cache"))
    with caplog.at_level(logging.WARNING):
        assert train_main(["--data-dir", str(release), "--variant", "A", "--hidden", "8",
                           "--sweeps", "1", "--no-plots", "--out", str(tmp_path / "run")]) == 0
    assert [m for m in _warnings(caplog) if str(blocker) in m] == [
        f"cannot write the cache folder {blocker / 'cache'} (Not a directory); "
        "continuing without it"]


# -- item 7: data safety ------------------------------------------------------------------------------
def test_synth_refuses_a_non_empty_target(release, capsys):
    before = {p: p.read_bytes() for p in release.rglob("*") if p.is_file()}
    assert tools_main(["synth", str(release), "--seed", "5"]) == 2
    err = capsys.readouterr().err
    assert "not an empty folder" in err and str(release) in err and "Traceback" not in err
    assert before == {p: p.read_bytes() for p in release.rglob("*") if p.is_file()}


def test_synth_writes_into_an_empty_folder_but_not_onto_a_file(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert tools_main(["synth", str(tmp_path / "empty")]) == 0
    (tmp_path / "file").write_text("keep me")
    assert tools_main(["synth", str(tmp_path / "file")]) == 2
    assert (tmp_path / "file").read_text() == "keep me"


def _skipped_with_one_warning(release, caplog, reason):
    with caplog.at_level(logging.WARNING):
        index = discover(release)
    warned = [m for m in _warnings(caplog) if TRIAL in m]
    assert len(warned) == 1 and reason in warned[0] and "\n" not in warned[0]
    assert TRIAL not in [t.name for t in index.trials] and len(index.trials) == 5
    assert any(reason in u for u in index.unusable)


def test_kinematics_path_that_is_a_folder(release, caplog, capsys):
    path = _kinematics(release)
    path.unlink()
    path.mkdir()
    _skipped_with_one_warning(release, caplog, "a folder, not a file")
    with pytest.raises(FormatError, match="a folder") as error:
        read_kinematics(path)
    assert error.value.path == path
    assert tools_main(["inspect", str(release)]) == 0
    assert "5 complete trials" in capsys.readouterr().out


def test_kinematics_symlink_loop(release, caplog):
    path = _kinematics(release)
    path.unlink()
    path.symlink_to(path.name)                             # points at itself
    _skipped_with_one_warning(release, caplog, "link loop")
    with pytest.raises(FormatError, match="link loop"):
        read_kinematics(path)


def test_empty_kinematics_file(release, caplog):
    _kinematics(release).write_bytes(b"")
    _skipped_with_one_warning(release, caplog, "empty file (0 bytes)")
    with pytest.raises(FormatError, match="empty") as error:
        read_kinematics(_kinematics(release))
    assert TRIAL in str(error.value) and "transcription" not in str(error.value)


def test_upper_case_extension_is_read_with_a_warning(release, caplog):
    for path in (_kinematics(release), _transcription(release)):
        path.rename(path.with_suffix(".TXT"))
    with caplog.at_level(logging.WARNING):
        index = discover(release)
    assert TRIAL in [t.name for t in index.trials] and len(index.trials) == 6
    warned = [m for m in _warnings(caplog) if ".TXT" in m]
    assert len(warned) == 2 and all(f"{TRIAL}.TXT" in m for m in warned)
    assert len(load_dataset(DataConfig(str(release)), use_cache=False).trials) == 6


def test_byte_order_mark_is_read_with_a_warning(release, caplog):
    expected_kinematics = read_kinematics(_kinematics(release))
    expected_segments = read_transcription(_transcription(release))
    for path in (_kinematics(release), _transcription(release)):
        path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    with caplog.at_level(logging.WARNING):
        np.testing.assert_array_equal(read_kinematics(_kinematics(release)), expected_kinematics)
        assert read_transcription(_transcription(release)) == expected_segments
    warned = _warnings(caplog)
    assert len(warned) == 2 and all("byte-order mark" in m and TRIAL in m for m in warned)


def test_release_with_one_user(release, tmp_path, capsys):
    for folder in ("kinematics/AllGestures", "transcriptions"):
        for path in (release / folder).glob("Suturing_[C-I]*.txt"):
            path.unlink()
    with pytest.raises(JigsawsError, match="leave-one-user-out needs at least two users"):
        load_dataset(DataConfig(str(release)), use_cache=False).louo_split("B")
    assert train_main(["--data-dir", str(release), "--test-user", "B", "--hidden", "8",
                       "--sweeps", "1", "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "at least two users" in err and str(release) in err and "Traceback" not in err
    spec = tmp_path / "one.toml"
    spec.write_text(f'data_dir = "{release}"\n')
    from multitask.grid.cli import main as grid_main

    assert grid_main(["--spec", str(spec), "--out", str(tmp_path / "grid"), "--dry-run"]) == 2
    assert "at least two users" in capsys.readouterr().err


def test_folder_of_another_task_says_which_task(release, tmp_path, capsys):
    assert tools_main(["inspect", str(release), "--task", "Knot_Tying"]) == 2
    err = capsys.readouterr().err
    assert "Knot_Tying trial" in err and "it holds Suturing trials" in err


def test_bad_task_file_on_every_command_is_a_clear_error(release, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "X"\n[gestures]\nG1 = "a"\n[progress]\nstages = [{ gestures = ["G1"] }]\n')
    assert tools_main(["inspect", str(release), "--task-file", str(bad)]) == 2
    assert train_main(["--data-dir", str(release), "--task-file", str(bad), "--out",
                       str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert err.count(f"{bad}: progress.stages: progress needs at least two stages") == 2
    assert "Traceback" not in err
