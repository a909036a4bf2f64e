"""Inverse dynamics of a converted human model in MuJoCo, against OpenSim 4.6's InverseDynamicsTool.

Both get the same inputs: the trial's IK coordinates low-pass filtered (4th-order Butterworth, zero phase,
:data:`CUTOFF_HZ`) at the IK frames, and the trial's ground reactions applied to the feet (force at the centre of
pressure plus the free torque, in ground). OpenSim splines the coordinates (quintic, interpolating: the filter is
switched off, the data are already smooth) and differentiates the splines; MuJoCo gets q, q̇, q̈ from the same
kind of spline (:func:`scipy.interpolate.make_interp_spline`, k = 5), mapped to its joints through the
coordinate map (tied joints: q̇_j = P'·q̇, q̈_j = P'·q̈ + P''·q̇²). ``mj_inverse`` runs with the constraints
switched off (the ties are holonomic and exact along this motion), the feet's loads are subtracted
(``mj_applyFT``), and the joint forces are projected onto the coordinates, τ = (∂qpos/∂q)ᵀ·f — the generalized
forces OpenSim reports. Frames within :data:`EDGE_FRAMES` of either end are left out of the comparison (the two
splines' end conditions differ).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from pamkin.errors import StorageFileError
from pamkin.opensim.storage import read_storage
from pamkin.outputs import write_file
from pamkin.sim.convert import Conversion
from pamkin.sim.opensim_id import opensim_inverse_dynamics

#: Cut-off of the coordinates' low-pass filter [Hz] (OpenSim's example pipelines use 6 Hz).
CUTOFF_HZ = 6.0
#: Frames at either end left out of the comparison.
EDGE_FRAMES = 6
#: Column prefixes of the two feet's ground reactions in the trial's GRF file.
GRF_PREFIXES = ("ground_force_", "1_ground_force_")


@dataclass
class IdComparison:
    """MuJoCo's and OpenSim's generalized forces over the compared frames.

    Attributes:
        times: (N,) [s].
        coordinates: Coordinate names.
        mujoco, opensim: (N, n_coordinates) [N·m or N].
        rms_pct: (n_coordinates,) RMS difference as % of OpenSim's peak |moment| per coordinate.
        peak: (n_coordinates,) OpenSim's peak |moment|.
        feet: GRF column prefix -> body.
    """

    times: np.ndarray
    coordinates: list[str]
    mujoco: np.ndarray
    opensim: np.ndarray
    rms_pct: np.ndarray
    peak: np.ndarray
    feet: dict[str, str]


def smoothed_coordinates(conv: Conversion, ik: str | os.PathLike, cutoff: float = CUTOFF_HZ):
    """(times (N,), q (N, n_coordinates) [rad, m]) of the IK file, low-pass filtered."""
    from scipy.signal import butter, filtfilt  # noqa: PLC0415

    st = read_storage(ik)
    model = conv.model
    q = st.coordinates_si(list(model.coordinates), [c.rotational for c in model.osim.coordinates])
    fs = 1.0 / float(np.median(np.diff(st.time)))
    b, a = butter(4, cutoff / (fs / 2))
    return st.time.copy(), filtfilt(b, a, q, axis=0)


def write_coordinates_mot(conv: Conversion, times: np.ndarray, q: np.ndarray, path: str | os.PathLike) -> Path:
    """An OpenSim coordinates file (degrees for rotations) of q."""
    rot = np.array([c.rotational for c in conv.model.osim.coordinates])
    vals = np.where(rot, np.degrees(q), q)
    head = (f"coordinates\nversion=1\nnRows={len(times)}\nnColumns={q.shape[1] + 1}\ninDegrees=yes\nendheader\n"
            + "\t".join(["time", *conv.model.coordinates]) + "\n")
    rows = "".join("\t".join(f"{v:.10g}" for v in (t, *row)) + "\n" for t, row in zip(times, vals))
    return write_file(path, head + rows)


def foot_assignment(conv: Conversion, times: np.ndarray, q: np.ndarray, grf: str | os.PathLike,
                    threshold: float = 50.0) -> dict[str, str]:
    """Which calcaneus each GRF column set belongs to: the one nearest its centres of pressure while loaded."""
    st = read_storage(grf)
    T = conv.model.body_transforms(q)
    out = {}
    for prefix in GRF_PREFIXES:
        cols = [f"{prefix}v{a}" for a in "xyz"] + [f"{prefix}p{a}" for a in "xyz"]
        missing = [c for c in cols if c not in st.columns]
        if missing:
            raise StorageFileError(str(grf), f"no column {missing[0]!r}", column=missing[0])
        fy = np.interp(times, st.time, st.data[:, st.columns.index(f"{prefix}vy")])
        P = np.column_stack([np.interp(times, st.time, st.data[:, st.columns.index(f"{prefix}p{a}")]) for a in "xz"])
        on = fy > threshold
        dist = {b: float(np.mean(np.linalg.norm(T[b][on][:, [0, 2], 3] - P[on], axis=1)))
                for b in ("calcn_r", "calcn_l")}
        out[prefix] = min(dist, key=dist.get)
    if len(set(out.values())) != 2:
        raise StorageFileError(str(grf), f"both ground reactions are nearest the same foot: {out}")
    return out


def mujoco_inverse_dynamics(conv: Conversion, times: np.ndarray, q: np.ndarray, grf: str | os.PathLike,
                            feet: dict[str, str]) -> np.ndarray:
    """(N, n_coordinates) generalized forces [N·m or N] of the model at the smoothed coordinates with the
    ground reactions applied (module docstring)."""
    from scipy.interpolate import make_interp_spline  # noqa: PLC0415

    spl = make_interp_spline(times, q, k=5)
    qd, qdd = spl.derivative(1)(times), spl.derivative(2)(times)
    model = conv.compile()
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    data = mujoco.MjData(model)
    cmap = conv.cmap
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j.name) for j in cmap.joints]
    qadr, dadr = model.jnt_qposadr[ids], model.jnt_dofadr[ids]
    st = read_storage(grf)

    def col(name):
        return np.interp(times, st.time, st.data[:, st.columns.index(name)])

    loads = []
    for prefix, body in feet.items():
        tq = prefix.replace("force_", "torque_")
        F = np.column_stack([col(f"{prefix}v{a}") for a in "xyz"])
        P = np.column_stack([col(f"{prefix}p{a}") for a in "xyz"])
        M = np.column_stack([col(f"{tq}{a}") if f"{tq}{a}" in st.columns else np.zeros(len(times)) for a in "xyz"])
        loads.append((mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body), F, P, M))
    # auxiliary joints (composed chains) and conditional points' step slides carry conversion artefacts of
    # 1e-5 kg only: their inertial forces (huge slopes inside a step's band) are not the model's
    model_joint = np.array([not (j.aux or "-step" in j.name) for j in cmap.joints], float)
    qpos = cmap.qpos(q)
    G = cmap.dqpos_dq(q)
    H = _second_derivatives(cmap, q)
    out = np.zeros_like(q)
    for n in range(len(times)):
        data.qpos[qadr] = qpos[n]
        data.qvel[dadr] = G[n] @ qd[n]
        data.qacc[dadr] = G[n] @ qdd[n] + np.einsum("jc,c->j", H[n], qd[n] ** 2)
        mujoco.mj_inverse(model, data)
        ext = np.zeros(model.nv)
        for body, F, P, M in loads:
            mujoco.mj_applyFT(model, data, F[n], M[n], P[n], body, ext)
        f = data.qfrc_inverse - ext
        out[n] = G[n].T @ (f[dadr] * model_joint)
    return out


def _second_derivatives(cmap, q: np.ndarray, h: float = 1e-5) -> np.ndarray:
    """(N, n_joints, n_coordinates) ∂²qpos_j/∂q_c² (each joint depends on one coordinate): quartic ties
    a²·P''(a·q + b); composed ties and their auxiliary joints by central differences of the exact slopes
    (step ``h`` [rad or m]; error O(h²))."""
    out = np.zeros((len(q), len(cmap.joints), len(cmap.coordinates)))
    composed = [k for k, mj in enumerate(cmap.joints) if mj.terms or mj.source]
    if composed:
        for c in range(len(cmap.coordinates)):
            dq = np.zeros(len(cmap.coordinates))
            dq[c] = h
            fd = (cmap.dqpos_dq(q + dq)[:, :, c] - cmap.dqpos_dq(q - dq)[:, :, c]) / (2 * h)
            out[:, composed, c] = fd[:, composed]
    for k, mj in enumerate(cmap.joints):
        if mj.primary or k in composed:
            continue
        c = cmap.coordinates.index(mj.coordinate)
        _, a, b = cmap.primary[mj.coordinate]
        d2 = np.polynomial.polynomial.polyder(mj.poly, 2)
        out[:, k, c] = a * a * np.polynomial.polynomial.polyval(a * q[:, c] + b, d2)
    return out


def compare_inverse_dynamics(conv: Conversion, osim: str | os.PathLike, ik: str | os.PathLike,
                             grf: str | os.PathLike, time_range: tuple[float, float] | None = None,
                             workdir: str | os.PathLike | None = None) -> IdComparison:
    """MuJoCo's inverse dynamics of ``conv`` against OpenSim's of ``osim`` on the same inputs (module
    docstring) over the IK frames inside the ground reactions' time range (cut to ``time_range`` [s]);
    ``workdir`` receives the coordinates file given to OpenSim (default: a temporary folder)."""
    import tempfile  # noqa: PLC0415

    times, q = smoothed_coordinates(conv, ik)
    g = read_storage(grf).time
    lo, hi = (g[0], g[-1]) if time_range is None else (max(g[0], time_range[0]), min(g[-1], time_range[1]))
    keep = (times >= lo - 1e-9) & (times <= hi + 1e-9)      # the ground reactions' time range
    if keep.sum() < 2 * EDGE_FRAMES + 2:
        raise StorageFileError(str(ik), f"fewer than {2 * EDGE_FRAMES + 2} IK frames in [{lo:.4g}, {hi:.4g}] s, "
                                        "where the ground reactions are given")
    times, q = times[keep], q[keep]
    feet = foot_assignment(conv, times, q, grf)
    with tempfile.TemporaryDirectory(prefix="pamkin-id-") as tmp:
        mot = write_coordinates_mot(conv, times, q, Path(workdir or tmp) / "coordinates.mot")
        t_os, labels, F_os = opensim_inverse_dynamics(osim, mot, grf, feet, (float(times[0]), float(times[-1])))
    F_mj = mujoco_inverse_dynamics(conv, times, q, grf, feet)
    rot = [c.rotational for c in conv.model.osim.coordinates]
    cols = [labels.index(c + ("_moment" if r else "_force")) for c, r in zip(conv.model.coordinates, rot)]
    F_os = np.column_stack([np.interp(times, t_os, F_os[:, k]) for k in cols])
    sel = slice(EDGE_FRAMES, len(times) - EDGE_FRAMES)
    times, F_mj, F_os = times[sel], F_mj[sel], F_os[sel]
    peak = np.abs(F_os).max(axis=0)
    rms = np.sqrt(np.mean((F_mj - F_os) ** 2, axis=0))
    return IdComparison(times, list(conv.model.coordinates), F_mj, F_os, 100 * rms / np.maximum(peak, 1e-9), peak,
                        feet)
