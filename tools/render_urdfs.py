"""Render the built-in URDFs with their bone meshes into docs/ (pictures shown in the README).

    python tools/render_urdfs.py [--out docs]

Writes ``urdf_gait2392.png`` and ``urdf_pam_biped.png``: the meshes yourdfpy loads from each
URDF, every OpenSim coordinate 0 (URDF joint values from pamkin's coordinate mapping: the knee
translations follow knee angle), front and side views (matplotlib; no display needed).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pamkin
from pamkin.human.meshes import render_urdf, urdf_configuration
from pamkin.human.urdf import GAIT2392_URDF, ROBOT_URDF

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs"), help="output folder (default: docs/ of the checkout)")
    args = ap.parse_args()
    pose = urdf_configuration(pamkin.gait2392())
    for urdf in (GAIT2392_URDF, ROBOT_URDF):
        print(f"wrote {render_urdf(urdf, Path(args.out) / f'urdf_{urdf.stem}.png', configuration=pose)}")


if __name__ == "__main__":
    main()
