"""Muscle physiology: static equilibrium of OpenSim 4.6's Thelen2003 and Millard2012 muscles
(forces in N, lengths in m), compiled with numba."""

from __future__ import annotations

from pamkin.muscles.millard2012 import MillardParams
from pamkin.muscles.thelen2003 import ThelenParams

__all__ = ["MillardParams", "ThelenParams"]
