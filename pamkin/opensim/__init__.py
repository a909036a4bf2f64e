"""Reading OpenSim files: ``.osim`` models, their scalar functions and wrap objects, ``.mot``/``.sto``
storage files and ``.vtp`` bone meshes. Nothing here depends on the rest of pamkin (errors aside)."""

from __future__ import annotations

from pamkin.opensim.functions import (
    Constant,
    LinearFunction,
    MultiplierFunction,
    PolynomialFunction,
    ScalarFunction,
    SimmSpline,
)
from pamkin.opensim.model_file import (
    Body,
    ConditionalPathPoint,
    Coordinate,
    Joint,
    MovingPathPoint,
    Muscle,
    OsimModel,
    PathPoint,
    load_osim_file,
)
from pamkin.opensim.storage import Storage, read_storage
from pamkin.opensim.vtp import body_meshes, read_vtp
from pamkin.opensim.wrapping import PathWrap, WrapObject, WrappedPaths

__all__ = ["Body", "ConditionalPathPoint", "Constant", "Coordinate", "Joint", "LinearFunction", "MovingPathPoint", "MultiplierFunction", "Muscle", "OsimModel", "PathPoint", "PathWrap", "PolynomialFunction", "ScalarFunction", "SimmSpline", "Storage", "WrapObject", "WrappedPaths", "body_meshes", "load_osim_file", "read_storage", "read_vtp"]
