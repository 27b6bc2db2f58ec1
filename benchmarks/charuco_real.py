"""camkit's ChArUco corners on OpenCV's tutorial photos against OpenCV 5's (issue 23, item 4).

For each photo of ../shared/data/charuco_opencv_tutorial: the corner ids OpenCV 5.0's
CharucoDetector returned (reference.json) that camkit misses, the ids camkit returns beyond
them, and the distance between the two detectors' corners on the ids both return.

Run: ``python -m benchmarks.charuco_real``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from camkit.io import read_image
from camkit.target import Charuco

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "charuco_opencv_tutorial"


def main() -> None:
    ref = json.loads((DATA / "reference.json").read_text())
    board = Charuco(5, 7, 0.04, 0.02, "DICT_6X6_250")
    print("| image | OpenCV ids | camkit misses | camkit adds | median px | max px |\n|---|---|---|---|---|---|")
    for entry in ref["detections"]:
        det = board.detect(read_image(DATA / "images" / entry["file"]))
        ids = np.ravel(entry["charuco_ids"])
        mine = set(det.ids.tolist())
        both = [i for i in ids if i in mine]
        ref_px = dict(zip(ids.tolist(), np.reshape(entry["charuco_corners"], (-1, 2)), strict=True))
        d = np.array([np.hypot(*(det.corners[i] - ref_px[i])) for i in both])
        missed, added = sorted(set(ids.tolist()) - mine), sorted(mine - set(ids.tolist()))
        print(f"| {entry['file']} | {len(ids)} | {missed} | {added} | {np.median(d):.3f} | {d.max():.3f} |")


if __name__ == "__main__":
    main()
