"""Running one training command: configuration first, then the run folder's lock, then training.

Shared by ``baseline-train`` and ``multitask-train``, inside
``jigsaws_tools.cli.common.run_command``: errors a user can act on (bad values or data, a folder
in use or holding other settings) propagate to it, which prints one line ``prog: error: ...``
(and the traceback with ``-v``) and exits with 2, and so does a write refused for lack of space
(``prog: failed: ...``, exit 1). Handled here: a loss that diverged (one line, exit 1); Ctrl-C
during training leaves a resumable run and goes on to ``run_command`` as an ``Interrupted`` that
says how to resume (exit 130, or the interrupt re-raised to a Python caller).
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Callable, TypeVar

from jigsaws_tools.cli.common import Interrupted, import_tensorflow
from rnn_seg.runs.lock import hold_folder
from rnn_seg.runs.outputs import check_output_folder

Config = TypeVar("Config")

EXIT_FAILED = 1


def run_training(prog: str, out: Path, configure: Callable[[], Config],
                 train: Callable[[Config], dict]) -> tuple[int, dict | None]:
    """``train(configure())`` holding ``out``'s lock; returns ``(exit code, metrics or None)``.

    The check of ``out`` and ``configure`` run before TensorFlow is imported (quietly, by
    ``import_tensorflow``), so that a mistake in the command line is reported at once.

    Args:
        prog: the command's name, first word of every message.
        out: the run folder, checked before ``configure`` and locked before ``train``.
        configure: builds (and so validates) the configuration; reads no data and imports no
            TensorFlow.
        train: trains a run of that configuration in ``out`` and returns its metrics.

    ``out`` must be a run folder or a new one: not a grid folder, a folder holding runs, or a
    place inside a run folder or a grid's ``runs/`` (``rnn_seg.runs.outputs``).

    Raises:
        The errors of ``configure``, ``train`` and the lock (``FolderLockedError``) other than
        ``TrainingDiverged``, for ``run_command`` to report (a write refused for lack of space
        included); ``Interrupted`` for Ctrl-C, saying how to resume.
    """
    check_output_folder(out, prog, may_be_run=True)
    config = configure()
    import_tensorflow()
    from rnn_seg.trainer import TrainingDiverged

    try:
        with hold_folder(out):
            return 0, train(config)
    except TrainingDiverged as error:
        print(f"{prog}: failed: {error}", file=sys.stderr)
        return EXIT_FAILED, None
    except KeyboardInterrupt:
        raise Interrupted(f"{prog}: interrupted; run the same command again to resume {out} "
                          "from its last checkpoint") from None
