"""The experiment grid: a TOML spec, its presets, and its expansion into independent runs.

A spec names experiments (each a product of variants x weightings x annotation versions x
directions), the LOUO folds, the seeds and a budget. Presets give the budget:

* ``converged`` (the default): H=128 and the paper's schedules (120 epochs, 80 for Pr/Pc/Poc),
  1.5x longer for APoc (180) and 2x for Poc (160), seed 0: per variant, the shortest of the
  measured lengths whose runs pass the convergence diagnostic (``rnn_seg.convergence``; the
  measurements are in docs/REPRODUCTION.md, "The converged preset");
* ``paper``: H=1024, the paper's schedules, seeds 0, 1, 2;
* ``quick``: H=128 and every schedule compressed 4x (30 epochs, 20 for P), seed 0: a fast look
  at a whole grid; its progress heads have not converged (``results/smoke.toml`` is the smoke
  test: a tiny model on two folds of the synthetic release).

An experiment may name its own ``seeds`` (e.g. three for the configurations the paper's claims
compare, one for the rest). Grids run every configuration's first seed first, in the order the
spec lists them, so a grid cut short still has complete single-seed tables; then the further
seeds configuration by configuration, in the same order, so each configuration's seeds complete
as early as they can: list first what you need first (e.g. Table I).

Every run has its own directory
``runs/<annotations>/<direction>/<variant>-<weighting>/seed<k>/<user>``
and is resumable on its own; ``finished.json`` marks it complete (``rnn_seg.runs.folder``). The path
does not name the budget: the grid's record (``record``) and each run's config.json do.
Every key's type and range is checked when the spec is read (``GridSpec.__post_init__``).

Example spec (every key optional)::

    preset = "converged"
    task = "Suturing"             # a built-in task (Knot_Tying, ...) or a definition file (*.toml)
    data_dir = "synthetic"        # or the task's JIGSAWS folder; default $JIGSAWS_DIR
    test_users = ["B", "C"]       # the LOUO folds; default: every user of the release
    seeds = [0]
    hidden = 64                   # budget overrides
    epochs = 10                   # length of the gesture variants' schedule; P scaled alike
    schedule_factors = {APoc = 1.5}   # per variant, a longer schedule still; {} = none
    precision = "fp32"            # or "bf16": the LSTM's matrix products in bfloat16
    loops = "auto"                # or "graph", "xla", "fused": how the LSTM's loops run (not a setting)
    ordinal_loss = "sum"          # the ordered progress head's loss: "sum" (paper) or "mean"
    relative_rate = "chen"        # GradNorm's r_i: "chen" (ratio mean) or "paper" (loss mean)
    encoder = "lstm"              # or "ed-tcn", "ms-tcn": their reference settings and schedule;
                                  # or your own, "package.module:name" (docs/YOUR_METHOD.md)
    resample_factor = 6           # one labelled 30 Hz frame in 6: the model's 5 Hz (10: 3 Hz)
    format = "jigsaws"            # the recordings' format: a built-in's name or a format file
                                  # (*.toml), as --format (docs/DATA.md, "Your own recordings")
    plots = "last"                # per-trial figures at the last evaluation point, "all" or
                                  # "none" (what runs write, not a setting; as --plots)

    [[experiments]]
    variants = ["A", "APc"]
    weightings = ["fixed"]
    annotations = ["revised"]
    directions = ["bidirectional"]
    seeds = [0, 1, 2]             # this experiment's seeds; default: the spec's

A temporal-convolution ``encoder`` trains every variant with its reference's configuration,
optimiser, batch size and length (``rnn_seg.encoders.config.SCHEDULES``), scaled only by the
preset's ``schedule_scale`` (``quick``: 4x shorter), never by the LSTM-measured
``schedule_factors``; ``epochs`` sets its length instead (the same optimiser and constant
learning rate, evaluated at the same fractions of the length: ``schedule_of_length``, e.g. the
convergence ladders of results/tcn/PLAN_factors.md); ``hidden``, ``schedule_factors``,
``precision`` and ``loops``, the LSTM's, are refused with it. ``directions = ["forward"]`` makes its convolutions causal.
``resample_factor`` (any encoder) and ``kernel`` (ED-TCN only, in samples) change the model's
sample rate and ED-TCN's kernel, e.g. Lea et al.'s released JIGSAWS model: 3 Hz, 15 samples
(``resample_factor = 10``, ``kernel = 15``; docs/REPRODUCTION.md, "ED-TCN at its reference's
rate"); without them a run keeps the paper's 5 Hz and ED-TCN's 2 s kernel.

A user's ``encoder``, given by its import path ``package.module:name`` (importable by every
worker: installed, or on ``PYTHONPATH``), trains every variant on the LSTM's schedules and
budget (``epochs``, ``schedule_factors``); ``hidden``, ``precision`` and ``loops``, the LSTM's
own, are refused with it. Each run records its import path and its module source's sha256
(``rnn_seg.encoders.config.CustomEncoderConfig``): a grid resumed after that source changed
finds its runs of other settings.

The factor study's keys (``results/tcn/PLAN_factors.md``; each None = the default, so a spec
without them trains what it always did): ``lowpass = false`` and ``normalise = false`` switch
those preprocessing steps off, ``feature_set`` names the inputs (``psm_all``, ``all``;
``jigsaws_tools.features``), ``padding = "reference"`` and ``head_init = "glorot"`` are ED-TCN's
Lea et al. options (``EDTCNConfig``). ``inner_validation = n`` trains, instead of each fold's
run, its *inner* runs: for outer fold u, one run per validation user v among the n users that
follow u in the release's (cyclic) user order, trained on the users other than u and v, scored
on v; u's trials are dropped first (``RunConfig.held_out_users``), so no score of u exists. An
inner run's folder is named ``<u>-val-<v>`` (``inner_fold``) where an outer run's is ``<u>``.

``fold_settings`` gives outer folds settings of their own (a *nested selection*: each fold's
chosen on its training users alone, e.g. by ``multitask-tables factors``), any of the keys in
``SELECTABLE`` per fold; a fold it does not name keeps the spec's::

    [fold_settings.B]
    kernel = 25
    lowpass = false

    [fold_settings.F]
    kernel = 15

An inner run takes its outer fold's. Every run records the whole selection
(``SelectionConfig``: each named fold's settings, the others', and the data fingerprint at the
others'), so that tables pool the folds' runs as one configuration, the procedure that chose
their settings (``multitask.evidence.runs.pooling``).

The keys ``data`` and ``folds`` of earlier versions are read as ``data_dir`` and ``test_users``,
with a deprecation warning.
"""
from __future__ import annotations

import json
import logging
from dataclasses import asdict, dataclass, fields, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

from baseline.config import DIRECTIONS, RunConfig
from jigsaws_tools.annotations import ANNOTATION_VERSIONS
from jigsaws_tools.dataset import DataConfig, data_fingerprint, default_cache_dir, default_data_dir
from jigsaws_tools.features import FEATURE_SETS
from jigsaws_tools.preprocessing import PreprocessConfig
from jigsaws_tools.release import discover
from jigsaws_tools.synth import SynthConfig, ensure_release
from jigsaws_tools.task_definition import PAPER_TASK, TaskDefinition, load_task
from jigsaws_tools.toml_files import read_toml
from rnn_seg.config import LOOPS, PLOT_POINTS, PRECISIONS, EncoderConfig, TrainConfig
from jigsaws_tools.recording_format import DEFAULT_FORMAT, RecordingFormat, load_format
from rnn_seg.encoders.config import (ENCODERS, HEAD_INITS, PADDINGS, SCHEDULES, encoder_config,
                                     schedule_of_length)
from rnn_seg.encoders.import_path import is_import_path, split_path
from rnn_seg.runs.settings import settings_of
from rnn_seg.validation import require_bool, require_choice, require_number

from ..models.config import (ORDINAL_LOSSES, RELATIVE_RATES, WEIGHTINGS, GradNormConfig,
                             HeadConfig, SelectionConfig)
from ..models.variants import MULTITASK_EVAL, VARIANTS, batch_size, get_variant

log = logging.getLogger(__name__)
PAPER_EPOCHS = MULTITASK_EVAL[-1]
#: Old spec key -> its name now.
DEPRECATED_KEYS = {"data": "data_dir", "folds": "test_users"}
#: The spec keys ``fold_settings`` may set per outer fold -> the setting each run records of it.
SELECTABLE = {"resample_factor": "run.data.preprocessing.resample_factor",
              "lowpass": "run.data.preprocessing.lowpass",
              "normalise": "run.data.preprocessing.normalise",
              "feature_set": "run.data.feature_set",
              "kernel": "run.encoder.kernel", "padding": "run.encoder.padding",
              "head_init": "run.encoder.head_init"}


def _tuple(value):
    """A list (TOML array) as a tuple; anything else unchanged, for the dataclasses to check."""
    return tuple(value) if isinstance(value, list) else value


def _require_seeds(name: str, seeds) -> None:
    """Raise unless ``seeds`` is a non-empty tuple of distinct integers >= 0."""
    _require_tuple(name, seeds, "a non-empty list of integers >= 0")
    for seed in seeds:
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"{name} must be a list of integers >= 0 (got {seed!r})")
    if len(set(seeds)) < len(seeds):
        raise ValueError(f"{name} must not repeat (got {list(seeds)})")


def _require_tuple(name: str, value, what: str) -> None:
    """Raise unless ``value`` is a non-empty tuple (a TOML array, see ``_tuple``)."""
    if not isinstance(value, tuple) or not value:
        shown = list(value) if isinstance(value, tuple) else value
        raise ValueError(f"{name} must be {what} (got {shown!r})")


@dataclass(frozen=True, order=True)
class RunKey:
    """Identity of one run of the grid."""

    annotations: str
    direction: str
    variant: str
    weighting: str
    seed: int
    fold: str

    @property
    def config_name(self) -> str:
        """The configuration, without fold and seed (a column of the tables)."""
        return f"{self.variant}-{self.weighting}"

    def path(self) -> Path:
        return (Path("runs") / self.annotations / self.direction / self.config_name
                / f"seed{self.seed}" / self.fold)


def expand(spec: GridSpec, users: tuple[str, ...]) -> list[RunKey]:
    """Every run of the grid, each once, in the spec's order: experiment by experiment, then
    variant, weighting, annotations, direction, seed, fold. ``users`` are the release's users."""
    folds = spec.test_users or users
    missing = sorted(set(folds) - set(users))
    if missing:
        raise ValueError(f"fold(s) {', '.join(missing)} not among the release's users "
                         f"{', '.join(users)}")
    unknown = sorted(set(spec.fold_settings or {}) - set(folds))
    if unknown:
        raise ValueError(f"fold_settings names fold(s) {', '.join(unknown)}, not among the "
                         f"grid's folds {', '.join(folds)}")
    if spec.inner_validation is not None:
        folds = tuple(inner_fold(u, v) for u in folds
                      for v in validation_users(users, u, spec.inner_validation))
    keys = (RunKey(a, d, v, w, s, f)
            for e in spec.experiments
            for v in e.variants for w in e.weightings for a in e.annotations for d in e.directions
            for s in spec.seeds_of(e) for f in folds
            if w == "fixed" or get_variant(v).multitask)
    return list(dict.fromkeys(keys))


#: Between an inner run's outer fold and its validation user in its fold's name (``inner_fold``).
INNER = "-val-"


def inner_fold(outer: str, validation: str) -> str:
    """The fold name of the inner run of outer fold ``outer`` scored on ``validation``:
    ``B-val-C``; never a user's name, so never an outer run's fold."""
    return f"{outer}{INNER}{validation}"


def fold_users(fold: str) -> tuple[str, tuple[str, ...]]:
    """A run's test user and held-out users from its fold's name: ``B`` -> ``("B", ())``, the
    inner run ``B-val-C`` -> ``("C", ("B",))``."""
    outer, inner, validation = fold.partition(INNER)
    return (validation, (outer,)) if inner else (fold, ())


def validation_users(users: tuple[str, ...], outer: str, count: int) -> tuple[str, ...]:
    """The ``count`` users that follow ``outer`` in the cyclic order of ``users`` (the release's):
    B's two among B..I are C and D, H's I and B (results/tcn/PLAN_factors.md, section B). At least
    one user must stay to train on."""
    if not count < len(users) - 1:
        raise ValueError(f"inner_validation = {count} leaves no training user among the "
                         f"{len(users)} users {', '.join(users)} once the outer fold's is dropped")
    at = users.index(outer)
    return tuple(users[(at + k) % len(users)] for k in range(1, count + 1))


def release_users(spec: GridSpec) -> tuple[str, ...]:
    """The LOUO folds of the spec's release: every user with at least one complete trial of the
    spec's task (at least two, or there is no fold to train)."""
    index = discover(spec.release_dir(), spec.task_definition(), spec.recording_format())
    if len(index.users) < 2:
        raise ValueError(f"{index.root}: only user {index.users[0]} has complete "
                         f"{index.task.name} trials; leave-one-user-out needs at least two users")
    return index.users


def run_config(spec: GridSpec, key: RunKey) -> RunConfig:
    """The ``RunConfig`` of one run: the variant's (scaled) paper schedule, the budget's size,
    its outer fold's settings (``fold_settings``)."""
    test_user, held_out = fold_users(key.fold)
    spec = spec.for_fold(held_out[0] if held_out else test_user)
    budget = spec.budget
    optim, points = _schedule(spec, key)
    bidirectional = key.direction == "bidirectional"
    encoder = (EncoderConfig(hidden=budget.hidden, bidirectional=bidirectional,
                             precision=spec.precision, loops=spec.loops)
               if spec.encoder == "lstm" else encoder_config(spec.encoder, not bidirectional))
    encoder = replace(encoder, **_given(spec, "kernel", "padding", "head_init"))
    preprocessing = PreprocessConfig(**_given(spec, "resample_factor", "lowpass", "normalise"))
    return RunConfig(
        data=DataConfig(str(spec.release_dir()), annotations=key.annotations,
                        preprocessing=preprocessing, task=spec.task_definition(),
                        recording_format=spec.recording_format(),
                        **_given(spec, "feature_set")),
        test_user=test_user,
        encoder=encoder,
        optim=optim,
        train=TrainConfig(seed=key.seed, eval_points=points,
                          batch_size=batch_size(spec.encoder), plots=spec.plots),
        held_out_users=held_out)


def _given(spec: GridSpec, *names: str) -> dict:
    """The keys ``names`` of ``spec`` that it sets (not None), as keyword arguments."""
    return {name: getattr(spec, name) for name in names if getattr(spec, name) is not None}


def schedule_epochs(spec: GridSpec, key: RunKey) -> int:
    """The length of one run's schedule, in epochs (its share of a grid's work)."""
    return _schedule(spec, key)[0].total


def _schedule(spec: GridSpec, key: RunKey):
    """The run's optimiser schedule and evaluation points: its variant's paper schedule scaled by
    the budget (``Variant.schedule``, a user's encoder's too); a TCN's reference schedule scaled
    by the preset's ``schedule_scale`` only (module docstring)."""
    if spec.encoder in SCHEDULES and spec.epochs is not None:
        schedule = schedule_of_length(spec.encoder, spec.epochs)
        return schedule.optim, schedule.eval_points
    if spec.encoder in SCHEDULES:
        return get_variant(key.variant).schedule(PRESETS[spec.preset].schedule_scale,
                                                 spec.encoder)
    return get_variant(key.variant).schedule(spec.budget.scale_of(key.variant))


def run_arguments(spec: GridSpec, key: RunKey, common_fingerprint: str | None = None) -> dict:
    """Keyword arguments of ``fold_run.variant_trainer`` (and ``variant_configs``) for one run:
    the one place a grid run's configuration is decided. Workers train with it and
    ``record`` checks run folders against it, so the two never disagree. ``common_fingerprint``:
    a nested selection's (``selection``), as a run folder records it; None = read the release."""
    return {"variant": get_variant(key.variant), "weighting": key.weighting,
            "config": run_config(spec, key), "gradnorm": spec.gradnorm, "heads": spec.heads,
            "selection": selection(spec, key, common_fingerprint)}


def selection(spec: GridSpec, key: RunKey, common_fingerprint: str | None = None
              ) -> SelectionConfig | None:
    """The nested selection the run at ``key`` records (module docstring), None when the spec
    sets no ``fold_settings``: every setting a fold's entry names, on each named fold and on
    the others, and the data fingerprint on the others (``common_fingerprint``; None = read
    the release for it)."""
    if not spec.fold_settings:
        return None
    names = sorted({SELECTABLE[k] for entry in spec.fold_settings.values() for k in entry})
    common = run_config(replace(spec, fold_settings=None), key)

    def values(config: RunConfig) -> dict[str, Any]:
        recorded = settings_of({"run": config})
        return {name: recorded.get(name) for name in names}

    per_fold = {fold: values(run_config(spec, replace(key, fold=fold)))
                for fold in spec.fold_settings}
    return SelectionConfig(per_fold, values(common),
                           common_fingerprint or _fingerprint(common.data))


@lru_cache(maxsize=16)
def _fingerprint(data: DataConfig) -> str:
    """``data_fingerprint``, once per process (a grid asks for it once per run)."""
    return data_fingerprint(data)


def stack_groups(keys: list[RunKey], size: int) -> list[list[RunKey]]:
    """``keys`` in groups of at most ``size`` runs of one configuration (differing only in fold
    and seed), in order; ``size`` 1 = every run alone."""
    by_config: dict[tuple, list[RunKey]] = {}
    for key in keys:
        by_config.setdefault(_configuration(key), []).append(key)
    return [runs[i:i + size] for runs in by_config.values() for i in range(0, len(runs), size)]


def job_groups(keys: list[RunKey], size: int,
               grid: list[RunKey] | None = None) -> list[list[RunKey]]:
    """``stack_groups`` in the order a grid runs them: first every configuration's first seed, in
    the spec's order, so a grid cut short still has complete single-seed tables; then the further
    seeds configuration by configuration, so each configuration's seeds (and the comparisons
    between them) complete as early as they can.

    Args:
        keys: the runs to group, e.g. a resumed grid's unfinished ones (``expand``'s order).
        size: runs per group (``stack_groups``).
        grid: the whole grid's runs, which define each configuration's first seed; default
            ``keys``.
    """
    first_seed: dict[tuple, int] = {}
    for key in grid if grid is not None else keys:
        config = _configuration(key)
        first_seed[config] = min(key.seed, first_seed.get(config, key.seed))
    return sorted(stack_groups(keys, size),
                  key=lambda group: all(k.seed != first_seed[_configuration(k)] for k in group))


def _configuration(key: RunKey) -> tuple[str, str, str]:
    """What the runs of one configuration share: annotations, direction and model."""
    return key.annotations, key.direction, key.config_name


def spec_payload(spec: GridSpec) -> dict:
    """``spec`` as plain data that ``spec_from_dict`` reads back (for workers and grid.json)."""
    data = asdict(spec)
    data["experiments"] = [dict(e) for e in data["experiments"]]
    return json.loads(json.dumps(data))


def with_budget(spec: GridSpec) -> GridSpec:
    """``spec`` with its preset's budget written out (``hidden``, ``epochs``, ``seeds``,
    ``schedule_factors``), as grid.json records it: two specs of the same runs then read the
    same. A TCN grid's budget is its seeds (its schedule is its encoder's); a user's encoder's,
    its seeds and schedule (its width is its own)."""
    budget = spec.budget
    if spec.encoder in SCHEDULES:
        return replace(spec, seeds=budget.seeds)
    return replace(spec, hidden=budget.hidden if spec.encoder == "lstm" else None,
                   seeds=budget.seeds,
                   epochs=round(budget.schedule_scale * PAPER_EPOCHS),
                   schedule_factors=dict(budget.schedule_factors))


def with_overrides(spec: GridSpec, **overrides) -> GridSpec:
    """``spec`` with the given non-None fields replaced (command-line overrides)."""
    return replace(spec, **{k: v for k, v in overrides.items() if v is not None})


@dataclass(frozen=True)
class Budget:
    """Model size, schedule length and seeds of a preset."""

    hidden: int
    schedule_scale: float           # multiplies every epoch count of the paper's schedules
    seeds: tuple[int, ...]
    #: (variant, factor): these variants' schedules are ``factor`` times longer still
    schedule_factors: tuple[tuple[str, float], ...] = ()

    def scale_of(self, variant: str) -> float:
        """The factor on every epoch count of ``variant``'s paper schedule."""
        return self.schedule_scale * dict(self.schedule_factors).get(variant, 1.0)

    def describe_schedule(self) -> str:
        """E.g. ``x1 (APoc, Poc x1.5)``."""
        longer = {}
        for variant, factor in self.schedule_factors:
            longer.setdefault(self.schedule_scale * factor, []).append(variant)
        extra = "; ".join(f"{', '.join(v)} x{scale:g}" for scale, v in longer.items())
        return f"x{self.schedule_scale:g}" + (f" ({extra})" if extra else "")


#: The converged preset's longer schedules: the variants whose runs the longer length made pass
#: the convergence diagnostic on the whole of Table I (docs/REPRODUCTION.md, "The converged
#: preset").
CONVERGED_FACTORS = (("APoc", 1.5), ("Poc", 2.0))
PRESETS = {"converged": Budget(hidden=128, schedule_scale=1.0, seeds=(0,),
                               schedule_factors=CONVERGED_FACTORS),
           "paper": Budget(hidden=1024, schedule_scale=1.0, seeds=(0, 1, 2)),
           "quick": Budget(hidden=128, schedule_scale=0.25, seeds=(0,))}
DEFAULT_PRESET = "converged"


@dataclass(frozen=True)
class Experiment:
    """A product of configurations; combinations that do not exist (GradNorm on one task) are
    skipped."""

    variants: tuple[str, ...]
    weightings: tuple[str, ...] = ("fixed",)
    annotations: tuple[str, ...] = ("revised",)
    directions: tuple[str, ...] = ("bidirectional",)
    seeds: tuple[int, ...] | None = None    # None = the spec's (its budget's) seeds

    def __post_init__(self):
        if self.seeds is not None:
            _require_seeds("experiments.seeds", self.seeds)
        for name, allowed, what in (("variants", VARIANTS, "variant"),
                                    ("weightings", WEIGHTINGS, "weighting"),
                                    ("annotations", ANNOTATION_VERSIONS, "annotation version"),
                                    ("directions", DIRECTIONS, "direction")):
            value = getattr(self, name)
            _require_tuple(f"experiments.{name}", value, f"a non-empty list of {what}s")
            for item in value:
                if not isinstance(item, str) or item not in allowed:
                    raise ValueError(f"unknown {what} {item!r} in experiments.{name}; choose from "
                                     f"{', '.join(allowed)}")


ALL_VARIANTS = tuple(VARIANTS)
#: The paper's evidence: Table I (revised labels), the same on the original labels (Table II and the
#: annotation ablation) and the online models of Table III.
PAPER_EXPERIMENTS = (
    Experiment(ALL_VARIANTS, WEIGHTINGS, ("revised", "original")),
    Experiment(("A", "APc"), ("fixed",), ("revised",), ("forward",)),
)


#: The loops a convolutional encoder's spec may name: none compiled, as its encoder has no LSTM
#: loops (``graph``: the default before ``auto``, in older grid.json, and a stacked grid's).
UNCOMPILED_LOOPS = ("auto", "graph")


@dataclass(frozen=True)
class GridSpec:
    """A whole grid; ``None`` budget fields take the preset's value."""

    preset: str = DEFAULT_PRESET
    task: str = PAPER_TASK          # a built-in task's name or a definition file's path
    data_dir: str = ""              # "" = $JIGSAWS_DIR or the default folder; "synthetic"
    test_users: tuple[str, ...] = ()    # the LOUO folds; () = every user of the release
    seeds: tuple[int, ...] | None = None
    hidden: int | None = None
    epochs: int | None = None
    schedule_factors: dict[str, float] | None = None    # None = the preset's
    precision: str = EncoderConfig.precision
    loops: str = EncoderConfig.loops
    ordinal_loss: str = HeadConfig.ordinal_loss
    relative_rate: str = GradNormConfig.relative_rate
    encoder: str = ENCODERS[0]
    resample_factor: int | None = None     # None = PreprocessConfig's (5 Hz)
    kernel: int | None = None              # ED-TCN's, in samples; None = its reference's
    format: str = DEFAULT_FORMAT           # the recordings': a built-in's name or a file's path
    lowpass: bool | None = None            # None = PreprocessConfig's (on)
    normalise: bool | None = None          # None = PreprocessConfig's (per trial)
    feature_set: str | None = None         # None = DataConfig's (14 features)
    padding: str | None = None             # ED-TCN's; None = "masked"
    head_init: str | None = None           # ED-TCN's heads; None = "uniform"
    inner_validation: int | None = None    # validation users per outer fold; None = outer runs
    #: outer fold -> its own values of ``SELECTABLE`` keys (a nested selection); None = none
    fold_settings: dict[str, dict[str, Any]] | None = None
    plots: str = TrainConfig.plots         # a run's per-trial figures (TrainConfig.plots)
    experiments: tuple[Experiment, ...] = PAPER_EXPERIMENTS

    def __post_init__(self):
        require_choice("preset", self.preset, PRESETS)
        if is_import_path(self.encoder):
            split_path(self.encoder)
        else:
            require_choice("encoder", self.encoder, ENCODERS)
        if self.encoder != "lstm":
            schedule = self.encoder in SCHEDULES          # a TCN's own; a user's: the LSTM's
            lstm_only = [name for name, given in (
                ("hidden", self.hidden is not None),
                ("schedule_factors", schedule and self.schedule_factors is not None),
                ("precision", self.precision != EncoderConfig.precision),
                ("loops", self.loops not in UNCOMPILED_LOOPS)) if given]
            if lstm_only:
                own = ("with its reference's (docs/REPRODUCTION.md)" if schedule
                       else "as its code says (docs/YOUR_METHOD.md)")
                raise ValueError(f"{lstm_only[0]} is an LSTM setting; encoder {self.encoder!r} "
                                 f"trains {own}")
        require_choice("precision", self.precision, PRECISIONS)
        require_choice("loops", self.loops, LOOPS)
        require_choice("ordinal_loss", self.ordinal_loss, ORDINAL_LOSSES)
        require_choice("relative_rate", self.relative_rate, RELATIVE_RATES)
        require_choice("plots", self.plots, PLOT_POINTS)
        if not isinstance(self.task, str):
            raise ValueError(f"task must be a task's name or a definition file (got {self.task!r})")
        self.task_definition()          # a bad task fails here, not in every worker
        if not isinstance(self.format, str) or not self.format:
            raise ValueError(f"format must be a recording format's name or file (got "
                             f"{self.format!r})")
        self.recording_format()         # and so does a bad format
        if not isinstance(self.data_dir, str):
            raise ValueError(f"data_dir must be a folder or \"synthetic\" (got {self.data_dir!r})")
        if self.test_users:
            _require_tuple("test_users", self.test_users, "a list of user letters")
        for user in self.test_users:
            if not isinstance(user, str) or not user:
                raise ValueError(f"test_users must be a list of user letters (got {user!r})")
        if self.seeds is not None:
            _require_seeds("seeds", self.seeds)
        self._check_factor_keys()
        for name in ("hidden", "epochs", "resample_factor", "kernel", "inner_validation"):
            if getattr(self, name) is not None:
                require_number(name, getattr(self, name), integer=True, low=1)
        if self.schedule_factors is not None:
            if not isinstance(self.schedule_factors, dict):
                raise ValueError("schedule_factors must be a table of variant = factor "
                                 f"(got {self.schedule_factors!r})")
            for variant, factor in self.schedule_factors.items():
                require_choice("schedule_factors", variant, VARIANTS)
                require_number(f"schedule_factors.{variant}", factor, low=0, open_low=True)
        _require_tuple("experiments", self.experiments, "a non-empty list of [[experiments]]")
        for experiment in self.experiments:
            if not isinstance(experiment, Experiment):
                raise ValueError(f"experiments must be tables of variants, weightings, "
                                 f"annotations, directions (got {experiment!r})")
        self._check_fold_settings()         # last: each fold's spec is checked whole again

    def _check_factor_keys(self) -> None:
        """The keys of the factor study (module docstring): ED-TCN's only with it."""
        for name, allowed in (("kernel", None), ("padding", PADDINGS),
                              ("head_init", HEAD_INITS)):
            value = getattr(self, name)
            if value is not None and self.encoder != "ed-tcn":
                raise ValueError(f"{name} is ED-TCN's setting (encoder is {self.encoder!r})")
            if value is not None and allowed is not None:
                require_choice(name, value, allowed)
        for name in ("lowpass", "normalise"):
            if getattr(self, name) is not None:
                require_bool(name, getattr(self, name))
        if self.feature_set is not None:
            require_choice("feature_set", self.feature_set, FEATURE_SETS)

    def _check_fold_settings(self) -> None:
        """``fold_settings``: a table per outer fold (among ``test_users`` when given) of
        ``SELECTABLE`` keys, each fold's spec valid as a whole (module docstring)."""
        if self.fold_settings is None:
            return
        if not isinstance(self.fold_settings, dict) or not self.fold_settings:
            raise ValueError("fold_settings must be a table of outer folds, each a table of "
                             f"settings (got {self.fold_settings!r})")
        for fold, entry in self.fold_settings.items():
            if not isinstance(fold, str) or not fold:
                raise ValueError(f"fold_settings must name outer folds by their user (got "
                                 f"{fold!r})")
            if not isinstance(entry, dict):
                raise ValueError(f"fold_settings.{fold} must be a table of settings (got "
                                 f"{entry!r})")
            if not entry:
                raise ValueError(f"fold_settings.{fold} sets nothing: remove it (a fold not "
                                 "listed keeps the spec's settings)")
            if self.test_users and fold not in self.test_users:
                raise ValueError(f"fold_settings.{fold}: {fold} is not among test_users "
                                 f"({', '.join(self.test_users)})")
            unknown = sorted(set(entry) - set(SELECTABLE))
            if unknown:
                raise ValueError(f"fold_settings.{fold}: {', '.join(unknown)} cannot be set per "
                                 f"fold; these can: {', '.join(SELECTABLE)}")
            try:
                self.for_fold(fold)
            except ValueError as error:
                raise ValueError(f"fold_settings.{fold}: {error}") from None

    def for_fold(self, outer: str) -> GridSpec:
        """This spec as outer fold ``outer`` runs it: its ``fold_settings`` entry applied."""
        if not self.fold_settings:
            return self
        return replace(self, **self.fold_settings.get(outer, {}), fold_settings=None)

    @property
    def budget(self) -> Budget:
        base = PRESETS[self.preset]
        scale = base.schedule_scale if self.epochs is None else self.epochs / PAPER_EPOCHS
        factors = (base.schedule_factors if self.schedule_factors is None
                   else tuple(self.schedule_factors.items()))
        return Budget(hidden=base.hidden if self.hidden is None else self.hidden,
                      schedule_scale=scale,
                      seeds=base.seeds if self.seeds is None else self.seeds,
                      schedule_factors=factors)

    @property
    def heads(self) -> HeadConfig:
        return HeadConfig(ordinal_loss=self.ordinal_loss)

    @property
    def gradnorm(self) -> GradNormConfig:
        return GradNormConfig(relative_rate=self.relative_rate)

    def seeds_of(self, experiment: Experiment) -> tuple[int, ...]:
        """The seeds ``experiment`` runs: its own, else the budget's."""
        return self.budget.seeds if experiment.seeds is None else experiment.seeds

    def task_definition(self) -> TaskDefinition:
        return load_task(self.task)

    def recording_format(self) -> RecordingFormat:
        """The format of the recordings ``data_dir`` holds (``format``)."""
        return load_format(self.format)

    def release_dir(self) -> Path:
        """The release folder ``data_dir`` names (the synthetic one written on first use)."""
        if self.data_dir == "synthetic":
            return ensure_release(default_cache_dir(), SynthConfig(), self.task_definition())
        return (Path(self.data_dir) if self.data_dir
                else default_data_dir(self.task_definition().name))

    def with_absolute_paths(self) -> GridSpec:
        """This spec with its data folder, task and format files as absolute paths, so that every
        worker (and grid.json) sees the same ones."""
        task, fmt = (str(Path(name).resolve()) if name.endswith(".toml") else name
                     for name in (self.task, self.format))
        return replace(self, data_dir=str(self.release_dir().resolve()), task=task, format=fmt)


def load_spec(path: Path | str) -> GridSpec:
    """Parse a TOML spec; a file that cannot be read as TOML (missing, a folder, unreadable, not
    UTF-8, invalid) and unknown keys are one-line errors naming the file (and the key)."""
    return spec_from_dict(read_toml(path, "spec"), source=str(path))


def spec_from_dict(raw: dict, source: str = "spec") -> GridSpec:
    """A ``GridSpec`` from plain data (a parsed TOML file, grid.json's ``spec``); every key's type
    and range is checked here, errors naming ``source`` and the key; deprecated keys are read
    under their new names with a warning."""
    raw = dict(raw)
    for old, new in DEPRECATED_KEYS.items():
        if old in raw:
            log.warning("%s: spec key %r is deprecated; use %r", source, old, new)
            if new in raw:
                raise ValueError(f"{source}: both {old!r} and {new!r} given; keep {new!r}")
            raw[new] = raw.pop(old)
    known = {f.name for f in fields(GridSpec)}
    unknown = set(raw) - known
    if unknown:
        raise ValueError(f"{source}: unknown key(s) {', '.join(sorted(unknown))}; "
                         f"known: {', '.join(sorted(known))}")
    values = {k: _tuple(v) for k, v in raw.items() if v is not None}
    try:
        if isinstance(values.get("experiments"), tuple):
            values["experiments"] = tuple(_experiment(e) for e in values["experiments"])
        return GridSpec(**values)
    except ValueError as error:
        raise ValueError(f"{source}: {error}") from None


def _experiment(raw: dict) -> Experiment:
    if not isinstance(raw, dict):
        return raw                          # GridSpec names what is wrong with it
    known = {f.name for f in fields(Experiment)}
    unknown = set(raw) - known
    if unknown:
        raise ValueError(f"unknown experiment key(s) {', '.join(sorted(unknown))}; "
                         f"known: {', '.join(sorted(known))}")
    return Experiment(**{k: _tuple(v) for k, v in raw.items()})
