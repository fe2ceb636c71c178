"""The commands of the package that the project's Markdown documents show, found without running
them (standard library only: ``tests/test_documented_commands.py`` checks them and
``bench/regenerate_results.py`` runs the results READMEs' regeneration blocks).

A shell block is a fenced block of a shell language (```` ```bash ````, ``sh``, ``shell``,
``console``), or an indented block (4 spaces, after a blank line) that starts with a command of
the package. A fenced block may be marked by an HTML comment on the line directly above its
fence: ``<!-- tested end to end -->`` (cheap: runs for real on the synthetic release) or
``<!-- regenerates -->`` (in a results README: reads committed archives and rewrites that
folder's committed outputs in place, from the repository root).
"""
from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
RESULTS_READMES = sorted((ROOT / "results").rglob("README.md"))
#: The marker of a block whose commands run end to end.
END_TO_END = "<!-- tested end to end -->"
#: The marker of a results README's block that regenerates its committed outputs in place.
REGENERATES = "<!-- regenerates -->"
MARKERS = (END_TO_END, REGENERATES)
SHELLS = {"bash", "sh", "shell", "console"}
#: Command -> module, from setup.py's console scripts.
COMMANDS = dict(re.findall(r'"([\w-]+)=([\w.]+):main"', (ROOT / "setup.py").read_text()))
SEPARATORS = {"&&", "||", ";", "|", "&"}


@dataclass(frozen=True)
class Block:
    """One shell block of a document: its first line's number (1-based), its lines as (number,
    text) and its marker (one of ``MARKERS``, or "" when unmarked)."""

    start: int
    lines: list[tuple[int, str]]
    marker: str


@dataclass(frozen=True)
class Command:
    """One command line of a document: its words (the program first), where it stands, the text
    of its line (comment included), the block it belongs to and that block's marker."""

    words: tuple[str, ...]
    document: Path
    line: int
    text: str
    block: int
    marker: str

    @property
    def end_to_end(self) -> bool:
        return self.marker == END_TO_END

    @property
    def regenerates(self) -> bool:
        return self.marker == REGENERATES

    def __str__(self) -> str:
        return f"{self.document.relative_to(ROOT)}:{self.line}: {shlex.join(self.words)}"


def blocks_of(path: Path) -> list[Block]:
    """The shell blocks of a Markdown file, in document order."""
    lines = path.read_text().splitlines()
    blocks, i = [], 0
    while i < len(lines):
        fence = re.match(r"^\s*```(\w*)", lines[i])
        if fence:
            end = next(j for j in range(i + 1, len(lines)) if lines[j].strip().startswith("```"))
            above = lines[i - 1].strip() if i > 0 else ""
            if fence.group(1) in SHELLS:
                blocks.append(Block(i + 1, [(k + 1, lines[k]) for k in range(i + 1, end)],
                                    above if above in MARKERS else ""))
            i = end + 1
        elif lines[i].startswith("    ") and i > 0 and not lines[i - 1].strip():
            start = i
            while i < len(lines) and (lines[i].startswith("    ") or not lines[i].strip()):
                i += 1
            if Path(lines[start].split()[0]).name in COMMANDS:     # not an indented list item
                blocks.append(Block(start + 1, [(k + 1, lines[k][4:]) for k in range(start, i)],
                                    ""))
        else:
            i += 1
    return blocks


def logical_lines(block: Block) -> list[tuple[int, str]]:
    """A block's lines with continuation lines joined and a leading ``$ `` prompt dropped:
    (number of the first line, text); blank lines left out."""
    logical: list[tuple[int, str]] = []
    for number, text in block.lines:
        text = re.sub(r"^\$ ", "", text)
        if logical and logical[-1][1].endswith("\\"):
            logical[-1] = (logical[-1][0], logical[-1][1][:-1] + " " + text.strip())
        elif text.strip():
            logical.append((number, text))
    return logical


def commands_of(path: Path) -> list[Command]:
    """Every command of the package in ``path``'s shell blocks, continuation lines joined,
    comments dropped, ``&&``-chains split, ``<placeholders>`` one word."""
    found = []
    for block in blocks_of(path):
        for number, text in logical_lines(block):
            for part in command_parts(text):
                if Path(part[0]).name in COMMANDS:
                    found.append(Command((Path(part[0]).name, *part[1:]), path, number, text,
                                         block.start, block.marker))
    return found


def command_parts(text: str) -> list[list[str]]:
    """The words of each command of one logical line, split at ``&&``, ``;``, ``|``...,
    ``VAR=value`` prefixes dropped; comments and empty parts left out."""
    words = shlex.split(re.sub(r"<[^<>]+>", "PLACEHOLDER", text), comments=True)
    parts: list[list[str]] = [[]]
    for word in words:
        if word in SEPARATORS:
            parts.append([])
        else:
            parts[-1].append(word)
    stripped = []
    for part in parts:
        while part and re.match(r"^\w+=", part[0]):          # VAR=value command
            part = part[1:]
        if part:
            stripped.append(part)
    return stripped


def documented(paths: list[Path]) -> list[Command]:
    """Every command of the package in ``paths``, in order."""
    return [command for path in paths for command in commands_of(path)]


def regenerating() -> list[Command]:
    """The commands of every ``<!-- regenerates -->`` block of the results READMEs, in order
    (READMEs sorted by path, so ``results/README.md`` first, then each block top to bottom)."""
    return [command for command in documented(RESULTS_READMES) if command.regenerates]
