"""Write camkit/target/data/aruco_dictionaries.json: the codes of OpenCV's predefined ArUco and
AprilTag dictionaries, as data (facts carried over with their source named).

Run from the checkout with OpenCV installed (a test extra): ``python scripts/make_aruco_dictionaries.py``.
camkit never imports OpenCV; tests/target/test_aruco.py checks every code against
``cv2.aruco.getPredefinedDictionary`` again.

Each family is stored once, at its largest size (a smaller predefined dictionary of a family is
its first codes: DICT_5X5_50 is the first 50 of DICT_5X5_1000, checked here), as one hex string
per code: the marker's n x n bits read row by row, 1 = white, most significant bit first.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

OUT = Path(__file__).resolve().parents[1] / "camkit" / "target" / "data" / "aruco_dictionaries.json"
FAMILIES = {  # family -> its largest predefined dictionary
    "4X4": "DICT_4X4_1000", "5X5": "DICT_5X5_1000", "6X6": "DICT_6X6_1000", "7X7": "DICT_7X7_1000",
    "ARUCO_ORIGINAL": "DICT_ARUCO_ORIGINAL", "APRILTAG_16h5": "DICT_APRILTAG_16h5",
    "APRILTAG_25h9": "DICT_APRILTAG_25h9", "APRILTAG_36h10": "DICT_APRILTAG_36h10",
    "APRILTAG_36h11": "DICT_APRILTAG_36h11", "ARUCO_MIP_36h12": "DICT_ARUCO_MIP_36h12",
}
NAMES = {  # predefined name -> family
    **{f"DICT_{s}_{n}": s for s in ("4X4", "5X5", "6X6", "7X7") for n in (50, 100, 250, 1000)},
    "DICT_ARUCO_ORIGINAL": "ARUCO_ORIGINAL", "DICT_APRILTAG_16h5": "APRILTAG_16h5",
    "DICT_APRILTAG_25h9": "APRILTAG_25h9", "DICT_APRILTAG_36h10": "APRILTAG_36h10",
    "DICT_APRILTAG_36h11": "APRILTAG_36h11", "DICT_ARUCO_MIP_36h12": "ARUCO_MIP_36h12",
}


def bits(d) -> np.ndarray:
    return np.array([cv2.aruco.Dictionary.getBitsFromByteList(d.bytesList[i:i + 1], d.markerSize)
                     for i in range(d.bytesList.shape[0])])


def main() -> None:
    families = {}
    for fam, name in FAMILIES.items():
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
        b = bits(d)
        families[fam] = {"marker_size": int(d.markerSize),
                         "codes": [format(int("".join(map(str, row.ravel())), 2), "x") for row in b]}
    names = {}
    for name, fam in NAMES.items():
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
        b = bits(d)
        full = bits(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, FAMILIES[fam])))
        assert (full[:len(b)] == b).all(), name
        names[name] = {"family": fam, "size": len(b), "max_correction_bits": int(d.maxCorrectionBits)}
    doc = {"source": f"OpenCV {cv2.__version__}, cv2.aruco.getPredefinedDictionary (opencv/opencv, "
                     "modules/objdetect/src/aruco/predefined_dictionaries.hpp; the AprilTag families from "
                     "AprilRobotics/apriltag); bits row by row, 1 = white, most significant first",
           "dictionaries": names, "families": families}
    OUT.write_text(json.dumps(doc, separators=(",", ":")) + "\n")
    print(f"wrote {OUT} ({OUT.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
