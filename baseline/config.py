"""DiPietro et al.'s hyperparameters, one dataclass per concern, bundled for one run."""
from __future__ import annotations

from dataclasses import dataclass, field, fields, is_dataclass
from typing import ClassVar

from jigsaws_tools.dataset import DataConfig, holds_unrecorded_default
from jigsaws_tools.preprocessing import decimation
from jigsaws_tools.release import KINEMATICS_HZ
from jigsaws_tools.recording_format import RecordingFormat
from jigsaws_tools.task_definition import TaskDefinition
from rnn_seg.config import EncoderConfig, OptimConfig, TrainConfig, check_eval_points
from rnn_seg.encoders.config import CustomEncoderConfig, EDTCNConfig, MSTCNConfig

#: Encoder directions by name (``EncoderConfig.bidirectional``): offline or online recognition.
DIRECTIONS = ("bidirectional", "forward")
#: A longer sequence is printed by its length and its first and last item (``RunConfig.describe``).
SHOWN_ITEMS = 4
#: What a recording format's printed line leaves out (config.json records it): where a data
#: folder's files are and its one-line summary, not how a recording is read.
_FORMAT_LAYOUT = ("recordings", "transcriptions", "trial", "extension", "summary")


@dataclass(frozen=True)
class RunConfig:
    """Everything that defines one training run of one LOUO fold."""

    data: DataConfig
    test_user: str = "B"
    encoder: EncoderConfig | EDTCNConfig | MSTCNConfig | CustomEncoderConfig = field(
        default_factory=EncoderConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    #: Users whose trials the run neither trains on nor is scored on, dropped before the split:
    #: an outer fold's test user, when ``test_user`` is a validation user among its training
    #: users (``results/tcn/PLAN_factors.md``). Not recorded while empty.
    held_out_users: tuple[str, ...] = ()

    unrecorded_defaults: ClassVar[tuple[str, ...]] = ("held_out_users",)

    def __post_init__(self):
        if not isinstance(self.test_user, str) or not self.test_user:
            raise ValueError(f"RunConfig.test_user must be a user letter (got {self.test_user!r})")
        if not isinstance(self.held_out_users, tuple) or not all(
                isinstance(u, str) and u for u in self.held_out_users):
            raise ValueError(f"RunConfig.held_out_users must be a list of user letters "
                             f"(got {self.held_out_users!r})")
        if self.test_user in self.held_out_users:
            raise ValueError(f"RunConfig: test user {self.test_user} is also held out")
        check_eval_points(self.train.eval_points, self.optim)

    def describe(self) -> str:
        """Printable summary, a line per configuration: ``name: field=value, ...`` (a nested
        configuration on a line of its own, a task by its name, a recording format without its
        file layout, a sequence of more than ``SHOWN_ITEMS`` items as ``76 (first ... last)``);
        config.json records every value in full."""
        lines = [f"test user: {self.test_user}" + (
            f" (held out: {', '.join(self.held_out_users)})" if self.held_out_users else "")]
        for name in ("data", "encoder", "optim", "train"):
            lines += _describe(name, getattr(self, name))
        return "\n".join(_with_real_step(line, self.data) for line in lines)


def _with_real_step(line: str, data: DataConfig) -> str:
    """The preprocessing line of ``describe`` saying the step it takes at the recording format's
    rate, where that is not ``resample_factor`` (given in 30 Hz release frames): at 50 Hz,
    ``resample_factor=6 (30 Hz frames; at rate_hz=50: one sample in 10, 5 Hz)``."""
    prep, rate = data.preprocessing, data.recording_format.rate_hz
    step = decimation(prep, rate)
    if not line.startswith("data.preprocessing:") or step == prep.resample_factor:
        return line
    factor = f"resample_factor={prep.resample_factor}"
    return line.replace(factor, f"{factor} ({KINEMATICS_HZ:g} Hz frames; at rate_hz={rate:g}: "
                                f"one sample in {step}, {prep.sample_hz:g} Hz)")


def _describe(name: str, config) -> list[str]:
    """``name: field=value, ...`` for a configuration dataclass, then its nested ones; a field
    that records leave out while it holds its default (``holds_unrecorded_default``) is left out
    too."""
    plain, nested = [], []
    for f in fields(config):
        value = getattr(config, f.name)
        if (isinstance(config, RecordingFormat) and f.name in _FORMAT_LAYOUT
                or not is_dataclass(value) and holds_unrecorded_default(config, f.name)):
            continue
        if isinstance(value, TaskDefinition):
            plain.append(f"{f.name}={value.name}")
        elif is_dataclass(value):
            nested += _describe(f"{name}.{f.name}", value)
        else:
            plain.append(f"{f.name}={_shown(value)}")
    return [f"{name}: {', '.join(plain)}", *nested]


def _shown(value: object) -> str:
    """``value`` as printed: a tuple or list of more than ``SHOWN_ITEMS`` items by its length and
    its first and last item, e.g. ``76 (mtml_pos_x ... psm2_gripper)``."""
    if isinstance(value, (tuple, list)) and len(value) > SHOWN_ITEMS:
        return f"{len(value)} ({value[0]} ... {value[-1]})"
    return str(value)
