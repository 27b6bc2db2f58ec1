"""The thin lens: focusing, magnification, aperture, blur circles and depth of field.

SI units throughout: distances in metres, measured from the lens. Every function accepts
scalars or arrays (broadcast together) and returns a float for scalar input.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from camkit._validate import as_real_array
from camkit.errors import ParameterError

__all__ = [
    "aperture_diameter",
    "circle_of_confusion",
    "depth_of_field",
    "field_of_view_deg",
    "focal_length_from_distances",
    "hyperfocal_distance",
    "image_distance",
    "magnification",
    "object_distance",
]


def _positive(x: Any, name: str) -> np.ndarray:
    a = as_real_array(x, name)
    if not np.isfinite(a).all() or (a <= 0).any():
        raise ParameterError(f"{name}: expected finite values > 0, got {a.tolist() if a.size < 8 else a}")
    return a


def _out(a: np.ndarray) -> Any:
    return float(a) if a.ndim == 0 else a


def _beyond_focus(d: np.ndarray, f: np.ndarray, name: str) -> None:
    if (d <= f).any():
        raise ParameterError(
            f"{name}: expected distances beyond the focal length (a thin lens forms a real image "
            f"only of objects farther than f), got {d.tolist() if d.size < 8 else d} with f = "
            f"{f.tolist() if f.size < 8 else f}"
        )


def image_distance(focal_length: Any, object_distance: Any) -> Any:
    """Distance behind the lens where an object at ``object_distance`` is in focus.

    ``1/d0 + 1/d1 = 1/f``, so ``d1 = f d0 / (d0 - f)``.

    >>> round(image_distance(0.050, 3.0), 6)
    0.050847
    """
    f = _positive(focal_length, "focal_length")
    d0 = _positive(object_distance, "object_distance")
    _beyond_focus(d0, f, "object_distance")
    return _out(f * d0 / (d0 - f))


def object_distance(focal_length: Any, image_distance: Any) -> Any:
    """The object distance focused at ``image_distance``: ``d0 = f d1 / (d1 - f)``."""
    f = _positive(focal_length, "focal_length")
    d1 = _positive(image_distance, "image_distance")
    _beyond_focus(d1, f, "image_distance")
    return _out(f * d1 / (d1 - f))


def focal_length_from_distances(object_distance: Any, image_distance: Any) -> Any:
    """The focal length that images ``object_distance`` at ``image_distance``:
    ``f = d0 d1 / (d0 + d1)``."""
    d0 = _positive(object_distance, "object_distance")
    d1 = _positive(image_distance, "image_distance")
    return _out(d0 * d1 / (d0 + d1))


def magnification(focal_length: Any, object_distance: Any) -> Any:
    """Lateral magnification ``m = -d1 / d0 = f / (f - d0)``; negative: the image is inverted.

    >>> round(magnification(0.050, 0.55), 6)   # 1:10 reproduction
    -0.1
    """
    f = _positive(focal_length, "focal_length")
    d0 = _positive(object_distance, "object_distance")
    _beyond_focus(d0, f, "object_distance")
    return _out(f / (f - d0))


def aperture_diameter(focal_length: Any, f_number: Any) -> Any:
    """Entrance pupil diameter ``D = f / N``.

    >>> aperture_diameter(0.050, 2.0)
    0.025
    """
    return _out(_positive(focal_length, "focal_length") / _positive(f_number, "f_number"))


def circle_of_confusion(focal_length: Any, f_number: Any, focus_distance: Any, object_distance: Any) -> Any:
    """Diameter on the sensor (metres) of the blur spot of a point at ``object_distance`` when
    the lens is focused at ``focus_distance``.

    ``c = (f / N) |d - s| / d * f / (s - f)`` (similar triangles behind a thin lens: the
    aperture ``f/N`` scaled by the defocus of the image plane, ``s`` focus distance, ``d``
    object distance).

    >>> round(circle_of_confusion(0.050, 2.0, 3.0, 3.0), 12)
    0.0
    """
    f = _positive(focal_length, "focal_length")
    N = _positive(f_number, "f_number")
    s = _positive(focus_distance, "focus_distance")
    d = _positive(object_distance, "object_distance")
    _beyond_focus(s, f, "focus_distance")
    return _out((f / N) * np.abs(d - s) / d * f / (s - f))


def hyperfocal_distance(focal_length: Any, f_number: Any, coc: Any) -> Any:
    """``H = f^2 / (N c) + f``: focused there, everything from H/2 to infinity is sharp.

    >>> round(hyperfocal_distance(0.050, 2.0, 0.03e-3), 2)
    41.72
    """
    f = _positive(focal_length, "focal_length")
    return _out(f * f / (_positive(f_number, "f_number") * _positive(coc, "coc")) + f)


def depth_of_field(focal_length: Any, f_number: Any, focus_distance: Any, coc: Any) -> tuple[Any, Any]:
    """Near and far limits of acceptable sharpness: ``(near, far)`` in metres.

    With ``H`` the hyperfocal distance and ``s`` the focus distance:
    ``near = s (H - f) / (H + s - 2 f)``, ``far = s (H - f) / (H - s)``, and ``far = inf`` at and
    beyond the hyperfocal distance.

    >>> near, far = depth_of_field(0.050, 2.0, 3.0, 0.03e-3)
    >>> round(near, 3), round(far, 3)
    (2.802, 3.229)
    >>> depth_of_field(0.050, 16.0, 10.0, 0.03e-3)[1]
    inf
    """
    f = _positive(focal_length, "focal_length")
    s = _positive(focus_distance, "focus_distance")
    _beyond_focus(s, f, "focus_distance")
    H = np.asarray(hyperfocal_distance(f, f_number, coc))
    near = s * (H - f) / (H + s - 2 * f)
    with np.errstate(divide="ignore"):
        far = np.where(s < H, s * (H - f) / np.where(s < H, H - s, 1.0), np.inf)
    return _out(near), _out(far)


def field_of_view_deg(sensor_size: Any, focal_length: Any) -> Any:
    """Full angle of view (degrees) across a sensor dimension: ``2 atan(d / 2f)``.

    This is the full angle. A formula often quoted in lectures, ``atan(d / 2f)``, is the half
    angle (from the axis to one edge).

    >>> round(field_of_view_deg(0.036, 0.050), 2)
    39.6
    """
    d = _positive(sensor_size, "sensor_size")
    f = _positive(focal_length, "focal_length")
    return _out(np.degrees(2 * np.arctan(d / (2 * f))))
