"""MuJoCo models of pamkin's models, and simulations of the PAM robot.

* :mod:`pamkin.sim.joints`, :mod:`pamkin.sim.mjcf`, :mod:`pamkin.sim.tendons`, :mod:`pamkin.sim.convert`,
  :mod:`pamkin.sim.files`: an OpenSim model or a robot design as MJCF (``pamkin mjcf``);
* :mod:`pamkin.sim.geometry`, :mod:`pamkin.sim.measure`: its tendon lengths and moment arms against pamkin's;
* :mod:`pamkin.sim.inverse`, :mod:`pamkin.sim.opensim_id`: its inverse dynamics against OpenSim's;
* :mod:`pamkin.sim.pams`, :mod:`pamkin.sim.scene`, :mod:`pamkin.sim.control`, :mod:`pamkin.sim.simulate`,
  :mod:`pamkin.sim.runs`: PAM forces, the simulation scene, the pressure controller, the harness walk and
  standing (``pamkin simulate``) and their run folders.
"""
