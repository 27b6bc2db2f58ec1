"""The exceptions camkit raises.

Every error camkit raises on purpose is a :class:`CamkitError`. The subclasses also derive
from the built-in exception a NumPy or SciPy user would expect, so ``except ValueError``
keeps working:

- :class:`ShapeError` (also ``ValueError``): an array has the wrong shape, dtype or size.
- :class:`ParameterError` (also ``ValueError``): a value is out of its domain (a zero focal
  length, NaN, a matrix that is not a rotation, an unknown option name).
- :class:`EstimationError` (also ``RuntimeError``): an estimate cannot be made from the data
  given (too few points, degenerate views); the message names the cause and the fix.
- :class:`ImageFileError` (also ``ValueError``): an image file that cannot be read (not an
  image, damaged, or an unsupported variant); the message names the file and the reason.

Messages name the argument, what was expected and what came, for example
``points_cam: expected shape (..., 3), got (17, 2)``.
"""

from __future__ import annotations

__all__ = ["CamkitError", "EstimationError", "ImageFileError", "ParameterError", "ShapeError"]


class CamkitError(Exception):
    """Root of every error camkit raises on purpose."""


class ShapeError(CamkitError, ValueError):
    """An array argument has the wrong shape, dtype or size."""


class ParameterError(CamkitError, ValueError):
    """An argument's value is outside its domain."""


class EstimationError(CamkitError, RuntimeError):
    """An estimation cannot succeed with the data given.

    ``detections``, where the estimate came from images (:func:`camkit.calib.calibrate_images`),
    holds the detector's result for each image, so that a caller can say which were found."""

    def __init__(self, message: str, *, detections: tuple | None = None) -> None:
        super().__init__(message)
        self.detections = detections


class ImageFileError(CamkitError, ValueError):
    """An image file cannot be read: not an image, damaged, or a variant not supported."""
