"""Score a trained run's saved weights on labelled trials, with the files of a training
evaluation point (``rnn_seg.trainer.write_evaluation``: per-trial predictions and plots,
``metrics.json``).

Offline, the test trials are preprocessed and predicted exactly as the run's own evaluation points
were, so the final checkpoint reproduces the run's last evaluation (exactly, or to float32
rounding for a run trained with XLA's loops, or with the fused ones where they cannot be built
here: ``load_run``'s loops). ``stream=True`` scores a forward
model as it would run online: each trial's every frame preprocessed causally (``TrainedRun.predict``
with ``causal=True``, equal to feeding the frames one at a time), each labelled sample scored with
the prediction of the last stream sample at or before its frame; the labels and the samples scored
are those of the offline evaluation, so the two sets of scores compare directly.
"""
from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

from baseline.builder import to_sequences
from jigsaws_tools.dataset import Dataset, Trial, load_dataset
from jigsaws_tools.preprocessing import Normalisation
from jigsaws_tools.recording_format import RecordingFormat
from jigsaws_tools.release import discover
from rnn_seg.runs.publish import staged_folder
from rnn_seg.sweeps import sweeps_per_epoch
from rnn_seg.trainer import predict, write_evaluation

from .output_folders import check_evaluation_folder
from .predictions import hold
from .run_record import data_folder
from .trained_run import FINGERPRINT_DIFFERS, TrainedRun

log = logging.getLogger(__name__)


def default_evaluation_dir(run: TrainedRun, test_user: str, stream: bool) -> Path:
    """``<run>/evaluate/ckpt-<sweeps>_<user>[_stream]``: where ``evaluate_run`` writes by default.

    Args:
        run: the loaded run; ``<sweeps>`` is its checkpoint's sweep count.
        test_user: whose trials are scored, e.g. ``"B"``.
        stream: the scores are of the streaming preprocessing.
    """
    return run.run_dir / "evaluate" / (f"ckpt-{run.checkpoint}_{test_user}"
                                       + ("_stream" if stream else ""))


def evaluate_run(run: TrainedRun, out: Path, data_dir: Path | str | None = None,
                 test_user: str | None = None, stream: bool = False, plots: bool = True,
                 overwrite: bool = False,
                 recording_format: str | Path | RecordingFormat | None = None
                 ) -> dict[str, dict[str, float]]:
    """Evaluate ``run``'s weights on one user's labelled trials and write the results to ``out``.

    Args:
        run: the loaded run and checkpoint.
        out: output folder (written whole at the end; an existing one only with ``overwrite``).
        data_dir: the release to read (default: the run's data folder).
        test_user: whose trials to score (default: the run's held-out user).
        stream: score the causal, streaming preprocessing (forward models only).
        plots: draw the per-trial plots.
        overwrite: replace an existing ``out``, an earlier evaluation (never a run, a grid or a
            run's own files: ``rnn_seg.runs.outputs``).
        recording_format: the layout and rate of ``data_dir``'s recordings (a built-in name, a
            format file or a format; checked to give the run's features at its sample rate;
            default: the run's).

    Returns:
        The metrics per task.
    """
    check_evaluation_folder(out, overwrite)
    fmt = run.recording_format(recording_format)
    if stream:
        run.require_online("streaming evaluation")
        if fmt != run.config.data.recording_format:
            raise ValueError(f"streaming evaluation reads the format the run trained on "
                             f"({run.config.data.recording_format.name}), not {fmt.name}")
    data_config = replace(run.config.data, recording_format=fmt,
                          data_dir=str(data_folder(run.config, run.run_dir, data_dir)))
    dataset = load_dataset(data_config)
    same_data = run.trained_on(dataset.fingerprint)
    if same_data is None:
        log.warning("%s records no data fingerprint (an early version's run): whether %s holds "
                    "the data it trained on is not checked", run.run_dir, data_config.data_dir)
    elif not same_data:
        _refuse_or_warn(run, data_config.data_dir, given=data_dir is not None)
    test_user = test_user or run.config.test_user
    _, trials = dataset.louo_split(test_user)
    if test_user != run.config.test_user:
        log.warning("user %s's trials were in this run's training set (it held out user %s): "
                    "these scores are not held-out scores", test_user, run.config.test_user)
    data = to_sequences(trials, run.tasks, data_config)
    if stream:
        outputs = causal_outputs(run, trials, data_config.data_dir,
                                 run.stream_normalisation(data_dir, dataset.fingerprint))
    else:
        outputs = predict(run.model, data.inputs, run.config.train.prediction)
    point, unit = checkpoint_point(run, dataset)
    header = {"point": point, "unit": unit, "checkpoint": run.checkpoint,
              "run_dir": str(run.run_dir.resolve()), "data_dir": data_config.data_dir,
              "test_user": test_user, "preprocessing": "stream" if stream else "offline",
              "trained_on_this_data": same_data}
    with staged_folder(out, overwrite) as folder:
        metrics = write_evaluation(folder, run.tasks, data, outputs, header,
                                   f"sweep {run.checkpoint}" + (" (stream)" if stream else ""),
                                   run.sample_hz, plots)
    return metrics


def _refuse_or_warn(run: TrainedRun, data_dir: str, given: bool) -> None:
    """The release in ``data_dir`` is not the data ``run`` trained on: an error when it is the
    folder the run records (moved or changed data would pass for the run's held-out scores), a
    warning when the caller named it (scoring other data on purpose)."""
    if given:
        log.warning("%s is not the data %s trained on (%s): these are not the run's held-out "
                    "scores", data_dir, run.run_dir, FINGERPRINT_DIFFERS)
        return
    relative = "" if Path(data_dir).is_absolute() else ", read from the current folder"
    raise ValueError(f"{data_dir} (the run's data folder{relative}) is not the data "
                     f"{run.run_dir} trained on ({FINGERPRINT_DIFFERS}); pass the release it "
                     "trained on with --data-dir, or name other data with --data-dir to score it "
                     "anyway")


def causal_outputs(run: TrainedRun, trials: list[Trial], data_dir: str,
                   normalisation: Normalisation) -> dict[str, list]:
    """Raw outputs of the causal pass over all of each trial's frames, at its labelled samples.

    Args:
        run: a forward run.
        trials: labelled trials (their ``frames`` are the samples scored).
        data_dir: the release holding the trials' kinematics files.
        normalisation: the fixed input statistics.

    Returns:
        Per task, one ``[T_i, K]`` array per trial, aligned with ``Trial.frames``.
    """
    data = run.config.data
    files = {t.name: t.kinematics
             for t in discover(data_dir, data.task, data.recording_format).trials}
    outputs: dict[str, list] = {t.name: [] for t in run.tasks}
    for trial in trials:
        prediction = run.predict(files[trial.name], causal=True, normalisation=normalisation)
        samples = hold(prediction.sample_frames, trial.frames)
        for name, values in outputs.items():
            values.append(prediction.outputs[name][samples])
    return outputs


def checkpoint_point(run: TrainedRun, dataset: Dataset) -> tuple[int, str]:
    """The checkpoint's position in the run's schedule unit (e.g. ``(120, "epochs")``), or in
    sweeps when it is not a whole number of units or the run's training set is not in
    ``dataset``."""
    config = run.config
    if {config.test_user, *config.held_out_users} <= set(dataset.users):
        train, _ = dataset.louo_split(config.test_user, config.held_out_users)
        per_unit = config.optim.sweeps(1, sweeps_per_epoch(len(train), config.train.batch_size))
        if run.checkpoint % per_unit == 0:
            return run.checkpoint // per_unit, config.optim.unit
    return run.checkpoint, "sweeps"
