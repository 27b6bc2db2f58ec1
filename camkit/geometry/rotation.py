"""Rotations: rotation vectors, unit quaternions, yaw/pitch/roll and matrices.

All functions are batched over leading dimensions, compute in float64 and accept any real
dtype. Conventions (docs/conventions.md):

- A rotation vector ``r`` is the axis times the angle in radians (right-hand rule), as
  OpenCV's ``Rodrigues``. ``rvec_from_matrix`` returns angles in [0, pi].
- Quaternions are ``(w, x, y, z)``, scalar first, Hamilton convention, unit norm;
  ``quat_from_matrix`` returns ``w >= 0``.
- Yaw/pitch/roll describe a camera's orientation in a reference frame with the same axes as
  the camera at zero angles (x right, y down, z forward):
  ``R = Ry(yaw) @ Rx(pitch) @ Rz(roll)`` maps camera coordinates to reference coordinates.
  Positive yaw pans right, positive pitch tilts up, positive roll turns the image clockwise
  as seen from behind the camera.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from camkit._kernels import rotation as rotation_kernels
from camkit._validate import as_points, as_rotation_matrix
from camkit.errors import ParameterError

__all__ = [
    "matrix_from_quat",
    "matrix_from_rvec",
    "matrix_from_ypr",
    "quat_from_matrix",
    "rvec_from_matrix",
    "ypr_from_matrix",
]

def _rows(arr: np.ndarray, k: tuple[int, ...]) -> np.ndarray:
    return np.ascontiguousarray(arr.reshape((-1, *k)))


def matrix_from_rvec(rvec: Any) -> np.ndarray:
    """Rotation matrices from rotation vectors (Rodrigues' formula).

    ``R = cos(t) I + sin(t)/t [r]_x + (1 - cos t)/t^2 r r^T`` with ``t = |r|``; accurate
    to machine precision near ``t = 0`` (Taylor series) and for any ``t``.

    Parameters
    ----------
    rvec : array_like, (..., 3)
        Axis times angle, radians.

    Returns
    -------
    ndarray, (..., 3, 3)

    Examples
    --------
    >>> import numpy as np
    >>> matrix_from_rvec([0.0, 0.0, np.pi / 2]).round(12) + 0.0
    array([[ 0., -1.,  0.],
           [ 1.,  0.,  0.],
           [ 0.,  0.,  1.]])
    """
    r = as_points(rvec, 3, "rvec")
    flat = _rows(r, (3,))
    out = np.empty((flat.shape[0], 3, 3))
    rotation_kernels.rvec_to_matrix(flat, out)
    return out.reshape((*r.shape[:-1], 3, 3))


def quat_from_matrix(R: Any) -> np.ndarray:
    """Unit quaternions ``(w, x, y, z)`` with ``w >= 0`` from rotation matrices.

    Shepperd's method (S. W. Shepperd, "Quaternion from rotation matrix", J. Guidance and
    Control 1(3), 1978, doi:10.2514/3.55767): accurate near 0 and near pi.

    Parameters
    ----------
    R : array_like, (..., 3, 3)

    Returns
    -------
    ndarray, (..., 4)
    """
    m = as_rotation_matrix(R, "R", batched=True)
    flat = _rows(m, (3, 3))
    out = np.empty((flat.shape[0], 4))
    rotation_kernels.matrix_to_quat(flat, out)
    return out.reshape((*m.shape[:-2], 4))


def matrix_from_quat(quat: Any) -> np.ndarray:
    """Rotation matrices from quaternions ``(w, x, y, z)`` (normalised here).

    Parameters
    ----------
    quat : array_like, (..., 4)
        Scalar first, Hamilton convention. Any non-zero norm; ``q`` and ``-q`` give the same R.

    Returns
    -------
    ndarray, (..., 3, 3)
    """
    q = as_points(quat, 4, "quat")
    norms = np.linalg.norm(q, axis=-1)
    if q.size and np.any(norms < 1e-12):
        raise ParameterError("quat: expected non-zero quaternions, got one of norm < 1e-12")
    flat = _rows(q, (4,))
    out = np.empty((flat.shape[0], 3, 3))
    rotation_kernels.quat_to_matrix(flat, out)
    return out.reshape((*q.shape[:-1], 3, 3))


def rvec_from_matrix(R: Any) -> np.ndarray:
    """Rotation vectors (angle in [0, pi]) from rotation matrices.

    Goes through Shepperd's quaternion and ``t = 2 atan2(|v|, w)``, so there is no loss of
    precision near 0 or near pi (where ``acos((tr R - 1)/2)`` fails). At exactly pi, ``r``
    and ``-r`` are the same rotation; either may come back.

    Parameters
    ----------
    R : array_like, (..., 3, 3)

    Returns
    -------
    ndarray, (..., 3)

    Examples
    --------
    >>> rvec_from_matrix(matrix_from_rvec([0.1, -0.2, 0.3])).round(12) + 0.0
    array([ 0.1, -0.2,  0.3])
    """
    m = as_rotation_matrix(R, "R", batched=True)
    flat = _rows(m, (3, 3))
    q = np.empty((flat.shape[0], 4))
    rotation_kernels.matrix_to_quat(flat, q)
    out = np.empty((flat.shape[0], 3))
    rotation_kernels.quat_to_rvec(q, out)
    return out.reshape((*m.shape[:-2], 3))


def matrix_from_ypr(ypr: Any) -> np.ndarray:
    """Rotation matrices ``R = Ry(yaw) @ Rx(pitch) @ Rz(roll)`` (reference <- camera).

    Parameters
    ----------
    ypr : array_like, (..., 3)
        Yaw (pan, about the camera's down axis y; positive pans right), pitch (tilt, about
        x; positive tilts up) and roll (about the optical axis z; positive turns the image
        clockwise as seen from behind), radians.

    Returns
    -------
    ndarray, (..., 3, 3)
        Maps camera coordinates to the reference frame; its columns are the camera's axes
        in the reference frame.

    Examples
    --------
    A camera panned 90 degrees to the right looks along the reference frame's +x:

    >>> import numpy as np
    >>> (matrix_from_ypr([np.pi / 2, 0, 0]) @ [0, 0, 1]).round(12) + 0.0
    array([1., 0., 0.])
    """
    a = as_points(ypr, 3, "ypr")
    cy, sy = np.cos(a[..., 0]), np.sin(a[..., 0])
    cp, sp = np.cos(a[..., 1]), np.sin(a[..., 1])
    cr, sr = np.cos(a[..., 2]), np.sin(a[..., 2])
    out = np.empty((*a.shape[:-1], 3, 3))
    # Ry(y) Rx(p) = [[cy, sy sp, sy cp], [0, cp, -sp], [-sy, cy sp, cy cp]], then times Rz(r).
    out[..., 0, 0] = cy * cr + sy * sp * sr
    out[..., 0, 1] = -cy * sr + sy * sp * cr
    out[..., 0, 2] = sy * cp
    out[..., 1, 0] = cp * sr
    out[..., 1, 1] = cp * cr
    out[..., 1, 2] = -sp
    out[..., 2, 0] = -sy * cr + cy * sp * sr
    out[..., 2, 1] = sy * sr + cy * sp * cr
    out[..., 2, 2] = cy * cp
    return out


def ypr_from_matrix(R: Any) -> np.ndarray:
    """Yaw, pitch, roll (radians) of rotation matrices, the inverse of :func:`matrix_from_ypr`.

    Yaw and roll are in (-pi, pi], pitch in [-pi/2, pi/2]. At pitch = +-pi/2 (gimbal lock)
    yaw and roll turn about the same axis and only their sum (or difference) is defined;
    the split returned is one of many, and ``matrix_from_ypr(ypr_from_matrix(R))`` equals
    ``R`` to machine precision there and everywhere else.

    Parameters
    ----------
    R : array_like, (..., 3, 3)

    Returns
    -------
    ndarray, (..., 3)
    """
    m = as_rotation_matrix(R, "R", batched=True)
    # Row 1 of R is cos(pitch) (sin roll, cos roll, -tan pitch): roll comes first. Undoing the
    # roll leaves M = R Rz(-roll) = Ry(yaw) Rx(pitch), from which yaw and pitch are read with
    # full precision even near gimbal lock (there roll is ill-defined, any value is exact).
    roll = np.arctan2(m[..., 1, 0], m[..., 1, 1])
    cr, sr = np.cos(roll), np.sin(roll)
    m00 = cr * m[..., 0, 0] - sr * m[..., 0, 1]
    m20 = cr * m[..., 2, 0] - sr * m[..., 2, 1]
    m11 = sr * m[..., 1, 0] + cr * m[..., 1, 1]
    yaw = np.arctan2(-m20, m00)
    pitch = np.arctan2(-m[..., 1, 2], m11)
    return np.stack([yaw, pitch, roll], axis=-1)
