"""Checkerboard detection on the real sets altered (issue 21, items 1, 2 and 4): photos the
detector has not seen in that form.

Every photo of ``../shared/data/real_boards`` whose board OpenCV found (``reference.json``) is
turned a quarter, shrunk to a half or a third (box filter), enlarged 2x or 3x (bicubic),
compressed as JPEG at quality 25, darkened to a fifth with noise, flattened to a quarter of
its contrast with noise, blurred (Gaussian, 2 px), lit by a ramp from 0.15 to 1 across its
width, or put half in a shadow (the right half dimmed to a fifth past a soft edge); and
(added in the forty-ninth session, as photos no step was tuned on) turned 23 and 137 degrees
(bilinear, on a canvas that holds the whole photo), smeared by a motion of 7 px at 30
degrees, put through a gamma of 2.2 or 0.45, vignetted to a fifth at the corners with noise,
mosaicked (RGGB) and demosaicked bilinearly, sprinkled with 1 % salt-and-pepper pixels,
resized by 1.5 or 0.7, or compressed as JPEG at quality 10. The reference corners follow the
same map. On each altered photo:

- OpenCV: whether ``findChessboardCornersSB`` (exhaustive, accuracy) or, up to 4 MP, the classic
  ``findChessboardCorners`` still finds the board;
- camkit: ``detect_corners``; a board OpenCV finds and camkit does not is *missed*; a returned
  board with a corner nearer another reference corner than a third of the way to it (the
  board's symmetries allowed, as :mod:`benchmarks.detect_real` scores) is *wrong*.

Run: ``python -m benchmarks.detect_altered [--set NAME] [--alter NAME]`` (all sets and
alterations by default: about 35 minutes on two cores).
"""

from __future__ import annotations

import argparse
import io
import json
import time
from collections.abc import Callable

import numpy as np

from benchmarks.detect_real import DATA, compare
from camkit.io import read_image
from camkit.target import Checkerboard, detect_corners

Alteration = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def _u8(a: np.ndarray) -> np.ndarray:
    return np.clip(np.round(a), 0, 255).astype(np.uint8)


def _turn(img: np.ndarray, pts: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """np.rot90 by k (counter-clockwise): (x, y) -> (y, W - 1 - x) each quarter."""
    x, y = pts[:, 0], pts[:, 1]
    h, w = img.shape[:2]
    for _ in range(k % 4):
        x, y = y, w - 1 - x
        h, w = w, h
    return np.ascontiguousarray(np.rot90(img, k)), np.stack([x, y], axis=-1)


def _resize(img: np.ndarray, pts: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
    from PIL import Image

    h, w = img.shape[:2]
    out = np.asarray(Image.fromarray(img).resize((round(w * s), round(h * s)),
                                                 Image.BICUBIC if s > 1 else Image.BOX))
    sx, sy = out.shape[1] / w, out.shape[0] / h
    return out, np.stack([(pts[:, 0] + 0.5) * sx - 0.5, (pts[:, 1] + 0.5) * sy - 0.5], axis=-1)


def _jpeg(img: np.ndarray, pts: np.ndarray, quality: int) -> tuple[np.ndarray, np.ndarray]:
    from PIL import Image

    img = img[..., :3] if img.ndim == 3 else img
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, "JPEG", quality=quality)
    buf.seek(0)
    return np.asarray(Image.open(buf)), pts


def _blur(img: np.ndarray, pts: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    from scipy.ndimage import gaussian_filter

    return _u8(gaussian_filter(img.astype(np.float64), (sigma, sigma, 0)[:img.ndim])), pts


def _noisy(img: np.ndarray, gain: float, offset: float, noise: float) -> np.ndarray:
    rng = np.random.default_rng(0)
    return _u8(offset + (img.astype(np.float64) - offset) * gain + rng.normal(0.0, noise, img.shape))


def _ramp(img: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    g = np.linspace(0.15, 1.0, img.shape[1])[None, :]
    return _u8(img.astype(np.float64) * (g[..., None] if img.ndim == 3 else g)), pts


def _shadow(img: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The right half in a shadow: dimmed to a fifth past a soft edge (a fortieth of the width)
    down the middle."""
    w = img.shape[1]
    g = (0.2 + 0.8 / (1.0 + np.exp((np.arange(w) - 0.5 * w) / (w / 40.0))))[None, :]
    return _u8(img.astype(np.float64) * (g[..., None] if img.ndim == 3 else g)), pts


def _rotate(img: np.ndarray, pts: np.ndarray, degrees: float) -> tuple[np.ndarray, np.ndarray]:
    """Turned ``degrees`` about the photo's centre (bilinear), on a canvas that holds it all."""
    from scipy.ndimage import map_coordinates

    h, w = img.shape[:2]
    a = np.deg2rad(degrees)
    c, s = np.cos(a), np.sin(a)
    W, H = int(np.ceil(abs(w * c) + abs(h * s))), int(np.ceil(abs(w * s) + abs(h * c)))
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    dx, dy = xx - (W - 1) / 2, yy - (H - 1) / 2
    sx, sy = c * dx + s * dy + (w - 1) / 2, -s * dx + c * dy + (h - 1) / 2  # the inverse turn
    f = img.astype(np.float64)
    chans = [f] if f.ndim == 2 else [f[..., k] for k in range(f.shape[2])]
    out = np.stack([map_coordinates(ch, [sy, sx], order=1, mode="constant", cval=0.0) for ch in chans], axis=-1)
    px, py = pts[:, 0] - (w - 1) / 2, pts[:, 1] - (h - 1) / 2
    return _u8(out[..., 0] if f.ndim == 2 else out), np.stack([c * px - s * py + (W - 1) / 2,
                                                               s * px + c * py + (H - 1) / 2], axis=-1)


def _motion(img: np.ndarray, pts: np.ndarray, length: float, degrees: float) -> tuple[np.ndarray, np.ndarray]:
    """A straight motion ``length`` px long at ``degrees``, centred (the corners stay put)."""
    from scipy.ndimage import convolve

    n = 2 * int(np.ceil(length / 2)) + 1
    k = np.zeros((n, n))
    a = np.deg2rad(degrees)
    for t in np.linspace(-length / 2, length / 2, 16 * n):
        k[round(n // 2 + t * np.sin(a)), round(n // 2 + t * np.cos(a))] += 1.0
    k = k[..., None] if img.ndim == 3 else k
    return _u8(convolve(img.astype(np.float64), k / k.sum(), mode="nearest")), pts


def _gamma(img: np.ndarray, pts: np.ndarray, g: float) -> tuple[np.ndarray, np.ndarray]:
    return _u8(255.0 * (img.astype(np.float64) / 255.0) ** g), pts


def _vignette(img: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Light falling to about a fifth at the corners ((1 + 1.2 r^2)^-2, r = 1 there), with
    noise of 2 levels."""
    h, w = img.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    r2 = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
    v = (1.0 + 1.2 * r2) ** -2.0
    return _noisy(img.astype(np.float64) * (v[..., None] if img.ndim == 3 else v), 1.0, 0.0, 2.0), pts


def _bayer(img: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An RGGB mosaic of the photo, demosaicked by bilinear interpolation (colour fringes at
    every edge)."""
    from scipy.ndimage import convolve

    f = (np.repeat(img[..., None], 3, axis=2) if img.ndim == 2 else img[..., :3]).astype(np.float64)
    h, w = f.shape[:2]
    has = np.zeros((h, w, 3), dtype=bool)
    has[0::2, 0::2, 0] = has[0::2, 1::2, 1] = has[1::2, 0::2, 1] = has[1::2, 1::2, 2] = True
    k = np.array([[1.0, 2.0, 1.0], [2.0, 4.0, 2.0], [1.0, 2.0, 1.0]])
    out = np.stack([convolve(np.where(has[..., c], f[..., c], 0.0), k, mode="mirror")
                    / convolve(has[..., c].astype(np.float64), k, mode="mirror") for c in range(3)], axis=-1)
    return _u8(out), pts


def _salt(img: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """1 % of the pixels set to black or white at random."""
    rng = np.random.default_rng(2)
    out = img.copy()
    hit = rng.random(img.shape[:2]) < 0.01
    v = rng.integers(0, 2, int(hit.sum())).astype(np.uint8) * 255
    out[hit] = v[:, None] if out.ndim == 3 else v
    return out, pts


ALTERATIONS: dict[str, Alteration] = {
    "as is": lambda i, p: (i, p),
    "turned 90": lambda i, p: _turn(i, p, 1),
    "turned 270": lambda i, p: _turn(i, p, 3),
    "half": lambda i, p: _resize(i, p, 0.5),
    "third": lambda i, p: _resize(i, p, 1 / 3),
    "2x": lambda i, p: _resize(i, p, 2.0),
    "3x": lambda i, p: _resize(i, p, 3.0),
    "jpeg 25": lambda i, p: _jpeg(i, p, 25),
    "dark": lambda i, p: (_noisy(i, 0.2, 0.0, 2.0), p),
    "flat": lambda i, p: (_noisy(i, 0.25, 128.0, 1.5), p),
    "blur 2": lambda i, p: _blur(i, p, 2.0),
    "ramp": _ramp,
    "shadow": _shadow,
    "turned 23": lambda i, p: _rotate(i, p, 23.0),
    "turned 137": lambda i, p: _rotate(i, p, 137.0),
    "motion 7": lambda i, p: _motion(i, p, 7.0, 30.0),
    "gamma 2.2": lambda i, p: _gamma(i, p, 2.2),
    "gamma 0.45": lambda i, p: _gamma(i, p, 0.45),
    "vignette": _vignette,
    "bayer": _bayer,
    "salt 1%": _salt,
    "1.5x": lambda i, p: _resize(i, p, 1.5),
    "0.7x": lambda i, p: _resize(i, p, 0.7),
    "jpeg 10": lambda i, p: _jpeg(i, p, 10),
}


def opencv_finds(img: np.ndarray, pattern: tuple[int, int]) -> bool:
    import cv2

    grey = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY) if img.ndim == 3 else img
    ok, _ = cv2.findChessboardCornersSB(grey, pattern, flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
    if ok or grey.size > 4e6:  # the classic detector takes seconds at 12 MP
        return bool(ok)
    ok, _ = cv2.findChessboardCorners(grey, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    return bool(ok)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", action="append", help="only this set (repeatable)")
    ap.add_argument("--alter", action="append", choices=list(ALTERATIONS), help="only this alteration (repeatable)")
    args = ap.parse_args(argv)
    if not DATA.is_dir():
        print(f"{DATA} is absent")
        return 1
    folders = sorted(p for p in DATA.iterdir() if (p / "reference.json").is_file())
    folders = [p for p in folders if not args.set or p.name in args.set]
    alters = args.alter or list(ALTERATIONS)
    totals = {a: [0, 0, 0, 0] for a in alters}  # OpenCV found, camkit found of those, missed, wrong
    print(f"{'set':18} {'alteration':11} {'OpenCV':>6} {'camkit':>6} {'missed':>6} {'wrong':>5} {'median px':>9} "
          f"{'s/image':>7}")
    for folder in folders:
        ref = json.loads((folder / "reference.json").read_text())
        cols, rows = ref["pattern"]
        board = Checkerboard(cols, rows, 0.03)
        photos = [(read_image(folder / "images" / e["image"]), e) for e in ref["images"] if e["found"]]
        for name in alters:
            cv_n = ck_n = 0
            medians, notes = [], []
            seconds = 0.0
            for photo, e in photos:
                img, pts = ALTERATIONS[name](photo, np.asarray(e["corners"], dtype=np.float64))
                t0 = time.perf_counter()
                det = detect_corners(img, board)
                seconds += time.perf_counter() - t0
                cv_ok = opencv_finds(img, (cols, rows))
                cv_n += cv_ok
                if det.found:
                    med, wrong, _, _ = compare(det.corners, pts, cols, rows)
                    medians.append(med)
                    ck_n += cv_ok
                    if wrong:
                        notes.append(f"WRONG {e['image']}: {wrong} corners")
                        totals[name][3] += 1
                elif cv_ok:
                    notes.append(f"missed {e['image']}: {det.message}")
                    totals[name][2] += 1
            totals[name][0] += cv_n
            totals[name][1] += ck_n
            print(f"{folder.name:18} {name:11} {cv_n:6d} {ck_n:6d} {cv_n - ck_n:6d} "
                  f"{sum(n.startswith('WRONG') for n in notes):5d} "
                  f"{np.median(medians) if medians else float('nan'):9.3f} {seconds / max(len(photos), 1):7.3f}",
                  flush=True)
            for n in notes:
                print(f"    {n}", flush=True)
    print("\nall sets:")
    for name, (cv_n, ck_n, missed, wrong) in totals.items():
        print(f"  {name:11} OpenCV {cv_n:4d}, camkit {ck_n:4d} of them (missed {missed}), wrong boards {wrong}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
