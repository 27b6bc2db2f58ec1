"""Rigid poses (rototranslations) ``[R t; 0 1]``.

A pose is named by what it maps: ``cam_from_world`` takes world coordinates to camera
coordinates, ``X_cam = R X_world + t``. Poses compose with ``@`` like the matrices they are:
``cam_from_world = cam_from_rig @ rig_from_world``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from camkit._kernels import transform as transform_kernels
from camkit._validate import as_matrix, as_points, as_real_array, as_rotation_matrix
from camkit.errors import ParameterError, ShapeError
from camkit.geometry.rotation import matrix_from_rvec, matrix_from_ypr, rvec_from_matrix, ypr_from_matrix

__all__ = ["Pose"]


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=np.float64, copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, slots=True, eq=False)
class Pose:
    """A rigid transform ``x -> R x + t`` (rotation then translation), immutable.

    Parameters
    ----------
    R : array_like, (3, 3)
        Rotation matrix (orthonormal within 1e-6, det +1); re-orthonormalised on storage.
    t : array_like, (3,)
        Translation, in the units of the points (metres by convention).

    Examples
    --------
    >>> import numpy as np
    >>> cam_from_world = Pose.from_rvec([0, 0, np.pi / 2], [1, 0, 0])
    >>> cam_from_world.apply([1, 0, 0]).round(12) + 0.0
    array([1., 1., 0.])
    >>> (cam_from_world @ cam_from_world.inverse()).matrix.round(12) + 0.0
    array([[1., 0., 0., 0.],
           [0., 1., 0., 0.],
           [0., 0., 1., 0.],
           [0., 0., 0., 1.]])
    """

    # NumPy defers binary operators to Pose, so ``pose @ array`` is a TypeError, not a
    # silent elementwise broadcast.
    __array_ufunc__: ClassVar[None] = None

    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    t: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        R = as_rotation_matrix(self.R, "R")
        # Project onto SO(3) (polar decomposition) so that a matrix within tolerance is stored
        # as an exact rotation and errors do not accumulate through compositions.
        u, _, vt = np.linalg.svd(R)
        R = u @ vt
        t = as_matrix(self.t, (3,), "t")
        object.__setattr__(self, "R", _frozen(R))
        object.__setattr__(self, "t", _frozen(t))

    # -- construction -------------------------------------------------------------------
    @classmethod
    def _unchecked(cls, R: np.ndarray, t: np.ndarray) -> Pose:
        """For camkit's own solvers, whose R is a rotation by construction (a product of
        exact rotations): skips validation and the projection onto SO(3)."""
        pose = object.__new__(cls)
        object.__setattr__(pose, "R", _frozen(np.array(R, dtype=np.float64)))
        object.__setattr__(pose, "t", _frozen(np.array(t, dtype=np.float64)))
        return pose

    @classmethod
    def identity(cls) -> Pose:
        """The pose that maps every point to itself."""
        return cls._unchecked(np.eye(3), np.zeros(3))

    @classmethod
    def from_rvec(cls, rvec: Any, t: Any) -> Pose:
        """Pose from a rotation vector (axis times angle, radians) and a translation."""
        return cls(matrix_from_rvec(as_matrix(rvec, (3,), "rvec")), t)

    @classmethod
    def from_ypr(cls, ypr: Any, t: Any) -> Pose:
        """Pose whose rotation is :func:`~camkit.geometry.matrix_from_ypr` of ``ypr`` (radians)."""
        return cls(matrix_from_ypr(as_matrix(ypr, (3,), "ypr")), t)

    @classmethod
    def from_matrix(cls, matrix: Any) -> Pose:
        """Pose from a 4x4 homogeneous matrix ``[R t; 0 0 0 1]`` (3x4 ``[R|t]`` is accepted too)."""
        shape = as_real_array(matrix, "matrix").shape
        if shape not in ((4, 4), (3, 4)):
            raise ShapeError(f"matrix: expected shape (4, 4) or (3, 4), got {shape}")
        m = as_matrix(matrix, shape, "matrix")
        if m.shape == (4, 4) and np.abs(m[3] - [0.0, 0.0, 0.0, 1.0]).max() > 1e-9:
            raise ParameterError(f"matrix: expected a last row of [0, 0, 0, 1], got {m[3].tolist()}")
        return cls(m[:3, :3], m[:3, 3])

    # -- views --------------------------------------------------------------------------
    @property
    def matrix(self) -> np.ndarray:
        """The 4x4 homogeneous matrix ``[R t; 0 0 0 1]``."""
        m = np.eye(4)
        m[:3, :3] = self.R
        m[:3, 3] = self.t
        return m

    @property
    def rvec(self) -> np.ndarray:
        """The rotation as a rotation vector (radians), shape (3,)."""
        return rvec_from_matrix(self.R)

    def ypr(self) -> np.ndarray:
        """Yaw, pitch, roll (radians) of this pose's rotation, as :func:`ypr_from_matrix`.

        For a pose ``a_from_b`` these are the angles of frame b's axes in frame a. The
        orientation of a camera in the world is therefore ``cam_from_world.inverse().ypr()``.
        """
        return ypr_from_matrix(self.R)

    # -- algebra ------------------------------------------------------------------------
    def inverse(self) -> Pose:
        """The pose that undoes this one: ``(R^T, -R^T t)``."""
        Rt = self.R.T
        return Pose(Rt, -Rt @ self.t)

    def __matmul__(self, other: Pose) -> Pose:
        """Compose: ``(a_from_b @ b_from_c)`` maps c to a."""
        if not isinstance(other, Pose):
            return NotImplemented
        return Pose(self.R @ other.R, self.R @ other.t + self.t)

    def apply(self, points: Any) -> np.ndarray:
        """Transform points: ``R x + t``.

        Parameters
        ----------
        points : array_like, (..., 3)

        Returns
        -------
        ndarray, (..., 3), float64
        """
        p = as_points(points, 3, "points", nan_rows=True)
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        out = np.empty_like(flat)
        transform_kernels.rigid_apply(self.R, self.t, flat, out)
        return out.reshape(p.shape)

    def allclose(self, other: Pose, *, atol: float = 1e-9) -> bool:
        """True when both R and t agree within ``atol``."""
        return bool(np.allclose(self.R, other.R, atol=atol, rtol=0)
                    and np.allclose(self.t, other.t, atol=atol, rtol=0))

    def __repr__(self) -> str:
        r = np.array2string(self.rvec, precision=6, separator=", ")
        t = np.array2string(self.t, precision=6, separator=", ")
        return f"Pose.from_rvec({r}, {t})"
