"""The package describes itself: licence, citation, metadata and one version everywhere; each
subpackage's public names."""
from __future__ import annotations

import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

from jigsaws_tools.cli_common import package_version

ROOT = Path(__file__).resolve().parents[1]


def _setup(*fields: str) -> list[str]:
    result = subprocess.run([sys.executable, "setup.py", *fields], cwd=ROOT, capture_output=True,
                            text=True, check=True)
    return result.stdout.splitlines()


def test_licence_is_mit_and_names_the_developers():
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License") and "The mtrnn-jigsaws developers" in text


def test_citation_cites_the_software_and_the_paper():
    yaml = pytest.importorskip("yaml")
    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert citation["cff-version"] == "1.2.0" and citation["type"] == "software"
    assert citation["license"] == "MIT"
    paper = citation["references"][0]
    assert paper["doi"] == "10.1109/ICRA40945.2020.9197301"
    assert [a["family-names"] for a in paper["authors"]] == ["van Amsterdam", "Clarkson",
                                                             "Stoyanov"]


def test_one_version_in_setup_citation_and_the_installed_package():
    version, = _setup("--version")
    citation = re.search(r"^version: (\S+)$", (ROOT / "CITATION.cff").read_text(), re.M).group(1)
    assert version == citation == package_version()


def test_metadata_is_complete_and_dependencies_have_upper_bounds():
    author, licence, url = _setup("--author", "--license", "--url")
    assert author == "The mtrnn-jigsaws developers" and licence == "MIT" and url.startswith("https")
    setup = (ROOT / "setup.py").read_text()
    requirements = re.search(r"install_requires=\[(.*?)\]", setup, re.S).group(1)
    for requirement in re.findall(r'"([^"]+)"', requirements):
        assert re.search(r">=[\d.]+,<\d+", requirement), requirement


@pytest.mark.parametrize("package", ["jigsaws_tools", "rnn_seg", "baseline", "multitask"])
def test_every_public_name_of_a_package_is_found_on_first_use(package):
    module = importlib.import_module(package)
    for name, submodule in module._PUBLIC.items():
        defined = importlib.import_module(f"{package}.{submodule}")
        assert getattr(module, name) is getattr(defined, name)
    assert module.__all__ == sorted(module._PUBLIC)
    with pytest.raises(AttributeError, match=f"module '{package}' has no attribute 'nope'"):
        module.nope


@pytest.mark.parametrize("package", ["jigsaws_tools", "rnn_seg", "baseline", "multitask"])
def test_the_readme_package_table_names_every_module(package):
    table = (ROOT / "README.md").read_text().split("## Packages")[1].split("Imports flow")[0]
    row, = [line for line in table.splitlines() if line.startswith(f"| `{package}`")]
    named = set(re.findall(r"`([\w/]+\.py)`", row))
    if "their CLIs" in row:                      # predict_cli.py, evaluate_cli.py, export_cli.py
        named |= {f"{command}_cli.py" for command in ("predict", "evaluate", "export")}
    modules = {path.name for path in (ROOT / package).glob("*.py")} - {"__init__.py"}
    assert modules == named, (sorted(modules - named), sorted(named - modules))
