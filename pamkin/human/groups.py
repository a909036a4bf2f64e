"""Muscle groups: the thesis's functional groups and the 27 robot-actuator groups.

Defined in ``robot/data/muscle_groups.yaml`` (right-side names); the left side is the
mirror image (suffix ``_l``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import yaml

from pamkin._resources import data_file
from pamkin.errors import DataFileError
from pamkin.yamlio import safe_load

GROUPS_FILE = data_file("muscle_groups.yaml")


@dataclass(frozen=True)
class MuscleGroup:
    """A named set of muscles.

    Attributes:
        key: Unique key (``uni_hip_r``, ``act04_r``).
        label: Human-readable name.
        muscles: Muscle names.
        side: ``r`` or ``l``.
        kind: ``thesis`` or ``actuator``.
        primary_coordinate: For actuator groups, the coordinate it mainly drives.
        secondary_coordinates: For actuator groups, further coordinates compared.
        actuator_id: For actuator groups, the robot actuator number (1-27).
    """

    key: str
    label: str
    muscles: tuple[str, ...]
    side: str
    kind: str
    primary_coordinate: str = ""
    secondary_coordinates: tuple[str, ...] = ()
    actuator_id: int = 0


def _side(name: str, side: str) -> str:
    if name.endswith("_r"):
        return name[:-2] + "_" + side
    if name.startswith("lumbar"):
        return name
    return f"{name}_{side}"


def load_groups(path: str | Path = GROUPS_FILE, sides: tuple[str, ...] = ("r", "l")) -> list[MuscleGroup]:
    """Every thesis group and actuator group for the given sides."""
    path = Path(path)
    try:
        data = safe_load(path.read_text())
        out = []
        for side in sides:
            for g, members in data["thesis_groups"].items():
                out.append(MuscleGroup(f"{g}_{side}", f"{g} ({side})",
                                       tuple(f"{m}_{side}" for m in members), side, "thesis"))
            for a in data["actuators"]:
                out.append(MuscleGroup(
                    f"act{int(a['id']):02d}_{side}", f"{a['id']} {a['name']} ({side})",
                    tuple(_side(m, side) for m in a["human_muscles"]), side, "actuator",
                    _side(a["primary_coordinate"], side),
                    tuple(_side(c, side) for c in a["secondary_coordinates"]), int(a["id"])))
        return out
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as e:
        raise DataFileError(str(path), f"malformed muscle groups file: {type(e).__name__}: {e}") from None
