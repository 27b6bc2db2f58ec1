"""Result objects print short: a notebook cell that ends with a calibration shows its summary,
not every view's points (the dataclass repr of a 20-view result was half a megabyte)."""

from __future__ import annotations

import numpy as np

from camkit._repr import short
from camkit.calib import calibrate
from camkit.render import default_camera, plan_views
from camkit.target import Checkerboard, Detection

BOARD = Checkerboard(9, 6, 0.03)
OBJ = BOARD.object_points()
CAM = default_camera("brown-conrady")


def _result(n_views):
    rng = np.random.default_rng(3)
    poses = plan_views(CAM, BOARD, n_views, rng)
    imgs = [CAM.project(p.apply(OBJ)) + rng.normal(0, 0.1, (len(OBJ), 2)) for p in poses]
    return calibrate([OBJ] * n_views, imgs, width=1280, height=960)


def test_a_calibration_result_prints_its_summary_whatever_the_number_of_views():
    small, large = _result(6), _result(30)
    r6, r30 = repr(small), repr(large)
    # The old repr grew with every corner: 30 views of 54 corners printed ~110 000 characters.
    assert len(r30) < 1500, len(r30)
    assert abs(len(r30) - len(r6)) < 150, (len(r6), len(r30))   # view_indices: 6 or 30 numbers
    # What a reader looks for is there, as values: the model, the RMS, the sigmas, the message.
    assert r30.startswith("CalibrationResult(model=BrownConrady(fx=")
    assert f"rms_px={large.rms_px:.6g}" in r30
    assert f"'fx': {large.stddev['fx']:.6g}" in r30
    assert "free_params=('fx', 'fy', 'cx', 'cy'" in r30
    assert f"message={large.message!r}" in r30
    # The bulk is named with its size.
    assert "poses=<list of 30 Pose>" in r30 and "covariance=<array (9, 9) float64>" in r30
    assert "residuals=<list of 30 ndarray>" in r30


def test_a_detection_prints_how_many_points_it_found():
    corners = np.full((54, 2), np.nan)
    corners[:40] = np.arange(80.0).reshape(40, 2)
    det = Detection(True, corners, np.full(54, 0.02), 4, "found 40 of 54 corners")
    text = repr(det)
    assert text == ("Detection(found=True, corners=<array (54, 2) float64>, sigma_px=<array (54,) float64>, "
                    "window_px=4, message='found 40 of 54 corners', board_seen=None, n_found=40)")


def test_small_values_are_shown_whole_and_large_ones_by_their_size():
    assert short(np.array([[1.0, 2.0], [3.0, 4.5]])) == "[[1. , 2. ], [3. , 4.5]]"
    assert short(np.zeros((7,))) == "<array (7,) float64>"
    assert short([1, 2, 3, 4, 5, 6, 7]) == "[1, 2, 3, 4, 5, 6, 7]"       # numbers that fit a line
    assert short([np.zeros(9)] * 5) == "<list of 5 ndarray>"
    assert short((np.zeros(2),)) == "([0., 0.],)"
    assert short({"a": 1.0, "b": np.zeros(100)}) == "<dict of 2>"
    assert short(0.1234567891) == "0.123457"
