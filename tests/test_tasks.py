"""Tasks as data: the definitions, their loader, Suturing's labels unchanged, every task end to end."""
from __future__ import annotations

import json
import logging

import numpy as np
import pandas as pd
import pytest

from jigsaws_tools.cli.main import main as tools_main
from jigsaws_tools.dataset import DataConfig, default_data_dir, load_dataset
from jigsaws_tools.errors import DefinitionError, JigsawsError
from jigsaws_tools.preprocessing import preprocess
from jigsaws_tools.progress import progress_labels
from jigsaws_tools.features import feature_columns
from jigsaws_tools.release import (discover, frame_labels, read_kinematics, read_meta,
                                   read_transcription, meta_path)
from jigsaws_tools.synth import SynthConfig, gesture_sequence, write_release
from jigsaws_tools.task_definition import (SUTURING, builtin_task_names, load_task,
                                           read_task_file)
from multitask.grid.spec import GridSpec, expand, release_users, run_config
from multitask.train_cli import main as train_main

#: The paper's Suturing vocabulary and stages, as the code had them before tasks became data.
PAPER_GESTURES = ("G1", "G2", "G3", "G4", "G5", "G6", "G8", "G9", "G10", "G11")
PAPER_STAGE = {"G1": 0, "G5": 0, "G2": 1, "G3": 2, "G6": 3, "G9": 3, "G10": 3, "G11": 4}

#: A made-up task with its own gestures and three stages: pick, carry, place.
TOY_TASK = """
name = "Toy_Sort"
summary = "Pick a block, carry it, place it; three times."

[gestures]
R = "Reach for a block"
L = "Lift the block"
C = "Carry it across"
A = "Align it over the slot"
P = "Place it"

[progress]
stages = [
    { name = "pick", gestures = ["R", "L"] },
    { name = "carry", gestures = ["C"] },
    { name = "place", gestures = ["P"] },
]
adjustments = ["A"]

[synthetic]
cycles = [3, 3]
lead_in = "R"
tail = "P"
cycle = [
    { gesture = "R" },
    { gesture = "L" },
    { gesture = "C" },
    { gesture = "A", p = 0.6 },
    { gesture = "P" },
]

[synthetic.gestures]
R = { frames = [40, 90] }
L = { frames = [30, 70] }
C = { frames = [60, 140] }
A = { frames = [30, 80], like = "C" }
P = { frames = [40, 90] }
"""


def _paper_progress(gestures: np.ndarray) -> np.ndarray:
    """The paper's rule on Suturing class indices, written out as the code had it before tasks:
    adjustments take the next essential stage, trailing ones the previous, none at all 0."""
    out = np.full(len(gestures), -1)
    labelled = np.flatnonzero(gestures >= 0)
    stages = [PAPER_STAGE.get(PAPER_GESTURES[g], -1) for g in gestures[labelled]]
    following = -1
    for i in reversed(range(len(stages))):
        stages[i] = following = stages[i] if stages[i] >= 0 else following
    previous = -1
    for i in range(len(stages)):
        stages[i] = previous = stages[i] if stages[i] >= 0 else previous
    out[labelled] = np.maximum(stages, 0)
    return out


# -- definitions and their loader ------------------------------------------------------------------
def test_builtin_definitions():
    assert builtin_task_names() == ("Knot_Tying", "Needle_Passing", "Suturing")
    assert SUTURING.gestures == PAPER_GESTURES
    assert {g: s for s, names in enumerate(SUTURING.stages) for g in names} == PAPER_STAGE
    assert SUTURING.adjustments == ("G4", "G8") and SUTURING.num_stages == 5
    knot = load_task("Knot_Tying")
    assert knot.gestures == ("G1", "G11", "G12", "G13", "G14", "G15")
    assert knot.adjustments == ("G14",) and knot.num_stages == 4
    needle = load_task("Needle_Passing")
    assert needle.gestures == SUTURING.gestures and needle.stages == SUTURING.stages
    for name in builtin_task_names():
        task = load_task(name)
        assert task.name == name and len(task.descriptions) == task.num_gestures
        assert task.synthetic is not None and task.name in task.describe()


def test_knot_tying_progress_grammar():
    knot = load_task("Knot_Tying")
    names = ["G1", "G12", "G13", "G14", "G15", "G14", "G12", "G13", "G14", "G15", "G11"]
    codes = np.array([knot.gesture_index[n] for n in names])
    # G14 takes the pull's stage inside a throw and the next reach's between throws.
    np.testing.assert_array_equal(progress_labels(codes, knot), [0, 0, 1, 2, 2, 0, 0, 1, 2, 2, 3])


def _write(tmp_path, text, name="task.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("change, key, problem", [
    (('name = "Toy_Sort"', 'name = "Toy Sort"'), "name", "letters, digits"),
    (('adjustments = ["A"]', 'adjustments = ["A", "R"]'), "progress.adjustments",
     "already listed"),
    (('adjustments = ["A"]', 'adjustments = []'), "progress", "every gesture"),
    (('gestures = ["P"] }', 'gestures = ["P", "Q"] }'), "progress.stages[2].gestures",
     "not a gesture of the vocabulary"),
    (('[progress]', '[progress]\nstage = 1'), "progress.stage", "unknown key"),
    (('L = { frames = [30, 70] }', 'L = { frames = [70, 30] }'), "synthetic.gestures.L.frames",
     "1 <= min < max"),
    (('{ gesture = "A", p = 0.6 }', '{ gesture = "A", p = 1.6 }'), "synthetic.cycle[3].p",
     "probability"),
    (('{ gesture = "A", p = 0.6 }', '{ gesture = ["A", "C"], weights = [1], p = 0.6 }'),
     "synthetic.cycle[3].weights", "one positive weight per gesture"),
    (('{ gesture = "A", p = 0.6 }', '{ gesture = ["A", "C"], weights = [1e308, 1e308], p = 0.6 }'),
     "synthetic.cycle[3].weights", "their sum must stay finite"),
    (('P = { frames = [40, 90] }', ''), "synthetic.gestures.P", "give its frames"),
    (('cycles = [3, 3]', 'cycles = 3'), "synthetic.cycles", "two integers"),
])
def test_bad_definitions_name_file_key_and_value(tmp_path, change, key, problem):
    path = _write(tmp_path, TOY_TASK.replace(*change))
    with pytest.raises(DefinitionError, match=problem) as error:
        read_task_file(path)
    assert error.value.key == key and str(path) in str(error.value)


def test_definition_file_errors(tmp_path):
    with pytest.raises(DefinitionError, match="not valid TOML.*line"):
        read_task_file(_write(tmp_path, "name = \n"))
    with pytest.raises(DefinitionError, match="no such task definition file"):
        read_task_file(tmp_path / "nowhere.toml")
    with pytest.raises(DefinitionError, match="at least two stages"):
        read_task_file(_write(tmp_path, TOY_TASK.replace(
            '    { name = "carry", gestures = ["C"] },\n    { name = "place", gestures = ["P"] },\n',
            "").replace('adjustments = ["A"]', 'adjustments = ["A", "C", "P"]')))
    with pytest.raises(JigsawsError, match="unknown task 'Origami'.*Suturing"):
        load_task("Origami")


# -- Suturing's labels unchanged on the real data ---------------------------------------------------
@pytest.mark.parametrize("version", ["original", "revised"])
@pytest.mark.slow
def test_real_suturing_labels_and_inputs_unchanged(real_dir, version):
    """Gesture labels from the paper's fixed vocabulary, progress from the paper's rule written
    out above, and inputs preprocessed from those labels: identical to what the task-driven
    pipeline gives, on every trial."""
    from jigsaws_tools.annotations import apply_amendments

    dataset = load_dataset(DataConfig(str(real_dir), annotations=version), use_cache=False)
    assert len(dataset.trials) == 38
    index = {t.name: t for t in discover(real_dir).trials}
    for trial in dataset.trials:
        files = index[trial.name]
        kinematics = read_kinematics(files.kinematics)
        gestures = np.full(len(kinematics), -1)
        for s in read_transcription(files.transcription):
            gestures[s.start - 1:s.end] = PAPER_GESTURES.index(s.gesture)
        gestures, _ = apply_amendments(trial.name, gestures, version)
        labels = np.stack([gestures, _paper_progress(gestures)], axis=1)
        inputs, labels, frames = preprocess(kinematics[:, feature_columns("psm_pos_vel_grip")],
                                            labels, dataset.config.preprocessing)
        np.testing.assert_array_equal(trial.gestures, labels[:, 0], err_msg=trial.name)
        np.testing.assert_array_equal(trial.progress, labels[:, 1], err_msg=trial.name)
        np.testing.assert_array_equal(trial.inputs, inputs, err_msg=trial.name)
        np.testing.assert_array_equal(trial.frames, frames, err_msg=trial.name)


# -- Knot_Tying on the real data ----------------------------------------------------------------------
@pytest.fixture(scope="session")
def knot_dir():
    path = default_data_dir().parent / "Knot_Tying"
    if not (path / "transcriptions").is_dir():
        pytest.skip(f"real JIGSAWS Knot_Tying not found at {path}")
    return path


def test_real_knot_tying_release(knot_dir, caplog):
    knot = load_task("Knot_Tying")
    with caplog.at_level(logging.WARNING):
        index = discover(knot_dir, knot)
    assert len(index.trials) == 36 and index.users == tuple("BCDEFGHI")
    assert index.missing_transcription == ("Knot_Tying_B005", "Knot_Tying_H001", "Knot_Tying_I004")
    h002 = [r.getMessage() for r in caplog.records if "Knot_Tying_H002" in r.getMessage()]
    assert len(h002) == 1 and "empty" in h002[0] and "\n" not in h002[0]
    assert read_meta(meta_path(knot_dir, knot))["Knot_Tying_B001"].skill == "N"
    with pytest.raises(JigsawsError, match="Knot_Tying trials.*--task"):
        discover(knot_dir)                                 # Suturing by default: a clear hint


def test_inspect_real_knot_tying(knot_dir, capsys):
    assert tools_main(["inspect", str(knot_dir), "--task", "Knot_Tying"]) == 0
    out = capsys.readouterr().out
    trials = [line.split()[0] for line in out.splitlines() if line.startswith("Knot_Tying_")]
    assert len(trials) == 36 and "36 complete trials" in out
    assert "gestures: G1 " in out and "G15" in out and "progress: reach " in out and "drop " in out
    assert "Knot_Tying_H002" in out.split("unusable files:")[1]


def test_real_knot_tying_dataset(knot_dir):
    knot = load_task("Knot_Tying")
    dataset = load_dataset(DataConfig(str(knot_dir), task="Knot_Tying"), use_cache=False)
    assert len(dataset.trials) == 36
    for trial in dataset.trials:
        assert set(np.unique(trial.gestures)) <= set(range(knot.num_gestures))
        assert set(np.unique(trial.progress)) <= set(range(knot.num_stages))
        drops = trial.gestures == knot.gesture_index["G11"]
        assert np.all(trial.progress[drops] == 3)
    train, test = dataset.louo_split("H")
    assert {t.user for t in test} == {"H"} and len(train) + len(test) == 36


# -- every task's synthetic release, end to end ----------------------------------------------------
@pytest.mark.parametrize("name", ["Suturing", "Knot_Tying", "Needle_Passing"])
@pytest.mark.slow
def test_synthetic_release_of_every_task_trains(tmp_path, name, capsys):
    task = load_task(name)
    root = write_release(tmp_path / name, SynthConfig(seed=1, users=("B", "C", "D"),
                                                     trials_per_user=2), task)
    assert (root / f"meta_file_{name}.txt").is_file()
    index = discover(root, task)
    assert len(index.trials) == 6 and index.users == ("B", "C", "D")
    for files in index.trials:
        segments = read_transcription(files.transcription, task=task)
        labels = frame_labels(segments, segments[-1].end, task)
        assert set(np.unique(labels)) - {-1} <= set(range(task.num_gestures))
    out = tmp_path / "run"
    assert train_main(["--task", name, "--data-dir", str(root), "--variant", "APoc",
                       "--hidden", "8", "--sweeps", "2", "--test-user", "C", "--no-plots",
                       "--out", str(out)]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["run"]["data"]["task"]["name"] == name
    metrics = json.loads((out / "metrics.json").read_text())["mean"]
    for head, classes in (("gesture", task.gestures), ("progress", task.stage_names)):
        per_class = {k for k in metrics[head] if k.startswith("accuracy_")} - {"accuracy_pooled"}
        assert per_class == {f"accuracy_{c}" for c in classes}


def test_synthetic_sequences_follow_the_grammar():
    knot = load_task("Knot_Tying")
    rng = np.random.default_rng(0)
    for _ in range(50):
        seq = gesture_sequence(rng, knot)
        assert seq[-1] == "G11" and 2 <= seq.count("G13") <= 3
        body = [g for g in seq if g not in ("G1", "G11")]
        assert body[:4] == ["G12", "G13", "G14", "G15"]


@pytest.mark.slow
def test_made_up_task_drives_synth_inspect_and_training(tmp_path, capsys):
    definition = _write(tmp_path, TOY_TASK, "toy.toml")
    release = tmp_path / "Toy_Sort"
    assert tools_main(["synth", str(release), "--task-file", str(definition), "--seed", "2"]) == 0
    assert (release / "kinematics/AllGestures/Toy_Sort_B001.txt").is_file()
    assert tools_main(["inspect", str(release), "--task-file", str(definition)]) == 0
    out = capsys.readouterr().out
    assert "40 complete trials" in out and "progress: pick " in out and " place " in out
    assert "gestures: R " in out
    run = tmp_path / "run"
    assert train_main(["--task-file", str(definition), "--data-dir", str(release),
                       "--variant", "APc", "--hidden", "16", "--epochs", "2", "--test-user", "D",
                       "--out", str(run)]) == 0
    table = pd.read_csv(next((run / "eval/epoch0002/predictions").glob("Toy_Sort_D00*.csv")))
    assert {f"gesture_p_{g}" for g in "RLCAP"} <= set(table.columns)
    assert [c for c in table.columns if c.startswith("progress_p_")] == [
        "progress_p_pick", "progress_p_carry", "progress_p_place"]
    assert set(table.gesture_true) <= set("RLCAP")
    assert set(table.progress) | set(table.progress_true) <= {"pick", "carry", "place"}
    assert len(list((run / "eval/epoch0002/plots").glob("*.png"))) == 5


@pytest.mark.slow
def test_knot_tying_grid_tables_and_figures(tmp_path, capsys):
    """A grid spec with ``task``: runs on the task's synthetic release, tables without the paper's
    (Suturing) comparisons, figures with the task's gestures and stages."""
    from multitask.grid.cli import main as grid_main
    from multitask.evidence.cli import main as tables_main

    release = write_release(tmp_path / "Knot_Tying", SynthConfig(users=("B", "C", "D"),
                                                                 trials_per_user=2),
                            load_task("Knot_Tying"))
    spec = _write(tmp_path, f'task = "Knot_Tying"\ndata_dir = "{release}"\ntest_users = ["B"]\n'
                            'seeds = [0]\nhidden = 8\nepochs = 1\n'
                            '[[experiments]]\nvariants = ["A", "APc"]\n', "knot.toml")
    grid = tmp_path / "grid"
    assert grid_main(["--spec", str(spec), "--out", str(grid), "--workers", "0"]) == 0
    assert "task Knot_Tying" in capsys.readouterr().out
    assert tables_main(["paper", str(grid)]) == 0
    tables = grid / "tables"
    assert (tables / "summary.csv").is_file() and not list(tables.glob("table*.csv"))
    summary = pd.read_csv(tables / "summary.csv")
    assert "gesture_accuracy_G15_mean" in summary and "progress_accuracy_drop_mean" in summary
    assert "progress_accuracy_push_mean" not in summary      # a Suturing stage
    assert (tables / "figures/per_gesture_accuracy.png").is_file()
    claims = pd.read_csv(tables / "claims.csv")         # the paper's conjecture, not its claims
    assert claims["claim"].str.startswith("conjecture").all()
    assert claims["paper_diff"].isna().all()
    apc = claims[claims["claim"] == "conjecture:APc-fixed:gesture_edit"].iloc[0]
    assert apc["folds"] == 1 and pd.isna(apc["verdict"])          # one fold: no verdict
    caption = (tables / "claims.tex").read_text()
    assert "The paper's conjecture" in caption and "paper's tables" not in caption
    assert "Knot Tying kinematics, 2 trials, leave-one-user-out over 1 fold (B)" in caption


@pytest.mark.slow
def test_a_grid_of_ones_own_task_tabulates_where_its_task_file_is_not(tmp_path, caplog):
    """grid.json names the task file by its path; on another machine (here: the file moved) the
    tables are still made, with a warning that the spec check was skipped."""
    from multitask.grid.cli import main as grid_main
    from multitask.evidence.cli import main as tables_main

    definition = _write(tmp_path, TOY_TASK, "toy.toml")
    release = write_release(tmp_path / "Toy_Sort", SynthConfig(users=("B", "C", "D"),
                                                               trials_per_user=2),
                            load_task(definition))
    spec = _write(tmp_path, f'task = "{definition}"\ndata_dir = "{release}"\n'
                            'test_users = ["B"]\nseeds = [0]\nhidden = 8\nepochs = 1\n'
                            '[[experiments]]\nvariants = ["A"]\n', "toy_grid.toml")
    grid = tmp_path / "grid"
    assert grid_main(["--spec", str(spec), "--out", str(grid), "--workers", "0"]) == 0
    definition.rename(tmp_path / "elsewhere.toml")
    with caplog.at_level(logging.WARNING):
        assert tables_main(["paper", str(grid), "--no-figures"]) == 0
    assert (grid / "tables" / "summary.csv").is_file()
    assert any(str(definition) in r.getMessage() and "not checked" in r.getMessage()
               for r in caplog.records)


def test_grid_spec_takes_a_task(tmp_path):
    spec = GridSpec(task="Knot_Tying", data_dir="synthetic", test_users=("B",), seeds=(0,))
    assert spec.release_dir().name == "Knot_Tying"
    keys = expand(spec, release_users(spec))
    config = run_config(spec, keys[0])
    assert config.data.task.name == "Knot_Tying" and config.data.task.num_stages == 4
    with pytest.raises(JigsawsError, match="unknown task"):
        GridSpec(task="Origami")
