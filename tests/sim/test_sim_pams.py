"""PAM actuators in MuJoCo (pamkin.sim.pams): joint torques equal pamkin's PAM torques at the same pressures,
pressure dynamics and limits."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from pamkin.robot.biped import design_robot
from pamkin.sim.convert import convert_robot
from pamkin.sim.measure import exact_constructs
from pamkin.sim.pams import P_MAX, PamDrive


@pytest.fixture(scope="module")
def setup():
    robot = design_robot()
    conv = convert_robot(robot, couplings="quartic")
    return robot, conv, conv.compile()


def _coordinate_torques(conv, model, data, q):
    """The applied generalized forces mapped to the coordinates: τ = (∂qpos/∂q)ᵀ qfrc_applied."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j.name) for j in conv.cmap.joints]
    G = conv.cmap.dqpos_dq(q[None])[0]
    return G.T @ data.qfrc_applied[model.jnt_dofadr[ids]]


@pytest.mark.parametrize("pressure", [0.0, 250e3, P_MAX])
def test_joint_torques_equal_pamkin(setup, pressure):
    robot, conv, model = setup
    data = mujoco.MjData(model)
    drive = PamDrive(robot, model, conv.cmap)
    exact = exact_constructs(conv)
    q = robot.model.random_q(6, seed=21)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j.name) for j in conv.cmap.joints]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = robot.evaluate(q, pressure=pressure)
    for n in range(len(q)):
        data.qpos[model.jnt_qposadr[ids]] = conv.cmap.qpos(q[n])[0]
        mujoco.mj_fwdPosition(model, data)
        drive.pressure[:] = pressure
        T = drive.apply(data)
        assert np.allclose(T[exact], ref.forces[n, exact], rtol=1e-12, atol=1e-9)
        tau_all = _coordinate_torques(conv, model, data, q[n])       # what MuJoCo integrates
        # exact routes only: equal to round-off
        tau = drive.generalized_forces(data, np.where(exact, T, 0.0))
        cols = [robot.coordinates.index(c) for c in drive.coordinates]
        tau_ref = ref.torques[n, exact].sum(axis=0)
        scale = max(np.abs(tau_ref).max(), 1.0)
        assert np.abs(tau - tau_ref[cols]).max() <= 1e-9 * scale
        # all PAMs: the approximated routes (patella point, knee polynomial) within 10 % of the peak torque
        # (measured: 8.1 % at 620 kPa, 6.0 % at 100 kPa on 200 poses; the knee extensors near full extension)
        ref_all = ref.torques[n].sum(axis=0)
        assert np.abs(tau_all - ref_all).max() <= 0.10 * max(np.abs(ref_all).max(), 1.0)
        assert np.allclose(tau_all[cols], drive.generalized_forces(data, T), rtol=1e-12, atol=1e-9)


def test_pressure_lag_and_limits(setup):
    robot, conv, model = setup
    drive = PamDrive(robot, model, conv.cmap, tau=0.04)
    drive.command[:] = 300e3
    drive.command[0] = 900e3          # above the valve limit: clipped to 620 kPa
    drive.command[1] = -50e3          # below 0: clipped
    for _ in range(40):
        drive.advance(0.001)
    lag = 1 - np.exp(-0.04 / 0.04)
    assert drive.pressure[2] == pytest.approx(300e3 * lag, rel=1e-12)
    assert drive.pressure[0] == pytest.approx(P_MAX * lag, rel=1e-12)
    assert drive.pressure[1] == 0.0
    with pytest.raises(ValueError, match="tau"):
        PamDrive(robot, model, conv.cmap, tau=0.0)
    with pytest.raises(ValueError, match="p_max"):
        PamDrive(robot, model, conv.cmap, p_max=800e3)
