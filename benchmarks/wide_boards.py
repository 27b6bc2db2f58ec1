"""Coded targets drawn wider than the corpora draw them: a probe of generalisation (issue 23).

``benchmarks.charuco_corpus`` and ``benchmarks.aprilgrid_corpus`` draw the boards the detectors
were developed on: ChArUco boards of 5-12 x 4-9 squares, markers 55-80 % of the square, a
4x4, 5x5 or 6x6 dictionary of 250 codes; AprilGrids of 3-8 x 3-7 tags, spacing 0.2-0.4,
tag36h11 or tag25h9. Users print others. Here, with the same cameras, poses, blur, noise, JPEG
and scores (:func:`benchmarks.charuco_corpus.score`), the draw is wider:

- ``--target charuco``: 3-20 x 3-15 squares, markers 40-90 % of the square (OpenCV warns
  that markers over about 81-85 % of the square, by dictionary, leave a margin under 0.7 of
  a cell: "unstable"), any of DICT_7X7_1000, DICT_ARUCO_ORIGINAL, DICT_APRILTAG_36h11,
  DICT_4X4_1000, DICT_5X5_1000, DICT_6X6_1000, DICT_APRILTAG_16h5, DICT_ARUCO_MIP_36h12,
  DICT_APRILTAG_25h9 and DICT_4X4_50 (a board needing more markers than its dictionary
  has is drawn again), legacy in three of ten;
- ``--target aprilgrid``: 2-12 x 2-10 tags, spacing 0.1-0.5, any of Kalibr's three families
  (a grid needing more tags than its family has is drawn again).

Seeds are ``(view, 77)`` and ``(view, 78)``: no view is a corpus view. Findings and figures:
benchmarks/notes.md (fiftieth session).

Run: ``python -m benchmarks.wide_boards --target charuco|aprilgrid [--views 300] [--start 0]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from benchmarks import aprilgrid_corpus
from benchmarks.charuco_corpus import eligible, opencv_corners, place_and_render, score
from camkit.errors import ParameterError
from camkit.target import APRILTAG_FAMILIES, AprilGrid, Charuco
from camkit.target.aruco import get_dictionary

DICTS = ("DICT_7X7_1000", "DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_36h11", "DICT_4X4_1000", "DICT_5X5_1000",
         "DICT_6X6_1000", "DICT_APRILTAG_16h5", "DICT_ARUCO_MIP_36h12", "DICT_APRILTAG_25h9", "DICT_4X4_50")


def charuco_view(seed: int):
    """(board, camera, lens kind, pose, uint8 image, truth, noisy) of ChArUco view ``seed``
    (:func:`benchmarks.charuco_corpus.place_and_render`), None where no pose fits."""
    rng = np.random.default_rng((seed, 77))
    while True:
        name = str(rng.choice(DICTS))
        nx, ny = int(rng.integers(3, 21)), int(rng.integers(3, 16))
        if (nx * ny) // 2 <= len(get_dictionary(name).codes):
            break
    board = Charuco(nx, ny, 0.03, 0.03 * rng.uniform(0.4, 0.9), name, legacy=bool(rng.random() < 0.3))
    return place_and_render(rng, board, (15, 120), False)


def aprilgrid_view(seed: int):
    """As :func:`charuco_view`, an AprilGrid (tags of 20-150 px, as the corpus's)."""
    rng = np.random.default_rng((seed, 78))
    while True:
        family = str(rng.choice(list(APRILTAG_FAMILIES)))
        tx, ty = int(rng.integers(2, 13)), int(rng.integers(2, 11))
        try:
            grid = AprilGrid(tx, ty, 0.03, float(rng.uniform(0.1, 0.5)), family)
            break
        except ParameterError:  # more tags than the family has
            pass
    return place_and_render(rng, grid, (20, 150), True, grid.tag_size)


def run(target: str, views: int, start: int = 0) -> dict:
    if target == "charuco":
        return score(views, start, charuco_view, eligible, opencv_corners)
    return score(views, start, aprilgrid_view, aprilgrid_corpus.eligible, aprilgrid_corpus.opencv_corners)


def main() -> None:
    p = argparse.ArgumentParser(prog="python -m benchmarks.wide_boards")
    p.add_argument("--target", choices=("charuco", "aprilgrid"), default="charuco")
    p.add_argument("--views", type=int, default=300)
    p.add_argument("--start", type=int, default=0)
    a = p.parse_args()
    t0 = time.perf_counter()
    for k, v in run(a.target, a.views, a.start).items():
        print(f"{k}: {v:.4g}" if isinstance(v, float) else f"{k}: {v}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
