"""Stereo rectification and triangulation (issue 24): OpenCV's stereoRectify as the oracle of
the rotations, the modes' promises, rows that agree after rectification, and triangulated
points inside their reported uncertainty."""

from __future__ import annotations

import numpy as np
import pytest

from camkit.calib import calibrate_rig
from camkit.errors import ParameterError, ShapeError
from camkit.geometry.pose import Pose
from camkit.lens import BrownConrady, KannalaBrandt
from camkit.render import simulate_rig
from camkit.resample import remap
from camkit.stereo import epipolar_error, rectify, rectify_maps, triangulate
from camkit.target import Checkerboard

LEFT = BrownConrady(fx=800.0, fy=800.0, cx=639.5, cy=479.5, width=1280, height=960, k1=-0.1, k2=0.02)
RIGHT = BrownConrady(fx=820.0, fy=815.0, cx=630.0, cy=470.0, width=1280, height=960, k1=-0.12, k2=0.03,
                     p1=3e-4)
RIGHT_FROM_LEFT = Pose.from_rvec([0.01, -0.02, 0.005], [-0.12, 0.001, 0.002])
LEFT_FROM_RIGHT = RIGHT_FROM_LEFT.inverse()
#: Chi-square with 3 degrees of freedom at 0.9973 (the probability within 3 sigma in one
#: dimension): the region a "3-sigma ellipsoid" of a 3-D point holds with that probability.
CHI2_3_9973 = 14.156


def _points(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.uniform([-0.5, -0.4, 1.0], [0.5, 0.4, 3.0], (n, 3))


@pytest.mark.parametrize("rvec,t", [([0.01, -0.02, 0.005], [-0.12, 0.001, 0.002]),
                                    ([0.0, 0.0, 0.0], [0.3, 0.0, 0.0]),
                                    ([0.02, 0.05, -0.01], [0.002, -0.1, 0.004])])
def test_rotations_agree_with_opencv_stereo_rectify(rvec, t) -> None:
    cv2 = pytest.importorskip("cv2")
    rfl = Pose.from_rvec(rvec, t)
    r = rectify(LEFT, RIGHT, rfl.inverse())
    dist = [np.array([m.k1, m.k2, m.p1, m.p2, m.k3]) for m in (LEFT, RIGHT)]
    R1, R2, _, P2, Q, _, _ = cv2.stereoRectify(LEFT.K, dist[0], RIGHT.K, dist[1], (1280, 960),
                                                np.array(rfl.R), np.array(rfl.t).reshape(3, 1), alpha=0)
    assert np.abs(R1 - r.rect_from_left).max() < 1e-12
    assert np.abs(R2 - r.rect_from_right).max() < 1e-12
    # The baseline in the rectified frame is OpenCV's P2 translation over its focal length.
    k = 1 if r.vertical else 0
    assert r.vertical == (abs(t[1]) > abs(t[0]))
    assert r.baseline[k] == pytest.approx(P2[k, 3] / P2[0, 0], rel=1e-12)
    assert np.abs(np.delete(r.baseline, k)).max() < 1e-12
    assert r.Q[3, 2] == pytest.approx(Q[3, 2], rel=1e-12)  # -1 / baseline, in both


def test_rectified_rows_agree_and_q_gives_the_points_back() -> None:
    r = rectify(LEFT, RIGHT, LEFT_FROM_RIGHT)
    X = _points(np.random.default_rng(0), 300)
    pl, pr = LEFT.project(X), RIGHT.project(RIGHT_FROM_LEFT.apply(X))
    assert np.abs(epipolar_error(pl, pr, r)).max() < 1e-8
    ql, qr = r.rectify_points(pl, "left"), r.rectify_points(pr, "right")
    P = np.c_[ql, ql[:, 0] - qr[:, 0], np.ones(len(X))] @ r.Q.T
    assert np.abs(P[:, :3] / P[:, 3:] - X @ r.rect_from_left.T).max() < 1e-9
    # OpenCV's P1, P2 project the rectified-left points.
    Xh = np.c_[X @ r.rect_from_left.T, np.ones(len(X))]
    for P_, q in ((r.P_left, ql), (r.P_right, qr)):
        h = Xh @ P_.T
        assert np.abs(h[:, :2] / h[:, 2:] - q).max() < 1e-8


@pytest.mark.parametrize("mode", ["valid", "full", 0.5])
def test_modes_keep_their_promise(mode) -> None:
    r = rectify(LEFT, RIGHT, LEFT_FROM_RIGHT, mode=mode)
    maps = rectify_maps(r, dtype=np.float64)
    for m, model, roi in zip(maps, (LEFT, RIGHT), (r.valid_left, r.valid_right), strict=True):
        x, y, w, h = roi
        sub = m[y:y + h, x:x + w]
        # Every pixel of the valid rectangle sees its source image.
        assert ((sub[..., 0] >= -0.5) & (sub[..., 0] <= model.width - 0.5)
                & (sub[..., 1] >= -0.5) & (sub[..., 1] <= model.height - 0.5)).all()
        if mode == "valid":
            assert (x, y, w, h) == (0, 0, 1280, 960)
    if mode == "full":
        # Every source pixel of both images lands inside its rectified image.
        u, v = np.meshgrid(np.linspace(0, 1279, 41), np.linspace(0, 959, 31))
        for side in ("left", "right"):
            q = r.rectify_points(np.stack([u.ravel(), v.ravel()], -1), side)
            assert ((q >= -0.5) & (q <= np.array([1279.5, 959.5]))).all()


def test_rectified_images_put_a_corner_on_one_row() -> None:
    """Rendered views, rectified with camkit's maps and remap: the detector's corners in the two
    rectified images lie on the same rows."""
    board = Checkerboard(inner_cols=8, inner_rows=6, square=0.03)
    small_l = BrownConrady(fx=600.0, fy=600.0, cx=319.5, cy=239.5, width=640, height=480, k1=-0.1)
    small_r = BrownConrady(fx=605.0, fy=603.0, cx=316.0, cy=242.0, width=640, height=480, k1=-0.11)
    inst = simulate_rig([small_l, small_r], [Pose.identity(), RIGHT_FROM_LEFT], board, 2, seed=2, fill=(0.5, 0.6))
    r = rectify(small_l, small_r, LEFT_FROM_RIGHT)
    maps = rectify_maps(r)
    for i in inst:
        dets = [board.detect(remap(img.astype(np.float32), m)) for img, m in zip(i.images, maps, strict=True)]
        if not all(d.found for d in dets):
            continue
        dy = dets[0].corners[:, 1] - dets[1].corners[:, 1]
        assert np.sqrt(np.nanmean(dy**2)) < 0.05
        return
    pytest.fail("the board was not found in both rectified images of either instant")


def test_triangulation_is_exact_without_noise_and_handles_fisheye() -> None:
    X = _points(np.random.default_rng(1), 200)
    tr = triangulate(LEFT.project(X), RIGHT.project(RIGHT_FROM_LEFT.apply(X)), (LEFT, RIGHT, LEFT_FROM_RIGHT))
    assert np.abs(tr.points - X).max() < 1e-9
    assert tr.reprojection_px.max() < 1e-6
    fish = KannalaBrandt(fx=400.0, fy=400.0, cx=639.5, cy=479.5, width=1280, height=960, k1=0.05)
    tr = triangulate(fish.project(X), RIGHT.project(RIGHT_FROM_LEFT.apply(X)), (fish, RIGHT, LEFT_FROM_RIGHT))
    assert np.abs(tr.points - X).max() < 1e-9


def test_pixel_noise_covariance_holds_the_errors() -> None:
    rng = np.random.default_rng(2)
    X = _points(rng, 4000)
    pl = LEFT.project(X) + rng.normal(0.0, 0.2, (len(X), 2))
    pr = RIGHT.project(RIGHT_FROM_LEFT.apply(X)) + rng.normal(0.0, 0.2, (len(X), 2))
    tr = triangulate(pl, pr, (LEFT, RIGHT, LEFT_FROM_RIGHT), sigma_px=0.2)
    e = tr.points - X
    d2 = np.einsum("ni,nij,nj->n", e, np.linalg.inv(tr.covariance), e)
    # Chi-square, 3 degrees of freedom: 97.07 % under 9, 99.73 % under 14.16.
    assert 0.96 < np.mean(d2 <= 9.0) < 0.98
    assert np.mean(d2 <= CHI2_3_9973) > 0.99


def test_calibration_covariance_is_carried_into_the_points() -> None:
    """Item 5: calibrate the rig from 15 instants at 0.1 px, triangulate fresh noisy pixels;
    errors against the covariance from the pixel noise and the calibration, over 20 rigs."""
    board = Checkerboard(inner_cols=9, inner_rows=6, square=0.04)
    d2_all, d2_pixels_only = [], []
    for seed in range(20):
        inst = simulate_rig([LEFT, RIGHT], [Pose.identity(), RIGHT_FROM_LEFT], board, 15, seed=seed, render=False)
        rng = np.random.default_rng(seed)
        views = [[i.corners_px[c] + rng.normal(0.0, 0.1, i.corners_px[c].shape) for i in inst] for c in range(2)]
        rig = calibrate_rig(views, board, sizes=(1280, 960), names=("left", "right"))
        X = _points(rng, 100)
        pl = LEFT.project(X) + rng.normal(0.0, 0.1, (len(X), 2))
        pr = RIGHT.project(RIGHT_FROM_LEFT.apply(X)) + rng.normal(0.0, 0.1, (len(X), 2))
        for pair, out in ((rig, d2_all), ((rig.cameras[0].model, rig.cameras[1].model,
                                          rig.relative_pose(0, 1)), d2_pixels_only)):
            tr = triangulate(pl, pr, pair, cameras=("left", "right"), sigma_px=0.1)
            e = tr.points - X
            out.append(np.einsum("ni,nij,nj->n", e, np.linalg.inv(tr.covariance), e))
    inside = np.mean(np.concatenate(d2_all) <= CHI2_3_9973)
    inside_pixels_only = np.mean(np.concatenate(d2_pixels_only) <= CHI2_3_9973)
    assert inside > 0.95 and inside > inside_pixels_only + 0.05, (inside, inside_pixels_only)


def test_bad_input() -> None:
    with pytest.raises(ParameterError, match="mode"):
        rectify(LEFT, RIGHT, LEFT_FROM_RIGHT, mode="cropped")
    with pytest.raises(ParameterError, match="mode"):
        rectify(LEFT, RIGHT, LEFT_FROM_RIGHT, mode=1.5)
    with pytest.raises(ParameterError, match="zero baseline"):
        rectify(LEFT, RIGHT, Pose.identity())
    with pytest.raises(ParameterError, match="left_from_right"):
        rectify(LEFT, RIGHT, "pose")
    with pytest.raises(ParameterError, match="right: expected a camkit camera model"):
        rectify(LEFT, None, LEFT_FROM_RIGHT)
    with pytest.raises(ShapeError, match="px_left, px_right"):
        triangulate(np.zeros((3, 2)), np.zeros((4, 2)), (LEFT, RIGHT, LEFT_FROM_RIGHT))
    with pytest.raises(ParameterError, match="pair"):
        triangulate(np.zeros((3, 2)), np.zeros((3, 2)), LEFT)
    with pytest.raises(ParameterError, match="sigma_px"):
        triangulate(np.zeros((3, 2)), np.zeros((3, 2)), (LEFT, RIGHT, LEFT_FROM_RIGHT), sigma_px=-1)
    with pytest.raises(ParameterError, match="rectification"):
        rectify_maps(None)


def test_triangulation_edge_cases() -> None:
    """Empty input gives empty output; NaN pixels and parallel rays (a point at infinity) give
    NaN rows, never a number; integer pixels are accepted."""
    pair = (LEFT, RIGHT, LEFT_FROM_RIGHT)
    tr = triangulate(np.zeros((0, 2)), np.zeros((0, 2)), pair)
    assert tr.points.shape == (0, 3) and tr.covariance.shape == (0, 3, 3)
    tr = triangulate(np.array([[np.nan, np.nan], [600.0, 400.0]]), np.array([[600.0, 400.0], [np.nan, np.nan]]),
                     pair)
    assert np.isnan(tr.points).all()
    with pytest.raises(ParameterError, match="px_left: expected finite values"):
        triangulate(np.array([[np.nan, 1.0]]), np.array([[600.0, 400.0]]), pair)
    same = Pose.from_rvec([0, 0, 0], [-0.1, 0, 0])
    tr = triangulate(np.array([[639.5, 479.5]]), np.array([[639.5, 479.5]]), (LEFT, LEFT, same), sigma_px=0.1)
    assert np.isnan(tr.points).all() and np.isnan(tr.covariance).all()
    X = np.array([[0.1, -0.05, 2.0]])
    pl = np.round(LEFT.project(X)).astype(np.int64)
    assert np.isfinite(triangulate(pl, np.round(RIGHT.project(RIGHT_FROM_LEFT.apply(X))).astype(int), pair).points).all()
    with pytest.raises(ShapeError, match="px_left"):
        triangulate("a", "b", pair)
    r = rectify(LEFT, RIGHT, LEFT_FROM_RIGHT)
    assert epipolar_error(np.zeros((0, 2)), np.zeros((0, 2)), r).shape == (0,)
    with pytest.raises(ShapeError, match="px_left, px_right"):
        epipolar_error(np.zeros((2, 2)), np.zeros((3, 2)), r)
    with pytest.raises(ParameterError, match="rectification"):
        epipolar_error(np.zeros((2, 2)), np.zeros((2, 2)), None)
    with pytest.raises(ParameterError, match="side"):
        r.rectify_points(np.zeros((1, 2)), "middle")
    with pytest.raises(ParameterError, match="size width"):
        rectify(LEFT, RIGHT, LEFT_FROM_RIGHT, size=(0, 10))


def test_simulate_rig_bad_input() -> None:
    board = Checkerboard(inner_cols=5, inner_rows=4, square=0.03)
    with pytest.raises(ParameterError, match="instants"):
        simulate_rig([LEFT], [Pose.identity()], board, 0)
    with pytest.raises(ParameterError, match="one pose per camera"):
        simulate_rig([LEFT, RIGHT], [Pose.identity()], board, 1)
    with pytest.raises(ParameterError, match=r"cameras\[0\]"):
        simulate_rig(["x"], [Pose.identity()], board, 1)
    with pytest.raises(ParameterError, match="target"):
        simulate_rig([LEFT], [Pose.identity()], "board", 1, render=False)
