"""Named kinematic feature sets: which of the 76 release columns feed the network, and the names
of those columns, by which a recording format (``recording_format``) finds them in other
layouts."""
from __future__ import annotations

from .errors import JigsawsError

# 1-based column ranges of the release (readme.txt): 1-38 master manipulators, 39-57 the first
# patient-side manipulator (PSM1, "slave left"), 58-76 the second (PSM2, "slave right").
_PSM_POSITION = ((39, 40, 41), (58, 59, 60))
_PSM_ROTATION = (tuple(range(42, 51)), tuple(range(61, 70)))
_PSM_LINEAR_VELOCITY = ((51, 52, 53), (70, 71, 72))
_PSM_ANGULAR_VELOCITY = ((54, 55, 56), (73, 74, 75))
_PSM_GRIPPER = ((57,), (76,))


def _per_psm(*groups: tuple[tuple[int, ...], tuple[int, ...]]) -> tuple[int, ...]:
    """Columns of the given groups, PSM1's groups first, then PSM2's."""
    return tuple(c for arm in (0, 1) for group in groups for c in group[arm])


#: Feature set name -> 1-based release columns, in network input order.
FEATURE_SETS: dict[str, tuple[int, ...]] = {
    # The paper's / DiPietro's 14: per PSM position xyz, linear velocity xyz, gripper angle.
    "psm_pos_vel_grip": _per_psm(_PSM_POSITION, _PSM_LINEAR_VELOCITY, _PSM_GRIPPER),
    # The same plus the 3x3 rotation matrices and angular velocities (38 columns).
    "psm_all": _per_psm(_PSM_POSITION, _PSM_ROTATION, _PSM_LINEAR_VELOCITY,
                        _PSM_ANGULAR_VELOCITY, _PSM_GRIPPER),
    # Every column of the release, masters included.
    "all": tuple(range(1, 77)),
}
DEFAULT_FEATURE_SET = "psm_pos_vel_grip"

_ARM_QUANTITIES = (("pos_x", "pos_y", "pos_z")
                   + tuple(f"rot_{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))
                   + ("vel_x", "vel_y", "vel_z", "angvel_x", "angvel_y", "angvel_z", "gripper"))
#: Name of each release column, index = column - 1: per arm (master left / right, PSM1, PSM2)
#: tool-tip position xyz [m], rotation matrix R11..R33, linear velocity xyz, angular velocity xyz
#: and gripper angle, e.g. ``psm1_pos_x`` (column 39).
FEATURE_NAMES: tuple[str, ...] = tuple(f"{arm}_{q}" for arm in ("mtml", "mtmr", "psm1", "psm2")
                                       for q in _ARM_QUANTITIES)


def feature_columns(name: str) -> tuple[int, ...]:
    """0-based column indices of the named feature set."""
    try:
        return tuple(c - 1 for c in FEATURE_SETS[name])
    except KeyError:
        raise JigsawsError(
            f"unknown feature set {name!r}; choose one of {', '.join(FEATURE_SETS)}") from None


def feature_names(name: str) -> tuple[str, ...]:
    """Names (``FEATURE_NAMES``) of the named feature set's columns, in network input order."""
    return tuple(FEATURE_NAMES[c] for c in feature_columns(name))
