"""The synthetic release round-trips through the reader; bad input raises named errors."""
import filecmp
import shutil

import numpy as np
import pytest

from jigsaws_tools.dataset import DataConfig, load_dataset
from jigsaws_tools.errors import FormatError, JigsawsError, ReleaseNotFoundError
from jigsaws_tools.features import FEATURE_SETS
from jigsaws_tools.release import (discover, frame_labels, read_kinematics, read_meta,
                                   read_transcription, meta_path)
from jigsaws_tools.synth import SynthConfig, synth_trial, write_release


def test_synthetic_release_round_trips(synth_dir):
    index = discover(synth_dir)
    assert len(index.trials) == 40 and index.users == tuple("BCDEFGHI")
    assert not index.missing_kinematics and not index.missing_transcription
    kinematics, lines = synth_trial(SynthConfig(seed=0), 0, 1)
    b001 = index.trials[0]
    np.testing.assert_allclose(read_kinematics(b001.kinematics), kinematics, atol=1e-8)
    assert [(s.start, s.end, s.gesture) for s in read_transcription(b001.transcription)] == lines
    assert read_meta(meta_path(synth_dir))["Suturing_B001"].skill == "N"
    assert lines[0][2] == "G1" and lines[-1][2] == "G11"


@pytest.mark.slow
def test_same_seed_same_files(tmp_path, synth_dir):
    again = write_release(tmp_path / "again", SynthConfig(seed=0))
    for sub in ("kinematics/AllGestures", "transcriptions"):
        cmp = filecmp.dircmp(synth_dir / sub, again / sub)
        assert not cmp.diff_files and not cmp.left_only and not cmp.right_only
    other, _ = synth_trial(SynthConfig(seed=1), 0, 1)
    assert other.shape != read_kinematics(discover(synth_dir).trials[0].kinematics).shape or \
        not np.allclose(other, read_kinematics(discover(synth_dir).trials[0].kinematics))


@pytest.mark.slow
def test_dataset_cache_is_reused_and_keyed_by_options(synth_dir, tmp_path):
    config = DataConfig(str(synth_dir))
    first = load_dataset(config, cache_dir=tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 1
    second = load_dataset(config, cache_dir=tmp_path)
    for a, b in zip(first.trials, second.trials):
        np.testing.assert_array_equal(a.inputs, b.inputs)
        np.testing.assert_array_equal(a.progress, b.progress)
    assert second.fingerprint == first.fingerprint == load_dataset(config,
                                                                  use_cache=False).fingerprint
    other = load_dataset(DataConfig(str(synth_dir), feature_set="psm_all"), cache_dir=tmp_path)
    assert other.fingerprint != first.fingerprint
    load_dataset(DataConfig(str(synth_dir), annotations="original"), cache_dir=tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 3
    assert not list(tmp_path.glob("*.tmp"))


def test_feature_sets(synth_dir):
    ds = load_dataset(DataConfig(str(synth_dir), feature_set="all"), use_cache=False)
    assert ds.num_features == 76
    assert len(FEATURE_SETS["psm_pos_vel_grip"]) == 14
    with pytest.raises(JigsawsError, match="unknown feature set"):
        DataConfig(str(synth_dir), feature_set="nope")


@pytest.fixture
def broken(tmp_path, synth_dir):
    """A writable copy of the synthetic release to damage."""
    return shutil.copytree(synth_dir, tmp_path / "Suturing")


def _rewrite_line(path, number, new):
    lines = path.read_bytes().decode().splitlines(keepends=True)
    lines[number - 1] = new
    path.write_bytes("".join(lines).encode())


def test_missing_folder_explains_layout(tmp_path):
    with pytest.raises(ReleaseNotFoundError, match="kinematics/AllGestures"):
        discover(tmp_path / "nowhere")


def test_wrong_column_count(broken):
    path = broken / "kinematics/AllGestures/Suturing_C002.txt"
    _rewrite_line(path, 17, "1.0 2.0 3.0\n")
    with pytest.raises(FormatError) as e:
        read_kinematics(path)
    assert e.value.line == 17 and e.value.value == 3 and "Suturing_C002" in str(e.value)


def test_non_numeric_value(broken):
    path = broken / "kinematics/AllGestures/Suturing_C002.txt"
    _rewrite_line(path, 5, " ".join(["0.5"] * 40 + ["abc"] + ["0.5"] * 35) + "\n")
    with pytest.raises(FormatError) as e:
        read_kinematics(path)
    assert (e.value.line, e.value.value) == (5, "abc") and "column 41" in str(e.value)


@pytest.mark.parametrize("line, problem", [
    ("10 20 G7 \r\n", "unknown Suturing gesture"),
    ("50 40 G2 \r\n", "1 <= start <= end"),
    ("x 40 G2 \r\n", "non-integer"),
])
def test_bad_transcription_lines(broken, line, problem):
    path = broken / "transcriptions/Suturing_D001.txt"
    _rewrite_line(path, 2, line)
    with pytest.raises(FormatError, match=problem) as e:
        read_transcription(path)
    assert e.value.line == 2 and "Suturing_D001" in str(e.value)


def test_overlapping_and_out_of_range_segments(broken):
    path = broken / "transcriptions/Suturing_D001.txt"
    first = read_transcription(path)[0]
    _rewrite_line(path, 2, f"{first.end} {first.end + 30} G5 \r\n")
    with pytest.raises(FormatError, match="overlaps") as e:
        read_transcription(path)
    assert e.value.line == 2
    with pytest.raises(FormatError, match="beyond the 10 kinematic frames"):
        read_transcription(broken / "transcriptions/Suturing_D002.txt", n_frames=10)


def test_missing_transcription_is_skipped_not_fatal(broken):
    (broken / "transcriptions/Suturing_E003.txt").unlink()
    index = discover(broken)
    assert index.missing_transcription == ("Suturing_E003",) and len(index.trials) == 39
    ds = load_dataset(DataConfig(str(broken)), use_cache=False)
    assert "Suturing_E003" not in [t.name for t in ds.trials]


def test_frame_labels_mark_gaps_unlabelled(synth_dir):
    t = discover(synth_dir).trials[0]
    segments = read_transcription(t.transcription)
    labels = frame_labels(segments, segments[-1].end + 5)
    assert np.all(labels[:segments[0].start - 1] == -1) and np.all(labels[-5:] == -1)


@pytest.mark.slow
def test_cli_commands(synth_dir, tmp_path, capsys):
    from jigsaws_tools.cli.main import main

    assert main(["synth", "--out", str(tmp_path / "s"), "--synthetic-seed", "3"]) == 0
    assert main(["inspect", "--data-dir", str(synth_dir)]) == 0
    out = capsys.readouterr().out
    assert "40 complete trials" in out and "missing kinematics: none" in out
    assert main(["amendments", "--data-dir", str(synth_dir)]) == 0
    assert "skipped: trial absent" not in capsys.readouterr().out  # synthetic trials all exist
    assert main(["plot", "--data-dir", str(synth_dir), "--out", str(tmp_path / "l.png")]) == 0
    assert (tmp_path / "l.png").stat().st_size > 10_000
    assert main(["inspect", "--data-dir", str(tmp_path / "missing")]) == 2
    assert "not found" in capsys.readouterr().err


def test_ensure_release_writes_once_and_keys_by_config(tmp_path):
    from jigsaws_tools.synth import ensure_release

    config = SynthConfig(seed=4, trials_per_user=1, users=("B", "C"))
    first = ensure_release(tmp_path, config)
    stamp = (first / "transcriptions/Suturing_B001.txt").stat().st_mtime_ns
    assert ensure_release(tmp_path, config) == first
    assert (first / "transcriptions/Suturing_B001.txt").stat().st_mtime_ns == stamp
    other = ensure_release(tmp_path, SynthConfig(seed=4, trials_per_user=1, users=("B", "C"),
                                                 noise=0.5))
    assert other != first and len(discover(other).trials) == 2
    assert not list(tmp_path.glob(".synthetic-*"))


@pytest.mark.slow
def test_a_cache_that_cannot_be_written_is_one_warning_with_synthetic_data(
        tmp_path, monkeypatch, caplog):
    """README: "a cache folder that cannot be written costs one warning and no cache". With
    ``--synthetic`` the release itself is written to the cache (issue 66: it stopped the command
    instead): one warning in all, saying where the release goes, for the release and the
    preprocessed data alike; a second command warns again."""
    import logging
    import tempfile

    from jigsaws_tools.dataset import default_cache_dir
    from jigsaws_tools.messages import new_command
    from jigsaws_tools.synth import ensure_release, fallback_cache_dir

    (tmp_path / "a-file").write_text("not a folder")
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(tmp_path / "a-file" / "cache"))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    for _ in range(2):
        new_command()
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            release = ensure_release(default_cache_dir())
            load_dataset(DataConfig(str(release)))
        warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
        assert len(warnings) == 1, warnings
        assert warnings[0].startswith(f"cannot write the cache folder {tmp_path / 'a-file'}")
        assert f"written to {fallback_cache_dir()} instead" in warnings[0]
        assert release.is_relative_to(tmp_path / "tmp") and discover(release).users
