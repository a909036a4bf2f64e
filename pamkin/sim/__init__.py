"""MuJoCo models of pamkin's models: OpenSim models and PAM robot designs as MJCF, their geometry measured
against pamkin's, and PAM actuators with the Festo force law (:mod:`pamkin.sim.joints`,
:mod:`pamkin.sim.mjcf`, :mod:`pamkin.sim.tendons`, :mod:`pamkin.sim.geometry`, :mod:`pamkin.sim.convert`,
:mod:`pamkin.sim.pams`)."""
