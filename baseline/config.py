"""DiPietro et al.'s hyperparameters, one dataclass per concern, bundled for one run."""
from __future__ import annotations

from dataclasses import dataclass, field

from jigsaws_tools.dataset import DataConfig
from rnn_seg.config import EncoderConfig, OptimConfig, TrainConfig

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

    def describe(self) -> str:
        """Printable multi-line summary of every field."""
        lines = [f"test user: {self.test_user}"]
        for name in ("data", "encoder", "optim", "train"):
            lines.append(f"{name}: {getattr(self, name)}")
        return "\n".join(lines)
