"""The package describes itself: licence, citation, metadata and one version everywhere; each
subpackage's public names."""
from __future__ import annotations

import ast
import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

from jigsaws_tools.cli.common import package_version

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("jigsaws_tools", "rnn_seg", "baseline", "multitask")


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


def _folders() -> list[str]:
    """Every package folder of the project (``multitask/grid`` ...), as a path under the root."""
    return sorted(str(init.parent.relative_to(ROOT)) for package in PACKAGES
                  for init in (ROOT / package).rglob("__init__.py"))


def test_the_package_table_names_every_folder_and_module():
    text = (ROOT / "docs" / "PACKAGES.md").read_text()
    table = text.split("# Packages")[1].split("Imports flow")[0]
    rows = {match.group(1): match.group(2)
            for match in re.finditer(r"^\| `([\w/]+)/` \|(.*)$", table, re.M)}
    assert sorted(rows) == _folders()
    for folder, row in rows.items():
        named = set(re.findall(r"`([\w]+\.py)`", row)) - {"__init__.py"}  # a pointer to it
        modules = {path.name for path in (ROOT / folder).glob("*.py")} - {"__init__.py"}
        assert modules == named, (folder, sorted(modules - named), sorted(named - modules))
        assert len(re.findall(r"\*\*`\w+\.py`\*\*", row)) == (folder != "multitask"), folder


def test_every_package_folder_says_what_it_holds_and_may_import():
    for folder in _folders():
        doc = ast.get_docstring(ast.parse((ROOT / folder / "__init__.py").read_text()))
        assert doc and re.search(r"\bimport", doc, re.I), folder


def _imports(module: str, source: str) -> set[str]:
    """The project modules that ``source`` (the text of ``module``) imports, relative imports
    resolved."""
    package = module.split(".")[:-1]          # the package of ``a.b.c`` or of ``a.b.__init__``
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            found.add(".".join(base + ([node.module] if node.module else [])))
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {name for name in found if name.split(".")[0] in PACKAGES}


#: Who may import whom: a layer imports itself and the layers listed for it (a layer listed
#: with its wings: ``multitask.evidence`` and ``multitask.evidence.runs``, ...).
_BELOW_EVIDENCE = {"jigsaws_tools", "rnn_seg", "baseline", "multitask.models", "multitask.grid",
                   "multitask.inference"}
#: ``multitask.evidence``'s wings in the order the evidence flows: each imports those before it.
EVIDENCE_WINGS = ("runs", "statistics", "render", "studies", "plans", "commands")
LAYERS = {
    "jigsaws_tools": set(),
    "rnn_seg": {"jigsaws_tools"},
    "baseline": {"jigsaws_tools", "rnn_seg"},
    "multitask": {"jigsaws_tools", "rnn_seg", "baseline", "multitask.models", "multitask.grid",
                  "multitask.inference", "multitask.evidence"},
    "multitask.models": {"jigsaws_tools", "rnn_seg", "baseline"},
    "multitask.grid": {"jigsaws_tools", "rnn_seg", "baseline", "multitask.models"},
    "multitask.inference": {"jigsaws_tools", "rnn_seg", "baseline", "multitask.models"},
    "multitask.evidence": _BELOW_EVIDENCE | {f"multitask.evidence.{w}" for w in EVIDENCE_WINGS},
    **{f"multitask.evidence.{wing}": _BELOW_EVIDENCE
       | {f"multitask.evidence.{w}" for w in EVIDENCE_WINGS[:i]}
       for i, wing in enumerate(EVIDENCE_WINGS)},
}


def _layer(module: str) -> str:
    """The innermost layer of ``LAYERS`` that holds ``module``."""
    parts = module.split(".")
    return next(".".join(parts[:n]) for n in range(len(parts), 0, -1)
                if ".".join(parts[:n]) in LAYERS or n == 1)


def _allowed(layer: str, target: str) -> bool:
    """Whether ``layer`` may import a module of the layer ``target``."""
    return any(target == name or target.startswith(name + ".") for name in (layer, *LAYERS[layer]))


def _upward_imports(module: str, source: str) -> list[str]:
    layer = _layer(module)
    return [f"{module} imports {name}" for name in sorted(_imports(module, source))
            if not _allowed(layer, _layer(name))]


def test_imports_flow_one_way_between_packages_and_between_wings():
    offending = []
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            offending += _upward_imports(module, path.read_text())
    assert not offending


def test_the_import_rule_refuses_an_upward_import():
    source = "from ..evidence import tables\nfrom ..grid.spec import GridSpec\nfrom .heads import x"
    assert _upward_imports("multitask.models.variants", source) == [
        "multitask.models.variants imports multitask.evidence",
        "multitask.models.variants imports multitask.grid.spec"]
    assert _upward_imports("rnn_seg.runs.lock", "import multitask.models") == [
        "rnn_seg.runs.lock imports multitask.models"]
    assert not _upward_imports("multitask.evidence.cli", "from ..grid.archive import a")


def test_the_import_rule_refuses_an_import_against_the_evidence_flow():
    assert _upward_imports("multitask.evidence.render.figures",
                           "from ..studies.claims import CLAIMS\nfrom ..runs.collect import a\n"
                           "from . import drawing\nfrom ...grid.spec import RunKey") == [
        "multitask.evidence.render.figures imports multitask.evidence.studies.claims"]
    assert _upward_imports("multitask.evidence.runs.collect", "from .. import cli") == [
        "multitask.evidence.runs.collect imports multitask.evidence"]
    assert not _upward_imports("multitask.evidence.studies.width",
                               "from ..render.figures import save\nfrom .claims import CLAIMS")
    assert _upward_imports("multitask.evidence.studies.claims",
                           "from ..plans.confirm import read_plan") == [
        "multitask.evidence.studies.claims imports multitask.evidence.plans.confirm"]
    assert _upward_imports("multitask.evidence.plans.design",
                           "from ..commands.common import publish\nfrom ..studies import claims\n"
                           "from .confirm import Plan") == [
        "multitask.evidence.plans.design imports multitask.evidence.commands.common"]
    assert not _upward_imports("multitask.evidence.commands.plans.confirm",
                               "from ..common import publish\nfrom ...plans.confirm import a")


def test_every_pip_install_builds_through_the_declared_build_system():
    """pyproject.toml names setuptools' PEP 517 backend (PEP 660 editable installs from 64 on),
    so that ``pip install -e .`` and ``pip install -e ".[test]"`` take one code path."""
    import tomllib

    build = tomllib.loads((ROOT / "pyproject.toml").read_text())["build-system"]
    assert build["build-backend"] == "setuptools.build_meta"
    assert "setuptools>=64" in build["requires"]
    extras = re.search(r"extras_require=\{(.*?)\n    \}", (ROOT / "setup.py").read_text(), re.S)
    assert '"mlflow": ["mlflow-skinny' in extras.group(1)
