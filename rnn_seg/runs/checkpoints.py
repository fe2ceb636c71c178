"""A run's checkpoints: ``checkpoints/ckpt-<N>.index|.data-*``, N the number of sweeps done.

Each is a ``tf.train.Checkpoint`` of everything training needs to continue (the ``Trainer`` says
what). While a run trains the store keeps the newest checkpoint and the one before it: the
fall-back when the newest cannot be read (cut short by a full disk, say), which restoring reports
and skips. What a finished run keeps is ``TrainConfig.keep_checkpoints``:

* ``final``: the final weights only (the default);
* ``eval_points``: also the checkpoint of every evaluation point
  (``restore_weights(..., point=N)``);
* ``all``: every checkpoint saved.

Beside each checkpoint, ``ckpt-<N>.clock.json`` holds the run's clock at that point (seconds per
phase and since the start, over every session; ``rnn_seg.runs.timing``), written before the
checkpoint and deleted with it, so that a run resumed from checkpoint N counts the time that
produced it, whichever checkpoint it resumes from.

Temporary leftovers of an interrupted save (``ckpt-N_temp/``, a data file or a clock without its
index) are removed when a run starts.
"""
from __future__ import annotations

import gc
import shutil
from pathlib import Path
from typing import Callable, Collection

import tensorflow as tf

from jigsaws_tools.errors import RESUMES

from ..config import KEEP_CHECKPOINTS, UNITS, KeepCheckpoints  # noqa: F401 (re-exported)
from .folder import CHECKPOINTS as FOLDER
from .folder import (RunFolderError, WriteFailed,  # noqa: F401 (re-exported)
                     checkpoint_sweeps, point_dir, read_json, write_json)

CLOCK_SUFFIX = ".clock.json"


def checkpoint_prefix(run_dir: Path, sweep: int) -> Path:
    return Path(run_dir) / FOLDER / f"ckpt-{sweep}"


def _clock_path(prefix: Path) -> Path:
    return prefix.with_name(prefix.name + CLOCK_SUFFIX)


class CheckpointStore:
    """Saves, restores and prunes the checkpoints of ``run_dir``.

    Args:
        run_dir: the run folder.
        checkpoint: what a checkpoint holds.
        keep: ``KEEP_CHECKPOINTS``, what a finished run keeps.
        eval_sweeps: sweep counts of the evaluation points (kept with ``eval_points``).
        log: where warnings go.
    """

    def __init__(self, run_dir: Path, checkpoint: tf.train.Checkpoint, keep: KeepCheckpoints,
                 eval_sweeps: Collection[int], log: Callable[[str], None]):
        self.run_dir, self.checkpoint, self.log = Path(run_dir), checkpoint, log
        self.keep, self.eval_sweeps = keep, set(eval_sweeps)

    def sweeps(self) -> list[int]:
        return checkpoint_sweeps(self.run_dir)

    def save(self, sweep: int, clock: dict) -> None:
        """Write the checkpoint after ``sweep`` sweeps and its ``clock`` (strict JSON), then drop
        those no longer needed."""
        prefix = checkpoint_prefix(self.run_dir, sweep)
        write_json(_clock_path(prefix), clock)
        try:
            self.checkpoint.write(str(prefix))
        except tf.errors.OpError as error:      # TensorFlow's own error, not an OSError
            _delete(prefix)                     # never an index without its data
            failed = WriteFailed.from_message(prefix, _first_line(error), "checkpoint", RESUMES)
            if failed:
                raise failed from None
            raise OSError(f"cannot write checkpoint {prefix}: {_first_line(error)}") from None
        saved = self.sweeps()
        self._keep_only(set(saved[-2:]) | self._kept(saved))

    def finalize(self) -> None:
        """Prune a finished run to what ``keep`` asks for (the newest checkpoint is its final)."""
        saved = self.sweeps()
        self._keep_only(set(saved[-1:]) | self._kept(saved))

    def restore(self) -> int:
        """Restore the newest readable checkpoint; returns its sweep count, 0 when there is none.

        An unreadable checkpoint is reported and skipped for the one before it; as training
        resumes from that one, the unreadable newer ones are deleted. Raises ``RunFolderError``
        when checkpoints exist but none can be read.
        """
        failures = []
        for sweep in reversed(self.sweeps()):
            prefix = checkpoint_prefix(self.run_dir, sweep)
            try:
                self.checkpoint.read(str(prefix)).assert_existing_objects_matched()
            except Exception as error:          # truncated, corrupt, another model's
                problem = _first_line(error)
                failures.append(f"{prefix}: {problem}")
                self.log(f"warning: cannot read checkpoint {prefix} ({problem}); trying the one "
                         "before")
                continue
            finally:
                gc.collect()       # drop a failed read's restore state while TensorFlow is alive
            for newer in self.sweeps():
                if newer > sweep:
                    _delete(checkpoint_prefix(self.run_dir, newer))
            return sweep
        if failures:
            raise RunFolderError(f"{self.run_dir}: no readable checkpoint:\n  "
                                 + "\n  ".join(failures)
                                 + "\nRestart the run (e.g. --restart) to train it afresh.")
        return 0

    def clock(self, sweep: int) -> dict | None:
        """The clock saved with the checkpoint after ``sweep`` sweeps; None when it has none (a
        checkpoint saved before clocks were kept)."""
        path = _clock_path(checkpoint_prefix(self.run_dir, sweep))
        return read_json(path) if path.is_file() else None

    def remove_leftovers(self) -> list[Path]:
        """Delete temporary files of interrupted saves; returns what was removed."""
        folder = self.run_dir / FOLDER
        if not folder.is_dir():
            return []
        indexed = {f"ckpt-{s}" for s in self.sweeps()}
        leftovers = sorted(p for p in folder.glob("ckpt-*")
                           if p.name.endswith("_temp")
                           or (".data-" in p.name and p.name.split(".data-")[0] not in indexed)
                           or (p.name.endswith(CLOCK_SUFFIX)
                               and p.name.removesuffix(CLOCK_SUFFIX) not in indexed))
        for path in leftovers:
            if path.is_dir():
                shutil.rmtree(path)
            else:
                path.unlink(missing_ok=True)
        return leftovers

    def _kept(self, saved: list[int]) -> set[int]:
        if self.keep == "all":
            return set(saved)
        return self.eval_sweeps & set(saved) if self.keep == "eval_points" else set()

    def _keep_only(self, keep: set[int]) -> None:
        for sweep in self.sweeps():
            if sweep not in keep:
                _delete(checkpoint_prefix(self.run_dir, sweep))


def _delete(prefix: Path) -> None:
    """Remove one checkpoint, its index first (so a half-deleted one is never listed)."""
    Path(f"{prefix}.index").unlink(missing_ok=True)
    for data in prefix.parent.glob(f"{prefix.name}.data-*"):
        data.unlink(missing_ok=True)
    _clock_path(prefix).unlink(missing_ok=True)


def restore_weights(model: tf.Module, run_dir: Path | str, *, sweep: int | None = None,
                    point: int | None = None) -> int:
    """Load a run's saved weights into ``model`` (the optimiser and other training state are not
    read). Give at most one of ``sweep`` and ``point``; neither = the newest checkpoint (a
    finished run's final weights).

    Args:
        model: built with the run's configuration and tasks (e.g. a ``SegmentationModel``).
        run_dir: the run folder.
        sweep: the sweep count after which the weights were saved (``checkpoints/ckpt-<sweep>``).
        point: an evaluation point in the run's schedule unit (e.g. epoch 100, as in
            ``eval/epoch0100``), whose weights a run keeps with ``keep_checkpoints``
            ``eval_points`` or ``all``.

    Returns:
        The sweep count of the weights loaded.

    Raises:
        RunFolderError: naming the folder or file, when the checkpoint asked for is missing, its
            files cannot be read or its weights do not fit ``model``.
        ValueError: both ``sweep`` and ``point`` given.
    """
    if sweep is not None and point is not None:
        raise ValueError(f"restore_weights: give sweep ({sweep}) or point ({point}), not both")
    run_dir = Path(run_dir)
    sweep = _chosen_sweep(run_dir, sweep, point)
    prefix = checkpoint_prefix(run_dir, sweep)
    try:
        status = tf.train.Checkpoint(model=model).read(str(prefix))
        status.expect_partial()                 # the checkpoint also holds the training state
        status.assert_existing_objects_matched()
    except Exception as error:                  # truncated, corrupt, another model's
        gc.collect()            # drop the failed read's restore state while TensorFlow is alive
        problem = ("its weights do not fit the model built from the run's configuration"
                   if isinstance(error, (AssertionError, ValueError))
                   else "unreadable (cut short or corrupt?)")
        raise RunFolderError(f"{prefix}: {problem} ({_first_line(error)})") from None
    return sweep


def _chosen_sweep(run_dir: Path, sweep: int | None, point: int | None) -> int:
    """The sweep count of the checkpoint ``restore_weights`` reads; ``RunFolderError`` when it
    was not kept."""
    saved = checkpoint_sweeps(run_dir)
    if not saved:
        raise RunFolderError(f"{run_dir}: no checkpoint in {run_dir / FOLDER} (has the run "
                             "trained for at least one checkpoint interval?)")
    if point is not None:
        sweep = _point_sweep(run_dir, point)
        if sweep not in saved:
            raise RunFolderError(
                f"{run_dir}: the weights of evaluation point {point} (sweep {sweep}) were not kept "
                f"(checkpoints after sweeps {_listed(saved)}); train with "
                "keep_checkpoints='eval_points' (--keep-checkpoints eval_points) to keep them")
        return sweep
    if sweep is None:
        return saved[-1]
    if sweep not in saved:
        raise RunFolderError(f"{run_dir}: no checkpoint after sweep {sweep} (checkpoints after "
                             f"sweeps {_listed(saved)}; a run keeps its evaluation points' "
                             "weights with --keep-checkpoints eval_points)")
    return sweep


def _listed(sweeps: list[int]) -> str:
    return ", ".join(map(str, sweeps))


def _first_line(error: Exception) -> str:
    return f"{type(error).__name__}: {error}".splitlines()[0]


def _point_sweep(run_dir: Path, point: int) -> int:
    """Sweep count of evaluation point ``point``, from its ``eval/<unit><N>/metrics.json``."""
    for unit in UNITS:
        metrics = point_dir(run_dir, unit, point) / "metrics.json"
        if metrics.is_file():
            recorded = read_json(metrics)
            sweep = recorded.get("sweep") if isinstance(recorded, dict) else None
            if not isinstance(sweep, int) or isinstance(sweep, bool):
                raise RunFolderError(f"{metrics}: no sweep count of the evaluation point "
                                     f"(value: {sweep!r})")
            return sweep
    raise RunFolderError(f"{run_dir}: no evaluation point {point} (no eval/<unit>{point:04d}/)")
