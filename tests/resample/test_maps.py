"""Lens maps: agreement with OpenCV, round trips through reprojection, optimal_pinhole."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from camkit.errors import ParameterError, ShapeError
from camkit.geometry import matrix_from_rvec
from camkit.lens import BrownConrady, KannalaBrandt, Pinhole
from camkit.resample import optimal_pinhole, remap, reproject_map, undistort_image, undistort_map

BC = BrownConrady(fx=600.0, fy=602.0, cx=321.3, cy=238.2, width=640, height=480,
                  k1=-0.3, k2=0.12, k3=-0.02, p1=1e-3, p2=-5e-4)
NEW = Pinhole(fx=560.0, fy=560.0, cx=319.5, cy=239.5, width=640, height=480)


def test_undistort_map_agrees_with_opencv():
    R = matrix_from_rvec([0.01, -0.02, 0.005])  # OpenCV's R is dst_from_src
    K, d = BC.to_opencv()
    ours = reproject_map(BC, NEW, R.T, dtype=np.float64)
    mx, my = cv2.initUndistortRectifyMap(K, d, R, NEW.K, (640, 480), cv2.CV_32FC1)
    # OpenCV returns float32: agreement to its resolution (~3e-5 px at 600 px).
    assert np.abs(ours[..., 0] - mx).max() < 1e-4
    assert np.abs(ours[..., 1] - my).max() < 1e-4


def test_fisheye_map_agrees_with_opencv():
    kb = KannalaBrandt(fx=250.0, fy=251.0, cx=320.0, cy=240.0, width=640, height=480, k1=0.02, k2=-0.004)
    Kf, D = kb.to_opencv()
    ours = undistort_map(kb, NEW, dtype=np.float64)
    mx, my = cv2.fisheye.initUndistortRectifyMap(Kf, D, np.eye(3), NEW.K, (640, 480), cv2.CV_32FC1)
    assert np.abs(ours[..., 0] - mx).max() < 1e-4 and np.abs(ours[..., 1] - my).max() < 1e-4


@pytest.mark.parametrize("src", [BC, BC.replace(k4=0.05, k5=0.01)], ids=["plain", "rational"])
@pytest.mark.parametrize("rotated", [False, True])
@pytest.mark.parametrize("dst", [NEW, BC.replace(k1=-0.1, k2=0.0, k3=0.0)], ids=["pinhole", "generic"])
def test_map_matches_project_unproject(src, rotated, dst):
    # Every kernel path (constant-depth rows or not, rational or not, fused or generic):
    # the map is exactly src.project(R @ dst.unproject(p)).
    R = matrix_from_rvec([0.02, 0.01, -0.01]) if rotated else np.eye(3)
    m = reproject_map(src, dst, R, dtype=np.float64)
    rng = np.random.default_rng(0)
    rows = rng.integers(0, 480, 200)
    cols = rng.integers(0, 640, 200)
    px = np.stack([cols, rows], axis=-1).astype(np.float64)
    expect = src.project(dst.unproject(px) @ R.T)
    assert np.allclose(m[rows, cols], expect, atol=1e-9, equal_nan=True)


def test_map_nan_outside_the_source_lens():
    fold = BrownConrady(fx=300.0, fy=300.0, cx=319.5, cy=239.5, width=640, height=480, k1=0.3, k2=-0.4)
    wide = Pinhole(fx=150.0, fy=150.0, cx=319.5, cy=239.5, width=640, height=480)
    m = undistort_map(fold, wide)
    nan = np.isnan(m).any(axis=-1)
    assert nan[0, 0] and not nan[240, 320]
    img = np.full((480, 640), 200, np.uint8)
    out = remap(img, m, fill_value=7)
    assert out[0, 0] == 7 and out[240, 320] == 200


def test_undistort_image_straightens_lines():
    # A straight vertical line in the scene is curved in the distorted image; undistorting
    # makes it straight again.
    H, W = 480, 640
    X = np.stack([np.full(400, 0.3), np.linspace(-0.4, 0.4, 400), np.ones(400)], axis=-1)
    curved = BC.project(X)
    # The distorted image of a bright band around x_ideal = 0.3, rendered through unproject.
    ideal = NEW.replace(fx=BC.fx, fy=BC.fy, cx=BC.cx, cy=BC.cy)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    rays = BC.unproject(np.stack([xx, yy], -1))
    xn = rays[..., 0] / rays[..., 2]
    img = np.clip(1 - np.abs(xn - 0.3) / 0.01, 0, 1)
    assert np.ptp(curved[:, 0]) > 5  # visibly curved in the distorted image
    und = undistort_image(img, BC, ideal, interpolation="bicubic")
    rows = np.arange(60, 420)
    cols = (und[rows] * np.arange(W)).sum(axis=1) / und[rows].sum(axis=1)
    assert np.ptp(cols) < 0.05  # straight to a twentieth of a pixel
    assert abs(cols.mean() - (ideal.cx + 0.3 * ideal.fx)) < 0.05


def test_optimal_pinhole_promises():
    for alpha in (0.0, 1.0):
        new = optimal_pinhole(BC, alpha)
        m = undistort_map(BC, new, dtype=np.float64)
        inside = ((m[..., 0] >= -0.5) & (m[..., 0] <= 639.5) & (m[..., 1] >= -0.5) & (m[..., 1] <= 479.5))
        if alpha == 0.0:
            assert inside.all()  # every output pixel sees the scene
        else:
            # every source pixel is kept: the source border maps inside the output
            edge = np.concatenate([np.stack([np.arange(640), np.zeros(640)], -1),
                                   np.stack([np.zeros(480), np.arange(480)], -1),
                                   np.stack([np.full(480, 639.0), np.arange(480)], -1),
                                   np.stack([np.arange(640), np.full(640, 479.0)], -1)])
            q = new.project(BC.unproject(edge))
            assert (q >= -0.5).all() and (q[:, 0] <= 639.5).all() and (q[:, 1] <= 479.5).all()
        assert new.fy / new.fx == pytest.approx(BC.fy / BC.fx, rel=1e-12)
    f = [optimal_pinhole(BC, a).fx for a in (0.0, 0.25, 0.5, 0.75, 1.0)]
    assert np.all(np.diff(f) < 0)  # more alpha, wider view (shorter focal length)


def test_optimal_pinhole_is_stable():
    # opencv/opencv#24923: a tiny change of the input moves OpenCV's result by tens of pixels.
    # Here a 0.1 px change of the principal point moves the new one by about as much.
    base = optimal_pinhole(BC, 0.0)
    for dx, dy in [(0.1, 0.0), (0.0, 0.1), (-0.1, 0.1)]:
        moved = optimal_pinhole(BC.replace(cx=BC.cx + dx, cy=BC.cy + dy), 0.0)
        assert abs(moved.cx - base.cx) <= 0.3 and abs(moved.cy - base.cy) <= 0.3
        assert abs(moved.fx - base.fx) <= 0.3


def test_bad_input():
    with pytest.raises(ParameterError, match="alpha: expected a number in"):
        optimal_pinhole(BC, 1.5)
    with pytest.raises(ParameterError, match="src_model: expected a camkit camera model"):
        reproject_map(np.eye(3), NEW)
    with pytest.raises(ParameterError, match="rotation: expected a rotation"):
        reproject_map(BC, NEW, np.ones((3, 3)))
    with pytest.raises(ParameterError, match="dtype: expected float32 or float64"):
        undistort_map(BC, dtype=np.int32)
    fish = KannalaBrandt(fx=150.0, fy=150.0, cx=319.5, cy=239.5, width=640, height=480)
    with pytest.raises(ParameterError, match="no ray in front of the camera"):
        optimal_pinhole(fish, 1.0)


def test_undistort_image_refuses_an_image_of_another_size():
    """A model describes the pixels of its own image size: a resized copy remapped through it
    would be silently wrong (the map samples its top-left 640x480)."""
    with pytest.raises(ShapeError, match=r"image: expected 640x480 \(the size the camera model describes\), got "
                                         r"1280x960"):
        undistort_image(np.zeros((960, 1280), np.uint8), BC)
    assert undistort_image(np.zeros((480, 640, 3), np.uint8), BC).shape == (480, 640, 3)
