"""The PAM robot: Festo fluidic-muscle force models and sizing, design files (routes, sizes, operating
point), the robot built on Gait2392's bone frames, PAM bodies on their routes, and the routing elements
(rollers, detours, eyelets); export of a design as an OpenSim model. SI units (m, N, Pa, rad)."""

from __future__ import annotations

from pamkin.robot.biped import (
    PamRobot,
    PamState,
    design_robot,
    robot_skeleton,
    thesis_robot,
)
from pamkin.robot.design import Design, Pam, load_design, save_design
from pamkin.robot.festo import FestoForceModel, FestoModel
from pamkin.robot.osim_export import design_to_osim
from pamkin.robot.rollers import Roller
from pamkin.robot.sizing import Sizing, size_pam, thesis_size

__all__ = ["Design", "FestoForceModel", "FestoModel", "Pam", "PamRobot", "PamState", "Roller", "Sizing", "design_robot", "design_to_osim", "load_design", "robot_skeleton", "save_design", "size_pam", "thesis_robot", "thesis_size"]
