"""Architectures side by side (``multitask-tables --architectures``): one grid per architecture,
the claims "progress heads help TCN backbones", Table II's measured rows and the
cross-architecture table, on fake grids (no training)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.render.latex import required_packages
from multitask.evidence.runs.pooling import MixedArchitectures, apart
from multitask.evidence.statistics.paired import ConfigId, Contrast, holm
from multitask.evidence.studies.architectures import (ArchitectureEvidence, architecture_markdown,
                                                      architecture_table, measured_table2,
                                                      read_architectures, runs_of)
from multitask.evidence.studies.claims import TCN_CLAIMS, Claim, evaluate
from multitask.evidence.studies.claims_table import claims_note
from multitask.grid.spec import Experiment
from multitask.models.run_record import read_run_record
from tests.fake_grid import FOLDS, write_fake_grid

#: The issue's TCN grid (results/tcn/*.toml): A, APc (fixed), APoc (GradNorm) on revised labels,
#: A on the original ones.
TCN_EXPERIMENTS = (Experiment(("A", "APc"), ("fixed",), ("revised",), ("bidirectional",)),
                   Experiment(("APoc",), ("gradnorm",), ("revised",), ("bidirectional",)),
                   Experiment(("A",), ("fixed",), ("original",), ("bidirectional",)))
LSTM_EXPERIMENTS = (*TCN_EXPERIMENTS[:2],
                    Experiment(("A", "APc", "APoc"), ("fixed",), ("original",),
                               ("bidirectional",)))


@pytest.fixture(scope="module")
def grids(tmp_path_factory) -> dict[str, Path]:
    """An LSTM grid (16 units, seeds 0-1), an ED-TCN and an MS-TCN grid (seeds 0-1), each with
    timing.json, one data set."""
    root = tmp_path_factory.mktemp("architectures")
    return {"lstm": write_fake_grid(root / "lstm", seeds=(0, 1), experiments=LSTM_EXPERIMENTS,
                                    seconds=120.0),
            "ed-tcn": write_fake_grid(root / "ed-tcn", seeds=(0, 1), encoder="ed-tcn",
                                      experiments=TCN_EXPERIMENTS, seconds=30.0),
            "ms-tcn": write_fake_grid(root / "ms-tcn", seeds=(0, 1), encoder="ms-tcn",
                                      experiments=TCN_EXPERIMENTS, seconds=45.0)}


def _unfinish(grid: Path, config: str, seed: int, folds: str) -> None:
    """Make the runs of ``config`` (``<variant>-<weighting>``, revised) of ``seed`` on ``folds``
    runs still training (no finished.json)."""
    for fold in folds:
        (grid / "runs/revised/bidirectional" / config / f"seed{seed}" / fold
         / "finished.json").unlink()


# --- The claims family ----------------------------------------------------------------------

def test_three_families_of_4_claims_per_score_without_a_published_side():
    families = {}
    for claim in TCN_CLAIMS:
        families.setdefault(claim.family, set()).add(claim.metric)
    assert len(TCN_CLAIMS) == 12 and families == {
        "tcn-progress-accuracy": {"gesture_accuracy"}, "tcn-progress-edit": {"gesture_edit"},
        "tcn-progress-f1@10": {"gesture_f1@10"}}
    assert all(sum(c.family == family for c in TCN_CLAIMS) == 4 for family in families)
    contrasts = {(c.comparison.label, c.metric) for c in TCN_CLAIMS}
    assert len(contrasts) == 12
    for backbone in ("ed-tcn", "ms-tcn"):
        for heads in ("APc-fixed", "APoc-gradnorm"):
            for metric in ("gesture_accuracy", "gesture_edit", "gesture_f1@10"):
                assert (f"{backbone}/{heads} - {backbone}/A-fixed", metric) in contrasts
    assert all(c.expect == +1 and not c.published and c.agreed == "supported"
               for c in TCN_CLAIMS)


@pytest.mark.slow
def test_holm_runs_over_each_familys_declared_4_and_a_missing_backbone_counts_as_untested(
        grids):
    runs = runs_of(read_architectures([grids["lstm"], grids["ed-tcn"]]))
    table = evaluate(runs, TCN_CLAIMS)
    tested = table[table.p_value.notna()]
    assert len(tested) == 6 and set(tested.comparison.str[:6]) == {"ed-tcn"}
    for family, rows in tested.groupby("family"):
        assert len(rows) == 2                  # ed-tcn's two heads; ms-tcn's two untested
        assert rows.p_adjusted.to_numpy() == pytest.approx(
            holm(rows.p_value.to_numpy(float), size=4))
    untested = table[table.p_value.isna()]
    assert all("not tested: no finished runs of ms-tcn/" in note for note in untested.note)
    assert table.paper_diff.isna().all() and table.power_at_paper_effect.isna().all()
    # 4 claims at 8 folds can reach 4 * 2 / 2^8 = 0.031: no floor note
    assert not any("cannot reach an adjusted p" in note for note in tested.note)


def test_the_backbones_claims_pair_only_their_own_runs(grids):
    runs = runs_of(read_architectures([grids["ed-tcn"], grids["ms-tcn"]]))
    edtcn = runs[runs.architecture == "ed-tcn"]
    table = evaluate(runs, TCN_CLAIMS).set_index("claim")
    row = table.loc["tcn-progress-edit:ed-tcn/APc-fixed:gesture_edit"]
    mean = (ConfigId("APc").select(edtcn).groupby("fold").gesture_edit.mean()
            - ConfigId("A").select(edtcn).groupby("fold").gesture_edit.mean()).mean()
    assert row.ours_diff == pytest.approx(mean) and row.folds == 8 and row.seeds == 2


def test_verdicts_read_supported_for_a_conjecture_and_the_note_says_what_they_mean():
    rng = np.random.default_rng(3)
    difficulty = dict(zip(FOLDS, rng.normal(0, 5, len(FOLDS))))
    runs = pd.DataFrame([{"architecture": "ed-tcn", "annotations": "revised",
                          "direction": "bidirectional", "variant": v, "weighting": "fixed",
                          "seed": 0, "fold": f, "gesture_edit": 80 + difficulty[f] + gain}
                         for v, gain in (("A", 0.0), ("APc", 3.0)) for f in FOLDS])
    claim = Claim("solo:ed-tcn/APc-fixed:gesture_edit", "q",
                  Contrast(ConfigId("APc", architecture="ed-tcn"),
                           ConfigId("A", architecture="ed-tcn")), "gesture_edit", +1,
                  published=False, agreed="supported")
    assert evaluate(runs, (claim,)).verdict.iloc[0] == "supported"     # a family of one
    loss = runs.assign(gesture_edit=np.where(runs.variant == "APc", runs.gesture_edit - 6,
                                             runs.gesture_edit))
    assert evaluate(loss, (claim,)).verdict.iloc[0] == "contradicted"
    note = claims_note(evaluate(runs, (claim,)), agreed="supported")
    assert "Verdict: supported / contradicted" in note and "no evidence of equality" in note
    assert "conjecture expects, a gain" in note and "ED-TCN: the backbone" in note
    assert "reproduced" not in note and "Paper:" not in note


# --- Keeping architectures apart ------------------------------------------------------------

def test_an_architecture_prefix_selects_its_grid_s_runs_and_reads_back():
    config = ConfigId.parse("ms-tcn/original/A-fixed")
    assert config == ConfigId("A", annotations="original", architecture="ms-tcn")
    assert config.label == "ms-tcn/original/A-fixed"
    assert ConfigId.parse("lstm-1024/APc").architecture == "lstm-1024"
    with pytest.raises(ValueError, match="nor an architecture"):
        ConfigId.parse("lstm/A-fixed")
    runs = pd.DataFrame({"architecture": ["ed-tcn", "ms-tcn"], "annotations": "revised",
                         "direction": "bidirectional", "variant": "A", "weighting": "fixed"})
    assert list(ConfigId("A", architecture="ms-tcn").select(runs).architecture) == ["ms-tcn"]
    assert ConfigId("A", architecture="ed-tcn").select(runs.drop(columns="architecture")).empty


def test_two_backbones_are_never_pooled_and_grids_must_share_their_data(grids, tmp_path):
    def records(grid: Path, config: str = "A-fixed") -> dict:
        folder = grid / "runs/revised/bidirectional" / config / "seed0"
        return {run: read_run_record(run) for run in sorted(folder.iterdir())}

    mixed = {**records(grids["ed-tcn"]), **records(grids["ms-tcn"], "APc-fixed")}
    with pytest.raises(MixedArchitectures, match="several architectures in one grid"):
        apart({tmp_path: mixed})
    assert apart({grids["ed-tcn"]: records(grids["ed-tcn"]),
                  grids["lstm"]: records(grids["lstm"])}) == {grids["ed-tcn"]: "ed-tcn",
                                                               grids["lstm"]: "lstm-16"}
    other = write_fake_grid(tmp_path / "other", seeds=(0,), encoder="ed-tcn",
                            experiments=TCN_EXPERIMENTS[:1])
    with pytest.raises(MixedArchitectures, match="both ed-tcn grids"):
        read_architectures([grids["ed-tcn"], other])
    refingered = write_fake_grid(tmp_path / "refingered", seeds=(0,), encoder="ms-tcn",
                                 experiments=TCN_EXPERIMENTS[:1])
    for config in refingered.glob("runs/*/*/*/seed*/*/config.json"):
        record = json.loads(config.read_text())
        config.write_text(json.dumps({**record, "data_fingerprint": "elsewhere"}))
    with pytest.raises(MixedArchitectures, match="differ in their data"):
        read_architectures([grids["ed-tcn"], refingered])


# --- Table II's measured rows ---------------------------------------------------------------

def test_table2_measures_model_a_on_the_original_labels_of_each_tcn(grids):
    evidence = read_architectures([grids["lstm"], grids["ed-tcn"], grids["ms-tcn"]])
    frame, caption = measured_table2(evidence)
    tcn = frame[frame.config.str.contains("tcn/")]
    assert set(tcn.model) == {"ED-TCN (A)", "MS-TCN (A)"}
    assert set(tcn.config) == {"ed-tcn/A-fixed", "ms-tcn/A-fixed"}     # no APc, no APoc
    assert tcn.right_mean.isna().all() and tcn["diff"].isna().all()   # nothing published
    runs = evidence[1].runs
    original = runs[(runs.annotations == "original") & (runs.variant == "A")]
    expected = original.groupby("fold").gesture_edit.mean()
    cell = tcn[(tcn.model == "ED-TCN (A)") & (tcn.metric == "gesture_edit")].iloc[0]
    assert cell.left_mean == pytest.approx(expected.mean())
    assert cell.left_std == pytest.approx(expected.std(ddof=1)) and cell.folds == 8
    revised = ConfigId("A").select(runs).groupby("fold").gesture_edit.mean().mean()
    assert cell.left_mean != pytest.approx(revised)
    assert {"TCN", "TCN+RL"} <= set(frame.model)                      # the quoted rows stay
    lstm = frame[frame.config.str.startswith("lstm-16/")]
    assert set(lstm.model) == {"BiLSTM-16 (A)", "APc (LSTM-16)", "APoc (LSTM-16)"}
    assert lstm.right_mean.notna().all()                             # against the paper's
    assert "Measured here, on this protocol (ours): BiLSTM-16 (A)" in caption
    assert "ED-TCN (A), MS-TCN (A)" in caption and "not run here" in caption


def test_table2_has_no_tcn_row_without_original_label_runs(grids, tmp_path):
    revised_only = write_fake_grid(tmp_path / "ms", seeds=(0,), encoder="ms-tcn",
                                   experiments=TCN_EXPERIMENTS[:2])
    frame, _ = measured_table2(read_architectures([grids["lstm"], revised_only]))
    assert not frame.model.str.contains("TCN \\(A\\)").any()
    frame, caption = measured_table2(read_architectures([revised_only]))
    assert frame.empty and caption == ""


def test_row_labels_name_the_encoder_and_only_an_lstm_joins_the_papers():
    from multitask.evidence.render.tables import PAPER_TABLES, encoder_label, of_encoder
    assert encoder_label("BiLSTM (A)", "LSTM-1024") == "BiLSTM-1024 (A)"
    assert encoder_label("LSTM (A)", "LSTM-128") == "LSTM-128 (A)"
    assert encoder_label("BiLSTM (A)", "ED-TCN") == "ED-TCN (A)"
    assert encoder_label("BiLSTM (A)", "LSTMish.enc:Enc") == "LSTMish.enc:Enc (A)"
    assert encoder_label("APc", "MS-TCN") == "APc (MS-TCN)"
    table3 = next(t for t in PAPER_TABLES if t.name == "table3")
    shown = of_encoder(table3, "my_pkg.enc:Enc")
    assert "LSTM" not in shown.title and r"my\_pkg.enc:Enc" in shown.title
    assert not any(shown.paper.values()) and shown.labels["A-fixed"] == "my_pkg.enc:Enc (A)"


def test_a_tcn_grids_own_tables_name_its_encoder_never_the_papers_bilstm(grids, tmp_path):
    """``multitask-tables paper`` on a TCN grid: Table II's row is the TCN's, alone (the paper has
    no such row; its BiLSTM's numbers beside ours would read as the paper's TCN); Table I keeps the
    paper's LSTM numbers and says so; the bold of the paper's rows stays the paper's own."""
    assert tables_main(["paper", str(grids["ed-tcn"]), "--no-figures", "--out",
                        str(tmp_path / "t")]) == 0
    table2 = pd.read_csv(tmp_path / "t" / "table2.csv")
    ours = table2[table2.config == "A-fixed"]
    assert set(ours.model) == {"ED-TCN (A)"} and not table2.model.str.contains("BiLSTM").any()
    assert ours.right_mean.isna().all() and ours["diff"].isna().all()
    assert {"TCN", "TCN+RL"} <= set(table2.model)
    tex = (tmp_path / "t" / "table2.tex").read_text()
    assert "Ours: ED-TCN, which the paper did not run" in tex and "BiLSTM" not in tex
    assert "ours beside the paper's Table II" in tex and r"$\Delta$ = ours" not in tex
    assert r"\textbf{87.9}" in tex and r"\textbf{82.1}" not in tex   # the paper's best edit only
    table1 = pd.read_csv(tmp_path / "t" / "table1.csv")
    assert table1[table1.config == "A-fixed"].right_mean.notna().all()
    assert "The paper's numbers are its LSTM's: the difference compares our ED-TCN" in (
        tmp_path / "t" / "table1.tex").read_text()
    assert "The paper's differences are its LSTM's; ours are ED-TCN's." in (
        tmp_path / "t" / "claims.tex").read_text()
    assert tables_main(["paper", str(grids["lstm"]), "--no-figures", "--out",
                        str(tmp_path / "l")]) == 0
    lstm = pd.read_csv(tmp_path / "l" / "table2.csv")
    ours = lstm[lstm.config == "A-fixed"]
    assert ours.model.str.startswith("BiLSTM (A)").all() and ours["diff"].notna().all()
    assert "LSTM's" not in (tmp_path / "l" / "claims.tex").read_text()


# --- The cross-architecture table -----------------------------------------------------------

def test_an_unfinished_grid_enters_with_its_finished_seeds_only_and_says_so(grids, tmp_path):
    partial = write_fake_grid(tmp_path / "wide", seeds=(0, 1), hidden=32,
                              experiments=TCN_EXPERIMENTS[:2], seconds=600.0)
    _unfinish(partial, "A-fixed", 1, "BCDEF")                 # seed 1 of A: 3 of 8 folds
    _unfinish(partial, "APoc-gradnorm", 0, FOLDS)             # APoc: seed 1 only
    _unfinish(partial, "APoc-gradnorm", 1, FOLDS)             # ... and not even that: none
    evidence = read_architectures([grids["lstm"], partial])
    table = architecture_table(evidence, None).set_index(["architecture", "model"])
    a = table.loc[("LSTM-32", "A")]
    assert (a.seeds, a.folds, a.runs, a.runs_recorded) == ("0", 8, 8, 16)
    assert a.note == "seed 1: 3 of 8 folds finished, left out"
    seed0 = ConfigId("A").select(evidence[1].runs)
    assert set(seed0.seed) == {0}
    assert a.gesture_edit_mean == pytest.approx(seed0.gesture_edit.mean())
    apoc = table.loc[("LSTM-32", "APoc (alpha=1.5)")]
    assert apoc.runs == 0 and apoc.runs_recorded == 16 and np.isnan(apoc.gesture_edit_mean)
    assert "seed 0: 0 of 8 folds finished" in apoc.note
    full = table.loc[("LSTM-16", "APc (w1=w2=1)")]
    assert (full.seeds, full.runs, full.note) == ("0 1", 16, "")
    assert full.seconds_mean == pytest.approx(120.0)          # timing.json, every phase
    markdown = architecture_markdown(architecture_table(evidence, None))
    assert "| LSTM-32 | A |" in markdown and "1 x 8 (8 of 16 runs)" in markdown
    assert "not run yet" in markdown and "10 min 00 s" in markdown and "2 min 00 s" in markdown


def test_the_table_lists_each_architecture_s_models_cost_and_the_time_only_row(grids):
    evidence = read_architectures([grids["lstm"], grids["ed-tcn"], grids["ms-tcn"]])
    time_only = pd.DataFrame({"fold": list(FOLDS), "progress_accuracy": np.linspace(40, 47, 8),
                              "progress_edit": 70.0, "progress_f1@10": 60.0})
    table = architecture_table(evidence, time_only)
    assert list(table.architecture[:9]) == ["LSTM-16"] * 3 + ["ED-TCN"] * 3 + ["MS-TCN"] * 3
    assert list(table.model[:3]) == ["A", "APc (w1=w2=1)", "APoc (alpha=1.5)"]
    assert table.seconds_mean[3] == pytest.approx(30.0)
    assert table.seconds_mean[6] == pytest.approx(45.0)
    assert table.progress_accuracy_mean.isna()[[0, 3, 6]].all()      # model A has no progress
    last = table.iloc[-1]
    assert last.model == "Time only (t/T)" and last.folds == 8
    assert last.progress_accuracy_mean == pytest.approx(43.5)
    assert np.isnan(last.gesture_accuracy_mean)


def test_a_run_without_timing_is_named_and_left_out_of_the_cost(grids, tmp_path):
    grid = write_fake_grid(tmp_path / "ed", seeds=(0,), encoder="ed-tcn",
                           experiments=TCN_EXPERIMENTS[:1], seconds=30.0)
    (grid / "runs/revised/bidirectional/A-fixed/seed0/B/timing.json").unlink()
    (grid / "runs/revised/bidirectional/APc-fixed/seed0/C/timing.json").write_text('{"train": 90}')
    table = architecture_table(read_architectures([grid]), None).set_index("model")
    assert table.loc["A"].note == "1 run(s) without timing.json"
    assert table.loc["A"].seconds_mean == pytest.approx(30.0)
    assert table.loc["APc (w1=w2=1)"].seconds_max == pytest.approx(90.0)


# --- The command ----------------------------------------------------------------------------

@pytest.mark.slow
def test_one_command_writes_every_file_and_again_the_same_bytes(grids, tmp_path, capsys):
    args = ["architectures", str(grids["lstm"]), str(grids["ed-tcn"]), str(grids["ms-tcn"])]
    assert tables_main([*args, "--out", str(tmp_path / "a")]) == 0
    assert tables_main([*args, "--out", str(tmp_path / "b")]) == 0
    names = {"architectures.csv", "architectures.tex", "architectures.md", "claims.csv",
             "claims.tex", "claims_note.tex", "claims_config.json", "table2.csv", "table2.tex"}
    assert {p.name for p in (tmp_path / "a").iterdir()} == names | {"architectures.json"}
    for name in names:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    claims = pd.read_csv(tmp_path / "a" / "claims.csv")
    assert len(claims) == 12 and claims.p_value.notna().all()
    assert "ED-TCN\\ APc" in (tmp_path / "a" / "claims.tex").read_text()
    for name in ("claims.tex", "claims_note.tex", "claims_config.json"):   # families per score
        assert "quoted sentence and score" in (tmp_path / "a" / name).read_text()


@pytest.mark.parametrize("case", ["missing", "not a grid", "twice", "same architecture",
                                  "with GRID_DIR"])
def test_command_errors_are_one_line_exit_2_and_write_nothing(grids, tmp_path, capsys, case):
    out = tmp_path / "out"
    grid = str(grids["ed-tcn"])
    copy = tmp_path / "copy"
    if case == "same architecture":
        write_fake_grid(copy, seeds=(0,), encoder="ed-tcn", experiments=TCN_EXPERIMENTS[:1])
    (tmp_path / "plain").mkdir()
    args = {"missing": [str(tmp_path / "nowhere")], "not a grid": [str(tmp_path / "plain")],
            "twice": [grid, grid + "/"], "same architecture": [grid, str(copy)],
            "with GRID_DIR": [grid]}[case]
    argv = ["architectures", *args, "--out", str(out)]
    if case == "with GRID_DIR":              # the flag form of earlier versions, checked as it was
        with pytest.raises(SystemExit) as exit_info:
            tables_main([grid, "--architectures", *args, "--out", str(out)])
        assert exit_info.value.code == 2
    else:
        assert tables_main(argv) == 2
    error = capsys.readouterr().err
    lines = [line for line in error.splitlines() if not line.startswith("WARNING")]
    assert lines[-1].startswith("multitask-tables: error: ") and "Traceback" not in error
    if case != "with GRID_DIR":
        assert len(lines) == 1
    expected = {"missing": "nowhere: no such folder", "not a grid": "no grid.json",
                "twice": "given twice", "same architecture": "both ed-tcn grids",
                "with GRID_DIR": "without GRID_DIR"}[case]
    assert expected in lines[-1]
    assert not out.exists()


def test_the_evidence_of_a_grid_names_its_architecture(grids):
    part = read_architectures([grids["ms-tcn"]])[0]
    assert isinstance(part, ArchitectureEvidence)
    assert part.architecture == "ms-tcn" and part.name == "MS-TCN"
    assert set(part.runs.architecture) == {"ms-tcn"} and part.left_out == {}


def test_grids_are_compared_per_annotation_version_whose_labels_the_fingerprint_covers(
        tmp_path):
    """The data fingerprint covers the labels: a grid whose first run is on the original labels
    and one on the revised labels only are the same data when each version's fingerprint
    agrees."""
    def fingerprinted(grid: Path, prints: dict[str, str]) -> Path:
        for config in grid.glob("runs/*/*/*/seed*/*/config.json"):
            record = json.loads(config.read_text())
            annotations = config.relative_to(grid).parts[1]
            config.write_text(json.dumps({**record, "data_fingerprint": prints[annotations]}))
        return grid

    originals_first = fingerprinted(write_fake_grid(
        tmp_path / "lstm", seeds=(0,), experiments=(LSTM_EXPERIMENTS[2], *TCN_EXPERIMENTS[:2])),
        {"revised": "r", "original": "o"})
    revised_only = fingerprinted(write_fake_grid(
        tmp_path / "ed", seeds=(0,), encoder="ed-tcn", experiments=TCN_EXPERIMENTS[:1]),
        {"revised": "r"})
    assert [p.architecture for p in read_architectures([originals_first, revised_only])] == [
        "lstm-16", "ed-tcn"]
    fingerprinted(revised_only, {"revised": "x"})
    with pytest.raises(MixedArchitectures, match="data_fingerprint; revised labels"):
        read_architectures([originals_first, revised_only])


@pytest.mark.slow
def test_the_latex_compiles_and_fits_an_ieee_page(grids, tmp_path):
    from tests.test_latex import IEEE_TWO_COLUMN, _pdflatex

    if shutil.which("pdflatex") is None:
        pytest.skip("pdflatex is not installed (Debian: apt-get install texlive-latex-base "
                    "texlive-latex-recommended)")
    partial = write_fake_grid(tmp_path / "wide", seeds=(0, 1), hidden=1024,
                              experiments=TCN_EXPERIMENTS[:2], seconds=3000.0)
    _unfinish(partial, "A-fixed", 1, "BCDEF")
    out = tmp_path / "out"
    assert tables_main(["architectures", str(grids["lstm"]), str(partial),
                        str(grids["ed-tcn"]), str(grids["ms-tcn"]), "--out", str(out)]) == 0
    for name in ("architectures", "claims", "table2"):
        tex = (out / f"{name}.tex").read_text()
        if name == "claims":
            tex += (out / "claims_note.tex").read_text()
        document = "\n".join([IEEE_TWO_COLUMN, *required_packages(tex), r"\begin{document}",
                              tex, r"\end{document}", ""])
        log = _pdflatex(tmp_path, name, document)
        assert "Overfull \\hbox" not in log, f"{name} is wider than the page"
        assert "Float too large" not in log, f"{name} is higher than a page"


def test_one_table_never_holds_runs_of_two_encoders(grids, tmp_path, capsys):
    """Runs trained one by one: an LSTM's model A and an ED-TCN's APc would be rows of one
    table, and multitask-tables pair would pair them as one model's configurations."""
    collection = tmp_path / "runs"
    for name, grid, config in (("lstm_A", grids["lstm"], "A-fixed"),
                               ("edtcn_APc", grids["ed-tcn"], "APc-fixed")):
        shutil.copytree(grid / "runs/revised/bidirectional" / config / "seed0/B",
                        collection / name)
    assert tables_main(["runs", str(collection), "--out", str(tmp_path / "tables")]) == 2
    error = capsys.readouterr().err
    assert "runs of several encoders (ed-tcn (" in error and "lstm (" in error
    assert "multitask-tables architectures" in error and len(error.strip().splitlines()) == 1
    assert not (tmp_path / "tables").exists()
