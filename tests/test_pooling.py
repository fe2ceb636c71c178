"""Issue 47, items 1, 2 and 6: one rule for what a table pools, every file checked before use,
and tables that read recorded settings only. Each test is a probe of the issue: it asserts the
refusal (one line naming the file and the field, exit 2, nothing written) or the right table.
Runs are written without training (``tests.fake_grid``)."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.runs.standalone import is_run_collection
from multitask.grid.spec import Experiment, RunKey
from multitask.models.run_record import read_run_config
from rnn_seg.runs.folder import RunFolderError, read_json, write_json
from tests.fake_grid import write_fake_grid, write_fake_run

ROOT = Path(__file__).resolve().parents[1]
SCORES = {"gesture": {"accuracy": 80.0, "edit": 70.0, "f1@10": 75.0}}
A_FIXED = "runs/revised/bidirectional/A-fixed/seed0"


def _key(fold: str, variant: str = "A", seed: int = 0) -> RunKey:
    return RunKey("revised", "bidirectional", variant, "fixed", seed, fold)


def _tables(folder: Path, capsys, *options: str) -> tuple[int, str]:
    """``multitask-tables paper FOLDER --no-figures --out FOLDER/../out`` (``runs FOLDER`` for
    runs trained one by one); exit code and stderr."""
    study = ["runs"] if is_run_collection(folder) else ["paper", "--no-figures"]
    code = tables_main([study[0], str(folder), *study[1:], "--out", str(folder.parent / "out"),
                        *options])
    return code, capsys.readouterr().err


def _refused(code: int, err: str, *named: str) -> None:
    """A clean refusal: exit 2, no traceback, naming each of ``named``."""
    assert code == 2 and "Traceback" not in err, err
    for text in named:
        assert text in err, (text, err)


def _edit(path: Path, change) -> None:
    """Rewrite the JSON file ``path`` with ``change(content)`` applied."""
    content = read_json(path)
    change(content)
    write_json(path, content)


# -- 1. one rule for what a table may pool ------------------------------------------------------
def test_runs_trained_one_by_one_of_other_widths_and_schedules_are_not_one_row(tmp_path, capsys):
    """A at hidden 8 / 1 epoch on fold B and A at hidden 16 / 2 epochs on fold C: no "A-fixed,
    2 folds" row with a mean and std, but a refusal naming what differs and the runs."""
    write_fake_run(tmp_path / "mine" / "A_B", _key("B"), SCORES, hidden=8, epochs=1)
    write_fake_run(tmp_path / "mine" / "A_C", _key("C"), SCORES, hidden=16, epochs=2)
    code, err = _tables(tmp_path / "mine", capsys)
    _refused(code, err, "run.encoder.hidden 8 (A_B) / 16 (A_C)", "run.optim.total 1 (A_B)")
    assert not (tmp_path / "out").exists()


def test_runs_of_other_settings_on_one_fold_are_not_duplicates(tmp_path, capsys):
    """Two runs of A on fold B at other widths are two configurations, not a duplicate that
    --allow-incomplete may drop: refused with or without it."""
    write_fake_run(tmp_path / "mine" / "narrow", _key("B"), SCORES, hidden=8)
    write_fake_run(tmp_path / "mine" / "wide", _key("B"), SCORES, hidden=16)
    for options in ((), ("--allow-incomplete",)):
        code, err = _tables(tmp_path / "mine", capsys, *options)
        _refused(code, err, "run.encoder.hidden 8 (narrow) / 16 (wide)")
        assert "second run" not in err
    assert not (tmp_path / "out").exists()


def test_a_duplicate_left_out_is_named(tmp_path, capsys):
    """Two runs of the same settings, seed and fold: refused; with --allow-incomplete the second
    is named as left out, and the table holds the first."""
    write_fake_run(tmp_path / "mine" / "a", _key("B"), SCORES)
    shutil.copytree(tmp_path / "mine" / "a", tmp_path / "mine" / "b")
    code, err = _tables(tmp_path / "mine", capsys)
    _refused(code, err, f"{tmp_path / 'mine' / 'b'}: a second run of the same settings")
    code, err = _tables(tmp_path / "mine", capsys, "--allow-incomplete")
    assert code == 0 and f"left out: {tmp_path / 'mine' / 'b'}" in err
    assert pd.read_csv(tmp_path / "out" / "runs.csv").run.tolist() == ["a"]


@pytest.mark.parametrize("setting,change", [
    ("run.encoder.hidden", lambda c: c["run"]["encoder"].update(hidden=32)),
    ("run.optim.total", lambda c: c["run"]["optim"].update(total=24)),
    ("run.encoder.precision", lambda c: c["run"]["encoder"].update(precision="bf16")),
    ("run.train.batch_size", lambda c: c["run"]["train"].update(batch_size=3)),
    ("run.data.preprocessing.cutoff_hz",
     lambda c: c["run"]["data"]["preprocessing"].update(cutoff_hz=2.0)),
    ("run.data.task.stage_names", lambda c: c["run"]["data"]["task"].update(
        stage_names=["a", "b", "c", "d", "e"])),
    ("data_fingerprint", lambda c: c.update(data_fingerprint="another")),
])
def test_every_setting_that_changes_a_result_separates_runs(tmp_path, capsys, setting, change):
    for fold in "BC":
        write_fake_run(tmp_path / "mine" / fold, _key(fold), SCORES)
    _edit(tmp_path / "mine" / "C" / "config.json", change)
    code, err = _tables(tmp_path / "mine", capsys)
    _refused(code, err, f"A-fixed: {setting} ")


@pytest.mark.parametrize("change", [
    lambda c: c["run"]["train"].update(log_every=5, plots="none"),     # what a run writes
    lambda c: c["run"]["encoder"].update(loops="xla"),                  # how it computes
    lambda c: c["run"]["data"].update(data_dir="/elsewhere"),           # where its data lay
    lambda c: c.update(provenance={"host": "another"}),
])
def test_settings_that_change_no_result_do_not_separate_runs(tmp_path, capsys, change):
    for fold in "BC":
        write_fake_run(tmp_path / "mine" / fold, _key(fold), SCORES)
    _edit(tmp_path / "mine" / "C" / "config.json", change)
    code, err = _tables(tmp_path / "mine", capsys)
    assert code == 0, err
    assert pd.read_csv(tmp_path / "out" / "summary.csv").folds.tolist() == [2]


def test_a_baseline_run_and_a_multitask_run_of_model_a_are_one_configuration(tmp_path, capsys):
    """baseline-train records no variant or weighting: its run is model A with fixed weights."""
    write_fake_run(tmp_path / "mine" / "B", _key("B"), SCORES)
    write_fake_run(tmp_path / "mine" / "C", _key("C"), SCORES)
    _edit(tmp_path / "mine" / "C" / "config.json", lambda c: [c.pop("variant"),
                                                              c.pop("weighting")])
    code, err = _tables(tmp_path / "mine", capsys)
    assert code == 0, err
    assert pd.read_csv(tmp_path / "out" / "summary.csv").folds.tolist() == [2]


def test_a_record_that_predates_a_setting_pools_with_one_at_its_default(tmp_path, capsys):
    """An APoc run whose config.json records GradNorm's and the head's settings at their
    defaults, and one of a version that recorded neither: one configuration; another alpha or
    head loss is another."""
    for fold in "BC":
        write_fake_run(tmp_path / "mine" / fold,
                       RunKey("revised", "bidirectional", "APoc", "gradnorm", 0, fold), SCORES)
    _edit(tmp_path / "mine" / "C" / "config.json", lambda c: c.update(
        gradnorm={"alpha": 1.5}, heads={"ordinal_loss": "sum"}))
    code, err = _tables(tmp_path / "mine", capsys)
    assert code == 0, err
    for change, setting in ((dict(gradnorm={"alpha": 0.5}), "gradnorm.alpha"),
                            (dict(heads={"ordinal_loss": "mean"}), "heads.ordinal_loss")):
        _edit(tmp_path / "mine" / "C" / "config.json", lambda c: c.update(change))
        code, err = _tables(tmp_path / "mine", capsys)
        _refused(code, err, f"APoc-gradnorm: {setting} ")
        _edit(tmp_path / "mine" / "C" / "config.json", lambda c: c.update(
            gradnorm={"alpha": 1.5}, heads={"ordinal_loss": "sum"}))


def test_annotations_and_direction_make_rows_of_their_own(tmp_path, capsys):
    write_fake_run(tmp_path / "mine" / "rev", _key("B"), SCORES)
    original = RunKey("original", "bidirectional", "A", "fixed", 0, "B")
    write_fake_run(tmp_path / "mine" / "orig", original, SCORES)
    forward = RunKey("revised", "forward", "A", "fixed", 0, "B")
    write_fake_run(tmp_path / "mine" / "fwd", forward, SCORES)
    code, err = _tables(tmp_path / "mine", capsys)
    assert code == 0, err
    summary = pd.read_csv(tmp_path / "out" / "summary.csv")
    assert sorted(zip(summary.annotations, summary.direction)) == [
        ("original", "bidirectional"), ("revised", "bidirectional"), ("revised", "forward")]


def _grid_without_spec(root: Path) -> Path:
    """A finished grid of A and APc (fixed weights, seed 0, 8 folds) whose grid.json records no
    spec, as an early version wrote it."""
    return write_fake_grid(root, seeds=(0,), experiments=(Experiment(("A", "APc")),))


def test_a_run_copied_into_another_configurations_folder_is_not_tabulated_as_it(tmp_path,
                                                                                capsys, caplog):
    """grid.json without a spec: an APc run copied into A-fixed's fold-C folder is not model A."""
    grid = _grid_without_spec(tmp_path / "grid")
    target = grid / A_FIXED / "C"
    shutil.rmtree(target)
    shutil.copytree(grid / "runs/revised/bidirectional/APc-fixed/seed0/C", target)
    code, err = _tables(grid, capsys)
    _refused(code, err, f"{target}: its config.json records variant: APc, not A")
    assert f"{grid / 'grid.json'} records no spec" in caplog.text    # unchecked, and says so
    assert not (tmp_path / "out").exists()
    code, err = _tables(grid, capsys, "--allow-incomplete")
    assert code == 0 and f"{target}: its config.json records variant: APc" in err
    summary = pd.read_csv(tmp_path / "out" / "summary.csv").set_index("variant")
    assert summary.loc["A", "runs"] == 7 and not summary.loc["A", "complete"]


def test_a_grid_of_mixed_widths_without_a_spec_is_refused(tmp_path, capsys):
    grid = _grid_without_spec(tmp_path / "grid")
    _edit(grid / A_FIXED / "D" / "config.json", lambda c: c["run"]["encoder"].update(hidden=64))
    code, err = _tables(grid, capsys, "--allow-incomplete")
    _refused(code, err, "revised/bidirectional/A-fixed: run.encoder.hidden 16 (",
             f"64 ({A_FIXED}/D)")


def test_compare_pools_by_the_same_rule(tmp_path, capsys):
    grid = _grid_without_spec(tmp_path / "grid")
    _edit(grid / A_FIXED / "D" / "config.json", lambda c: c["run"]["optim"].update(total=99))
    code = tables_main(["pair", str(grid), "APc-fixed", "A-fixed", "--metric",
                        "gesture_accuracy"])
    _refused(code, capsys.readouterr().err, "run.optim.total")


def _width_grids(root: Path) -> list[Path]:
    """Grids of A and APoc (GradNorm) at 16 and 64 units."""
    experiments = (Experiment(("A",)), Experiment(("APoc",), ("gradnorm",)))
    return [write_fake_grid(root / f"h{hidden}", seeds=(0,), hidden=hidden,
                            experiments=experiments) for hidden in (16, 64)]


def test_widths_refuse_a_grid_folder_without_its_record(tmp_path, capsys):
    """The width study over a grid without grid.json and with a run of A removed: not 7 folds of A
    beside 8 of APoc, but a refusal saying the grid's runs are unknown."""
    narrow, wide = _width_grids(tmp_path)
    (wide / "grid.json").unlink()
    shutil.rmtree(wide / A_FIXED / "C")
    code = tables_main(["width", str(narrow), str(wide), "--out", str(tmp_path / "w")])
    _refused(code, capsys.readouterr().err, f"{wide}: not a grid: {wide / 'grid.json'} missing")
    assert not (tmp_path / "w").exists()


def test_widths_refuse_a_models_runs_of_other_settings(tmp_path, capsys):
    narrow, wide = _width_grids(tmp_path)
    _edit(wide / A_FIXED / "C" / "config.json", lambda c: c["run"]["train"].update(batch_size=3))
    code = tables_main(["width", str(narrow), str(wide), "--out", str(tmp_path / "w")])
    _refused(code, capsys.readouterr().err, "run.train.batch_size")


def test_widths_refuse_grids_whose_models_differ_in_more_than_width_and_schedule(tmp_path,
                                                                                  capsys):
    narrow, wide = _width_grids(tmp_path)
    for config in wide.glob("runs/**/config.json"):
        _edit(config, lambda c: c["run"]["encoder"].update(precision="bf16"))
    code = tables_main(["width", str(narrow), str(wide), "--out", str(tmp_path / "w")])
    _refused(code, capsys.readouterr().err, "the grids of the width study",
             "run.encoder.precision")


def test_a_recorded_run_the_spec_does_not_hold_is_not_tabulated(tmp_path, capsys):
    """grid.json lists a seed-3 run its spec (seed 0) never planned, its config.json consistent
    with its place: named, not tabulated as the grid's."""
    grid = write_fake_grid(tmp_path / "grid", seeds=(0,), fingerprint="0123",
                           experiments=(Experiment(("A", "APc")),))
    extra = grid / "runs/revised/bidirectional/A-fixed/seed3/B"
    shutil.copytree(grid / A_FIXED / "B", extra)
    _edit(extra / "config.json", lambda c: c["run"]["train"].update(seed=3))
    _edit(grid / "grid.json", lambda r: r["runs"].append(str(extra.relative_to(grid))))
    code, err = _tables(grid, capsys)
    _refused(code, err, f"{extra}: no run of the grid's spec")


# -- 2. every read is validated -----------------------------------------------------------------
def _two_runs(root: Path) -> Path:
    """Runs of A on folds B and C, trained one by one; returns B's."""
    for fold in "BC":
        write_fake_run(root / "mine" / fold, _key(fold), SCORES)
    return root / "mine" / "B"


def _confusion(counts) -> dict:
    from jigsaws_tools.task_definition import SUTURING

    return {"gesture": {"classes": list(SUTURING.gestures), "counts": counts}}


@pytest.mark.parametrize("change,field", [
    (lambda m: m["mean"]["gesture"].update(accuracy=99.0),
     "mean.gesture.accuracy: 99 is not the mean of its evaluation points (80)"),
    (lambda m: m.pop("points"), "points: no metrics per evaluation point"),
    (lambda m: m["mean"]["gesture"].update(edit="70"), "mean.gesture.edit: not a number"),
    (lambda m: m["mean"].update(progress={"accuracy": 50.0}),
     "mean: tasks ['gesture', 'progress'], but the run's config.json records ['gesture']"),
    (lambda m: m.update(confusion=None), "confusion: not a confusion matrix per task"),
    (lambda m: m.update(confusion={}),
     "confusion: tasks [], but the run's config.json records ['gesture']"),
    (lambda m: m.update(confusion=_confusion([[1] * 10] * 9 + [[1] * 9])),
     "confusion.gesture.counts: not a 10 x 10 table of non-negative integers"),
    (lambda m: m.update(confusion=_confusion([[-1] * 10] * 10)),
     "confusion.gesture.counts: not a 10 x 10 table"),
    (lambda m: m.update(confusion=_confusion([[0.5] * 10] * 10)),
     "confusion.gesture.counts: not a 10 x 10 table"),
    (lambda m: m.update(confusion={"gesture": {"classes": ["G1", "G2"], "counts": [[1, 0],
                                                                                 [0, 1]]}}),
     "confusion.gesture.classes: ['G1', 'G2'] are not the run's gesture classes"),
])
def test_a_metrics_file_that_contradicts_itself_or_its_run_is_named(tmp_path, capsys, change,
                                                                      field):
    run = _two_runs(tmp_path)
    _edit(run / "metrics.json", change)
    code, err = _tables(tmp_path / "mine", capsys, "--allow-incomplete")
    assert code == 0 and f"{run / 'metrics.json'}: {field}" in err, err
    code, err = _tables(tmp_path / "mine", capsys)
    _refused(code, err, f"{run / 'metrics.json'}: {field}")


def test_a_mean_rounded_by_hand_still_agrees_with_its_points(tmp_path, capsys):
    run = _two_runs(tmp_path)
    _edit(run / "metrics.json", lambda m: m["points"]["12"]["gesture"].update(accuracy=80.0004))
    code, err = _tables(tmp_path / "mine", capsys)
    assert code == 0, err


@pytest.mark.parametrize("content,field", [
    ({"run": 5}, "config.json: run: not a run's configuration (value: '5')"),
    ([1, 2], "config.json: run: not a run's configuration"),
    (None, "config.json: run: not a run's configuration"),
])
def test_a_config_that_is_no_run_configuration_is_one_line(tmp_path, capsys, content, field):
    run = _two_runs(tmp_path)
    (run / "config.json").write_text(json.dumps(content))
    code, err = _tables(tmp_path / "mine", capsys)
    _refused(code, err, f"{run / field.split(': ', 1)[0]}: {field.split(': ', 1)[1]}")
    with pytest.raises(RunFolderError, match="config.json: run: not a run's configuration"):
        read_run_config(run)                    # what multitask-predict and -evaluate read


@pytest.mark.parametrize("command", ["evaluate", "predict", "export"])
def test_inference_commands_name_a_config_that_is_no_run_configuration(tmp_path, capsys,
                                                                       command):
    from multitask.inference import evaluate_cli, export_cli, predict_cli

    run = tmp_path / "run"
    write_json(run / "config.json", {"run": 5})
    argv = {"evaluate": [str(run)], "predict": [str(run), str(tmp_path / "rec.csv"), "--out",
                                                str(tmp_path / "p")],
            "export": [str(run), "--out", str(tmp_path / "e")]}[command]
    main = {"evaluate": evaluate_cli, "predict": predict_cli, "export": export_cli}[command].main
    code = main(argv)
    err = capsys.readouterr().err
    _refused(code, err, f"{run / 'config.json'}: run: not a run's configuration (value: '5')")
    assert err.count("\n") == 1


@pytest.mark.parametrize("change,field", [
    (lambda c: c["run"]["encoder"].update(hidden="big"), "run.encoder.hidden"),
    (lambda c: c["run"].pop("test_user"), "run.test_user: missing"),
    (lambda c: c["run"]["train"].pop("seed"), "run.train.seed: missing"),
    (lambda c: c["run"]["optim"].update(total=None), "run.optim.total"),
    (lambda c: c.update(variant="APx"), "variant: expected one of A, APr"),
    (lambda c: c.update(variant=["A"]), "variant: expected one of"),
    (lambda c: c.update(weighting="gradnorm"), "GradNorm needs two tasks"),
    (lambda c: c.update(tasks=["progress"]), "tasks: ['progress'] are not variant A's"),
    (lambda c: c.update(data_fingerprint=7), "data_fingerprint: not a fingerprint"),
])
def test_a_config_of_wrong_types_or_fields_is_one_line_naming_the_field(tmp_path, capsys,
                                                                         change, field):
    run = _two_runs(tmp_path)
    _edit(run / "config.json", change)
    code, err = _tables(tmp_path / "mine", capsys)
    _refused(code, err, str(run / "config.json"), field)
    assert err.count("\n") <= 4                 # the heading, one line per problem, the advice


@pytest.mark.parametrize("path", ["runs/revised", "runs/revised/bidirectional/A-fixed/0/B",
                                  "runs/revised/bidirectional/A-fixed/seed00/B",
                                  "runs/revised/sideways/A-fixed/seed0/B",
                                  "runs/revised/bidirectional/A-lots/seed0/B"])
def test_a_grid_record_with_a_run_path_of_the_wrong_shape_is_one_line(tmp_path, capsys, path):
    narrow, wide = _width_grids(tmp_path)
    _edit(wide / "grid.json", lambda r: r["runs"].append(path))
    record = wide / "grid.json"
    for argv in (["paper", str(wide), "--no-figures", "--out", str(tmp_path / "t")],
                 ["width", str(narrow), str(wide), "--out", str(tmp_path / "w")]):
        code = tables_main(argv)
        err = capsys.readouterr().err
        _refused(code, err, f"{record}: runs: {path!r}")
        assert err.count("\n") == 1


def test_a_grid_record_listing_a_run_twice_is_one_line(tmp_path, capsys):
    grid = _grid_without_spec(tmp_path / "grid")
    _edit(grid / "grid.json", lambda r: r["runs"].append(r["runs"][0]))
    code, err = _tables(grid, capsys)
    _refused(code, err, f"{grid / 'grid.json'}: runs: '{A_FIXED}/B' is listed twice")


# -- 6. no side doors ---------------------------------------------------------------------------
@pytest.mark.slow
def test_a_spec_check_reads_recorded_settings_only(tmp_path):
    """Tables over a grid whose spec names the synthetic release: every run checked against the
    spec, without TensorFlow and without writing a synthetic release."""
    grid = write_fake_grid(tmp_path / "grid", seeds=(0,), fingerprint="0123",
                           experiments=(Experiment(("A", "APc")),))
    _edit(grid / "grid.json", lambda r: r["spec"].update(data_dir="synthetic"))
    retrained = grid / A_FIXED / "D" / "config.json"
    _edit(retrained, lambda c: c["run"]["encoder"].update(hidden=64))
    script = ("import sys\nfrom multitask.evidence.cli import main\n"
              f"code = main([{str(grid)!r}, '--no-figures', '--allow-incomplete', '--out', "
              f"{str(tmp_path / 'out')!r}])\n"
              "print(code, 'tensorflow' in sys.modules)")
    cache = tmp_path / "cache"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "JIGSAWS_CACHE_DIR": str(cache)}
    result = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                            text=True, timeout=600)
    assert result.stdout.split()[-2:] == ["0", "False"], result.stderr
    assert f"other settings than the grid's spec: {retrained.parent}" in result.stderr
    assert "run.encoder.hidden: 64 -> 16" in result.stderr
    assert not cache.exists()
    assert pd.read_csv(tmp_path / "out" / "runs.csv").shape[0] == 15
