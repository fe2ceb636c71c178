"""A surgical task as data: its name, gesture vocabulary, progress grammar and synthetic grammar.

Definitions are small TOML files; the package ships ``Suturing`` (the paper's task), ``Knot_Tying``
and ``Needle_Passing`` in ``jigsaws_tools/data/tasks/``, and a user passes their own with
``--task-file``. The format, every key checked by ``read_task_file``::

    name = "Suturing"               # as in the release's file names: Suturing_B001.txt,
                                    # meta_file_Suturing.txt
    summary = "..."                 # optional, one line

    [gestures]                      # the vocabulary: class index = position in this table
    G1 = "Reaching for needle with right hand"
    G2 = "Positioning needle"

    [progress]                      # essential gestures define stages 0..K-1 in order (K >= 2)
    stages = [{ name = "reach", gestures = ["G1", "G5"] }, { name = "position", gestures = ["G2"] }]
    adjustments = ["G4", "G8"]      # every other gesture: takes the stage of the next essential one

    [synthetic]                     # optional: what `jigsaws-tools synth` generates
    cycles = [3, 5]                 # repetitions of `cycle` per trial, uniform in [min, max]
    lead_in = "G1"                  # unlabelled motion before / after the segments looks like these
    tail = "G11"
    opening = [{ gesture = "G1" }, { gesture = "G5", p = 0.5 }]
    cycle = [{ gesture = ["G4", "G8"], weights = [0.5, 0.5], p = 0.5, cycles = "later" }, ...]
    closing = [{ gesture = "G11" }]

    [synthetic.gestures]            # every gesture a step can produce
    G1 = { frames = [45, 110] }     # segment length in 30 Hz frames, from [min, max)
    G5 = { frames = [40, 90], like = "G1" }     # motion blended with G1's (hard to tell apart)

A step produces one of its gestures (with the given weights: positive, at most 1e6; uniform by
default), with probability ``p`` (default 1); ``cycles = "first"`` / ``"later"`` restricts a cycle
step to the first cycle / to the others. The adjustment rule is the paper's
(``jigsaws_tools.progress``).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from .errors import DefinitionError
from .toml_files import (builtin_names, find_definition, known_keys, read_definition, table,
                         typed)

#: The paper's task, the default wherever a task can be omitted.
PAPER_TASK = "Suturing"
CYCLE_SCOPES = ("every", "first", "later")
#: The largest weight of a synthetic step's gesture: relative weights, bounded so that their sum,
#: which normalises them, stays finite.
MAX_WEIGHT = 1e6
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]*$")
_GESTURE = re.compile(r"^\S+$")


@dataclass(frozen=True)
class SynthStep:
    """One step of a synthetic gesture sequence (see the module docstring)."""

    gestures: tuple[str, ...]
    weights: tuple[float, ...]      # one per gesture, in (0, MAX_WEIGHT]; normalised when sampled
    p: float = 1.0
    cycles: str = "every"


@dataclass(frozen=True)
class SynthGesture:
    """Synthetic motion of one gesture: segment length ``[min_frames, max_frames)`` at 30 Hz."""

    gesture: str
    min_frames: int
    max_frames: int
    like: str = ""                  # a gesture whose motion prototype this one's is blended with


@dataclass(frozen=True)
class SynthGrammar:
    """How the synthetic generator writes a trial of the task."""

    cycles: tuple[int, int]
    lead_in: str
    tail: str
    opening: tuple[SynthStep, ...]
    cycle: tuple[SynthStep, ...]
    closing: tuple[SynthStep, ...]
    gestures: tuple[SynthGesture, ...]

    def timing(self, gesture: str) -> SynthGesture:
        return next(g for g in self.gestures if g.gesture == gesture)


@dataclass(frozen=True)
class TaskDefinition:
    """A task: file-name prefix, gesture classes, progress stages and (optionally) its synthetic
    grammar. Construction checks every invariant (``DefinitionError`` naming the key)."""

    name: str
    gestures: tuple[str, ...]
    stages: tuple[tuple[str, ...], ...]         # essential gestures of stage 0, 1, ...
    adjustments: tuple[str, ...]
    stage_names: tuple[str, ...]
    descriptions: tuple[str, ...] = field(default=(), repr=False)     # one per gesture
    summary: str = field(default="", repr=False)
    synthetic: SynthGrammar | None = field(default=None, repr=False)

    def __post_init__(self):
        _check_task(self)

    @property
    def num_gestures(self) -> int:
        return len(self.gestures)

    @property
    def num_stages(self) -> int:
        return len(self.stages)

    @cached_property
    def gesture_index(self) -> dict[str, int]:
        """Gesture name -> class index."""
        return {name: i for i, name in enumerate(self.gestures)}

    @cached_property
    def stage_of_class(self) -> np.ndarray:
        """``[num_gestures]`` int64: each class's stage, -1 for adjustments."""
        stages = np.full(self.num_gestures, -1, dtype=np.int64)
        for stage, names in enumerate(self.stages):
            stages[[self.gesture_index[n] for n in names]] = stage
        return stages

    def describe(self) -> str:
        """Multi-line summary: vocabulary with descriptions, then the progress grammar."""
        lines = [f"task {self.name}: {self.summary}".rstrip(": "), "gestures:"]
        lines += [f"  {i:2d} {g:>4}  {d}" for i, (g, d) in
                  enumerate(zip(self.gestures, self.descriptions or [""] * self.num_gestures))]
        lines.append("progress stages:")
        lines += [f"  {k} {name}: {', '.join(names)}"
                  for k, (name, names) in enumerate(zip(self.stage_names, self.stages))]
        lines.append(f"adjustments (stage of the next essential gesture): "
                     f"{', '.join(self.adjustments) or 'none'}")
        return "\n".join(lines)


def builtin_task_names() -> tuple[str, ...]:
    """Names of the definitions shipped with the package."""
    return builtin_names("tasks")


def load_task(task: str | Path | TaskDefinition) -> TaskDefinition:
    """A built-in task by name, a definition file by path (``*.toml``), or ``task`` itself."""
    if isinstance(task, TaskDefinition):
        return task
    return find_definition(task, "tasks", "task", read_task_file)


def read_task_file(path: Path | str) -> TaskDefinition:
    """Parse and check a task definition file; errors name the file, the key and the value."""
    return read_definition(path, "task definition", _task_from_toml)


# -- parsing: TOML tables -> dataclasses, with the key of every value ------------------------------
def _task_from_toml(raw: dict) -> TaskDefinition:
    known_keys(raw, "", ("name", "summary", "gestures", "progress", "synthetic"),
                required=("name", "gestures", "progress"))
    gestures = table(raw["gestures"], "gestures")
    for key, value in gestures.items():
        typed(value, f"gestures.{key}", str, "a description string")
    progress = table(raw["progress"], "progress")
    known_keys(progress, "progress", ("stages", "adjustments"), required=("stages",))
    stages = _list(progress["stages"], "progress.stages")
    for k, stage in enumerate(stages):
        known_keys(table(stage, f"progress.stages[{k}]"), f"progress.stages[{k}]",
                    ("name", "gestures"), required=("gestures",))
    return TaskDefinition(
        name=typed(raw["name"], "name", str, "a string"),
        gestures=tuple(gestures),
        stages=tuple(_names(s["gestures"], f"progress.stages[{k}].gestures")
                     for k, s in enumerate(stages)),
        adjustments=_names(progress.get("adjustments", []), "progress.adjustments", empty=True),
        stage_names=tuple(typed(s.get("name", f"stage {k}"), f"progress.stages[{k}].name", str,
                                 "a string") for k, s in enumerate(stages)),
        descriptions=tuple(gestures.values()),
        summary=typed(raw.get("summary", ""), "summary", str, "a string"),
        synthetic=_synthetic_from_toml(raw["synthetic"]) if "synthetic" in raw else None)


def _synthetic_from_toml(raw: Any) -> SynthGrammar:
    raw = table(raw, "synthetic")
    known_keys(raw, "synthetic", ("cycles", "lead_in", "tail", "opening", "cycle", "closing",
                                   "gestures"),
                required=("cycles", "lead_in", "tail", "cycle", "gestures"))
    timings = table(raw["gestures"], "synthetic.gestures")
    return SynthGrammar(
        cycles=_int_pair(raw["cycles"], "synthetic.cycles"),
        lead_in=typed(raw["lead_in"], "synthetic.lead_in", str, "a gesture name"),
        tail=typed(raw["tail"], "synthetic.tail", str, "a gesture name"),
        opening=_steps(raw.get("opening", []), "synthetic.opening"),
        cycle=_steps(raw["cycle"], "synthetic.cycle"),
        closing=_steps(raw.get("closing", []), "synthetic.closing"),
        gestures=tuple(_timing(name, value, f"synthetic.gestures.{name}")
                       for name, value in timings.items()))


def _steps(raw: Any, key: str) -> tuple[SynthStep, ...]:
    steps = []
    for i, step in enumerate(_list(raw, key)):
        where = f"{key}[{i}]"
        known_keys(table(step, where), where, ("gesture", "weights", "p", "cycles"),
                    required=("gesture",))
        value = step["gesture"]
        gestures = (_names(value, f"{where}.gesture") if isinstance(value, list)
                    else (typed(value, f"{where}.gesture", str, "a gesture name or a list"),))
        weights = step.get("weights", [1.0] * len(gestures))
        weights = tuple(_number(w, f"{where}.weights") for w in _list(weights, f"{where}.weights"))
        steps.append(SynthStep(gestures, weights, _number(step.get("p", 1.0), f"{where}.p"),
                               typed(step.get("cycles", "every"), f"{where}.cycles", str,
                                      f"one of {', '.join(CYCLE_SCOPES)}")))
    return tuple(steps)


def _timing(name: str, raw: Any, key: str) -> SynthGesture:
    known_keys(table(raw, key), key, ("frames", "like"), required=("frames",))
    low, high = _int_pair(raw["frames"], f"{key}.frames")
    return SynthGesture(name, low, high, typed(raw.get("like", ""), f"{key}.like", str,
                                                "a gesture name"))


def _list(value: Any, key: str) -> list:
    return typed(value, key, list, "a list")


def _names(value: Any, key: str, empty: bool = False) -> tuple[str, ...]:
    names = _list(value, key)
    if not names and not empty:
        raise DefinitionError("", key, value, "expected at least one gesture")
    return tuple(typed(n, key, str, "a list of gesture names") for n in names)


def _number(value: Any, key: str) -> float:
    number = float(typed(value, key, (int, float), "a number"))
    if not math.isfinite(number):           # TOML allows nan and inf
        raise DefinitionError("", key, value, "expected a finite number")
    return number


def _int_pair(value: Any, key: str) -> tuple[int, int]:
    if not (isinstance(value, list) and len(value) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
        raise DefinitionError("", key, value, "expected [min, max], two integers")
    return value[0], value[1]


# -- invariants ------------------------------------------------------------------------------
def _check_task(task: TaskDefinition) -> None:
    """Raise ``DefinitionError`` (key, value, problem) at the first broken invariant."""
    if not _NAME.match(task.name):
        raise DefinitionError("", "name", task.name, "a task name is letters, digits, '_' or "
                              "'-' (it prefixes the release's file names)")
    if not task.gestures:
        raise DefinitionError("", "gestures", {}, "the vocabulary needs at least one gesture")
    for g in task.gestures:
        if not _GESTURE.match(g):
            raise DefinitionError("", f"gestures.{g}", g, "gesture names cannot hold whitespace")
    if task.descriptions and len(task.descriptions) != task.num_gestures:
        raise DefinitionError("", "gestures", task.descriptions, "one description per gesture")
    if len(task.stages) < 2:
        raise DefinitionError("", "progress.stages", task.stages,
                              "progress needs at least two stages")
    if len(task.stage_names) != len(task.stages):
        raise DefinitionError("", "progress.stages", task.stage_names, "one name per stage")
    if len(set(task.stage_names)) != len(task.stage_names):
        raise DefinitionError("", "progress.stages", task.stage_names, "stage names must differ "
                              "(they name the progress classes)")
    places = [(g, f"progress.stages[{k}].gestures") for k, s in enumerate(task.stages) for g in s]
    places += [(g, "progress.adjustments") for g in task.adjustments]
    seen: dict[str, str] = {}
    for g, key in places:
        _check_known(task, g, key)
        if g in seen:
            raise DefinitionError("", key, g, f"gesture already listed in {seen[g]}; each gesture "
                                  "is in one stage or an adjustment")
        seen[g] = key
    missing = [g for g in task.gestures if g not in seen]
    if missing:
        raise DefinitionError("", "progress", missing, "every gesture of the vocabulary must be in "
                              "a stage or in progress.adjustments")
    if task.synthetic is not None:
        _check_synthetic(task, task.synthetic)


def _check_synthetic(task: TaskDefinition, grammar: SynthGrammar) -> None:
    low, high = grammar.cycles
    if not 1 <= low <= high:
        raise DefinitionError("", "synthetic.cycles", [low, high], "need 1 <= min <= max")
    _check_known(task, grammar.lead_in, "synthetic.lead_in")
    _check_known(task, grammar.tail, "synthetic.tail")
    timed = {t.gesture: t for t in grammar.gestures}
    for t in grammar.gestures:
        key = f"synthetic.gestures.{t.gesture}"
        _check_known(task, t.gesture, key)
        if not 1 <= t.min_frames < t.max_frames:
            raise DefinitionError("", f"{key}.frames", [t.min_frames, t.max_frames],
                                  "need 1 <= min < max (frames at 30 Hz, max excluded)")
        if t.like:
            _check_known(task, t.like, f"{key}.like")
            if t.like == t.gesture or timed.get(t.like, SynthGesture("", 1, 2)).like:
                raise DefinitionError("", f"{key}.like", t.like, "must name another gesture "
                                      "whose own motion is not blended (no chains)")
    always = False
    for part in ("opening", "cycle", "closing"):
        for i, step in enumerate(getattr(grammar, part)):
            key = f"synthetic.{part}[{i}]"
            for g in step.gestures:
                _check_known(task, g, f"{key}.gesture")
                if g not in timed:
                    raise DefinitionError("", f"synthetic.gestures.{g}", None,
                                          f"{key} can produce {g}: give its frames")
            if (len(step.weights) != len(step.gestures) or min(step.weights) <= 0
                    or max(step.weights) > MAX_WEIGHT):
                raise DefinitionError("", f"{key}.weights", list(step.weights),
                                      f"one positive weight per gesture, at most {MAX_WEIGHT:g} "
                                      "(relative weights: their sum must stay finite)")
            if not 0 < step.p <= 1:
                raise DefinitionError("", f"{key}.p", step.p, "a probability in (0, 1]")
            if step.cycles not in CYCLE_SCOPES or (part != "cycle" and step.cycles != "every"):
                raise DefinitionError("", f"{key}.cycles", step.cycles,
                                      f"one of {', '.join(CYCLE_SCOPES)}, in synthetic.cycle only")
            always |= step.p == 1 and step.cycles == "every"
    if not always:
        raise DefinitionError("", "synthetic", None, "some step must always happen (p = 1, every "
                              "cycle), or a trial could have no labelled segment")


def _check_known(task: TaskDefinition, gesture: str, key: str) -> None:
    if gesture not in task.gesture_index:
        raise DefinitionError("", key, gesture, f"not a gesture of the vocabulary "
                              f"({', '.join(task.gestures)})")


#: The paper's task, read from its shipped definition.
SUTURING = load_task(PAPER_TASK)
