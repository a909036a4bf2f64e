"""What the rack rules cost: the rack layout of a design at several bracket limits, each audited, and the
scored objectives of audited designs side by side (docs/layout.md).

    python tools/rack_tradeoff.py DESIGN OUT.json [--brackets 20,30,40,50,60] [--quick]
    python tools/rack_tradeoff.py --plot OUT.json [LABEL=AUDIT.json ...] PNG

The first form hangs ``DESIGN`` on racks (``pamkin.optimize.rack_layout.layout``, 200 random poses of the rack
stage's stream, every 6th walking frame) at every bracket limit and audits each result (``pamkin audit``
without the gait plan; ``--quick``: the quick audit); the second draws the sweep and the audited designs.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from pamkin.audit.measure import GAIT_IK, AuditOptions, audit_design, gait_poses, random_poses  # noqa: E402
from pamkin.human.bones import BoneSet  # noqa: E402
from pamkin.human.rom import load_rom  # noqa: E402
from pamkin.optimize.rack_layout import layout  # noqa: E402
from pamkin.optimize.stages.rack import RACK_STREAM  # noqa: E402
from pamkin.robot.biped import robot_skeleton  # noqa: E402
from pamkin.robot.design import load_design  # noqa: E402

FIGURES = ("pam_body_pairs_closer_than_gap", "pam_bodies_near_bone", "random_nrmse_median",
           "capacity_directions_met", "mass_kg", "pams_not_on_one_segment")


def sweep(design: str, brackets: list[float], quick: bool) -> list[dict]:
    des = load_design(design)
    skel = robot_skeleton()
    bones = BoneSet(skel)
    q = random_poses(skel, load_rom(des.rom or "robot_thesis"), 200, 0, stream=RACK_STREAM)
    qg = gait_poses(skel, GAIT_IK, stride=6)[0]
    opts = AuditOptions.quick(gait_plan=False) if quick else AuditOptions(gait_plan=False)
    rows = []
    for b in brackets:
        new, rep = layout(des, skel, bones, q, qg, bracket_max=b / 1000.0)
        res = audit_design(new, options=opts)
        rows.append({"bracket_max_mm": b, "racked": len(rep.placed), "pams": len(des.pams),
                     **{k: res.summary[k] for k in FIGURES}})
        print(json.dumps(rows[-1]), flush=True)
    return rows


def plot(sweep_rows: list[dict], designs: dict[str, dict], png: str) -> None:
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.6))
    x = [r["bracket_max_mm"] for r in sweep_rows]
    a = ax[0]
    a.plot(x, [r["racked"] for r in sweep_rows], "o-", label="PAMs on racks (of %d)" % sweep_rows[0]["pams"])
    a.plot(x, [r["pam_body_pairs_closer_than_gap"] for r in sweep_rows], "s-", label="body pairs < 5 mm apart")
    a.plot(x, [r["pam_bodies_near_bone"] for r in sweep_rows], "^-", label="bodies < 5 mm from bone")
    a.set_xlabel("longest bracket allowed [mm]")
    a.set_title("default optimised design hung on racks: the bracket rule")
    a.legend()
    a.grid(alpha=0.3)
    b = ax[1]
    names = list(designs)
    keys = [("random_nrmse_median", "NRMSE median ×100"), ("capacity_directions_met", "capacity directions met"),
            ("mass_kg", "mass [kg]"), ("pam_body_pairs_closer_than_gap", "body pairs < 5 mm / 4")]
    scale = {"random_nrmse_median": 100.0, "pam_body_pairs_closer_than_gap": 0.25}
    w = 0.8 / len(keys)
    for i, (k, label) in enumerate(keys):
        vals = [designs[n][k] * scale.get(k, 1.0) for n in names]
        b.bar([j + i * w for j in range(len(names))], vals, w, label=label)
    b.set_xticks([j + 0.4 - w / 2 for j in range(len(names))], names, fontsize=8)
    b.set_title("what the rules cost in the scored objectives (audited)")
    b.legend(fontsize=8)
    b.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("args", nargs="+")
    p.add_argument("--brackets", default="20,30,40,50,60")
    p.add_argument("--quick", action="store_true")
    p.add_argument("--plot", action="store_true")
    a = p.parse_args(argv)
    if a.plot:
        rows = json.loads(Path(a.args[0]).read_text())
        designs = {}
        for item in a.args[1:-1]:
            label, path = item.split("=", 1)
            designs[label] = json.loads(Path(path).read_text())["summary"]
        plot(rows, designs, a.args[-1])
        return 0
    rows = sweep(a.args[0], [float(v) for v in a.brackets.split(",")], a.quick)
    Path(a.args[1]).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
