"""Lens models: projection, unprojection (to 1e-9) and undistortion maps vs OpenCV."""

from __future__ import annotations

import cv2
import numpy as np

from benchmarks.harness import Case
from camkit.lens import BrownConrady, KannalaBrandt, Pinhole
from camkit.resample import undistort_map


def cases() -> list[Case]:
    rng = np.random.default_rng(0)
    n = 1_000_000
    K = np.array([[1500.0, 0.0, 960.3], [0.0, 1490.0, 540.8], [0.0, 0.0, 1.0]])
    d5 = np.array([-0.28, 0.11, 8e-4, -5e-4, -0.02])
    d8 = np.array([-0.28, 0.11, 8e-4, -5e-4, -0.02, 0.05, 0.01, 0.002])
    bc5 = BrownConrady(fx=1500.0, fy=1490.0, cx=960.3, cy=540.8, width=1920, height=1080,
                       k1=-0.28, k2=0.11, p1=8e-4, p2=-5e-4, k3=-0.02)
    bc8 = bc5.replace(k4=0.05, k5=0.01, k6=0.002)
    # Points in front of the camera, spread over the image.
    X = np.empty((n, 3))
    X[:, 0] = rng.uniform(-0.6, 0.6, n)
    X[:, 1] = rng.uniform(-0.35, 0.35, n)
    X[:, 2] = 1.0
    X *= rng.uniform(1.0, 10.0, (n, 1))
    zero = np.zeros(3)

    Kf = np.array([[600.0, 0.0, 960.0], [0.0, 601.0, 540.0], [0.0, 0.0, 1.0]])
    D = np.array([-0.012, 0.035, -0.014, 0.002])
    kb = KannalaBrandt(fx=600.0, fy=601.0, cx=960.0, cy=540.0, width=1920, height=1080,
                       k1=-0.012, k2=0.035, k3=-0.014, k4=0.002)
    Xf = X.copy()

    px = rng.uniform([0.0, 0.0], [1919.0, 1079.0], size=(n, 2))
    px_cv = px.reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-9)

    big = BrownConrady(fx=3000.0, fy=3010.0, cx=2001.3, cy=1498.2, width=4000, height=3000,
                       k1=-0.2, k2=0.08, k3=-0.01, p1=1e-3, p2=-5e-4)
    Kb, db = big.to_opencv()
    new = Pinhole(fx=big.fx, fy=big.fy, cx=big.cx, cy=big.cy, width=4000, height=3000)

    return [
        Case("project, Brown-Conrady 5 coefficients", "1e6 points", lambda: bc5.project(X),
             "cv2.projectPoints", lambda: cv2.projectPoints(X, zero, zero, K, d5), target=1.0),
        Case("project, Brown-Conrady 8 coefficients", "1e6 points", lambda: bc8.project(X),
             "cv2.projectPoints", lambda: cv2.projectPoints(X, zero, zero, K, d8), target=1.0),
        Case("project, Kannala-Brandt fisheye", "1e6 points", lambda: kb.project(Xf),
             "cv2.fisheye.projectPoints",
             lambda: cv2.fisheye.projectPoints(Xf.reshape(-1, 1, 3), zero, zero, Kf, D), target=1.0),
        Case("unproject to 1e-9, Brown-Conrady 5 coefficients", "1e6 pixels", lambda: bc5.unproject(px),
             "cv2.undistortPoints (criteria 100 iter, eps 1e-9)",
             lambda: cv2.undistortPoints(px_cv, K, d5, criteria=criteria), target=1.0),
        Case("undistort map, Brown-Conrady", "4000x3000", lambda: undistort_map(big, new),
             "cv2.initUndistortRectifyMap (CV_32FC1)",
             lambda: cv2.initUndistortRectifyMap(Kb, db, None, Kb, (4000, 3000), cv2.CV_32FC1), target=1.0),
    ]
