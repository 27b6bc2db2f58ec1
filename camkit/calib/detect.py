"""Checkerboard corner detection: X-corners, the board's lattice, sub-pixel saddle points."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from camkit._kernels import detect as _kd
from camkit._validate import as_image
from camkit.calib.targets import Checkerboard
from camkit.errors import ParameterError
from camkit.resample.remap import remap

__all__ = ["CornerDetection", "detect_corners"]

_SIGMA = 1.5  # smoothing for the saddle response (pixels)
_PROFILE_RADIUS = 4.0  # circle on which an X-corner shows four alternating sectors
_MAX_CANDIDATES = 5000


@dataclass(frozen=True, slots=True, eq=False)
class CornerDetection:
    """The corners found in one image.

    Attributes
    ----------
    found : bool
        The board's lattice was identified (some corners may still be missing).
    corners : ndarray, (n_corners, 2)
        Pixel positions in the order of ``board.object_points()``; NaN rows for corners not
        seen (covered by fingers, outside the image).
    sigma_px : ndarray, (n_corners,)
        Per-corner standard deviation of the position from the sub-pixel fit (NaN where
        not seen).
    window_px : int
        Half-size of the sub-pixel window chosen for this image.
    message : str
    """

    found: bool
    corners: np.ndarray
    sigma_px: np.ndarray
    window_px: int
    message: str

    @property
    def n_found(self) -> int:
        return int(np.isfinite(self.corners).all(axis=1).sum())


def _to_grey(image: np.ndarray) -> np.ndarray:
    img = as_image(image, "image")
    g = img.astype(np.float64)
    if img.dtype.kind == "u":
        g /= np.iinfo(img.dtype).max
    if g.ndim == 3:
        g = g[:, :, :3].mean(axis=2) if g.shape[2] >= 3 else g[:, :, 0]
    lo, hi = np.percentile(g, [1, 99])
    return np.ascontiguousarray((g - lo) / max(hi - lo, 1e-12))


def _sample(img: np.ndarray, x: np.ndarray, y: np.ndarray, interpolation: str) -> np.ndarray:
    mp = np.stack([x.ravel(), y.ravel()], axis=-1)[None]
    return remap(img, np.ascontiguousarray(mp), interpolation=interpolation, border="replicate")[0].reshape(x.shape)


def _profiles(s: np.ndarray, pts: np.ndarray, n: int = 32) -> np.ndarray:
    ang = np.arange(n) * 2 * np.pi / n
    return _sample(s, pts[:, :1] + _PROFILE_RADIUS * np.cos(ang), pts[:, 1:] + _PROFILE_RADIUS * np.sin(ang),
                   "bilinear")


def _saddle_fit(s: np.ndarray, pts: np.ndarray, r: int, iters: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Saddle point of a quadratic fitted on a (2r+1)^2 window centred on each estimate
    (sampled bicubically, so the window is symmetric about it); per-corner sigma from the
    fit's residuals propagated through the saddle equations."""
    q = pts.astype(np.float64).copy()
    oy, ox = np.mgrid[-r:r + 1, -r:r + 1].astype(np.float64)
    dx, dy = ox.ravel(), oy.ravel()
    A = np.stack([dx * dx, dx * dy, dy * dy, dx, dy, np.ones_like(dx)], -1)
    pinv = np.linalg.pinv(A)
    AtA_inv = np.linalg.inv(A.T @ A)
    for _ in range(iters):
        vals = _sample(s, q[:, :1] + dx, q[:, 1:] + dy, "bicubic")
        c = vals @ pinv.T
        a, b, cc, d, e = c[:, 0], c[:, 1], c[:, 2], c[:, 3], c[:, 4]
        det = 4 * a * cc - b * b
        step = np.stack([(-2 * cc * d + b * e) / det, (b * d - 2 * a * e) / det], -1)
        q += np.clip(np.nan_to_num(step, nan=0.0), -1.0, 1.0)
    vals = _sample(s, q[:, :1] + dx, q[:, 1:] + dy, "bicubic")
    c = vals @ pinv.T
    res = vals - c @ A.T
    var = (res * res).sum(axis=1) / max(A.shape[0] - 6, 1)
    a, b, cc = c[:, 0], c[:, 1], c[:, 2]
    Hdet = 4 * a * cc - b * b
    # d saddle / d (d, e) = -H^-1, H = [[2a, b], [b, 2c]]; var(d) = var(e) = var * (AtA^-1)_33
    h11, h12, h22 = 2 * cc / Hdet, -b / Hdet, 2 * a / Hdet
    cvar = var * AtA_inv[3, 3]
    sigma = np.sqrt(0.5 * cvar * (h11 * h11 + 2 * h12 * h12 + h22 * h22))
    return q, sigma


def _edge_directions(v: np.ndarray) -> np.ndarray:
    """The two edge lines through each corner, from the four sign changes of its profile."""
    n = v.shape[1]
    sign = v > v.mean(axis=1, keepdims=True)
    change = sign != np.roll(sign, 1, axis=1)
    idx = np.sort(np.argsort(~change, axis=1, kind="stable")[:, :4], axis=1)
    th = (idx - 0.5) * 2 * np.pi / n
    a = np.angle(np.exp(2j * th[:, 0]) + np.exp(2j * th[:, 2])) / 2
    b = np.angle(np.exp(2j * th[:, 1]) + np.exp(2j * th[:, 3])) / 2
    return np.stack([np.stack([np.cos(a), np.sin(a)], -1), np.stack([np.cos(b), np.sin(b)], -1)], axis=1)


def _assemble(pts: np.ndarray, dirs: np.ndarray, max_angle_deg: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """Link each corner to its nearest corner along each of its edge directions (mutual links
    only), then walk the links breadth-first assigning lattice coordinates; the largest
    connected lattice wins. Returns (indices into pts, lattice coordinates)."""
    n = len(pts)
    D = pts[None, :, :] - pts[:, None, :]
    dist = np.hypot(D[..., 0], D[..., 1])
    np.fill_diagonal(dist, np.inf)
    cosmax = np.cos(np.radians(max_angle_deg))
    nb = -np.ones((n, 4), dtype=np.int64)
    # The neighbour along an edge is among a corner's 8 nearest (4 along the edges, 4 on the
    # diagonals), so only those are looked at.
    K = min(8, n - 1)
    rows = np.arange(n)[:, None]
    nn = np.argpartition(dist, K - 1, axis=1)[:, :K] if K > 0 else np.zeros((n, 0), np.int64)
    Dn = D[rows, nn]  # (n, K, 2)
    dn = dist[rows, nn]
    for k, (ax, sg) in enumerate(((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0))):
        u = sg * dirs[:, ax]  # (n, 2)
        cosang = (Dn[..., 0] * u[:, :1] + Dn[..., 1] * u[:, 1:]) / dn
        cand = np.where(cosang > cosmax, dn, np.inf)
        if K == 0:
            continue
        j = np.argmin(cand, axis=1)
        nb[:, k] = np.where(np.isfinite(cand[np.arange(n), j]), nn[np.arange(n), j], -1)
    spacing = float(np.median(dist.min(axis=1)))
    # The walk is graph logic over a few hundred corners: plain Python floats, not NumPy
    # scalars, keep it to a few milliseconds.
    P = pts.tolist()
    Dr = dirs.tolist()
    NB = nb.tolist()
    # Whether each link is short enough, looked up as Python booleans (indexing the NumPy
    # distance matrix inside the walk cost more than the rest of it).
    near = (np.take_along_axis(dist, np.maximum(nb, 0), axis=1) <= 3.6 * spacing).tolist()
    visited = [False] * n
    best: dict[int, tuple[int, int]] = {}
    order = np.argsort(-(nb >= 0).sum(axis=1)).tolist()
    for seed in order:
        if visited[seed]:
            continue
        comp = {seed: (0, 0)}
        taken = {(0, 0)}
        axes = {seed: (Dr[seed][0], Dr[seed][1])}
        visited[seed] = True
        queue = deque([seed])
        while queue:
            i = queue.popleft()
            gi, gj = comp[i]
            (eax, eay), (ebx, eby) = axes[i]
            for j, ok in zip(NB[i], near[i], strict=True):
                if j < 0 or not ok or j in comp or i not in NB[j]:
                    continue
                sx, sy = P[j][0] - P[i][0], P[j][1] - P[i][1]
                pa, pb = sx * eax + sy * eay, sx * ebx + sy * eby
                target = (gi + (1 if pa > 0 else -1), gj) if abs(pa) >= abs(pb) else (gi, gj + (1 if pb > 0 else -1))
                if target in taken:
                    continue
                (dax, day), (dbx, dby) = Dr[j]
                if abs(dax * eax + day * eay) < abs(dbx * eax + dby * eay):
                    (dax, day), (dbx, dby) = (dbx, dby), (dax, day)
                if dax * eax + day * eay < 0:
                    dax, day = -dax, -day
                if dbx * ebx + dby * eby < 0:
                    dbx, dby = -dbx, -dby
                axes[j] = ((dax, day), (dbx, dby))
                comp[j] = target
                taken.add(target)
                visited[j] = True
                queue.append(j)
        if len(comp) > len(best):
            best = comp
    idx = np.array(list(best.keys()), dtype=np.int64)
    g = np.array([best[i] for i in idx], dtype=np.int64).reshape(-1, 2)
    return idx, g - g.min(axis=0) if len(g) else g


def detect_corners(image: np.ndarray, board: Checkerboard) -> CornerDetection:
    """Find the inner corners of a checkerboard, in the order of ``board.object_points()``.

    1. X-corners: local maxima of the saddle response ``-(Ixx Iyy - Ixy^2)`` of the image
       smoothed with sigma = 1.5 px, kept where a circle of radius 4 px around them crosses
       four alternating sectors, with contrast, that are point-symmetric (true inner corners;
       the board's outer edge against the background is not).
    2. Sub-pixel: the saddle point of a quadratic fitted on a window centred on each estimate,
       the window's half-size chosen per image from the corner spacing (an eleventh of it,
       2 to 5 px); each corner's sigma from the fit's residuals.
    3. Lattice: corners linked to their nearest neighbours along their own edge directions,
       walked breadth-first into integer coordinates; extra lines (edge corners) trimmed
       towards the board's size by symmetry; the labelling made right-handed in the image
       (the printed face is seen) and matched to ``inner_cols x inner_rows`` in either
       orientation.
    4. Ordering: a non-square board's lattice fixes the axes; the remaining half-turn is
       resolved by the board's colours (the outer square diagonal from corner (0, 0) is
       black, as :class:`Checkerboard` defines it), when the board's colours distinguish the
       two ends; otherwise corner (0, 0) is the one nearer the image's top-left.

    5. Scale: where the board is not found, steps 1-4 run again on the image halved (2x2 means)
       as long as its smaller side keeps 600 px, and the corners found there are refined on the
       full image with the smoothing and window scaled by the factor.

    Corners not seen (fingers over the edge squares) are NaN rows. Grey, RGB(A) and 16-bit
    images are accepted. An image without a board gives ``found=False`` quickly.
    """
    if not isinstance(board, Checkerboard):
        raise ParameterError(f"board: expected a Checkerboard, got {type(board).__name__}")
    grey = _to_grey(image)
    det = _detect(grey, board)
    level = grey
    factor = 1
    while not det.found and min(level.shape) >= 2 * _MIN_PYRAMID_SIDE:
        # Large squares (a 300-dpi scan, a 24 MP photo of a near board): the fixed smoothing and
        # profile circle see edges, not corners. Look again at half the resolution, then refine
        # at full resolution.
        level = _half(level)
        factor *= 2
        coarse = _detect(level, board)
        if coarse.found:
            return _refine_full(grey, coarse, factor, board)
    return det


#: The pyramid stops before an image side falls under this many pixels.
_MIN_PYRAMID_SIDE = 600


def _half(img: np.ndarray) -> np.ndarray:
    """The 2x2 mean: pixel (x, y) of the half image covers full-resolution pixels 2x..2x+1."""
    h, w = img.shape[0] // 2 * 2, img.shape[1] // 2 * 2
    a = img[:h, :w]
    return np.ascontiguousarray(0.25 * (a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]))


def _refine_full(grey: np.ndarray, coarse: CornerDetection, factor: int, board: Checkerboard) -> CornerDetection:
    """Corners found at 1/factor resolution, refined on the full image: positions mapped back
    (x_full = (x + 0.5) * factor - 0.5), then the saddle fit with the smoothing and window scaled
    by the factor; a corner that moves more than ``factor`` pixels is dropped (NaN)."""
    cols, rows = board.inner_cols, board.inner_rows
    c = (coarse.corners + 0.5) * factor - 0.5
    seen = np.isfinite(c).all(axis=1)
    grid = c.reshape(rows, cols, 2)
    steps = np.concatenate([np.hypot(*np.diff(grid, axis=1).reshape(-1, 2).T),
                            np.hypot(*np.diff(grid, axis=0).reshape(-1, 2).T)])
    spacing = float(np.nanmedian(steps)) if np.isfinite(steps).any() else 11.0 * factor
    r = int(np.clip(round(spacing / 11.0), 2, 5 * factor))
    s = np.empty_like(grey)
    _kd.gaussian_blur(grey, _SIGMA * factor, s)
    refined, sig = _saddle_fit(s, c[seen], r)
    out = np.full_like(c, np.nan)
    sigma = np.full(len(c), np.nan)
    moved = np.hypot(*(refined - c[seen]).T)
    keep = np.flatnonzero(seen)[np.isfinite(moved) & (moved <= factor)]
    ok = np.isfinite(moved) & (moved <= factor)
    out[keep] = refined[ok]
    sigma[keep] = sig[ok]
    if _bent_fraction(out.reshape(rows, cols, 2)) > 0.1:
        return CornerDetection(False, np.full_like(c, np.nan), np.full(len(c), np.nan), r,
                               f"not found: the lattice found at 1/{factor} resolution is inconsistent at full "
                               "resolution")
    found = int(np.isfinite(out).all(axis=1).sum())
    return CornerDetection(True, out, sigma, r, f"found {found} of {cols * rows} corners at 1/{factor} resolution, "
                           f"refined at full resolution (window {r} px)")


def _detect(grey: np.ndarray, board: Checkerboard) -> CornerDetection:
    """Steps 1-4 of :func:`detect_corners` on one resolution."""
    cols, rows = board.inner_cols, board.inner_rows
    n_corners = cols * rows
    empty = np.full((n_corners, 2), np.nan)

    def fail(msg: str, window: int = 0) -> CornerDetection:
        return CornerDetection(False, empty.copy(), np.full(n_corners, np.nan), window, msg)

    s = np.empty_like(grey)
    _kd.gaussian_blur(grey, _SIGMA, s)
    R = np.empty_like(s)
    _kd.saddle_response(s, R)
    rmax = float(R.max())
    if not rmax > 0:
        return fail("not found: no saddle points in the image")
    buf = np.empty((_MAX_CANDIDATES, 2), dtype=np.int64)
    n = _kd.local_maxima(R, 3, 0.05 * rmax, buf)
    if n < 4:
        return fail("not found: fewer than 4 corner candidates")
    pts = buf[:n].astype(np.float64)
    v = _profiles(s, pts)
    sign = v > v.mean(axis=1, keepdims=True)
    changes = (sign != np.roll(sign, 1, axis=1)).sum(axis=1)
    contrast = v.max(axis=1) - v.min(axis=1)
    sym = np.abs(v - np.roll(v, v.shape[1] // 2, axis=1)).mean(axis=1) / np.maximum(contrast, 1e-12)
    ok = (changes == 4) & (contrast > 0.15) & (sym < 0.25)
    if ok.sum() < min(4, n_corners):
        return fail(f"not found: {int(ok.sum())} X-corners")
    pts, v, sym = pts[ok], v[ok], sym[ok]
    strength = R[pts[:, 1].astype(np.int64), pts[:, 0].astype(np.int64)]
    if len(pts) > 3 * n_corners:  # clutter or noise: keep the strongest (bounds the time)
        keep = np.argsort(-strength)[:3 * n_corners]
        pts, v, sym = pts[keep], v[keep], sym[keep]
    # Linking needs only the integer positions (+-0.5 px against the corner spacing); the
    # sub-pixel fit runs once, on the lattice's corners, below.
    idx, g = _assemble(pts, _edge_directions(v))
    if len(idx) < 4:
        return fail("not found: the corners form no lattice")
    ext = g.max(axis=0) + 1
    targets = [t for t in ((cols, rows), (rows, cols)) if ext[0] >= t[0] and ext[1] >= t[1]]
    if not targets:
        return fail(f"not found: the largest lattice is {ext[0]}x{ext[1]} corners, smaller than the board's "
                    f"{cols}x{rows} (partly hidden along a whole edge, or another pattern)")
    tgt = min(targets, key=lambda t: int(ext[0] - t[0] + ext[1] - t[1]))
    symv = sym[idx]
    for ax in (0, 1):
        while g[:, ax].max() + 1 > tgt[ax]:
            lo = g[:, ax] == g[:, ax].min()
            hi = g[:, ax] == g[:, ax].max()
            drop = lo if symv[lo].mean() > symv[hi].mean() else hi
            idx, g, symv = idx[~drop], g[~drop], symv[~drop]
            g = g - g.min(axis=0)
    ext = g.max(axis=0) + 1
    M = np.linalg.lstsq(np.c_[g, np.ones(len(g))], pts[idx], rcond=None)[0]
    if M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0] < 0:  # make the labelling right-handed in the image
        g[:, 1] = ext[1] - 1 - g[:, 1]
    if (ext[0], ext[1]) == (rows, cols) and rows != cols:
        g = np.stack([g[:, 1], ext[0] - 1 - g[:, 0]], axis=-1)
        ext = ext[::-1]
    if (int(ext[0]), int(ext[1])) != (cols, rows):
        return fail(f"not found: lattice {ext[0]}x{ext[1]} does not match the board's {cols}x{rows}")
    M = np.linalg.lstsq(np.c_[g, np.ones(len(g))], pts[idx], rcond=None)[0]
    where = {(int(a), int(b)): pts[i] for i, (a, b) in zip(idx, g, strict=True)}

    def corner(a: int, b: int) -> np.ndarray:
        return where.get((a, b), M[2] + a * M[0] + b * M[1])  # the lattice fit where not seen

    # Colours decide the half-turn: from each seen corner (a, b) whose diagonal neighbour
    # (a + 1, b + 1) is seen too, probe half a diagonal step the other way, inside square
    # (a, b) of the board, which is black when a + b is even; under a half-turn it is square
    # (cols - a, rows - b). The two predictions differ when cols + rows is odd; every such
    # corner votes (local probes: perspective and lens distortion cannot move them off their
    # square, and no corner is extrapolated).
    a, b = g[:, 0], g[:, 1]
    nb = np.array([where.get((int(x) + 1, int(y) + 1), (np.nan, np.nan)) for x, y in g])
    ok = np.isfinite(nb).all(axis=1)
    agree = 1.0
    if ok.sum() >= 4:
        p = pts[idx][ok]
        probe = p + 0.5 * (p - nb[ok])
        shade = _sample(s, probe[:, :1], probe[:, 1:], "bilinear").ravel()
        mid = 0.5 * (shade.max() + shade.min())
        agree = float(np.mean((shade < mid) == ((a[ok] + b[ok]) % 2 == 0)))
    if (cols + rows) % 2 == 1:
        flip = agree < 0.5
        agree = max(agree, 1.0 - agree)
    else:
        flip = (corner(0, 0) @ [1.0, 1.0]) > (corner(cols - 1, rows - 1) @ [1.0, 1.0])
    if agree < 0.8:
        # Labels off by one square (a partial lattice trimmed on the wrong side) put every
        # probe in a square of the other colour.
        return fail(f"not found: the corners' labels disagree with the squares' colours ({agree:.0%} agree); "
                    "part of the board may be hidden")
    if flip:
        g = np.stack([cols - 1 - g[:, 0], rows - 1 - g[:, 1]], axis=-1)
    # Sub-pixel refinement with the window chosen for this image.
    spacing = float(np.mean([np.hypot(*M[0]), np.hypot(*M[1])]))  # pixels between corners
    r = int(np.clip(round(spacing / 11.0), 2, 5))
    refined, sig = _saddle_fit(s, pts[idx], r)
    out = empty.copy()
    sigma = np.full(n_corners, np.nan)
    flat = g[:, 1] * cols + g[:, 0]
    out[flat] = refined
    sigma[flat] = sig
    inside = ((out[:, 0] >= 0) & (out[:, 0] <= grey.shape[1] - 1) & (out[:, 1] >= 0)
              & (out[:, 1] <= grey.shape[0] - 1))
    out[~inside] = np.nan
    sigma[~inside] = np.nan
    bent = _bent_fraction(out.reshape(rows, cols, 2))
    if bent > 0.1:
        # A lattice walked wrongly (a skipped or doubled column, as strong fisheye distortion
        # can cause) bends rows by a whole square; fingers over edge corners bend a few. Say
        # "not found" rather than return corners with wrong indices.
        return fail(f"not found: the corner lattice is inconsistent ({bent:.0%} of rows and columns bend by more "
                    "than half a square; a lens this strong may need the board nearer the image centre)", r)
    seen = out[np.isfinite(out).all(axis=1)]
    if len(seen) > 1:
        d = np.hypot(*(seen[:, None, :] - seen[None, :, :]).transpose(2, 0, 1))
        np.fill_diagonal(d, np.inf)
        if d.min() < 0.3 * spacing:
            # Two labels on one corner: the lattice was walked over something else (text,
            # clutter). Never return it.
            return fail("not found: the corner lattice is inconsistent (two labels on one corner)", r)
    found = int(np.isfinite(out).all(axis=1).sum())
    return CornerDetection(True, out, sigma, r, f"found {found} of {n_corners} corners (window {r} px)")


def _bent_fraction(grid: np.ndarray) -> float:
    """Fraction of consecutive corner triples along rows and columns whose second difference
    exceeds half the smaller of their two spacings (a correct lattice, even through a strong
    lens, stays far below: 0.47 at most in tests on fisheye renders)."""
    ratios = []
    for q in (grid, grid.transpose(1, 0, 2)):
        if q.shape[1] < 3:
            continue
        d1 = np.diff(q, axis=1)
        d2 = np.diff(q, n=2, axis=1)
        step = np.minimum(np.hypot(d1[:, :-1, 0], d1[:, :-1, 1]), np.hypot(d1[:, 1:, 0], d1[:, 1:, 1]))
        ratios.append((np.hypot(d2[..., 0], d2[..., 1]) / np.maximum(step, 1e-12)).ravel())
    if not ratios:
        return 0.0
    r = np.concatenate(ratios)
    r = r[np.isfinite(r)]
    return float(np.mean(r > 0.5)) if r.size else 0.0
