"""Projection matrix P = K[R|t] and its decomposition; OpenCV as oracle."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from camkit.errors import CamkitError, ParameterError, ShapeError
from camkit.geometry import (
    Pose,
    decompose_projection_matrix,
    from_homogeneous,
    projection_matrix,
    to_homogeneous,
)

vec3 = arrays(np.float64, (3,), elements=st.floats(-3, 3))
Ks = st.builds(
    lambda fx, fy, s, cx, cy: np.array([[fx, s, cx], [0, fy, cy], [0, 0, 1.0]]),
    st.floats(50, 5000), st.floats(50, 5000), st.floats(-5, 5), st.floats(-500, 2500), st.floats(-500, 2500),
)


@given(Ks, vec3, vec3, st.floats(-100, 100).filter(lambda s: abs(s) > 1e-3))
def test_decompose_round_trip(K, rvec, t, scale):
    pose = Pose.from_rvec(rvec, t)
    P = scale * projection_matrix(K, pose)
    K2, pose2 = decompose_projection_matrix(P)
    # K entries up to ~5000 and an RQ of a well-conditioned block: 1e-9 relative.
    assert np.allclose(K2, K, rtol=1e-9, atol=1e-9 * np.abs(K).max())
    assert pose2.allclose(pose, atol=1e-8)
    assert np.linalg.det(pose2.R) > 0 and K2[0, 0] > 0 and K2[1, 1] > 0


def test_agrees_with_cv2_decompose():
    rng = np.random.default_rng(11)
    for _ in range(50):
        K = np.array([[rng.uniform(300, 3000), rng.uniform(-2, 2), rng.uniform(200, 900)],
                      [0, rng.uniform(300, 3000), rng.uniform(200, 700)], [0, 0, 1]])
        pose = Pose.from_rvec(rng.normal(size=3), rng.normal(size=3) * 2)
        P = projection_matrix(K, pose)
        K_cv, R_cv, c_cv = cv2.decomposeProjectionMatrix(P)[:3]
        K2, pose2 = decompose_projection_matrix(P)
        assert np.allclose(K2, K_cv / K_cv[2, 2], rtol=1e-9, atol=1e-9)
        assert np.allclose(pose2.R, R_cv, rtol=1e-9, atol=1e-12)
        centre = (c_cv[:3] / c_cv[3]).ravel()  # OpenCV returns the camera centre, -R^T t
        assert np.allclose(pose2.inverse().t, centre, rtol=1e-9, atol=1e-9)


def test_projection_matrix_projects_like_pinhole():
    from camkit.lens import Pinhole

    cam = Pinhole(fx=700.0, fy=710.0, cx=300.0, cy=200.0, skew=0.5, width=640, height=480)
    pose = Pose.from_rvec([0.2, -0.1, 0.05], [0.1, 0.2, 4.0])
    X = np.random.default_rng(0).uniform(-1, 1, size=(20, 3))
    uv = from_homogeneous(to_homogeneous(X) @ projection_matrix(cam.K, pose).T)
    assert np.allclose(uv, cam.project(pose.apply(X)), atol=1e-10)


def test_homogeneous_helpers():
    assert np.array_equal(to_homogeneous(np.zeros((2, 3, 2))).shape, (2, 3, 3))
    assert np.isnan(from_homogeneous([1.0, 2.0, 0.0])).all()
    with pytest.raises(ShapeError, match="points"):
        from_homogeneous([1.0])


@pytest.mark.parametrize(
    ("call", "exc", "needle"),
    [
        (lambda: decompose_projection_matrix(np.zeros((3, 4))), ParameterError, "P: expected a finite camera"),
        (lambda: decompose_projection_matrix(np.eye(3)), ShapeError, "P: expected shape (3, 4)"),
        (lambda: decompose_projection_matrix(np.full((3, 4), np.nan)), ParameterError, "P: expected finite"),
        (lambda: projection_matrix(np.diag([0.0, 1.0, 1.0]), Pose.identity()), ParameterError,
         "K: expected positive focal lengths"),
        (lambda: projection_matrix(np.ones((3, 3)), Pose.identity()), ParameterError, "K: expected upper"),
        (lambda: projection_matrix(np.eye(3), np.eye(4)), ParameterError, "cam_from_world: expected a"),
    ],
)
def test_bad_input(call, exc, needle):
    with pytest.raises(exc) as info:
        call()
    assert isinstance(info.value, CamkitError)
    assert needle in str(info.value)
