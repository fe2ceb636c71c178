"""What a run's ``config.json`` records, without TensorFlow: written and read back.

``variant_record`` is the record a run of a variant writes (``variant_configs`` adds the data
fingerprint, reading the release when none is given; a grid's run folder is checked against it
with the fingerprint the folder records). ``read_run_record`` reads a run folder's record back,
every field checked: the run's ``RunConfig`` (``from_jsonable``: types, ranges, unknown keys),
its variant, weighting, tasks, GradNorm and head settings and data fingerprint; a
``baseline-train`` run, which records no variant, is model A with fixed weights. A bad record is
a ``RunFolderError`` naming the file and the field.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from baseline.config import RunConfig
from jigsaws_tools.dataset import data_fingerprint
from rnn_seg.runs.folder import (CONFIG, FINISHED, ConfigError, RunFolderError, from_jsonable,
                                 read_json)
from rnn_seg.runs.provenance import started_loops
from rnn_seg.runs.segments import SEGMENTS, ran_loops

from .config import WEIGHTINGS, GradNormConfig, HeadConfig, SelectionConfig, Weighting
from .variants import VARIANTS, Variant


def check_weighting(variant: Variant, weighting: Weighting) -> None:
    """Raise ``ValueError`` unless ``variant`` has ``weighting`` (GradNorm needs two tasks)."""
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting must be one of {WEIGHTINGS}, not {weighting!r}")
    if weighting == "gradnorm" and not variant.multitask:
        raise ValueError(f"GradNorm needs two tasks; variant {variant.name} has one")


def variant_extra(variant: Variant, weighting: Weighting, gradnorm: GradNormConfig,
                  heads: HeadConfig, selection: SelectionConfig | None = None) -> dict:
    """What config.json records of a variant beyond its ``RunConfig`` and tasks: its name and
    weighting, the GradNorm settings of a GradNorm run, the head settings of an ordered progress
    head, the nested selection a run of one is part of.

    Args:
        variant: the model variant (``variants.VARIANTS``).
        weighting: ``"fixed"`` or ``"gradnorm"`` (checked against the variant).
        gradnorm: GradNorm's settings, recorded with ``"gradnorm"``.
        heads: the progress heads' settings, recorded for an ordered progress head.
        selection: the settings chosen per outer fold, when the run's were (None: not
            recorded).
    """
    check_weighting(variant, weighting)
    extra = {"variant": variant.name, "weighting": weighting}
    if weighting == "gradnorm":
        extra["gradnorm"] = gradnorm
    if variant.progress == "oc":
        extra["heads"] = heads
    if selection is not None:
        extra["selection"] = selection
    return extra


def variant_record(variant: Variant, weighting: Weighting, config: RunConfig,
                   gradnorm: GradNormConfig, heads: HeadConfig, fingerprint: str | None,
                   selection: SelectionConfig | None = None) -> dict:
    """The record (and settings) of a run of ``variant`` whose data has ``fingerprint``, as
    config.json holds it (``baseline.builder.run_configs``' layout)."""
    return {"run": config, "tasks": list(variant.task_names),
            **variant_extra(variant, weighting, gradnorm, heads, selection),
            "data_fingerprint": fingerprint}


#: Fields of config.json's ``run`` that place a run and that tables read (dotted): present in
#: every record, so never taken from ``RunConfig``'s defaults (an older record may lack a field
#: added since, which then holds its default).
IDENTITY = ("test_user", "train.seed", "data.annotations", "optim.total")
#: What a run of each encoder kind records of its encoder besides (a record without a kind is
#: the LSTM's, written before other encoders existed).
ENCODER_IDENTITY = {"lstm": ("encoder.bidirectional", "encoder.hidden"),
                    "custom": ("encoder.kind", "encoder.path", "encoder.source_sha256")}


@dataclass(frozen=True)
class RunRecord:
    """A run folder's config.json, checked."""

    path: Path                      # the config.json
    saved: dict                     # as parsed
    config: RunConfig
    variant: str
    weighting: Weighting
    tasks: tuple[str, ...]
    gradnorm: GradNormConfig        # as recorded, else the default (a fixed-weight run's)
    heads: HeadConfig               # as recorded, else the default (a run without ordered head)
    fingerprint: str | None         # of the data; None in a record of an early version
    selection: SelectionConfig | None = None    # a nested selection's, else None

    def configs(self) -> dict[str, Any]:
        """The record as ``variant_record`` writes it, for ``rnn_seg.runs.settings``: every
        entry read back as its dataclass (so output-only fields are told apart), a field the
        record's version did not write at its default, and a ``baseline-train`` run's variant
        and weighting, which it leaves unsaid, as model A's with fixed weights."""
        return variant_record(VARIANTS[self.variant], self.weighting, self.config,
                              self.gradnorm, self.heads, self.fingerprint, self.selection)

    def loops(self) -> str:
        """The LSTM loops that trained the run: its finished.json's segments' (one name, or
        ``mixed (fused, graph)`` when its sessions ran on different loops); for a run without
        them (unfinished, or finished before segments were recorded) the loops it started on, as
        its provenance says (``auto`` resolved), else, in a record older than that entry, the
        configured ones."""
        return ran_loops(self.segments()) or started_loops(self.saved) or self.config.encoder.loops

    def segments(self) -> list[dict]:
        """The training segments its finished.json records (``rnn_seg.runs.segments``; none for
        an unfinished run or one finished before they were recorded)."""
        path = self.path.parent / FINISHED
        try:
            segments = read_json(path).get(SEGMENTS) if path.is_file() else None
        except (RunFolderError, AttributeError):
            return []
        return [s for s in segments if isinstance(s, dict)] if isinstance(segments, list) else []

    def classes(self, task: str) -> tuple[str, ...]:
        """The class names of ``task`` (``"gesture"``: the task definition's gestures;
        ``"progress"``: its stages)."""
        definition = self.config.data.task
        return tuple(definition.gestures if task == "gesture" else definition.stage_names)


def variant_configs(variant: Variant, weighting: Weighting, config: RunConfig,
                    gradnorm: GradNormConfig = GradNormConfig(),
                    fingerprint: str | None = None, heads: HeadConfig = HeadConfig(),
                    selection: SelectionConfig | None = None) -> dict:
    """The record (and settings) of a run of ``variant``, as ``variant_trainer`` writes it to
    config.json.

    Args:
        variant: the model variant.
        weighting: ``"fixed"`` or ``"gradnorm"``.
        config: the run's configuration.
        gradnorm: GradNorm's settings (with ``"gradnorm"``).
        fingerprint: the data's (``jigsaws_tools.dataset.data_fingerprint``); None = compute
            it (reading the release's files).
        heads: the progress heads' settings.
        selection: the nested selection the run is part of (None: none).
    """
    return variant_record(variant, weighting, config, gradnorm, heads,
                          fingerprint or data_fingerprint(config.data), selection)


def read_run_config(run_dir: Path) -> tuple[RunConfig, dict]:
    """``(RunConfig, the whole config.json)`` of a run folder (``read_run_record``)."""
    record = read_run_record(run_dir)
    return record.config, record.saved


def read_run_record(run_dir: Path) -> RunRecord:
    """The checked record of the run folder ``run_dir``.

    Raises:
        RunFolderError: one line naming the folder or config.json and the field at fault.
    """
    if not Path(run_dir).is_dir():
        raise RunFolderError(f"{run_dir}: no such run folder")
    path = Path(run_dir) / CONFIG
    if not path.is_file():
        raise RunFolderError(f"{path}: not found; a run folder is what multitask-train, "
                             "baseline-train or multitask-grid wrote (--out)")
    saved = read_json(path)
    if not isinstance(saved, dict) or not isinstance(saved.get("run"), dict):
        shown = saved.get("run") if isinstance(saved, dict) else saved
        raise RunFolderError(f"{path}: run: not a run's configuration (value: "
                             f"{str(shown)[:60]!r})")
    encoder = saved["run"].get("encoder")
    kind = encoder.get("kind", "lstm") if isinstance(encoder, dict) else "lstm"
    kind = kind if isinstance(kind, str) else ""        # a bad kind: from_jsonable names it
    for field in (*IDENTITY, *ENCODER_IDENTITY.get(kind, ("encoder.kind",))):
        if not _holds(saved["run"], field.split(".")):
            raise RunFolderError(f"{path}: run.{field}: missing; every run records it")
    try:
        config = from_jsonable(RunConfig, _upgraded(saved["run"]), f"{path}: run")
        variant = _choice(saved, "variant", VARIANTS, "A")
        weighting = _choice(saved, "weighting", WEIGHTINGS, "fixed")
        check_weighting(VARIANTS[variant], weighting)
        gradnorm = from_jsonable(GradNormConfig, saved.get("gradnorm", {}), f"{path}: gradnorm")
        heads = from_jsonable(HeadConfig, saved.get("heads", {}), f"{path}: heads")
        selection = (from_jsonable(SelectionConfig, saved["selection"], f"{path}: selection")
                     if saved.get("selection") is not None else None)
    except ConfigError as error:
        raise RunFolderError(f"{error.where}: {error.problem} (value: "
                             f"{str(error.value)[:60]!r})") from None
    except ValueError as error:
        raise RunFolderError(f"{path}: {error}") from None
    tasks = saved.get("tasks", list(VARIANTS[variant].task_names))
    if tasks != list(VARIANTS[variant].task_names):
        raise RunFolderError(f"{path}: tasks: {tasks!r} are not variant {variant}'s "
                             f"({list(VARIANTS[variant].task_names)})")
    fingerprint = saved.get("data_fingerprint")
    if fingerprint is not None and not isinstance(fingerprint, str):
        raise RunFolderError(f"{path}: data_fingerprint: not a fingerprint (value: "
                             f"{fingerprint!r})")
    return RunRecord(path, saved, config, variant, weighting, tuple(tasks), gradnorm, heads,
                     fingerprint, selection)


def _holds(tree: dict, keys: list[str]) -> bool:
    """Whether nested dict ``tree`` has the key path ``keys``."""
    for key in keys:
        if not isinstance(tree, dict) or key not in tree:
            return False
        tree = tree[key]
    return True


def _choice(saved: dict, name: str, allowed, default: str) -> str:
    """``saved[name]``, one of ``allowed`` (``default`` when absent); a ``ValueError`` naming
    ``name`` otherwise."""
    value = saved.get(name, default)
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(f"{name}: expected one of {', '.join(allowed)} (value: {value!r})")
    return value


def _upgraded(run: dict) -> dict:
    """A run configuration written by an earlier version, in today's terms: ``train.plots`` was
    a bool (figures at every evaluation point or none)."""
    train = run.get("train", {})
    if isinstance(train, dict) and isinstance(train.get("plots"), bool):
        return {**run, "train": {**train, "plots": "all" if train["plots"] else "none"}}
    return run
