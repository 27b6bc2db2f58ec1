"""camkit: the whole camera in one library.

Geometry, lens models, optics, sensor, resampling, simulation and calibration, with one set
of conventions (docs/conventions.md).
"""

import os

# camkit's parallel kernels run on numba's OpenMP pool. libgomp's default keeps its idle
# workers spinning for milliseconds after every parallel loop, which takes a core from
# whatever the caller runs next (benchmarks/notes.md has the measurement). Sleeping workers
# cost a wake-up per parallel loop instead. libgomp reads this once, when numba first loads it (at the first
# parallel call), so it is set here, before any kernel runs; a value the user set wins
# (docs/conventions.md, "Threads").
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from camkit.errors import CamkitError, EstimationError, ParameterError, ShapeError
from camkit.geometry import Pose
from camkit.lens import Pinhole

__version__ = "0.1.0"

__all__ = [
    "CamkitError",
    "EstimationError",
    "ParameterError",
    "Pinhole",
    "Pose",
    "ShapeError",
    "__version__",
]
