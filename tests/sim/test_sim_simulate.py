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
    return robot, convert_robot(robot, couplings="quartic")


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
    """Rigid harness on the trial's pelvis over 0.3 s (its first tenth of a second is the start transient): the
    feedback keeps every tracked joint within 7.5° RMS, the plan alone drifts far beyond."""
    robot, conv = robot_conv
    window = {"time_range": (0.5, 0.8), "support": None}
    open_loop = harness_walk(robot, conv, kp=0.0, kd=0.0, **window).summary
    closed = harness_walk(robot, conv, **window).summary
    assert closed["tracked_rms_max_deg"] < 7.5 < open_loop["tracked_rms_max_deg"]
    assert closed["duration_s"] == pytest.approx(0.3, abs=0.02)


def test_harness_walk_meets_the_goal(robot_conv):
    """The whole trial window (1.1 s) with the defaults (regulated harness, treadmill, swing gains): hip, knee and
    ankle within issue 45's 5° RMS and the harness carrying at most 20 % of the weight on average (measured
    2026-11-29: 3.9° and 10 %)."""
    robot, conv = robot_conv
    s = harness_walk(robot, conv).summary
    assert s["tracked_rms_max_deg"] <= 5.0
    assert 0.0 < s["harness_mean_vertical_load_fraction"] <= 0.2
    assert 0.9 < s["treadmill_speed_m_per_s"] < 1.2


def test_treadmill_belt_moves_at_its_speed(robot_conv):
    """The belt's slide joint advances at −belt_speed while the robot falls towards it from 1 m above; the robot's
    mass excludes the 8 t belt (Gait2392: 75.16 kg)."""
    robot, conv = robot_conv
    q0 = robot.model.default_q
    scene = build_scene(conv, robot, None, floor=-1.0, belt_speed=1.25)
    scene.set_pose(q0)
    for _ in range(100):
        scene.step()
    assert scene.data.qpos[scene.belt_dof] == pytest.approx(-0.125, rel=1e-9)
    assert scene.mass() == pytest.approx(75.16, abs=0.01)


def test_regulated_harness_carries_its_target_share(robot_conv):
    """The load-regulated harness moves its height by the integrated load error: over a 0.3 s window where the
    rigid harness carries 83 % of the weight, asked for half or none of it, it carries that share within 5 % of
    the weight (measured 50 % and 2 %; the load is the weld's own force in every case)."""
    robot, conv = robot_conv
    window = {"time_range": (0.5, 0.8)}
    rigid = harness_walk(robot, conv, support=None, **window).summary["harness_mean_vertical_load_fraction"]
    assert rigid > 0.7
    for share in (0.5, 0.0):
        res = harness_walk(robot, conv, support=share, **window)
        assert res.summary["harness_mean_vertical_load_fraction"] == pytest.approx(share, abs=0.05)
        assert res.harness_offset.min() < -0.005                    # lowered: the legs take the rest


def test_harness_offset_integrates_the_load_error():
    """d(offset)/dt = −(F − s·W)/c, bounded (hand calculation)."""
    from pamkin.sim.harness import OFFSET_MIN, Harness

    h = Harness(0.001, np.tile(np.eye(4), (3, 1, 1)), weight=700.0, support=0.1, admittance=1000.0)
    h.update(170.0, 0.01)                                  # 100 N above the 70 N target for 10 ms: −1 mm
    assert h.offset == pytest.approx(-0.001)
    h.update(1e6, 1.0)
    assert h.offset == OFFSET_MIN
    rigid = Harness(0.001, np.tile(np.eye(4), (3, 1, 1)), weight=700.0, support=None)
    rigid.update(500.0, 1.0)
    assert rigid.offset == 0.0 and rigid.pose(0.0)[0].tolist() == [0.0, 0.0, 0.0]


def test_standing_stays_up_with_cocontraction_and_balance(robot_conv):
    """1.5 s of standing (the default controller: co-contracted static feedforward, low-gain PD, centre-of-mass
    balance on the ankles): the pelvis drifts < 3 cm and drops < 5 cm; without the balance term and co-contraction
    (the least-effort static pressures, PD only) it drifts more than twice as far."""
    from pamkin.sim.simulate import stand

    robot, conv = robot_conv
    s = stand(robot, conv, duration=1.5).summary
    assert s["stayed_up"] and s["pelvis_horizontal_drift_max_m"] < 0.03 and s["pelvis_drop_max_m"] < 0.05
    bare = stand(robot, conv, duration=1.5, cocontraction=0.0, k_com=0.0, d_com=0.0).summary
    assert bare["pelvis_horizontal_drift_max_m"] > 2 * s["pelvis_horizontal_drift_max_m"]


def test_simulate_cli_writes_the_run_folder(tmp_path, capsys):
    out = tmp_path / "stand"
    assert main(["simulate", "--mode", "stand", "--duration", "0.2", "--out", str(out)]) == 0
    assert "stayed up" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["kind"] == "stand" and summary["duration_s"] == 0.2
    rows = (out / "timeseries.csv").read_text().splitlines()
    assert rows[0].startswith("t_s,") and len(rows) == 1 + 101          # 0.2 s at the 2 ms control period
    data = np.load(out / "timeseries.npz")
    assert data["pressures"].shape == (101, 54) and (data["pressures"] <= 620e3).all()
    assert (out / "animation.html").read_text().startswith("<!DOCTYPE html>")
    for png in ("tracking.png", "pressures.png"):
        assert (out / png).stat().st_size > 10_000
    assert main(["simulate", "--mode", "stand", "--out", str(out)]) == 2          # exists: refused
    assert main(["simulate", "--tau", "0", "--out", str(tmp_path / "x")]) == 2
    assert "--tau" in capsys.readouterr().err and not (tmp_path / "x").exists()
    assert main(["simulate", "--support", "1.5", "--out", str(tmp_path / "x")]) == 2
    assert "--support" in capsys.readouterr().err and not (tmp_path / "x").exists()
    assert main(["simulate", "--swing-scale", "0", "--out", str(tmp_path / "x")]) == 2
    assert "--swing-scale" in capsys.readouterr().err and not (tmp_path / "x").exists()


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
