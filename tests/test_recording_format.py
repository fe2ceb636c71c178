"""Recordings in another layout (issue #31): a synthetic release converted to a robot's CSVs at
100 Hz with its own column names, read through a recording format file, trained on and
predicted; bad format files and bad recordings give one-line errors (exit 2)."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from jigsaws_tools.annotations import amendments, apply_amendments
from jigsaws_tools.errors import DefinitionError, FormatError, JigsawsError
from jigsaws_tools.features import FEATURE_NAMES, feature_names
from jigsaws_tools.gestures import GESTURES
from jigsaws_tools.dataset import check_format_fits
from jigsaws_tools.preprocessing import PreprocessConfig, decimation
from jigsaws_tools.recording_format import JIGSAWS_FORMAT, read_format_file
from jigsaws_tools.release import (discover, frame_labels, read_kinematics, read_recording,
                                   read_transcription)
from jigsaws_tools.task_definition import SUTURING
from jigsaws_tools.cli.main import main as tools_main
from multitask.inference.evaluate_cli import main as evaluate_main
from multitask.inference.predict_cli import main as predict_main
from multitask.inference.trained_run import load_run
from multitask.train_cli import main as train_main
from tests.robot_recordings import (COLUMNS, FORMAT, RATE, USERS, _upsample,
                                   write_robot_folder)



@pytest.fixture(scope="module")
def robot_dir(synth_dir, tmp_path_factory):
    """Users B-E of the synthetic release as the robot's data folder, and its format file."""
    return write_robot_folder(synth_dir, tmp_path_factory.mktemp("robot"))


@pytest.fixture(scope="module")
def robot_run(robot_dir):
    out = robot_dir / "run"
    assert train_main(["--data-dir", str(robot_dir / "data"), "--format",
                       str(robot_dir / "my_robot.toml"), "--variant", "APc", "--hidden", "16",
                       "--epochs", "6", "--test-user", "B", "--no-plots", "--threads", "1",
                       "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def release_run(synth_dir, tmp_path_factory):
    """A tiny run trained on the synthetic release, so in the release's format."""
    out = tmp_path_factory.mktemp("release_run") / "run"
    assert train_main(["--data-dir", str(synth_dir), "--variant", "APc", "--hidden", "16",
                       "--epochs", "1", "--test-user", "B", "--no-plots", "--threads", "1",
                       "--out", str(out)]) == 0
    return out


def test_jigsaws_format_is_the_release():
    assert JIGSAWS_FORMAT.columns == FEATURE_NAMES and JIGSAWS_FORMAT.rate_hz == 30
    assert JIGSAWS_FORMAT.is_default and not JIGSAWS_FORMAT.header


def test_decimation_keeps_the_model_rate_and_refuses_other_ratios():
    config = PreprocessConfig()
    assert decimation(config, 30) == config.resample_factor
    assert decimation(config, 100) == 20 and decimation(config, 5) == 1
    for rate in (33.0, 7.5, 2.5):
        with pytest.raises(ValueError, match=f"sample rate {rate:g} Hz"):
            decimation(config, rate)


@pytest.mark.slow
def test_reads_and_discovers_the_declared_layout(robot_dir, synth_dir):
    fmt = read_format_file(robot_dir / "my_robot.toml")
    index = discover(robot_dir / "data", recording_format=fmt)
    assert index.users == USERS and len(index.trials) == 5 * len(USERS)
    b1 = next(t for t in index.trials if (t.user, t.trial) == ("B", 1))
    values = read_recording(b1.kinematics, fmt, feature_names("psm_pos_vel_grip"))
    original = read_kinematics(next(t for t in discover(synth_dir).trials
                                    if t.name == "Suturing_B001").kinematics)
    assert values.shape == (len(_upsample(original)[0]), 14)
    np.testing.assert_allclose(values[::10], original[::3][:len(values[::10]),
                               [JIGSAWS_FORMAT.columns.index(f) for f in COLUMNS]], atol=1e-6)


def test_trains_and_predicts_a_100hz_recording(robot_run, robot_dir, synth_dir, tmp_path):
    recording = robot_dir / "data" / "recordings" / "Suturing-B-1.csv"
    out = tmp_path / "pred"
    assert predict_main([str(robot_run), str(recording), "--out", str(out), "--no-plots"]) == 0
    table = pd.read_csv(out / "Suturing-B-1.csv")
    rows = len(pd.read_csv(recording))
    assert len(table) == rows
    # held-out user B: the row labels are well above chance
    segments = read_transcription(robot_dir / "data" / "labels" / "Suturing-B-1.txt")
    truth = frame_labels(segments, rows)
    labelled = truth >= 0
    predicted = np.array([GESTURES.index(g) for g in table["gesture"]])
    accuracy = 100 * np.mean(predicted[labelled] == truth[labelled])
    majority = 100 * np.bincount(truth[labelled]).max() / labelled.sum()
    assert accuracy > majority + 15, (accuracy, majority)
    # the API gives the same, and the same recording at 30 Hz in the release's format nearly so
    run = load_run(robot_run)
    api = run.predict(recording)
    np.testing.assert_array_equal(api.labels("gesture"), predicted)
    release_file = next(t for t in discover(synth_dir).trials
                        if t.name == "Suturing_B001").kinematics
    at_30hz = run.predict(release_file, recording_format="jigsaws")
    same_time = at_30hz.labels("gesture")[(np.arange(rows) * 30) // RATE]
    assert np.mean(same_time == predicted) > 0.8


def _error_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


def _bad_copy(robot_dir, tmp_path, edit) -> str:
    table = pd.read_csv(robot_dir / "data" / "recordings" / "Suturing-B-1.csv", dtype=str)
    path = tmp_path / "bad.csv"
    edit(table).to_csv(path, index=False)
    return str(path)


@pytest.mark.parametrize("edit, expected", [
    (lambda t: t.rename(columns={"arm1_pos_x": "x"}), ["'arm1_pos_x'", "psm1_pos_x", ":1:"]),
    (lambda t: t.assign(time_s=(t.time_s.astype(float) * RATE / 30).map(str)),
     ["'time_s'", "30 Hz", "rate_hz = 100"]),
    (lambda t: t.head(12), ["12 frames", "low-pass"]),
    (lambda t: t.assign(arm2_gripper=t.arm2_gripper.where(t.index != 40, "abc")),
     [":42:", "'abc'", "arm2_gripper"]),
    (lambda t: t.rename(columns={"time_s": "t"}), ["'time_s'", "time_column"]),
])
def test_a_bad_recording_is_one_line_naming_file_column_and_value(robot_run, robot_dir, tmp_path,
                                                                  capsys, edit, expected):
    bad = _bad_copy(robot_dir, tmp_path, edit)
    assert predict_main([str(robot_run), bad, "--out", str(tmp_path / "out"), "--no-plots"]) == 2
    err = _error_line(capsys)
    assert bad in err and all(e in err for e in expected), err
    assert not (tmp_path / "out" / "bad.csv").exists()


@pytest.mark.parametrize("change, expected", [
    # a valid file, but 5 Hz samples cannot be taken one in k from 33 Hz
    (("rate_hz = 100", "rate_hz = 33"), ["rate_hz", "33", "whole multiple"]),
    (("header = true", "header = false"), ["columns", "with header = false"]),
    (("delimiter = \",\"", "delimiter = \"|\""), ["delimiter", "'|'"]),
    (("psm1_pos_x =", "psm9_pos_x ="), ["features.psm9_pos_x", "not a model feature"]),
    (('trial = "{task}-{user}-{trial}"', 'trial = "{task}-{trial}"'), ["files.trial"]),
    (("rate_hz = 100", "rate = 100"), ["rate", "unknown key"]),
    (("header = true", 'header = false\ncolumns = ["t"]'),
     ["time_column", "'time_s'", "not one of columns"]),
    # two features read one column, or a feature the time column
    (('psm2_pos_x = "arm2_pos_x"', 'psm2_pos_x = "arm1_pos_x"'),
     ["features.psm2_pos_x", "features.psm1_pos_x", "'arm1_pos_x'"]),
    (('psm1_pos_x = "arm1_pos_x"', 'psm1_pos_x = "time_s"'),
     ["features.psm1_pos_x", "time_column", "'time_s'"]),
])
def test_a_bad_format_file_is_one_line_naming_file_key_and_value(robot_run, robot_dir, tmp_path,
                                                                 capsys, change, expected):
    bad = tmp_path / "bad.toml"
    bad.write_text(FORMAT.replace(*change))
    if "rate_hz = 33" not in change:
        with pytest.raises(DefinitionError):
            read_format_file(bad)
    recording = robot_dir / "data" / "recordings" / "Suturing-B-1.csv"
    assert predict_main([str(robot_run), str(recording), "--format", str(bad), "--out",
                         str(tmp_path / "out")]) == 2
    err = _error_line(capsys)
    assert str(bad) in err and all(e in err for e in expected), err
    assert train_main(["--data-dir", str(robot_dir / "data"), "--format", str(bad), "--epochs",
                       "1", "--out", str(tmp_path / "run")]) == 2
    assert str(bad) in _error_line(capsys) and not (tmp_path / "run").exists()


def test_a_release_file_of_another_width_is_refused(tmp_path):
    path = tmp_path / "narrow.txt"
    path.write_text("1 2 3\n4 5 6\n")
    with pytest.raises(FormatError, match=r"narrow.txt:1: expected 76 kinematic columns"):
        read_recording(path, JIGSAWS_FORMAT, ["psm1_pos_x"])


def test_a_folder_of_another_layout_without_format_points_to_it(robot_dir, tmp_path, capsys):
    data, out = robot_dir / "data", tmp_path / "run"
    assert train_main(["--data-dir", str(data), "--hidden", "16", "--epochs", "1", "--out",
                       str(out)]) == 2
    err = _error_line(capsys)
    assert str(data) in err and "--format" in err and "Your own recordings" in err, err
    assert not out.exists()
    release = tmp_path / "release"                # the release's folders, the robot's files
    shutil.copytree(data / "recordings", release / JIGSAWS_FORMAT.recordings)
    shutil.copytree(data / "labels", release / JIGSAWS_FORMAT.transcriptions)
    with pytest.raises(JigsawsError) as error:
        discover(release)
    message = str(error.value)
    assert "\n" not in message and "--format" in message, message
    assert str(release / JIGSAWS_FORMAT.recordings) in message


def test_a_recording_of_another_layout_without_format_points_to_it(release_run, robot_dir,
                                                                  tmp_path, capsys):
    recording, out = robot_dir / "data" / "recordings" / "Suturing-B-1.csv", tmp_path / "out"
    assert predict_main([str(release_run), str(recording), "--out", str(out), "--no-plots"]) == 2
    err = _error_line(capsys)
    assert f"{recording}:1:" in err and f"{len(JIGSAWS_FORMAT.columns)} kinematic columns" in err
    assert "--format" in err and "Your own recordings" in err, err
    assert not (out / recording.name).exists()


def test_evaluate_scores_labelled_recordings_of_another_layout(release_run, robot_dir, tmp_path,
                                                              capsys, caplog):
    """A run trained on the release scores the robot's labelled recordings given --format: other
    data than its training data, so a warning and trained_on_this_data false."""
    data, out = robot_dir / "data", tmp_path / "evaluation"
    assert evaluate_main([str(release_run), "--data-dir", str(data), "--out", str(out)]) == 2
    assert "--format" in _error_line(capsys) and not out.exists()
    assert evaluate_main([str(release_run), "--data-dir", str(data), "--format",
                          str(robot_dir / "my_robot.toml"), "--out", str(out), "--no-plots"]) == 0
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["trained_on_this_data"] is False and "held-out scores" in caplog.text
    trials = discover(data, recording_format=read_format_file(robot_dir / "my_robot.toml")).trials
    assert sorted(p.stem for p in (out / "predictions").glob("*.csv")) == sorted(
        t.name for t in trials if t.user == "B")


def test_a_row_of_another_width_in_a_given_format_gets_no_format_hint(robot_dir, tmp_path):
    lines = (robot_dir / "data" / "recordings" / "Suturing-B-1.csv").read_text().splitlines()
    lines[5] += ",1.0"
    wide = tmp_path / "wide.csv"
    wide.write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError, match=r"wide\.csv:6: expected") as error:
        read_recording(wide, read_format_file(robot_dir / "my_robot.toml"),
                       feature_names("psm_pos_vel_grip"))
    assert "--format" not in str(error.value)


def _edited(robot_dir, tmp_path, line: int, old: bytes, new: bytes) -> str:
    """A copy of the robot's trial B1 whose 1-based ``line`` has ``old`` replaced by ``new``."""
    lines = (robot_dir / "data" / "recordings" / "Suturing-B-1.csv").read_bytes().split(b"\n")
    assert old in lines[line - 1]
    lines[line - 1] = lines[line - 1].replace(old, new, 1)
    path = tmp_path / "edited.csv"
    path.write_bytes(b"\n".join(lines))
    return str(path)


def test_a_byte_that_is_not_utf8_is_one_line_naming_file_and_line(robot_run, robot_dir, tmp_path,
                                                                  capsys):
    """A header saved in Latin-1 (``°`` is byte 0xb0 there), not the codec's bare message."""
    bad = _edited(robot_dir, tmp_path, 1, b"battery", "battery_°C".encode("latin-1"))
    assert predict_main([str(robot_run), bad, "--out", str(tmp_path / "out"), "--no-plots"]) == 2
    err = _error_line(capsys)
    assert f"{bad}:1: not UTF-8" in err and r"b'\xb0'" in err, err


@pytest.mark.parametrize("line, old, new", [
    (7, b",", ",\xe9".encode("latin-1")),          # a Latin-1 byte in a row
    (9, b"0.", b"0_0."),                           # float() reads 0_0.07 as 0.07, numpy not
    (11, b"0.", "\u0660.".encode()),               # nor an Arabic-Indic digit
])
def test_a_value_numpy_cannot_read_is_named_with_its_line(robot_dir, tmp_path, line, old, new):
    bad = _edited(robot_dir, tmp_path, line, old, new)
    with pytest.raises(FormatError, match=rf"edited\.csv:{line}: ") as error:
        read_recording(bad, read_format_file(robot_dir / "my_robot.toml"),
                       feature_names("psm_pos_vel_grip"))
    assert "\n" not in str(error.value)


def test_rows_numpy_refuses_for_a_reason_not_found_are_named_by_file(robot_dir, monkeypatch):
    """Whatever ``numpy.loadtxt`` refuses that no row check explains is still one line naming
    the file, never numpy's bare message."""
    def refuse(*args, **kwargs):
        raise ValueError("something numpy refuses\nover two lines")

    recording = robot_dir / "data" / "recordings" / "Suturing-B-1.csv"
    monkeypatch.setattr(np, "loadtxt", refuse)
    with pytest.raises(FormatError) as error:
        read_recording(recording, read_format_file(robot_dir / "my_robot.toml"))
    message = str(error.value)
    assert message.startswith(f"{recording}: ") and "something numpy refuses" in message
    assert "\n" not in message


@pytest.mark.parametrize("comment", [b"# robot paused", b"#"])
def test_a_comment_line_is_refused_on_its_own_line(robot_dir, tmp_path, comment):
    """numpy would skip it but count it out of the rows, so every later error's line and every
    transcription row would be off by one: a recording has no comment lines."""
    bad = _edited(robot_dir, tmp_path, 3, b"0.01", comment + b"\n0.01")   # before line 3
    with pytest.raises(FormatError, match=r"edited\.csv:3: a comment line"):
        read_recording(bad, read_format_file(robot_dir / "my_robot.toml"))


def test_a_bad_value_after_blank_lines_is_named_on_its_own_line(robot_dir, tmp_path):
    """Blank lines are skipped, and still counted in the line an error names."""
    recording = robot_dir / "data" / "recordings" / "Suturing-B-1.csv"
    lines = recording.read_text().split("\n")
    fields = lines[10].split(",")
    lines[10] = ",".join([fields[0], "nan", *fields[2:]])        # line 11
    lines[4:4] = ["", "   "]                                    # it becomes line 13
    bad = tmp_path / "gaps.csv"
    bad.write_text("\n".join(lines))
    with pytest.raises(FormatError, match=r"gaps\.csv:13: non-finite"):
        read_recording(bad, read_format_file(robot_dir / "my_robot.toml"))


def _times(edit):
    """A ``_bad_copy`` edit giving the time column ``edit(times)`` (float seconds)."""
    return lambda t: t.assign(time_s=[f"{v:.8f}" for v in edit(t.time_s.astype(float).values)])


def _read_robot(path, robot_dir) -> np.ndarray:
    return read_recording(path, read_format_file(robot_dir / "my_robot.toml"),
                          feature_names("psm_pos_vel_grip"))


def _late(row: int, periods: float):
    """A ``_bad_copy`` edit stamping ``row`` (0-based) ``periods`` sample periods late."""
    return _times(lambda s: s + periods / RATE * (np.arange(len(s)) == row))


@pytest.mark.parametrize("edit, row, expected", [
    # a 10 s dropout before row 100: one step of 1001 periods
    (_times(lambda s: s + 10 * (np.arange(len(s)) >= 100)), 100, ["jumps 10.01 s", "0.99 s"]),
    # two samples missing in a row: a step of three periods
    (lambda t: t.drop(index=t.index[[30, 31]]), 30, ["jumps 0.03 s", "3.0 periods"]),
    # one row in 20 lost: each step passes, the fourth loss puts row 76 four periods late
    (lambda t: t.drop(index=t.index[19::20]), 76, ["drifts", "76 rows give 0.76 s"]),
    # a clock 30 % slow: 0.3 periods a row, over 2.5 periods and 1 % at row 9
    (_times(lambda s: 1.3 * s), 9, ["drifts", "9 rows give 0.09 s"]),
    # a clock 4 % slow: 3 % over 1 %, more than 2.5 periods after 84 rows
    (_times(lambda s: 1.04 * s), 84, ["drifts", "84 rows give 0.84 s"]),
    # times going back
    (_late(40, -1.5), 40, ["does not increase", "0.39 s"]),
])
def test_times_off_the_rate_are_refused_at_their_line(robot_dir, tmp_path, edit, row, expected):
    bad = _bad_copy(robot_dir, tmp_path, edit)
    with pytest.raises(FormatError) as error:
        _read_robot(bad, robot_dir)
    message = str(error.value)
    assert message.startswith(f"{bad}:{row + 2}: time column 'time_s' ")   # line 1: the header
    assert "\n" not in message and all(e in message for e in expected), message
    assert "resample" in message


@pytest.mark.parametrize("edit", [
    _times(lambda s: s + np.random.default_rng(0).normal(0, 0.1, len(s)) / RATE),  # jitter
    _late(50, 0.6),                               # a late wake-up
    _late(50, -0.7),                              # an early stamp
    lambda t: t.drop(index=t.index[50]),          # one dropped sample
    _times(lambda s: 1.005 * s),                  # a clock 0.5 % slow
    _times(lambda s: s + 1234.5),                 # times since another origin
])
def test_times_a_real_robot_log_has_pass(robot_dir, tmp_path, edit):
    recording = robot_dir / "data" / "recordings" / "Suturing-B-1.csv"
    read = _read_robot(_bad_copy(robot_dir, tmp_path, edit), robot_dir)
    expected = _read_robot(recording, robot_dir)
    if len(read) < len(expected):                 # the dropped sample
        expected = np.delete(expected, 50, axis=0)
    np.testing.assert_array_equal(read, expected)


@pytest.mark.parametrize("layout", ["my_robot", "jigsaws"])
def test_a_lower_case_user_letter_is_refused_naming_the_file(robot_dir, synth_dir, tmp_path,
                                                              capsys, layout):
    """Read as user ``c``, ``Suturing-c-1`` would be another user than ``C``: with test user C,
    a C trial in the training set."""
    fmt = JIGSAWS_FORMAT if layout == "jigsaws" else read_format_file(robot_dir / "my_robot.toml")
    data = tmp_path / "data"
    shutil.copytree(synth_dir if fmt.is_default else robot_dir / "data", data)
    name = fmt.trial_name(SUTURING, "C", 1) + fmt.extension
    renamed = name.replace("C", "c")
    (data / fmt.recordings / name).rename(data / fmt.recordings / renamed)
    with pytest.raises(FormatError) as error:
        discover(data, recording_format=fmt)
    message = str(error.value)
    assert str(data / fmt.recordings / renamed) in message and "lower case" in message, message
    assert f"rename the file {name}" in message
    options = [] if fmt.is_default else ["--format", str(robot_dir / "my_robot.toml")]
    assert train_main(["--data-dir", str(data), *options, "--test-user", "C", "--epochs", "1",
                       "--out", str(tmp_path / "run")]) == 2
    assert renamed in _error_line(capsys)


@pytest.mark.slow
def test_jigsaws_tools_reads_a_folder_of_another_layout_with_format(robot_dir, tmp_path, capsys):
    data, fmt = str(robot_dir / "data"), str(robot_dir / "my_robot.toml")
    assert tools_main(["inspect", "--data-dir", data, "--format", fmt]) == 0
    out = capsys.readouterr().out
    assert f"{5 * len(USERS)} complete trials" in out and f"frames at {RATE} Hz" in out, out
    assert tools_main(["stages", "--data-dir", data, "--format", fmt]) == 0
    assert f"of {5 * len(USERS)} trials follow the stage order" in capsys.readouterr().out
    png = tmp_path / "labels.png"
    assert tools_main(["plot", "--data-dir", data, "--format", fmt, "--out", str(png)]) == 0
    assert png.is_file()


@pytest.mark.parametrize("command, takes_format", [
    (["inspect"], True), (["stages"], True), (["plot", "--out", "unwritten.png"], True),
    (["amendments"], False),
])
def test_a_folder_of_another_layout_is_pointed_to_format_by_commands_that_take_it(
        robot_dir, capsys, command, takes_format):
    assert tools_main([*command, "--data-dir", str(robot_dir / "data")]) == 2
    err = _error_line(capsys)
    assert str(robot_dir / "data") in err and "Your own recordings" in err, err
    assert ("--format" in err) == takes_format, err
    assert takes_format or "reads the JIGSAWS release's layout only" in err


def test_a_feature_may_take_an_unread_features_own_column_but_not_a_read_ones(robot_dir, tmp_path,
                                                                               capsys):
    """Unlisted, psm2_pos_x reads the column of its own name: mapping psm1_pos_x there feeds the
    model one signal twice, while mapping psm1_rot_11 there harms no run that does not read it."""
    unlisted = FORMAT.replace('psm2_pos_x = "arm2_pos_x"\n', "")
    unread = tmp_path / "unread.toml"
    unread.write_text(unlisted.replace("[features]\n", '[features]\npsm1_rot_11 = "psm2_pos_x"\n'))
    check_format_fits(read_format_file(unread), "psm_pos_vel_grip", PreprocessConfig())
    with pytest.raises(DefinitionError, match=r"psm2_pos_x \(not in \[features\]"):
        check_format_fits(read_format_file(unread), "all", PreprocessConfig())
    bad = tmp_path / "bad.toml"
    bad.write_text(unlisted.replace('psm1_pos_x = "arm1_pos_x"', 'psm1_pos_x = "psm2_pos_x"'))
    assert train_main(["--data-dir", str(robot_dir / "data"), "--format", str(bad), "--epochs",
                       "1", "--out", str(tmp_path / "run")]) == 2
    err = _error_line(capsys)
    assert str(bad) in err and "features.psm1_pos_x" in err, err
    assert "also the column of psm2_pos_x (not in [features]" in err and "'psm2_pos_x'" in err


def test_the_papers_amendments_never_relabel_a_recording_at_another_rate():
    """The amendments are frame ranges of the release's 30 Hz trials: a trial of such a name at
    another rate is refused under them, not relabelled at the wrong rows."""
    amendment = amendments("revised", SUTURING)[0]
    labels = np.zeros(amendment.end + 10, dtype=int)
    amended, _ = apply_amendments(amendment.trial, labels, "revised", SUTURING, 30.0)
    assert np.any(amended != labels)
    with pytest.raises(JigsawsError, match=rf"{amendment.trial}.* at 100 Hz"):
        apply_amendments(amendment.trial, labels, "revised", SUTURING, float(RATE))
    kept, _ = apply_amendments(amendment.trial, labels, "original", SUTURING, float(RATE))
    assert np.array_equal(kept, labels)


# -- own-format runs exported and streamed (issue #48) ---------------------------------------------
@pytest.fixture(scope="module")
def robot_forward_run(robot_dir):
    """A tiny forward run on the robot's 100 Hz CSVs: streamable."""
    out = robot_dir / "forward_run"
    assert train_main(["--data-dir", str(robot_dir / "data"), "--format",
                       str(robot_dir / "my_robot.toml"), "--variant", "APc", "--hidden", "8",
                       "--epochs", "2", "--direction", "forward", "--test-user", "B",
                       "--no-plots", "--threads", "1", "--out", str(out)]) == 0
    return out


@pytest.mark.slow
def test_an_own_format_run_streams_its_recordings(robot_forward_run, robot_dir, tmp_path):
    recording = robot_dir / "data" / "recordings" / "Suturing-B-1.csv"
    out = tmp_path / "stream"
    assert predict_main([str(robot_forward_run), str(recording), "--stream", "--no-plots",
                         "--out", str(out)]) == 0
    table = pd.read_csv(out / "Suturing-B-1.csv")
    assert len(table) == len(pd.read_csv(recording))           # one row per 100 Hz row
    assert np.diff(table["sample"].drop_duplicates()).tolist() == [1] * (table["sample"].max())
    run = load_run(robot_forward_run)
    causal = run.predict(recording, causal=True)               # the whole-sequence causal pass
    np.testing.assert_array_equal(causal.labels("gesture"),
                                  [GESTURES.index(g) for g in table["gesture"]])
    assert causal.sample_frames[1] - causal.sample_frames[0] == RATE // 5


def test_an_own_format_run_exports_a_savedmodel_of_its_format(robot_run, robot_dir, tmp_path):
    import tensorflow as tf

    from multitask.inference.export_cli import main as export_main

    recording = robot_dir / "data" / "recordings" / "Suturing-B-1.csv"
    assert export_main([str(robot_run), "--out", str(tmp_path / "saved")]) == 0
    description = json.loads((tmp_path / "saved" / "assets.extra" / "model.json").read_text())
    run = load_run(robot_run)
    assert description["recording"]["rate_hz"] == RATE
    assert description["recording"]["columns"] == list(COLUMNS.values())   # the run's features
    assert description["preprocessing"]["resample_step"] == RATE // 5
    model = tf.saved_model.load(str(tmp_path / "saved"))
    inputs = run.read_inputs(recording)                        # [rows, 14] in those columns
    served = model.signatures["serving_default"](kinematics=tf.constant(inputs))
    offline = run.predict(recording)
    assert len(served["frame"]) == len(inputs)
    np.testing.assert_array_equal(served["gesture"].numpy(), offline.labels("gesture"))
    with pytest.raises((ValueError, tf.errors.InvalidArgumentError)):   # 13 columns, not 14
        model.signatures["serving_default"](kinematics=tf.constant(inputs[:, :-1]))


def _format_at(rate: int, **changes) -> str:
    text = FORMAT.replace(f"rate_hz = {RATE}", f"rate_hz = {rate}")
    for old, new in changes.items():
        text = text.replace(old, new)
    return text


def test_times_at_another_rate_name_the_rate_they_fit(robot_dir, tmp_path):
    (tmp_path / "at50.toml").write_text(_format_at(50))
    recording = robot_dir / "data" / "recordings" / "Suturing-B-1.csv"
    with pytest.raises(FormatError) as error:
        read_recording(recording, read_format_file(tmp_path / "at50.toml"))
    message = str(error.value)
    assert "its times fit 100 Hz" in message and "rate_hz = 100" in message, message
    assert "\n" not in message


def test_a_gap_at_the_formats_rate_is_called_a_gap(robot_dir, tmp_path):
    bad = _bad_copy(robot_dir, tmp_path, lambda t: t.drop(index=t.index[30:40]))
    with pytest.raises(FormatError, match="a gap in a recording at 100 Hz"):
        _read_robot(bad, robot_dir)


def test_a_comment_before_the_header_says_comments_are_not_allowed(robot_dir, tmp_path):
    recording = robot_dir / "data" / "recordings" / "Suturing-B-1.csv"
    commented = tmp_path / "commented.csv"
    commented.write_text("# recorded 2026-11-27 on arm 1\n" + recording.read_text())
    with pytest.raises(FormatError, match=r"commented\.csv:1: a comment line: comments are not "
                                          r"allowed"):
        _read_robot(commented, robot_dir)


def test_inspect_names_labels_no_amendment_touches_as_transcribed(robot_dir, synth_dir, capsys):
    assert tools_main(["inspect", "--data-dir", str(robot_dir / "data"), "--format",
                       str(robot_dir / "my_robot.toml")]) == 0
    out = capsys.readouterr().out
    assert "revised annotations" not in out and "labels as transcribed" in out, out
    assert tools_main(["inspect", "--data-dir", str(synth_dir)]) == 0
    assert "(revised annotations: " in capsys.readouterr().out      # the release's trial names


@pytest.mark.parametrize("rate, step", [(30, 6), (50, 10), (100, 20)])
def test_the_printed_configuration_gives_the_step_at_the_formats_rate(tmp_path, rate, step):
    from baseline.config import RunConfig
    from jigsaws_tools.dataset import DataConfig

    (tmp_path / "fmt.toml").write_text(_format_at(rate))
    fmt = read_format_file(tmp_path / "fmt.toml")
    text = RunConfig(DataConfig(str(tmp_path), recording_format=fmt)).describe()
    line = next(line for line in text.splitlines() if line.startswith("data.preprocessing:"))
    assert f"rate_hz={rate}" in text
    assert (f"one sample in {step}" in line) == (step != 6), line
