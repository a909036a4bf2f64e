"""A robot's simulation scene: the converted robot with foot contacts, a floor, optionally a harness, and its
stepping with the PAM forces.

Contact: four spheres under each calcaneus (heel and forefoot, medial and lateral) and one under the toes
(:data:`FOOT_CONTACTS`, right side; the left mirrored in z as Gait2392's left bones are), MuJoCo's soft
contacts with friction 1 against a plane (normal +Y, OpenSim's up). The floor is placed where the lowest sphere
touches it over the given poses. Every coordinate's joint is limited to its range (the robot's hard stops) and
damped by :data:`DAMPING`. The harness is a mocap body ``harness`` welded to the pelvis (MuJoCo's soft
weld, time constant 0.02 s): moving the mocap body moves the pelvis; its constraint force is what the harness
carries.

A step is ``mj_step1`` (positions, tendon lengths), the PAM forces at those lengths (:meth:`PamDrive.apply`),
``mj_step2``, then the pressure lag (:meth:`PamDrive.advance`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import mujoco
import numpy as np

from pamkin.robot.biped import PamRobot
from pamkin.sim.convert import Conversion
from pamkin.sim.mjcf import mjcf_document, safe
from pamkin.sim.pams import TAU, PamDrive

#: Contact spheres of the right foot: (body, centre in the body frame [m], radius [m]).
FOOT_CONTACTS = (("calcn_r", (0.005, 0.0, -0.02), 0.01), ("calcn_r", (0.005, 0.0, 0.025), 0.01),
                 ("calcn_r", (0.17, 0.0, -0.03), 0.01), ("calcn_r", (0.17, 0.0, 0.035), 0.01),
                 ("toes_r", (0.05, 0.0, 0.0), 0.01))


#: Viscous damping of every joint in the scene [N·m·s/rad] (the PAMs' and joints' losses, lumped).
DAMPING = 0.5


def foot_contacts() -> list[tuple[str, tuple[float, float, float], float]]:
    """Both feet's contact spheres (the left mirrored in z)."""
    out = list(FOOT_CONTACTS)
    out += [(b[:-2] + "_l", (p[0], p[1], -p[2]), r) for b, p, r in FOOT_CONTACTS]
    return out


@dataclass
class Scene:
    """A compiled simulation scene.

    Attributes:
        conv: The conversion.
        model, data: MuJoCo's.
        drive: The PAMs.
        qadr, dadr: qpos and dof addresses of :attr:`conv.cmap.joints`.
        floor: Floor height [m] (Y).
        harness: Id of the harness weld (-1 without).
        belt_dof: Dof of the treadmill belt's slide joint (-1: a fixed floor).
        belt_speed: The belt's speed [m/s], towards −x (the walking direction is +x).
    """

    conv: Conversion
    model: mujoco.MjModel
    data: mujoco.MjData
    drive: PamDrive
    qadr: np.ndarray
    dadr: np.ndarray
    floor: float
    harness: int
    belt_dof: int = -1
    belt_speed: float = 0.0
    _prim: tuple | None = field(default=None, init=False, repr=False)

    def foot_geoms(self, side: str) -> np.ndarray:
        """Ids of the contact spheres of one foot (``side`` "r" or "l": calcaneus and toes)."""
        m = self.model
        bodies = (m.body(f"calcn_{side}").id, m.body(f"toes_{side}").id)
        return np.array([g for g in range(m.ngeom) if m.geom(g).name.startswith("contact")
                         and m.geom_bodyid[g] in bodies])

    def foot_gap(self, side: str) -> float:
        """Height of one foot's lowest contact sphere above the floor [m] (positions of the last position
        stage)."""
        g = self.foot_geoms(side)
        return float(np.min(self.data.geom_xpos[g, 1] - self.model.geom_size[g, 0]) - self.floor)

    def mass(self) -> float:
        """The robot's mass [kg] (the world's subtree without the belt)."""
        m = self.model
        belt = m.body_subtreemass[m.body("belt").id] if self.belt_dof >= 0 else 0.0
        return float(m.body_subtreemass[0] - belt)

    def set_pose(self, q: np.ndarray, qdot: np.ndarray | None = None) -> None:
        """Put the robot at coordinates q (tied joints at their polynomial) with coordinate speeds qdot."""
        d = self.data
        d.qpos[self.qadr] = self.conv.cmap.qpos(q)[0]
        d.qvel[:] = 0.0
        if qdot is not None:
            d.qvel[self.dadr] = self.conv.cmap.dqpos_dq(q)[0] @ qdot
        mujoco.mj_forward(self.model, d)

    def _primary(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per coordinate of the drive: its primary joint's index, slope and offset (cached)."""
        if self._prim is None:
            cmap = self.conv.cmap
            rows = [cmap.primary[c] for c in self.drive.coordinates]
            self._prim = tuple(np.array(v) for v in zip(*rows))
        return self._prim

    def positions(self) -> np.ndarray:
        """The independent coordinates of the current state, in the drive's order (``drive.coordinates``)
        [rad, m] (a primary joint's value less its offset, divided by its slope)."""
        idx, a, b = self._primary()
        return (self.data.qpos[self.qadr[idx]] - b) / a

    def speeds(self) -> np.ndarray:
        """Their speeds [rad/s, m/s] (a primary joint's speed divided by its slope)."""
        idx, a, _ = self._primary()
        return self.data.qvel[self.dadr[idx]] / a

    def step(self) -> np.ndarray:
        """One time step with the PAM forces; returns the route tensions used [N]."""
        m, d = self.model, self.data
        if self.belt_dof >= 0:
            d.qvel[self.belt_dof] = -self.belt_speed
        mujoco.mj_step1(m, d)
        T = self.drive.apply(d)
        mujoco.mj_step2(m, d)
        self.drive.advance(m.opt.timestep)
        return T

    def harness_force(self) -> np.ndarray:
        """(3,) force the harness weld exerts on the pelvis, world frame [N] (0 without a harness)."""
        if self.harness < 0:
            return np.zeros(3)
        d = self.data
        rows = np.nonzero((d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & (d.efc_id == self.harness))[0]
        return -d.efc_force[rows[:3]] if len(rows) else np.zeros(3)


def build_scene(conv: Conversion, robot: PamRobot, floor_poses: np.ndarray | None, harness: bool = False,
                tau: float = TAU, timestep: float = 0.001, floor_offset: float = 0.0,
                floor: float | None = None, belt_speed: float | None = None) -> Scene:
    """The scene of a converted robot: foot contacts, a floor at height ``floor`` [m] or, without it, touching
    the lowest foot sphere over ``floor_poses`` (N, n_coordinates), lowered by ``floor_offset`` [m]; a pelvis
    harness when asked; with ``belt_speed`` [m/s] the floor is a treadmill belt running at that speed towards
    −x (its velocity set before every step)."""
    spec = replace(conv.spec, contacts=foot_contacts(), floor=None, harness="pelvis" if harness else None,
                   meshes={}, timestep=timestep, limit_all=True, damping=DAMPING)
    model = mujoco.MjModel.from_xml_string(mjcf_document(conv.model.osim, conv.cmap, spec))
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, safe(j.name)) for j in conv.cmap.joints]
    qadr, dadr = model.jnt_qposadr[ids], model.jnt_dofadr[ids]
    geoms = [g for g in range(model.ngeom) if model.geom(g).name.startswith("contact")]
    low = np.inf if floor is None else float(floor)
    for qpos in conv.cmap.qpos(np.atleast_2d(floor_poses)) if floor is None else ():
        data.qpos[qadr] = qpos
        mujoco.mj_kinematics(model, data)
        low = min(low, float(np.min(data.geom_xpos[geoms, 1] - model.geom_size[geoms, 0])))
    low -= floor_offset
    spec.floor = low
    spec.belt = belt_speed is not None
    model = mujoco.MjModel.from_xml_string(mjcf_document(conv.model.osim, conv.cmap, spec))
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, safe(j.name)) for j in conv.cmap.joints]
    qadr, dadr = model.jnt_qposadr[ids], model.jnt_dofadr[ids]      # the belt's joint, when any, comes first
    weld = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, "harness") if harness else -1
    belt = int(model.jnt_dofadr[model.joint("belt").id]) if spec.belt else -1
    return Scene(conv, model, data, PamDrive(robot, model, conv.cmap, tau=tau), qadr, dadr, low, weld, belt,
                 float(belt_speed or 0.0))
