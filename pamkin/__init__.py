"""pamkin: design biomimetic bipedal robots actuated by pneumatic artificial muscles.

The human side: :func:`load_osim` imports an OpenSim model and returns a :class:`Model` with kinematics,
muscle paths, forces and torques (:func:`gait2392`: the built-in Gait2392). The robot side: a
:class:`Design` (:func:`load_design`) of Festo PAMs on routes over Gait2392's bones, the :class:`PamRobot`
that evaluates its PAM lengths, moment arms, forces and torques, :func:`audit_design` (what a design is
worth on held-out poses, bones and buildability) and :func:`gait_plan` (PAM pressures over a walking trial).
The optimiser is :mod:`pamkin.optimize` (``from pamkin.optimize import run, load_config``; it is not
imported here: it loads matplotlib and, when it solves, CasADi). SI units throughout (m, N, Pa, rad).
"""

from .audit.measure import AuditOptions, AuditResult, audit_design
from .errors import (
    ConfigurationError,
    EquilibriumWarning,
    OsimError,
    PamkinError,
    ParameterError,
    RangeWarning,
    UnsupportedFeatureError,
)
from .gait.plan import GaitPlan, gait_plan
from .human.model import Model, gait2392, load_osim
from .robot.biped import PamRobot, design_robot, thesis_robot
from .robot.design import Design, Pam, load_design, save_design

__all__ = [
    "AuditOptions",
    "AuditResult",
    "ConfigurationError",
    "Design",
    "EquilibriumWarning",
    "GaitPlan",
    "Model",
    "OsimError",
    "Pam",
    "PamRobot",
    "PamkinError",
    "ParameterError",
    "RangeWarning",
    "UnsupportedFeatureError",
    "audit_design",
    "design_robot",
    "gait2392",
    "gait_plan",
    "load_design",
    "load_osim",
    "save_design",
    "thesis_robot",
]
__version__ = "0.1.0"
