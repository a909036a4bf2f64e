"""The :class:`Model`: an imported OpenSim model with kinematics, muscle paths and forces."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .kinematics import ConfigLike, Kinematics, KinematicsState
from .osim import OsimModel, load_osim_file
from .paths import PathResult, PathSet
from .urdf_build import GAIT2392_DATA, GAIT2392_URDF, cached_urdf, load_model_data


class Model:
    """An OpenSim model in pamkin: import → Xacro → URDF → Pinocchio.

    Build it with :func:`load_osim`. Configurations ``q`` are (N, n_coordinates)
    arrays in :attr:`coordinates` order (or (n_coordinates,), or a mapping from
    coordinate names), in OpenSim units (radians, metres).

    Attributes:
        osim: The imported model description.
        urdf_path: The generated URDF.
        kinematics: Batched kinematics (Pinocchio-backed).
    """

    def __init__(self, osim: OsimModel, urdf_path: Path) -> None:
        import pinocchio as pin  # noqa: PLC0415

        self.osim = osim
        self.urdf_path = Path(urdf_path)
        self.pin_model = pin.buildModelFromUrdf(str(urdf_path))
        self.kinematics = Kinematics(osim, self.pin_model)
        self.paths = PathSet(self.kinematics, [m.name for m in osim.muscles],
                             [m.points for m in osim.muscles])

    @property
    def coordinates(self) -> list[str]:
        """OpenSim coordinate names in model (CoordinateSet) order."""
        return list(self.kinematics.coordinates)

    @property
    def bodies(self) -> list[str]:
        """Body names (ground excluded) in model order."""
        return list(self.kinematics.bodies)

    @property
    def coordinate_ranges(self) -> np.ndarray:
        """(n_coordinates, 2) coordinate ranges [rad or m]."""
        return self.kinematics.ranges.copy()

    @property
    def default_q(self) -> np.ndarray:
        """(n_coordinates,) default coordinate values."""
        return self.kinematics.defaults.copy()

    def forward(self, q: ConfigLike) -> KinematicsState:
        """Evaluate kinematics of a batch of configurations once (see :class:`KinematicsState`)."""
        return self.kinematics.forward(q)

    def body_transforms(self, q: ConfigLike) -> dict[str, np.ndarray]:
        """Body frame → ground homogeneous transforms, ``{body: (N, 4, 4)}`` [m]."""
        return self.kinematics.body_transforms(q)

    def point_jacobian(self, q: ConfigLike, body: str, point) -> np.ndarray:
        """Jacobian (N, 3, n_coordinates) of a point fixed in ``body`` w.r.t. the coordinates."""
        return self.kinematics.point_jacobian(q, body, point)

    @property
    def muscles(self) -> list[str]:
        """Muscle names in ForceSet order."""
        return list(self.paths.names)

    def path_result(self, q: ConfigLike, moment_arms: bool = True) -> PathResult:
        """Lengths and sparse moment arms (only spanned muscle × coordinate pairs)."""
        return self.paths.evaluate(self.kinematics.forward(q), moment_arms=moment_arms)

    def lengths(self, q: ConfigLike) -> np.ndarray:
        """Musculotendon path lengths (N, n_muscles) [m]."""
        return self.path_result(q, moment_arms=False).lengths

    def moment_arms(self, q: ConfigLike) -> np.ndarray:
        """Moment arms −∂L/∂q (N, n_muscles, n_coordinates) [m; m/m for translations]."""
        return self.path_result(q).dense_moment_arms(len(self.coordinates))

    def random_q(self, n: int, seed: int | None = 0) -> np.ndarray:
        """``n`` configurations uniform over every coordinate's range (fixed seed by default)."""
        rng = np.random.default_rng(seed)
        lo, hi = self.kinematics.ranges.T
        return lo + (hi - lo) * rng.random((n, len(lo)))


def load_osim(path: str | os.PathLike) -> Model:
    """Load an OpenSim ``.osim`` model: import → Xacro → URDF (cached) → Pinocchio.

    Args:
        path: The ``.osim`` file (OpenSim 4.x format).

    Raises:
        pamkin.errors.OsimError: The file is malformed.
        pamkin.errors.UnsupportedFeatureError: It uses features pamkin does not implement.
    """
    osim = load_osim_file(path)
    return Model(osim, cached_urdf(osim))


def gait2392() -> Model:
    """The built-in Gait2392 model (project data ``robot/data/gait2392.yaml``, ``urdf/gait2392.urdf``).

    Needs no OpenSim files: the data file holds the model imported from OpenSim's
    ``gait2392_thelen2003muscle.osim`` (Delp et al., CC BY 3.0).
    """
    return Model(load_model_data(GAIT2392_DATA), GAIT2392_URDF)
