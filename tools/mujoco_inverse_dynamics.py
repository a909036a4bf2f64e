"""Inverse dynamics of the Gait2392 MJCF against OpenSim 4.6's InverseDynamicsTool on the walking trial.

Usage: ``python tools/mujoco_inverse_dynamics.py [FIGURE.png]`` — prints the RMS difference per coordinate as a
percentage of OpenSim's peak moment (goal of issue 45: ≤ 5 %) and, given a path, writes a figure of both
tools' moments (``docs/mujoco_inverse_dynamics.png`` in the documentation). OpenSim runs in a child process.
"""

from __future__ import annotations

import sys
import warnings

import numpy as np

from pamkin._resources import DEFAULT_OSIM
from pamkin.gait.plan import DEFAULT_GRF, DEFAULT_IK
from pamkin.human.model import gait2392
from pamkin.outputs import write_figure
from pamkin.sim.convert import convert_model
from pamkin.sim.inverse import compare_inverse_dynamics


def main(argv: list[str]) -> None:
    warnings.simplefilter("ignore")
    conv = convert_model(gait2392())
    r = compare_inverse_dynamics(conv, DEFAULT_OSIM, DEFAULT_IK, DEFAULT_GRF)
    print(f"{len(r.times)} frames, {r.times[0]:.3f}-{r.times[-1]:.3f} s; feet {r.feet}")
    print(f"{'coordinate':22s} {'RMS [% of peak]':>16s} {'peak [N·m or N]':>16s}")
    for c, p, k in zip(r.coordinates, r.rms_pct, r.peak):
        print(f"{c:22s} {p:16.3f} {k:16.2f}")
    print(f"largest: {r.rms_pct.max():.2f} % ({r.coordinates[int(np.argmax(r.rms_pct))]}); goal <= 5 %: "
          f"{'met' if r.rms_pct.max() <= 5 else 'NOT met'}")
    if argv:
        import matplotlib  # noqa: PLC0415

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # noqa: PLC0415

        show = ["pelvis_ty", "hip_flexion_r", "knee_angle_r", "ankle_angle_r", "hip_adduction_l", "lumbar_extension"]
        fig, axes = plt.subplots(3, 2, figsize=(10, 8), sharex=True)
        for ax, c in zip(axes.ravel(), show):
            i = r.coordinates.index(c)
            ax.plot(r.times, r.opensim[:, i], "k", lw=2.5, label="OpenSim InverseDynamicsTool")
            ax.plot(r.times, r.mujoco[:, i], "tab:orange", lw=1.2, label="MuJoCo mj_inverse")
            ax.set_title(f"{c}: RMS {r.rms_pct[i]:.2f} % of peak", fontsize=9)
            ax.grid(alpha=0.3)
        axes[0, 0].legend(fontsize=7)
        for ax in axes[-1]:
            ax.set_xlabel("time [s]")
        fig.suptitle("Gait2392 generalized forces on the walking trial (same coordinates, same ground reactions)")
        fig.tight_layout()
        write_figure(fig, argv[0], dpi=90)


if __name__ == "__main__":
    main(sys.argv[1:])
