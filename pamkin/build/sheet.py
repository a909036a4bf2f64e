"""What a workshop needs to build a design: the build sheet's content (:func:`build_sheet`).

Per PAM (actuator): the Festo DMSP designation with its nominal length, the parallel count, the fittings,
the pulley block, the artificial tendon (cable) and the segment and end of its route the PAM body sits at
(the audit's rule, :func:`pamkin.robot.pam_body.placement`, over the viewer's random poses
:func:`pamkin.viz.meshcat_view.pam_placements`), its guides (rollers, eyelets, via points and detours,
conditional and moving points), its length and cable-tension ranges over those poses and its mass.
Per attachment point: the bone, its coordinates in the bone's (body's) frame [mm], and the bracket that
holds it — its length (the point's distance from the bone surface, :meth:`pamkin.human.bones.BoneSet.body_closest`),
its direction (the bone's outward normal at the bracket's foot) and its foot on the bone [mm].
Parts and mass totals for both sides (the left side is the mirror image, z → −z in every body frame).

The sheet is plain data (dicts, lists, numbers); :mod:`pamkin.build.documents` writes it as Markdown, CSV
and JSON and rebuilds a design's routes from the JSON.
"""

from __future__ import annotations

import warnings

import numpy as np

from pamkin.audit.measure import random_poses
from pamkin.errors import RangeWarning
from pamkin.human.bones import BoneSet
from pamkin.human.rom import load_rom
from pamkin.opensim.model_file import ConditionalPathPoint, MovingPathPoint, _point_to_dict
from pamkin.robot import festo
from pamkin.robot.biped import PamRobot, robot_skeleton
from pamkin.robot.design import Design, pam_unit_mass, pams_mass
from pamkin.robot.pam_body import route_positions, segment_names
from pamkin.robot.rack import ANCHOR, GUIDE
from pamkin.viz.meshcat_view import PLACEMENT_POSES, pam_placements

__all__ = ["CONNECTIONS", "FORMAT", "build_sheet", "festo_designation"]

#: Version of the build sheet's JSON form.
FORMAT = "pamkin.build_sheet/1"
#: Festo DMSP connection variant assumed for every PAM: a radial supply port at one end, the other end
#: closed, both with male threads ("RM-CM"). An assumption: choose the variant with Festo's configurator.
CONNECTIONS = "RM-CM"


def festo_designation(diameter_mm: int, resting_length_m: float) -> str:
    """Festo DMSP order designation of one PAM: ``DMSP-{diameter}-{nominal length in mm}N-{connections}``
    (:data:`CONNECTIONS`; the nominal length rounded to whole millimetres)."""
    return f"DMSP-{festo.check_diameter(diameter_mm)}-{int(round(resting_length_m * 1000))}N-{CONNECTIONS}"


def _role(pam, i: int) -> str:
    """What point ``i`` of ``pam``'s route is for a builder."""
    pt = pam.points[i]
    if isinstance(pt, MovingPathPoint):
        return "moving point"
    if isinstance(pt, ConditionalPathPoint):
        return "conditional guide"
    if pt.name == ANCHOR:
        return "rack anchor"         # pamkin.robot.rack: the bracket holding the PAM's far end
    if pt.name == GUIDE:
        return "rack guide pulley"   # the pulley turning the cable from the PAM to the route's end
    if i == 0:
        return "origin anchor"
    if i == len(pam.points) - 1:
        return "insertion anchor"
    parts = pt.name.split(".")
    last = parts[-1]
    if len(parts) >= 3 and (last == "e" or (last.startswith("e") and last[1:].isdigit())):
        return "eyelet"              # pamkin.robot.eyelets names them "p1.p2.e", "p1.p2.e1", ...
    if len(parts) >= 3:
        return "detour guide"        # pamkin.robot.detour: "p3.p4.1", ...
    return "via guide"


def _attachments(pam, local: np.ndarray, bones: BoneSet) -> list[dict]:
    """One dict per route point of ``pam`` (positions ``local`` (P, 3) [m] in their bodies' frames at the
    default pose): body, role, coordinates [mm] and the bracket."""
    out = []
    for i, pt in enumerate(pam.points):
        row = {"pam_id": pam.id, "pam": pam.name, "index": i, "point": pt.name, "body": pt.body, "role": _role(pam, i),
               "x_mm": round(1000 * float(local[i, 0]), 4), "y_mm": round(1000 * float(local[i, 1]), 4),
               "z_mm": round(1000 * float(local[i, 2]), 4)}
        if isinstance(pt, MovingPathPoint):
            row["note"] = (f"moves with {', '.join(sorted(set(pt.coordinates)))} (a linkage or guide in the joint); "
                           "coordinates at the default pose")
            row["definition"] = _point_to_dict(pt)
        else:
            d, c, n = bones.body_closest(pt.body, np.asarray(pt.location, float)[None, :])
            if np.isfinite(d[0]):
                row.update(bracket_mm=round(1000 * float(d[0]), 2),
                           bracket_direction=[round(float(v), 4) for v in n[0]],
                           bracket_foot_mm=[round(1000 * float(v), 2) for v in c[0]])
                if d[0] < 0:
                    row["note"] = "inside the bone: cannot be built as given"
            else:
                row["note"] = "no bone mesh for this body: bracket not measured"
            if isinstance(pt, ConditionalPathPoint):
                row["definition"] = _point_to_dict(pt)
                lo, hi = np.degrees(pt.range)
                row["note"] = (row.get("note", "") + f"; the cable touches it only while {pt.coordinate} is in "
                               f"[{lo:.1f}, {hi:.1f}] deg").lstrip("; ")
        out.append(row)
    return out


def _cable(pam, place, pts: np.ndarray, fit: float) -> dict:
    """The PAM's artificial tendon: its length and, for a PAM on one straight segment without a pulley
    block, the constant pieces before and after the body along the route [mm]."""
    out = {"tendon_mm": round(1000 * pam.tendon_length_m, 2)}
    seg = np.linalg.norm(pts[:, 1:] - pts[:, :-1], axis=2)
    cum = np.concatenate([np.zeros((len(pts), 1)), np.cumsum(seg, axis=1)], axis=1)
    if place.on_one_segment and pam.transmission == 1 and not pam.rollers:
        j = place.segment
        if place.side == "origin":
            before = float(np.median(cum[:, j]))
            after = pam.tendon_length_m - before
        else:
            after = float(np.median(cum[:, -1] - cum[:, j + 1]))
            before = pam.tendon_length_m - after
        out.update(before_body_mm=round(1000 * before, 2), after_body_mm=round(1000 * after, 2))
    return out


def _pam_entry(pam, place, pts: np.ndarray, st, k: int, fit: float) -> dict:
    """The build sheet's entry of one PAM (see the module docstring)."""
    names = segment_names(pam)
    rest = pam.resting_length_m
    entry = {
        "id": pam.id, "name": pam.name, "human_muscles": list(pam.human_muscles),
        "designation": festo_designation(pam.diameter_mm, rest), "diameter_mm": pam.diameter_mm,
        "nominal_length_mm": int(round(rest * 1000)), "resting_length_mm": round(1000 * rest, 3),
        "n_parallel": pam.n_parallel, "units_both_sides": 2 * pam.n_parallel,
        "fittings_per_unit": 2, "fitting_length_mm": round(1000 * fit, 2),
        "transmission": int(pam.transmission),
        "pulley_block": None if pam.transmission == 1 else f"{pam.transmission}:1 ({pam.transmission - 1} pulley"
                                                          f"{'s' if pam.transmission > 2 else ''} in a frame)",
        "cable_efficiency": round(float(pam.cable_efficiency), 4),
        "mount_segment": names[place.segment], "on_one_segment": bool(place.on_one_segment),
        "pam_at": place.side if place.on_one_segment else None,
        "cable": _cable(pam, place, pts, fit),
        "pam_length_mm": [round(1000 * float(np.min(st.pam_lengths[:, k])), 1),
                          round(1000 * float(np.max(st.pam_lengths[:, k])), 1)],
        "route_length_mm": [round(1000 * float(np.min(st.lengths[:, k])), 1),
                            round(1000 * float(np.max(st.lengths[:, k])), 1)],
        "contraction_max": round(float(np.max(st.strain[:, k])), 4),
        "peak_cable_tension_N": round(float(np.max(st.forces[:, k])), 1),
        "mass_per_unit_kg": round(pam_unit_mass(pam), 4),
        "rollers": [{"segment": r.segment, "body": r.body, "centre_mm": [round(1000 * v, 3) for v in r.centre],
                     "axis": [round(float(v), 4) for v in r.axis], "side": [round(float(v), 4) for v in r.side],
                     "radius_mm": round(1000 * r.radius_m, 2), "length_mm": round(1000 * r.length_m, 2),
                     "definition": r.to_dict()}
                    for r in pam.rollers],
    }
    warn = []
    if not place.on_one_segment:
        warn.append(f"does not fit on one straight segment of its route: bends over "
                    f"{pam.points[min(place.segment + 1, len(pam.points) - 1)].name}")
    if pam.tendon_length_m < 0:
        warn.append("negative tendon: the PAM with its fittings is longer than its route")
    if warn:
        entry["warning"] = "; ".join(warn)
    return entry


def _parts(des: Design, pams: list[dict], attachments: list[dict]) -> list[dict]:
    """Parts for both sides: PAMs by designation, fittings, pulley blocks, rollers, brackets and guides."""
    count: dict[tuple[str, str], int] = {}

    def add(kind: str, what: str, n: int) -> None:
        count[(kind, what)] = count.get((kind, what), 0) + n

    for p in pams:
        add("PAM (Festo DMSP)", p["designation"], p["units_both_sides"])
        add("end fitting", f"for DMSP-{p['diameter_mm']} ({p['fitting_length_mm']:g} mm)", 2 * p["units_both_sides"])
        if p["pulley_block"]:
            add("pulley block", f"{p['transmission']}:1 for DMSP-{p['diameter_mm']} x{p['n_parallel']}", 2)
        for r in p["rollers"]:
            add("roller", f"radius {r['radius_mm']:g} mm, length {r['length_mm']:g} mm", 2)
    for a in attachments:
        if a["role"] == "moving point":
            add("moving attachment", f"on {a['body'].removesuffix('_r')}", 2)
        else:
            add("bracket", f"{a['role']} on {a['body'].removesuffix('_r')}", 2)
    return [{"part": k, "what": w, "count": n} for (k, w), n in sorted(count.items())]


def build_sheet(design: Design, geometry_dir: str | None = None) -> dict:
    """The build sheet of ``design`` (right side given; the left side mirrors it): ``pams``, ``attachments``,
    ``parts``, ``mass`` and the design's operating point (see the module docstring).

    Args:
        design: The design.
        geometry_dir: Folder of the bone meshes (default: found beside the model).

    Raises:
        pamkin.errors.DataFileError: No bone meshes.
    """
    skel = robot_skeleton()
    bones = BoneSet(skel, geometry_dir)
    right = PamRobot(design, skel, sides=("r",))
    places = pam_placements(right)
    q = random_poses(skel, load_rom(design.rom, "r"), PLACEMENT_POSES)
    q0 = skel.default_q[None, :]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        st = right.evaluate(q)
        ks = skel.kinematics.forward(q, warn_range=False)
        k0 = skel.kinematics.forward(q0, warn_range=False)
    X0, _ = right.paths.point_positions(k0)
    pams, attachments = [], []
    for k, (pam, place) in enumerate(zip(design.pams, places)):
        a = right.paths._path_start[k]
        pts = route_positions(right.paths, ks, k)
        local = np.empty((len(pam.points), 3))
        for i, pt in enumerate(pam.points):
            b = skel.bodies.index(pt.body)
            local[i] = k0.body_R[0, b].T @ (X0[0, a + i] - k0.body_p[0, b])
        pams.append(_pam_entry(pam, place, pts, st, k, design.fitting_length_m))
        attachments += _attachments(pam, local, bones)
    units = sum(p.n_parallel for p in design.pams)
    pam_mass = 2 * sum(float(festo.pam_mass(p.resting_length_m, p.diameter_mm)) * p.n_parallel for p in design.pams)
    total = pams_mass(design.pams)
    return {
        "format": FORMAT, "design": design.name, "source": design.path, "side": "right (the left is its mirror "
        "image: z -> -z in every body frame, _r -> _l)", "pressure_kPa": design.pressure_Pa / 1000.0,
        "force_model": design.force_model, "rom": design.rom, "fitting_length_mm": 1000 * design.fitting_length_m,
        "connections": CONNECTIONS, "placement_poses": PLACEMENT_POSES,
        "pams": pams, "attachments": attachments, "parts": _parts(design, pams, attachments),
        "mass": {"pams_and_fittings_kg": round(pam_mass, 3), "pulley_blocks_kg": round(total - pam_mass, 3),
                 "total_kg": round(total, 3), "pam_units_both_sides": 2 * units,
                 "source": "assumed Festo weights (festo_models.json assumed_mass, assumed_pulley_block_mass); "
                           "brackets, cables, rollers and valves not included"},
        "bones": str(bones.geometry_dir),
    }
