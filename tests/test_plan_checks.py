"""A confirmatory plan cannot say what its numbers do not (issue 66, item 3), and no TOML file the
project reads can crash its reader.

A plan (``multitask.evidence.plans.confirm``) and its exploratory file are checked as strictly as a grid
spec: every number finite and in range, outcomes three distinct words, one-line names and titles,
configurations and metrics that exist, no endpoint twice in a part. Every TOML file (task
definitions, recording formats, grid specs, plans, exploratory files) is read by
``jigsaws_tools.toml_files.read_toml``: a folder, a FIFO, a file too large, bad UTF-8, nesting
too deep or an integer too long is one line naming the file, at once.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from jigsaws_tools.errors import DefinitionError
from jigsaws_tools.recording_format import load_format
from jigsaws_tools.task_definition import read_task_file
from jigsaws_tools.toml_files import MAX_TOML_BYTES, read_toml
from multitask.evidence.cli import main as tables_main
from multitask.evidence.plans.confirm import PlanError, analyse, read_plan
from multitask.evidence.plans.exploratory import read_exploratory
from multitask.grid.spec import load_spec
from test_archive_and_inputs import at_most
from test_confirm import PLAN, project  # noqa: F401  (a fixture)

ENDPOINT = '{x = "APc-fixed", y = "A-fixed", metric = "gesture_edit", paper_gain = 2.3}'

#: (what the plan's text has, what it is replaced by, the key the error names).
BAD_PLANS = {
    # numbers no interval can be compared with, or out of their range
    "an infinite gain": ("paper_gain = 2.3", "paper_gain = inf", "endpoints[1].paper_gain"),
    "a negative infinite gain": ("paper_gain = 2.3", "paper_gain = -inf",
                                 "endpoints[1].paper_gain"),
    "a NaN gain": ("paper_gain = 0.7", "paper_gain = nan", "endpoints[0].paper_gain"),
    "an infinite threshold": ("rule_out_below = 3.0", "rule_out_below = inf",
                              "parts[1].rule_out_below"),
    "a NaN threshold": ("rule_out_below = 3.0", "rule_out_below = nan",
                        "parts[1].rule_out_below"),
    "a NaN confidence": ("confidence = 0.95", "confidence = nan", "confidence"),
    "a confidence of 1.5": ("confidence = 0.95", "confidence = 1.5", "confidence"),
    "a confidence of 1": ("confidence = 0.95", "confidence = 1", "confidence"),
    "no width": ('grid = "grids/wide"', 'grid = "grids/wide"\nhidden = 0', "parts[0].hidden"),
    "a negative seed": ("seeds = [0, 1, 2]", "seeds = [-1, 1, 2]", "parts[0].seeds"),
    # outcomes: three distinct one-line words
    "two outcomes alike": ('"reproduced", "contradicted", "inconclusive"',
                           '"reproduced", "reproduced", "inconclusive"', "parts[0].outcomes"),
    "an empty outcome": ('"reproduced", "contradicted", "inconclusive"',
                         '"reproduced", "", "inconclusive"', "parts[0].outcomes[1]"),
    "a blank outcome": ('"replicated", "not replicated", "inconclusive"',
                        '"replicated", "   ", "inconclusive"', "parts[1].outcomes[1]"),
    "an outcome of two lines": ('"reproduced", "contradicted", "inconclusive"',
                                '"reproduced", "contra\\ndicted", "inconclusive"',
                                "parts[0].outcomes[1]"),
    "a numeric outcome": ('"reproduced", "contradicted", "inconclusive"',
                          '"reproduced", 2, "inconclusive"', "parts[0].outcomes"),
    "two outcomes": ('"reproduced", "contradicted", "inconclusive"',
                     '"reproduced", "contradicted"', "parts[0].outcomes"),
    "two outcomes alike but for case": ('"reproduced", "contradicted", "inconclusive"',
                                        '"reproduced", "Reproduced", "inconclusive"',
                                        "parts[0].outcomes must be 3 distinct"),
    "two outcomes alike but for spaces": ('"replicated", "not replicated", "inconclusive"',
                                          '"replicated", "not  replicated ", "not replicated"',
                                          "parts[1].outcomes must be 3 distinct"),
    # names and titles on one line
    "a title of two lines": ('title = "a claim"', 'title = "a claim\\n## injected"',
                             "parts[0].title"),
    "an empty title": ('title = "a claim"', 'title = ""', "parts[0].title"),
    "a name with a control character": ('name = "primary"', 'name = "pri\\u001bmary"',
                                        "parts[0].families[0].name"),
    "two families of one name": ('name = "secondary"', 'name = "primary"',
                                 "parts[0].families: two families of one name"),
    # an endpoint twice in a family: the same, reversed, or spelt another way
    "an endpoint twice": (ENDPOINT, f"{ENDPOINT}, {ENDPOINT}", "endpoints[2]"),
    "an endpoint reversed": (ENDPOINT, ENDPOINT + ", " + ENDPOINT.replace(
        'x = "APc-fixed", y = "A-fixed"', 'x = "A-fixed", y = "APc-fixed"'), "endpoints[2]"),
    "an endpoint spelt another way": (ENDPOINT, ENDPOINT + ", " + ENDPOINT.replace(
        'y = "A-fixed"', 'y = "revised/A"'), "endpoints[2]"),
    # ... or in two families of a part (one test reported twice, counted in both corrections)
    "an endpoint in two families": ('metric = "gesture_accuracy", paper_gain = 0.7',
                                    'metric = "gesture_edit", paper_gain = 0.7',
                                    "parts[0].families[1].endpoints[0]: APoc-gradnorm - A-fixed"),
    "an endpoint reversed in another family": (
        '{x = "APoc-gradnorm", y = "A-fixed", metric = "gesture_accuracy"',
        '{x = "A-fixed", y = "APc-fixed", metric = "gesture_edit"',
        "parts[0].families[1].endpoints[0]: A-fixed - APc-fixed"),
    "a configuration against itself": ('y = "A-fixed", metric = "gesture_edit", paper_gain = 2.3',
                                       'y = "APc", metric = "gesture_edit", paper_gain = 2.3',
                                       "endpoints[1]"),
    # a misspelt configuration or metric is named as such
    "a misspelt weighting": ('x = "APc-fixed"', 'x = "APc-fixd"', "endpoints[1].x"),
    "a misspelt variant": ('x = "APc-fixed"', 'x = "APx-fixed"', "endpoints[1].x"),
    "GradNorm on one task": ('y = "A-fixed", metric = "gesture_edit", paper_gain = 2.3',
                             'y = "A-gradnorm", metric = "gesture_edit", paper_gain = 2.3',
                             "endpoints[1].y"),
    "a misspelt direction": ('x = "APc-fixed"', 'x = "backward/APc-fixed"', "endpoints[1].x"),
    "a misspelt metric": ('metric = "gesture_accuracy"', 'metric = "gesture_acuracy"',
                          "endpoints[0].metric"),
    "a misspelt task's score": ('metric = "gesture_accuracy"', 'metric = "gestures_f1_G2"',
                                "endpoints[0].metric"),
    "a width of 1000.0": ('grid = "grids/wide"', 'grid = "grids/wide"\nhidden = 1e3',
                          "parts[0].hidden must be an integer"),
}


@pytest.mark.parametrize("case", BAD_PLANS)
def test_a_plan_that_says_what_its_numbers_do_not_is_refused_naming_the_key(
        tmp_path: Path, capsys, case: str):
    """Refused when read, naming the plan and the key, in one line; the command exits 2 and
    writes nothing (not a part reported as not analysed, not an outcome of an interval
    compared with inf)."""
    old, new, key = BAD_PLANS[case]
    assert old in PLAN
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.replace(old, new, 1))
    with pytest.raises(PlanError, match=re.escape(key)) as refused:
        read_plan(plan)
    assert str(refused.value).startswith(f"{plan}: ") and "\n" not in str(refused.value)
    out = tmp_path / "out"
    assert tables_main(["confirm", str(plan), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and key in err and str(plan) in err
    assert not out.exists()


def test_a_configuration_the_grid_lacks_is_named_not_taken_for_an_incomplete_grid(
        project: Path):  # noqa: F811
    """A configuration that exists but is not in the part's complete grid (APr-fixed): the part
    is not analysed, saying the grid holds no run of it and which configurations it holds,
    never that runs are still to finish."""
    plan = project / "confirm" / "plan.toml"
    plan.write_text(PLAN.replace('x = "APc-fixed"', 'x = "APr-fixed"'))
    table, _, skipped = analyse(read_plan(plan))
    assert table.empty
    assert skipped[0].startswith("wide: not analysed, its grid grids/wide does not hold what "
                                 "the plan tests: APr-fixed: no run of this configuration (the "
                                 "grid holds A-fixed, APc-fixed, APoc-gradnorm)")
    assert "complete grids only" not in skipped[0]


@pytest.mark.parametrize("metric", ["gesture_accuracy_poled", "gesture_f1_G99"])
def test_a_metric_the_grids_runs_have_not_is_named_as_the_plans_error(
        project: Path, metric: str):  # noqa: F811
    """A per-class score's class is the task's, known from the grid only: a class the runs have
    not is a ``PlanError`` naming the plan, the part and the metric when the part is analysed
    (not a part reported as incomplete)."""
    plan = project / "confirm" / "plan.toml"
    plan.write_text(PLAN.replace('metric = "gesture_accuracy"', f'metric = "{metric}"'))
    with pytest.raises(PlanError, match=re.escape(f"{plan}: part wide, family secondary: metric "
                                                  f"{metric!r} is not a score of the runs of "
                                                  "grids/wide")):
        analyse(read_plan(plan))


EXPLORATORY = """
[[analyses]]
part = "wide"
name = "more seeds"
borrowed = [{config = "A-fixed", grid = "grids/other", seeds = [3]}]
"""


@pytest.mark.parametrize("old, new, key", [
    ('config = "A-fixed"', 'config = "A-fixd"', "borrowed[0].config: 'A-fixd' is not a"),
    ("seeds = [3]", "seeds = [-3]", "borrowed[0].seeds"),
    ('name = "more seeds"', 'name = "more\\nseeds"', "analyses[0].name"),
    ('seeds = [3]}]', 'seeds = [3]}, {config = "A", grid = "grids/x", seeds = [4, 3]}]',
     "borrowed[1]: A-fixed's seeds 3 are borrowed already"),
    ("[[analyses]]", EXPLORATORY.strip() + "\n\n[[analyses]]",
     "analyses[1].name: part wide has an analysis 'more seeds' already"),
])
def test_an_exploratory_file_is_checked_as_its_plan(tmp_path: Path, old, new, key):
    (tmp_path / "plan.toml").write_text(PLAN)
    plan = read_plan(tmp_path / "plan.toml")
    path = tmp_path / "exploratory.toml"
    path.write_text(EXPLORATORY.replace(old, new, 1))
    with pytest.raises(PlanError, match=re.escape(key)):
        read_exploratory(path, plan)


def _plan_reader(path: Path):
    return read_plan(path)


def _exploratory_reader(path: Path):
    plan = path.parent / "plan.toml"
    plan.write_text(PLAN)
    return read_exploratory(path, read_plan(plan))


#: Every kind of TOML file the project reads, by its reader.
READERS = {"task definition": read_task_file, "recording format": load_format,
           "spec": load_spec, "plan": _plan_reader,
           "plan's exploratory": _exploratory_reader}


def _bad_files(folder: Path) -> dict[str, Path]:
    """Files no reader may crash on, in ``folder``: each named ``<case>.toml``."""
    texts = {"nested too deeply": "a = " + "[" * 5000 + "]" * 5000,
             "nested tables too deeply": "a = " + "{b = " * 3000 + "1" + "}" * 3000,
             "an integer too long": "a = " + "7" * 5000,
             "bad UTF-8": b"name = \"\xff\xfe\"\n",
             "not TOML": "name = ",
             "NUL bytes": b"name = \"a\0\"\n",
             "too large": "# " + "x" * MAX_TOML_BYTES + "\n"}
    files = {}
    for case, text in texts.items():
        files[case] = folder / f"{case}.toml"
        data = text.encode() if isinstance(text, str) else text
        files[case].write_bytes(data)
    files["a folder"] = folder / "folder.toml"
    files["a folder"].mkdir()
    files["a FIFO"] = folder / "fifo.toml"
    os.mkfifo(files["a FIFO"])
    files["missing"] = folder / "missing.toml"
    files["a dangling link"] = folder / "dangling.toml"
    files["a dangling link"].symlink_to(folder / "nowhere.toml")
    return files


@pytest.mark.parametrize("what", READERS)
def test_no_toml_file_crashes_its_reader(tmp_path: Path, what: str):
    """Each reader, on each file it cannot read: a ``ValueError`` of one line that names the
    file, at once (a FIFO is not waited on)."""
    read = READERS[what]
    for case, path in _bad_files(tmp_path).items():
        if read is _exploratory_reader and case == "missing":
            assert read(path) == ()                 # no exploratory file: no analyses
            continue
        with at_most(30), pytest.raises(ValueError) as refused:
            read(path)
        message = str(refused.value)
        assert message.startswith(str(path)) and "\n" not in message, (case, message)


@pytest.mark.parametrize("case, problem", [
    ("nested too deeply", "nested too deeply"), ("an integer too long", "4300 digits"),
    ("too large", f"larger than {MAX_TOML_BYTES} bytes"), ("bad UTF-8", "not UTF-8"),
    ("a FIFO", "a FIFO (named pipe), not a spec file"), ("a folder", "a folder, not a spec")])
def test_read_toml_says_what_is_wrong(tmp_path: Path, case: str, problem: str):
    with pytest.raises(DefinitionError, match=re.escape(problem)):
        read_toml(_bad_files(tmp_path)[case], "spec")


@pytest.mark.parametrize("name", ["plan.toml", "exploratory.toml"])
def test_a_fifo_plan_is_refused_before_the_outputs_lock_is_taken(tmp_path: Path, capsys,
                                                                  name: str):
    """A FIFO as the plan or as its exploratory file: one line at once; the output folder is
    not created, so no lock was taken there."""
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN)
    (tmp_path / name).unlink(missing_ok=True)
    os.mkfifo(tmp_path / name)
    out = tmp_path / "out"
    with at_most(60):
        assert tables_main(["confirm", str(plan), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"{tmp_path / name}: a FIFO (named pipe)" in err
    assert not out.exists()


def test_every_toml_file_is_read_by_the_one_reader():
    """Only ``jigsaws_tools/toml_files.py`` parses TOML (``tomllib``): a reader of its own would
    miss its protections."""
    root = Path(__file__).resolve().parents[1]
    parsers = sorted(str(path.relative_to(root))
                     for package in ("jigsaws_tools", "rnn_seg", "baseline", "multitask")
                     for path in (root / package).rglob("*.py")
                     if re.search(r"^\s*(import tomllib|from tomllib)", path.read_text(), re.M))
    assert parsers == ["jigsaws_tools/toml_files.py"]
