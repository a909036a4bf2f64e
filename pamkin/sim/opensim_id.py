"""OpenSim 4.6's InverseDynamicsTool in a child process (``opensim`` and ``casadi`` cannot share a process).

:func:`opensim_inverse_dynamics` writes nothing the caller keeps: it runs ``python -m pamkin.sim.opensim_id``
in a temporary folder with the model, a coordinates ``.mot`` (used as given: no low-pass filter) and the
ground reactions (an ``ExternalLoads`` file: one ``ExternalForce`` per foot, force, point and torque expressed
in ground), and reads back the generalized forces.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from pamkin.errors import PamkinError
from pamkin.opensim.storage import read_storage


def opensim_inverse_dynamics(osim: str | os.PathLike, coordinates_mot: str | os.PathLike,
                             grf_mot: str | os.PathLike, feet: dict[str, str], time_range: tuple[float, float],
                             timeout: float = 600.0) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Run OpenSim's InverseDynamicsTool (muscles excluded) in a child process.

    Args:
        osim: The model.
        coordinates_mot: Coordinates (OpenSim storage, every coordinate).
        grf_mot: Ground reactions; ``feet`` maps a column prefix (``"ground_force_"``, ``"1_ground_force_"``)
            to the body it acts on (``calcn_r`` ...).
        time_range: (start, end) [s].

    Returns:
        (times (N,), column labels, generalized forces (N, n_columns) [N·m or N]).
    """
    with tempfile.TemporaryDirectory(prefix="pamkin-opensim-id-") as tmp:
        job = {"osim": str(Path(osim).resolve()), "mot": str(Path(coordinates_mot).resolve()),
               "grf": str(Path(grf_mot).resolve()), "feet": feet, "t0": time_range[0], "t1": time_range[1],
               "out": tmp}
        env = dict(os.environ)
        run = subprocess.run([sys.executable, "-m", "pamkin.sim.opensim_id", json.dumps(job)], capture_output=True,
                             text=True, timeout=timeout, env=env, cwd=tmp)    # OpenSim writes opensim.log there
        out = Path(tmp) / "id.sto"
        if run.returncode != 0 or not out.is_file():
            raise PamkinError(f"OpenSim's InverseDynamicsTool failed: {run.stderr.strip()[-800:]}")
        st = read_storage(out)
        return st.time.copy(), list(st.columns), st.data.copy()


def _main(job: dict) -> None:
    import opensim as osm  # noqa: PLC0415

    osm.Logger.setLevelString("Error")
    out = Path(job["out"])
    loads = osm.ExternalLoads()
    loads.setDataFileName(job["grf"])
    for prefix, body in job["feet"].items():
        ef = osm.ExternalForce()
        ef.setName(f"grf_{body}")
        ef.set_applied_to_body(body)
        ef.set_force_expressed_in_body("ground")
        ef.set_point_expressed_in_body("ground")
        ef.set_force_identifier(f"{prefix}v")
        ef.set_point_identifier(f"{prefix}p")
        ef.set_torque_identifier(prefix.replace("force_", "torque_"))
        loads.cloneAndAppend(ef)
    loads.printToXML(str(out / "loads.xml"))
    model = osm.Model(job["osim"])
    model.initSystem()
    tool = osm.InverseDynamicsTool()
    tool.setModel(model)
    tool.setCoordinatesFileName(job["mot"])
    tool.setLowpassCutoffFrequency(-1.0)
    tool.setStartTime(job["t0"])
    tool.setEndTime(job["t1"])
    tool.setExternalLoadsFileName(str(out / "loads.xml"))
    excluded = osm.ArrayStr()
    excluded.append("Muscles")
    tool.setExcludedForces(excluded)
    tool.setResultsDir(str(out))
    tool.setOutputGenForceFileName("id.sto")
    if not tool.run():
        raise SystemExit("InverseDynamicsTool.run() returned false")


if __name__ == "__main__":
    _main(json.loads(sys.argv[1]))
