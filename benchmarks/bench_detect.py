"""Checkerboard detection against OpenCV's two detectors (issue 21, item 6).

Images, the same for both sides in the same run:

- 640x480: the Bouguet set's real photos (12x13 inner corners, 30 px squares).
- 2 MP and 12 MP: three of those photos enlarged by cv2.resize (bicubic) to 1632x1224 and
  4000x3000, so the squares grow with the image (76 px and 190 px): camkit then looks at a
  coarser level of its pyramid and refines at full resolution.
- 5.5 MP: the plantcv_wide set (19x13, strong barrel distortion).
- No board: noise at 640x480 and skimage's astronaut enlarged to 12 MP (a photo without a
  board: textures, edges, no lattice).

cv2.findChessboardCornersSB runs with its default flags; cv2.findChessboardCorners with its
default flags (adaptive threshold, normalise), as a user would call them.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from benchmarks.harness import Case, median_time
from camkit.io import read_image
from camkit.target import Checkerboard, detect_corners

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
BOUGUET = Checkerboard(12, 13, 0.030)


def _bouguet(ks) -> list[np.ndarray]:
    return [cv2.imread(str(DATA / "bouguet_calib_example" / f"Image{k}.tif"), cv2.IMREAD_UNCHANGED) for k in ks]


def _enlarge(images: list[np.ndarray], size: tuple[int, int]) -> list[np.ndarray]:
    return [cv2.resize(im, size, interpolation=cv2.INTER_CUBIC) for im in images]


def _both(images, board, label, size, target_sb: float | None = 1.0, classic=False, repeats=5) -> list[Case]:
    pattern = (board.inner_cols, board.inner_rows)
    cases = [Case(f"detect a {pattern[0]}x{pattern[1]} board, {label}", size,
                  lambda: [detect_corners(im, board) for im in images],
                  "cv2.findChessboardCornersSB", lambda: [cv2.findChessboardCornersSB(im, pattern) for im in images],
                  target=target_sb, repeats=repeats, warmup=1)]
    if classic:
        cases.append(Case(f"detect a {pattern[0]}x{pattern[1]} board, {label}", size,
                          lambda: [detect_corners(im, board) for im in images],
                          "cv2.findChessboardCorners",
                          lambda: [cv2.findChessboardCorners(im, pattern) for im in images],
                          target=2.0, repeats=repeats, warmup=1))
    return cases


def cases() -> list[Case]:
    if not (DATA / "bouguet_calib_example").is_dir():
        print(f"  (skipping detection benchmarks: {DATA} is absent)")
        return []
    small = _bouguet(range(1, 21))
    three = small[:3]
    out = _both(small, BOUGUET, "20 real photos", "640x480", classic=True, repeats=3)
    out += _both(_enlarge(three, (1632, 1224)), BOUGUET, "3 photos enlarged", "2 MP (1632x1224)")
    out += _both(_enlarge(three, (4000, 3000)), BOUGUET, "3 photos enlarged", "12 MP (4000x3000)", repeats=3)
    plant = DATA / "real_boards" / "plantcv_wide"
    if plant.is_dir():
        ref = json.loads((plant / "reference.json").read_text())
        imgs = [read_image(plant / "images" / it["image"]) for it in ref["images"][1:4]]
        imgs = [np.ascontiguousarray(im[..., :3]) for im in imgs]  # RGBA files; cv2 takes 3 channels
        # Not one of the sizes: shown without a target.
        out += _both(imgs, Checkerboard(19, 13, 0.03), "3 real wide-angle photos", "5.5 MP (2880x1920)",
                     target_sb=None, repeats=3)
    return out


def extra_tables() -> str:
    import skimage.data

    noise = np.random.default_rng(0).integers(0, 256, (480, 640), dtype=np.uint8)
    photo = cv2.resize(skimage.data.astronaut(), (4000, 3000), interpolation=cv2.INTER_CUBIC)
    rows = []
    for name, img, target in (("640x480 noise", noise, 0.05), ("12 MP photo (astronaut, enlarged)", photo, 0.4)):
        ours = median_time(lambda img=img: detect_corners(img, BOUGUET), repeats=5, warmup=1)
        sb = median_time(lambda img=img: cv2.findChessboardCornersSB(img, (12, 13)), repeats=3, warmup=1)
        classic = median_time(lambda img=img: cv2.findChessboardCorners(img, (12, 13)), repeats=3, warmup=1)
        rows.append(f"| {name} | {ours * 1e3:.1f} ms | {sb * 1e3:.1f} ms | {classic * 1e3:.1f} ms | "
                    f"<= {target * 1e3:g} ms: {'met' if ours <= target else 'MISSED'} |")
    return ("| an image with no board (12x13 asked) | camkit | cv2 SB | cv2 classic | target |\n"
            "|---|---|---|---|---|\n" + "\n".join(rows) + "\n")
