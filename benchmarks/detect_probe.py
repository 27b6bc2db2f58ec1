"""Checkerboard detection on stress views altered in ways the corpus does not draw (issue 21,
item 2): a check of the rule "never a wrong label" on conditions the detector was not tuned on.

Each view of :func:`camkit.render.stress.stress_view` (its final 8-bit image) is altered six
ways, each drawn from ``numpy.random.default_rng([seed, 99, k])``:

- ``glare``: a specular highlight, a Gaussian spot of 0.3-1.5 times white and 0.5-3 squares
  across, centred near a corner of the board, clipped at white;
- ``bayer_ca``: lateral chromatic aberration (red and blue scaled about the image's centre by
  0.3-2.5 px at the corners of the frame, against green), then a Bayer RGGB mosaic and
  camkit's demosaicing (bilinear or Menon), as a camera's raw pipeline;
- ``screen``: the board shown on a screen: a grid of dark gaps between pixels of 2.2-5 px at a
  random angle (15-50 % dark: moire), and an emissive black lifted to 5-25 % grey;
- ``motion``: motion blur of 8-20 px along a random direction (the corpus's own stops at 8);
- ``noise``: added white noise of 5-12 % of the range (the corpus's stops at 3 %);
- ``gamma``: a tone curve, gamma 0.45 or 2.2.

A returned corner more than 1 px from the true corner of its label (under the labellings the
view allows) is *wrong*, as :mod:`benchmarks.detect_corpus` scores. The truth is the view's:
glare, screen, noise and gamma move no corner; the chromatic aberration moves red and blue
against green by up to its size.

Run: ``python -m benchmarks.detect_probe [--views N] [--start S] [--max-mp M] [--alter NAME]``
(200 views at up to 2 MP: about 15 minutes on one core).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np
from scipy import ndimage

from benchmarks.detect_corpus import eligible, score
from camkit.render.stress import StressView, stress_view
from camkit.sensor.cfa import mosaic
from camkit.sensor.demosaic import demosaic
from camkit.target import detect_corners


def _rgb(image: np.ndarray) -> np.ndarray:
    return np.repeat(image[:, :, None], 3, axis=2) if image.ndim == 2 else image


def _u8(image: np.ndarray) -> np.ndarray:
    return np.clip(np.round(image), 0, 255).astype(np.uint8)


def glare(view: StressView, rng: np.random.Generator) -> np.ndarray:
    img = view.image.astype(np.float64)
    seen = view.corners_px[np.isfinite(view.corners_px).all(axis=1)]
    centre = seen[rng.integers(len(seen))] + rng.normal(0.0, 0.5 * view.square_px, 2)
    H, W = img.shape[:2]
    yy, xx = np.mgrid[0:H, 0:W]
    width = rng.uniform(0.5, 3.0) * view.square_px
    spot = rng.uniform(0.3, 1.5) * 255 * np.exp(-((xx - centre[0]) ** 2 + (yy - centre[1]) ** 2) / (2 * width ** 2))
    return _u8(img + (spot[:, :, None] if img.ndim == 3 else spot))


def bayer_ca(view: StressView, rng: np.random.Generator) -> np.ndarray:
    img = _rgb(view.image).astype(np.float64)
    H, W = img.shape[:2]
    shift = rng.uniform(0.3, 2.5)  # px at the frame's corners
    e = shift / np.hypot(W / 2, H / 2)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    cx, cy = (W - 1) / 2, (H - 1) / 2
    out = img.copy()
    for channel, scale in ((0, 1 + e), (2, 1 - e)):
        out[:, :, channel] = ndimage.map_coordinates(img[:, :, channel], [cy + (yy - cy) / scale,
                                                                          cx + (xx - cx) / scale],
                                                     order=1, mode="nearest")
    method = str(rng.choice(["bilinear", "menon"]))
    return demosaic(mosaic(_u8(out), "RGGB"), "RGGB", method=method)


def screen(view: StressView, rng: np.random.Generator) -> np.ndarray:
    img = view.image.astype(np.float64)
    H, W = img.shape[:2]
    period, angle, dark = rng.uniform(2.2, 5.0), rng.uniform(0.0, np.pi), rng.uniform(0.15, 0.5)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    u = xx * np.cos(angle) + yy * np.sin(angle)
    v = -xx * np.sin(angle) + yy * np.cos(angle)
    grid = ((1 - dark * (0.5 + 0.5 * np.cos(2 * np.pi * u / period)))
            * (1 - dark * (0.5 + 0.5 * np.cos(2 * np.pi * v / period))))
    lift = rng.uniform(0.05, 0.25)
    return _u8(lift * 255 + (1 - lift) * img * (grid[:, :, None] if img.ndim == 3 else grid))


def motion(view: StressView, rng: np.random.Generator) -> np.ndarray:
    length, angle = rng.uniform(8.0, 20.0), rng.uniform(0.0, np.pi)
    n = int(np.ceil(length)) | 1
    kernel = np.zeros((n, n))
    c = n // 2
    for t in np.linspace(-length / 2, length / 2, 4 * n):
        kernel[round(c + t * np.sin(angle)), round(c + t * np.cos(angle))] += 1
    kernel /= kernel.sum()
    img = view.image.astype(np.float64)
    if img.ndim == 3:
        return _u8(np.stack([ndimage.convolve(img[:, :, i], kernel, mode="nearest") for i in range(3)], axis=2))
    return _u8(ndimage.convolve(img, kernel, mode="nearest"))


def noise(view: StressView, rng: np.random.Generator) -> np.ndarray:
    return _u8(view.image + rng.normal(0.0, rng.uniform(0.05, 0.12) * 255, view.image.shape))


def gamma(view: StressView, rng: np.random.Generator) -> np.ndarray:
    return _u8(255 * (view.image / 255.0) ** float(rng.choice([0.45, 2.2])))


ALTERATIONS: dict[str, Callable[[StressView, np.random.Generator], np.ndarray]] = {
    "glare": glare, "bayer_ca": bayer_ca, "screen": screen, "motion": motion, "noise": noise, "gamma": gamma}


def alter(view: StressView, seed: int, name: str) -> np.ndarray:
    """The view's image altered by ``name`` (one of :data:`ALTERATIONS`), drawn from the seed."""
    return ALTERATIONS[name](view, np.random.default_rng([seed, 99, list(ALTERATIONS).index(name)]))


def run(views: int, start: int, max_mp: float, names: list[str]) -> dict:
    out = {name: dict(views=0, boards=0, eligible=0, found_eligible=0, wrong=[], err=[]) for name in names}
    for seed in range(start, start + views):
        v = stress_view(seed, megapixels=(0.1, max_mp))
        el = eligible(v)
        for name in names:
            r = out[name]
            r["views"] += 1
            r["eligible"] += el
            det = detect_corners(alter(v, seed, name), v.board)
            if not det.found:
                continue
            r["boards"] += 1
            r["found_eligible"] += el
            wrong, d = score(v, det.corners)
            if wrong:
                r["wrong"].append((seed, wrong))
            r["err"].extend(d[d <= 1.0].tolist())
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--views", type=int, default=200)
    p.add_argument("--start", type=int, default=3000)
    p.add_argument("--max-mp", type=float, default=2.0)
    p.add_argument("--alter", choices=list(ALTERATIONS), action="append")
    a = p.parse_args()
    res = run(a.views, a.start, a.max_mp, a.alter or list(ALTERATIONS))
    print(f"seeds {a.start}-{a.start + a.views - 1}, up to {a.max_mp:g} MP")
    print("| alteration | boards returned | eligible found | views with a wrong corner | median error | 95th |")
    print("|---|---|---|---|---|---|")
    for name, r in res.items():
        err = np.asarray(r["err"]) if r["err"] else np.full(1, np.nan)
        wrong = ", ".join(f"{s} ({n})" for s, n in r["wrong"]) or "none"
        print(f"| {name} | {r['boards']} of {r['views']} | {r['found_eligible']} of {r['eligible']} | "
              f"{len(r['wrong'])}: {wrong} | {np.median(err):.4f} px | {np.percentile(err, 95):.4f} px |")


if __name__ == "__main__":
    main()
