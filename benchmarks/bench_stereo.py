"""Stereo (issue 24, item 7): the rig solve vs cv2.stereoCalibrate on the same corners, and
rectification maps plus remap of a 2 x 12 MP pair vs cv2.initUndistortRectifyMap + cv2.remap."""

from __future__ import annotations

import cv2
import numpy as np

from benchmarks.harness import Case
from camkit.calib import calibrate_rig
from camkit.geometry.pose import Pose
from camkit.lens import BrownConrady
from camkit.render import simulate_rig
from camkit.resample import remap
from camkit.stereo import rectify, rectify_maps
from camkit.target import Checkerboard

BOARD = Checkerboard(inner_cols=12, inner_rows=9, square=0.04)
LEFT = BrownConrady(fx=1400.0, fy=1400.0, cx=799.5, cy=599.5, width=1600, height=1200, k1=-0.1, k2=0.02)
RIGHT = BrownConrady(fx=1410.0, fy=1405.0, cx=790.0, cy=590.0, width=1600, height=1200, k1=-0.12, k2=0.03)
RIGHT_FROM_LEFT = Pose.from_rvec([0.01, -0.02, 0.005], [-0.12, 0.001, 0.002])
BIG_L = BrownConrady(fx=3500.0, fy=3500.0, cx=1999.5, cy=1499.5, width=4000, height=3000, k1=-0.1, k2=0.02)
BIG_R = BrownConrady(fx=3520.0, fy=3510.0, cx=1990.0, cy=1505.0, width=4000, height=3000, k1=-0.11, k2=0.03)


def _dist(m: BrownConrady) -> np.ndarray:
    return np.array([m.k1, m.k2, m.p1, m.p2, m.k3])


def cases() -> list[Case]:
    inst = simulate_rig([LEFT, RIGHT], [Pose.identity(), RIGHT_FROM_LEFT], BOARD, 15, seed=0, render=False)
    rng = np.random.default_rng(0)
    views = [[i.corners_px[c] + rng.normal(0.0, 0.1, i.corners_px[c].shape) for i in inst] for c in range(2)]
    both = [t for t in range(15) if np.isfinite(views[0][t]).all() and np.isfinite(views[1][t]).all()]
    obj = BOARD.object_points().astype(np.float32)
    pts = [[v[t].astype(np.float32) for t in both] for v in views]
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-10)

    def ck_fixed():
        return calibrate_rig([[v[t] for t in both] for v in views], BOARD, sizes=(1600, 1200),
                             intrinsics=[LEFT, RIGHT], reject_sigma=None)

    def cv_fixed():
        return cv2.stereoCalibrate([obj] * len(both), pts[0], pts[1], LEFT.K, _dist(LEFT), RIGHT.K, _dist(RIGHT),
                                   (1600, 1200), flags=cv2.CALIB_FIX_INTRINSIC, criteria=crit)

    def ck_free():
        return calibrate_rig([[v[t] for t in both] for v in views], BOARD, sizes=(1600, 1200), reject_sigma=None)

    def cv_free():
        n = len(both)
        _, K1, d1, _, _ = cv2.calibrateCamera([obj] * n, pts[0], (1600, 1200), None, None, flags=cv2.CALIB_FIX_K3)
        _, K2, d2, _, _ = cv2.calibrateCamera([obj] * n, pts[1], (1600, 1200), None, None, flags=cv2.CALIB_FIX_K3)
        return cv2.stereoCalibrate([obj] * n, pts[0], pts[1], K1, d1, K2, d2, (1600, 1200),
                                   flags=cv2.CALIB_USE_INTRINSIC_GUESS, criteria=crit)

    big = rectify(BIG_L, BIG_R, RIGHT_FROM_LEFT.inverse(), mode="valid")
    rng = np.random.default_rng(1)
    imgs = [rng.integers(0, 256, (3000, 4000, 3), dtype=np.uint8) for _ in range(2)]
    R1, R2, P1, P2, *_ = cv2.stereoRectify(BIG_L.K, _dist(BIG_L), BIG_R.K, _dist(BIG_R), (4000, 3000),
                                           np.array(RIGHT_FROM_LEFT.R), np.array(RIGHT_FROM_LEFT.t).reshape(3, 1),
                                           alpha=0)

    def ck_rect():
        maps = rectify_maps(big)
        return [remap(im, m) for im, m in zip(imgs, maps, strict=True)]

    def cv_rect():
        out = []
        for im, K, d, R, P in ((imgs[0], BIG_L.K, _dist(BIG_L), R1, P1), (imgs[1], BIG_R.K, _dist(BIG_R), R2, P2)):
            mx, my = cv2.initUndistortRectifyMap(K, d, R, P, (4000, 3000), cv2.CV_32FC1)
            out.append(cv2.remap(im, mx, my, cv2.INTER_LINEAR))
        return out

    return [
        Case("stereo solve, intrinsics fixed", f"{len(both)} instants, 2 x 108 corners", ck_fixed,
             "cv2.stereoCalibrate (CALIB_FIX_INTRINSIC)", cv_fixed, target=1.0, repeats=5, warmup=1),
        Case("stereo solve, intrinsics free (from scratch)", f"{len(both)} instants, 2 x 108 corners", ck_free,
             "cv2.calibrateCamera x 2 + cv2.stereoCalibrate", cv_free, target=1.0, repeats=5, warmup=1),
        Case("rectify_maps + remap (bilinear)", "2 x 12 MP RGB", ck_rect,
             "cv2.initUndistortRectifyMap + cv2.remap", cv_rect, target=1.0, repeats=3, warmup=1),
    ]
