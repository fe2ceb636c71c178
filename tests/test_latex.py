"""Paste-ready LaTeX: every table multitask-tables writes compiles with the packages it names, fits
an IEEE two-column page without scaling, uses true minus signs and states its budget."""
from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.render.latex import escape, mean_std, number, required_packages
from multitask.grid.spec import Experiment
from tests.fake_grid import FOLDS, TRIALS, write_fake_grid

#: IEEE conference page (IEEEtran): 43pc text width, two 21pc columns.
IEEE_TWO_COLUMN = (r"\documentclass[10pt,twocolumn]{article}" "\n"
                   r"\setlength{\textwidth}{43pc}\setlength{\columnsep}{1pc}" "\n"
                   r"\setlength{\textheight}{56pc}\setlength{\oddsidemargin}{0pt}" "\n")


@pytest.fixture(scope="module")
def tables(tmp_path_factory) -> dict[str, Path]:
    """Every .tex file of a fake paper grid, with the paper's columns and ``--ours-only``."""
    grid = write_fake_grid(tmp_path_factory.mktemp("grid"))
    written = {}
    for flags, suffix in (([], ""), (["--ours-only"], "_ours")):
        out = grid / f"tables{suffix}"
        assert tables_main([str(grid), "--no-figures", "--out", str(out)] + flags) == 0
        written.update({f"{p.stem}{suffix}": p for p in sorted(out.glob("*.tex"))
                        if p.stem != "claims_note"})          # a paragraph, not a table
    return written


PAPER_TABLES = ("table1", "table2", "table3", "ablation_annotations")


@pytest.fixture(scope="module")
def paper_tables(tables) -> dict[str, Path]:
    return {name: path for name, path in tables.items() if not name.startswith("claims")}


@pytest.mark.slow
def test_every_table_is_written(tables):
    assert set(tables) == {f"{name}{suffix}" for suffix in ("", "_ours")
                           for name in (*PAPER_TABLES, "claims")}


def test_claims_caption_is_short_and_its_method_is_in_the_note_beside_it(tables):
    caption = re.search(r"\\caption\{(.*)\}\n", tables["claims"].read_text()).group(1)
    assert len(caption[:caption.index(" Data:")]) < 400            # the budget sentence aside
    assert "sign vectors" not in caption and "Subscripts" not in caption
    note = tables["claims"].with_name("claims_note.tex").read_text()
    assert r"\ref{tab:claims}" in note and "\\caption" not in note
    for words in ("sign-flip test over all $2^n$ sign vectors", "Holm's correction", "Verdict",
                  "Power", "Subscripts", "fwd.: forward LSTM"):
        assert words in note, words


def test_tables_name_their_packages_and_never_scale(tables):
    for name, path in tables.items():
        tex = path.read_text()
        assert required_packages(tex) == [r"\usepackage{booktabs}"], name
        assert r"\resizebox" not in tex and r"\scalebox" not in tex, name


def test_numbers_have_true_minus_signs(paper_tables):
    differences = 0
    for name, path in paper_tables.items():
        body = path.read_text().split(r"\begin{tabular}")[1]
        assert not re.search(r"(?<![\w$-])-\d", body), name       # a hyphen before a digit
        for row in re.findall(r"\$\\Delta\$ &(.*)\\\\", body):     # differences: signed
            cells = [cell.strip() for cell in row.split("&")]
            assert all(re.fullmatch(r"(\$[+-]\$)?\d+\.\d|0\.0|--", c) for c in cells), (name, row)
            assert all(c.startswith("$") for c in cells if c not in ("--", "0.0")), (name, row)
            differences += len(cells)
    assert differences, "no difference rows found"


def test_captions_state_data_folds_budget_and_seeds(tables):
    trials = sum(TRIALS.values())
    for name, path in tables.items():
        caption = re.search(r"\\caption\{(.*)\}\n", path.read_text()).group(1)
        assert f"JIGSAWS Suturing kinematics, {trials} trials" in caption, name
        assert f"leave-one-user-out over {len(FOLDS)} folds (B, C, D, E, F, G, H, I)" in caption
        assert "16 hidden units" in caption and "2 seeds (0, 1)" in caption, name
    assert "12 epochs (8 for Pr, Pc, Poc)" in tables["table1"].read_text()
    assert "12 epochs," in tables["table3"].read_text()          # no P model in Table III


def test_captions_name_the_variants_with_longer_schedules(tmp_path):
    grid = write_fake_grid(tmp_path / "grid", seeds=(0,), schedule_factors={"APoc": 1.5},
                           experiments=(Experiment(("A", "APc", "APoc", "Pc")),))
    assert tables_main(["paper", str(grid), "--no-figures", "--out", str(tmp_path / "out")]) == 0
    assert "12 epochs (18 for APoc; 8 for Pc)" in (tmp_path / "out" / "table1.tex").read_text()


def test_runs_without_their_configuration_get_no_caption(tmp_path, capsys):
    """A run without config.json cannot be checked against its place or the other runs: the
    tables are refused, naming its config.json, rather than captioned with a guess."""
    grid = write_fake_grid(tmp_path / "grid", seeds=(0,), experiments=(Experiment(("A",)),))
    missing = next(grid.glob("runs/**/config.json"))
    missing.unlink()
    assert tables_main(["paper", str(grid), "--no-figures", "--out", str(tmp_path / "out")]) == 2
    assert f"{missing}: not found" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_ours_only_leaves_out_the_paper(tables):
    ours, both = tables["table2_ours"].read_text(), tables["table2"].read_text()
    assert "Paper" in both and "TCN" in both and r"$\Delta$" in both
    assert "Paper" not in ours and "TCN" not in ours and r"$\Delta$" not in ours


def test_bold_is_explained_in_a_note(paper_tables):
    for name, path in paper_tables.items():
        tex = path.read_text()
        assert r"\textbf{" in tex and "Bold: the best value of each row" in tex, name


def test_number_formatting():
    assert number(-1.25) == "$-$1.2" and number(0.04, signed=True) == "0.0"
    assert number(2.0, signed=True) == "$+$2.0" and number(float("nan")) == "--"
    assert mean_std(84.83, 6.31) == "84.8 (6.3)" and mean_std(83.3, None) == "83.3"
    assert escape("a_b & 5%") == r"a\_b \& 5\%"


def _pdflatex(folder: Path, name: str, document: str) -> str:
    (folder / f"{name}.tex").write_text(document)
    result = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error",
                             f"{name}.tex"], cwd=folder, capture_output=True, text=True,
                            timeout=120)
    log = (folder / f"{name}.log").read_text(errors="replace")
    assert result.returncode == 0, log[-3000:]
    return log


needs_pdflatex = pytest.mark.skipif(
    shutil.which("pdflatex") is None,
    reason="pdflatex is not installed (Debian: apt-get install texlive-latex-base "
           "texlive-latex-recommended; .ci/run installs them)")


@needs_pdflatex
def test_every_table_compiles_in_a_minimal_article(tables, tmp_path):
    for name, path in tables.items():
        tex = path.read_text()
        if name.startswith("claims"):                         # and the note beneath it
            tex += path.with_name("claims_note.tex").read_text()
        document = "\n".join([r"\documentclass{article}", *required_packages(tex),
                              r"\begin{document}", tex, r"\end{document}", ""])
        _pdflatex(tmp_path, name, document)


@needs_pdflatex
def test_every_table_fits_an_ieee_two_column_page(tables, tmp_path):
    """``table`` floats fit the column width and ``table*`` the text width, unscaled."""
    for name, path in tables.items():
        tex = path.read_text()
        document = "\n".join([IEEE_TWO_COLUMN, *required_packages(tex), r"\begin{document}",
                              tex, r"\end{document}", ""])
        log = _pdflatex(tmp_path, f"ieee_{name}", document)
        assert "Overfull \\hbox" not in log, f"{name} is wider than its column or page"
        assert "Float too large" not in log, f"{name} is higher than a page"


#: LaTeX that may hold an unescaped ``_``, ``#`` or ``%``: comments, math, labels and references.
_NOT_TEXT = re.compile(r"^\s*%.*$|(?<!\\)\$[^$]*(?<!\\)\$"
                       r"|\\(?:label|ref|begin|end|usepackage)\{[^}]*\}", re.MULTILINE)


def test_every_committed_latex_file_escapes_its_text():
    """Without compiling each (pdflatex may be missing): no committed ``results/**/*.tex`` has a
    ``_``, ``#`` or ``%`` outside math, comments, labels and references that is not escaped, as
    an encoder's import path or a selected setting's name (``feature_set``) in a caption once
    was."""
    root = Path(__file__).resolve().parents[1]
    listed = subprocess.run(["git", "ls-files", "results/*.tex", "results/**/*.tex"], cwd=root,
                            capture_output=True, text=True)
    if listed.returncode != 0:
        pytest.skip(f"git cannot list the committed files: {listed.stderr.strip()}")
    assert listed.stdout.strip(), "no committed .tex file found"
    found = {}
    for name in sorted(set(listed.stdout.split())):
        text = _NOT_TEXT.sub("", (root / name).read_text(encoding="utf-8"))
        bare = re.findall(r".{0,30}(?<!\\)[_#%].{0,10}", text)
        if bare:
            found[name] = bare[0]
    assert not found, found
