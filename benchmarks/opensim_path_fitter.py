"""Child process: OpenSim 4.6's PolynomialPathFitter on a model over its coordinate ranges (never import with casadi).

The reference trajectory is N_FRAMES identical frames at the middle of every coordinate's range; each frame is
sampled SAMPLES_PER_FRAME times within +-half the range (degrees for rotations, as the fitter takes them), so the
samples cover the same box as ``pamkin fit-paths``. Writes the fitter's results to OUT_DIR and the fitted model
(``ModOpReplacePathsWithFunctionBasedPaths``) to OUT_DIR/fitted.osim; prints one JSON line with the fit time [s].

Usage: python benchmarks/opensim_path_fitter.py MODEL.osim OUT_DIR N_FRAMES SAMPLES_PER_FRAME MAX_ORDER
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path


def main() -> None:
    import opensim as osim

    osim.Logger.setLevelString("Error")
    src, out = sys.argv[1], Path(sys.argv[2])
    n_frames, per_frame, order = (int(v) for v in sys.argv[3:6])
    model = osim.Model(src)
    model.initSystem()
    coords = model.getCoordinateSet()
    table = osim.TimeSeriesTable([0.01 * i for i in range(n_frames)])
    bounds = {}
    for i in range(coords.getSize()):
        c = coords.get(i)
        lo, hi = c.getRangeMin(), c.getRangeMax()
        table.appendColumn(c.getAbsolutePathString() + "/value", osim.Vector(n_frames, 0.5 * (lo + hi)))
        half = 0.5 * (hi - lo)
        bounds[c.getAbsolutePathString()] = math.degrees(half) if c.getMotionType() == 1 else half
    table.addTableMetaDataString("inDegrees", "no")
    fitter = osim.PolynomialPathFitter()
    fitter.setModel(osim.ModelProcessor(model))
    fitter.setCoordinateValues(osim.TableProcessor(table))
    fitter.setOutputDirectory(str(out))
    fitter.setMaximumPolynomialOrder(order)
    fitter.setNumSamplesPerFrame(per_frame)
    for path, h in bounds.items():
        fitter.appendCoordinateSamplingBounds(path, osim.Vec2(-h, h))
    fitter.setPathLengthTolerance(1e-4)
    fitter.setMomentArmTolerance(1e-3)
    t = time.perf_counter()
    fitter.run()
    seconds = time.perf_counter() - t
    sets = sorted(out.glob("*_FunctionBasedPathSet.xml"))
    proc = osim.ModelProcessor(src)
    proc.append(osim.ModOpReplacePathsWithFunctionBasedPaths(str(sets[0])))
    fitted = proc.process()
    fitted.initSystem()
    fitted.printToXML(str(out / "fitted.osim"))
    print(json.dumps({"seconds": seconds}))


if __name__ == "__main__":
    main()
