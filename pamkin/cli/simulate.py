"""``pamkin simulate``: a robot design in MuJoCo, walking on a harness or standing."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parsers(sub) -> None:
    s = sub.add_parser(
        "simulate", help="simulate a robot design in MuJoCo: harness walk along the trial, or standing",
        description="Convert a design to MuJoCo (as pamkin mjcf --design) with foot contacts on a floor, PAM "
                    "forces from the Festo force law at the tendons' lengths and first-order pressure dynamics, "
                    "and simulate it; the pressure commands are updated every 2 ms. walk: the pelvis is welded to a "
                    "harness that follows the walking trial's pelvis, its height regulated so that it carries "
                    "--support of the body weight (or rigid on the trial's pelvis with --rigid-harness), the feet "
                    "on a treadmill belt at the trial's speed; pressures are pamkin gait's plan plus a PD feedback "
                    "distributed over the PAMs (damped least squares through the moment arms), a swinging foot's "
                    "gains lowered. stand: the free robot from a standing pose with its centre of mass "
                    "over the feet; pressures holding the pose statically with the antagonists co-contracted near "
                    "--cocontraction, plus a low-gain PD feedback and a centre-of-mass balance term on the ankles. "
                    "Writes a run folder: timeseries.csv/.npz, summary.json, tracking.png, pressures.png, "
                    "animation.html.")
    s.add_argument("design", nargs="?", default=None,
                   help="design file, 'thesis' or 'robot' (default: the robot's design robot/data/thesis_design.yaml)")
    s.add_argument("--mode", choices=("walk", "stand"), default="walk", help="what to simulate (default walk)")
    s.add_argument("--out", metavar="DIR", required=True, help="run folder (refused if it exists unless --force)")
    s.add_argument("--force", action="store_true", help="replace an existing run folder whole (default: refuse)")
    s.add_argument("--duration", type=float, default=10.0, help="stand: simulated time [s] (default 10)")
    s.add_argument("--pressure", type=float, default=None,
                   help="stand: a constant feedforward pressure of every PAM [kPa] (default: the pressures "
                        "holding the pose statically, each foot carrying half the weight, co-contracted)")
    s.add_argument("--cocontraction", type=float, default=400.0,
                   help="stand: pressure level [kPa] the static-equilibrium pressures are kept near (antagonists "
                        "pressurised: intrinsic stiffness without the pressure lag; default 400; 0: least effort)")
    s.add_argument("--k-com", type=float, default=2000.0,
                   help="stand: centre-of-mass balance stiffness on both ankles together [N·m/m] (default 2000; 0: "
                        "no balance term)")
    s.add_argument("--d-com", type=float, default=300.0,
                   help="stand: centre-of-mass balance damping on both ankles together [N·m·s/m] (default 300)")
    s.add_argument("--tau", type=float, default=None, help="pressure time constant [s] (default 0.05)")
    s.add_argument("--kp", type=float, default=None,
                   help="PD stiffness [N·m/rad] before per-joint scaling (default: walk 1600, stand 400)")
    s.add_argument("--kd", type=float, default=None,
                   help="PD damping [N·m·s/rad] before scaling (default: walk 80, stand 30)")
    s.add_argument("--floor-offset", type=float, default=0.0,
                   help="walk: floor this far below the lowest foot point of the trial [m], negative: above "
                        "(default 0)")
    s.add_argument("--lead", type=float, default=1.0,
                   help="walk: command the plan this many pressure time constants ahead (default 1; 0: no lead)")
    s.add_argument("--ground", action="store_true",
                   help="walk: lower the pelvis frame by frame until the loaded feet touch the floor (default: the "
                        "trial's pelvis height; the harness regulation adds its offset to either)")
    s.add_argument("--support", type=float, default=0.1,
                   help="walk: share of the body weight the harness is regulated to carry (its height follows the "
                        "trial's pelvis plus an offset integrated from the load error; default 0.1)")
    s.add_argument("--admittance", type=float, default=300.0,
                   help="walk: admittance damping of the harness height [N·s/m]: offset rate = -(load - support x "
                        "weight) / admittance (default 300)")
    s.add_argument("--rigid-harness", action="store_true",
                   help="walk: the harness rigid on the trial's pelvis (no load regulation; --support ignored; "
                        "default: its height regulated on the measured load)")
    s.add_argument("--no-treadmill", action="store_true",
                   help="walk: a fixed floor (default: a treadmill belt at the trial's speed, as the trial was recorded "
                        "on a treadmill: its pelvis does not advance)")
    s.add_argument("--swing-scale", type=float, default=0.5,
                   help="walk: multiplier of a swinging foot's ankle, subtalar and mtp gains (default 0.5; 1: the "
                        "same gains in swing and stance)")
    s.set_defaults(func=cmd_simulate)


def cmd_simulate(args: argparse.Namespace) -> int:
    from pamkin.errors import ParameterError  # noqa: PLC0415
    from pamkin.outputs import check_output_folder  # noqa: PLC0415
    from pamkin.sim import pams  # noqa: PLC0415

    tau = pams.TAU if args.tau is None else args.tau
    if not 0 < tau <= 1:
        raise ParameterError(f"--tau must be in (0, 1] s, got {tau}")
    if not 0 < args.duration <= 120:
        raise ParameterError(f"--duration must be in (0, 120] s, got {args.duration}")
    if args.pressure is not None and not 0 <= args.pressure <= pams.P_MAX / 1e3:
        raise ParameterError(f"--pressure must be in [0, 620] kPa, got {args.pressure}")
    for name in ("kp", "kd"):
        v = getattr(args, name)
        if v is not None and not 0 <= v <= 1e5:
            raise ParameterError(f"--{name} must be in [0, 1e5], got {v}")
    if not -0.1 <= args.floor_offset <= 0.5:
        raise ParameterError(f"--floor-offset must be in [-0.1, 0.5] m, got {args.floor_offset}")
    if not 0 < args.swing_scale <= 2:
        raise ParameterError(f"--swing-scale must be in (0, 2], got {args.swing_scale}")
    if not 0 <= args.support <= 1:
        raise ParameterError(f"--support must be in [0, 1] of the body weight, got {args.support}")
    if not 100 <= args.admittance <= 1e7:
        raise ParameterError(f"--admittance must be in [100, 1e7] N·s/m, got {args.admittance}")
    if not 0 <= args.cocontraction <= pams.P_MAX / 1e3:
        raise ParameterError(f"--cocontraction must be in [0, 620] kPa, got {args.cocontraction}")
    for name in ("k_com", "d_com"):
        v = getattr(args, name)
        if not 0 <= v <= 1e5:
            raise ParameterError(f"--{name.replace('_', '-')} must be in [0, 1e5], got {v}")
    if not 0 <= args.lead <= 5:
        raise ParameterError(f"--lead must be in [0, 5] time constants, got {args.lead}")
    check_output_folder(args.out, args.force)              # before any work
    from pamkin.robot.biped import design_robot  # noqa: PLC0415
    from pamkin.sim.convert import convert_robot  # noqa: PLC0415
    from pamkin.sim.runs import write_run  # noqa: PLC0415
    from pamkin.sim.simulate import harness_walk, stand  # noqa: PLC0415

    robot = design_robot(None if args.design in (None, "robot") else args.design)
    conv = convert_robot(robot, couplings="quartic")
    if args.mode == "walk":
        res = harness_walk(robot, conv, tau=tau, kp=args.kp, kd=args.kd, floor_offset=args.floor_offset,
                           lead=args.lead, ground=args.ground, admittance=args.admittance,
                           support=None if args.rigid_harness else args.support, treadmill=not args.no_treadmill,
                           swing_scale=args.swing_scale)
    else:
        pressure = None if args.pressure is None else args.pressure * 1e3
        res = stand(robot, conv, duration=args.duration, pressure=pressure, tau=tau, kp=args.kp, kd=args.kd,
                    cocontraction=args.cocontraction * 1e3, k_com=args.k_com, d_com=args.d_com)
    write_run(conv, res, Path(args.out), args.force, res.summary.get("weight_N"))
    s = res.summary
    rms = ", ".join(f"{c} {s['angle_rms_deg'][c]:.1f}°" for c in s["tracked"])
    print(f"wrote {args.out}: {res.kind} of {robot.design.name}, {res.times[-1]:.2f} s simulated; angle RMS {rms}")
    if res.kind == "harness_walk":
        print(f"harness carries {100 * s['harness_mean_vertical_load_fraction']:.0f} % of body weight on average "
              f"(goal <= 20 %; it pushes down {100 * s['harness_push_time_fraction']:.0f} % of the time); "
              f"tracking goal <= 5°: {'met' if s['tracked_rms_max_deg'] <= 5 else 'NOT met'}")
    else:
        print(f"stayed up: {s['stayed_up']}; pelvis drift {100 * s['pelvis_horizontal_drift_max_m']:.1f} cm, "
              f"drop {100 * s['pelvis_drop_max_m']:.1f} cm (goal: up 10 s, drift <= 5 cm)")
    return 0
