"""Geometry: rotations, rigid poses and the projection matrix."""

from camkit.geometry.homogeneous import (
    decompose_projection_matrix,
    from_homogeneous,
    projection_matrix,
    to_homogeneous,
)
from camkit.geometry.pose import Pose
from camkit.geometry.rotation import (
    matrix_from_quat,
    matrix_from_rvec,
    matrix_from_ypr,
    quat_from_matrix,
    rvec_from_matrix,
    ypr_from_matrix,
)

__all__ = [
    "Pose",
    "decompose_projection_matrix",
    "from_homogeneous",
    "matrix_from_quat",
    "matrix_from_rvec",
    "matrix_from_ypr",
    "projection_matrix",
    "quat_from_matrix",
    "rvec_from_matrix",
    "to_homogeneous",
    "ypr_from_matrix",
]
