"""A build sheet (:func:`pamkin.build.sheet.build_sheet`) as files a workshop reads — ``build_sheet.md``,
``pams.csv``, ``attachments.csv``, ``parts.csv``, ``build_sheet.json`` and the assembled 3-D view
``assembly.html`` (optionally ``assembly.png``) — written whole into one folder through
:mod:`pamkin.outputs`; and the routes rebuilt from the JSON (:func:`routes_from_sheet`)."""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

from pamkin.errors import DataFileError
from pamkin.opensim.model_file import ConditionalPathPoint, PathPoint, point_from_dict
from pamkin.outputs import output_folder, strict_json, write_file
from pamkin.robot.pam_body import Placement
from pamkin.robot.rollers import roller_from_dict
from pamkin.viz.assembly_view import SCREENSHOT_SIZE, assembly_view
from pamkin.viz.meshcat_view import screenshot

__all__ = ["FILES", "rollers_from_sheet", "routes_from_sheet", "sheet_markdown", "write_build_sheet"]

#: The files of a build-sheet folder (``assembly.png`` only with a screenshot).
FILES = ("build_sheet.md", "pams.csv", "attachments.csv", "parts.csv", "build_sheet.json", "assembly.html")

PAM_COLUMNS = ("id", "name", "designation", "diameter_mm", "nominal_length_mm", "n_parallel", "units_both_sides",
               "fittings_per_unit", "fitting_length_mm", "pulley_block", "mount_segment", "pam_at", "tendon_mm",
               "before_body_mm", "after_body_mm", "guides", "pam_length_min_mm", "pam_length_max_mm",
               "contraction_max", "peak_cable_tension_N", "mass_per_unit_kg", "warning")
ATTACHMENT_COLUMNS = ("pam_id", "pam", "index", "point", "role", "body", "x_mm", "y_mm", "z_mm", "bracket_mm",
                      "bracket_dx", "bracket_dy", "bracket_dz", "foot_x_mm", "foot_y_mm", "foot_z_mm", "note")


def _guides(p: dict, attachments: list[dict]) -> str:
    """The guides of one PAM as one line: rollers and the route's intermediate points by role."""
    out = [f"roller on {r['segment']} ({r['body']}, r {r['radius_mm']:g} mm)" for r in p["rollers"]]
    out += [f"{a['role']} {a['point']} ({a['body']})" for a in attachments
            if a["pam_id"] == p["id"] and a["role"] not in ("origin anchor", "insertion anchor")]
    return "; ".join(out) or "-"


def _pam_rows(sheet: dict) -> list[dict]:
    rows = []
    for p in sheet["pams"]:
        c = p["cable"]
        rows.append({**{k: p.get(k) for k in PAM_COLUMNS}, "tendon_mm": c["tendon_mm"],
                     "before_body_mm": c.get("before_body_mm"), "after_body_mm": c.get("after_body_mm"),
                     "guides": _guides(p, sheet["attachments"]), "pulley_block": p["pulley_block"] or "none",
                     "pam_length_min_mm": p["pam_length_mm"][0], "pam_length_max_mm": p["pam_length_mm"][1],
                     "warning": p.get("warning", "")})
    return rows


def _attachment_rows(sheet: dict) -> list[dict]:
    rows = []
    for a in sheet["attachments"]:
        d = a.get("bracket_direction") or [None] * 3
        f = a.get("bracket_foot_mm") or [None] * 3
        rows.append({**{k: a.get(k) for k in ATTACHMENT_COLUMNS}, "bracket_dx": d[0], "bracket_dy": d[1],
                     "bracket_dz": d[2], "foot_x_mm": f[0], "foot_y_mm": f[1], "foot_z_mm": f[2],
                     "note": a.get("note", "")})
    return rows


def _csv(rows: list[dict], columns) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in columns})
    return buf.getvalue()


def _num(v, nd: int = 1) -> str:
    return "-" if v is None else f"{v:.{nd}f}"


def sheet_markdown(sheet: dict) -> str:
    """The build sheet as one Markdown page: how to read it, PAMs, attachments, parts and mass."""
    m = sheet["mass"]
    lines = [f"# Build sheet: {sheet['design']}", "",
             f"Design `{sheet['source']}`; {sheet['side']}. Operating pressure {sheet['pressure_kPa']:g} kPa. "
             f"Bone meshes: `{sheet['bones']}`.", "",
             "Coordinates are in each bone's (OpenSim body's) frame in millimetres: x forward, y up, z to the right "
             "for the right leg (mirror z for the left). A bracket runs from its *foot* on the bone surface along "
             "its *direction* (the bone's outward normal there) for its *length* to the attachment point. Each PAM "
             f"body sits on its *mount segment*, at the named end (origin or insertion), over "
             f"{sheet['placement_poses']} random poses of the range of motion `{sheet['rom']}`; the rest of the "
             "route is cable (the artificial tendon: route length = k x (PAM + 2 fittings) + tendon for a k:1 "
             f"block). Festo designations assume the connection variant {sheet['connections']} (radial supply "
             "port at one end, closed at the other): confirm with Festo's configurator.", "",
             "## PAMs (per side)", "",
             "| id | PAM | Festo | x | block | mount | cable [mm] | guides | PAM length [mm] | peak tension [N] | "
             "kg/unit |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for p, r in zip(sheet["pams"], _pam_rows(sheet)):
        cable = f"{r['tendon_mm']:.1f}"
        if r["before_body_mm"] is not None:
            cable += f" ({r['before_body_mm']:.1f} before + {r['after_body_mm']:.1f} after the body)"
        mount = f"{p['mount_segment']} at {p['pam_at']}" if p["on_one_segment"] else "-"
        if p.get("warning"):
            mount += f" **{p['warning']}**"
        lines.append(f"| {p['id']} | {p['name']} | {p['designation']} | {p['n_parallel']} | {r['pulley_block']} | "
                     f"{mount} | {cable} | {r['guides']} | {p['pam_length_mm'][0]:.0f}-{p['pam_length_mm'][1]:.0f} | "
                     f"{p['peak_cable_tension_N']:.0f} | {p['mass_per_unit_kg']:.3f} |")
    lines += ["", "## Attachments (right side)", "",
              "| PAM | point | role | bone | x | y | z | bracket [mm] | direction | foot (x, y, z) | note |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for a in sheet["attachments"]:
        d = a.get("bracket_direction")
        f = a.get("bracket_foot_mm")
        lines.append(f"| {a['pam_id']} | {a['point']} | {a['role']} | {a['body']} | {a['x_mm']:.1f} | {a['y_mm']:.1f} | "
                     f"{a['z_mm']:.1f} | {_num(a.get('bracket_mm'))} | "
                     f"{'-' if d is None else '(' + ', '.join(f'{v:.2f}' for v in d) + ')'} | "
                     f"{'-' if f is None else '(' + ', '.join(f'{v:.1f}' for v in f) + ')'} | {a.get('note', '')} |")
    lines += ["", "## Parts (both sides)", "", "| part | what | count |", "|---|---|---|"]
    lines += [f"| {p['part']} | {p['what']} | {p['count']} |" for p in sheet["parts"]]
    lines += ["", "## Mass (both sides)", "",
              f"PAMs with fittings {m['pams_and_fittings_kg']:.2f} kg, pulley blocks {m['pulley_blocks_kg']:.2f} kg, "
              f"total {m['total_kg']:.2f} kg for {m['pam_units_both_sides']} PAM units ({m['source']}).", "",
              "Files: `pams.csv`, `attachments.csv`, `parts.csv` (the tables above), `build_sheet.json` (everything, "
              "with the definitions of moving and conditional points), `assembly.html` (the assembled robot, PAM "
              "bodies at their inflated size).", ""]
    return "\n".join(lines)


def write_build_sheet(sheet: dict, design, out: str | os.PathLike, *, force: bool = False,
                      placements: list[Placement] | None = None, geometry_dir: str | None = None,
                      screenshot_png: bool = False) -> list[Path]:
    """Write the build sheet's files (:data:`FILES`, and ``assembly.png`` with ``screenshot_png``) into the
    folder ``out``, whole or not at all (refused if it exists, unless ``force``).

    Args:
        sheet: :func:`pamkin.build.sheet.build_sheet` of ``design``.
        design: The design (for the 3-D view).
        out: The folder.
        force: Replace an existing folder whole.
        placements: Where each PAM body sits (default: the sheet's mount segments and ends).
        geometry_dir: Folder of the bone meshes.
        screenshot_png: Also render the 3-D view with headless Chromium.

    Returns:
        The files written.
    """
    if placements is None:
        names = [[f"{a.name}->{b.name}" for a, b in zip(p.points[:-1], p.points[1:])] for p in design.pams]
        placements = [Placement(n.index(p["mount_segment"]), 0.0 if p["on_one_segment"] else -1.0,
                                p["pam_at"] or "origin") for n, p in zip(names, sheet["pams"])]
    out = Path(out)
    files = list(FILES) + (["assembly.png"] if screenshot_png else [])
    with output_folder(out, force) as tmp:
        write_file(tmp / "build_sheet.md", sheet_markdown(sheet))
        write_file(tmp / "pams.csv", _csv(_pam_rows(sheet), PAM_COLUMNS))
        write_file(tmp / "attachments.csv", _csv(_attachment_rows(sheet), ATTACHMENT_COLUMNS))
        write_file(tmp / "parts.csv", _csv(sheet["parts"], ("part", "what", "count")))
        write_file(tmp / "build_sheet.json", strict_json(sheet, indent=1))
        title = (f"<b>pamkin build: {sheet['design']}</b> &nbsp; PAM bodies at their largest outer radius "
                 "(green 10 mm, blue 20 mm, red 40 mm DMSP), cables dark, brackets grey; default pose")
        assembly_view(design, tmp / "assembly.html", placements, sheet["attachments"], geometry_dir, title)
        if screenshot_png:
            screenshot(tmp / "assembly.html", tmp / "assembly.png", size=SCREENSHOT_SIZE)
    return [out / f for f in files]


def routes_from_sheet(sheet: dict, where: str = "build_sheet.json") -> dict[int, tuple]:
    """Every PAM's route rebuilt from a build sheet's JSON (``sheet``, as loaded): ``{pam id: (points...)}``,
    fixed points from their coordinates in millimetres, conditional and moving points from their definitions.

    Raises:
        DataFileError: Not a build sheet, or an attachment without coordinates (naming ``where``).
    """
    if not isinstance(sheet, dict) or not str(sheet.get("format", "")).startswith("pamkin.build_sheet/"):
        raise DataFileError(where, "not a pamkin build sheet (no 'format: pamkin.build_sheet/...')")
    routes: dict[int, list] = {}
    for n, a in enumerate(sheet.get("attachments", [])):
        try:
            loc = (a["x_mm"] / 1000.0, a["y_mm"] / 1000.0, a["z_mm"] / 1000.0)
            d = a.get("definition")
            if d is not None and d.get("type") == "MovingPathPoint":
                pt = point_from_dict(d)
            elif d is not None and d.get("type") == "ConditionalPathPoint":
                pt = ConditionalPathPoint(a["point"], a["body"], loc, d["coordinate"], tuple(d["range"]))
            else:
                pt = PathPoint(a["point"], a["body"], loc)
            routes.setdefault(int(a["pam_id"]), []).append((int(a["index"]), pt))
        except (KeyError, TypeError) as e:
            raise DataFileError(where, f"attachments[{n}]: missing or bad field {e}") from None
    return {k: tuple(p for _, p in sorted(v, key=lambda x: x[0])) for k, v in routes.items()}


def rollers_from_sheet(sheet: dict, where: str = "build_sheet.json") -> dict[int, tuple]:
    """Every PAM's rollers rebuilt from a build sheet's JSON: ``{pam id: (Roller, ...)}`` from their
    definitions (full precision), checked against the PAM's route as rebuilt by :func:`routes_from_sheet`.

    Raises:
        DataFileError: Not a build sheet, or a roller that is not valid (naming ``where`` and the PAM).
    """
    routes = routes_from_sheet(sheet, where)
    out = {}
    for p in sheet.get("pams", []):
        pts = routes.get(p.get("id"), ())
        segments = [f"{a.name}->{b.name}" for a, b in zip(pts[:-1], pts[1:])]
        try:
            out[p["id"]] = tuple(roller_from_dict(r["definition"], segments) for r in p.get("rollers", []))
        except (KeyError, TypeError, ValueError) as e:
            raise DataFileError(where, f"PAM {p.get('id')}: roller: {e}") from None
    return out
