"""Calibration on the real Bouguet set: the solve vs OpenCV (detection: bench_detect)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from benchmarks.harness import Case
from camkit.calib import DEFAULT_FIX, calibrate
from camkit.target import Checkerboard, detect_corners

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bouguet_calib_example"
BOARD = Checkerboard(12, 13, 0.030)


def _images() -> list[np.ndarray]:
    return [cv2.imread(str(DATA / f"Image{k}.tif"), cv2.IMREAD_UNCHANGED) for k in range(1, 21)]


def cases() -> list[Case]:
    if not DATA.is_dir():
        print(f"  (skipping calibration benchmarks: {DATA} is absent)")
        return []
    images = _images()
    corners = [detect_corners(im, BOARD).corners for im in images]
    obj = BOARD.object_points()
    obj_cv = [obj[np.isfinite(c).all(1)].astype(np.float32) for c in corners]
    img_cv = [c[np.isfinite(c).all(1)].astype(np.float32) for c in corners]
    flags = cv2.CALIB_FIX_K3

    return [
        Case("calibrate from the detected corners (k1 k2 p1 p2)", "20 views, ~3100 corners",
             lambda: calibrate([obj] * 20, corners, width=640, height=480, fix=(*DEFAULT_FIX, "k3")),
             "cv2.calibrateCamera (CALIB_FIX_K3)",
             lambda: cv2.calibrateCamera(obj_cv, img_cv, (640, 480), None, None, flags=flags),
             target=1.0, repeats=5, warmup=1),
    ]
