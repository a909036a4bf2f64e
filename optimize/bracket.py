"""Attachment points on their bone, as smooth constraints of every solve (``[bone_rounds] bracket_fit``).

The bone-mesh rounds (:mod:`optimize.bone_cuts`) keep every body-fixed attachment point in the band
``POINT_MIN``..``POINT_MAX`` outside its own bone, linearised round by round from wherever the first fit
left it. Without this module the first fit does not know the band: its points may leave the bone by the
whole 50 mm of their box, and the rounds then pull them back, often far from any good fit.

Here the band is a constraint of the fit itself: the signed distance of a point to its own bone is a
function of the point's body-frame location only (the point and the bone move together), so one smooth
function per point serves every pose. It is a tensor-product cubic B-spline whose coefficients are the
exact signed distances (:meth:`pamkin.human.bones.BoneSet.body_signed_distance`, libigl) on a regular grid
over the point's box (quasi-interpolation: exact for linear fields, not passing through curved ones;
measured around a 10 mm sphere, 2–20 mm out: within 0.18 mm of the exact distance). The rows are approximate by design: the bone
rounds replace them with the exact mesh rows (as they replace the capsules) and measure the result
exactly.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from pamkin.optimize.bone_cuts import POINT_MAX, POINT_MIN
from pamkin.optimize.samples import is_free

#: Grid spacing of the signed-distance splines [m].
GRID_STEP = 0.0025
#: The grid covers the point's box and this much more on every side [m] (the spline's support needs one
#: cell beyond the last evaluated point; IPOPT may step a little outside the box bounds).
GRID_PAD = 0.005
#: Band of the fit's rows [m]: the exact band widened by the spline's error (the rounds enforce the
#: exact band; a fit point a fraction of a millimetre outside it is moved onto it there).
BAND = (POINT_MIN - 0.0005, POINT_MAX + 0.0005)


def distance_spline(bones, body: str, lo: np.ndarray, hi: np.ndarray, name: str = "sdf") -> ca.Function:
    """A smooth signed distance [m] to ``body``'s bone over the box ``lo``..``hi`` (body frame [m]).

    Args:
        bones: A :class:`pamkin.human.bones.BoneSet`.
        body: The body whose bone meshes are meant (they must exist).
        lo, hi: (3,) corners of the box the function must cover [m].
        name: Name of the CasADi function.

    Returns:
        A CasADi function of one 3-vector (callable with SX or MX): a cubic B-spline whose coefficients
        are the exact signed distances at the nodes of a grid of spacing :data:`GRID_STEP` (negative inside
        the bone). Outside the box plus :data:`GRID_PAD` it is not meaningful.
    """
    lo = np.asarray(lo, float) - GRID_PAD
    hi = np.asarray(hi, float) + GRID_PAD
    n = np.maximum(np.ceil((hi - lo) / GRID_STEP).astype(int) + 1, 4)
    axes = [lo[k] + GRID_STEP * np.arange(n[k]) for k in range(3)]
    P = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    d = bones.body_signed_distance(body, P)
    if not np.all(np.isfinite(d)):
        raise ValueError(f"body {body!r} has no bone mesh")
    coeffs = ca.DM(d.reshape(n).ravel(order="F"))
    # uniform cubic knots with basis function j centred on grid node j (coefficients = node values)
    knots = [list(a[0] + GRID_STEP * (np.arange(len(a) + 4) - 2)) for a in axes]
    x = ca.MX.sym("x", 3)
    return ca.Function(name, [x], [ca.bspline(x, coeffs, knots, [3, 3, 3], 1, {})], ["x"], ["d"],
                       {"never_inline": True})


def bracket_splines(pam, bones, seed: list[np.ndarray], regions: list) -> dict[int, ca.Function]:
    """The signed-distance spline of every route point of ``pam`` that the band applies to.

    A point gets one when it is body-fixed, its body has a bone mesh, its box (``seed ± region``) has
    some extent, and some grid node inside the box lies in the band (else the rows could not be met
    and the bone rounds deal with it as before).

    Returns:
        ``{point index: function}`` (see :func:`distance_spline`).
    """

    out: dict[int, ca.Function] = {}
    for i, pt in enumerate(pam.points):
        r = np.asarray(regions[i], float)
        if not is_free(pt) or pt.body not in bones.bodies or not np.any(r > 0):
            continue
        s = np.asarray(seed[i], float)
        # some point of the box in the band (a coarse check on the box's own grid)
        axes = [np.linspace(s[k] - r[k], s[k] + r[k], 9) for k in range(3)]
        P = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        d = bones.body_signed_distance(pt.body, P)
        if np.any((d >= BAND[0]) & (d <= BAND[1])):
            out[i] = distance_spline(bones, pt.body, s - r, s + r, f"sdf_{pam.id}_{pt.name}")
    return out
