"""Resampling on a 4000x3000 uint8 RGB image vs OpenCV and Pillow (both cores)."""

from __future__ import annotations

import cv2
import numpy as np
from PIL import Image

from benchmarks.harness import Case
from camkit.lens import BrownConrady
from camkit.resample import remap, resize, undistort_map, warp_perspective


def cases() -> list[Case]:
    rng = np.random.default_rng(0)
    H, W = 3000, 4000
    # A smooth, textured image (random noise would defeat every cache equally).
    img = cv2.GaussianBlur(rng.integers(0, 256, (H, W, 3), dtype=np.uint8), (0, 0), 2.0)
    pil = Image.fromarray(img)
    cam = BrownConrady(fx=3000.0, fy=3010.0, cx=2001.3, cy=1498.2, width=W, height=H,
                       k1=-0.2, k2=0.08, k3=-0.01, p1=1e-3, p2=-5e-4)
    mp = undistort_map(cam)  # full-resolution undistortion map, float32 (H, W, 2)
    mx = np.ascontiguousarray(mp[..., 0])
    my = np.ascontiguousarray(mp[..., 1])
    m1, m2 = cv2.convertMaps(mx, my, cv2.CV_16SC2)
    Hm = np.array([[0.98, 0.03, 25.0], [-0.02, 0.99, 12.0], [4e-6, 3e-6, 1.0]])
    return [
        Case("remap bilinear, undistortion map", "4000x3000 RGB u8", lambda: remap(img, mp),
             "cv2.remap INTER_LINEAR (float32 maps)", lambda: cv2.remap(img, mx, my, cv2.INTER_LINEAR),
             target=1.0),
        Case("remap bilinear, undistortion map (stretch)", "4000x3000 RGB u8", lambda: remap(img, mp),
             "cv2.remap INTER_LINEAR (CV_16SC2 fixed-point maps)",
             lambda: cv2.remap(img, m1, m2, cv2.INTER_LINEAR), target=1.0),
        Case("remap bicubic, undistortion map", "4000x3000 RGB u8",
             lambda: remap(img, mp, interpolation="bicubic"),
             "cv2.remap INTER_CUBIC (float32 maps)", lambda: cv2.remap(img, mx, my, cv2.INTER_CUBIC),
             target=1.0),
        # The halving takes ~8 ms: 25 pairs (0.3 s) instead of 7 (0.1 s, where one slow spell
        # on the shared machine moved the ratio from 1.6 to 2.6 between runs).
        Case("resize to half, antialiased bicubic", "4000x3000 -> 2000x1500",
             lambda: resize(img, width=2000, height=1500),
             "cv2.resize INTER_AREA", lambda: cv2.resize(img, (2000, 1500), interpolation=cv2.INTER_AREA),
             target=2.0, repeats=25),
        Case("resize to half, antialiased bicubic", "4000x3000 -> 2000x1500",
             lambda: resize(img, width=2000, height=1500),
             "Pillow Image.resize BICUBIC", lambda: pil.resize((2000, 1500), Image.BICUBIC), target=0.1),
        Case("resize x1.5, bicubic", "4000x3000 -> 6000x4500", lambda: resize(img, width=6000, height=4500),
             "cv2.resize INTER_CUBIC", lambda: cv2.resize(img, (6000, 4500), interpolation=cv2.INTER_CUBIC),
             target=1.0, repeats=15),
        Case("warp_perspective bilinear", "4000x3000 RGB u8",
             lambda: warp_perspective(img, Hm, width=W, height=H),
             "cv2.warpPerspective INTER_LINEAR", lambda: cv2.warpPerspective(img, Hm, (W, H)), target=1.0),
    ]
