"""Running one training command: configuration first, then the run folder's lock, then training.

Shared by ``baseline-train`` and ``multitask-train``: errors a user can act on are one line on
stderr (``prog: error: ...``) with a non-zero exit, never a traceback; Ctrl-C leaves a resumable
run and exits with 130.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Callable, TypeVar

from jigsaws_tools.errors import JigsawsError
from rnn_seg.folder_lock import hold_folder
from rnn_seg.rundir import RunFolderError
from rnn_seg.trainer import TrainingDiverged

Config = TypeVar("Config")

EXIT_ERROR, EXIT_FAILED, EXIT_INTERRUPTED = 2, 1, 130


def run_training(prog: str, out: Path, configure: Callable[[], Config],
                 train: Callable[[Config], dict]) -> tuple[int, dict | None]:
    """``train(configure())`` holding ``out``'s lock; returns ``(exit code, metrics or None)``.

    Args:
        prog: the command's name, first word of every error line.
        out: the run folder, locked after ``configure`` and before ``train``.
        configure: builds (and so validates) the configuration; reads no data.
        train: trains a run of that configuration in ``out`` and returns its metrics.
    """
    try:
        config = configure()
        with hold_folder(out):
            return 0, train(config)
    except (JigsawsError, ValueError, RunFolderError, OSError) as error:
        print(f"{prog}: error: {error}", file=sys.stderr)
        return EXIT_ERROR, None
    except TrainingDiverged as error:
        print(f"{prog}: failed: {error}", file=sys.stderr)
        return EXIT_FAILED, None
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; run the same command again to resume {out} from its last "
              "checkpoint", file=sys.stderr)
        return EXIT_INTERRUPTED, None
