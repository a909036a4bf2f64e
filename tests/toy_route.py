"""The two-body toy of the bone-mesh tests: one pin joint, block-shaped bones, a two-point route fitted to
its own torque (shared by test_bone_cuts and test_bracket)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

import pamkin
from pamkin.robot.design import Design, Pam
from pamkin.optimize.config import FAST_FIT, RunConfig
from pamkin.optimize.samples import actuator_data
from pamkin.opensim.model_file import PathPoint
from pamkin.robot.biped import PamRobot
from pamkin.human.rom import RangeOfMotion

DATA = Path(__file__).parent / "data"
#: The blocks the route's points stand 30 mm off: the origin's on "base", the insertion's on "arm".
ORIGIN_BLOCK = ((0.0, -0.08, -0.02), (0.02, -0.02, 0.02))
INSERTION_BLOCK = ((0.0, -0.15, -0.02), (0.02, -0.09, 0.02))


def box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of the axis-aligned box ``lo``..``hi`` [m]."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(extents=hi - lo)
    m.apply_translation((lo + hi) / 2)
    return m.vertices, m.faces


def toy_problem(region: float):
    """``(model, seed, cfg, data, seed_points, regions)`` of the toy route: seed PAM (10 mm, 0.25 m) whose
    own torque over the angle range ±0.2 rad is the target, points free by ``region`` in x and y [m]."""
    model = pamkin.load_osim(DATA / "two_body.osim")
    rom = RangeOfMotion({"angle": (-0.2, 0.2)})
    route = (PathPoint("o", "base", (0.05, -0.05, 0.0)), PathPoint("i", "arm", (0.05, -0.12, 0.0)))
    seed = Pam(1, "toy", (), "angle", (), 10, 1, 0.25, 0.0, route)   # the target: its own torque
    seed_robot = PamRobot(Design("seed", (seed,)), model, sides=("r",))

    def target(q):
        return seed_robot.evaluate(q).torques[:, 0, :]

    cfg = RunConfig().replace({**FAST_FIT, "bone_rounds.enabled": True, "weights.regularization": 0.0, "limits.bone_clearance": False, "samples.primary": 21, "regions": {"1": [region, region, 0.0]}})
    data = actuator_data(seed, model, rom, cfg, 0.0125, target=target)
    seed_points = [np.array(p.location) for p in seed.points]
    regions = [np.array(cfg.region(1, p.name)) for p in seed.points]
    return model, rom, seed, cfg, data, seed_points, regions
