"""``multitask-predict``: label new recordings with a trained run.

INPUT is a JIGSAWS-layout kinematics file (76 columns, one line per 30 Hz frame; no transcription
needed) or a folder of them; with --format, a recording in that format (e.g. a CSV at 100 Hz with
its own column names) or a folder of them. For each recording NAME the output folder gets NAME.csv
(one row per frame of the recording: the predicted gesture name, its class probabilities, the
progress stage and scores when the model has a progress head) and NAME.png (ribbons at 5 Hz), then
prediction.json, written last, records the run, the checkpoint and the inputs. See
docs/REPRODUCTION.md for how prediction treats every frame.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from jigsaws_tools.cli.common import import_tensorflow, run_command
from jigsaws_tools.cli.format_options import add_format_option
from jigsaws_tools.recording_format import JIGSAWS_FORMAT, RecordingFormat
from rnn_seg.runs.outputs import check_output_folder

from .options import load_for_command, trained_run_parser

if TYPE_CHECKING:
    from jigsaws_tools.preprocessing import Normalisation

    from .predictions import RecordingPrediction
    from .trained_run import TrainedRun

PROG = "multitask-predict"
RECORD_FILE = "prediction.json"


def build_parser() -> argparse.ArgumentParser:
    parser = trained_run_parser(PROG, __doc__)
    parser.add_argument("inputs", metavar="INPUT", nargs="+", type=Path,
                        help="kinematics files, or folders of them (their *.txt files; a release "
                             "folder's kinematics/AllGestures)")
    parser.add_argument("--out", type=Path, required=True, help="output folder (required)")
    parser.add_argument("--stream", action="store_true",
                        help="forward models only: feed the frames one at a time with causal "
                             "preprocessing and the LSTM state carried over, as online use "
                             "would (default: the run's offline preprocessing)")
    parser.add_argument("--data-dir", type=Path, default=None,
                        help="with --stream, when the run folder holds no "
                             "stream_normalisation.json yet: the release with the run's training "
                             "trials, whose statistics normalise the stream (default: the run's "
                             "data folder)")
    parser.add_argument("--no-plots", action="store_true",
                        help="write the CSVs only (default: CSVs and plots)")
    add_format_option(parser, "the INPUT recordings (default: the format the run trained on)")
    return parser


def kinematics_files(inputs: list[Path], recording_format: RecordingFormat = JIGSAWS_FORMAT
                     ) -> list[Path]:
    """The kinematics files named by INPUT arguments, in order; folders expand to their sorted
    files with the format's extension (``*.txt``; or those of a data folder's recordings folder,
    a release's ``kinematics/AllGestures``)."""
    files: list[Path] = []
    pattern = f"*{recording_format.extension}"
    for path in inputs:
        if path.is_file():
            files.append(path)
        elif path.is_dir():
            recordings = path / recording_format.recordings
            folder = recordings if recordings.is_dir() else path
            found = sorted(p for p in folder.glob(pattern) if p.is_file())
            if not found:
                raise ValueError(f"{folder}: no kinematics files ({pattern})")
            files.extend(found)
        else:
            raise ValueError(f"{path}: no such file or folder")
    names: dict[str, Path] = {}
    for f in files:
        if f.stem in names:
            raise ValueError(f"two inputs would write {f.stem}.csv: {names[f.stem]} and {f}")
        names[f.stem] = f
    return files


def _predict(args: argparse.Namespace) -> None:
    from jigsaws_tools.recording_format import load_format
    from rnn_seg.runs.folder import write_json

    import_tensorflow()                 # quietly, before trained_run imports it
    from .trained_run import read_run_config

    if args.data_dir and not args.stream:
        raise ValueError("--data-dir only applies with --stream (offline prediction normalises "
                         "each recording by itself)")
    recording_format = (load_format(args.format) if args.format
                        else read_run_config(args.run_dir)[0].data.recording_format)
    files = kinematics_files(args.inputs, recording_format)
    _check_outputs(args, files)
    run = load_for_command(args)
    recording_format = run.recording_format(args.format)        # checked against the run
    predictions, normalisation = _predict_all(run, files, recording_format, args)
    _remove_earlier_prediction(args.out)                    # --overwrite: replaced whole
    mode = "stream" if args.stream else "offline"
    record = {"run_dir": str(args.run_dir.resolve()), "variant": run.variant,
              "checkpoint": run.checkpoint, "finished": run.finished, "mode": mode,
              "normalisation": normalisation, "recordings": {}}
    first = run.tasks[0]
    for f, prediction in predictions.items():
        prediction.write(args.out, f.stem, f"{f.stem} - {run.variant} ({args.run_dir.name}, "
                                           f"sweep {run.checkpoint}, {mode})",
                         plot=not args.no_plots)
        record["recordings"][f.stem] = {"input": str(f.resolve()), "frames": prediction.n_frames,
                                        "samples": len(prediction.sample_frames)}
        labels = prediction.labels(first.name)
        print(f"{f.stem}: {prediction.n_frames} frames, most frequent {first.name} "
              f"{first.class_names[np.bincount(labels).argmax()]}", flush=True)
    write_json(args.out / RECORD_FILE, record)              # last: the folder is complete
    print(f"done: {len(files)} recording(s) predicted ({mode}) with {args.run_dir}, checkpoint "
          f"after sweep {run.checkpoint}; outputs in {args.out}")


def _check_outputs(args: argparse.Namespace, files: list[Path]) -> None:
    """Refuse a run or grid folder (``rnn_seg.runs.outputs``) and to replace an earlier
    prediction's files unless ``--overwrite``."""
    check_output_folder(args.out, PROG)
    existing = [p for p in _outputs(args.out, [f.stem for f in files]) + [args.out / RECORD_FILE]
                if p.exists()]
    if existing and not args.overwrite:
        raise ValueError(f"{existing[0]} exists (from an earlier prediction?); use --overwrite "
                         "to replace that prediction, or another --out")
    _earlier_recordings(args.out)                  # an unreadable record stops us before work


def _outputs(out: Path, names: list[str]) -> list[Path]:
    """The files a prediction of the recordings ``names`` may write into ``out``."""
    return [out / f"{name}{ext}" for name in names for ext in (".csv", ".png")]


def _earlier_recordings(out: Path) -> list[str]:
    """The recordings an earlier prediction's record in ``out`` lists (none without one)."""
    from rnn_seg.runs.folder import read_json

    record = out / RECORD_FILE
    if not record.is_file():
        return []
    data = read_json(record)
    recordings = data.get("recordings") if isinstance(data, dict) else None
    if not isinstance(recordings, dict) or any(Path(name).name != name for name in recordings):
        raise ValueError(f"{record}: not a prediction record (no 'recordings' of file names); "
                         "remove it or choose another --out")
    return list(recordings)


def _remove_earlier_prediction(out: Path) -> None:
    """Remove the record of an earlier prediction in ``out`` and the files it lists, so that
    the folder never holds outputs its record does not describe (``--overwrite`` replaces the
    earlier prediction whole; files of the new one are written over anyway)."""
    earlier = _earlier_recordings(out)
    (out / RECORD_FILE).unlink(missing_ok=True)            # first: it would vouch for the rest
    for path in _outputs(out, earlier):
        path.unlink(missing_ok=True)


def _predict_all(run: TrainedRun, files: list[Path], recording_format: RecordingFormat,
                 args: argparse.Namespace
                 ) -> tuple[dict[Path, RecordingPrediction], Normalisation | None]:
    """Every recording's predictions (offline, or frame by frame with ``--stream``) and the fixed
    statistics a stream used; every input is read and checked before anything is written."""
    from jigsaws_tools.release import read_kinematics

    from .streaming import StreamingPredictor, stream_recording

    if not args.stream:
        return {f: run.predict(f, recording_format=recording_format) for f in files}, None
    if not recording_format.is_default:
        raise ValueError(f"--stream reads JIGSAWS-layout recordings only, not format "
                         f"{recording_format.name}; predict offline (without --stream)")
    run.require_online("--stream")
    recordings = {f: read_kinematics(f) for f in files}
    streamer = StreamingPredictor(run, run.stream_normalisation(args.data_dir))
    return ({f: stream_recording(streamer, k, str(f)) for f, k in recordings.items()},
            streamer.normalisation)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return run_command(PROG, args.verbose, lambda: _predict(args))


if __name__ == "__main__":
    sys.exit(main())
