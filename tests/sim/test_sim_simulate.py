"""Simulations (pamkin.sim.scene, simulate, runs): the harness force is what holds the body, the PAM feedback
tracks better than the plan alone, and `pamkin simulate` writes its run folder."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from pamkin.cli import main
from pamkin.robot.biped import design_robot
from pamkin.sim.convert import convert_robot
from pamkin.sim.scene import build_scene
from pamkin.sim.simulate import harness_walk


@pytest.fixture(scope="module")
def robot_conv():
    robot = design_robot()
    return robot, convert_robot(robot)


def test_harness_force_balances_momentum(robot_conv):
    """Feet off the floor: the harness force's impulse equals the body's change of momentum plus gravity's
    impulse (Newton, from MuJoCo's own subtree momentum): its sign and size are the force on the body."""
    robot, conv = robot_conv
    q0 = robot.model.default_q.copy()
    low = q0.copy()
    low[robot.model.coordinates.index("pelvis_ty")] -= 0.3          # the floor 0.3 m below the feet
    scene = build_scene(conv, robot, low[None], harness=True)
    m, d = scene.model, scene.data
    scene.data.mocap_pos[0] = [0.0, q0[robot.model.coordinates.index("pelvis_ty")], 0.0]
    scene.set_pose(q0)
    mass = m.body_subtreemass[0]

    def momentum():
        mujoco.mj_subtreeVel(m, d)
        return mass * d.subtree_linvel[0].copy()

    for _ in range(200):
        scene.step()
    P0, impulse, n = momentum(), np.zeros(3), 500
    for _ in range(n):
        scene.step()
        impulse += scene.harness_force() * m.opt.timestep
    dP = momentum() - P0
    gravity = mass * np.array(m.opt.gravity) * n * m.opt.timestep
    assert np.allclose(impulse + gravity, dP, atol=0.02 * mass * 9.81 * n * m.opt.timestep)
    assert impulse[1] > 0.5 * mass * 9.80665 * n * m.opt.timestep             # it holds the body up


def test_feedback_tracks_better_than_the_plan_alone(robot_conv):
    robot, conv = robot_conv
    window = {"time_range": (0.5, 0.8)}
    open_loop = harness_walk(robot, conv, kp=0.0, kd=0.0, **window).summary
    closed = harness_walk(robot, conv, **window).summary
    assert closed["tracked_rms_max_deg"] < open_loop["tracked_rms_max_deg"]
    assert closed["duration_s"] == pytest.approx(0.3, abs=0.02)


def test_simulate_cli_writes_the_run_folder(tmp_path, capsys):
    out = tmp_path / "stand"
    assert main(["simulate", "--mode", "stand", "--duration", "0.2", "--out", str(out)]) == 0
    assert "stayed up" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["kind"] == "stand" and summary["duration_s"] == 0.2
    rows = (out / "timeseries.csv").read_text().splitlines()
    assert rows[0].startswith("t_s,") and len(rows) == 1 + 41           # 0.2 s at the 5 ms control period
    data = np.load(out / "timeseries.npz")
    assert data["pressures"].shape == (41, 54) and (data["pressures"] <= 620e3).all()
    assert (out / "animation.html").read_text().startswith("<!DOCTYPE html>")
    for png in ("tracking.png", "pressures.png"):
        assert (out / png).stat().st_size > 10_000
    assert main(["simulate", "--mode", "stand", "--out", str(out)]) == 2          # exists: refused
    assert main(["simulate", "--tau", "0", "--out", str(tmp_path / "x")]) == 2
    assert "--tau" in capsys.readouterr().err and not (tmp_path / "x").exists()


def test_feedback_pressures_produce_the_asked_torque(robot_conv):
    """The controller's pressure change realises the requested torque about each coordinate (Festo law and
    MuJoCo's moment arms, pressures within 0-620 kPa), with little torque about the others."""
    from pamkin.sim.control import PressureController

    robot, conv = robot_conv
    q0 = robot.model.default_q
    scene = build_scene(conv, robot, q0[None])
    scene.set_pose(q0)
    drive = scene.drive
    ctrl = PressureController.for_drive(drive, [c for c in drive.coordinates if not c.startswith("pelvis_")])
    drive.pressure[:] = 200e3
    mujoco.mj_fwdPosition(scene.model, scene.data)

    def torques(p):
        return drive.generalized_forces(scene.data, drive.tension(scene.data.ten_length[drive.tendons], p))

    base = torques(drive.pressure)
    for c in ("hip_flexion_r", "knee_angle_l", "ankle_angle_r", "lumbar_extension"):
        k = ctrl.coordinates.index(c)
        tau = np.zeros(len(ctrl.columns))
        tau[k] = 20.0
        dp = ctrl.feedback(drive, scene.data, None, None, drive.pressure.copy(), tau=tau)
        assert (drive.pressure + dp >= -1e-6).all() and (drive.pressure + dp <= 620e3 + 1e-6).all()
        got = (torques(drive.pressure + dp) - base)[ctrl.columns]
        assert got[k] == pytest.approx(20.0, rel=0.1), c
        assert np.abs(np.delete(got, k)).max() < 2.0, c
