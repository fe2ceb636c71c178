"""What a run folder's config.json records, read without TensorFlow: its ``RunConfig`` and the
data folder it trained on, so that a command checks them before it loads a model.

A run of this version records its data folder absolute (``DataConfig.data_dir``) and as typed
(``data_dir_as_given``), so every command that reads a run finds it from any working directory.
A run of an earlier version recorded the path as typed, possibly relative: it is read relative to
the working directory, the only place it ever meant anything. A recorded folder that does not
exist is one line naming it as the run's recorded path and the override (``--data-dir``).
"""
from __future__ import annotations

from pathlib import Path

from baseline.config import RunConfig
from rnn_seg.runs.folder import RunFolderError

from ..models.run_record import read_run_config  # noqa: F401 (the checked reader, re-exported)

CONFIG_FILE = "config.json"
#: Fixed normalisation statistics of a forward run's streaming inputs, saved once per run
#: (``TrainedRun.stream_normalisation``).
STREAM_NORMALISATION_FILE = "stream_normalisation.json"
#: How a command that reads a run is told another data folder (``recorded_data_dir``'s advice).
DATA_DIR_OVERRIDE = "--data-dir DIR (data_dir= in Python)"


def recorded_data_dir(config: RunConfig, run_dir: Path | str) -> Path:
    """The data folder the run in ``run_dir`` trained on, as its config.json records it
    (absolute; a relative path of an earlier version's run taken from the working directory).

    Raises:
        RunFolderError: the folder does not exist; one line naming it as the run's recorded path
            (and as it was typed) and the override, ``--data-dir``.
    """
    data = config.data
    folder = Path(data.data_dir)
    if folder.is_dir():
        return folder
    typed = data.data_dir_as_given
    how = (f", typed as {typed}" if typed and typed != data.data_dir else
           f", relative to the working directory {Path.cwd()}" if not folder.is_absolute()
           else "")
    raise RunFolderError(f"{folder}: no such folder; it is the data folder run {run_dir} "
                         f"recorded (config.json run.data.data_dir{how}); give the folder that "
                         f"holds its data now with {DATA_DIR_OVERRIDE}")


def data_folder(config: RunConfig, run_dir: Path | str, data_dir: Path | str | None = None
                ) -> Path:
    """``data_dir`` when given (checked later, by what reads it), else the run's recorded data
    folder (``recorded_data_dir``)."""
    return Path(data_dir) if data_dir is not None else recorded_data_dir(config, run_dir)
