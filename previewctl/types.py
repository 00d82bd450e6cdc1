"""Array type aliases shared by the whole package."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
"""A float64 array; shapes and units are given where it is used."""

IntArray = NDArray[np.int64]
"""An int64 array (indices, counts)."""

BoolArray = NDArray[np.bool_]
"""A boolean array (masks)."""
