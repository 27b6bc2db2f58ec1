"""OpenCV as oracle: projectPoints with 4/5/8/12 coefficients, fisheye.projectPoints,
undistortPoints; the converters; the valid region of strong lenses."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from camkit.errors import ParameterError, ShapeError
from camkit.geometry import Pose
from camkit.lens import BrownConrady, KannalaBrandt, Pinhole, from_opencv, from_opencv_fisheye, to_opencv

K = np.array([[812.5, 0.0, 331.2], [0.0, 809.0, 244.7], [0.0, 0.0, 1.0]])
DIST = {
    4: np.array([-0.28, 0.11, 8e-4, -5e-4]),
    5: np.array([-0.28, 0.11, 8e-4, -5e-4, -0.02]),
    8: np.array([-0.28, 0.11, 8e-4, -5e-4, -0.02, 0.05, 0.01, 0.002]),
    12: np.array([-0.28, 0.11, 8e-4, -5e-4, -0.02, 0.05, 0.01, 0.002, 1e-3, -2e-4, 5e-4, 1e-4]),
}


def _scene(n=2000, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.uniform([-0.35, -0.25, 0.8], [0.35, 0.25, 1.2], size=(n, 3))
    return X * rng.uniform(0.5, 4, size=(n, 1))


@pytest.mark.parametrize("n", [4, 5, 8, 12])
def test_project_points_agrees_with_opencv(n):
    cam = from_opencv(K, DIST[n], width=640, height=480)
    pose = Pose.from_rvec([0.05, -0.1, 0.02], [0.01, -0.02, 0.1])
    X = _scene()
    ref, _ = cv2.projectPoints(X, pose.rvec, pose.t, K, DIST[n])
    ours = cam.project(pose.apply(X))
    assert np.isfinite(ours).all()
    assert np.abs(ours - ref.reshape(-1, 2)).max() <= 1e-9


def test_fisheye_project_points_agrees_with_opencv():
    Kf = np.array([[285.0, 0.0, 641.0], [0.0, 286.5, 481.5], [0.0, 0.0, 1.0]])
    D = np.array([-0.012, 0.035, -0.014, 0.002])
    cam = from_opencv_fisheye(Kf, D, width=1280, height=960)
    rng = np.random.default_rng(1)
    X = rng.uniform([-3, -3, 0.05], [3, 3, 3], size=(3000, 1, 3))  # up to ~89 degrees off-axis
    ref, _ = cv2.fisheye.projectPoints(X, np.zeros(3), np.zeros(3), Kf, D)
    assert np.abs(cam.project(X[:, 0]) - ref.reshape(-1, 2)).max() <= 1e-9


def test_converters_round_trip():
    for n, d in DIST.items():
        cam = from_opencv(K, d.reshape(1, -1), width=640, height=480)
        K2, d2 = to_opencv(cam)
        assert np.array_equal(K2, K)
        expected = np.concatenate([d, np.zeros(1)]) if n == 4 else d  # 4 -> 5 with k3 = 0
        assert np.array_equal(d2, expected)
        assert np.array_equal(cam.to_opencv()[1], d2)
    fish = KannalaBrandt(fx=300.0, fy=300.0, cx=320.0, cy=240.0, width=640, height=480, k1=0.1, k4=-0.01)
    Kf, D = to_opencv(fish)
    assert from_opencv_fisheye(Kf, D, width=640, height=480) == fish
    assert from_opencv(K, np.r_[DIST[12], 0.0, 0.0], width=640, height=480) == from_opencv(
        K, DIST[12], width=640, height=480)
    # No distortion vector, as OpenCV's functions take None or an empty one.
    plain = from_opencv(K, np.zeros(4), width=640, height=480)
    assert from_opencv(K, None, width=640, height=480) == plain == from_opencv(K, np.zeros((1, 0)), width=640,
                                                                            height=480)


@pytest.mark.parametrize(
    ("call", "exc", "needle"),
    [
        (lambda: from_opencv(K, np.zeros(6), width=640, height=480), ShapeError, "dist: expected 4, 5, 8, 12 or 14"),
        (lambda: from_opencv(K, np.r_[DIST[12], 0.1, 0.0], width=640, height=480), ParameterError, "tilted-sensor"),
        (lambda: from_opencv(K, [np.nan, 0, 0, 0], width=640, height=480), ParameterError, "dist: expected finite"),
        (lambda: from_opencv(np.ones((3, 3)), DIST[4], width=640, height=480), ParameterError, "K: expected"),
        (lambda: from_opencv_fisheye(K, np.zeros(5), width=640, height=480), ShapeError, "D: expected 4"),
        (lambda: to_opencv(Pinhole(fx=1.0, fy=1.0, cx=0.0, cy=0.0, width=2, height=2)), ParameterError,
         "model: expected a BrownConrady or KannalaBrandt"),
    ],
)
def test_converter_bad_input(call, exc, needle):
    with pytest.raises(exc, match=None) as info:
        call()
    assert needle in str(info.value)


def _grid(w, h, n=65):
    u = np.linspace(-0.5, w - 0.5, n)
    v = np.linspace(-0.5, h - 0.5, n)
    return np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)


def test_strong_rational_lens_opencv_default_is_wrong_camkit_is_right():
    # A strong rational barrel lens, one-to-one over its whole image (the valid disk reaches
    # the search limit, three times the corner radius).
    cam = BrownConrady(fx=400.0, fy=400.0, cx=319.5, cy=239.5, width=640, height=480,
                       k1=-0.35, k2=0.1, k4=0.25)
    px = _grid(640, 480)
    rays = cam.unproject(px)
    assert np.isfinite(rays).all()
    ours = np.abs(cam.project(rays) - px).max()
    assert ours <= 1e-9
    Kc, d = to_opencv(cam)
    und = cv2.undistortPoints(px.reshape(-1, 1, 2), Kc, d).reshape(-1, 2)  # OpenCV's defaults
    back, _ = cv2.projectPoints(np.c_[und, np.ones(len(und))], np.zeros(3), np.zeros(3), Kc, d)
    cv_err = np.abs(back.reshape(-1, 2) - px).max()
    assert cv_err > 20.0  # measured 110.7 px at the corners (OpenCV 5.0)


def test_fold_inside_the_image_gives_nan_not_a_wrong_ray():
    # k1 > 0 with a negative k2: the distorted radius peaks and turns back inside the image.
    cam = BrownConrady(fx=300.0, fy=300.0, cx=319.5, cy=239.5, width=640, height=480, k1=0.3, k2=-0.4)
    r_valid = cam.valid_radius
    # r d/dr [r (1 + k1 r^2 + k2 r^4)] = 0 at 1 + 3 k1 r^2 + 5 k2 r^4 = 0.
    r_fold = np.sqrt((3 * 0.3 + np.sqrt(9 * 0.09 + 20 * 0.4)) / (2 * 5 * 0.4))
    assert r_fold * 0.998 <= r_valid <= r_fold
    px = _grid(640, 480)
    rays = cam.unproject(px)
    ok = np.isfinite(rays).all(axis=-1)
    assert 0 < ok.mean() < 1
    # Every ray given back is right; the others are NaN.
    assert np.abs(cam.project(rays[ok]) - px[ok]).max() <= 1e-9
    xy = rays[ok, :2] / rays[ok, 2:]
    assert np.hypot(xy[:, 0], xy[:, 1]).max() <= r_valid
    # Beyond the fold, project refuses too.
    assert np.isnan(cam.project([[1.01 * r_valid, 0.0, 1.0]])).all()
    assert np.isfinite(cam.project([[0.99 * r_valid, 0.0, 1.0]])).all()


def test_rational_pole_is_outside_the_valid_disk():
    # 1 + k4 r^2 = 0 at r = 1 for k4 = -1: the map has a pole at r = 1.
    cam = BrownConrady(fx=300.0, fy=300.0, cx=319.5, cy=239.5, width=640, height=480, k4=-1.0)
    assert cam.valid_radius < 1.0
    assert np.isnan(cam.project([[1.0, 0.0, 1.0]])).all()


def test_fisheye_valid_angle():
    # theta_d = theta (1 - 0.1 theta^2) peaks where 1 - 0.3 theta^2 = 0.
    cam = KannalaBrandt(fx=300.0, fy=300.0, cx=319.5, cy=239.5, width=640, height=480, k1=-0.1)
    assert cam.valid_theta == pytest.approx(np.sqrt(1 / 0.3), abs=1e-4)
    assert KannalaBrandt(fx=300.0, fy=300.0, cx=0.0, cy=0.0, width=4, height=4).valid_theta == np.pi
