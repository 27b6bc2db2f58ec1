"""Converters between camkit's models and OpenCV's ``(K, dist)`` vectors.

OpenCV stores distortion as a vector whose meaning depends on its length:
``(k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tx, ty]]]])``. That is a converter's
concern; camkit's models have named parameters.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from camkit._validate import as_matrix, as_real_array
from camkit.errors import ParameterError, ShapeError
from camkit.lens.brown_conrady import BrownConrady
from camkit.lens.kannala_brandt import KannalaBrandt

__all__ = ["from_opencv", "from_opencv_fisheye", "to_opencv"]

_BC_ORDER = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4")


def _intrinsics(K: Any) -> dict[str, float]:
    k = as_matrix(K, (3, 3), "K")
    if k[1, 0] != 0 or k[2, 0] != 0 or k[2, 1] != 0 or k[2, 2] != 1:
        raise ParameterError(f"K: expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got {k.tolist()}")
    return {"fx": k[0, 0], "fy": k[1, 1], "cx": k[0, 2], "cy": k[1, 2], "skew": k[0, 1]}


def from_opencv(K: Any, dist: Any, *, width: int, height: int) -> BrownConrady:
    """A :class:`BrownConrady` from OpenCV's camera matrix and distortion vector.

    Parameters
    ----------
    K : array_like, (3, 3)
    dist : array_like, 4, 5, 8, 12 or 14 values (any of OpenCV's shapes: (n,), (1, n), (n, 1)),
        or None or no values
        ``(k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tx, ty]]]])``. The tilted-sensor
        terms ``tx, ty`` of the 14-vector must be 0: camkit does not model a tilted sensor.
        None or an empty vector is no distortion, as OpenCV takes it (a ROS camera_info of
        rectified images writes ``D: []``).
    width, height : int

    Note that ``cv2.projectPoints`` ignores ``K[0, 1]``; camkit keeps it as ``skew``.

    Examples
    --------
    >>> import numpy as np
    >>> K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
    >>> cam = from_opencv(K, [-0.2, 0.05, 0.001, -0.002, 0.01], width=640, height=480)
    >>> cam.k1, cam.p2, cam.k3
    (-0.2, -0.002, 0.01)
    >>> to_opencv(cam)[1]
    array([-0.2  ,  0.05 ,  0.001, -0.002,  0.01 ])
    """
    d = np.zeros(4) if dist is None else as_real_array(dist, "dist")
    if d.size == 0:
        d = np.zeros(4)
    if d.ndim > 1 and sum(s != 1 for s in d.shape) <= 1:
        d = d.ravel()
    if d.ndim != 1 or d.size not in (4, 5, 8, 12, 14):
        raise ShapeError(f"dist: expected 4, 5, 8, 12 or 14 coefficients, or none, got shape {np.shape(dist)}")
    if not np.isfinite(d).all():
        raise ParameterError(f"dist: expected finite values, got {d.tolist()}")
    if d.size == 14:
        if d[12] != 0 or d[13] != 0:
            raise ParameterError(
                f"dist: the tilted-sensor terms (tx, ty) = ({d[12]}, {d[13]}) are not supported; "
                "expected 0"
            )
        d = d[:12]
    coeffs = dict(zip(_BC_ORDER, d.tolist(), strict=False))
    return BrownConrady(**_intrinsics(K), **coeffs, width=width, height=height)


def from_opencv_fisheye(K: Any, D: Any, *, width: int, height: int) -> KannalaBrandt:
    """A :class:`KannalaBrandt` from ``cv2.fisheye``'s camera matrix and ``D = (k1, k2, k3, k4)``.

    ``K[0, 1]`` becomes ``skew`` (``cv2.fisheye``'s ``alpha`` is ``skew / fx``).
    """
    d = as_real_array(D, "D").ravel()
    if d.size != 4:
        raise ShapeError(f"D: expected 4 coefficients (k1, k2, k3, k4), got shape {np.shape(D)}")
    if not np.isfinite(d).all():
        raise ParameterError(f"D: expected finite values, got {d.tolist()}")
    k1, k2, k3, k4 = d.tolist()
    return KannalaBrandt(**_intrinsics(K), k1=k1, k2=k2, k3=k3, k4=k4, width=width, height=height)


def to_opencv(model: BrownConrady | KannalaBrandt) -> tuple[np.ndarray, np.ndarray]:
    """``(K, dist)`` for OpenCV: the shortest of OpenCV's vectors (5, 8 or 12 values) that
    holds every non-zero term of a :class:`BrownConrady`, or ``D`` (4 values) of a
    :class:`KannalaBrandt` for ``cv2.fisheye``."""
    if isinstance(model, KannalaBrandt):
        return model.K, np.array([model.k1, model.k2, model.k3, model.k4])
    if not isinstance(model, BrownConrady):
        raise ParameterError(
            f"model: expected a BrownConrady or KannalaBrandt, got {type(model).__name__}"
        )
    full = np.array([getattr(model, n) for n in _BC_ORDER])
    n = 12 if full[8:].any() else 8 if full[5:8].any() else 5
    return model.K, full[:n]
