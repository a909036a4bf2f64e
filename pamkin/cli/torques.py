"""``pamkin torques``: human muscle torques over a range-of-motion grid."""

from __future__ import annotations

import argparse

import numpy as np


def add_parsers(sub) -> None:
    s = sub.add_parser(
        "torques",
        help="human muscle torques, group torques and capacity envelopes over a coordinate grid",
        description="Evaluate the human model (Thelen2003 static equilibrium at full activation) over a "
                    "grid of coordinates within a range of motion, and print per-coordinate capacity "
                    "envelopes (sum of positive / negative muscle torques) and the peak torques of the "
                    "thesis groups and the 27 robot-actuator groups.")
    s.add_argument("--osim", help="an .osim file (default: built-in Gait2392)")
    s.add_argument("--rom", default="robot_thesis",
                   help="range of motion from robot/data/rom.yaml: human_thesis, robot_thesis (default), "
                        "robot_2026")
    s.add_argument("--side", default="r", choices=("r", "l"), help="leg side (default r)")
    s.add_argument("--coords", default="hip_flexion,knee_angle",
                   help="comma-separated grid coordinates, side suffix optional "
                        "(default hip_flexion,knee_angle)")
    s.add_argument("-n", type=int, default=21, help="grid points per coordinate, 2..201; the grid (n^coordinates "
                                                  "poses) must fit in memory (default 21)")
    s.add_argument("--activation", type=float, default=1.0, help="activation of every muscle, in [0, 1] (default: 1)")
    s.add_argument("--json", action="store_true", help="machine-readable output (default: tables)")
    s.set_defaults(func=cmd_torques)


def cmd_torques(args: argparse.Namespace) -> int:
    from pamkin.cli import _load  # noqa: PLC0415
    from pamkin.cli.bounds import check_count, check_memory  # noqa: PLC0415
    from pamkin.errors import ConfigurationError  # noqa: PLC0415
    from pamkin.human.groups import load_groups  # noqa: PLC0415
    from pamkin.human.rom import load_rom  # noqa: PLC0415
    from pamkin.outputs import strict_json  # noqa: PLC0415

    model = _load(args.osim)
    rom = load_rom(args.rom, args.side)
    coords = []
    for c in args.coords.split(","):
        c = c.strip()
        name = c if c in model.coordinates else f"{c}_{args.side}"
        if name not in model.coordinates:
            raise ConfigurationError(f"unknown coordinate {c!r}; valid: {model.coordinates}")
        coords.append(name)
    check_count("-n", args.n, 2, 201)
    check_memory(f"torques on a {args.n}^{len(coords)} grid", args.n ** len(coords), 3 * 8 * len(model.muscles)
                 * len(model.coordinates))
    if not 0.0 <= args.activation <= 1.0:
        raise ConfigurationError("--activation must lie in [0, 1]")
    grid = rom.grid(coords, args.n)
    q = np.tile(model.default_q, (len(grid), 1))
    for i, c in enumerate(coords):
        q[:, model.coordinates.index(c)] = grid[:, i]
    pos, neg = model.capacity(q, args.activation)
    groups = [g for g in load_groups(sides=(args.side,)) if all(m in model.muscles for m in g.muscles)]
    gt = model.group_torques(q, groups, args.activation)
    shown = [c for c in model.coordinates if c.endswith(f"_{args.side}") or c.startswith("lumbar")]
    result = {
        "model": model.osim.name, "rom": rom.name, "grid_coordinates": coords, "n_configurations": len(q),
        "capacity_Nm": {c: {"max_positive": float(pos[:, model.coordinates.index(c)].max()),
                            "min_negative": float(neg[:, model.coordinates.index(c)].min())} for c in shown},
        "groups_Nm": {},
    }
    for g in groups:
        cols = [g.primary_coordinate] if g.primary_coordinate else coords
        T = gt[g.key]
        result["groups_Nm"][g.key] = {"label": g.label, **{
            c: [float(T[:, model.coordinates.index(c)].min()), float(T[:, model.coordinates.index(c)].max())]
            for c in cols}}
    if args.json:
        print(strict_json(result))
        return 0
    print(f"{result['model']}: {len(q)} configurations over {', '.join(coords)} ({rom.name} range of motion), "
          f"activation {args.activation:g}")
    print("\nCapacity envelopes [N·m] (sum of positive / negative muscle torques, extremes over the grid)")
    print(f"  {'coordinate':22s} {'max +':>10s} {'min -':>10s}")
    for c, v in result["capacity_Nm"].items():
        print(f"  {c:22s} {v['max_positive']:10.1f} {v['min_negative']:10.1f}")
    print("\nGroup torques [N·m] (min .. max over the grid)")
    for key, v in result["groups_Nm"].items():
        rng = "; ".join(f"{c}: {lo:8.1f} .. {hi:8.1f}" for c, (lo, hi) in
                        ((c, v[c]) for c in v if c != "label"))
        print(f"  {v['label']:38s} {rng}")
    return 0
