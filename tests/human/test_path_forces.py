"""Forces of PathActuator (optimal force × control) and PathSpring (stiffness × stretch) against OpenSim 4.6."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest
from locations import load_model as _load
from opensim_ref import SHARED

from pamkin.errors import ParameterError

PATH_ACTUATOR = SHARED / "opensim-models" / "Models" / "Gait10dof18musc" / "subject01_metabolics_path_actuator.osim"
pytestmark = pytest.mark.needs_shared

_REFERENCE = """
import sys, numpy as np, opensim as osim
osim.Logger.setLevelString("Error")
m = osim.Model(sys.argv[1])
q, controls = np.load(sys.argv[2]), float(sys.argv[3])
s = m.initSystem()
coords = m.getCoordinateSet()
fs = m.getForceSet()
names = [fs.get(i).getName() for i in range(fs.getSize())
         if fs.get(i).getConcreteClassName() in ("PathActuator", "PathSpring")]
out = np.zeros((len(q), len(names)))
for k in range(len(q)):
    for i in range(coords.getSize()):
        coords.get(i).setValue(s, float(q[k, i]), False)
        coords.get(i).setSpeedValue(s, 0.0)
    m.realizeVelocity(s)
    for j, n in enumerate(names):
        f = fs.get(n)
        if f.getConcreteClassName() == "PathActuator":
            a = osim.PathActuator.safeDownCast(f)
            x = osim.Vector(1, controls)
            ctrl = osim.Vector(m.getNumControls(), 0.0)
            a.addInControls(x, ctrl)
            m.setControls(s, ctrl)
            m.realizeDynamics(s)
            out[k, j] = a.computeActuation(s)
        else:
            out[k, j] = osim.PathSpring.safeDownCast(f).getTension(s)
np.save(sys.argv[4], out)
print(" ".join(names))
"""


def _opensim_tensions(path, q, control, tmp_path):
    np.save(tmp_path / "q.npy", q)
    proc = subprocess.run([sys.executable, "-c", _REFERENCE, str(path), str(tmp_path / "q.npy"), repr(control),
                           str(tmp_path / "out.npy")], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.split(), np.load(tmp_path / "out.npy")


def _spring_variant(tmp_path):
    """The same model with the PathActuator turned into a PathSpring (resting length, stiffness, dissipation)."""
    text = PATH_ACTUATOR.read_text()
    a = text.index('<PathActuator name="PlantarFlexAssist">')
    b = text.index("</PathActuator>", a) + len("</PathActuator>")
    body = text[a:b]
    gp = body[body.index("<GeometryPath"):body.index("</GeometryPath>") + len("</GeometryPath>")]
    spring = (f'<PathSpring name="PlantarFlexAssist">{gp}<resting_length>0.355</resting_length>'
              "<stiffness>2500</stiffness><dissipation>0.3</dissipation></PathSpring>")
    p = tmp_path / "spring.osim"
    p.write_text(text[:a] + spring + text[b:])
    return p



@pytest.mark.opensim
def test_path_actuator_force_is_optimal_force_times_control(tmp_path):
    model = _load(PATH_ACTUATOR)
    i = model.muscles.index("PlantarFlexAssist")
    q = model.random_q(6, seed=4)
    names, ref = _opensim_tensions(PATH_ACTUATOR, q, 0.35, tmp_path)
    assert names == ["PlantarFlexAssist"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        F = model.tendon_forces(q, activation=0.35)
    assert np.abs(F[:, i] - ref[:, 0]).max() < 1e-9 * max(1.0, np.abs(ref).max())
    assert F[0, i] == pytest.approx(0.35 * model.osim.muscles[i].params["optimal_force"], rel=1e-15)
    # its torques: tension × moment arm
    T = model.torques(q, activation=0.35)
    R = model.moment_arms(q)
    assert np.allclose(T[:, i], F[:, i, None] * R[:, i], rtol=1e-12, atol=1e-12)


@pytest.mark.opensim
def test_path_spring_tension_is_stiffness_times_stretch(tmp_path):
    path = _spring_variant(tmp_path)
    model = _load(path)
    i = model.muscles.index("PlantarFlexAssist")
    q = model.random_q(8, seed=6)
    names, ref = _opensim_tensions(path, q, 0.0, tmp_path)
    assert names == ["PlantarFlexAssist"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        F = model.tendon_forces(q)
    L = model.lengths(q)[:, i]
    assert np.abs(F[:, i] - ref[:, 0]).max() < 1e-9 * max(1.0, np.abs(ref).max())
    assert np.array_equal(F[:, i] > 0, L > 0.355) and (F[:, i] > 0).any() and (F[:, i] == 0).any()


def test_path_spring_without_stiffness_is_named(tmp_path):
    path = _spring_variant(tmp_path)
    path.write_text(path.read_text().replace("<stiffness>2500</stiffness>", ""))
    model = _load(path)
    with pytest.raises(ParameterError, match=r'<PathSpring name="PlantarFlexAssist">: no <stiffness>'):
        model.tendon_forces(model.default_q)
