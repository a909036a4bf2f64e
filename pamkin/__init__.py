"""pamkin: design biomimetic bipedal robots actuated by pneumatic artificial muscles.

Start with :func:`load_osim`, which imports an OpenSim model and returns a
:class:`Model` with kinematics, muscle paths, forces and torques.
"""

from pamkin.errors import (
    ConfigurationError,
    EquilibriumWarning,
    OsimError,
    PamkinError,
    ParameterError,
    RangeWarning,
    UnsupportedFeatureError,
)
from pamkin.human.model import Model, gait2392, load_osim

__all__ = [
    "ConfigurationError",
    "EquilibriumWarning",
    "Model",
    "OsimError",
    "PamkinError",
    "ParameterError",
    "RangeWarning",
    "UnsupportedFeatureError",
    "gait2392",
    "load_osim",
]
__version__ = "0.1.0"
