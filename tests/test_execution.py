"""An execution path against its reference (``multitask-tables execution GRID --reference REF
--margin M``),
on fake grids that differ only in the path their config.json files record."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.runs.collect import run_rows
from multitask.evidence.statistics.paired import StatsConfig, paired_sides
from multitask.evidence.studies.execution import SMALL_SHIFT, outcome, shift_note
from multitask.grid.spec import Experiment
from tests.fake_grid import FOLDS, write_fake_grid

MODELS = (Experiment(variants=("A",)), Experiment(variants=("APoc",), weightings=("gradnorm",)))


def _grid(root, name, scores_seed, seeds=(0, 1), **path):
    return write_fake_grid(root / name, seeds=seeds, experiments=MODELS, scores_seed=scores_seed,
                           **path)


def _fold_means(grid, variant, metric):
    runs, _ = run_rows(grid)
    return runs[runs.variant == variant].groupby("fold")[metric].mean()


def _compare(option, reference, out, margin="2.0"):
    return tables_main(["execution", str(option), "--reference", str(reference),
                        "--margin", margin, "--out", str(out)])


def test_option_minus_reference_per_configuration_and_score(tmp_path):
    reference = _grid(tmp_path, "ref", 0)
    option = _grid(tmp_path, "fused", 1, loops="fused")
    assert _compare(option, reference, tmp_path / "out") == 0
    table = pd.read_csv(tmp_path / "out" / "execution.csv", dtype={"seeds": str})
    assert list(table.configuration.unique()) == ["A-fixed", "APoc-gradnorm"]
    row = table[(table.configuration == "APoc-gradnorm") & (table.metric == "gesture_edit")].iloc[0]
    difference = (_fold_means(option, "APoc", "gesture_edit")
                  - _fold_means(reference, "APoc", "gesture_edit"))
    assert row["diff"] == pytest.approx(difference.mean(), abs=1e-4)
    assert row.ci_low <= row["diff"] <= row.ci_high
    assert (row.folds, row.seeds, row.margin) == (len(FOLDS), "0 1", 2.0)
    assert (row.option, row.reference) == ("fused loops, fp32", "graph loops, fp32")
    for _, r in table.iterrows():
        inside = -r.margin < r.ci_low and r.ci_high < r.margin
        outside = r.ci_low > r.margin or r.ci_high < -r.margin
        assert r.outcome == ("equivalent" if inside else "different" if outside
                             else "inconclusive")
        small = r.outcome == "equivalent" and r.p_value <= 0.05
        assert (r.note if isinstance(r.note, str) else "") == (SMALL_SHIFT if small else "")
    manifest = json.loads((tmp_path / "out" / "execution.json").read_text())
    assert (manifest["option"], manifest["reference"], manifest["margin"]) == (
        str(option), str(reference), 2.0)
    per_fold = pd.read_csv(tmp_path / "out" / "execution_per_fold.csv")
    edit = per_fold[(per_fold.configuration == "APoc-gradnorm")
                    & (per_fold.metric == "gesture_edit")].set_index("fold").difference
    assert edit.to_dict() == pytest.approx(difference.to_dict(), abs=1e-4)


def test_a_model_comparison_in_each_grid_and_their_difference(tmp_path):
    reference = _grid(tmp_path, "ref", 0)
    option = _grid(tmp_path, "bf16", 2, precision="bf16", loops="fused")
    assert _compare(option, reference, tmp_path / "out") == 0
    contrasts = pd.read_csv(tmp_path / "out" / "execution_contrasts.csv")
    assert list(contrasts.contrast.unique()) == ["APoc-gradnorm - A-fixed"]
    row = contrasts[contrasts.metric == "gesture_accuracy"].iloc[0]
    gain = {name: (_fold_means(grid, "APoc", "gesture_accuracy")
                   - _fold_means(grid, "A", "gesture_accuracy"))
            for name, grid in (("option", option), ("reference", reference))}
    assert row.option_diff == pytest.approx(gain["option"].mean(), abs=1e-4)
    assert row.reference_diff == pytest.approx(gain["reference"].mean(), abs=1e-4)
    assert row.diff_of_diffs == pytest.approx((gain["option"] - gain["reference"]).mean(),
                                              abs=1e-4)
    assert row.same_reading == (row.option_verdict == row.reference_verdict)
    for side in ("option", "reference"):
        expected = ("no difference detected" if row[f"{side}_p"] > 0.05 else
                    f"APoc-gradnorm {'above' if row[f'{side}_diff'] > 0 else 'below'} A-fixed")
        assert row[f"{side}_verdict"] == expected


@pytest.mark.slow
def test_each_configuration_is_compared_with_a_of_its_labels_and_direction(tmp_path):
    models = MODELS + (Experiment(variants=("A", "APoc"), directions=("forward",)),
                       Experiment(variants=("A", "APoc"), weightings=("fixed", "gradnorm"),
                                  annotations=("original",)))
    reference = write_fake_grid(tmp_path / "ref", experiments=models, scores_seed=0)
    option = write_fake_grid(tmp_path / "fused", experiments=models, scores_seed=1,
                             loops="fused")
    assert _compare(option, reference, tmp_path / "out") == 0
    contrasts = pd.read_csv(tmp_path / "out" / "execution_contrasts.csv")
    assert sorted(contrasts.contrast.unique()) == [
        "APoc-gradnorm - A-fixed", "forward/APoc-fixed - forward/A-fixed",
        "original/APoc-fixed - original/A-fixed",
        "original/APoc-gradnorm - original/A-fixed"]
    runs, _ = run_rows(option)
    original = runs[runs.annotations == "original"]
    gain = (original[original.variant == "APoc"].query("weighting == 'gradnorm'")
            .groupby("fold").gesture_edit.mean()
            - original[original.variant == "A"].groupby("fold").gesture_edit.mean())
    row = contrasts[(contrasts.contrast == "original/APoc-gradnorm - original/A-fixed")
                    & (contrasts.metric == "gesture_edit")].iloc[0]
    assert row.option_diff == pytest.approx(gain.mean(), abs=1e-4)
    assert all(verdict == "no difference detected" or verdict.endswith("original/A-fixed")
               for verdict in contrasts.loc[contrasts.contrast.str.startswith("original/"),
                                            ["option_verdict", "reference_verdict"]].values.ravel())


def test_a_grid_without_a_has_a_contrasts_table_of_the_header_alone(tmp_path):
    reference = _grid(tmp_path, "ref", 0)
    option = write_fake_grid(tmp_path / "fused", experiments=MODELS[1:], scores_seed=1,
                             loops="fused")
    assert _compare(option, reference, tmp_path / "out") == 0
    contrasts = pd.read_csv(tmp_path / "out" / "execution_contrasts.csv")
    assert contrasts.empty and {"contrast", "diff_of_diffs", "same_reading"} <= set(contrasts)
    table = pd.read_csv(tmp_path / "out" / "execution.csv")
    assert list(table.configuration.unique()) == ["APoc-gradnorm"]


def test_outcome_against_the_margin():
    def result(differences):
        values = {f: np.array([d]) for f, d in zip(FOLDS, differences)}
        zeros = {f: np.array([0.0]) for f in FOLDS}
        return paired_sides("x", "m", {"a": (1, values), "b": (-1, zeros)}, StatsConfig())

    assert outcome(result([0.1, -0.2, 0.3, 0.0, -0.1, 0.2, 0.1, -0.3]), 2.0) == "equivalent"
    assert outcome(result([5.1, 4.8, 5.3, 5.0, 4.9, 5.2, 5.1, 4.7]), 2.0) == "different"
    assert outcome(result([-5.1, -4.8, -5.3, -5.0, -4.9, -5.2, -5.1, -4.7]), 2.0) == "different"
    assert outcome(result([3.0, -2.5, 4.0, -1.0, 2.0, -3.5, 1.0, 0.5]), 2.0) == "inconclusive"
    shifted = result([0.5, 0.6, 0.4, 0.5, 0.7, 0.3, 0.5, 0.6])
    assert (outcome(shifted, 2.0), shift_note(shifted, 2.0, 0.05)) == ("equivalent", SMALL_SHIFT)
    assert shift_note(result([0.1, -0.2, 0.3, 0.0, -0.1, 0.2, 0.1, -0.3]), 2.0, 0.05) == ""
    assert shift_note(result([5.1, 4.8, 5.3, 5.0, 4.9, 5.2, 5.1, 4.7]), 2.0, 0.05) == ""


def _set_provenance_loops(grid, loops, run="runs"):
    """Record ``loops`` as what every run under ``grid / run`` ran (its provenance)."""
    for config in (grid / run).rglob("config.json"):
        record = json.loads(config.read_text())
        record["provenance"] = {**record.get("provenance", {}), "loops": loops}
        config.write_text(json.dumps(record))


def test_a_grid_on_the_default_loops_reads_as_the_loops_its_runs_ran(tmp_path):
    """``auto`` is no path: the runs' provenance says which loops they ran."""
    reference = _grid(tmp_path, "ref", 0)
    option = _grid(tmp_path, "auto", 1, loops="auto")
    _set_provenance_loops(option, "fused")
    assert _compare(option, reference, tmp_path / "out") == 0
    table = pd.read_csv(tmp_path / "out" / "execution.csv")
    assert set(table.option) == {"fused loops, fp32"}


@pytest.mark.parametrize("case, message", [
    ("width", "run.encoder.hidden"),
    ("unfinished", "31 of its 32 runs have finished"),
    ("seed", "no usable run of A-fixed, seed 1, fold B: "),
    ("same path", "ran on the same execution path (graph loops, fp32): nothing to compare"),
    ("two paths", "ran on more than one execution path"),
    ("fell back", "ran on more than one execution path (fused loops, fp32, graph loops, fp32)"),
    ("unfinished reference run", "no usable run of A-fixed, seed 1, fold C: not finished: "),
    ("unreadable option run", "seed1/C/config.json: unreadable or not valid JSON"),
    ("unreadable reference run", "no usable run of A-fixed, seed 1, fold C: unreadable "
                                 "configuration: "),
    ("reference not a grid", "not a grid: "),
    ("tcn", "runs of several encoders (ed-tcn "),
    ("margin", "--margin must be a finite number of points above 0 (value: 0.0)"),
    ("infinite margin", "--margin must be a finite number of points above 0 (value: inf)"),
    ("nan margin", "--margin must be a finite number of points above 0 (value: nan)"),
])
def test_what_cannot_be_compared_is_a_one_line_error_and_writes_nothing(tmp_path, capsys, case,
                                                                         message):
    option = _grid(tmp_path, "option", 1, seeds=(0, 1), loops="fused")
    reference = {"width": lambda: write_fake_grid(tmp_path / "ref", seeds=(0, 1), hidden=32,
                                                  experiments=MODELS),
                 "seed": lambda: _grid(tmp_path, "ref", 0, seeds=(0,)),
                 }.get(case, lambda: _grid(tmp_path, "ref", 0))()
    if case == "tcn":
        option = write_fake_grid(tmp_path / "tcn", seeds=(0, 1), experiments=MODELS,
                                 encoder="ed-tcn")
    if case == "same path":
        option = _grid(tmp_path, "graph", 1)
    if case == "unfinished":
        (option / "runs/revised/bidirectional/A-fixed/seed1/C/finished.json").unlink()
    run = "runs/revised/bidirectional/A-fixed/seed1/C"
    if case == "unfinished reference run":
        (reference / run / "finished.json").unlink()
    if case in ("unreadable option run", "unreadable reference run"):
        ((option if case == "unreadable option run" else reference) / run
         / "config.json").write_text("{not json")
    if case == "reference not a grid":
        (reference / "grid.json").unlink()
    if case == "two paths":
        config = option / "runs/revised/bidirectional/A-fixed/seed1/C/config.json"
        record = json.loads(config.read_text())
        record["run"]["encoder"]["loops"] = "graph"
        config.write_text(json.dumps(record))
    if case == "fell back":          # configured fused, ran graph (no compiler on its machine)
        _set_provenance_loops(option, "graph", run="runs/revised/bidirectional/A-fixed/seed1/C")
    margin = {"margin": "0", "infinite margin": "inf", "nan margin": "nan"}.get(case, "2.0")
    assert _compare(option, reference, tmp_path / "out", margin) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("extra,message", [
    (["--margin", "2"], "the following arguments are required: --reference"),
    (["--reference", "REF"], "the following arguments are required: --margin")])
def test_reference_and_margin_go_together(tmp_path, capsys, extra, message):
    grid = _grid(tmp_path, "g", 0)
    extra = [str(grid) if word == "REF" else word for word in extra]
    with pytest.raises(SystemExit) as exit_:
        tables_main(["execution", str(grid), *extra, "--out", str(tmp_path / "out")])
    assert exit_.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_flag_form_still_checks_its_options_as_it_did(tmp_path, capsys):
    grid = _grid(tmp_path, "g", 0)
    for extra in (["--margin", "2"], ["--reference", str(grid)]):
        with pytest.raises(SystemExit) as exit_:
            tables_main([str(grid), *extra, "--out", str(tmp_path / "out")])
        assert exit_.value.code == 2
    assert "--reference needs --margin" in capsys.readouterr().err
    for extra in (["--reference", str(grid), "--margin", "2"], ["--margin", "2"],
                  ["--architectures", str(grid)]):
        with pytest.raises(SystemExit) as exit_:
            tables_main(["--confirm", str(tmp_path / "plan.toml"), *extra,
                         "--out", str(tmp_path / "out")])
        assert exit_.value.code == 2
    assert "--confirm reads its grids from the plan" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_second_call_replaces_the_first_and_a_failed_one_leaves_it(tmp_path):
    reference = _grid(tmp_path, "ref", 0)
    out = tmp_path / "out"
    assert _compare(_grid(tmp_path, "fused", 1, loops="fused"), reference, out) == 0
    bf16 = _grid(tmp_path, "bf16", 2, precision="bf16", loops="fused")
    assert _compare(bf16, reference, out, margin="3") == 0
    written = {path.name: path.read_bytes() for path in out.iterdir()}
    table = pd.read_csv(out / "execution.csv")
    assert set(table.option) == {"fused loops, bf16"} and set(table.margin) == {3.0}
    assert json.loads(written["execution.json"])["option"] == str(bf16)
    assert _compare(bf16, _grid(tmp_path, "one seed", 0, seeds=(0,)), out) == 2
    assert {path.name: path.read_bytes() for path in out.iterdir()} == written


def test_the_help_shows_the_example_command_on_two_lines(capsys):
    with pytest.raises(SystemExit):
        tables_main(["execution", "--help"])
    example = "--margin 2.0 \\\n        --out results/precision/bf16-vs-fp32"
    assert example in capsys.readouterr().out


def test_progress_only_models_are_left_out_with_a_note(tmp_path, capsys):
    models = MODELS + (Experiment(variants=("Pc",)),)
    reference = write_fake_grid(tmp_path / "ref", experiments=models, scores_seed=0)
    option = write_fake_grid(tmp_path / "fused", experiments=models, scores_seed=1,
                             loops="fused")
    assert _compare(option, reference, tmp_path / "out") == 0
    assert "note: Pc-fixed: no gesture scores" in capsys.readouterr().err
    table = pd.read_csv(tmp_path / "out" / "execution.csv")
    assert list(table.configuration.unique()) == ["A-fixed", "APoc-gradnorm"]
    progress = (Experiment(variants=("Pc",)),)
    option = write_fake_grid(tmp_path / "pc", experiments=progress, loops="fused")
    assert _compare(option, reference, tmp_path / "out2") == 2
    err = capsys.readouterr().err
    assert "no configuration with gesture scores (it holds Pc-fixed)" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "out2").exists()


def test_too_few_folds_for_an_interval_is_said(tmp_path, capsys):
    reference = _grid(tmp_path, "ref", 0)
    option = _grid(tmp_path, "fused", 1, loops="fused")
    record = json.loads((option / "grid.json").read_text())
    kept = [run for run in record["runs"] if run.rsplit("/", 1)[1] in FOLDS[:5]]
    for run in set(record["runs"]) - set(kept):
        shutil.rmtree(option / run)
    (option / "grid.json").write_text(json.dumps({**record, "runs": kept}))
    assert _compare(option, reference, tmp_path / "out") == 0
    table = pd.read_csv(tmp_path / "out" / "execution.csv")
    assert set(table.folds) == {5} and set(table.outcome) == {"inconclusive"}
    assert "6 of 6 endpoints have 5 or fewer paired folds" in capsys.readouterr().err


def test_p_values_and_intervals_agree_with_scipy_s_exact_permutation_test(tmp_path):
    from scipy.stats import permutation_test

    def p_value(d, d0=0.0):
        return permutation_test((d - d0,), np.mean, permutation_type="samples",
                                n_resamples=np.inf).pvalue

    reference = _grid(tmp_path, "ref", 0)
    option = _grid(tmp_path, "bf16", 3, precision="bf16", loops="fused")
    assert _compare(option, reference, tmp_path / "out") == 0
    table = pd.read_csv(tmp_path / "out" / "execution.csv")
    for _, row in table[table.metric == "gesture_f1@10"].iterrows():
        variant = row.configuration.split("-")[0]
        d = (_fold_means(option, variant, "gesture_f1@10")
             - _fold_means(reference, variant, "gesture_f1@10")).to_numpy()
        assert row.p_value == pytest.approx(p_value(d), abs=1e-4)    # 4 decimals
        step = 2e-4                                     # beyond the CSV's 4 decimals
        assert p_value(d, row.ci_low + step) > 0.05 and p_value(d, row.ci_high - step) > 0.05
        assert p_value(d, row.ci_low - step) <= 0.05 and p_value(d, row.ci_high + step) <= 0.05
    contrasts = pd.read_csv(tmp_path / "out" / "execution_contrasts.csv")
    row = contrasts[contrasts.metric == "gesture_f1@10"].iloc[0]
    gain = {name: (_fold_means(grid, "APoc", "gesture_f1@10")
                   - _fold_means(grid, "A", "gesture_f1@10")).to_numpy()
            for name, grid in (("option", option), ("reference", reference))}
    assert row.option_p == pytest.approx(p_value(gain["option"]), abs=1e-4)
    assert row.reference_p == pytest.approx(p_value(gain["reference"]), abs=1e-4)
    assert row.dd_p == pytest.approx(p_value(gain["option"] - gain["reference"]), abs=1e-4)


def test_scores_archives_compare_as_their_grids(tmp_path):
    reference = _grid(tmp_path, "ref", 0)
    option = _grid(tmp_path, "fused", 1, loops="fused")
    for grid in (reference, option):
        assert tables_main(["archive", str(grid), str(tmp_path / f"{grid.name}-archive")]) == 0
    assert _compare(option, reference, tmp_path / "grids") == 0
    assert _compare(tmp_path / "fused-archive", tmp_path / "ref-archive",
                    tmp_path / "archives") == 0
    for name in ("execution.csv", "execution_contrasts.csv", "execution_per_fold.csv"):
        assert ((tmp_path / "grids" / name).read_text()
                == (tmp_path / "archives" / name).read_text())
