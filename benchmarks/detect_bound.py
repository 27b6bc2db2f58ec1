"""The noisy views' corners against the Cramer-Rao bound (issue 21, item 3).

For every backlit view of the stress corpus (``camkit.render.stress.stress_view``, up to 2 MP)
with sensor noise (with ``--every``, every view with sensor noise), where camkit finds the
board: the view is drawn again with its noise draw replaced by zeros (the generator's other
draws, and the JPEG step, unchanged), and the noise the detector sees is measured as the
standard deviation of the noisy grey less the clean one. For each corner camkit returns with
the right label, the Cramer-Rao bound of its position: the clean image's pattern known, that
noise taken as white, every pixel within half a square of the corner (Fisher information
``sum grad I grad I^T / sigma^2``). No unbiased estimator
using those pixels does better; JPEG's error is not white and gathers at edges, so there the
bound is optimistic.

Prints camkit's error (median, 95th percentile) and the bound's (its radial error's, by
sampling each corner's 2-D Gaussian), for views with noise only and with noise and JPEG. With
``--every``, also the corners over 0.1 px as a share of all the corners scored: camkit's, and
an estimator's at the bound on every corner (the views with JPEG only, no sensor noise, are not
scored: their error is not white and has no such bound).

Run: ``python -m benchmarks.detect_bound [--views 2000] [--start 0] [--every] [--save F.npy]
[--load F.npy ...]`` (``--views 0 --load ...`` scores saved runs together).
"""

from __future__ import annotations

import argparse

import numpy as np

import camkit.render.stress as stress
from benchmarks.detect_corpus import best_labelling
from camkit.target import detect_corners


class _NoNoise:
    """A generator that draws as the one it wraps, but returns zeros for the image's noise."""

    def __init__(self, rng: np.random.Generator, noise: float) -> None:
        self._rng, self._noise = rng, noise

    def __getattr__(self, name: str):
        return getattr(self._rng, name)

    def normal(self, loc=0.0, scale=1.0, size=None):
        r = self._rng.normal(loc, scale, size)
        if isinstance(size, tuple) and len(size) >= 2 and loc == 0 and scale == self._noise:
            return np.zeros(size)
        return r


def _clean_view(seed: int, noise: float):
    make = stress.np.random.default_rng
    stress.np.random.default_rng = lambda *a, **k: _NoNoise(make(*a, **k), noise)
    try:
        return stress.stress_view(seed, megapixels=(0.1, 2))
    finally:
        stress.np.random.default_rng = make


def _grey(img: np.ndarray) -> np.ndarray:
    g = img.astype(np.float64) / 255.0
    return g.mean(axis=2) if g.ndim == 3 else g


def run(views: int, start: int, every: bool = False) -> np.ndarray:
    """Rows (seed, error px, bound sigma per axis px, JPEG quality or 0, backlit 1 or 0)."""
    rows = []
    for seed in range(start, start + views):
        v = stress.stress_view(seed, megapixels=(0.1, 2))
        if ("backlit" not in v.tags and not every) or v.noise == 0:
            continue
        det = detect_corners(v.image, v.board)
        if not det.found:
            continue
        d, truth = best_labelling(v, det.corners)
        clean = _grey(_clean_view(seed, v.noise).image)
        sigma = float(np.std(_grey(v.image) - clean))
        gy, gx = np.gradient(clean)
        H, W = clean.shape
        R = 0.5 * v.square_px
        r = int(R) + 1
        for k, p in enumerate(truth):
            if not np.isfinite(d[k]) or d[k] > 1.0 or not np.isfinite(p).all():
                continue
            if not (0 <= p[0] < W and 0 <= p[1] < H):  # the label's true corner out of the image
                continue
            x0, y0 = int(p[0]), int(p[1])
            sl = (slice(max(y0 - r, 0), min(y0 + r + 1, H)), slice(max(x0 - r, 0), min(x0 + r + 1, W)))
            yy, xx = np.mgrid[sl]
            m = (xx - p[0]) ** 2 + (yy - p[1]) ** 2 <= R * R
            a, b = gx[sl][m], gy[sl][m]
            F = np.array([[a @ a, a @ b], [a @ b, b @ b]]) / sigma**2
            if not np.linalg.det(F) > 1e-12 * np.trace(F) ** 2:
                continue
            rows.append((seed, d[k], float(np.sqrt(0.5 * np.trace(np.linalg.inv(F)))), v.jpeg_quality or 0,
                         float("backlit" in v.tags)))
    return np.array(rows).reshape(-1, 5)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, default=2000)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--every", action="store_true", help="every view with sensor noise, not only the backlit ones")
    ap.add_argument("--load", nargs="*", default=[], help="rows saved by earlier runs (.npy), scored with these")
    ap.add_argument("--save", help="save this run's rows (.npy) for a later --load")
    args = ap.parse_args(argv)
    a = run(args.views, args.start, args.every)
    if args.save:
        np.save(args.save, a)
    a = np.concatenate([a, *(np.load(p) for p in args.load)])
    rng = np.random.default_rng(0)
    which = "every view's" if args.every else "backlit"
    span = f"views {args.start}..{args.start + args.views - 1}" if args.views else "no views run"
    loaded = f" and {len(args.load)} saved runs" if args.load else ""
    print(f"{span}{loaded}: {which} corners with noise, camkit's error against the Cramer-Rao bound")
    groups = [("noise only", a[:, 3] == 0), ("noise and JPEG", a[:, 3] > 0), ("all", a[:, 3] >= 0)]
    if args.every:
        groups += [("backlit", a[:, 4] == 1), ("lit", a[:, 4] == 0)]
    for name, m in groups:
        x = a[m]
        if not len(x):
            continue
        bound = np.concatenate([np.hypot(*rng.normal(0.0, s, (2, 50))) for s in x[:, 2]])
        e50, e95 = np.percentile(x[:, 1], [50, 95])
        b50, b95 = np.percentile(bound, [50, 95])
        print(f"  {name}: {len(x)} corners in {len(set(x[:, 0]))} views; camkit median {e50:.3f} / 95th {e95:.3f} px; "
              f"bound median {b50:.3f} / 95th {b95:.3f} px; over 0.1 px: camkit {np.mean(x[:, 1] > 0.1):.1%}, "
              f"bound {np.mean(bound > 0.1):.1%}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
