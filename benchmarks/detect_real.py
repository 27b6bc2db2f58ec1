"""Checkerboard detection on the real photo sets in ../shared/data/real_boards (issue 21, item 4).

For every image: camkit's ``detect_corners`` against OpenCV 5's reference corners
(``reference.json``: found by ``findChessboardCornersSB`` or the classic detector). OpenCV's
labelling may differ from camkit's by a symmetry of the board, so each detection is compared
under the board symmetry that fits it best. A *wrong label* is a returned corner nearer another
reference corner than a third of the way to it (half a square is where the label would change);
corners more than 1 px from the reference under their right label are counted apart as *far*
(on these photos they are blurred or badly printed corners where the two detectors' saddle
estimates differ, e.g. right01.jpg, whose squares' edges are offset by about 1 px).

Run: ``python -m benchmarks.detect_real [--set NAME] [--verbose]``. Prints per set: images,
boards OpenCV found, boards camkit found, boards found by OpenCV and missed by camkit, wrong
boards, and the median corner distance. Used in the tests on a sample (tests/calib).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camkit.io import read_image
from camkit.target import Checkerboard, detect_corners

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real_boards"


def symmetries(cols: int, rows: int) -> list[np.ndarray]:
    """Index permutations of a cols x rows lattice (row-major) under the board's symmetries:
    the identity, both mirrors and the half-turn (and, for a square board, the transposes)."""
    g = np.arange(cols * rows).reshape(rows, cols)
    perms = [g, g[:, ::-1], g[::-1, :], g[::-1, ::-1]]
    if cols == rows:
        perms += [p.T for p in perms]
    return [p.ravel() for p in perms]


def point_asymmetry(grey: np.ndarray, pts: np.ndarray, rho: float) -> np.ndarray:
    """How far the image is from point-symmetric about each of ``pts`` (K, 2): on a circle of
    ``rho`` px, the mean difference between opposite points over the circle's contrast. A true
    X-junction is a centre of point symmetry (about 0.03-0.1 on real photos); a point on a
    square's edge beside it is not. Where no truth is known, it tells which of two detectors'
    corners lies at the junction."""
    from camkit.target.checkerboard import _sample

    ang = np.arange(64) * 2 * np.pi / 64
    p = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    v = _sample(grey, p[:, :1] + rho * np.cos(ang), p[:, 1:] + rho * np.sin(ang), "bilinear")
    return np.abs(v - np.roll(v, 32, axis=1)).mean(axis=1) / np.maximum(v.max(axis=1) - v.min(axis=1), 1e-12)


def compare(corners: np.ndarray, reference: np.ndarray, cols: int,
            rows: int) -> tuple[float, int, int, np.ndarray]:
    """(median distance, wrong labels, far corners, per-corner distances) under the best
    symmetry."""
    best = None
    for perm in symmetries(cols, rows):
        d = np.hypot(*(corners - reference[perm]).T)
        med = float(np.nanmedian(d)) if np.isfinite(d).any() else np.inf
        if best is None or med < best[0]:
            best = (med, d, reference[perm])
    med, d, ref = best
    seen = np.isfinite(d)
    grid = ref.reshape(rows, cols, 2)
    steps = np.concatenate([np.hypot(*np.diff(grid, axis=1).reshape(-1, 2).T),
                            np.hypot(*np.diff(grid, axis=0).reshape(-1, 2).T)])
    spacing = float(np.median(steps))
    wrong = int((d[seen] > spacing / 3.0).sum())
    far = int(((d[seen] > 1.0) & (d[seen] <= spacing / 3.0)).sum())
    return med, wrong, far, d


@dataclass
class SetResult:
    name: str
    images: int = 0
    reference_found: int = 0
    found: int = 0
    missed: list[str] = field(default_factory=list)
    wrong: list[str] = field(default_factory=list)
    far: int = 0
    extra: int = 0
    distances: list[float] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def median_px(self) -> float:
        return float(np.median(self.distances)) if self.distances else float("nan")


def run_set(folder: Path, verbose: bool = False) -> SetResult:
    ref = json.loads((folder / "reference.json").read_text())
    cols, rows = ref["pattern"]
    board = Checkerboard(cols, rows, (ref.get("square_mm") or 30.0) / 1000.0)
    res = SetResult(folder.name)
    for item in ref["images"]:
        img = read_image(folder / "images" / item["image"])
        t0 = time.perf_counter()
        det = detect_corners(img, board)
        res.seconds += time.perf_counter() - t0
        res.images += 1
        res.found += det.found
        if item["found"]:
            res.reference_found += 1
            if not det.found:
                res.missed.append(f"{item['image']}: {det.message}")
        if det.found and item["found"]:
            med, wrong, far, d = compare(det.corners, np.asarray(item["corners"], dtype=float), cols, rows)
            if wrong:
                res.wrong.append(f"{item['image']}: {wrong} corners with another corner's label (median {med:.2f} px)")
            res.far += far
            res.distances.extend(d[np.isfinite(d)].tolist())
        elif det.found:
            res.extra += 1
        if verbose:
            print(f"  {item['image']}: ref {item['found']}, camkit {det.message}")
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", action="append", help="only this set (repeatable)")
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args(argv)
    if not DATA.is_dir():
        print(f"{DATA} is absent")
        return 1
    folders = sorted(p for p in DATA.iterdir() if (p / "reference.json").is_file())
    if args.set:
        folders = [p for p in folders if p.name in args.set]
    total = SetResult("all")
    print(f"{'set':18} {'images':>6} {'OpenCV':>6} {'camkit':>6} {'missed':>6} {'wrong':>5} {'extra':>5} "
          f"{'far':>4} {'median px':>9} {'s/image':>7}")
    for folder in folders:
        r = run_set(folder, args.verbose)
        print(f"{r.name:18} {r.images:6d} {r.reference_found:6d} {r.found:6d} {len(r.missed):6d} {len(r.wrong):5d} "
              f"{r.extra:5d} {r.far:4d} {r.median_px:9.3f} {r.seconds / r.images:7.3f}")
        for m in r.missed:
            print(f"    missed {m}")
        for w in r.wrong:
            print(f"    WRONG {w}")
        total.images += r.images
        total.reference_found += r.reference_found
        total.found += r.found
        total.missed += r.missed
        total.wrong += r.wrong
        total.extra += r.extra
        total.far += r.far
        total.distances += r.distances
        total.seconds += r.seconds
    print(f"{'all':18} {total.images:6d} {total.reference_found:6d} {total.found:6d} {len(total.missed):6d} "
          f"{len(total.wrong):5d} {total.extra:5d} {total.far:4d} {total.median_px:9.3f} "
          f"{total.seconds / max(total.images, 1):7.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
