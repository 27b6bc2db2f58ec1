"""solve_pnp: coplanar and general points, any lens model, OpenCV as oracle, bad input."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from camkit.calib import solve_pnp
from camkit.errors import EstimationError
from camkit.geometry import Pose
from camkit.render import default_camera
from camkit.target import Checkerboard

BOARD = Checkerboard(9, 6, 0.03)


@pytest.mark.parametrize("model_name", ["pinhole", "brown-conrady", "kannala-brandt"])
def test_coplanar_board_exact(model_name):
    cam = default_camera(model_name)
    pose = Pose.from_ypr(np.radians([25, -15, 8]), [-0.1, -0.05, 0.55])
    obj = BOARD.object_points()
    res = solve_pnp(obj, cam.project(pose.apply(obj)), cam)
    assert res.converged and res.rms_px < 1e-8
    assert res.cam_from_object.allclose(pose, atol=1e-9)


def test_general_points_and_opencv():
    cam = default_camera("brown-conrady")
    rng = np.random.default_rng(0)
    obj = rng.uniform(-0.3, 0.3, (40, 3))
    pose = Pose.from_rvec([0.2, -0.3, 0.1], [0.05, -0.02, 1.2])
    px = cam.project(pose.apply(obj)) + rng.normal(0, 0.2, (40, 2))
    res = solve_pnp(obj, px, cam)
    K, d = cam.to_opencv()
    ok, rvec, tvec = cv2.solvePnP(obj, px, K, d, flags=cv2.SOLVEPNP_ITERATIVE)
    ref = Pose.from_rvec(rvec.ravel(), tvec.ravel())
    # Both minimise the same reprojection error: the same pose to well below the noise's effect.
    assert ok and res.cam_from_object.allclose(ref, atol=1e-5)
    assert 0.1 < res.rms_px < 0.35


def test_bad_input():
    cam = default_camera("pinhole")
    obj = BOARD.object_points()
    with pytest.raises(EstimationError, match="at least 4 points"):
        solve_pnp(obj[:3], np.zeros((3, 2)), cam)
    line = np.stack([np.arange(6) * 0.1, np.zeros(6), np.zeros(6)], -1)
    with pytest.raises(EstimationError, match="collinear"):
        solve_pnp(line, np.random.default_rng(0).uniform(100, 500, (6, 2)), cam)
    rng = np.random.default_rng(1)
    with pytest.raises(EstimationError, match="general case needs at least 6"):
        solve_pnp(rng.uniform(-1, 1, (5, 3)) + [0, 0, 3], rng.uniform(100, 500, (5, 2)), cam)
