"""Every committed output under ``results/`` regenerates byte-identically from what is committed.

Runs each command of every ``<!-- regenerates -->`` block of the results READMEs
(``results/**/README.md``, sorted by path, each block top to bottom) in that order, from the
repository root, each in a subprocess of the console scripts of this Python's environment; those
commands read committed scores archives and rewrite the tables, claims and figures of their own
results folder in place. Then ``git status --porcelain -- results`` names every file that
changed or appeared. Exit status 0: every command succeeded and ``results/`` is as committed;
1: each failed command (with the last lines of its standard error) and each changed or new file
is listed (``git diff -- results`` shows how; ``git checkout -- results`` restores); 2:
``results/`` had uncommitted changes before the run (nothing is run) or git is missing.

Cost: about 5-6 minutes on 2 cores, no training (``multitask-tables paper``, ``confirm``,
``design``, ``execution``, ``tasks``, ``architectures``, ``factors``, ``ladder``, ``width``). The time-only
progress rows come from the archives; the example figures need the JIGSAWS release each grid
records (``../shared/jigsaws`` beside the clone) for their true labels: without it they are
not redrawn and stay as committed, so this check then cannot vouch for them.

    python bench/regenerate_results.py            # run every command, then check git status
    python bench/regenerate_results.py --list     # only print the commands, in order
"""
from __future__ import annotations

import argparse
import shlex
import shutil
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from documented import ROOT, Command, regenerating  # noqa: E402

#: How many of a failed command's last standard-error lines the report shows.
STDERR_LINES = 8


def changed_files() -> list[str]:
    """``git status --porcelain`` lines of every file under ``results/`` that differs from the
    commit or is new (each untracked file named, not its folder)."""
    status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=all", "--",
                             "results"], cwd=ROOT, capture_output=True, text=True, check=True)
    return status.stdout.splitlines()


def program(name: str) -> str:
    """The path of console script ``name`` in this Python's environment (else on ``PATH``)."""
    script = Path(sysconfig.get_path("scripts")) / name
    return str(script) if script.is_file() else (shutil.which(name) or name)


def run(command: Command) -> tuple[int, str, float]:
    """``command`` run from the repository root: its exit status (127 when its program is not
    installed), its standard error and its duration in seconds."""
    start = time.monotonic()
    try:
        done = subprocess.run([program(command.words[0]), *command.words[1:]], cwd=ROOT,
                              capture_output=True, text=True)
    except OSError as error:
        return 127, str(error), time.monotonic() - start
    return done.returncode, done.stderr, time.monotonic() - start


def last_lines(text: str, count: int = STDERR_LINES) -> str:
    """The last ``count`` non-blank lines of ``text``, each indented by 4 spaces."""
    lines = [line for line in text.splitlines() if line.strip()][-count:]
    return "\n".join(f"    {line}" for line in lines)


def regenerate(commands: list[Command]) -> list[str]:
    """Runs ``commands`` in order, printing each as it goes; the report of each that failed."""
    failures = []
    for number, command in enumerate(commands, 1):
        print(f"[{number}/{len(commands)}] {shlex.join(command.words)}", flush=True)
        code, stderr, seconds = run(command)
        print(f"    {'ok' if code == 0 else f'FAILED (exit {code})'}, {seconds:.0f} s",
              flush=True)
        if code != 0:
            failures.append(f"{command}\n  failed (exit {code}); its standard error ends:\n"
                            f"{last_lines(stderr)}")
    return failures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--list", action="store_true",
                        help="only print the commands, in the order they would run")
    args = parser.parse_args(argv)
    commands = regenerating()
    if args.list:
        for command in commands:
            print(shlex.join(command.words))
        return 0
    try:
        before = changed_files()
    except (OSError, subprocess.CalledProcessError) as error:
        print(f"regenerate_results: git status failed in {ROOT}: {error}", file=sys.stderr)
        return 2
    if before:
        print(f"regenerate_results: results/ has {len(before)} uncommitted change(s), e.g. "
              f"'{before[0]}': commit or restore them first", file=sys.stderr)
        return 2
    start = time.monotonic()
    failures = regenerate(commands)
    changed = changed_files()
    minutes = (time.monotonic() - start) / 60
    if not failures and not changed:
        print(f"{len(commands)} commands in {minutes:.1f} min: results/ regenerates "
              "byte-identically (git status clean)")
        return 0
    print(f"\n{len(commands)} commands in {minutes:.1f} min: {len(failures)} failed, "
          f"{len(changed)} file(s) under results/ changed or new")
    for failure in failures:
        print(failure)
    for line in changed:
        print(f"  {line}")
    return 1


if __name__ == "__main__":
    sys.exit(main())
