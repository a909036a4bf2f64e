"""Build sheets: what a workshop needs to buy, cut and drill for a design — per PAM the Festo designation,
count, fittings, pulley block, cable and guides; per attachment the bone, coordinates and bracket; parts and
mass totals (:mod:`pamkin.build.sheet`), written as Markdown, CSV and JSON with an assembled 3-D view
(:mod:`pamkin.build.documents`)."""

from __future__ import annotations

from pamkin.build.documents import rollers_from_sheet, routes_from_sheet, write_build_sheet
from pamkin.build.sheet import build_sheet, festo_designation

__all__ = ["build_sheet", "festo_designation", "rollers_from_sheet", "routes_from_sheet", "write_build_sheet"]
