"""Rollers in the optimiser's CasADi problem: a route segment's length over a roller and its derivative.

The library (:mod:`pamkin.robot.rollers`) computes a roller as OpenSim's ``WrapCylinder`` does; the optimiser
needs an expression smooth enough for IPOPT, so it uses the exact shortest path over an infinite cylinder
instead: in the roller's frame (z its axis, x the side the cable passes on), with a, b the segment's ends,
ρ their distances from the axis and θ their angles about it (atan2(y, x)), the cable wraps where the ends
lie on either side of the x axis (θa·θb < 0) and the straight line would pass the roller on its other side
or through it (φ = |θa| + |θb| − acos(r/ρa) − acos(r/ρb) > 0, the arc over the +x side between the tangent
points) and neither end lies inside the roller (OpenSim's rule); its length is then the unrolled geodesic √((ta + tb + r·φ)² + (za − zb)²), ta = √(ρa² − r²),
and the straight distance elsewhere. The two agree in value and slope where the line touches the roller.
OpenSim's algorithm (the audit's) slides its tangent points along the axis by a construction of its own,
so the two lengths differ slightly where the cable runs askew over the roller (where both wrap, 1.5 µm at
most on 500 random poses of a biceps femoris roller, ``tests/test_roller_stage.py``; 0.03 mm for another
placement in an experiment). As OpenSim, the cable misses the roller
where both tangent points lie beyond its ends.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np


@dataclass
class RollerData:
    """A roller of one actuator's problem at its S samples.

    Attributes:
        segment: Route segment index (points segment, segment + 1).
        radius: Roller radius [m].
        length: Roller length along its axis [m] (no wrap where both tangent points lie beyond its ends).
        R: (S, 3, 3) the roller frame's orientation in ground (columns: side, axis × side, axis).
        c: (S, 3) its centre in ground [m].
        omega, tau: {coordinate: (S, 3)} its body's velocity field (∂x/∂q = ω × x + τ).
    """

    segment: int
    radius: float
    length: float
    R: np.ndarray
    c: np.ndarray
    omega: dict
    tau: dict


def _column_function(radius: float, length: float) -> ca.Function:
    """(a, b) in the roller frame (3,) each -> (length, ∂length/∂a, ∂length/∂b)."""
    a = ca.SX.sym("a", 3)
    b = ca.SX.sym("b", 3)
    r = float(radius)
    half = 0.5 * float(length)
    ra0, rb0 = ca.sqrt(a[0] ** 2 + a[1] ** 2), ca.sqrt(b[0] ** 2 + b[1] ** 2)
    ra, rb = ca.fmax(ra0, 1.000001 * r), ca.fmax(rb0, 1.000001 * r)
    tha = ca.atan2(a[1], a[0])
    thb = ca.atan2(b[1], b[0])
    phi = ca.fabs(tha) + ca.fabs(thb) - ca.acos(r / ra) - ca.acos(r / rb)
    ta, tb = ca.sqrt(ra ** 2 - r * r), ca.sqrt(rb ** 2 - r * r)
    horizontal = ta + tb + r * phi
    wrapped = ca.sqrt(horizontal ** 2 + (a[2] - b[2]) ** 2)
    straight = ca.norm_2(b - a)
    # the tangent points' heights along the axis (the unrolled line): beyond both ends, the cable misses it
    z1 = a[2] + (b[2] - a[2]) * ta / ca.fmax(horizontal, 1e-12)
    z2 = a[2] + (b[2] - a[2]) * (ta + r * phi) / ca.fmax(horizontal, 1e-12)
    on = ca.logic_not(ca.logic_and(ca.fabs(z1) > half, ca.fabs(z2) > half))
    # as OpenSim: no wrap where an end lies inside the roller's radius
    outside = ca.logic_and(ra0 > r, rb0 > r)
    active = ca.logic_and(ca.logic_and(ca.logic_and(tha * thb < 0, phi > 0), on), outside)
    L = ca.if_else(active, wrapped, straight)
    return ca.Function("roller_segment", [a, b], [L, ca.gradient(L, a), ca.gradient(L, b)])


def roller_length_numeric(a: np.ndarray, b: np.ndarray, radius: float, length: float) -> np.ndarray:
    """The model's segment length for (S, 3) ends in the roller frame (numpy in, numpy out) [m]."""
    f = _column_function(radius, length).map(len(a))
    return np.asarray(f(a.T, b.T)[0]).ravel()


def _rotate(v, R: np.ndarray):
    """Vectors (3, S) in ground (CasADi) into the roller frame (R (S, 3, 3)): Rᵀ v per sample."""
    return ca.vertcat(*[sum(ca.DM(np.ascontiguousarray(R[:, i, k][None, :])) * v[i, :] for i in range(3))
                        for k in range(3)])


def segment_terms(Xa, Xb, roller: RollerData):
    """The roller segment's length (1, S) and a function of the ends' velocities (3, S) for one coordinate
    giving ∂length/∂q (1, S) (CasADi expressions)."""
    S = roller.R.shape[0]
    f = _column_function(roller.radius, roller.length).map(S)
    c = ca.DM(np.ascontiguousarray(roller.c.T))
    a = _rotate(Xa - c, roller.R)          # the ends in the roller's frame
    b = _rotate(Xb - c, roller.R)
    L, ga, gb = f(a, b)

    def derivative(Va, Vb, coordinate: str):
        w = ca.DM(np.ascontiguousarray(roller.omega[coordinate].T))
        t = ca.DM(np.ascontiguousarray(roller.tau[coordinate].T))
        # the ends' velocities relative to the roller (its body's velocity field at each end), in its frame
        rel_a = _rotate(Va - (ca.cross(w, Xa) + t), roller.R)
        rel_b = _rotate(Vb - (ca.cross(w, Xb) + t), roller.R)
        return ca.sum1(ga * rel_a) + ca.sum1(gb * rel_b)

    return L, derivative
