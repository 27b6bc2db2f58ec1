"""ChArUco detection on OpenCV's tutorial photos altered (issue 23, items 2 and 4): the
alterations of :mod:`benchmarks.detect_altered` (turned by quarters and by 23 and 137 degrees,
shrunk, enlarged, JPEG 25 and 10, dark, flat, blurred, smeared, ramp-lit, in a shadow, under a
gamma curve, vignetted, mosaicked, salted) applied to ../shared/data/charuco_opencv_tutorial, OpenCV 5's
reference corners following each map. Per alteration: the reference ids camkit returns, the
ids OpenCV's CharucoDetector still returns on the altered photos and how many of those camkit
misses, camkit's corners more than a pixel and a tenth of a square from the reference
(a wrong id), and the largest distance.

Run: ``python -m benchmarks.charuco_altered`` (about two minutes).
"""

from __future__ import annotations

import json

import numpy as np

from benchmarks.charuco_real import DATA
from benchmarks.detect_altered import ALTERATIONS
from camkit.io import read_image
from camkit.target import Charuco


def main() -> int:
    import cv2

    if not DATA.is_dir():
        print(f"{DATA} is absent")
        return 1
    ref = json.loads((DATA / "reference.json").read_text())
    board = Charuco(5, 7, 0.04, 0.02, "DICT_6X6_250")
    detector = cv2.aruco.CharucoDetector(cv2.aruco.CharucoBoard(
        (5, 7), 0.04, 0.02, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)))
    photos = [(read_image(DATA / "images" / e["file"]), np.ravel(e["charuco_ids"]).astype(int),
               np.reshape(e["charuco_corners"], (-1, 2)).astype(np.float64)) for e in ref["detections"]]
    print("| alteration | reference ids | camkit | OpenCV on the altered photos | of those camkit misses | "
          "wrong | largest distance px |\n|---|---|---|---|---|---|---|")
    for name, alter in ALTERATIONS.items():
        n_ref = n_mine = n_cv = missed = wrong = 0
        worst = 0.0
        for photo, ids, pts in photos:
            img, px = alter(photo, pts)
            det = board.detect(img)
            mine = {int(i): det.corners[int(i)] for i in det.ids}
            grey = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY) if img.ndim == 3 else img
            _, cv_ids, _, _ = detector.detectBoard(grey)
            theirs = set(np.ravel(cv_ids).astype(int).tolist()) & set(ids.tolist()) if cv_ids is not None else set()
            square = float(np.median(np.hypot(*np.diff(px, axis=0).T)))
            for i, p in zip(ids.tolist(), px, strict=True):
                n_ref += 1
                if i in mine:
                    n_mine += 1
                    d = float(np.hypot(*(mine[i] - p)))
                    worst = max(worst, d)
                    wrong += d > 1.0 and d > 0.1 * square
            n_cv += len(theirs)
            missed += len(theirs - set(mine))
        print(f"| {name} | {n_ref} | {n_mine} | {n_cv} | {missed} | {wrong} | {worst:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
