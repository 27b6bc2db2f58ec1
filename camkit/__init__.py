"""camkit: the whole camera in one library.

Geometry, lens models, optics, sensor, resampling, simulation and calibration, with one set
of conventions (docs/conventions.md).
"""

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
