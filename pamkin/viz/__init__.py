"""Views: meshcat pages of the skeleton, muscles and PAMs, and the torque-surface report."""

from __future__ import annotations

from pamkin.viz.audit_page import audit_view
from pamkin.viz.meshcat_view import View, build_view, screenshot
from pamkin.viz.torque_report import Report, torque_report

__all__ = ["audit_view", "Report", "View", "build_view", "screenshot", "torque_report"]
