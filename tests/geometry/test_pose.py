"""Pose: composition, inverse, apply, matrix form, yaw/pitch/roll, bad input."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from camkit.errors import CamkitError, ParameterError, ShapeError
from camkit.geometry import Pose, matrix_from_rvec, matrix_from_ypr

vec3 = arrays(np.float64, (3,), elements=st.floats(-5, 5))
poses = st.builds(Pose.from_rvec, vec3, vec3)


@given(poses)
def test_inverse_round_trip(pose):
    ident = pose @ pose.inverse()
    assert ident.allclose(Pose.identity(), atol=1e-12)
    assert pose.inverse().inverse().allclose(pose, atol=1e-12)


@given(poses, poses, arrays(np.float64, (7, 3), elements=st.floats(-10, 10)))
def test_composition_is_matrix_product(a, b, pts):
    ab = a @ b
    assert np.allclose(ab.matrix, a.matrix @ b.matrix, atol=1e-12)
    assert np.allclose(ab.apply(pts), a.apply(b.apply(pts)), atol=1e-10)


def test_apply_matches_numpy_reference():
    rng = np.random.default_rng(3)
    pose = Pose.from_rvec(rng.normal(size=3), rng.normal(size=3))
    pts = rng.normal(size=(4, 5, 3))
    assert np.allclose(pose.apply(pts), pts @ pose.R.T + pose.t, atol=1e-14)
    assert pose.apply(pts).shape == (4, 5, 3)
    assert pose.apply(np.zeros((0, 3))).shape == (0, 3)


def test_matrix_and_from_matrix():
    pose = Pose.from_rvec([0.1, -0.2, 0.3], [1.0, 2.0, 3.0])
    m = pose.matrix
    assert m.shape == (4, 4)
    assert np.array_equal(m[3], [0, 0, 0, 1])
    assert Pose.from_matrix(m).allclose(pose, atol=1e-15)
    assert Pose.from_matrix(m[:3]).allclose(pose, atol=1e-15)
    assert np.allclose(pose.rvec, [0.1, -0.2, 0.3], atol=1e-15)


def test_frozen_and_read_only():
    pose = Pose.identity()
    with pytest.raises(dataclasses.FrozenInstanceError):
        pose.t = np.ones(3)  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        pose.t[0] = 1.0


def test_stored_rotation_is_orthonormalised():
    R = matrix_from_rvec([0.3, 0.1, -0.2])
    noisy = np.round(R, 7)  # 7 significant digits, as text files hold them
    pose = Pose(noisy, np.zeros(3))
    assert np.allclose(pose.R @ pose.R.T, np.eye(3), atol=1e-15)


def test_ypr_of_a_camera():
    # A camera at the origin panned 30 degrees right and tilted 10 degrees up.
    ypr = np.radians([30.0, 10.0, 0.0])
    world_from_cam = Pose(matrix_from_ypr(ypr), np.zeros(3))
    cam_from_world = world_from_cam.inverse()
    assert np.allclose(cam_from_world.inverse().ypr(), ypr, atol=1e-15)
    assert Pose.from_ypr(ypr, [0, 0, 0]).allclose(world_from_cam)


@pytest.mark.parametrize(
    ("make", "exc", "needle"),
    [
        (lambda: Pose(np.eye(3) * 1.1, np.zeros(3)), ParameterError, "R: expected a rotation matrix"),
        (lambda: Pose(np.diag([1.0, -1.0, 1.0]), np.zeros(3)), ParameterError, "reflection"),
        (lambda: Pose(np.eye(3), np.zeros(2)), ShapeError, "t: expected shape (3,), got (2,)"),
        (lambda: Pose(np.eye(3), [0.0, np.nan, 0.0]), ParameterError, "t: expected finite"),
        (lambda: Pose.from_rvec([0, 0], [0, 0, 0]), ShapeError, "rvec: expected shape (3,)"),
        (lambda: Pose.from_matrix(np.eye(3)), ShapeError, "matrix: expected shape (4, 4) or (3, 4)"),
        (lambda: Pose.from_matrix(np.ones((3, 4))), ParameterError, "R: expected a rotation"),
        (lambda: Pose.identity().apply(np.zeros((3, 2))), ShapeError, "points: expected shape (..., 3)"),
        (lambda: Pose.identity().apply([[np.inf, 0, 0]]), ParameterError, "points: expected finite"),
    ],
)
def test_bad_input(make, exc, needle):
    with pytest.raises(exc) as info:
        make()
    assert isinstance(info.value, CamkitError)
    assert needle in str(info.value)


def test_from_matrix_bad_last_row():
    m = np.eye(4)
    m[3, 0] = 0.5
    with pytest.raises(ParameterError, match="last row"):
        Pose.from_matrix(m)


def test_matmul_with_other_types_is_refused():
    with pytest.raises(TypeError):
        Pose.identity() @ np.eye(4)  # type: ignore[operator]
    with pytest.raises(TypeError):
        np.eye(4) @ Pose.identity()  # type: ignore[operator]
