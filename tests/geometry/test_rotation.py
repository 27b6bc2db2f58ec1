"""Rotations: round trips, precision near 0 and pi, OpenCV and SciPy as oracles, bad input."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from camkit.errors import CamkitError, ParameterError, ShapeError
from camkit.geometry import (
    matrix_from_quat,
    matrix_from_rvec,
    matrix_from_ypr,
    quat_from_matrix,
    rvec_from_matrix,
    ypr_from_matrix,
)

finite = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
rvecs = arrays(np.float64, (3,), elements=finite)
angles = st.floats(-np.pi, np.pi, allow_nan=False)


def _wrap(rvec: np.ndarray) -> np.ndarray:
    """The rotation vector with angle in [0, pi] for the same rotation."""
    t = np.linalg.norm(rvec)
    if t == 0:
        return rvec
    axis = rvec / t
    t = np.mod(t, 2 * np.pi)
    if t > np.pi:
        axis, t = -axis, 2 * np.pi - t
    return axis * t


def _is_rotation(R: np.ndarray) -> bool:
    return np.allclose(R @ R.swapaxes(-1, -2), np.eye(3), atol=1e-12) and np.allclose(
        np.linalg.det(R), 1.0, atol=1e-12
    )


@given(rvecs)
def test_rvec_round_trip(rvec):
    R = matrix_from_rvec(rvec)
    assert _is_rotation(R)
    back = rvec_from_matrix(R)
    # The matrices agree to a few ulps of entries of size 1.
    assert np.abs(matrix_from_rvec(back) - R).max() < 1e-14
    assert np.linalg.norm(back) <= np.pi + 1e-12


@given(arrays(np.float64, (4,), elements=st.floats(-1, 1)).filter(lambda q: np.linalg.norm(q) > 1e-3))
def test_quat_round_trip(q):
    R = matrix_from_quat(q)
    assert _is_rotation(R)
    q2 = quat_from_matrix(R)
    qn = q / np.linalg.norm(q) * np.sign(q[0] if q[0] != 0 else 1)
    assert q2[0] >= 0
    # q and -q are the same rotation; compare the matrices, and q up to sign.
    assert np.abs(matrix_from_quat(q2) - R).max() < 1e-14
    assert min(np.abs(q2 - qn).max(), np.abs(q2 + qn).max()) < 1e-12


@given(angles, st.floats(-np.pi / 2, np.pi / 2), angles)
def test_ypr_round_trip(yaw, pitch, roll):
    R = matrix_from_ypr([yaw, pitch, roll])
    back = ypr_from_matrix(R)
    assert np.abs(matrix_from_ypr(back) - R).max() < 1e-14
    if np.cos(pitch) > 1e-6:  # away from gimbal lock the angles themselves come back
        assert np.allclose(np.cos(back - [yaw, pitch, roll]), 1.0, atol=1e-12)


@pytest.mark.parametrize("pitch", [np.pi / 2, -np.pi / 2, np.pi / 2 - 1e-9, -np.pi / 2 + 1e-13])
def test_ypr_near_gimbal_lock_is_exact(pitch):
    R = matrix_from_ypr([0.7, pitch, -1.1])
    back = ypr_from_matrix(R)
    assert np.isfinite(back).all()
    assert np.abs(matrix_from_ypr(back) - R).max() < 1e-15 * 4


def test_ypr_meaning():
    # Positive yaw pans right: the optical axis turns toward +x.
    assert np.allclose(matrix_from_ypr([0.1, 0, 0]) @ [0, 0, 1], [np.sin(0.1), 0, np.cos(0.1)])
    # Positive pitch tilts up: the optical axis turns toward -y (y points down).
    assert np.allclose(matrix_from_ypr([0, 0.1, 0]) @ [0, 0, 1], [0, -np.sin(0.1), np.cos(0.1)])
    # Positive roll turns the camera's x axis toward +y (clockwise seen from behind).
    assert np.allclose(matrix_from_ypr([0, 0, 0.1]) @ [1, 0, 0], [np.cos(0.1), np.sin(0.1), 0])
    # Intrinsic order: yaw about the reference y, then pitch about the panned x.
    y, p, r = 0.3, -0.2, 0.5
    expected = Rotation.from_euler("YXZ", [y, p, r]).as_matrix()
    assert np.allclose(matrix_from_ypr([y, p, r]), expected, atol=1e-15)


@pytest.mark.parametrize("angle", [0.0, 1e-300, 1e-12, 1e-8, 1e-5, 1e-4, 1e-3, 0.5, np.pi - 1e-3,
                                   np.pi - 1e-6, np.pi - 1e-9, np.pi - 1e-12, np.pi])
def test_precision_near_0_and_pi(angle):
    axis = np.array([0.36, -0.48, 0.8])
    rvec = axis * angle
    R = matrix_from_rvec(rvec)
    back = rvec_from_matrix(R)
    assert np.isfinite(back).all()
    if angle < np.pi - 1e-6:
        # Small angles come back with relative precision, not just absolute.
        assert np.allclose(back, rvec, rtol=1e-13, atol=1e-300)
    else:
        # Near pi the axis sign is ambiguous at exactly pi; compare rotations.
        assert np.abs(matrix_from_rvec(back) - R).max() < 1e-14
        assert abs(np.linalg.norm(back) - angle) < 1e-12


def test_agrees_with_cv2_rodrigues():
    rng = np.random.default_rng(1234)
    rv = rng.normal(size=(200, 3)) * rng.uniform(0, np.pi, size=(200, 1))
    R = matrix_from_rvec(rv)
    for i in range(len(rv)):
        Rcv, _ = cv2.Rodrigues(rv[i])
        assert np.allclose(R[i], Rcv, rtol=1e-9, atol=1e-12)
        back_cv, _ = cv2.Rodrigues(Rcv)
        # OpenCV returns angles in [0, pi] too; away from pi they agree to 1e-9 relative.
        assert np.allclose(rvec_from_matrix(Rcv), back_cv.ravel(), rtol=1e-9, atol=1e-12)


def test_agrees_with_scipy_quaternions():
    rng = np.random.default_rng(7)
    q = rng.normal(size=(500, 4))
    R = matrix_from_quat(q)
    ref = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()  # SciPy is scalar-last
    assert np.allclose(R, ref, atol=1e-14)


def test_batched_shapes():
    rv = np.zeros((2, 5, 3))
    assert matrix_from_rvec(rv).shape == (2, 5, 3, 3)
    assert rvec_from_matrix(matrix_from_rvec(rv)).shape == (2, 5, 3)
    assert quat_from_matrix(np.eye(3)).shape == (4,)
    assert matrix_from_ypr(np.zeros((4, 3))).shape == (4, 3, 3)
    assert ypr_from_matrix(np.broadcast_to(np.eye(3), (4, 3, 3))).shape == (4, 3)
    assert matrix_from_rvec(np.zeros((0, 3))).shape == (0, 3, 3)


def test_float32_and_int_input():
    r32 = np.array([0.1, 0.2, 0.3], dtype=np.float32)
    assert matrix_from_rvec(r32).dtype == np.float64
    assert np.allclose(matrix_from_rvec(r32), matrix_from_rvec(r32.astype(np.float64)))
    assert np.allclose(matrix_from_rvec([0, 0, 0]), np.eye(3))


@pytest.mark.parametrize(
    ("func", "arg", "exc", "needle"),
    [
        (matrix_from_rvec, np.zeros((4, 2)), ShapeError, "rvec: expected shape (..., 3), got (4, 2)"),
        (matrix_from_rvec, [0.0, np.nan, 0.0], ParameterError, "rvec: expected finite"),
        (matrix_from_rvec, ["a", "b", "c"], ShapeError, "rvec: expected a real numeric array"),
        (matrix_from_rvec, np.array([1j, 0, 0]), ShapeError, "rvec"),
        (matrix_from_quat, [0.0, 0.0, 0.0, 0.0], ParameterError, "quat: expected non-zero"),
        (matrix_from_quat, [1.0, 0.0, 0.0], ShapeError, "quat: expected shape (..., 4)"),
        (rvec_from_matrix, np.eye(3) * 2, ParameterError, "R: expected a rotation matrix"),
        (rvec_from_matrix, np.diag([1.0, 1.0, -1.0]), ParameterError, "reflection"),
        (rvec_from_matrix, np.eye(4), ShapeError, "R: expected shape (..., 3, 3)"),
        (quat_from_matrix, np.full((3, 3), np.nan), ParameterError, "R: expected finite"),
        (ypr_from_matrix, [[1, 0], [0, 1]], ShapeError, "R: expected shape"),
        (matrix_from_ypr, [0.0, 0.0], ShapeError, "ypr: expected shape (..., 3)"),
        (matrix_from_ypr, [0.0, np.inf, 0.0], ParameterError, "ypr: expected finite"),
    ],
)
def test_bad_input(func, arg, exc, needle):
    with pytest.raises(exc) as info:
        func(arg)
    assert isinstance(info.value, CamkitError)
    assert needle in str(info.value)


@settings(max_examples=30)
@given(rvecs)
def test_matrix_rows_match_scipy(rvec):
    assert np.allclose(matrix_from_rvec(rvec), Rotation.from_rotvec(rvec).as_matrix(), atol=1e-14)
    assert np.allclose(_wrap(rvec_from_matrix(matrix_from_rvec(rvec))), rvec_from_matrix(
        Rotation.from_rotvec(rvec).as_matrix()), atol=1e-12)
