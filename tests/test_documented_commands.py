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
``runs/``), on the synthetic release (``slow``).
"""
from __future__ import annotations

import importlib
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
RESULTS_READMES = sorted((ROOT / "results").rglob("README.md"))
#: The marker of a block whose commands run end to end.
END_TO_END = "<!-- tested end to end -->"
SHELLS = {"bash", "sh", "shell", "console"}
#: Command -> module, from setup.py's console scripts.
COMMANDS = dict(re.findall(r'"([\w-]+)=([\w.]+):main"', (ROOT / "setup.py").read_text()))
SEPARATORS = {"&&", "||", ";", "|", "&"}
PAPER_SIZE = re.compile(r"paper[ -]size", re.I)
TRAINING = ("baseline-train", "multitask-train")


@dataclass(frozen=True)
class Command:
    """One command line of a document: its words (the program first), where it stands, the text
    of its line (comment included) and the block it belongs to."""

    words: tuple[str, ...]
    document: Path
    line: int
    text: str
    block: int
    end_to_end: bool

    def __str__(self) -> str:
        return f"{self.document.relative_to(ROOT)}:{self.line}: {shlex.join(self.words)}"


def _blocks(path: Path) -> list[tuple[int, list[tuple[int, str]], bool]]:
    """The shell blocks of a Markdown file: (first line, [(line number, text)], marked end to
    end); fenced blocks of a shell language, and indented blocks (4 spaces, after a blank line)
    that start with a command of the package."""
    lines = path.read_text().splitlines()
    blocks, i = [], 0
    while i < len(lines):
        fence = re.match(r"^\s*```(\w*)", lines[i])
        if fence:
            end = next(j for j in range(i + 1, len(lines)) if lines[j].strip().startswith("```"))
            marked = i > 0 and lines[i - 1].strip() == END_TO_END
            if fence.group(1) in SHELLS:
                blocks.append((i + 1, [(k + 1, lines[k]) for k in range(i + 1, end)], marked))
            i = end + 1
        elif lines[i].startswith("    ") and i > 0 and not lines[i - 1].strip():
            start = i
            while i < len(lines) and (lines[i].startswith("    ") or not lines[i].strip()):
                i += 1
            if Path(lines[start].split()[0]).name in COMMANDS:     # not an indented list item
                blocks.append((start + 1, [(k + 1, lines[k][4:]) for k in range(start, i)],
                               False))
        else:
            i += 1
    return blocks


def commands_of(path: Path) -> list[Command]:
    """Every command of the package in ``path``'s shell blocks, continuation lines joined,
    comments dropped, ``&&``-chains split, ``<placeholders>`` one word."""
    found = []
    for block, lines, marked in _blocks(path):
        logical: list[tuple[int, str]] = []
        for number, text in lines:
            text = re.sub(r"^\$ ", "", text)
            if logical and logical[-1][1].endswith("\\"):
                logical[-1] = (logical[-1][0], logical[-1][1][:-1] + " " + text.strip())
            elif text.strip():
                logical.append((number, text))
        for number, text in logical:
            words = shlex.split(re.sub(r"<[^<>]+>", "PLACEHOLDER", text), comments=True)
            for part in _split(words):
                while part and re.match(r"^\w+=", part[0]):          # VAR=value command
                    part = part[1:]
                if part and Path(part[0]).name in COMMANDS:
                    found.append(Command((Path(part[0]).name, *part[1:]), path, number, text,
                                         block, marked))
    return found


def _split(words: list[str]) -> list[list[str]]:
    parts = [[]]
    for word in words:
        if word in SEPARATORS:
            parts.append([])
        else:
            parts[-1].append(word)
    return [part for part in parts if part]


def _documented(paths: list[Path]) -> list[Command]:
    return [command for path in paths for command in commands_of(path)]


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


@pytest.mark.parametrize("command", _documented(DOCUMENTS), ids=str)
def test_every_command_of_the_readme_and_docs_is_read_as_written(command, monkeypatch, capsys):
    err = _checked(command, monkeypatch, capsys)
    assert "deprecated" not in err, f"{command}: an old form\n{err}"


@pytest.mark.parametrize("command", _documented(RESULTS_READMES), ids=str)
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
    commands = _documented(DOCUMENTS)
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
    commands = _documented(DOCUMENTS)
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
                   "\n    multitask-tables pair g X Y --metric m\n")
    found = [(c.words, c.end_to_end) for c in commands_of(doc)]
    assert found == [
        (("multitask-train", "--synthetic", "--hidden", "8", "--out", "runs/x"), False),
        (("multitask-grid", "--out", "../PLACEHOLDER/g"), False),
        (("jigsaws-tools", "synth", "--out", "s"), True),
        (("multitask-tables", "pair", "g", "X", "Y", "--metric", "m"), False)]
    paper = Command(("baseline-train", "--data-dir", "D"), doc, 1, "", 0, False)
    assert _paper_size(paper)
    assert not _paper_size(Command((*paper.words, "--hidden", "64"), doc, 1, "", 0, False))


def _end_to_end() -> list[Command]:
    return [command for command in _documented(DOCUMENTS) if command.end_to_end]


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
