"""The human model: kinematics (Pinocchio), musculotendon paths and their moment arms (straight and
wrapped, reference numpy code beside the compiled kernels), bones, ranges of motion, muscle groups and the
URDFs generated from an OpenSim model. Lengths in metres, angles in radians, torques in N·m."""

from __future__ import annotations

from pamkin.human.bones import BoneMesh, BoneSet
from pamkin.human.groups import MuscleGroup, load_groups
from pamkin.human.kinematics import Kinematics, KinematicsState
from pamkin.human.model import Model, MuscleState, gait2392, load_osim
from pamkin.human.paths import PathResult, PathSet
from pamkin.human.rom import CoupledLimit, RangeOfMotion, load_rom

__all__ = ["BoneMesh", "BoneSet", "CoupledLimit", "Kinematics", "KinematicsState", "Model", "MuscleGroup", "MuscleState", "PathResult", "PathSet", "RangeOfMotion", "gait2392", "load_groups", "load_osim", "load_rom"]
