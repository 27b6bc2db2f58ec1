"""Checkerboard detection on the rendered stress corpus (issue 21, item 3).

Views come from :func:`camkit.render.stress.stress_view` (seed = view number): poses up to 70
degrees of tilt, squares of 10-250 px, margins of 0.1-1.5 squares round them, 0.1-24 MP,
barrel, pincushion and fisheye lenses, defocus and motion blur, noise, JPEG 40-95, vignetting
and uneven light, partial views, occluders, tiles, text and second boards. For each view
camkit's ``detect_corners`` is scored against the exact truth under the labellings the view
allows (see ``stress_view``):

- wrong labels: returned corners more than 1 px from the true corner of their label (the
  issue's definition), counted per view and per corner;
- found: in views where the whole board is visible, the squares are >= 12 px, the blur
  (Gaussian sigma combined with the motion's box, length / sqrt(12)) is <= 2 px and the board
  is seen at most 70 degrees from square on (the issue's "poses up to 70 degrees of tilt",
  measured against the line of sight: the generator draws the tilt about the camera's axis,
  so a board placed off the axis of a wide lens is seen up to edge on). The figure without
  that last condition is printed too;
- corner error: median over noise-free views (no noise, no JPEG), 95th percentile over the
  rest (and over the rest less the backlit views, whose board spans a tenth to a third of
  the image's range under the same noise), for corners found with the right label.

Run: ``python -m benchmarks.detect_corpus [--views 2000] [--start 0] [--max-mp 24] [--jobs 2]``
(``--jobs``: the seeds split over processes, the figures pooled as one run's).
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from itertools import pairwise

import numpy as np

from camkit.render.stress import StressView, stress_view
from camkit.target import detect_corners


def best_labelling(view: StressView, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(each corner's distance to its true corner, NaN where not returned; the true corners in
    the returned corners' order) under the allowed labelling with the least median distance."""
    best = None
    for perm in view.labellings:
        d = np.hypot(*(corners - view.corners_px[perm]).T)
        seen = np.isfinite(d)
        med = float(np.median(d[seen])) if seen.any() else 0.0
        if best is None or med < best[0]:
            best = (med, d, view.corners_px[perm])
    return best[1], best[2]


def score(view: StressView, corners: np.ndarray) -> tuple[int, np.ndarray]:
    """(wrong labels, distances of the returned corners to the truth) under the allowed
    labelling that fits best."""
    d = best_labelling(view, corners)[0]
    seen = np.isfinite(d)
    return int((d[seen] > 1.0).sum()), d[seen]


#: The issue's largest tilt, measured against the line of sight (degrees).
MAX_OBLIQUITY = 70.0


def eligible(view: StressView, obliquity: bool = True) -> bool:
    """Whether the view counts for the found rate (see the module's text); ``obliquity=False``
    drops the condition on the angle the board is seen at."""
    blur = float(np.hypot(view.blur_sigma_px, view.motion_px / np.sqrt(12.0)))
    return (view.whole and view.square_px >= 12.0 and blur <= 2.0
            and (not obliquity or view.obliquity_deg <= MAX_OBLIQUITY))


def run(views: int, start: int = 0, max_mp: float = 24.0, verbose: bool = False, jobs: int = 1) -> dict:
    """The corpus's figures over seeds ``start`` .. ``start + views - 1``; ``jobs`` > 1 splits
    the seeds over that many processes and pools what they measured (the same figures)."""
    if jobs > 1 and views > 1:
        from concurrent.futures import ProcessPoolExecutor

        cuts = np.linspace(start, start + views, min(jobs, views) + 1).round().astype(int)
        with ProcessPoolExecutor(len(cuts) - 1) as ex:
            parts = list(ex.map(_run_part, [(int(b - a), int(a), max_mp, verbose) for a, b in pairwise(cuts)]))
        stats, raw = Counter(), {"err_clean": [], "err_noisy": [], "err_noisy_lit": [], "misses": [], "wrongs": []}
        seconds = 0.0
        for p in parts:
            stats.update(p["stats"])
            seconds += p["seconds"]
            for k in raw:
                raw[k].extend(p[k])
        return _summary(stats, raw, seconds)
    return _summary(*_measure(views, start, max_mp, verbose))


def _run_part(args: tuple[int, int, float, bool]) -> dict:
    stats, raw, seconds = _measure(*args)
    return {"stats": stats, "seconds": seconds, **raw}


def _summary(stats: Counter, raw: dict, seconds: float) -> dict:
    ec, en, el = raw["err_clean"], raw["err_noisy"], raw["err_noisy_lit"]
    return {
        "stats": stats, "misses": raw["misses"], "wrongs": raw["wrongs"], "seconds": seconds,
        "median_clean": float(np.median(ec)) if ec else float("nan"),
        "p95_noisy": float(np.percentile(en, 95)) if en else float("nan"),
        "p95_noisy_lit": float(np.percentile(el, 95)) if el else float("nan"),
        "over_noisy": float(np.mean(np.asarray(en) > 0.1)) if en else float("nan"),
    }


def _measure(views: int, start: int, max_mp: float, verbose: bool) -> tuple[Counter, dict, float]:
    stats = Counter()
    err_clean: list[float] = []
    err_noisy: list[float] = []
    err_noisy_lit: list[float] = []  # the same, without the backlit views
    misses: list[str] = []
    wrongs: list[str] = []
    t_detect = 0.0
    for seed in range(start, start + views):
        v = stress_view(seed, megapixels=(0.1, max_mp))
        t0 = time.perf_counter()
        det = detect_corners(v.image, v.board)
        t_detect += time.perf_counter() - t0
        stats["views"] += 1
        ok = eligible(v)
        any_angle = eligible(v, obliquity=False)
        stats["eligible"] += ok
        stats["eligible_any_angle"] += any_angle
        if det.found:
            stats["found"] += 1
            wrong, d = score(v, det.corners)
            if wrong:
                stats["wrong_views"] += 1
                stats["wrong_corners"] += wrong
                wrongs.append(f"seed {seed}: {wrong} corners wrong ({v.tags}, square {v.square_px:.1f} px, "
                              f"{v.image.shape[1]}x{v.image.shape[0]})")
            good = d[d <= 1.0]
            (err_clean if v.noise == 0 and v.jpeg_quality is None else err_noisy).extend(good.tolist())
            if (v.noise > 0 or v.jpeg_quality is not None) and "backlit" not in v.tags:
                err_noisy_lit.extend(good.tolist())
            stats["eligible_found"] += ok
            stats["eligible_any_angle_found"] += any_angle
        elif ok:
            misses.append(f"seed {seed}: {det.message} ({v.tags}, square {v.square_px:.1f} px, "
                          f"{v.image.shape[1]}x{v.image.shape[0]}, blur {v.blur_sigma_px:.2f}, "
                          f"seen {v.obliquity_deg:.0f} deg from square on)")
        if verbose:
            print(f"seed {seed}: {det.message}")
    return stats, {"err_clean": err_clean, "err_noisy": err_noisy, "err_noisy_lit": err_noisy_lit,
                   "misses": misses, "wrongs": wrongs}, t_detect


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, default=2000)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--max-mp", type=float, default=24.0)
    ap.add_argument("--verbose", action="store_true")
    ap.add_argument("--jobs", type=int, default=1, help="processes to split the seeds over (the figures pooled)")
    args = ap.parse_args(argv)
    r = run(args.views, args.start, args.max_mp, args.verbose, args.jobs)
    s = r["stats"]
    for m in r["misses"]:
        print("missed", m)
    for w in r["wrongs"]:
        print("WRONG", w)
    print(f"views {s['views']} (seeds {args.start}..{args.start + args.views - 1}, up to {args.max_mp} MP); "
          f"boards returned {s['found']}; with a wrong label: {s['wrong_views']} views, {s['wrong_corners']} corners")
    print(f"eligible (whole board, squares >= 12 px, blur <= 2 px, seen <= {MAX_OBLIQUITY:.0f} deg from square on): "
          f"{s['eligible']}, found {s['eligible_found']} ({100 * s['eligible_found'] / max(s['eligible'], 1):.1f} %)")
    print(f"  at any angle (up to edge on): {s['eligible_any_angle']}, found {s['eligible_any_angle_found']} "
          f"({100 * s['eligible_any_angle_found'] / max(s['eligible_any_angle'], 1):.1f} %)")
    print(f"corner error: median {r['median_clean']:.4f} px noise-free, 95th percentile {r['p95_noisy']:.4f} px "
          f"with noise/JPEG ({100 * r['over_noisy']:.2f} % over 0.1 px; {r['p95_noisy_lit']:.4f} px without the "
          "backlit views); "
          f"detection {r['seconds'] / max(s['views'], 1) * 1000:.0f} ms a view")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
