"""Recordings of another layout (issue #31): users of a synthetic release converted to a robot's
CSVs at 100 Hz with its own column names, and the recording format file that reads them (shared
by the tests of recording formats and of a grid on a user's recordings)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from jigsaws_tools.features import feature_names
from jigsaws_tools.recording_format import JIGSAWS_FORMAT
from jigsaws_tools.release import discover, read_kinematics, read_transcription

RATE = 100
USERS = ("B", "C", "D", "E")
#: The robot's name of each model feature: a 14-feature run reads these columns.
COLUMNS = {f: f"arm{f[3]}_{f[5:]}" for f in feature_names("psm_pos_vel_grip")}
FORMAT = f"""name = "my_robot"
rate_hz = {RATE}
delimiter = ","
header = true
time_column = "time_s"

[features]
{chr(10).join(f'{feature} = "{column}"' for feature, column in COLUMNS.items())}

[files]
recordings = "recordings"
transcriptions = "labels"
trial = "{{task}}-{{user}}-{{trial}}"
extension = ".csv"
"""


def _upsample(kinematics: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """30 Hz frames ``[n, C]`` -> ``(times [m] in s, values [m, C])`` at RATE, linearly
    interpolated over the same time span."""
    times = np.arange(int((len(kinematics) - 1) / 30 * RATE) + 1) / RATE
    frame_times = np.arange(len(kinematics)) / 30
    return times, np.stack([np.interp(times, frame_times, c) for c in kinematics.T], axis=1)


def _row(frame: int) -> int:
    """The 1-based RATE row where 30 Hz frame ``frame`` (1-based) starts."""
    return int((frame - 1) * RATE / 30) + 1


def write_robot_folder(synth_dir: Path, root: Path) -> Path:
    """Users B-E of the synthetic release in ``synth_dir`` as the robot's data folder
    (``root/data``), and its format file ``root/my_robot.toml``; returns ``root``."""
    (root / "data" / "recordings").mkdir(parents=True)
    (root / "data" / "labels").mkdir()
    columns = [JIGSAWS_FORMAT.columns.index(f) for f in COLUMNS]
    for t in discover(synth_dir).trials:
        if t.user not in USERS:
            continue
        times, values = _upsample(read_kinematics(t.kinematics)[:, columns])
        table = pd.DataFrame(values, columns=list(COLUMNS.values()))
        table.insert(0, "time_s", times)
        table["battery"] = 1.0                       # a column the model does not use
        name = f"Suturing-{t.user}-{t.trial}"
        table.to_csv(root / "data" / "recordings" / f"{name}.csv", index=False,
                     float_format="%.8f")
        lines = [f"{_row(s.start)} {min(_row(s.end + 1) - 1, len(times))} {s.gesture}"
                 for s in read_transcription(t.transcription)]
        (root / "data" / "labels" / f"{name}.txt").write_text("\n".join(lines) + "\n")
    (root / "my_robot.toml").write_text(FORMAT)
    return root
