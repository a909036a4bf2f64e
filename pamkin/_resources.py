"""Where pamkin's project data lives: one place for every data-path constant.

The project keeps its data in top-level folders of the repository (``robot/``: Xacro sources and
data files; ``urdf/``: generated URDFs and bone meshes). The wheel installs them inside the
package (``pyproject.toml`` maps ``pamkin.robot_sources -> robot``, beside the ``pamkin.robot`` package,
and ``pamkin.urdf -> urdf``), so they are found

* in an installed wheel: ``<site-packages>/pamkin/robot_sources`` and ``<site-packages>/pamkin/urdf``;
* in a checkout or an editable install (``pip install -e .``): ``<checkout>/robot`` and
  ``<checkout>/urdf`` beside the ``pamkin/`` folder.

``$PAMKIN_ROBOT_DIR`` overrides the robot folder (its sibling ``urdf/`` is then used). Nothing
here depends on the current folder or on a checkout being present.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["CACHE_DIR", "DEFAULT_GEOMETRY", "DEFAULT_OSIM", "MESH_DIR", "PACKAGE_DIR", "ROBOT_DIR", "SHARED_DIR",
           "URDF_DIR", "cache_dir", "data_file"]

#: The ``pamkin`` package folder.
PACKAGE_DIR = Path(__file__).resolve().parent


def _find(installed: str, checkout: str) -> Path:
    """``pamkin/<installed>`` in an installed wheel, else ``<checkout>/<checkout>`` (editable install)."""
    for folder in (PACKAGE_DIR / installed, PACKAGE_DIR.parent / checkout):
        if folder.is_dir():
            return folder
    return PACKAGE_DIR / installed  # missing: errors then name the installed location


def _robot_dir() -> Path:
    env = os.environ.get("PAMKIN_ROBOT_DIR")
    return Path(env).resolve() if env else _find("robot_sources", "robot")


#: Xacro sources and project data files (``robot/``).
ROBOT_DIR = _robot_dir()
#: Generated URDFs (``urdf/``), beside the robot folder when it was overridden.
URDF_DIR = ROBOT_DIR.parent / "urdf" if os.environ.get("PAMKIN_ROBOT_DIR") else _find("urdf", "urdf")
#: Bone meshes of the built-in URDFs, generated from Gait2392's ``.vtp`` files (``urdf/meshes/``).
MESH_DIR = URDF_DIR / "meshes"


def data_file(name: str) -> Path:
    """A file of ``robot/data/`` (e.g. ``"rom.yaml"``)."""
    return ROBOT_DIR / "data" / name


def cache_dir() -> Path:
    """Cache folder of generated URDFs of imported models: ``$PAMKIN_CACHE`` or ``~/.cache/pamkin``."""
    return Path(os.environ.get("PAMKIN_CACHE", Path.home() / ".cache" / "pamkin"))


#: The reference data folder of the development setup (``../shared`` beside a checkout, or
#: ``$PAMKIN_SHARED``). Only ``pamkin urdf`` (which regenerates the built-in data from the
#: ``.osim``) and the bone-mesh options of ``pamkin view`` use it; an installed package does not
#: need it.
SHARED_DIR = Path(os.environ.get("PAMKIN_SHARED", PACKAGE_DIR.parent.parent / "shared"))
#: OpenSim's Gait2392 model file the built-in data is imported from.
DEFAULT_OSIM = SHARED_DIR / "opensim-models" / "Gait2392_Simbody" / "gait2392_thelen2003muscle.osim"
#: OpenSim's Geometry folder (the ``.vtp`` bone meshes of Gait2392).
DEFAULT_GEOMETRY = SHARED_DIR / "opensim-models" / "Geometry"

#: The cache folder at import time (:func:`cache_dir` reads the environment at each call).
CACHE_DIR = cache_dir()
