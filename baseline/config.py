"""DiPietro et al.'s hyperparameters, one dataclass per concern, bundled for one run."""
from __future__ import annotations

from dataclasses import dataclass, field

from jigsaws_tools.dataset import DataConfig
from rnn_seg.config import EncoderConfig, OptimConfig, TrainConfig, check_eval_points

#: Encoder directions by name (``EncoderConfig.bidirectional``): offline or online recognition.
DIRECTIONS = ("bidirectional", "forward")


@dataclass(frozen=True)
class RunConfig:
    """Everything that defines one training run of one LOUO fold."""

    data: DataConfig
    test_user: str = "B"
    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    train: TrainConfig = field(default_factory=TrainConfig)

    def __post_init__(self):
        if not isinstance(self.test_user, str) or not self.test_user:
            raise ValueError(f"RunConfig.test_user must be a user letter (got {self.test_user!r})")
        check_eval_points(self.train.eval_points, self.optim)

    def describe(self) -> str:
        """Printable multi-line summary of every field."""
        lines = [f"test user: {self.test_user}"]
        for name in ("data", "encoder", "optim", "train"):
            lines.append(f"{name}: {getattr(self, name)}")
        return "\n".join(lines)
