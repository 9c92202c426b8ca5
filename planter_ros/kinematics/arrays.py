"""Type names for the core's numbers: one value, or a batch of them (numpy arrays broadcast
together). Lengths in m, angles in rad, as everywhere in the core."""

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
Floats = float | NDArray[np.float64]            # a number, or an array of them
Bools = bool | np.bool_ | NDArray[np.bool_]

__all__ = ['Bools', 'FloatArray', 'Floats']
