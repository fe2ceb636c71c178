"""What every command of this package shares: ``--version``, ``-v``, quiet TensorFlow, errors.

A command is a module with ``build_parser()`` and ``main(argv) -> int``; a new one follows these
steps (``multitask/inference/predict_cli.py`` takes them, its parser and run loading in
``multitask.inference.options``)::

    from jigsaws_tools.cli.common import command_parser, import_tensorflow, run_command

    def build_parser() -> argparse.ArgumentParser:
        parser = command_parser("multitask-predict", __doc__)   # --version, -v/--verbose, help
        parser.add_argument("--out", type=Path, required=True, help="where to write")
        return parser

    def main(argv: list[str] | None = None) -> int:
        args = build_parser().parse_args(argv)
        return run_command("multitask-predict", args.verbose, lambda: _predict(args))

    def _predict(args) -> None:
        import_tensorflow()                 # quietly, only in commands that need it
        from .trained_run import load_run   # modules that import TensorFlow come after it
        ...

Conventions:

* **Fast, quiet start.** A command module imports nothing heavy at the top (no TensorFlow, SciPy,
  pandas or Matplotlib), so ``--help`` and ``--version`` return at once; its work imports them.
  ``run_command`` sets TensorFlow's C++ log level before anything can import it; then
  ``import_tensorflow`` loads TensorFlow with its start-up lines (absl's "All log messages before
  absl::InitializeLog()" banner and oneDNN's ``I0000 ... port.cc`` notice, which no log level
  silences) filtered out of standard error. At the default log level 3 TensorFlow's C++ errors
  are hidden too: the only one training prints, ``E0000 ... oneDNN supports DT_BOOL only on
  platforms with AVX-512``, is harmless (Grappler moves the encoder's ``transpose(cast(resets))``
  onto the bool flags, and oneDNN, which handles float types only, leaves that transpose to Eigen).
  Real failures still raise Python errors.
* **``-v`` / ``--verbose``** shows everything: TensorFlow's start-up and C++ log lines, INFO logging
  and the traceback of an error. ``TF_CPP_MIN_LOG_LEVEL=0`` in the environment does the same for
  TensorFlow's lines; another value set there is respected.
* **Errors** a user can fix (bad data, bad values, missing files) print one line
  ``prog: error: message`` on standard error and exit 2, without traceback; Ctrl-C prints
  ``prog: interrupted`` and exits 130. Bad option values are argparse errors (exit 2), checked by
  the ``type=`` functions of ``jigsaws_tools.cli.arg_types``.
* **Help** shows every option's default (``HelpFormatter``); an old option spelling (or a
  positional argument that became an option) stays usable through ``deprecated_alias``
  (``deprecated_positional``), which prints one deprecation line.
* **Unknown options** are refused in one line naming the option and the (sub)command
  (``CommandParser``), before an old positional argument can take the value that followed them;
  so is an **empty or blank value** of any option or argument (``--out ""``, ``--mlflow " "``),
  which would otherwise name the current folder or nothing at all.
"""
from __future__ import annotations

import argparse
import ast
import difflib
import logging
import os
import re
import sys
import tempfile
import traceback
from typing import Any, Callable, NoReturn, Sequence

from ..errors import JigsawsError, WriteFailed
from ..messages import FORMAT as MESSAGE_FORMAT, new_command

DISTRIBUTION = "mtrnn-jigsaws"
TF_LOG_LEVEL_ENV = "TF_CPP_MIN_LOG_LEVEL"
QUIET_TF_LOG_LEVEL = "3"        # hide INFO, WARNING and ERROR lines of TensorFlow's C++ runtime
#: Errors a user can act on: printed as one line, exit 2.
USER_ERRORS = (JigsawsError, ValueError, OSError)
#: The exit status of a command stopped by Ctrl-C (128 + SIGINT), as a shell reports it.
EXIT_INTERRUPTED = 130

#: TensorFlow's start-up lines on standard error: absl's banner, glog-style lines
#: (``I0000 00:00:1795... 8348 port.cc:153] ...``) and cpu_feature_guard's continuation line.
_TF_NOISE = re.compile(r"WARNING: All log messages before absl::InitializeLog\(\)"
                       r"|[IWE]\d{4} [\d:. ]+\d+ [\w./-]+:\d+\] "
                       r"|To enable the following instructions: ")
#: An option string left over by argparse (``--format``, ``-x``, ``--format=x.toml``), not a lone
#: ``-``, ``--`` or a negative number.
_OPTION = re.compile(r"--?[A-Za-z][^=]*")
#: reST markup of the module docstrings that describe the commands (``plain_text``).
_INLINE_LITERAL = re.compile(r"``(.+?)``", re.DOTALL)
_ROLE = re.compile(r":[a-z]+:`([^`]+)`")
_LITERAL_BLOCK = re.compile(r"(?<=\S)::(?=\n)")


def package_version() -> str:
    """The installed version of the ``mtrnn-jigsaws`` distribution."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:
        return "unknown (not installed: pip install -e .)"


class _VersionAction(argparse.Action):
    """``--version``: print ``prog version`` and exit; the version is looked up only then."""

    def __init__(self, option_strings: Sequence[str], dest: str = argparse.SUPPRESS, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS,
                         help="print the installed version and exit", **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"{parser.prog} {package_version()}")
        parser.exit()


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the description's layout and appends ``(default: X)`` to every option that has a
    default (not to flags, and not where the help text already states it). The descriptions are
    the commands' module docstrings: their reST markup is left out of the help (``x`` -> x, a
    literal block's ``::`` -> ``:``)."""

    def format_help(self) -> str:
        return plain_text(super().format_help())

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if ("default" in text or default is None or default is False
                or default == argparse.SUPPRESS or isinstance(action, argparse._SubParsersAction)):
            return text
        return f"{text} (default: %(default)s)"


def plain_text(text: str) -> str:
    """``text`` without reST markup: ``x`` -> x, ``:func:`x``` -> x, and a paragraph's closing
    ``::`` (announcing a literal block) -> ``:``."""
    return _LITERAL_BLOCK.sub(":", _ROLE.sub(r"\1", _INLINE_LITERAL.sub(r"\1", text)))


class CommandParser(argparse.ArgumentParser):
    """The parser of every command and subcommand (``command_parser``; a subcommand's parser is of
    its command's class). Once the whole command line is read, an option the (sub)command does not
    take is refused in one line naming it and the closest option it does take (``did you mean``),
    and the deprecated positional arguments (``deprecated_positional``) are resolved: argparse
    would give the value that follows an unknown option to such a positional argument."""

    def parse_known_args(self, args=None, namespace=None):
        self._given = list(sys.argv[1:] if args is None else args)
        namespace, extras = super().parse_known_args(args, namespace)
        self._refuse_unknown(extras)
        for action in self._actions:
            if isinstance(action, _DeprecatedPositional):
                action.resolve(self, namespace)
        return namespace, extras

    def _refuse_unknown(self, words: Sequence[str]) -> None:
        """Refuse the first of ``words`` that looks like an option this parser does not take."""
        unknown = next((m.group() for m in map(_OPTION.match, words)
                        if m and not self._takes(m.group())), None)
        if unknown:
            self.refuse(f"{self.prog.split()[-1]} takes no {unknown} option"
                        f"{self._did_you_mean(unknown)} (see {self.prog} --help)")

    def _takes(self, option: str) -> bool:
        """Whether ``option`` is one of this parser's, or a prefix argparse reads as one."""
        return any(known.startswith(option) for known in self._option_string_actions)

    def error(self, message: str) -> NoReturn:
        """argparse's error; a missing required argument is named after a misspelt option, which
        is often why it is missing (``--ouut DIR``: did you mean --out?)."""
        if message.startswith("the following arguments are required"):
            self._refuse_unknown(getattr(self, "_given", ()))
        super().error(message)

    def _get_value(self, action: argparse.Action, arg_string: str) -> Any:
        """argparse's conversion of one value, after refusing an empty or blank one for every
        option and argument: ``--out ""`` would name the current folder, ``--mlflow ""`` no
        tracking server, ``--data-dir ""`` the default release (``Path("")`` is ``.``)."""
        if not arg_string.strip() and action.nargs not in (argparse.PARSER, argparse.REMAINDER):
            raise argparse.ArgumentError(action, f"expected a value, got {arg_string!r}")
        return super()._get_value(action, arg_string)

    def _check_value(self, action: argparse.Action, value: Any) -> None:
        """argparse's check of a value against ``action.choices`` (a subcommand's name too),
        its message ending with the closest choice (``did you mean APoc?``)."""
        if action.choices is not None and value not in action.choices:
            choices = ", ".join(map(repr, action.choices))
            raise argparse.ArgumentError(action, f"invalid choice: {value!r} (choose from "
                                                 f"{choices}){_closest(value, action.choices)}")
        super()._check_value(action, value)

    def _did_you_mean(self, unknown: str) -> str:
        """``"; did you mean --hidden?"`` for the option shown in help that is closest to
        ``unknown`` (``--hiden``, ``--hidden=3``), or "" when none is close."""
        options = [o for a in self._actions if a.help != argparse.SUPPRESS
                   for o in a.option_strings if o.startswith("--")]
        return _closest(unknown.split("=")[0], options)

    def refuse(self, message: str) -> NoReturn:
        """Exit 2 after one line ``prog: error: message`` (``error`` also prints the usage)."""
        self.exit(2, f"{self.prog}: error: {message}\n")


def _closest(given: Any, candidates: Sequence[Any]) -> str:
    """``"; did you mean X?"`` for the candidate closest to ``given`` (the same but for case
    first, else ``difflib``'s closest match), or "" when none is close."""
    names = [str(c) for c in candidates]
    close = ([n for n in names if n.lower() == str(given).lower()]
             or difflib.get_close_matches(str(given), names, n=1, cutoff=0.7))
    return f"; did you mean {close[0]}?" if close else ""


def command_parser(prog: str, description: str | None, **kwargs: Any) -> CommandParser:
    """A ``CommandParser`` with the shared ``HelpFormatter``, ``--version`` and ``-v``."""
    parser = CommandParser(prog=prog, description=description, formatter_class=HelpFormatter,
                           **kwargs)
    parser.add_argument("--version", action=_VersionAction)
    add_verbose_argument(parser)
    return parser


def add_verbose_argument(parser: argparse.ArgumentParser, default: Any = False) -> None:
    """``-v`` / ``--verbose``; ``command_parser`` adds it. A subcommand's parser passes
    ``default=argparse.SUPPRESS``, so that it keeps a ``-v`` given before the subcommand."""
    parser.add_argument("-v", "--verbose", action="store_true", default=default,
                        help="also show INFO messages, TensorFlow's log lines and the traceback "
                             "of an error")


class _DeprecatedAlias(argparse.Action):
    """An old spelling of an option: stores into the new option's destination and prints one
    deprecation line."""

    def __init__(self, option_strings, dest, target: str, replacement: str, **kwargs):
        super().__init__(option_strings, dest, help=argparse.SUPPRESS, **kwargs)
        self.target, self.replacement = target, replacement

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"{parser.prog}: warning: {option_string} is deprecated; use {self.replacement}",
              file=sys.stderr)
        setattr(namespace, self.target, values)


class _DeprecatedPositional(argparse.Action):
    """A positional argument that became the option ``target``: holds its value until
    ``CommandParser`` has read the whole command line, then ``resolve`` moves it to the option."""

    def __init__(self, option_strings, dest, target: argparse.Action, **kwargs):
        super().__init__(option_strings, dest, help=argparse.SUPPRESS, nargs="?", default=None,
                         **kwargs)
        self.target = target

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)

    def resolve(self, parser: CommandParser, namespace: argparse.Namespace) -> None:
        """Refuse the value if the option (or one exclusive with it) was given too; otherwise
        store it as the option and print one deprecation line."""
        value = getattr(namespace, self.dest)
        if value is None:
            return
        option = f"{self.target.option_strings[-1]} {self.metavar}"
        given = [_as_given(a, namespace) for a in _exclusive_with(parser, self.target)
                 if getattr(namespace, a.dest, a.default) != a.default]
        if given:
            parser.refuse(f"{given[0]} and the positional {self.metavar} {value} both given; "
                          f"give only one (the positional {self.metavar} is now {option})")
        print(f"{parser.prog}: warning: the positional {self.metavar} is deprecated; use "
              f"{option}", file=sys.stderr)
        setattr(namespace, self.target.dest, value)


def _exclusive_with(parser: argparse.ArgumentParser, action: argparse.Action
                    ) -> list[argparse.Action]:
    """``action`` and the actions of its mutually exclusive groups."""
    groups = [g._group_actions for g in parser._mutually_exclusive_groups
              if action in g._group_actions]
    return [action] + [a for group in groups for a in group if a is not action]


def _as_given(action: argparse.Action, namespace: argparse.Namespace) -> str:
    """``--data-dir /x`` or, for a flag, ``--synthetic``: an option as the command line gave it."""
    option = action.option_strings[-1]
    return option if action.nargs == 0 else f"{option} {getattr(namespace, action.dest)}"


def deprecated_alias(parser: argparse.ArgumentParser, old: str, new: argparse.Action) -> None:
    """Accept option ``old`` (hidden from help) as a deprecated spelling of the option ``new``:
    same value type and destination, and a warning naming ``new`` when used.

    Args:
        parser: the command's parser, which already holds ``new``.
        old: the deprecated option string, e.g. ``"--seed"``.
        new: the action ``parser.add_argument`` returned for the current option.
    """
    parser.add_argument(old, action=_DeprecatedAlias, target=new.dest,
                        replacement=new.option_strings[-1], dest=f"deprecated_{new.dest}",
                        type=new.type, choices=new.choices, metavar=new.metavar,
                        default=argparse.SUPPRESS)


def deprecated_positional(parser: CommandParser, new: argparse.Action) -> None:
    """Accept an optional positional argument (hidden from help) as a deprecated spelling of the
    option ``new``, for commands whose positional argument became an option; given with ``new``
    (or an option exclusive with it), it is refused."""
    if not isinstance(parser, CommandParser):
        raise TypeError("deprecated_positional needs a CommandParser (command_parser), which "
                        "resolves it after parsing")
    parser.add_argument(f"deprecated_{new.dest}", action=_DeprecatedPositional, target=new,
                        type=new.type, metavar=new.metavar or new.dest.upper())


def configure_output(verbose: bool) -> None:
    """Logging format and level, and TensorFlow's C++ log level (before anything imports it);
    a new command, whose data warnings are each said once (``messages.new_command``)."""
    if verbose:
        os.environ[TF_LOG_LEVEL_ENV] = "0"
    else:
        os.environ.setdefault(TF_LOG_LEVEL_ENV, QUIET_TF_LOG_LEVEL)
    new_command()
    logging.basicConfig(format=MESSAGE_FORMAT,
                        level=logging.INFO if verbose else logging.WARNING)


def import_tensorflow():
    """Import TensorFlow (once per process) and return it, its start-up lines filtered out of
    standard error unless ``TF_CPP_MIN_LOG_LEVEL`` is 0 (``-v``). Other output of the import is
    passed on; if the import fails, everything it printed is shown."""
    if "tensorflow" in sys.modules:
        return sys.modules["tensorflow"]
    if os.environ.get(TF_LOG_LEVEL_ENV) == "0":
        import tensorflow as tf
        return tf
    with tempfile.TemporaryFile(mode="w+b") as captured:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(captured.fileno(), 2)
        try:
            import tensorflow as tf
        except BaseException:
            _restore_stderr(saved)
            _replay(captured, keep=lambda line: True)
            raise
        sys.stderr.flush()
        _restore_stderr(saved)
        _replay(captured, keep=lambda line: not _TF_NOISE.match(line))
    tf.get_logger().setLevel(logging.ERROR)
    return tf


def _restore_stderr(saved: int) -> None:
    os.dup2(saved, 2)
    os.close(saved)


def _replay(captured, keep: Callable[[str], bool]) -> None:
    captured.seek(0)
    lines = captured.read().decode(errors="replace").splitlines(keepends=True)
    sys.stderr.write("".join(line for line in lines if keep(line)))
    sys.stderr.flush()


class Interrupted(KeyboardInterrupt):
    """Ctrl-C, caught where the work stopped resumably and worded there (``str``: the line to
    print, e.g. how to resume); ``run_command`` prints it in place of its own line."""


def run_command(prog: str, verbose: bool, body: Callable[[], int | None],
                layout_advice: str | None = None, *, argv: list[str] | None = None) -> int:
    """Run a command's work with the shared output setup (``configure_output``).

    Args:
        prog: the command's name, first word of every error line.
        verbose: log at INFO level, show TensorFlow's start-up lines and print a user error's
            traceback too.
        body: the command's work; returns its exit code or None.
        layout_advice: None for a command that takes ``--format`` (``format_options``): an
            error's advice for recordings of another layout
            (``recording_format.another_layout_hint``) suggests it. A command that does not
            gives the advice that replaces it (e.g. ``recording_format.RELEASE_LAYOUT_ONLY``).
        argv: the arguments the command's ``main`` was given. None when it reads the process's
            command line (a console script, ``python -m``): Ctrl-C then exits with 130. A list
            when Python code calls it (a test, a notebook, a script): Ctrl-C is then re-raised
            after its line, so that it stops the caller too (one Ctrl-C ends a test run).

    Returns:
        The exit code: ``body``'s, 0 if it returns None, 1 after a write the disk refused
        (``WriteFailed``, or an ``OSError`` of ``NO_SPACE``: one line ``<prog>: failed: ...``),
        2 after a user error (``USER_ERRORS``, or a path in a loop of symbolic links,
        ``symlink_loop``: one line ``<prog>: error: ...``), 130 after Ctrl-C
        (one line: ``<prog>: interrupted``, or the ``Interrupted``'s own).

    Raises:
        KeyboardInterrupt: Ctrl-C, when ``argv`` is a list.
    """
    configure_output(verbose)
    try:
        code = body()
    except (WriteFailed, *USER_ERRORS) as error:
        if verbose:
            traceback.print_exc()
        if isinstance(error, OSError):
            error = WriteFailed.from_os_error(error) or error
        failed = isinstance(error, WriteFailed)
        print(f"{prog}: {'failed' if failed else 'error'}: {_worded(error, layout_advice)}",
              file=sys.stderr)
        return 1 if failed else 2
    except RuntimeError as error:
        loop = symlink_loop(error)
        if loop is None:
            raise
        if verbose:
            traceback.print_exc()
        print(f"{prog}: error: {loop}: a loop of symbolic links, not a file or folder",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupt:
        print(interrupt if isinstance(interrupt, Interrupted) else f"{prog}: interrupted",
              file=sys.stderr)
        if argv is not None:
            raise
        return EXIT_INTERRUPTED
    return 0 if code is None else code


def symlink_loop(error: RuntimeError) -> str | None:
    """The path of a loop of symbolic links that ``pathlib.Path.resolve`` met (Python < 3.13
    raises ``RuntimeError("Symlink loop from <repr of the path>")``; from 3.13 a non-strict
    ``resolve`` raises nothing), else None."""
    match = re.fullmatch(r"Symlink loop from (?P<path>(['\"]).*\2)", str(error), re.DOTALL)
    if match is None:
        return None
    try:
        return str(ast.literal_eval(match["path"]))
    except (ValueError, SyntaxError):
        return match["path"]


def _worded(error: BaseException, layout_advice: str | None) -> str:
    """``error``'s message, its advice for recordings of another layout (to give ``--format``)
    replaced by ``layout_advice`` unless that is None (``run_command``); an operating system's
    error on a file as ``<file>: <reason>`` (``/proc/x: No such file or directory``)."""
    text = _file_error(error) if isinstance(error, OSError) else str(error)
    if layout_advice is None:
        return text
    from ..recording_format import another_layout_hint

    return text.replace(another_layout_hint(), layout_advice)


def _file_error(error: OSError) -> str:
    """``<file>: <reason>`` (``<file> -> <other>: <reason>`` for a rename) for an error of the
    operating system on a file; any other ``OSError`` as it reads."""
    if not (error.errno and error.strerror and error.filename is not None):
        return str(error)
    names = str(error.filename) + (f" -> {error.filename2}" if error.filename2 else "")
    return f"{names}: {error.strerror}"
