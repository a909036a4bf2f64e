"""Simulations of a robot design in MuJoCo: walking on a harness along a recorded trial, and standing.

* :func:`harness_walk`: the pelvis follows the trial's pelvis (the mocap body of the scene's harness weld moves
  along pamkin's pelvis placements of the trial's IK coordinates, its height regulated on the harness's load,
  :mod:`pamkin.sim.harness`), the feet meet a treadmill belt at the trial's speed (:func:`treadmill_speed`), the
  PAM pressures are ``pamkin gait``'s plan of the trial plus the PD feedback of :mod:`pamkin.sim.control` towards
  the trial's angles (a swinging foot's gains lowered). Reported: angle RMS per coordinate against the trial, the
  harness's mean vertical load as a fraction of body weight.
* :func:`stand`: the free robot (no harness) from a standing pose with the feet on the floor (:func:`standing_pose`),
  co-contracted feedforward pressures holding it statically, a low-gain PD towards that pose and a balance term
  on the centre of mass; reported: pelvis drift and whether it stays up.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np

from pamkin.errors import RangeWarning
from pamkin.gait.plan import DEFAULT_GRF, evaluate_plan, load_trial
from pamkin.opensim.storage import read_storage
from pamkin.robot.biped import PamRobot
from pamkin.sim.control import (COCONTRACTION, D_COM, K_COM, KD_STAND, KP_STAND, STAND_GAIN_SCALE, SWING_SCALE,
                                Balance, PressureController, SwingGains, cocontracted_pressures)
from pamkin.sim.harness import ADMITTANCE, SUPPORT, Harness
from pamkin.sim.inverse import foot_assignment
from pamkin.sim.convert import Conversion
from pamkin.sim.pams import TAU
from pamkin.sim.scene import Scene, build_scene

#: Control period [s] (the pressure commands are updated at this rate, 500 Hz; the physics steps at 1 ms; see
#: :mod:`pamkin.sim.control` for why not slower).
CONTROL_PERIOD = 0.002
#: Coordinates whose angle RMS is the harness walk's tracking verdict.
TRACKED = ("hip_flexion_r", "hip_flexion_l", "knee_angle_r", "knee_angle_l", "ankle_angle_r", "ankle_angle_l")
#: Frames per second of the recorded body poses (animation).
ANIMATION_FPS = 50
#: The standing robot has fallen when its pelvis is this much lower than at the start [m].
FALL_DROP = 0.25


@dataclass
class SimResult:
    """Time series of a simulation (rows: control periods).

    Attributes:
        kind: ``"harness_walk"`` or ``"stand"``.
        times: (T,) [s].
        coordinates: Coordinate names (columns of q, q_ref).
        q, q_ref: (T, n_coordinates) simulated and reference coordinates [rad, m].
        pam_names: PAM columns.
        pressures, commands: (T, n_pams) [Pa].
        tensions: (T, n_pams) route tensions [N].
        harness: (T, 3) harness force on the pelvis, world frame [N] (zeros without harness).
        pelvis: (T, 3) pelvis origin [m].
        body_poses: {body: (F, 4, 4)} placements at :data:`ANIMATION_FPS` for the animation.
        summary: Verdict numbers (JSON-ready).
        harness_offset: (T,) the regulated harness's height offset from the trial's pelvis [m] (zeros: none).
    """

    kind: str
    times: np.ndarray
    coordinates: list[str]
    q: np.ndarray
    q_ref: np.ndarray
    pam_names: list[str]
    pressures: np.ndarray
    commands: np.ndarray
    tensions: np.ndarray
    harness: np.ndarray
    pelvis: np.ndarray
    body_poses: dict[str, np.ndarray] = field(default_factory=dict)
    summary: dict = field(default_factory=dict)
    harness_offset: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _run(scene: Scene, ctrl: PressureController, duration: float, reference, feedforward,
         harness: Harness | None = None, kind: str = "", extra=None, gains: SwingGains | None = None) -> SimResult:
    """Step ``scene`` for ``duration`` s: every control period the command from the reference (t -> (q, q̇) in
    drive order), the feedforward (t -> pressures), ``extra`` (() -> extra torques on the controlled
    coordinates [N·m], optional) and the gain schedule ``gains``; ``harness`` moves the mocap body and regulates
    its height on the measured load."""
    m, d, drive = scene.model, scene.data, scene.drive
    dt = m.opt.timestep
    per = max(1, int(round(CONTROL_PERIOD / dt)))
    n = int(round(duration / dt))
    names = drive.coordinates
    rows = {k: [] for k in ("t", "q", "q_ref", "p", "u", "T", "H", "pelvis", "off")}
    bodies = [b.name for b in scene.conv.model.osim.bodies]
    bid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in bodies]
    poses = {b: [] for b in bodies}
    every = max(1, int(round(1.0 / (ANIMATION_FPS * dt))))
    T = np.zeros(len(drive.tendons))
    for k in range(n + 1):
        t = k * dt
        if k % per == 0:
            load = scene.harness_force()             # of the last step (mj_fwdPosition resets the constraint forces)
            if harness is not None and k:
                harness.update(load[1], per * dt)
            qr, qdr = reference(t)
            cols = ctrl.columns
            mujoco.mj_fwdPosition(m, d)
            err, derr = qr[cols] - scene.positions()[cols], qdr[cols] - scene.speeds()[cols]
            drive.command[:] = ctrl.command(drive, d, feedforward(t), err, derr, None if extra is None else extra(),
                                            None if gains is None else gains.gain(scene))
            for key, v in (("t", t), ("q", scene.positions()), ("q_ref", qr), ("p", drive.pressure.copy()),
                           ("u", drive.command.copy()), ("T", T.copy()), ("H", load), ("pelvis", d.xpos[bid[0]].copy()),
                           ("off", 0.0 if harness is None else harness.offset)):
                rows[key].append(v)
        if harness is not None:
            d.mocap_pos[0], d.mocap_quat[0] = harness.pose(t)
        if k % every == 0:
            for b, i in zip(bodies, bid):
                P = np.eye(4)
                P[:3, :3] = d.xmat[i].reshape(3, 3)
                P[:3, 3] = d.xpos[i]
                poses[b].append(P)
        if k < n:
            T = scene.step()
            if not np.isfinite(d.qpos).all():
                raise FloatingPointError(f"{kind}: the simulation diverged at t = {t:.3f} s")
    arr = {k: np.array(v) for k, v in rows.items()}
    return SimResult(kind, arr["t"], list(names), arr["q"], arr["q_ref"], list(scene.drive.robot.names), arr["p"],
                     arr["u"], arr["T"], arr["H"], arr["pelvis"], {b: np.array(v) for b, v in poses.items()},
                     harness_offset=arr["off"])


def grounded(scene: Scene, times: np.ndarray, q: np.ndarray, grf) -> np.ndarray:
    """The trial's coordinates with the pelvis lowered, frame by frame, until the loaded feet (the ground
    reactions' vertical force above 20 N) touch the floor, no foot going below it; smoothed over 5 frames. The
    IK belongs to the scaled subject, whose pelvis rides higher than the generic skeleton's legs reach."""
    conv, m, d = scene.conv, scene.model, scene.data
    feet = foot_assignment(conv, times, q, grf)
    st = read_storage(grf)
    side_geoms = {}
    for side in ("r", "l"):
        bodies = {m.body(f"calcn_{side}").id, m.body(f"toes_{side}").id}
        side_geoms[side] = [g for g in range(m.ngeom) if m.geom(g).name.startswith("contact")
                            and m.geom_bodyid[g] in bodies]
    low = np.zeros((len(q), 2))
    for k, qpos in enumerate(conv.cmap.qpos(q)):
        d.qpos[scene.qadr] = qpos
        mujoco.mj_kinematics(m, d)
        for j, side in enumerate(("r", "l")):
            g = side_geoms[side]
            low[k, j] = np.min(d.geom_xpos[g, 1] - m.geom_size[g, 0])
    loaded = np.zeros((len(q), 2), dtype=bool)
    for prefix, body in feet.items():
        loaded[:, 0 if body.endswith("_r") else 1] = np.interp(times, st.time,
                                                                st.data[:, st.columns.index(f"{prefix}vy")]) > 20.0
    stance = np.where(loaded, low, np.inf).min(axis=1)
    dy = np.minimum(np.where(np.isfinite(stance), stance, low.min(axis=1)), low.min(axis=1)) - scene.floor
    dy = np.convolve(np.pad(dy, 2, mode="edge"), np.ones(5) / 5, mode="valid")
    out = q.copy()
    out[:, list(conv.model.coordinates).index("pelvis_ty")] -= np.maximum(dy, 0.0)
    return out


def treadmill_speed(robot: PamRobot, conv: Conversion, times: np.ndarray, q: np.ndarray, grf) -> float:
    """The trial's treadmill speed [m/s]: the median backward speed of the loaded feet (the ground reactions'
    vertical force above 20 N) in the trial's kinematics (the pelvis stays within ±2 cm of 0.59 m forward over the
    4 s of the trial: it was recorded on a treadmill)."""
    feet = foot_assignment(conv, times, q, grf)
    st = read_storage(grf)
    placements = robot.model.body_transforms(q)
    speeds = []
    for prefix, body in feet.items():
        x = placements[body][:, 0, 3]
        loaded = np.interp(times, st.time, st.data[:, st.columns.index(f"{prefix}vy")]) > 20.0
        speeds.append(-np.gradient(x, times)[loaded])
    return float(np.median(np.concatenate(speeds)))


def harness_walk(robot: PamRobot, conv: Conversion, tau: float = TAU, kp: float | None = None,
                 kd: float | None = None, floor_offset: float = 0.0, lead: float = 1.0, ground: bool = False,
                 support: float | None = SUPPORT, admittance: float = ADMITTANCE, treadmill: bool = True,
                 swing_scale: float = SWING_SCALE, **trial) -> SimResult:
    """Walk on a harness along the trial (``trial``: keyword arguments of :func:`pamkin.gait.plan.load_trial`).

    The feedforward is the plan ``lead``·τ ahead (the pressures lag their commands by τ; 0: the plan as is). With
    ``ground`` the pelvis follows the trial lowered so that the loaded feet touch the floor (:func:`grounded`).
    The harness's height is regulated towards carrying ``support`` × the body weight with the admittance
    ``admittance`` [N·s/m] (:class:`pamkin.sim.harness.Harness`; ``support=None``: rigid on the trial's pelvis).
    With ``treadmill`` the floor is a belt running backward at :func:`treadmill_speed`, as under the subject
    (otherwise a fixed floor, on which a loaded stance foot cannot follow the trial's backward sweep). A swinging
    foot's gains are multiplied by ``swing_scale`` (:class:`pamkin.sim.control.SwingGains`; 1: no schedule).

    The floor touches the lowest foot sphere over the trial's frames, lowered by ``floor_offset`` [m] (negative:
    raised). The trial's own floor (its centres of pressure, y = −0.0075 m) is not used: the IK angles belong to
    the scaled subject, whose pelvis rides higher than the generic skeleton's legs reach (the generic feet stay
    8–9 cm above that floor over the whole trial)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RangeWarning)
        tr = load_trial(robot.model, **trial)
        plan = evaluate_plan(robot, tr)
    order = [plan.pam_names.index(n) for n in robot.names]
    P = plan.pressures[:, order]
    times = tr.times - tr.times[0]
    model = robot.model
    grf = trial.get("grf", DEFAULT_GRF)
    speed = treadmill_speed(robot, conv, tr.times, tr.q, grf) if treadmill else None
    scene = build_scene(conv, robot, tr.q, harness=True, tau=tau, floor_offset=floor_offset, belt_speed=speed)
    if ground:
        tr = replace(tr, q=grounded(scene, tr.times, tr.q, grf))
    drive = scene.drive
    cidx = [model.coordinates.index(c) for c in drive.coordinates]
    qd = np.gradient(tr.q, tr.times, axis=0)
    dt = scene.model.opt.timestep
    fine = np.arange(0.0, times[-1] + dt / 2, dt)
    qf = np.column_stack([np.interp(fine, times, tr.q[:, j]) for j in range(tr.q.shape[1])])
    weight = scene.mass() * 9.80665
    harness = Harness(dt, model.body_transforms(qf)["pelvis"], weight, support, admittance)

    def reference(t):
        return (np.array([np.interp(t, times, tr.q[:, j]) for j in cidx]),
                np.array([np.interp(t, times, qd[:, j]) for j in cidx]))

    def feedforward(t):                     # the plan τ ahead: the pressures lag the commands by τ
        return np.array([np.interp(t + lead * tau, times, P[:, j]) for j in range(P.shape[1])])

    kw = {k: v for k, v in (("kp", kp), ("kd", kd)) if v is not None}
    controlled = [c for c in drive.coordinates if c in tr.coordinates]
    ctrl = PressureController.for_drive(drive, controlled, **kw)
    scene.data.mocap_pos[0], scene.data.mocap_quat[0] = harness.pose(0.0)
    scene.set_pose(tr.q[0], qd[0])
    drive.pressure[:] = P[0]
    gains = SwingGains.for_controller(ctrl, swing_scale) if swing_scale != 1.0 else None
    res = _run(scene, ctrl, float(times[-1]), reference, feedforward, harness, "harness_walk", gains=gains)
    res.summary = _tracking_summary(res) | {
        "duration_s": float(times[-1]), "trial_start_s": float(tr.times[0]),
        "body_mass_kg": weight / 9.80665, "weight_N": weight,
        "harness_mean_vertical_load_fraction": float(np.mean(res.harness[:, 1]) / weight),
        "harness_peak_vertical_load_fraction": float(np.max(res.harness[:, 1]) / weight),
        "harness_push_time_fraction": float(np.mean(res.harness[:, 1] < 0)),
        "harness_mean_lift_fraction": float(np.mean(np.maximum(res.harness[:, 1], 0)) / weight),
        "plan_feasible_frame_fraction": float(plan.feasible_frame_fraction),
        "pressure_time_constant_s": tau, "kp": float(ctrl.kp.max()), "kd": float(ctrl.kd.max()),
        "floor_m": scene.floor, "feedforward_lead_s": lead * tau, "grounded_pelvis": ground,
        "control_period_s": CONTROL_PERIOD, "harness_target_share": support, "harness_admittance_Ns_per_m": admittance,
        "harness_offset_mean_m": float(res.harness_offset.mean()), "treadmill_speed_m_per_s": speed,
        "swing_gain_scale": swing_scale,
        "harness_offset_range_m": [float(res.harness_offset.min()), float(res.harness_offset.max())]}
    return res


def static_torques(scene: Scene, q: np.ndarray) -> np.ndarray:
    """Coordinate torques (drive order) holding the robot still at ``q`` with each foot carrying half the weight
    straight up under its contact spheres' centre (``mj_inverse`` with zero speeds and accelerations,
    constraints off; the pelvis's six are what the feet's split leaves unbalanced)."""
    m, d = scene.model, scene.data
    scene.set_pose(q)
    weight = scene.mass() * 9.80665
    ext = np.zeros(m.nv)
    for side in ("r", "l"):
        geoms = [g for g in range(m.ngeom) if m.geom(g).name.startswith("contact")
                 and m.geom_bodyid[g] in (m.body(f"calcn_{side}").id, m.body(f"toes_{side}").id)]
        point = d.geom_xpos[geoms].mean(axis=0)
        mujoco.mj_applyFT(m, d, np.array([0.0, weight / 2, 0.0]), np.zeros(3), point, m.body(f"calcn_{side}").id,
                          ext)
    flags = m.opt.disableflags
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    d.qacc[:] = 0.0
    mujoco.mj_inverse(m, d)
    m.opt.disableflags = flags
    f = d.qfrc_inverse - ext
    drive = scene.drive
    G = scene.conv.cmap.dqpos_dq(q[None])[0]
    cols = [scene.conv.cmap.coordinates.index(c) for c in drive.coordinates]
    return (G.T @ f[scene.dadr])[cols]


def standing_pose(robot: PamRobot, conv: Conversion) -> np.ndarray:
    """The default pose leaned forward about the ankles (ankle angles +a, pelvis tilt −a: the feet stay flat)
    until the centre of mass is above the middle of the feet's contact spheres (Gait2392's all-zero pose has it
    3 cm inside the heels)."""
    C = robot.model.coordinates

    def offset(a: float) -> tuple[np.ndarray, float]:
        q = robot.model.default_q.copy()
        for side in ("r", "l"):
            q[C.index(f"ankle_angle_{side}")] = a
        q[C.index("pelvis_tilt")] = -a
        scene = build_scene(conv, robot, q[None])
        scene.set_pose(q)
        m, d = scene.model, scene.data
        g = [i for i in range(m.ngeom) if m.geom(i).name.startswith("contact")]
        mujoco.mj_subtreeVel(m, d)
        return q, float(d.subtree_com[0][0] - 0.5 * (d.geom_xpos[g, 0].min() + d.geom_xpos[g, 0].max()))

    a0, a1 = 0.0, 0.1
    e0, e1 = offset(a0)[1], offset(a1)[1]
    return offset(a0 - e0 * (a1 - a0) / (e1 - e0))[0]


def stand(robot: PamRobot, conv: Conversion, duration: float = 10.0, pressure: float | None = None, tau: float = TAU,
          kp: float | None = None, kd: float | None = None, cocontraction: float = COCONTRACTION,
          k_com: float = K_COM, d_com: float = D_COM) -> SimResult:
    """Stand unsupported from :func:`standing_pose`: feedforward pressures holding the pose statically with the
    antagonists co-contracted near ``cocontraction`` [Pa] (:func:`static_torques` through
    :func:`pamkin.sim.control.cocontracted_pressures`; 0: the least-effort pressures of
    :meth:`PressureController.pressures_for`), or a constant ``pressure`` [Pa] when given; plus the PD feedback
    towards the pose (every non-pelvis coordinate; default gains :data:`~pamkin.sim.control.KP_STAND`,
    :data:`~pamkin.sim.control.KD_STAND`, scaled by :data:`~pamkin.sim.control.STAND_GAIN_SCALE`) and the
    centre-of-mass balance on the ankles (gains ``k_com`` [N·m/m], ``d_com`` [N·m·s/m]; 0, 0: none)."""
    model = robot.model
    q0 = standing_pose(robot, conv)
    scene = build_scene(conv, robot, q0[None], harness=False, tau=tau)
    drive = scene.drive
    cidx = [model.coordinates.index(c) for c in drive.coordinates]
    controlled = [c for c in drive.coordinates if not c.startswith("pelvis_")]
    ctrl = PressureController.for_drive(drive, controlled, kp=KP_STAND if kp is None else kp,
                                        kd=KD_STAND if kd is None else kd, gain_scale=STAND_GAIN_SCALE)
    ref = (q0[cidx], np.zeros(len(cidx)))
    scene.set_pose(q0)
    tau_static = static_torques(scene, q0)[ctrl.columns]
    scene.set_pose(q0)
    if pressure is not None:
        ff = np.full(len(drive.tendons), float(pressure))
    elif cocontraction > 0:
        ff = cocontracted_pressures(drive, scene.data, ctrl.columns, tau_static, cocontraction)
    else:
        ff = ctrl.pressures_for(drive, scene.data, tau_static)
    scene.set_pose(q0)
    drive.pressure[:] = ff
    ankles = [controlled.index(f"ankle_angle_{s}") for s in ("r", "l")]
    balance = Balance(ankles, float(scene.data.subtree_com[0][0]), k_com, d_com)
    n = len(controlled)
    res = _run(scene, ctrl, duration, lambda t: ref, lambda t: ff, None, "stand",
               lambda: balance.torque(scene.model, scene.data, n))
    p = res.pelvis
    drift = np.linalg.norm((p - p[0])[:, [0, 2]], axis=1)
    fallen = np.nonzero(p[0, 1] - p[:, 1] >= FALL_DROP)[0]
    res.summary = _tracking_summary(res) | {
        "duration_s": duration, "feedforward": f"{pressure:g} Pa" if pressure is not None else
        f"static equilibrium, co-contracted near {cocontraction:g} Pa" if cocontraction > 0 else "static equilibrium",
        "feedforward_pressure_mean_Pa": float(ff.mean()),
        "pelvis_horizontal_drift_max_m": float(drift.max()), "pelvis_drop_max_m": float(np.max(p[0, 1] - p[:, 1])),
        "stayed_up": not len(fallen), "fell_at_s": float(res.times[fallen[0]]) if len(fallen) else None,
        "pressure_time_constant_s": tau,
        "kp": float(ctrl.kp.max()), "kd": float(ctrl.kd.max()), "k_com_N_m_per_m": k_com,
        "d_com_N_m_s_per_m": d_com, "control_period_s": CONTROL_PERIOD}
    return res


def _tracking_summary(res: SimResult) -> dict:
    err = np.degrees(res.q - res.q_ref)
    rms = {c: float(np.sqrt(np.mean(err[:, i] ** 2))) for i, c in enumerate(res.coordinates)
           if not c.startswith("pelvis_")}
    tracked = [rms[c] for c in TRACKED if c in rms]
    return {"angle_rms_deg": rms, "tracked_rms_max_deg": max(tracked) if tracked else None,
            "tracked": [c for c in TRACKED if c in rms]}
