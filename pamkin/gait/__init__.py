"""Walking: PAM pressure plans (Pa) that reproduce a recorded trial's inverse-dynamics joint moments."""

from __future__ import annotations

from pamkin.gait.plan import (
    GaitPlan,
    GaitTrial,
    feasible_frame_fraction,
    gait_plan,
    load_trial,
    plan_pressures,
    plot_pressures,
)

__all__ = ["GaitPlan", "GaitTrial", "feasible_frame_fraction", "gait_plan", "load_trial", "plan_pressures", "plot_pressures"]
