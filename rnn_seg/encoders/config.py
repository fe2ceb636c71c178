"""The encoders' configurations and each temporal-convolution encoder's reference schedule.

Plain frozen dataclasses without TensorFlow, like ``rnn_seg.config`` (which holds the LSTM's
``EncoderConfig``). A run's ``RunConfig.encoder`` is one of the three; its ``kind`` names it
(``"lstm"``, ``"ed-tcn"``, ``"ms-tcn"``) and is what ``--encoder`` and a grid spec's ``encoder``
key choose. The settings follow each architecture's paper and code, adapted to the engine's
5 Hz samples by one rule: a kernel keeps its length in seconds, a receptive field its span in
seconds (docs/REPRODUCTION.md, "Temporal-convolution encoders", gives every value's source).

A user's own encoder (``CustomEncoderConfig``, kind ``"custom"``) is named by its import path
``package.module:name`` instead (``rnn_seg.encoders.import_path``, docs/YOUR_METHOD.md).

Every configuration offers what the engine reads of any encoder: ``output_size`` (features per
time step; a user's encoder's is its output's width, known once built), ``bidirectional`` (False = online: a forward LSTM, or causal convolutions),
``hidden`` (the widest layer, for the thread plan), ``precision`` and ``loops`` (the LSTM's
options; a TCN always runs float32 TensorFlow ops).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import ClassVar, Literal

from ..config import EncoderConfig, OptimConfig
from ..validation import require_bool, require_choice, require_number

EncoderKind = Literal["lstm", "ed-tcn", "ms-tcn"]
#: The built-in encoders; ``--encoder`` and a grid spec's ``encoder`` also take a user's encoder
#: by its import path (``CustomEncoderConfig``).
ENCODERS = ("lstm", "ed-tcn", "ms-tcn")

#: A SHA-256 digest in hexadecimal (a user's encoder's source, ``CustomEncoderConfig``).
SHA256 = re.compile(r"[0-9a-f]{64}")
#: ED-TCN's padding: the engine's (zeros, every layer's output masked) or Lea et al.'s (-1, the
#: layers unmasked, the loss masked; ``rnn_seg.encoders.ed_tcn``).
PADDINGS = ("masked", "reference")
#: ED-TCN's heads' initial weights: U(+-1/sqrt(D)), bias alike (PyTorch's 1x1 convolution), or
#: Glorot uniform with a zero bias (Keras's ``Dense``, Lea et al.'s heads).
HEAD_INITS = ("uniform", "glorot")

#: Samples per second of every model input (``jigsaws_tools.preprocessing``).
MODEL_HZ = 5.0


def samples(seconds: float, hz: float = MODEL_HZ) -> int:
    """A duration in seconds as a whole number of samples at ``hz`` (at least 1)."""
    return max(1, round(seconds * hz))


class _Convolutional:
    """What the engine reads of any encoder, for those without the LSTM's loops (the
    temporal-convolution ones and a user's own)."""

    precision: ClassVar[str] = "fp32"
    loops: ClassVar[str] = "graph"

    @property
    def bidirectional(self) -> bool:
        """Offline (non-causal convolutions) or online (causal)."""
        return not self.causal


@dataclass(frozen=True)
class EDTCNConfig(_Convolutional):
    """Lea et al.'s (CVPR 2017) encoder-decoder TCN, their JIGSAWS configuration at 5 Hz.

    Encoder: per entry of ``filters`` a temporal convolution of ``kernel`` samples, spatial
    dropout (whole channels) at rate ``dropout``, ReLU, normalisation by the step's largest
    activation, max pooling by 2; decoder: the mirror image, upsampling by 2 before each
    convolution. ``[B, T, F]`` -> ``[B, T, filters[0]]``. ``padding`` and ``head_init``
    (``PADDINGS``, ``HEAD_INITS``) are Lea et al.'s options of results/tcn/PLAN_factors.md, not
    recorded while they hold the engine's defaults (earlier runs keep their settings hash).
    """

    unrecorded_defaults: ClassVar[tuple[str, ...]] = ("padding", "head_init")

    kind: Literal["ed-tcn"] = "ed-tcn"
    filters: tuple[int, ...] = (64, 96)     # per encoder layer; the decoder runs them backwards
    kernel: int = samples(2.0)              # 2.0 s: Lea et al.'s 20 samples at 10 Hz
    dropout: float = 0.3                    # spatial dropout rate (whole channels)
    causal: bool = False
    padding: str = PADDINGS[0]
    head_init: str = HEAD_INITS[0]

    def __post_init__(self):
        if not isinstance(self.filters, tuple) or not self.filters:
            raise ValueError(f"EDTCNConfig.filters must be a non-empty list of integers >= 1 "
                             f"(got {self.filters!r})")
        for width in self.filters:
            require_number("EDTCNConfig.filters", width, integer=True, low=1)
        require_number("EDTCNConfig.kernel", self.kernel, integer=True, low=1)
        require_number("EDTCNConfig.dropout", self.dropout, low=0, high=1, open_high=True)
        require_bool("EDTCNConfig.causal", self.causal)
        require_choice("EDTCNConfig.padding", self.padding, PADDINGS)
        require_choice("EDTCNConfig.head_init", self.head_init, HEAD_INITS)

    @property
    def output_size(self) -> int:
        return self.filters[0]

    @property
    def hidden(self) -> int:
        return max(self.filters)


@dataclass(frozen=True)
class MSTCNConfig(_Convolutional):
    """Farha & Gall's (CVPR 2019) multi-stage TCN at 5 Hz.

    ``stages`` stages of ``layers`` dilated residual layers (kernel ``kernel``, dilation
    ``2**l``, ``filters`` maps, dropout ``dropout`` on each residual branch); every stage after
    the first reads the previous stage's predictions of every head. Each stage's loss adds
    ``smoothing_weight`` times the truncated MSE of its log-probabilities between neighbouring
    steps, truncated at ``smoothing_tau`` (``rnn_seg.encoders.ms_tcn``).
    """

    kind: Literal["ms-tcn"] = "ms-tcn"
    stages: int = 4
    layers: int = 8            # receptive field 511 samples = 102 s, the original's 2047 at 15 Hz
    filters: int = 64
    kernel: int = 3
    dropout: float = 0.5
    smoothing_weight: float = 0.15
    smoothing_tau: float = 4.0
    causal: bool = False

    def __post_init__(self):
        require_number("MSTCNConfig.stages", self.stages, integer=True, low=1)
        require_number("MSTCNConfig.layers", self.layers, integer=True, low=1)
        require_number("MSTCNConfig.filters", self.filters, integer=True, low=1)
        require_number("MSTCNConfig.kernel", self.kernel, integer=True, low=2)
        require_number("MSTCNConfig.dropout", self.dropout, low=0, high=1, open_high=True)
        require_number("MSTCNConfig.smoothing_weight", self.smoothing_weight, low=0)
        require_number("MSTCNConfig.smoothing_tau", self.smoothing_tau, low=0, open_low=True)
        require_bool("MSTCNConfig.causal", self.causal)

    @property
    def output_size(self) -> int:
        return self.filters

    @property
    def hidden(self) -> int:
        return self.filters

    @property
    def receptive_field(self) -> int:
        """Samples one stage sees: ``1 + (kernel - 1) * (2**layers - 1)``."""
        return 1 + (self.kernel - 1) * (2 ** self.layers - 1)


@dataclass(frozen=True)
class CustomEncoderConfig(_Convolutional):
    """A user's own encoder: the Keras layer that the function or class ``path`` names builds
    (``package.module:name``, called as ``build(input_size, config)``; docs/YOUR_METHOD.md and
    ``rnn_seg.encoders.keras_layer``). ``source_sha256`` is the hash of that module's source file
    when the run was configured: a trained run's encoder is rebuilt only from the same source.
    ``causal``: an online encoder is asked for (``directions = ["forward"]``, ``--direction
    forward``); the builder reads it and must honour it (the engine cannot check it).
    ``[B, T, F]`` -> ``[B, T, D]``, ``D`` the width of the layer's output."""

    #: The thread plan's LSTM width (``rnn_seg.threads``): none, as for a TCN's small layers.
    hidden: ClassVar[int] = 0

    kind: Literal["custom"] = "custom"
    path: str = ""
    source_sha256: str = ""
    causal: bool = False

    def __post_init__(self):
        from .import_path import split_path

        split_path(self.path)
        if not isinstance(self.source_sha256, str) or not SHA256.fullmatch(self.source_sha256):
            raise ValueError(f"CustomEncoderConfig.source_sha256 must be 64 hexadecimal digits "
                             f"(got {self.source_sha256!r})")
        require_bool("CustomEncoderConfig.causal", self.causal)

    def describe(self) -> str:
        """``package.module:name (sha256 0123456789ab)``: how tables and errors name it."""
        return f"{self.path} (sha256 {self.source_sha256[:12]})"


AnyEncoderConfig = EncoderConfig | EDTCNConfig | MSTCNConfig | CustomEncoderConfig


@dataclass(frozen=True)
class Schedule:
    """An encoder's reference training: optimiser, evaluation points (epochs), batch size."""

    optim: OptimConfig
    eval_points: tuple[int, ...]
    batch_size: int


def _relative_points(total: int) -> tuple[int, ...]:
    """The paper's evaluation points 100, 110, 120 of 120 epochs, at the same fractions of
    ``total`` epochs (rounded half up)."""
    return tuple(sorted({max(1, int(total * p / 120 + 0.5)) for p in (100, 110, 120)}))


def _constant(optimizer: str, learning_rate: float, epochs: int) -> OptimConfig:
    """A constant learning rate for ``epochs`` epochs, no clipping (as both references)."""
    return OptimConfig(optimizer=optimizer, learning_rate=learning_rate, clip_norm=0.0,
                       total=epochs, decay_start=epochs)


#: Lea et al.'s code: RMSprop (Keras defaults, lr 1e-3), 200 epochs, batches of 8 trials;
#: Farha & Gall's: Adam lr 5e-4, 50 epochs, one video per batch.
SCHEDULES = {
    "ed-tcn": Schedule(_constant("rmsprop", 1e-3, 200), _relative_points(200), 8),
    "ms-tcn": Schedule(_constant("adam", 5e-4, 50), _relative_points(50), 1),
}


def schedule_of_length(kind: str, epochs: int) -> Schedule:
    """Encoder ``kind``'s reference training (``SCHEDULES``) run for ``epochs`` epochs: the same
    optimiser, constant learning rate and batch size, evaluated at the same fractions of the
    length (``_relative_points``). E.g. the convergence ladders of results/tcn/PLAN_factors.md."""
    reference = SCHEDULES[kind]
    return Schedule(replace(reference.optim, total=epochs, decay_start=epochs),
                    _relative_points(epochs), reference.batch_size)


def encoder_config(kind: str, causal: bool = False
                   ) -> EDTCNConfig | MSTCNConfig | CustomEncoderConfig:
    """The reference configuration of a temporal-convolution encoder, causal (online) or not;
    for an import path ``package.module:name``, that user's encoder with its source's hash now
    (``import_path.custom_encoder``)."""
    from .import_path import custom_encoder, is_import_path

    if is_import_path(kind):
        return custom_encoder(kind, causal)
    if kind == "ed-tcn":
        return EDTCNConfig(causal=causal)
    if kind == "ms-tcn":
        return MSTCNConfig(causal=causal)
    raise ValueError(f"encoder must be one of {', '.join(ENCODERS[1:])} or an import path "
                     f"package.module:name here (got {kind!r})")
