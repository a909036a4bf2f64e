"""What a design is worth on samples no optimiser trains on: robot-vs-human torque comparison
(per PAM, group and joint), the audit's measurements and limits, and its scorecard, figure and page."""

from __future__ import annotations

from pamkin.audit.compare import (
    PamComparison,
    TorqueMatch,
    compare_design,
    compare_groups,
    compare_joints,
    compare_pam,
)
from pamkin.audit.measure import (
    AuditOptions,
    AuditResult,
    audit_design,
    load_limits,
    random_poses,
)
from pamkin.audit.scorecard import plot_criteria, scorecard_text

__all__ = ["AuditOptions", "AuditResult", "PamComparison", "TorqueMatch", "audit_design", "compare_design", "compare_groups", "compare_joints", "compare_pam", "load_limits", "plot_criteria", "random_poses", "scorecard_text"]
