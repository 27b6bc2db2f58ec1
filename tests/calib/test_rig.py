"""Rig calibration (issue 24): simulated stereo and three-camera rigs against their truth,
the reported sigma against the spread over seeds, OpenCV's stereoCalibrate on the same corners,
and bad input."""

from __future__ import annotations

import numpy as np
import pytest

from camkit.calib import RigResult, calibrate_rig
from camkit.errors import EstimationError, ParameterError, ShapeError
from camkit.geometry.pose import Pose
from camkit.lens import BrownConrady
from camkit.render import simulate_rig
from camkit.target import Checkerboard

BOARD = Checkerboard(inner_cols=12, inner_rows=9, square=0.04)
LEFT = BrownConrady(fx=1400.0, fy=1400.0, cx=799.5, cy=599.5, width=1600, height=1200, k1=-0.1, k2=0.02)
RIGHT = BrownConrady(fx=1410.0, fy=1405.0, cx=790.0, cy=590.0, width=1600, height=1200, k1=-0.12, k2=0.03,
                     p1=2e-4)
#: A 12 cm baseline, the right camera slightly turned.
RIGHT_FROM_LEFT = Pose.from_rvec([0.01, -0.02, 0.005], [-0.12, 0.001, 0.002])


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(a @ b.T) - 1) / 2, -1.0, 1.0))))


def _views(cameras, poses, seed: int, n: int = 15, noise: float = 0.1):
    inst = simulate_rig(cameras, poses, BOARD, n, seed=seed, render=False)
    rng = np.random.default_rng(10_000 + seed)
    return [[i.corners_px[c] + rng.normal(0.0, noise, i.corners_px[c].shape) for i in inst]
            for c in range(len(cameras))], inst


def test_stereo_rig_recovers_the_relative_pose_within_its_sigma() -> None:
    views, inst = _views([LEFT, RIGHT], [Pose.identity(), RIGHT_FROM_LEFT], seed=0)
    r = calibrate_rig(views, BOARD, sizes=(1600, 1200), names=("left", "right"))
    assert isinstance(r, RigResult) and r.converged
    assert r.names == ("left", "right") and r.cam_from_rig[0].allclose(Pose.identity())
    err = _angle_deg(r.cam_from_rig[1].R, RIGHT_FROM_LEFT.R)
    sigma = float(np.linalg.norm(r.rotation_sigma_deg[1]))
    assert err < 3 * sigma and err < 0.03, (err, sigma)
    base = float(np.linalg.norm(RIGHT_FROM_LEFT.t))
    assert abs(r.baseline_m[1] - base) < 3 * r.baseline_sigma_m[1] + 1e-12
    assert abs(r.baseline_m[1] - base) / base < 5e-4
    # The residuals are the noise's: 0.1 px per axis -> RMS of the 2-D error about 0.14 px.
    assert 0.12 < r.rms_px < 0.16
    assert r.camera_rms_px.shape == (2,) and np.isfinite(r.instant_rms_px).all()
    # Per camera, what a single-camera calibration gives: the model within its sigma.
    for cam, truth in zip(r.cameras, (LEFT, RIGHT), strict=True):
        for p in ("fx", "cx", "cy"):
            assert abs(getattr(cam.model, p) - getattr(truth, p)) < 4 * cam.stddev[p]
        assert len(cam.poses) == 15 and cam.view_indices == tuple(range(15))
    # The rig's pose per instant and the relative pose helper.
    assert r.rig_from_target[3].allclose(inst[3].rig_from_target, atol=2e-3)
    assert r.relative_pose("left", "right").allclose(r.cam_from_rig[1].inverse(), atol=1e-12)
    d = r.to_dict()
    assert d["format"] == "camkit-rig" and d["cameras"][1]["name"] == "right"


def test_a_12_mp_pair_is_within_a_hundredth_of_a_degree() -> None:
    """Issue 24 item 5's figures on a sample (benchmarks/rig_acceptance.py --scale 2.5 runs 30
    seeds: max 0.0086 deg): the same lenses on 4000x3000 sensors, 15 instants, 0.1 px. At
    1600x1200 the rotation's own sigma (0.011 deg) is above the bound, so no estimator keeps
    every seed within it there; at 12 MP the sigma is 0.0044 deg and every seed is."""
    from benchmarks.rig_acceptance import cameras

    left, right, _ = cameras(2.5)
    for seed in range(6):
        views, _ = _views([left, right], [Pose.identity(), RIGHT_FROM_LEFT], seed=seed)
        r = calibrate_rig(views, BOARD, sizes=(4000, 3000))
        err = _angle_deg(r.cam_from_rig[1].R, RIGHT_FROM_LEFT.R)
        assert err < 0.01 and err < 3.5 * np.linalg.norm(r.rotation_sigma_deg[1]), (seed, err)
        base = float(np.linalg.norm(RIGHT_FROM_LEFT.t))
        assert abs(r.baseline_m[1] - base) / base < 5e-4


def test_reported_sigma_matches_the_spread_over_seeds() -> None:
    """Item 5: the reported 1-sigma of the relative pose against the standard deviation of the
    estimates over 30 seeds (noise 0.1 px), within a factor of 1.5 on every axis."""
    est, sig = [], []
    for seed in range(30):
        views, _ = _views([LEFT, RIGHT], [Pose.identity(), RIGHT_FROM_LEFT], seed=seed)
        r = calibrate_rig(views, BOARD, sizes=(1600, 1200))
        p = r.cam_from_rig[1]
        # The rotation's error as the small vector w of R = exp([w]x) R_true (the solver's).
        dR = p.R @ RIGHT_FROM_LEFT.R.T
        w = np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]) / 2
        est.append(np.r_[np.degrees(w), p.t])
        sig.append(np.r_[r.rotation_sigma_deg[1], r.translation_sigma_m[1]])
    ratio = np.std(est, axis=0) / np.mean(sig, axis=0)
    assert (ratio > 1 / 1.5).all() and (ratio < 1.5).all(), ratio


def test_three_camera_rig_with_instants_some_cameras_miss() -> None:
    third = BrownConrady(fx=1380.0, fy=1380.0, cx=805.0, cy=602.0, width=1600, height=1200, k1=-0.08)
    poses = [Pose.identity(), RIGHT_FROM_LEFT, Pose.from_rvec([-0.02, 0.01, 0.0], [0.0, -0.1, 0.003])]
    views, _ = _views([LEFT, RIGHT, third], poses, seed=3, n=18)
    # The third camera misses the first six instants; the second the last three.
    for t in range(6):
        views[2][t] = None
    for t in range(15, 18):
        views[1][t] = None
    r = calibrate_rig(views, BOARD, sizes=(1600, 1200), names=("a", "b", "c"))
    for k in (1, 2):
        assert _angle_deg(r.cam_from_rig[k].R, poses[k].R) < 0.05
        assert np.linalg.norm(r.cam_from_rig[k].t - poses[k].t) < 1e-3
    assert r.cameras[2].view_indices == tuple(range(6, 18))
    assert [t for t, _ in r.cameras[1].rejected_views] == [15, 16, 17]


def test_fixed_intrinsics_are_kept() -> None:
    views, _ = _views([LEFT, RIGHT], [Pose.identity(), RIGHT_FROM_LEFT], seed=5)
    r = calibrate_rig(views, BOARD, sizes=(1600, 1200), intrinsics=[LEFT, None])
    assert r.cameras[0].model.params() == pytest.approx(LEFT.params(), abs=0)
    assert r.cameras[0].free_params == ()
    assert all(not p.startswith("cam0.f") for p in r.param_names)
    assert _angle_deg(r.cam_from_rig[1].R, RIGHT_FROM_LEFT.R) < 0.05


def test_a_held_camera_keeps_one_model_until_its_points_reach_farther() -> None:
    """A camera whose intrinsics are all held keeps the model the solver projects with; where
    the points reach past the radius its valid disk was searched to, the search runs again,
    and the projections are those of a fresh model for those points (a strong barrel lens,
    whose valid disk ends near 0.85 of the ideal radius). A camera given as a model keeps
    that model."""
    from camkit.calib.rig import _RigProblem, _RigState

    lens = BrownConrady(fx=800.0, fy=800.0, cx=640.0, cy=480.0, width=1280, height=960, k1=-0.45)
    obj = BOARD.object_points()
    problem = _RigProblem([BrownConrady], [(1280, 960)], ["cam0"], [[]], 0,
                          [(0, 0, obj, np.zeros((len(obj), 2)))], 1)
    state = _RigState((lens.params(),), np.eye(3)[None], np.zeros((1, 3)), np.eye(3)[None], np.zeros((1, 3)))
    models = []
    for reach in (0.2, 0.22, 0.6):
        xy = np.random.default_rng(0).uniform(-1.0, 1.0, (200, 2))
        xy *= reach / np.hypot(*xy.T).max()
        X = np.c_[xy, np.ones(200)]
        m = problem._pointed(state, 0, X)
        models.append(m)
        np.testing.assert_array_equal(m.project(X), lens.for_points(X).project(X))
        assert np.isfinite(m.project(X)).all()
    assert models[0] is models[1] and models[2] is not models[1]
    # A camera given with its intrinsics (calibrate_rig's intrinsics=) projects through the
    # model it was given, whose valid radius is searched over its whole image once.
    given = _RigProblem([BrownConrady], [(1280, 960)], ["cam0"], [[]], 0,
                        [(0, 0, obj, np.zeros((len(obj), 2)))], 1, [lens])
    assert given._pointed(state, 0, X) is lens
    np.testing.assert_array_equal(lens.project(X), models[2].project(X))


def _cv_dist(m: BrownConrady) -> np.ndarray:
    return np.array([m.k1, m.k2, m.p1, m.p2, m.k3])


@pytest.mark.parametrize("fixed", [True, False])
def test_agrees_with_opencv_stereo_calibrate(fixed: bool) -> None:
    """Item 6: cv2.stereoCalibrate on the same corners (the same objective where the models
    agree: Brown-Conrady k1, k2, p1, p2, k3, no skew) gives the same R and T within 1e-6
    relative, intrinsics fixed (CALIB_FIX_INTRINSIC) and free (from camkit's start)."""
    cv2 = pytest.importorskip("cv2")
    views, _ = _views([LEFT, RIGHT], [Pose.identity(), RIGHT_FROM_LEFT], seed=7, n=12)
    both = [t for t in range(12) if np.isfinite(views[0][t]).all() and np.isfinite(views[1][t]).all()]
    views = [[v[t] for t in both] for v in views]
    obj = BOARD.object_points().astype(np.float32)
    if fixed:
        r = calibrate_rig(views, BOARD, sizes=(1600, 1200), intrinsics=[LEFT, RIGHT], reject_sigma=None)
        K1, d1, K2, d2 = LEFT.K, _cv_dist(LEFT), RIGHT.K, _cv_dist(RIGHT)
        flags = cv2.CALIB_FIX_INTRINSIC
    else:
        r = calibrate_rig(views, BOARD, sizes=(1600, 1200), reject_sigma=None)
        # OpenCV starts from camkit's intrinsics, perturbed, and must reach the same minimum.
        m1, m2 = r.cameras[0].model, r.cameras[1].model
        K1, d1, K2, d2 = m1.K * 1.001, _cv_dist(m1) * 0.9, m2.K * 1.001, _cv_dist(m2) * 0.9
        K1[2, 2] = K2[2, 2] = 1.0
        flags = cv2.CALIB_USE_INTRINSIC_GUESS
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 500, 1e-16)
    out = cv2.stereoCalibrate([obj] * len(both), [v.astype(np.float32) for v in views[0]],
                              [v.astype(np.float32) for v in views[1]], K1.copy(), d1.copy(), K2.copy(), d2.copy(),
                              (1600, 1200), flags=flags, criteria=crit)
    R, T = out[5], out[6].ravel()
    p = r.cam_from_rig[1]
    assert np.abs(p.R - R).max() < 1e-6
    assert np.linalg.norm(p.t - T) / np.linalg.norm(T) < 1e-6
    if not fixed:
        assert np.abs(out[1] - r.cameras[0].model.K).max() / 1400 < 1e-6


def test_rendered_stereo_pair_through_the_detector() -> None:
    """The simulator renders each camera's images; the detector's corners calibrate the rig."""
    small_l = BrownConrady(fx=600.0, fy=600.0, cx=319.5, cy=239.5, width=640, height=480, k1=-0.1)
    small_r = BrownConrady(fx=605.0, fy=603.0, cx=316.0, cy=242.0, width=640, height=480, k1=-0.11)
    board = Checkerboard(inner_cols=8, inner_rows=6, square=0.03)
    inst = simulate_rig([small_l, small_r], [Pose.identity(), RIGHT_FROM_LEFT], board, 8, seed=1,
                        fill=(0.5, 0.7))
    views = [[board.detect(i.images[c]) for i in inst] for c in range(2)]
    assert sum(d.found for d in views[0]) >= 7
    r = calibrate_rig(views, board, sizes=(640, 480))
    assert abs(r.baseline_m[1] - 0.12) / 0.12 < 0.01
    assert _angle_deg(r.cam_from_rig[1].R, RIGHT_FROM_LEFT.R) < 0.2
    assert r.rms_px < 0.2


def test_bad_input_names_the_camera_and_the_instant() -> None:
    views, _ = _views([LEFT, RIGHT], [Pose.identity(), RIGHT_FROM_LEFT], seed=2, n=6)
    with pytest.raises(ShapeError, match=r"views\[1\] \(right\): expected 6 instants"):
        calibrate_rig([views[0], views[1][:5]], BOARD, sizes=(1600, 1200), names=("left", "right"))
    with pytest.raises(EstimationError, match="camera 'right': the target was not seen"):
        calibrate_rig([views[0], [None] * 6], BOARD, sizes=(1600, 1200), names=("left", "right"))
    bad = [v.copy() for v in views[1]]
    bad[2] = np.zeros((5, 2))
    with pytest.raises(ShapeError, match=r"views\[1\]\[2\] \(right, instant 2\)"):
        calibrate_rig([views[0], bad], BOARD, sizes=(1600, 1200), names=("left", "right"))
    with pytest.raises(ShapeError, match="2 or more cameras"):
        calibrate_rig([views[0]], BOARD, sizes=(1600, 1200))
    with pytest.raises(ParameterError, match="reference"):
        calibrate_rig(views, BOARD, sizes=(1600, 1200), reference=2)
    with pytest.raises(ParameterError, match="targets"):
        calibrate_rig(views, "board", sizes=(1600, 1200))


def test_a_rig_that_is_not_connected_is_refused_naming_the_cameras() -> None:
    cams = [LEFT, RIGHT, LEFT, RIGHT]
    poses = [Pose.identity(), RIGHT_FROM_LEFT, Pose.from_rvec([0, 3.0, 0], [0, 0, -0.2]),
             RIGHT_FROM_LEFT @ Pose.from_rvec([0, 3.0, 0], [0, 0, -0.2])]
    views, _ = _views(cams, poses, seed=4, n=12)
    # Cameras 0 and 1 see the first six instants, 2 and 3 the last six: two rigs, not one.
    for t in range(12):
        for c in ((2, 3) if t < 6 else (0, 1)):
            views[c][t] = None
    for c in (2, 3):  # the back pair sees the board from behind in the simulation: give it its own
        for t in range(6, 12):
            views[c][t] = views[c - 2][t - 6]
    with pytest.raises(EstimationError, match=r"cameras \['c', 'd'\]: they never see the target at an instant"):
        calibrate_rig(views, BOARD, sizes=(1600, 1200), names=("a", "b", "c", "d"))


def test_real_bumblebee_pairs_agree_with_opencv_within_sigma(shared_data) -> None:
    """Item 6: the Bumblebee2 stereo pairs (30 mm squares; BoofCV-Data, CC-BY-4.0): camkit's
    rig from its own detections; cv2.stereoCalibrate on the same corners (intrinsics started
    from cv2.calibrateCamera) gives R and T within a tenth of camkit's reported sigma, and the
    baseline is the camera's 12 cm."""
    cv2 = pytest.importorskip("cv2")
    from camkit.io import read_image

    folder = shared_data / "real_boards" / "boofcv_bumblebee" / "images"
    board = Checkerboard(inner_cols=6, inner_rows=4, square=0.030)
    det = {side: [board.detect(read_image(f)) for f in sorted(folder.glob(f"*_{side}*.jpg"))]
           for side in ("left", "right")}
    assert len(det["left"]) == len(det["right"]) == 11
    r = calibrate_rig([det["left"], det["right"]], board, sizes=(640, 480), names=("left", "right"))
    assert r.rms_px < 0.15
    assert abs(r.baseline_m[1] - 0.12) < 0.001
    both = [k for k in range(11) if np.isfinite(det["left"][k].corners).all()
            and np.isfinite(det["right"][k].corners).all()]
    obj = [board.object_points().astype(np.float32)] * len(both)
    px = {s: [det[s][k].corners.astype(np.float32) for k in both] for s in det}
    _, K1, d1, _, _ = cv2.calibrateCamera(obj, px["left"], (640, 480), None, None)
    _, K2, d2, _, _ = cv2.calibrateCamera(obj, px["right"], (640, 480), None, None)
    out = cv2.stereoCalibrate(obj, px["left"], px["right"], K1, d1, K2, d2, (640, 480),
                              flags=cv2.CALIB_USE_INTRINSIC_GUESS,
                              criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12))
    p = r.cam_from_rig[1]
    dR = p.R @ out[5].T
    w = np.degrees(np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]) / 2)
    assert (np.abs(w) < 0.1 * r.rotation_sigma_deg[1]).all()
    assert (np.abs(p.t - out[6].ravel()) < 0.1 * r.translation_sigma_m[1]).all()


def test_agrees_with_opencv_fisheye_stereo_calibrate() -> None:
    """Item 6: Kannala-Brandt pairs, intrinsics fixed: cv2.fisheye.stereoCalibrate on the same
    corners gives the same R and T within 1e-6 relative."""
    cv2 = pytest.importorskip("cv2")
    from camkit.lens import KannalaBrandt

    board = Checkerboard(inner_cols=9, inner_rows=6, square=0.04)
    left = KannalaBrandt(fx=400.0, fy=400.0, cx=639.5, cy=479.5, width=1280, height=960, k1=0.02, k2=-0.01,
                         k3=0.003, k4=-0.0005)
    right = KannalaBrandt(fx=405.0, fy=402.0, cx=630.0, cy=470.0, width=1280, height=960, k1=0.025, k2=-0.008,
                          k3=0.002, k4=-0.0003)
    inst = simulate_rig([left, right], [Pose.identity(), RIGHT_FROM_LEFT], board, 12, seed=3, render=False)
    rng = np.random.default_rng(0)
    views = [[i.corners_px[c] + rng.normal(0, 0.1, i.corners_px[c].shape) for i in inst] for c in range(2)]
    both = [t for t in range(12) if np.isfinite(views[0][t]).all() and np.isfinite(views[1][t]).all()]
    views = [[v[t] for t in both] for v in views]
    r = calibrate_rig(views, board, sizes=(1280, 960), intrinsics=[left, right], reject_sigma=None)
    obj = [board.object_points().reshape(-1, 1, 3)] * len(both)
    d = [np.array([m.k1, m.k2, m.k3, m.k4]).reshape(4, 1) for m in (left, right)]
    out = cv2.fisheye.stereoCalibrate(obj, [v.reshape(-1, 1, 2) for v in views[0]],
                                      [v.reshape(-1, 1, 2) for v in views[1]], left.K, d[0], right.K, d[1],
                                      (1280, 960), flags=cv2.CALIB_FIX_INTRINSIC,
                                      criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 500, 1e-15))
    p = r.cam_from_rig[1]
    assert np.abs(p.R - out[5]).max() < 1e-6
    assert np.linalg.norm(p.t - out[6].ravel()) / np.linalg.norm(out[6]) < 1e-6
