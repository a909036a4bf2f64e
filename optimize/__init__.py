"""The attachment-point optimiser: a declared pipeline of stages (:data:`pamkin.optimize.pipeline.STAGES`) over
one CasADi/IPOPT problem per actuator, configured by a TOML run description nested by stage
(:mod:`pamkin.optimize.config`).

    from pamkin.optimize import load_config, run
    summary = run(load_config("examples/knee_pams.toml"), "runs/knee")
"""

from pamkin.optimize.config import RunConfig, config_changes, config_toml, load_config
from pamkin.optimize.context import RunContext
from pamkin.optimize.executor import DaskExecutor, LocalExecutor, make_executor
from pamkin.optimize.pipeline import STAGES, Stage, apply_design, run
from pamkin.optimize.results import ActuatorResult, InfeasibleError

__all__ = ["STAGES", "ActuatorResult", "DaskExecutor", "InfeasibleError", "LocalExecutor", "RunConfig", "RunContext",
           "Stage", "apply_design", "config_changes", "config_toml", "load_config", "make_executor", "run"]
