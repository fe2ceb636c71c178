"""``multitask.train``: train one variant on one fold from Python, as ``multitask-train`` does,
and get the trained run back (``inference.trained_run.TrainedRun``)::

    import multitask

    run = multitask.train(variant="APoc", weighting="gradnorm", data_dir="/data/Suturing",
                          out="runs/APoc_B", test_user="B", hidden=256, epochs=60)
    run.predict("Suturing_B001.txt").table()

Settings are ``multitask-train``'s options with ``_`` for ``-`` (``test_user="B"``,
``keep_prob=0.5``, ``eval_at=(50, 60)``, ``synthetic=True``, ``restart=True``), each checked as
on the command line: a bad value, or a setting the command has not (with the nearest one it has),
is a ``ValueError`` before anything is read or written. The run folder is the command's: the same
call again resumes an interrupted run and returns a finished one at once.
"""
from __future__ import annotations

import argparse
import contextlib
import difflib
import io
from pathlib import Path
from typing import Any, Callable

from .models.config import WEIGHTINGS
from .models.variants import VARIANTS, get_variant
from .train_cli import (DEFAULT_VARIANT, build_parser, configure_run, log_to_mlflow,
                        train_configured, unused_options)

#: Options of the command that are no training settings.
_NOT_SETTINGS = {"help", "version", "verbose"}


def train(variant: str = DEFAULT_VARIANT, weighting: str = WEIGHTINGS[0], *,
          out: Path | str, data_dir: Path | str | None = None,
          log: Callable[[str], None] | None = print, mlflow: str | None = None,
          **settings: Any):
    """Train ``variant`` with ``weighting`` on one LOUO fold into the run folder ``out`` and
    return it loaded with its final weights (``multitask.load_run``).

    Args:
        variant: ``A``, ``APr``, ``APc``, ``APoc``, ``Pr``, ``Pc`` or ``Poc``; its defaults are the
            paper's (``multitask-train --variant APoc --help`` lists them).
        weighting: ``"fixed"`` (w1 = w2 = 1) or ``"gradnorm"`` (two-task variants).
        out: the run folder (``--out``): new, or this run's to resume.
        data_dir: the release's folder (``--data-dir``; default: ``$JIGSAWS_DIR``, else
            ``../shared/jigsaws/Suturing``); or ``synthetic=True``.
        log: where the configuration and progress lines go; None = nowhere.
        mlflow: an MLflow tracking URI to log the finished run to (``rnn_seg.runs.tracking``).
        **settings: any other option of ``multitask-train``, ``_`` for ``-``.

    Returns:
        The ``TrainedRun`` of ``out``.

    Raises:
        ValueError: before anything is read or written: a setting the command has not, a value
            it refuses, an empty path (the message is the command's), an ``out`` that may not
            hold a run (a file, a grid's folder), an unusable ``mlflow`` URI
            (``rnn_seg.runs.tracking.TrackingError``); then, as the command: a task definition,
            recording format or release file that is none (``jigsaws_tools.errors``), a run
            folder in use or of other settings (``rnn_seg.runs.folder.RunFolderError``).
        FileNotFoundError: the release folder, or a file it must hold, is missing
            (``jigsaws_tools.errors.ReleaseNotFoundError``, which says how to obtain JIGSAWS or
            write a synthetic release); ``OSError`` for another file that cannot be read.
        jigsaws_tools.errors.WriteFailed: the disk refused a write (full, or a quota), naming
            the file; the run resumes from its last checkpoint once there is room.
        rnn_seg.trainer.TrainingDiverged: the loss became NaN or infinite.
        KeyboardInterrupt: passed on; the run resumes from its last checkpoint.
    """
    from jigsaws_tools.cli.common import import_tensorflow
    from jigsaws_tools.errors import WriteFailed
    from rnn_seg.runs.outputs import check_output_folder
    from rnn_seg.runs.tracking import Tracker

    say = log or (lambda message: None)
    parser = build_parser(variant if variant in VARIANTS else DEFAULT_VARIANT)   # argparse
    # refuses another, naming the variants
    args = _parse(parser, {"variant": variant, "weighting": weighting, "out": out,
                           "data_dir": data_dir, "mlflow": mlflow, **settings})
    chosen = get_variant(args.variant)
    unused = unused_options(args, chosen)
    if unused:
        raise ValueError(unused)
    tracker = Tracker(mlflow) if mlflow else None
    configs = configure_run(args, chosen, say)
    check_output_folder(args.out, "multitask.train", may_be_run=True)
    import_tensorflow()
    from .inference.trained_run import load_run

    try:
        train_configured(args, chosen, configs, say)
    except OSError as error:                 # a full disk, named as the command names it
        failed = WriteFailed.from_os_error(error)
        if failed is None:
            raise
        raise failed from None
    if tracker is not None:
        log_to_mlflow(tracker, args.out, say)
    return load_run(args.out)


def _parse(parser: argparse.ArgumentParser, settings: dict[str, Any]) -> argparse.Namespace:
    """``settings`` read by the command's ``parser`` as its options (None = not given); an error
    is a ``ValueError`` with the command's message."""
    options = parser._option_string_actions          # argparse has no public lookup
    argv: list[str] = []
    for name, value in settings.items():
        option = "--" + name.replace("_", "-")
        if name in _NOT_SETTINGS or option not in options:
            known = sorted(o[2:].replace("-", "_") for o in options
                           if o.startswith("--") and o[2:] not in _NOT_SETTINGS)
            near = difflib.get_close_matches(name, known, n=1)
            raise ValueError(f"multitask.train takes no setting {name!r}"
                             + (f"; did you mean {near[0]!r}?" if near else
                                f" (settings: {', '.join(known)})"))
        if value is None:
            continue
        if options[option].nargs == 0:                              # a flag
            if not isinstance(value, bool):
                raise ValueError(f"{name}: True or False, not {value!r}")
            argv += [option] * value
        elif isinstance(value, (list, tuple)):
            argv += [option, ",".join(map(str, value))]
        else:
            argv += [option, str(value)]
    errors = io.StringIO()
    try:
        with contextlib.redirect_stderr(errors):
            return parser.parse_args(argv)
    except SystemExit:
        message = errors.getvalue().strip().splitlines()[-1]
        raise ValueError(message.split(": error: ", 1)[-1]) from None
