"""Convert a pamkin model (an OpenSim model or a PAM robot design) to a MuJoCo model, and write it.

:func:`convert_model` / :func:`convert_robot` build the joints (:mod:`pamkin.sim.joints`), the tendons
(:mod:`pamkin.sim.tendons`, choices fitted on :data:`pamkin.sim.tendons.FIT_POSES` poses of their own seed) and
the bone meshes; :func:`pamkin.sim.files.write_conversion` writes them.
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from pamkin._resources import MESH_DIR
from pamkin.errors import RangeWarning
from pamkin.human.meshes import find_geometry_dir, mesh_files, stl_name
from pamkin.human.model import Model
from pamkin.robot.biped import PamRobot
from pamkin.robot.rollers import path_wraps
from pamkin.sim.joints import CoordinateMap
from pamkin.sim.mjcf import MjcfSpec, inertia_issues, mjcf_document, safe
from pamkin.sim.tendons import FIT_POSES, FIT_SEED, PathChoice, PathSpec, choose

#: Reference geometry: q (N, n_coordinates) -> (lengths (N, M) [m], moment arms (N, M, n_coordinates) [m]).
Reference = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass
class Conversion:
    """A converted model.

    Attributes:
        name: Model name.
        model: The pamkin model (the robot's skeleton for a design).
        cmap: Coordinates ↔ MuJoCo joints.
        spec: Sites, geoms, tendons, meshes.
        choices: Per path, the construct chosen and its error on the fit poses.
        paths: Path (tendon) names, in order.
        reference: pamkin's lengths and moment arms of the paths.
        meshes: ``{relative path: STL bytes}``.
        seconds: Conversion time [s].
    """

    name: str
    model: Model
    cmap: CoordinateMap
    spec: MjcfSpec
    choices: list[PathChoice]
    paths: list[str]
    reference: Reference
    meshes: dict[str, bytes]
    seconds: float

    def mjcf(self) -> str:
        """The MJCF text (meshes referenced as ``meshes/<bone>.stl`` beside it)."""
        return mjcf_document(self.model.osim, self.cmap, self.spec)

    def compile(self, with_meshes: bool = False) -> mujoco.MjModel:
        """The compiled MuJoCo model (without the meshes unless asked: they are visuals only)."""
        spec = self.spec if with_meshes else _without_meshes(self.spec)
        xml = mjcf_document(self.model.osim, self.cmap, spec)
        if not with_meshes:
            return mujoco.MjModel.from_xml_string(xml)
        return mujoco.MjModel.from_xml_string(xml, {k: v for k, v in self.meshes.items()})

    def summary(self) -> dict:
        """Joint polynomials (with their largest deviation) and path choices, JSON-ready."""
        ties = [{"joint": j.name, "coordinate": j.coordinate, "polycoef": j.poly.tolist(), "max_error": j.error,
                 **({"of_joint": j.source} if j.source else {}),
                 **({"composed_terms": j.terms, "max_slope_error": j.slope_error} if j.terms else {})}
                for j in self.cmap.joints if not j.primary]
        return {"model": self.name, "seconds": self.seconds, "couplings": self.cmap.couplings,
                "inertia_adjusted": inertia_issues(self.model.osim),
                "primary_joints": {c: {"joint": self.cmap.joints[i].name, "slope": a, "intercept": b}
                                   for c, (i, a, b) in self.cmap.primary.items()},
                "tied_joints": ties,
                "paths": [{"path": c.name, "conditional_points": c.conditional, "wrap_geoms": c.wraps,
                           "wraps_left_out": c.omitted, "fit_max_length_error_m": c.fit_error,
                           **({"conditional_steps": c.steps} if c.steps else {})}
                          for c in self.choices]}


def _without_meshes(spec: MjcfSpec) -> MjcfSpec:
    return replace(spec, meshes={})


def convert_model(model: Model, name: str | None = None, geometry: str | os.PathLike | None = None,
                  fit_poses: int = FIT_POSES, couplings: str = "composed") -> Conversion:
    """Convert a pamkin :class:`~pamkin.human.model.Model` (its muscles as tendons).

    Args:
        model: The model.
        name: Model name (default: the model's).
        geometry: Folder of the ``.vtp`` bone meshes (default: found beside the model file, else pamkin's
            built-in bone meshes where their names match).
        fit_poses: Poses the path constructs are chosen on.
        couplings: ``"composed"`` (auxiliary joint chains: splines fitted in a rich basis, conditional points
            as sharp steps) or ``"quartic"`` (one degree-4 joint equality per tie; conditional points as
            always/never/small wrap geoms); :mod:`pamkin.sim.couplings`.
    """
    t0 = time.perf_counter()
    paths = [PathSpec(m.name, m.points, m.wraps) for m in model.osim.muscles]

    def reference(q):
        res = model.path_result(q)
        return res.lengths, res.dense_moment_arms(len(model.coordinates))

    return _convert(model, name or model.osim.name, paths, reference, lambda q: model.lengths(q), geometry,
                    fit_poses, t0, couplings)


def convert_robot(robot: PamRobot, name: str | None = None, fit_poses: int = FIT_POSES,
                  couplings: str = "composed") -> Conversion:
    """Convert a PAM robot (both sides): the skeleton's bodies and joints, each PAM route a tendon named
    after its column (``pam01_r`` ...; forces: :mod:`pamkin.sim.pams`), rollers as cylinder wrap geoms
    (``couplings``: as :func:`convert_model`)."""
    t0 = time.perf_counter()
    paths = []
    for k, (nm, pts, rs) in enumerate(zip(robot.names, robot.routes, robot.rollers)):
        segs = [f"{a.name}->{b.name}" for a, b in zip(pts[:-1], pts[1:])]
        paths.append(PathSpec(nm, pts, tuple(path_wraps(segs, rs, nm)) if rs else ()))

    def reference(q):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RangeWarning)
            st = robot.evaluate(q)
        return st.lengths, st.moment_arms

    return _convert(robot.model, name or robot.design.name, paths, reference, lambda q: reference(q)[0], None,
                    fit_poses, t0, couplings)


def _convert(model: Model, name: str, paths: list[PathSpec], reference: Reference, lengths, geometry,
             fit_poses: int, t0: float, couplings: str) -> Conversion:
    cmap = CoordinateMap(model.osim, couplings)
    spec = MjcfSpec(name)
    q_fit = model.random_q(fit_poses, seed=FIT_SEED)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        choices = choose(model.osim, cmap, paths, lengths, q_fit, spec)
    meshes = _meshes(model, spec, geometry)
    conv = Conversion(name, model, cmap, spec, choices, [p.name for p in paths], reference, meshes, 0.0)
    conv.compile()                         # MuJoCo accepts it
    conv.seconds = time.perf_counter() - t0
    return conv


def _meshes(model: Model, spec: MjcfSpec, geometry) -> dict[str, bytes]:
    """Bone meshes as visual geoms of ``spec`` and their STL bytes."""
    folder = geometry if geometry is not None else find_geometry_dir(model.osim.path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        files = mesh_files(model.osim, folder) if folder is not None else {}
    if not files:                         # pamkin's built-in bone meshes (Gait2392's)
        for b in model.osim.bodies:
            for g in b.meshes:
                src = MESH_DIR / Path(stl_name(g.mesh_file)).name
                if src.is_file():
                    files[stl_name(g.mesh_file)] = src.read_bytes()
    for b in model.osim.bodies:
        for g in b.meshes:
            rel = stl_name(g.mesh_file)
            if rel in files:
                T = g.frame.transform()
                spec.meshes.setdefault(b.name, []).append((safe(Path(rel).stem), rel, T[:3, :3], T[:3, 3],
                                                           tuple(g.scale_factors)))
    return files
