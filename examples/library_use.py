"""pamkin as a library: human torques, the robot's PAM torques, and one actuator compared.

Run: python examples/library_use.py
"""

import numpy as np

import pamkin
from pamkin.audit.compare import compare_pam
from pamkin.robot.biped import design_robot
from pamkin.human.rom import load_rom

human = pamkin.gait2392()                              # built-in Gait2392 (Delp et al., CC BY 3.0)
rom = load_rom("robot_thesis", "r")
q, shape = human.grid(["hip_flexion_r", "knee_angle_r"], n=[5, 7], rom=rom,
                      base={c: 0.0 for c in human.coordinates})
tau = human.torques(q)                                 # (35, 92, 23) N·m, full activation
knee = human.coordinates.index("knee_angle_r")
print("human knee capacity [N·m]:", tau[:, :, knee].clip(min=0).sum(1).max().round(1),
      tau[:, :, knee].clip(max=0).sum(1).min().round(1))

robot = design_robot("thesis")                         # the thesis design (both sides)
state = robot.evaluate(q)
k = robot.names.index("pam05_r")                       # semimembranosus PAM
print("semimembranosus PAM strain range:", state.strain[:, k].min().round(3), state.strain[:, k].max().round(3))
print("its knee torque [N·m]:", np.round(state.torques[:, k, knee].reshape(shape)[0], 1))

m = compare_pam(robot, human, k, rom)
print(f"NRMSE {m.primary.nrmse:.2f}, sign agreement {m.primary.sign_agreement:.2f}, buildable {m.buildable}")
