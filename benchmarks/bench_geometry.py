"""Geometry: projecting points through a posed pinhole, rotation vectors to matrices."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from benchmarks.harness import Case
from camkit.geometry import Pose, matrix_from_rvec
from camkit.lens import Pinhole


def cases() -> list[Case]:
    rng = np.random.default_rng(0)
    n = 1_000_000
    X = rng.uniform(-1, 1, size=(n, 3))
    cam = Pinhole(fx=1500.0, fy=1490.0, cx=960.3, cy=540.8, width=1920, height=1080)
    pose = Pose.from_rvec([0.3, -0.2, 0.1], [0.2, -0.1, 3.0])
    K = cam.K
    rvec, tvec = pose.rvec, pose.t
    rv = rng.normal(size=(n, 3))
    return [
        Case("project points through a posed Pinhole", "1e6 points",
             lambda: cam.project(pose.apply(X)),
             "cv2.projectPoints", lambda: cv2.projectPoints(X, rvec, tvec, K, None), target=1.0),
        Case("rotation vector -> matrix", "1e6 vectors",
             lambda: matrix_from_rvec(rv),
             "scipy Rotation.from_rotvec().as_matrix()",
             lambda: Rotation.from_rotvec(rv).as_matrix(), target=1.0),
    ]
