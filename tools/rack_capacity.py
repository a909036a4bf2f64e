"""How many PAM bodies the bones hold: the rack layout of a design with every PAM's body replaced by one size.

    python tools/rack_capacity.py DESIGN OUT.json [--sizes 20x0.15,20x0.20,20x0.25,20x0.30] [--angles 16]

Every PAM of ``DESIGN`` keeps its route (so its racks sit where the rack stage would put them: on the bones of
its route's two ends) but gets a body of diameter ``d`` [mm] and resting length ``L`` [m], one PAM, no pulley
block; the rack layout (``pamkin.optimize.rack_layout.layout``, the stage's uniform poses: 200 random poses of
its stream, every 6th walking frame, the chosen racks checked again at 2000 more; not the stage's edge poses,
which can only remove places) then says how many of them fit
at once, 5 mm from each other and from bone at every checked pose, brackets at most 50 mm from their bone. It
also prints, per PAM of the design, the shortest resting length its route's stroke allows at 1:1 (the route's
length range over 2000 random poses of the audit's stream divided by the strain range Festo allows its
diameter: largest contraction + largest pretension), the length below which no fit can go without a pulley
block.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from pamkin.audit.measure import GAIT_IK, gait_poses, random_poses
from pamkin.human.bones import BoneSet
from pamkin.human.rom import load_rom
from pamkin.optimize.rack_layout import layout
from pamkin.optimize.stages.rack import RACK_CHECK_STREAM, RACK_STREAM
from pamkin.robot import festo
from pamkin.robot.biped import PamRobot, robot_skeleton
from pamkin.robot.design import Design, load_design
from pamkin.robot.rack import ANCHOR, GUIDE


def uniform(design: Design, diameter_mm: int, rest_m: float) -> Design:
    """``design`` with every PAM a single ``diameter_mm`` PAM of resting length ``rest_m`` on its route (off any
    rack it hangs on), 1:1."""
    for p in design.pams:
        points = tuple(pt for pt in p.points if pt.name not in (ANCHOR, GUIDE))
        design = design.replace_pam(dataclasses.replace(p, diameter_mm=diameter_mm, n_parallel=1, points=points,
                                                        resting_length_m=rest_m, transmission=1, pam_on=None,
                                                        pam_at=None, cable_efficiency=1.0))
    return design


def strokes(design: Design, skel, q: np.ndarray) -> list[dict]:
    """Per PAM: the route's length range over ``q`` [m] and the shortest resting length it allows at 1:1."""
    robot = PamRobot(design, skel, sides=("r",))
    L = robot.paths.evaluate(skel.kinematics.forward(q, warn_range=False), moment_arms=False).lengths
    out = []
    for k, p in enumerate(design.pams):
        stroke = float(L[:, k].max() - L[:, k].min()) / p.transmission
        out.append({"id": p.id, "name": p.name, "stroke_m": stroke, "diameter_mm": p.diameter_mm,
                    "resting_length_m": p.resting_length_m,
                    "shortest_rest_m": stroke / (festo.max_contraction(p.diameter_mm)
                                                              + festo.max_pretension(p.diameter_mm))})
    return out


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("design")
    ap.add_argument("out")
    ap.add_argument("--sizes", default="20x0.15,20x0.20,20x0.25,20x0.30",
                    help="comma-separated DIAMETERxLENGTH bodies [mm x m]")
    ap.add_argument("--angles", type=int, default=16)
    a = ap.parse_args(argv)
    des = load_design(a.design)
    skel = robot_skeleton()
    bones = BoneSet(skel)
    rom = load_rom(des.rom or "robot_thesis")
    q = random_poses(skel, rom, 200, 0, stream=RACK_STREAM)
    q_check = random_poses(skel, rom, 2000, 0, stream=RACK_CHECK_STREAM)
    qg = gait_poses(skel, GAIT_IK, stride=6)[0]
    report = {"design": a.design, "strokes": strokes(des, skel, random_poses(skel, rom, 2000, 0)), "sizes": []}
    for s in report["strokes"]:
        print(f"{s['id']:3d} {s['name'][:40]:40s} stroke {1000 * s['stroke_m']:5.1f} mm -> resting length >= "
              f"{s['shortest_rest_m']:.3f} m at 1:1 ({s['diameter_mm']} mm; the design's {s['resting_length_m']:.3f} m)")
    for size in a.sizes.split(","):
        d, L = size.split("x")
        new, rep = layout(uniform(des, int(d), float(L)), skel, bones, q, qg, angles=a.angles, q_check=q_check)
        row = {"diameter_mm": int(d), "resting_length_m": float(L), "pams": len(des.pams),
               "racked": len(rep.placed), "unplaced": rep.unplaced,
               "reasons": {str(k): v for k, v in rep.reasons.items()}}
        report["sizes"].append(row)
        print(f"{d} mm x {float(L):.2f} m: {row['racked']} of {row['pams']} bodies on racks; left: {rep.unplaced}",
              flush=True)
        Path(a.out).write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
