"""Every command shown in README.md and docs/*.md runs as written.

Each fenced shell command (```` ```bash ````, ``sh``, ``shell``, ``console``) of README.md and
docs/*.md whose program is one of the package's commands is read by that command's own ``main``
with its work replaced by nothing (``run_command``): every option, value and combination is
checked as on the command line, and no work is done. The results READMEs' commands (indented
blocks too) are parsed the same way. A command added to a document later is checked without an
edit here. Documents show the current forms only (no deprecation warning), and a training command
of paper size (the LSTM at 1024 units and 120 epochs: hours on some CPUs) says so on its line, and
its block holds a quick training beside it.

Blocks preceded by the comment ``<!-- tested end to end -->`` are cheap: they run for real, in a
temporary folder beside a link to the project's ``results/`` (read only: they write under
``runs/``), on the synthetic release (``slow``). Blocks of the results READMEs preceded by
``<!-- regenerates -->`` rewrite committed outputs from committed archives, in place, from the
repository root (``bench/regenerate_results.py`` runs them): each line is one command of
``multitask-tables``, none trains, and every folder of ``results/`` that ``multitask-tables``
wrote has one. The extraction is ``documented.py``'s, shared with that script.
"""
from __future__ import annotations

import importlib
import importlib.util
import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from documented import (COMMANDS, DOCUMENTS, END_TO_END, REGENERATES, RESULTS_READMES, ROOT,
                        Command, blocks_of, command_parts, commands_of, documented,
                        logical_lines, regenerating)

PAPER_SIZE = re.compile(r"paper[ -]size", re.I)
TRAINING = ("baseline-train", "multitask-train")


def _checked(command: Command, monkeypatch, capsys) -> str:
    """``command`` read by its program's ``main`` with no work done; its standard error."""
    module = importlib.import_module(COMMANDS[command.words[0]])
    ran = []
    monkeypatch.setattr(module, "run_command", lambda *args, **kwargs: ran.append(args) or 0)
    try:
        code = module.main(list(command.words[1:]))
    except SystemExit as error:
        pytest.fail(f"{command}\n{capsys.readouterr().err}(exit {error.code})")
    err = capsys.readouterr().err
    assert code == 0 and ran, f"{command}\n{err}"
    return err


@pytest.mark.parametrize("command", documented(DOCUMENTS), ids=str)
def test_every_command_of_the_readme_and_docs_is_read_as_written(command, monkeypatch, capsys):
    err = _checked(command, monkeypatch, capsys)
    assert "deprecated" not in err, f"{command}: an old form\n{err}"


@pytest.mark.parametrize("command", documented(RESULTS_READMES), ids=str)
def test_every_command_of_the_results_readmes_is_read(command, monkeypatch, capsys):
    _checked(command, monkeypatch, capsys)


def _paper_size(command: Command) -> bool:
    """A training of the LSTM at the paper's width and length (1024 units, 100 epochs or more)."""
    words = command.words
    if words[0] not in TRAINING or "--encoder" in words:
        return False

    def value(option: str, default: int) -> int:
        return int(words[words.index(option) + 1]) if option in words else default

    return "--sweeps" not in words and value("--hidden", 1024) >= 1024 \
        and value("--epochs", 120) >= 100


def test_a_paper_size_training_says_so_beside_a_quick_variant():
    commands = documented(DOCUMENTS)
    for command in filter(_paper_size, commands):
        assert PAPER_SIZE.search(command.text), f"{command}: say 'paper size' on its line"
        quick = [c for c in commands if c.document == command.document
                 and c.block == command.block and c.words[0] in TRAINING and not _paper_size(c)]
        assert quick, f"{command}: no quick variant in its block"


#: A user's encoder by its import path (``--encoder package.module:name``).
USER_ENCODER = re.compile(r"^[\w.]+:\w+$")
#: The commands that import a run's encoder: they train or load it.
IMPORTS_ENCODER = ("multitask-train", "multitask-grid", "multitask-evaluate", "multitask-predict",
                   "multitask-export")


def test_a_block_with_a_user_s_encoder_puts_its_folder_on_the_path_of_each_command():
    """A console script does not look in the working folder: each command of a block that trains
    a user's encoder, and each that loads its run, sets PYTHONPATH on its own line (a reader
    copies lines one by one)."""
    commands = documented(DOCUMENTS)
    for document, block in {(c.document, c.block) for c in commands
                            if "--encoder" in c.words and USER_ENCODER.match(
                                c.words[c.words.index("--encoder") + 1])}:
        for command in commands:
            if (command.document, command.block) == (document, block) \
                    and command.words[0] in IMPORTS_ENCODER:
                assert "PYTHONPATH=" in command.text, f"{command}: no PYTHONPATH on its line"


def test_the_rules_find_what_they_should(tmp_path):
    """The extraction on a document of every shape the rules name."""
    doc = tmp_path / "doc.md"
    doc.write_text("text\n\n```bash\npip install -e . && multitask-train --synthetic \\\n"
                   "    --hidden 8 --out runs/x   # a comment\n.venv/bin/multitask-grid --out "
                   "../<this checkout>/g\n```\n\n```python\nmultitask-train --no\n```\n\n"
                   f"{END_TO_END}\n```console\n$ MLFLOW_X=1 jigsaws-tools synth --out s\n```\n"
                   "\n    multitask-tables pair g X Y --metric m\n\n"
                   f"{REGENERATES}\n```bash\nmultitask-tables paper g \\\n    --out results\n```\n"
                   f"{REGENERATES}\n\n```bash\nmultitask-tables paper h --out results\n```\n")
    found = [(c.words, c.marker) for c in commands_of(doc)]
    assert found == [
        (("multitask-train", "--synthetic", "--hidden", "8", "--out", "runs/x"), ""),
        (("multitask-grid", "--out", "../PLACEHOLDER/g"), ""),
        (("jigsaws-tools", "synth", "--out", "s"), END_TO_END),
        (("multitask-tables", "pair", "g", "X", "Y", "--metric", "m"), ""),
        (("multitask-tables", "paper", "g", "--out", "results"), REGENERATES),
        (("multitask-tables", "paper", "h", "--out", "results"), "")]   # not directly above
    paper = Command(("baseline-train", "--data-dir", "D"), doc, 1, "", 0, "")
    assert _paper_size(paper)
    assert not _paper_size(Command((*paper.words, "--hidden", "64"), doc, 1, "", 0, ""))


def _end_to_end() -> list[Command]:
    return [command for command in documented(DOCUMENTS) if command.end_to_end]


def test_some_commands_are_marked_to_run_end_to_end():
    assert {c.words[0] for c in _end_to_end()} >= {"multitask-train", "multitask-grid",
                                                  "multitask-tables"}


@pytest.mark.slow
@pytest.mark.parametrize("block", sorted({(c.document, c.block) for c in _end_to_end()}),
                         ids=lambda b: f"{b[0].name}:{b[1]}")
def test_the_marked_blocks_run_end_to_end(block, tmp_path):
    """The block's commands in order, in a folder beside a link to ``results/``, each with exit
    status 0; none writes under ``results/``."""
    (tmp_path / "results").symlink_to(ROOT / "results")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for command in [c for c in _end_to_end() if (c.document, c.block) == block]:
        words = list(command.words)
        outputs = [words[i + 1] for i, word in enumerate(words[:-1]) if word == "--out"]
        assert not any(Path(out).parts[0] == "results" for out in outputs), command
        script = f"import sys; from {COMMANDS[words[0]]} import main; sys.exit(main())"
        result = subprocess.run([sys.executable, "-c", script, *words[1:]], cwd=tmp_path,
                                env=env, capture_output=True, text=True, timeout=1800)
        assert result.returncode == 0, f"{command}\n{result.stderr}"


#: The programs that train: never in a ``regenerates`` block (it reads committed archives only).
TRAINERS = ("baseline-train", "multitask-train", "multitask-grid")


def _listed_folders() -> set[str]:
    """Every folder under ``results/`` holding a listing of ``multitask-tables``' outputs
    (``tables.json``, ``width.json``, ...: ``"written_by": "multitask-tables"``), relative to the
    repository root; archives' ``runs/`` folders are not read."""
    folders = set()
    for path in (ROOT / "results").rglob("*.json"):
        if "runs" not in path.relative_to(ROOT).parts:
            listing = json.loads(path.read_text())
            if isinstance(listing, dict) and listing.get("written_by") == "multitask-tables":
                folders.add(str(path.parent.relative_to(ROOT)))
    return folders


def _out(command: Command) -> str:
    words = command.words
    return words[words.index("--out") + 1] if "--out" in words else ""


def test_every_output_folder_of_results_has_a_regenerating_command():
    """Each committed output of ``multitask-tables`` (20 folders on 2026-12-03: ``results``,
    ``results/paper``, ``results/confirm`` and its ``design``, ``design-128``, both
    ``precision/*-vs-fp32``, ``reference``, ``tasks`` and its two tasks, ``tcn`` with its
    ``ed-tcn-tables``, ``ms-tcn-tables``, ``factors/tables`` and three ladders, ``width`` and
    ``width/a180``) is rewritten in place by a marked block (``bench/regenerate_results.py``)."""
    folders = _listed_folders()
    assert len(folders) >= 20, sorted(folders)
    missing = folders - {_out(command) for command in regenerating()}
    assert not missing, f"no <!-- regenerates --> block writes {sorted(missing)}"


@pytest.mark.parametrize("command", regenerating(), ids=str)
def test_a_regenerating_command_reads_committed_archives_into_its_folder(command, monkeypatch,
                                                                         capsys):
    """Read by its program's parser in its current form, not a training, writing a committed
    folder of ``results/`` in place from paths that exist (relative to the repository root)."""
    assert command.words[0] not in TRAINERS, f"{command}: a training in a regenerates block"
    assert command.words[:2] != ("multitask-tables", "archive"), f"{command}: reads runs/"
    out = _out(command)
    assert out.split("/")[0] == "results" and (ROOT / out).is_dir(), \
        f"{command}: --out is not a committed folder of results/"
    for word in command.words[2:]:
        for path in re.split(r"[+=]", word):
            assert not path.startswith(("results/", "runs/")) or (ROOT / path).exists(), \
                f"{command}: {path} does not exist"
    err = _checked(command, monkeypatch, capsys)
    assert "deprecated" not in err, f"{command}: an old form\n{err}"


def test_every_line_of_a_regenerating_block_is_one_command_of_the_package():
    """``bench/regenerate_results.py`` runs each line as one command of the package: a ``cp``,
    a chain (``&&``) or a variable would be skipped or misread."""
    for readme in RESULTS_READMES:
        for block in blocks_of(readme):
            if block.marker != REGENERATES:
                continue
            for number, text in logical_lines(block):
                parts = command_parts(text)
                assert len(parts) == 1 and parts[0][0] in COMMANDS and "$" not in text, \
                    f"{readme.relative_to(ROOT)}:{number}: not one command of the package"


def test_a_marker_stands_directly_above_a_shell_block_of_its_documents():
    """A marker on another line is silently ignored; ``regenerates`` belongs to results READMEs
    only (the script reads nowhere else)."""
    for document in [*DOCUMENTS, *RESULTS_READMES]:
        lines = document.read_text().splitlines()
        for i, line in enumerate(lines):
            if line.strip() in (END_TO_END, REGENERATES):
                where = f"{document.relative_to(ROOT)}:{i + 1}"
                nxt = lines[i + 1].strip() if i + 1 < len(lines) else ""
                assert re.match(r"^```(bash|sh|shell|console)$", nxt), \
                    f"{where}: its marker is not directly above a shell block"
                assert line.strip() != REGENERATES or document in RESULTS_READMES, \
                    f"{where}: a regenerates block outside results/**/README.md"


def test_the_regeneration_script_lists_the_marked_commands():
    listed = subprocess.run([sys.executable, str(ROOT / "bench" / "regenerate_results.py"),
                             "--list"], capture_output=True, text=True, timeout=60, check=True)
    assert listed.stdout.splitlines() == [shlex.join(c.words) for c in regenerating()]


def _script():
    spec = importlib.util.spec_from_file_location("regenerate_results",
                                                  ROOT / "bench" / "regenerate_results.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_regeneration_script_reports_failures_and_changed_files(monkeypatch, capsys):
    """Exit 1 naming a failed command with its stderr's last lines and every changed or new
    file; 2 (nothing run) when results/ was not clean before; 0 when all ran and nothing
    changed."""
    script = _script()
    command = Command(("multitask-tables", "paper", "g", "--out", "results"),
                      ROOT / "results" / "README.md", 7, "", 6, REGENERATES)
    monkeypatch.setattr(script, "regenerating", lambda: [command, command])
    statuses = iter([[], [" M results/table1.csv", "?? results/new.png"]])
    monkeypatch.setattr(script, "changed_files", lambda: next(statuses))
    outcomes = iter([(0, "", 1.0), (3, "line 1\n\nTraceback\nValueError: bad\n", 2.0)])
    monkeypatch.setattr(script, "run", lambda _: next(outcomes))
    assert script.main([]) == 1
    out = capsys.readouterr().out
    assert "1 failed, 2 file(s)" in out and "failed (exit 3)" in out
    assert "    ValueError: bad" in out and "results/README.md:7:" in out
    assert " M results/table1.csv" in out and "?? results/new.png" in out

    monkeypatch.setattr(script, "changed_files", lambda: [" M results/README.md"])
    assert script.main([]) == 2
    assert "uncommitted" in capsys.readouterr().err

    monkeypatch.setattr(script, "changed_files", lambda: [])
    monkeypatch.setattr(script, "run", lambda _: (0, "", 1.0))
    assert script.main([]) == 0
    assert "byte-identically" in capsys.readouterr().out
