"""The CasADi/IPOPT problem of one actuator: route points, resting length and tendon length.

Decision variables: every body-fixed route point's location in its body frame (a box around its
seed), the PAM's resting length l0 and its artificial tendon length t. Diameter and the number of
parallel PAMs are fixed per solve (the outer loop in :func:`optimize.actuator.solve_actuator`).

World positions are affine in the decision variables (x = p_b + R_b ℓ with numeric placements), so
the library's own path formulas (:func:`pamkin.human.paths.path_length`, :func:`pamkin.human.paths.path_moment_arm`,
:func:`pamkin.human.paths.point_velocity`) and Festo force model (:func:`pamkin.robot.festo.force`) give lengths,
moment arms, contractions, forces and torques as CasADi expressions.

Objective: Σ_c w_c · mean_s (τ_robot − τ_human)² / peak_c² + λ Σ_i |ℓ_i − ℓ_i⁰|² / region_i².
Constraints (every constraint sample, including the multi-joint training poses): −pretension ≤ ε ≤
kmax(l0); force per PAM ≤ Festo's rated force and contraction ≤ Festo's 25 % (``rated_force``); the PAM (resting and actual length, with both fittings)
fits on the route's longest segment (``one_segment``; left out, and reported, where that makes the
problem infeasible); successive points at least ``min_point_distance`` apart; interior points of every
segment clear the bone-shaft capsules by capsule radius + PAM radius; t ≥ 0 (PAM + fittings + tendon
fit the route). The objective's whole-vector terms (every coordinate the route or the human muscles
cross, on the training poses) are normalised by the human peak about the primary coordinate.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np
from pamkin.optimize.bracket import BAND as BRACKET_BAND
from pamkin.optimize.config import RunConfig
from pamkin.optimize.limit_check import limit_rows
from pamkin.optimize.pam_clearance import segment_point_distance
from pamkin.optimize.roller_model import segment_terms
from pamkin.optimize.samples import CLEARANCE_MARGIN, CLEARANCE_T, ActuatorData, is_free

from pamkin.human.paths import path_length, path_moment_arm, point_velocity
from pamkin.robot import festo
from pamkin.robot.design import mirror_name, pam_length, tendon_for


@dataclass
class Solution:
    """Result of one solve."""

    diameter_mm: int
    n_parallel: int
    points: list[np.ndarray]            # body-frame locations of every route point (moving: unchanged)
    rest_length: float
    tendon_length: float
    objective: float
    status: str
    success: bool
    violations: dict[str, float]        # constraint family -> worst violation (> 0 violated)
    nrmse_samples: dict[str, float]     # per objective label, on the optimisation samples
    torque_samples: dict[str, np.ndarray]
    seconds: float
    z: np.ndarray | None = None
    skip_capsules: bool = False         # checked against the bone meshes instead of the capsules
    mount_segment: int | None = None    # the problem's segment given for the PAM (a warm start's), if any


#: Margins that keep the audit's limits when they are checked between the samples.
#: Penalty of the elastic (bone-clearance) rows per metre of violation (objective units: NRMSE²).
CUT_PENALTY = 3000.0
#: Rows of the bone-mesh solver (unused rows are inactive): as many as optimize.bone_cuts.MAX_CUTS.
CUT_SLOTS = 320
#: Give the solvers the objective and rows with each distinct subexpression once (``casadi.cse``): the same
#: values to the bit and first derivatives too, about 40 % fewer graph nodes, so the exact-Hessian solvers
#: build about twice as fast and evaluate faster; the Hessian's round-off differs (tests/test_optimize.py).
#: Made when a problem's first solver is built (:meth:`ActuatorProblem.shared`): ~0.27 s a problem, and
#: many problems are only evaluated (a warm start's given routes).
SHARED_SUBEXPRESSIONS = True
#: The balls' slack is a squared length [m²]: scaled so that 1 mm outside an 18 mm ball costs ~1 mm of a row.
BALL_PENALTY_SCALE = 40.0
#: Largest constraint violation (in each row's own units: m, N, -) of a solution counted as feasible.
FEASIBILITY_TOL = 1e-6
SEGMENT_MARGIN = 0.002           # [m] the PAM clears its segment's ends
MIDLINE_MARGIN = 0.001           # [m] a point on a shared body (pelvis, torso) clears its left copy by 2x this


def _norm_rows(d):
    """(1, S) norms of a (3, S) CasADi matrix."""
    return ca.sqrt(ca.sum1(d * d))


def _dm(a: np.ndarray) -> ca.DM:
    return ca.DM(np.ascontiguousarray(a))


class ActuatorProblem:
    """CasADi expressions of one actuator's problem for a given diameter and parallel count."""

    def __init__(self, data: ActuatorData, cfg: RunConfig, diameter: int,
                 seed_points: list[np.ndarray], regions: list[list[float]], relax: frozenset = frozenset(),
                 bracket: dict | None = None, mount_segment: int | None = None, rollers: list | None = None) -> None:
        self.data, self.cfg, self.d = data, cfg, diameter
        #: rollers on route segments (optimize.roller_model.RollerData): the segment's length over the
        #: roller, its moment arms, no bone-capsule rows there
        self.rollers = list(rollers or [])
        self.relax = relax           # constraint groups left out ("one_segment"): the run reports them
        self.mount: int | None = None  # the segment the PAM sits on (one_segment)
        self.npar = ca.SX.sym("n_parallel")      # a parameter: one solver serves 1..3 parallel PAMs
        self._solver = None
        self._cut_solvers: dict[int, object] = {}
        pts = data.pam.points
        # every route point has 3 decision variables: a body-fixed point its location, a point moving
        # with a coordinate (e.g. the patella) a constant offset of its path in its body
        self.free = list(range(len(pts)))
        self.moving = {i for i, pt in enumerate(pts) if not is_free(pt)}
        self.seed = [np.asarray(seed_points[i], float) for i in range(len(pts))]
        self.regions = regions
        nz = 3 * len(self.free) + 2
        self.z = ca.SX.sym("z", nz)
        loc = {i: self.z[3 * k:3 * k + 3] for k, i in enumerate(self.free)}
        self.l0 = self.z[nz - 2]
        self.t = self.z[nz - 1]
        # world positions (3, S) of every route point
        X = []
        self.offset = {}
        for i, pt in enumerate(pts):
            b = data.body_of_point[i]
            R = data.R[:, b]                                      # (S, 3, 3)
            rot = 0
            for j in range(3):
                rot = rot + _dm(R[:, :, j].T) * loc[i][j]         # R_b · (location or offset)
            if i in self.moving:
                self.offset[i] = rot
                X.append(_dm(data.moving_x[i].T) + rot)
            else:
                X.append(_dm(data.p[:, b].T) + rot)
        self.X = X
        self.L = path_length(X, xp=ca)                            # (1, S)
        rolled = {}
        for rd in self.rollers:
            j = rd.segment
            Lseg, dseg = segment_terms(X[j], X[j + 1], rd)
            self.L = self.L - _norm_rows(X[j + 1] - X[j]) + Lseg
            rolled[j] = dseg
        #: transmission (pamkin.robot.design): the route moves k times the PAM's stroke at 1/k of its force
        self.k = int(data.pam.transmission)
        pam_len = pam_length(self.L, self.t, self.k, data.fitting_length)
        self.strain = (self.l0 - pam_len) / self.l0
        self.unit_force = festo.force(self.strain, self.l0, data.pressure, diameter, model=data.force_model)
        self.force = self.npar * self.unit_force / self.k
        self.kmax = festo.kmax(self.l0, diameter, model=data.force_model)
        # objective
        J = 0
        self.torque = {}
        for c, rows, th, w, label in data.objective:
            V = []
            for i, x in enumerate(X):
                b = data.body_of_point[i]
                if i in self.moving:   # the offset moves with the body: add ω × (R_b δ)
                    V.append(_dm(data.moving_v[i][c].T)
                             + point_velocity(_dm(data.omega[c][:, b].T), 0, self.offset[i], xp=ca))
                else:
                    V.append(point_velocity(_dm(data.omega[c][:, b].T), _dm(data.tau[c][:, b].T), x, xp=ca))
            r = path_moment_arm(X, V, xp=ca)
            for j, dseg in rolled.items():       # the roller's segment: its own −∂L/∂q for the straight one's
                d = X[j + 1] - X[j]
                r = r - ca.sum1(d * (V[j] - V[j + 1])) / _norm_rows(d) - dseg(V[j], V[j + 1], c)
            tau_r = self.force * r
            cols = list(map(int, rows))
            tr = tau_r[0, cols] if tau_r.shape[0] == 1 else tau_r[cols]
            peak = float(np.max(np.abs(th))) if len(th) else 0.0
            if data.norm and label in data.norm:       # whole-vector terms: the human primary peak
                peak = float(data.norm[label])
            self.torque[label] = (tr, th, peak)
            if peak > 1e-9:
                J = J + w * ca.sumsqr(tr - _dm(th[None, :])) / (len(cols) * peak ** 2)
        reg = 0
        for i in self.free:
            sc = np.maximum(np.asarray(regions[i], float), 1e-3)
            reg = reg + ca.sumsqr((loc[i] - _dm(self.seed[i])) / _dm(sc))
        self.J = J + cfg.weights.regularization * reg
        # constraints
        g, lbg, ubg, fam = [], [], [], []
        capsule_rows: list[int] = []     # indices of the bone-capsule rows (the bone-mesh rounds replace them)
        ci = [int(s) for s in data.constraint_idx]
        eps_c = self.strain[0, ci]
        for family, expr, lo, hi in limit_rows(cfg, diameter, eps_c, self.unit_force[0, ci], self.kmax):
            g.append(expr.T); lbg += [lo] * len(ci); ubg += [hi] * len(ci)
            fam += [family] * len(ci)
        if cfg.limits.sensitivity_pct > 0 and "sensitivity" not in relax:
            # a 1 mm error of any body-fixed attachment point moves the primary torque on its 1-D sweep
            # by at most sensitivity_pct % of the human peak: |∂τ/∂ℓ_i| · 1 mm <= limit at every sweep
            # sample (the audit's measure, there by central differences), normalised to <= 1
            tr, _, peak = self.torque[f"1-D {data.primary_coordinate}"]
            limit = 1e-2 * cfg.limits.sensitivity_pct * peak / 1e-3          # [N·m per m]
            if peak > 1e-9:
                G = ca.jacobian(ca.vec(tr), self.z)                      # (S1, nz)
                for k, i in enumerate(self.free):
                    if i in self.moving:
                        continue
                    Gi = G[:, 3 * k:3 * k + 3]
                    g.append(ca.sum2(Gi * Gi) / limit ** 2)
                    lbg += [-np.inf] * Gi.shape[0]
                    ubg += [1.0] * Gi.shape[0]
                    fam += [f"1 mm error of point {i + 1} <= sensitivity limit"] * Gi.shape[0]
        if (mount_segment is not None or cfg.one_segment_for(data.pam.id)) and "one_segment" not in relax:
            # the PAM sits on segment ``mount_segment``, else on the route's longest segment (at the seed):
            # that segment holds the resting PAM and the actual (possibly stretched) PAM with both fittings;
            # the tendon takes the rest
            seed_len = [float(np.mean(np.linalg.norm(self._seed_world(a + 1) - self._seed_world(a), axis=1)))
                        for a in range(len(X) - 1)]
            self.mount = int(np.argmax(seed_len)) if mount_segment is None else int(mount_segment)
            rest_row, actual_row = self.one_segment_rows(self.mount)
            g.append(rest_row); lbg += [0.0] * len(ci); ubg += [np.inf] * len(ci)
            fam += [f"PAM fits on segment {self.mount + 1}-{self.mount + 2} (resting)"] * len(ci)
            g.append(actual_row); lbg += [0.0] * len(ci); ubg += [np.inf] * len(ci)
            fam += [f"PAM fits on segment {self.mount + 1}-{self.mount + 2} (actual)"] * len(ci)
        if cfg.limits.min_point_distance_m > 0:
            for a, b in zip(range(len(X) - 1), range(1, len(X))):
                same = (a not in self.moving and b not in self.moving
                        and data.body_of_point[a] == data.body_of_point[b])
                cols = ci[:1] if same else ci        # within one body the distance is constant
                dv = X[b][:, cols] - X[a][:, cols]
                g.append(ca.sum1(dv * dv).T)
                lbg += [cfg.limits.min_point_distance_m ** 2] * len(cols)
                ubg += [np.inf] * len(cols)
                fam += [f"distance point {a + 1}-{b + 1} >= min_point_distance"] * len(cols)
        radius = diameter / 2000.0
        # bone clearance on a subset of the constraint samples; pairs (segment point, capsule) that
        # cannot come closer than required whatever the points do within their boxes are skipped
        cc = [int(s_) for s_ in data.clearance_idx]
        reach = [float(np.linalg.norm(regions[i])) for i in range(len(X))]
        for cap, wa, wb in data.capsules:
            A, B = _dm(wa[cc].T), _dm(wb[cc].T)
            AB = B - A
            ab2 = ca.sum1(AB * AB)
            need = cap.radius + radius + CLEARANCE_MARGIN
            for a in range(len(X) - 1):
                if a in rolled:              # the roller keeps this segment off the bone
                    continue
                xa = self._seed_world(a)
                xb = self._seed_world(a + 1)
                for tpar in CLEARANCE_T:
                    P0 = (1 - tpar) * xa + tpar * xb                       # (S, 3) seed positions
                    d0 = segment_point_distance(P0[cc][:, None, :], wa[cc], wb[cc])[0][:, 0]
                    if d0.min() - max(reach[a], reach[a + 1]) > need + 0.005:
                        continue
                    P = (1 - tpar) * X[a][:, cc] + tpar * X[a + 1][:, cc]
                    u = ca.fmin(ca.fmax(ca.sum1((P - A) * AB) / ab2, 0), 1)
                    D = P - (A + AB * ca.repmat(u, 3, 1))
                    g.append(ca.sum1(D * D).T)
                    lbg += [need ** 2] * len(cc)
                    ubg += [np.inf] * len(cc)
                    fam += [f"segment {a + 1}-{a + 2} clears {cap.name}"] * len(cc)
                    capsule_rows += range(len(fam) - len(cc), len(fam))
        # the left side is the mirror image (z -> -z): a point on a body both sides share (pelvis, torso)
        # keeps its PAM clear of its own left copy (z >= Festo's outer PAM radius + margin, as the audit
        # measures it; the segment between two such points then too, and over lumbar motion both copies
        # move with the same bodies)
        self.midline = festo.outer_diameter(diameter) / 2 + MIDLINE_MARGIN
        #: (n_points,) smallest body-frame z of each route point [m] (-inf: no such row)
        self.zmin = np.full(len(pts), -np.inf)
        for i, pt in enumerate(pts):
            if data.mirrored and i not in self.moving and mirror_name(pt.body) == pt.body:
                self.zmin[i] = self.midline
                g.append(loc[i][2])
                lbg += [self.midline]
                ubg += [np.inf]
                fam += [f"{pt.name} leaves room for its left copy (z >= PAM outer radius + {1e3 * MIDLINE_MARGIN:g} mm)"]
        # attachment points on their own bone (``bracket``: point index -> smooth signed distance to its
        # bone, optimize.bracket): approximate rows, replaced by the exact mesh rows in the bone rounds
        self.bracket = dict(bracket or {})
        for i, f in sorted(self.bracket.items()):
            g.append(f(loc[i]))
            lbg += [BRACKET_BAND[0]]
            ubg += [BRACKET_BAND[1]]
            fam += [f"{pts[i].name} on its bone ({1e3 * BRACKET_BAND[0]:g}..{1e3 * BRACKET_BAND[1]:g} mm out, "
                    f"bone distance spline)"]
            capsule_rows.append(len(fam) - 1)
        self.g = ca.vertcat(*g)
        self._shared: tuple | None = None     # (J, g) for the solvers, made when the first one is built
        self._eval_fn = None                  # (J, g, torques) at a decision vector, made on first use
        self.lbg, self.ubg, self.family = np.array(lbg), np.array(ubg), fam
        self._capsule_mask = np.zeros(len(fam), dtype=bool)
        self._capsule_mask[capsule_rows] = True
        # variable bounds
        lbx, ubx = [], []
        for i in self.free:
            r = np.asarray(regions[i], float)
            lo, hi = self.seed[i] - r, self.seed[i] + r
            if np.isfinite(self.zmin[i]) and r[2] > 0:
                # room on the right of the midline (row above) even for a seed on or across it
                hi[2] = max(hi[2], self.midline + r[2])
            lbx += list(lo)
            ubx += list(hi)
        lmin, lmax = festo.nominal_length_range(diameter)
        if cfg.limits.max_resting_length_m > 0:
            lmax = max(lmin, min(lmax, cfg.limits.max_resting_length_m))
        if cfg.limits.fix_lengths:
            rest, tendon = data.pam.resting_length_m, max(data.pam.tendon_length_m, 0.0)
            lbx += [rest, tendon]
            ubx += [rest, tendon]
        else:
            lbx += [lmin, 0.0]
            ubx += [lmax, 5.0]
        self.lbx, self.ubx = np.array(lbx), np.array(ubx)

    def with_mount(self, segment: int) -> ActuatorProblem:
        """The same problem (data, diameter, route box, relaxed groups, brackets) with the PAM on route
        segment ``segment`` at every constraint sample (the one-segment rows)."""
        return ActuatorProblem(self.data, self.cfg, self.d, self.seed, self.regions,
                               self.relax - {"one_segment"}, self.bracket or None, mount_segment=segment,
                               rollers=self.rollers)

    def one_segment_rows(self, segment: int):
        """The PAM on route segment ``segment`` at every constraint sample, as two (S_c, 1) CasADi rows
        ≥ 0: the segment holds the resting PAM, and the actual (possibly stretched) PAM, with both fittings
        and :data:`SEGMENT_MARGIN` (the tendon takes the rest of the route). The audit's measure is
        :func:`pamkin.robot.pam_body.body_room`."""
        ci = [int(s) for s in self.data.constraint_idx]
        seg = _norm_rows(self.X[segment + 1] - self.X[segment])[0, ci]
        rest = (seg - (self.l0 + 2 * self.data.fitting_length + SEGMENT_MARGIN)).T
        actual = (seg - (self.L[0, ci] - self.t) / self.k - SEGMENT_MARGIN).T
        return rest, actual

    def _seed_world(self, i: int) -> np.ndarray:
        """(S, 3) world positions of route point ``i`` at its seed location (or offset)."""
        b = self.data.body_of_point[i]
        base = self.data.moving_x[i] if i in self.moving else self.data.p[:, b]
        return base + self.data.R[:, b] @ self.seed[i]

    def lengths(self, z: np.ndarray) -> np.ndarray:
        """(S,) route lengths [m] at the decision vector ``z`` (every sample)."""
        if getattr(self, "_length_fn", None) is None:
            self._length_fn = ca.Function("L", [self.z], [self.L])
        return np.asarray(self._length_fn(z)).ravel()

    def initial_guess(self, points: list[np.ndarray], rest: float | None, tendon: float | None) -> np.ndarray:
        """Start vector: given points; l0 and t from the seed or sized so ε spans [0, 0.8·kmax]."""
        z = []
        for k, i in enumerate(self.free):
            z += list(np.clip(points[i], self.lbx[3 * k:3 * k + 3], self.ubx[3 * k:3 * k + 3]))
        f = ca.Function("L", [self.z], [self.L])  # lengths do not depend on n_parallel
        L = np.array(f(np.array(z + [1.0, 0.0]))).ravel()
        if self.cfg.limits.fix_lengths:
            rest, tendon = self.data.pam.resting_length_m, max(self.data.pam.tendon_length_m, 0.0)
        elif rest is None or tendon is None or tendon < 0:
            km = float(festo.kmax(0.5, self.d, model=self.data.force_model))
            delta = (L.max() - L.min()) / self.k
            rest = max(delta / (0.8 * km), 1e-3)
            rest = min(rest, L.max() / self.k - 2 * self.data.fitting_length - 1e-3)
            tendon = tendon_for(L.max(), rest, self.k, self.data.fitting_length)
        rest = float(np.clip(rest, self.lbx[-2], self.ubx[-2]))
        tendon = float(np.clip(tendon, self.lbx[-1], self.ubx[-1]))
        return np.array(z + [rest, tendon])

    def shared(self) -> tuple:
        """(objective, rows) as the solvers get them: with each distinct subexpression once
        (:data:`SHARED_SUBEXPRESSIONS`; made once, on first use), else :attr:`J` and :attr:`g` themselves."""
        if self._shared is None:
            if SHARED_SUBEXPRESSIONS:
                fg = ca.cse(ca.vertcat(self.J, self.g))
                self._shared = (fg[0], fg[1:])
            else:
                self._shared = (self.J, self.g)
        return self._shared

    def _values(self, z: np.ndarray, n_parallel: int) -> list[np.ndarray]:
        """[objective, rows, torques of every :attr:`torque` label] at ``z`` (one function, made once)."""
        if self._eval_fn is None:
            J, g = self._shared if self._shared is not None else (self.J, self.g)
            self._eval_fn = ca.Function("values", [self.z, self.npar], [J, g, *(tr for tr, _, _ in self.torque.values())])
        return [np.array(v).ravel() for v in self._eval_fn(z, n_parallel)]

    def solver(self):
        """The IPOPT solver (built once; CasADi derives exact Hessians of the SX expressions)."""
        if self._solver is None:
            J, g = self.shared()
            nlp = {"x": self.z, "p": self.npar, "f": J, "g": g}
            self._solver = ca.nlpsol("pam", "ipopt", nlp, self._ipopt_options())
        return self._solver

    def solve(self, z0: np.ndarray, n_parallel: int = 1) -> Solution:
        """Solve from ``z0`` with ``n_parallel`` PAMs on the route."""
        t0 = time.perf_counter()
        solver = self.solver()
        res = solver(x0=z0, p=n_parallel, lbx=self.lbx, ubx=self.ubx, lbg=self.lbg, ubg=self.ubg)
        stats = solver.stats()
        z = np.array(res["x"]).ravel()
        return self._solution(z, float(res["f"]), stats.get("return_status", "?"), bool(stats.get("success")),
                              time.perf_counter() - t0, n_parallel)

    def _ipopt_options(self) -> dict:
        """IPOPT options of every solve. IPOPT's own feasibility tolerances (``constr_viol_tol`` 1e-4,
        ``acceptable_constr_viol_tol`` 1e-2 by default) are set below the run's feasibility check
        (:data:`FEASIBILITY_TOL`), so "solved" and "solved to an acceptable level" mean feasible for it."""
        t = float(self.cfg.first_fit.max_solve_seconds)
        return {"ipopt.print_level": 0, "print_time": False, "ipopt.max_iter": self.cfg.first_fit.max_iter,
                "ipopt.tol": 1e-6, "ipopt.acceptable_tol": 1e-4, "ipopt.acceptable_iter": 5,
                "ipopt.constr_viol_tol": 0.1 * FEASIBILITY_TOL,
                "ipopt.acceptable_constr_viol_tol": 0.1 * FEASIBILITY_TOL,
                "ipopt.mu_strategy": "adaptive", "ipopt.sb": "yes",
                **({"ipopt.max_cpu_time": t} if t > 0 else {})}

    def cut_solver(self, k: int):
        """IPOPT solver of the problem with ``k`` elastic linear rows ``W z + w0 + s ≥ 0`` and, per
        route point i, an elastic ball ``r_i² − |ℓ_i − c_i|² + s_i ≥ 0`` (s ≥ 0, penalty
        :data:`CUT_PENALTY` · Σ s): W, w0, c and r are parameters, filled each round by
        :mod:`optimize.bone_cuts` (built once per row count). The capsule rows (:meth:`_capsule_rows`), which
        the mesh rows replace in these solves, are left out of its rows: with infinite bounds IPOPT would still
        carry them in every iteration's linear system (flexor digitorum longus' first-phase NLP, 1476 of its
        2809 rows: the same optimum to 8 digits, 9.1 -> 6.9 s)."""
        if k not in self._cut_solvers:
            nz = self.z.shape[0]
            npt = len(self.free)
            s = ca.SX.sym("s", k + npt)
            W = ca.SX.sym("W", k, nz)
            w0 = ca.SX.sym("w0", k)
            c = ca.SX.sym("c", 3 * npt)
            r2 = ca.SX.sym("r2", npt)
            ball = [r2[i] - ca.sumsqr(self.z[3 * i:3 * i + 3] - c[3 * i:3 * i + 3]) for i in range(npt)]
            J, g0 = self.shared()
            g0 = g0[np.flatnonzero(~self._capsule_rows()).tolist()]
            g = ca.vertcat(g0, ca.mtimes(W, self.z) + w0 + s[:k], ca.vertcat(*ball) + s[k:])
            nlp = {"x": ca.vertcat(self.z, s), "p": ca.vertcat(self.npar, ca.vec(W), w0, c, r2),
                   "f": J + CUT_PENALTY * ca.sum1(s[:k]) + CUT_PENALTY * BALL_PENALTY_SCALE * ca.sum1(s[k:]),
                   "g": g}
            self._cut_solvers[k] = ca.nlpsol("pam_cuts", "ipopt", nlp, self._ipopt_options())
        return self._cut_solvers[k]

    def solve_with_rows(self, z0: np.ndarray, n_parallel: int, W: np.ndarray, w0: np.ndarray,
                        lbx: np.ndarray, ubx: np.ndarray, centres: np.ndarray | None = None,
                        radii: np.ndarray | None = None, hard_balls: bool = False,
                        hard_rows: int = 0) -> tuple[Solution, float]:
        """Solve from ``z0`` with the rows ``W z + w0 ≥ 0`` (elastic, the first ``hard_rows`` hard), the
        balls ``|ℓ_i − centres_i| ≤ radii_i`` (route point i; ``inf``: none; elastic, or hard with
        ``hard_balls``) and bounds ``lbx``/``ubx`` on z (a trust region). Rows are padded to
        :data:`CUT_SLOTS` (inactive rows: 0·z + 1 ≥ 0).

        Returns:
            The solution (its success and violations are those of the problem's own constraints)
            and the largest slack of a linear row [m].
        """
        t0 = time.perf_counter()
        nz = self.z.shape[0]
        npt = len(self.free)
        k = max(CUT_SLOTS, int(np.ceil(len(W) / 64.0)) * 64)     # one solver build for every round
        Wp = np.zeros((k, nz))
        w0p = np.ones(k)
        Wp[:len(W)] = W
        w0p[:len(W)] = w0
        c = np.zeros((npt, 3)) if centres is None else np.array(centres, float)
        r = np.full(npt, np.inf) if radii is None else np.asarray(radii, float)
        inactive = ~np.isfinite(r)
        c[inactive] = 0.0
        r2 = np.where(inactive, 1e6, r ** 2)
        pts = z0[:3 * npt].reshape(npt, 3)
        row_ub = np.full(k, np.inf)
        row_ub[:hard_rows] = 0.0
        slack0 = np.concatenate([np.minimum(np.maximum(-(Wp @ z0 + w0p), 0.0), row_ub),
                                 np.zeros(npt) if hard_balls else np.maximum(np.sum((pts - c) ** 2, axis=1) - r2, 0.0)])
        solver = self.cut_solver(k)
        keep = ~self._capsule_rows()         # the mesh rows replace the capsules (and the bone-distance splines)
        lbg, ubg = self.lbg[keep], self.ubg[keep]
        res = solver(x0=np.concatenate([z0, slack0]),
                     p=np.concatenate([[n_parallel], Wp.ravel(order="F"), w0p, c.ravel(), r2]),
                     lbx=np.concatenate([lbx, np.zeros(k + npt)]),
                     ubx=np.concatenate([ubx, row_ub, np.zeros(npt) if hard_balls else np.full(npt, np.inf)]),
                     lbg=np.concatenate([lbg, np.zeros(k + npt)]),
                     ubg=np.concatenate([ubg, np.full(k + npt, np.inf)]))
        stats = solver.stats()
        x = np.array(res["x"]).ravel()
        z = x[:nz]
        slack = float(np.max(x[nz:nz + k], initial=0.0))
        f = float(self._values(z, n_parallel)[0][0])
        sol = self._solution(z, f, stats.get("return_status", "?"), bool(stats.get("success")),
                             time.perf_counter() - t0, n_parallel, skip_capsules=True)
        return sol, slack

    def evaluate(self, z: np.ndarray, n_parallel: int = 1) -> Solution:
        """The solution at a given decision vector (checked against the meshes, not the capsules)."""
        f = float(self._values(z, n_parallel)[0][0])
        return self._solution(np.asarray(z, float), f, "given", True, 0.0, n_parallel, skip_capsules=True)

    def _capsule_rows(self) -> np.ndarray:
        """Mask of the bone-capsule clearance rows of :attr:`g` (recorded where they are built)."""
        return self._capsule_mask

    def _solution(self, z: np.ndarray, f: float, status: str, success: bool, seconds: float,
                  n_parallel: int = 1, skip_capsules: bool = False) -> Solution:
        # resting and tendon length within their bounds: IPOPT relaxes bounds by ~1e-8 (bound_relax_factor),
        # which left a 40 mm PAM's resting length at 0.11999999 m, below Festo's nominal 0.12 m in the audit
        # (the points may leave their boxes in the bone-mesh rounds' trust regions: not clipped)
        z = np.array(z, float)
        z[-2:] = np.minimum(np.maximum(z[-2:], self.lbx[-2:]), self.ubx[-2:])
        _, gval, *tvals = self._values(z, n_parallel)
        viol = np.maximum(self.lbg - gval, 0) + np.maximum(gval - self.ubg, 0)
        if skip_capsules:         # bone-mesh rounds: the exact meshes replace the capsules
            viol = np.where(self._capsule_rows(), 0.0, viol)
        violations: dict[str, float] = {}
        for fam, v in zip(self.family, viol):
            violations[fam] = max(violations.get(fam, 0.0), float(v))
        pts = [p.copy() for p in self.seed]
        for k, i in enumerate(self.free):
            pts[i] = z[3 * k:3 * k + 3].copy()
        nrmse, torques = {}, {}
        for val, (label, (_, th, peak)) in zip(tvals, self.torque.items()):
            torques[label] = val
            nrmse[label] = float(np.sqrt(np.mean((val - th) ** 2)) / peak) if peak > 0 else float("nan")
        if skip_capsules:
            capsule_families = {f for f, cap in zip(self.family, self._capsule_mask) if cap}
            violations = {k: v for k, v in violations.items() if k not in capsule_families}
        return Solution(self.d, n_parallel, pts, float(z[-2]), float(z[-1]), f, status,
                        success and max(viol, default=0) <= FEASIBILITY_TOL, violations, nrmse, torques, seconds, z.copy(),
                        skip_capsules)

    def finalize(self, sol: Solution) -> Solution:
        """The solution as saved: the tendon clipped at 0 (IPOPT's bound relaxation can leave it at
        −1e-9), with torques and constraint values re-evaluated there."""
        z = sol.z.copy()
        z[-1] = max(z[-1], 0.0)
        out = self._solution(z, sol.objective, sol.status, sol.success, sol.seconds, sol.n_parallel,
                             sol.skip_capsules)
        out.success = sol.success and max(out.violations.values(), default=0.0) <= FEASIBILITY_TOL
        return out
