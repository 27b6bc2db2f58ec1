"""camkit's ChArUco corners on OpenCV's tutorial photos against OpenCV 5's (issue 23, item 4).

For each photo of ../shared/data/charuco_opencv_tutorial: the corner ids OpenCV 5.0's
CharucoDetector returned (reference.json) that camkit misses, the ids camkit returns beyond
them, and the distance between the two detectors' corners on the ids both return. Then, as a
measure of which is the more precise where no truth is known: the four img_0* views calibrated
(camkit's Brown-Conrady fit, default parameters) once from each detector's corners on the
same ids; the lower RMS reprojection error is the more self-consistent set of corners. And
where the two disagree most in each photo, how far the image is from point-symmetric about
each detector's corner (a true X-junction is a centre of point symmetry), and, in the img_0*
views, where a calibration without that corner puts it: the four views calibrated from one
detector's corners less that one, the corner reprojected, and its distance to each
detector's corner (once from camkit's corners, once from OpenCV's): the detector nearer the
reprojection agrees better with the rest of the views.

Run: ``python -m benchmarks.charuco_real``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from benchmarks.detect_real import point_asymmetry
from camkit.calib.calibrate import calibrate
from camkit.io import read_image
from camkit.target import Charuco
from camkit.target.checkerboard import _to_grey

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "charuco_opencv_tutorial"


def main() -> None:
    ref = json.loads((DATA / "reference.json").read_text())
    board = Charuco(5, 7, 0.04, 0.02, "DICT_6X6_250")
    print("| image | OpenCV ids | camkit misses | camkit adds | median px | max px | point asymmetry at the max, "
          "camkit / OpenCV |\n|---|---|---|---|---|---|---|")
    objs, mine_px, theirs_px, worst = [], [], [], []
    for entry in ref["detections"]:
        img = read_image(DATA / "images" / entry["file"])
        det = board.detect(img)
        ids = np.ravel(entry["charuco_ids"])
        mine = set(det.ids.tolist())
        both = [i for i in ids if i in mine]
        ref_px = dict(zip(ids.tolist(), np.reshape(entry["charuco_corners"], (-1, 2)), strict=True))
        d = np.array([np.hypot(*(det.corners[i] - ref_px[i])) for i in both])
        missed, added = sorted(set(ids.tolist()) - mine), sorted(mine - set(ids.tolist()))
        # Where the two disagree most, which corner is the junction's centre of symmetry (circle of 3 px).
        k = both[int(np.argmax(d))]
        grey = np.ascontiguousarray(_to_grey(img), dtype=np.float64)
        a_mine, a_theirs = (float(point_asymmetry(grey, p, 3.0)[0]) for p in (det.corners[k], ref_px[k]))
        print(f"| {entry['file']} | {len(ids)} | {missed} | {added} | {np.median(d):.3f} | {d.max():.3f} "
              f"| {a_mine:.3f} / {a_theirs:.3f} |")
        if entry["file"].startswith("img_0") and not missed:
            objs.append(board.object_points()[ids])
            mine_px.append(det.corners[ids])
            theirs_px.append(np.reshape(entry["charuco_corners"], (-1, 2)))
            worst.append((entry["file"], len(objs) - 1, int(np.flatnonzero(ids == k)[0]), float(d.max())))
    rms = [calibrate(objs, px, width=640, height=480).rms_px for px in (mine_px, theirs_px)]
    print(f"\nCalibration from the {len(objs)} img_0* views on the same ids: RMS reprojection error "
          f"{rms[0]:.4f} px from camkit's corners, {rms[1]:.4f} px from OpenCV 5's.")
    print("\nWhere the detectors disagree most in each view, the corner as the other corners place it (the four "
          "views calibrated without it, from each detector's corners in turn), its distance to each detector's "
          "corner:\n\n| image | disagreement px | from camkit's corners: to camkit / to OpenCV px | "
          "from OpenCV's corners: to camkit / to OpenCV px |\n|---|---|---|---|")
    for file, v, k, gap in worst:
        cells = []
        for corners in (mine_px, theirs_px):
            px = [c.copy() for c in corners]
            px[v][k] = np.nan
            res = calibrate(objs, px, width=640, height=480)
            at = res.model.project(res.poses[v].apply(objs[v][k:k + 1]))[0]
            cells.append(f"{np.hypot(*(at - mine_px[v][k])):.3f} / {np.hypot(*(at - theirs_px[v][k])):.3f}")
        print(f"| {file} | {gap:.3f} | {cells[0]} | {cells[1]} |")


if __name__ == "__main__":
    main()
