"""Kinematics of the generated Gait2392 URDF against OpenSim 4.6, Pinocchio and finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from opensim_ref import opensim_reference

N_CONFIGS = 200


@pytest.mark.opensim
def test_body_transforms_match_opensim(gait2392, gait2392_path):
    q = gait2392.random_q(N_CONFIGS, seed=11)
    ref = opensim_reference(gait2392_path, q, what=("transforms",))
    assert list(ref["bodies"]) == gait2392.bodies
    assert list(ref["coordinates"]) == gait2392.coordinates
    T = gait2392.body_transforms(q)
    assert len(T) == 12
    R = np.stack([T[b][:, :3, :3] for b in gait2392.bodies], axis=1)
    p = np.stack([T[b][:, :3, 3] for b in gait2392.bodies], axis=1)
    pos_err = np.abs(p - ref["p"]).max()
    rot_err = np.abs(R - ref["R"]).max()
    print(f"max position error {pos_err:.2e} m, max rotation element error {rot_err:.2e}")
    assert pos_err <= 1e-9
    assert rot_err <= 1e-9


def test_batched_equals_pinocchio(gait2392):
    q = gait2392.random_q(50, seed=12)
    st = gait2392.forward(q)
    R, p = gait2392.kinematics.pinocchio_placements(q)
    assert np.abs(st.body_p - p).max() < 1e-12
    assert np.abs(st.body_R - R).max() < 1e-12


@pytest.mark.parametrize("body", ["tibia_r", "toes_l", "torso", "calcn_r", "femur_l", "pelvis"])
def test_point_jacobian_matches_finite_differences(gait2392, body):
    kin = gait2392.kinematics
    q = gait2392.random_q(20, seed=13)
    point = np.array([0.02, -0.15, 0.03])
    J = gait2392.point_jacobian(q, body, point)
    assert J.shape == (20, 3, 23)
    h = 1e-6
    b = gait2392.bodies.index(body)
    Jfd = np.zeros_like(J)
    for c in range(23):
        dq = np.zeros(23)
        dq[c] = h
        xp = kin.point_positions(kin.forward(q + dq, warn_range=False), b, point[None])[:, 0]
        xm = kin.point_positions(kin.forward(q - dq, warn_range=False), b, point[None])[:, 0]
        Jfd[:, :, c] = (xp - xm) / (2 * h)
    assert np.abs(J - Jfd).max() <= 1e-7
    # and Pinocchio's own frame Jacobian, chained through the couplings
    Jpin = kin.pinocchio_point_jacobian(q, body, point)
    assert np.abs(J - Jpin).max() <= 1e-12


def test_knee_coupling_moves_tibia(gait2392):
    """Knee angle translates the tibia through the SimmSpline functions (chain rule)."""
    kin = gait2392.kinematics
    q = np.tile(gait2392.default_q, (1, 1))
    J = gait2392.point_jacobian(q, "tibia_r", [0.0, 0.0, 0.0])[0]
    knee = gait2392.coordinates.index("knee_angle_r")
    # origin of the tibia frame moves with knee angle only through the spline translations
    v, dv = kin.joint_values(q)
    names = [gait2392.pin_model.names[j + 1] for j in range(kin.n_joints)]
    slope_x = dv[0, names.index("knee_r_translation1")]
    slope_y = dv[0, names.index("knee_r_translation2")]
    T = gait2392.body_transforms(q)["femur_r"][0]
    expected = T[:3, :3] @ np.array([slope_x, slope_y, 0.0])
    assert np.allclose(J[:, knee], expected, atol=1e-14)


def test_single_configuration_and_mapping(gait2392):
    q1 = gait2392.default_q
    T1 = gait2392.body_transforms(q1)
    assert T1["pelvis"].shape == (1, 4, 4)
    T2 = gait2392.body_transforms({"pelvis_ty": 0.95, "knee_angle_r": np.array([0.0, -1.0])})
    assert T2["tibia_r"].shape == (2, 4, 4)
    assert np.allclose(T2["pelvis"][0], T1["pelvis"][0])
    assert not np.allclose(T2["tibia_r"][0], T2["tibia_r"][1])
