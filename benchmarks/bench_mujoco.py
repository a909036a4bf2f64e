"""Benchmark of the MuJoCo robot simulation (goal: ≥ 1× real time on one core with every PAM's force).

Usage: ``python benchmarks/bench_mujoco.py [DESIGN] [SECONDS]`` (default: the robot's design, 2 s of simulated
time). Builds the scene (both legs, every PAM, foot contacts on a floor, standing pose, 1 ms steps), then
times the same number of steps three ways in this process: MuJoCo alone (``mj_step``, no PAM forces), with the
PAM forces (``Scene.step``: Festo force law per step, pressure lag), and the whole ``stand`` simulation (PAM
forces and the 500 Hz pressure controller, :mod:`pamkin.sim.control`), and prints steps/s, the ratio to MuJoCo's
own rate and the real-time factor (simulated seconds per wall-clock second). One thread (``OMP/MKL``
threads are not used by MuJoCo's stepping).
"""

from __future__ import annotations

import sys
import time
import warnings

import mujoco
import numpy as np

from pamkin.robot.biped import design_robot
from pamkin.sim.convert import convert_robot
from pamkin.sim.scene import build_scene
from pamkin.sim.simulate import stand


def main(argv: list[str]) -> None:
    design = argv[0] if argv else None
    seconds = float(argv[1]) if len(argv) > 1 else 2.0
    warnings.simplefilter("ignore")
    robot = design_robot(design)
    conv = convert_robot(robot, couplings="quartic")
    q0 = robot.model.default_q
    scene = build_scene(conv, robot, q0[None])
    n = int(round(seconds / scene.model.opt.timestep))
    print(f"{robot.design.name}: {scene.model.nv} dofs, {len(robot.names)} PAMs, {scene.model.ngeom} geoms, "
          f"timestep {scene.model.opt.timestep * 1e3:g} ms, {n} steps")

    def run(with_pams: bool) -> float:
        scene.set_pose(q0)
        scene.drive.pressure[:] = 200e3
        scene.drive.command[:] = 200e3
        scene.data.ctrl[:] = 0.0
        t = time.perf_counter()
        if with_pams:
            for _ in range(n):
                scene.step()
        else:
            for _ in range(n):
                mujoco.mj_step(scene.model, scene.data)
        return n / (time.perf_counter() - t)

    run(True)                                  # warm-up
    bare = run(False)
    pams = run(True)
    real = 1.0 / scene.model.opt.timestep
    print(f"MuJoCo alone:    {bare:9.0f} steps/s ({bare / real:.1f}x real time)")
    print(f"with PAM forces: {pams:9.0f} steps/s ({pams / real:.1f}x real time; {pams / bare:.2f} of MuJoCo's rate)")
    t = time.perf_counter()
    res = stand(robot, conv, duration=seconds)
    ctrl = n / (time.perf_counter() - t - 0.0)
    print(f"with PAM forces and the pressure controller (pamkin simulate --mode stand, scene build included): "
          f"{ctrl:9.0f} steps/s ({ctrl / real:.1f}x real time; {ctrl / bare:.2f} of MuJoCo's rate)")
    print(f"goal >= 1x real time: {'met' if min(pams, ctrl) >= real else 'NOT met'}")
    assert len(res.times) > 0
    assert np.isfinite(scene.data.qpos).all()


if __name__ == "__main__":
    main(sys.argv[1:])
