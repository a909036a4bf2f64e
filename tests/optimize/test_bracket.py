"""Attachment points on their bone in the fit itself (optimize.bracket): the bone-distance spline
against exact distances, and a toy fit whose points would leave their bones without it."""

from __future__ import annotations


import casadi as ca
import numpy as np
import trimesh

import pamkin
from pamkin.human.bones import BoneSet
from pamkin.optimize.bracket import BAND, bracket_splines, distance_spline
from pamkin.optimize.problem import ActuatorProblem
from toy_route import INSERTION_BLOCK, ORIGIN_BLOCK, box, toy_problem
from locations import DATA



def test_distance_spline_matches_the_sphere_distance_and_its_gradient():
    """Around a sphere of radius 30 mm (a 4-times subdivided icosphere: its own distance to the true sphere
    is < 0.1 mm), the spline's value is within 0.2 mm of |x| - r (analytic) and its gradient (CasADi's)
    within 0.1 of the radial unit vector, at random points 2..25 mm outside the surface; negative inside."""
    model = pamkin.load_osim(DATA / "two_body.osim")
    s = trimesh.creation.icosphere(subdivisions=4, radius=0.03)
    bones = BoneSet.from_meshes(model, {"base": [(s.vertices, s.faces)]})
    f = distance_spline(bones, "base", np.full(3, -0.06), np.full(3, 0.06))
    x = ca.MX.sym("x", 3)
    grad = ca.Function("g", [x], [ca.gradient(f(x), x)])
    rng = np.random.default_rng(3)
    u = rng.normal(size=(60, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    r = rng.uniform(0.032, 0.055, 60)
    for ui, ri in zip(u, r):
        p = ui * ri
        assert abs(float(f(p)) - (ri - 0.03)) < 2e-4
        assert np.linalg.norm(np.array(grad(p)).ravel() - ui) < 0.1
    assert float(f(np.array([0.0, 0.01, 0.0]))) < -0.015


def test_bracket_rows_keep_a_toy_fit_on_its_bones():
    """The toy route of the bone-mesh test, each point's target 30 mm off its block: the plain fit puts
    both points there (outside the band), the fit with the bone-distance rows puts both in the band
    (exact distances, libigl) at a fit cost; a point whose box holds no band gets no row."""
    model, _, seed, cfg, data, seed_points, regions = toy_problem(0.04)
    bones = BoneSet.from_meshes(model, {"base": [box(*ORIGIN_BLOCK)], "arm": [box(*INSERTION_BLOCK)]})

    def own(points):
        return [bones.body_signed_distance(p.body, np.array([loc]))[0] for p, loc in zip(seed.points, points)]

    plain = ActuatorProblem(data, cfg, 10, seed_points, regions)
    sol = plain.solve(plain.initial_guess(seed_points, None, None), 1)
    assert sol.success and all(d > 0.025 for d in own(sol.points)), own(sol.points)
    splines = bracket_splines(seed, bones, seed_points, regions)
    assert sorted(splines) == [0, 1]
    prob = ActuatorProblem(data, cfg, 10, seed_points, regions, bracket=splines)
    fit = prob.solve(prob.initial_guess(seed_points, None, None), 1)
    assert fit.success, fit.status
    d = own(fit.points)
    print("exact bone distances of the fitted points [mm]:", np.round(1e3 * np.array(d), 2))
    assert all(BAND[0] - 2e-4 <= x <= BAND[1] + 2e-4 for x in d), d
    assert fit.objective >= sol.objective
    # the bone rounds drop these rows (the exact mesh rows replace them): no violation counted there
    z = fit.z.copy()
    z[0] += 0.03                                        # the origin 30 mm further out
    assert float(splines[0](z[:3])) > BAND[1] + 0.01
    assert not [k for k in prob.evaluate(z, 1).violations if "bone distance spline" in k]
    assert [k for k in fit.violations if "bone distance spline" in k]       # the fit itself has them
    # a box with no point in the band: no row (the rows could not be met)
    far = [np.array([0.2, -0.05, 0.0]), seed_points[1]]
    boxes = [np.array([0.01, 0.01, 0.0]), np.array([0.04, 0.04, 0.0])]
    assert sorted(bracket_splines(seed, bones, far, boxes)) == [1]
