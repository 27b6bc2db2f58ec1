"""Pinhole: physical construction, projection vs OpenCV, round trips, FOV, vanishing points."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from camkit.errors import CamkitError, ParameterError, ShapeError
from camkit.geometry import Pose
from camkit.lens import MODELS, Pinhole, get_model

CAM = Pinhole(fx=812.5, fy=809.0, cx=331.2, cy=244.7, skew=0.0, width=640, height=480)

pixels = arrays(np.float64, (2,), elements=st.floats(-0.5, 639.5))
depths = st.floats(0.05, 1e4)


@given(pixels, depths)
def test_unproject_project_round_trip(px, depth):
    ray = CAM.unproject(px)
    assert abs(np.linalg.norm(ray) - 1) < 1e-15 * 4
    assert np.allclose(CAM.project(ray * depth), px, atol=1e-9)
    X = CAM.unproject_depth(px, depth)
    assert abs(X[2] - depth) <= 1e-12 * depth
    assert np.allclose(CAM.project(X), px, atol=1e-9)


def test_agrees_with_cv2_project_points():
    rng = np.random.default_rng(5)
    pose = Pose.from_rvec([0.3, -0.2, 0.1], [0.2, -0.1, 3.0])
    X = rng.uniform(-1, 1, size=(1000, 3))
    cam = Pinhole(fx=1500.0, fy=1490.0, cx=960.3, cy=540.8, width=1920, height=1080)
    ours = cam.project(pose.apply(X))
    ref, _ = cv2.projectPoints(X, pose.rvec, pose.t, cam.K, None)
    # Relative 1e-9 of pixel coordinates of ~1000: agreement to 1e-6 px or better.
    assert np.allclose(ours, ref.reshape(-1, 2), rtol=1e-9, atol=0)


def test_behind_camera_is_nan_not_wrong():
    out = CAM.project([[0, 0, 1.0], [0, 0, 0.0], [0.1, 0.2, -3.0]])
    assert np.isfinite(out[0]).all()
    assert np.isnan(out[1:]).all()


def test_from_physical_and_back():
    cam = Pinhole.from_physical(focal_length=0.035, pixel_pitch=4.4e-6, width=6000, height=4000)
    assert cam.fx == pytest.approx(0.035 / 4.4e-6, rel=1e-15)
    assert (cam.cx, cam.cy) == (2999.5, 1999.5)
    assert cam.focal_length_m(4.4e-6) == pytest.approx(0.035, rel=1e-15)
    rect = Pinhole.from_physical(focal_length=0.01, pixel_pitch=(2e-6, 4e-6), width=10, height=10,
                                 principal_point=(3.0, 4.0))
    assert (rect.fx, rect.fy, rect.cx, rect.cy) == (5000.0, 2500.0, 3.0, 4.0)
    assert rect.focal_length_m((2e-6, 4e-6)) == pytest.approx(0.01)
    with pytest.raises(ParameterError, match="pixel_pitch"):
        rect.focal_length_m(2e-6)


def test_fov_full_frame_50mm():
    # 36 x 24 mm full frame behind a 50 mm lens: 39.60 x 26.99 degrees, 46.79 diagonal
    # (2 atan(d / 2f), published in every lens table).
    cam = Pinhole.from_physical(focal_length=0.050, pixel_pitch=6e-6, width=6000, height=4000)
    fov = cam.fov_deg()
    assert fov.horizontal_deg == pytest.approx(2 * np.degrees(np.arctan(36 / 100)), abs=1e-9)
    assert fov.vertical_deg == pytest.approx(2 * np.degrees(np.arctan(24 / 100)), abs=1e-9)
    assert fov.diagonal_deg == pytest.approx(2 * np.degrees(np.arctan(np.hypot(36, 24) / 100)), abs=1e-9)
    assert round(fov.horizontal_deg, 2) == 39.60


def test_vanishing_points():
    pose = Pose.from_rvec([0.1, 0.4, -0.2], [0.3, 0.1, 5.0])
    d = np.array([0.3, -0.2, 1.0])
    vp = CAM.vanishing_point(d, pose)
    # Far points along any line with this direction converge to the vanishing point.
    for start in ([0, 0, 0], [1, -2, 3]):
        far = CAM.project(pose.apply(np.array(start) + 1e9 * d))
        assert np.allclose(far, vp, atol=1e-5)
    assert np.allclose(CAM.vanishing_point(-d, pose), vp)  # d and -d: the same lines
    # A direction parallel to the image plane has its vanishing point at infinity: NaN.
    parallel_world = pose.R.T @ [1.0, 0.5, 0.0]
    assert np.isnan(CAM.vanishing_point(parallel_world, pose)).all()
    assert CAM.vanishing_point(np.tile(d, (4, 1)), pose).shape == (4, 2)


def test_jacobian_against_finite_differences():
    cam = Pinhole(fx=700.0, fy=720.0, cx=300.0, cy=200.0, skew=1.5, width=640, height=480)
    X = np.array([[0.3, -0.2, 2.0], [-1.0, 0.5, 4.0]])
    uv, dp, dk = cam.project_with_jacobian(X)
    assert np.allclose(uv, cam.project(X))
    h = 1e-6
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        num = (cam.project(X + e) - cam.project(X - e)) / (2 * h)
        assert np.allclose(dp[..., j], num, rtol=1e-6, atol=1e-6)
    p0 = cam.params()
    for j in range(len(p0)):
        e = np.zeros_like(p0)
        e[j] = h
        num = (Pinhole.from_params(p0 + e, width=640, height=480).project(X)
               - Pinhole.from_params(p0 - e, width=640, height=480).project(X)) / (2 * h)
        assert np.allclose(dk[..., j], num, rtol=1e-6, atol=1e-6)


def test_registry_and_params():
    assert MODELS["pinhole"] is Pinhole and get_model("pinhole") is Pinhole
    assert Pinhole.from_params(CAM.params(), width=640, height=480) == CAM
    assert Pinhole.param_indices("focal") == [0, 1]
    assert Pinhole.param_indices(("principal_point", "skew")) == [2, 3, 4]
    assert CAM.replace(fx=100.0).fx == 100.0 and CAM.fx == 812.5
    with pytest.raises(dataclasses.FrozenInstanceError):
        CAM.fx = 1.0  # type: ignore[misc]
    with pytest.raises(ParameterError, match="name: expected one of"):
        get_model("nope")
    with pytest.raises(ParameterError, match="names: expected parameter or group names"):
        Pinhole.param_indices("k9")


def test_broadcasting_and_float32():
    X = np.random.default_rng(2).uniform(0.5, 2, size=(3, 4, 3)).astype(np.float32)
    out = CAM.project(X)
    assert out.shape == (3, 4, 2) and out.dtype == np.float64
    assert np.allclose(out, CAM.project(X.astype(np.float64)))
    assert CAM.unproject(np.zeros((2, 0, 2))).shape == (2, 0, 3)
    assert CAM.unproject_depth(np.zeros((5, 2)), np.arange(1, 6)).shape == (5, 3)


@pytest.mark.parametrize(
    ("call", "exc", "needle"),
    [
        (lambda: Pinhole(fx=0.0, fy=1.0, cx=0, cy=0, width=4, height=4), ParameterError,
         "fx: expected a positive number, got 0.0"),
        (lambda: Pinhole(fx=-5.0, fy=1.0, cx=0, cy=0, width=4, height=4), ParameterError, "fx: expected a positive"),
        (lambda: Pinhole(fx=1.0, fy=1.0, cx=np.nan, cy=0, width=4, height=4), ParameterError, "cx: expected a finite"),
        (lambda: Pinhole(fx=1.0, fy=1.0, cx=0, cy=0, width=0, height=4), ParameterError, "width: expected a positive"),
        (lambda: Pinhole(fx=1.0, fy=1.0, cx=0, cy=0, width=4.5, height=4), ParameterError, "width: expected a positive"),
        (lambda: Pinhole(fx="1", fy=1.0, cx=0, cy=0, width=4, height=4), ParameterError, "fx: expected a finite"),
        (lambda: CAM.project(np.zeros((4, 2))), ShapeError, "points_cam: expected shape (..., 3), got (4, 2)"),
        (lambda: CAM.project([[0, np.nan, 1]]), ParameterError, "points_cam: expected finite"),
        (lambda: CAM.project([[0, np.inf, 1]]), ParameterError, "points_cam: expected finite"),
        (lambda: CAM.unproject(np.zeros(3)), ShapeError, "pixels: expected shape (..., 2), got (3,)"),
        (lambda: CAM.unproject_depth([[1.0, 2.0]], -1.0), ParameterError, "depth: expected finite values > 0"),
        (lambda: CAM.unproject_depth(np.zeros((3, 2)), np.ones(4)), ShapeError, "depth: expected a shape"),
        (lambda: CAM.vanishing_point([0, 0, 0], Pose.identity()), ParameterError, "direction_world: expected non-zero"),
        (lambda: CAM.vanishing_point([0, 0, 1], np.eye(4)), ParameterError, "cam_from_world: expected a"),
        (lambda: Pinhole.from_physical(focal_length=0, pixel_pitch=1e-6, width=4, height=4), ParameterError,
         "focal_length: expected a positive"),
        (lambda: Pinhole.from_physical(focal_length=0.01, pixel_pitch=[1e-6] * 3, width=4, height=4), ParameterError,
         "pixel_pitch: expected a number or (width, height)"),
        (lambda: Pinhole.from_params([1.0, 2.0], width=4, height=4), ShapeError, "params: expected shape (5,)"),
    ],
)
def test_bad_input(call, exc, needle):
    with pytest.raises(exc) as info:
        call()
    assert isinstance(info.value, CamkitError)
    assert needle in str(info.value)
