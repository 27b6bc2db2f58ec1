"""The ChArUco board (a checkerboard with an ArUco marker in each white square) and its detector.

Layout, object points and ids are OpenCV's ``cv2.aruco.CharucoBoard`` (4.6 and later, with its
``legacy`` setting), checked against it in tests/target/test_charuco.py:

- the board frame's origin is the outer top-left corner of the squares, x along the columns,
  y along the rows (down the printed face), z = 0 on the board;
- square ``(x, y)`` spans ``[x, x + 1] x [y, y + 1]`` squares; it holds a marker where ``x + y``
  is odd (the top-left square is black), except with ``legacy=True`` on a board with an even
  number of rows, where the markers are where ``x + y`` is even (OpenCV before 4.6);
- markers are numbered 0, 1, ... row by row over the squares that hold one, each centred in
  its square, corners in the order top-left, top-right, bottom-right, bottom-left;
- the ChArUco corners are the inner corners ``((x + 1) s, (y + 1) s)``, numbered row by row.

Detection reads the markers first, then places the chessboard corners by their saddle points:

1. dark regions of an adaptive threshold (each pixel against the mean of a window around
   it, three window sizes), 4-connected; each region the size of a marker gives a quad (the
   farthest pixel from its centre, the farthest from that, and the farthest from the line
   through both on either side);
2. the quad's cells are sampled through the homography of the unit square (3 x 3 samples in
   the middle of each cell), thresholded halfway between the black border and the white
   margin around the marker; a border that is not black, or bits more than the dictionary's
   correction away from every code in all four turns, reject the quad;
3. the markers' ids are checked against the board: an id the board does not have is
   another board's; an id seen twice is dropped; and each marker must be confirmed by a
   neighbour (another marker within two squares such that one homography maps both markers'
   board corners onto their eight image corners within 15 % of a square, 2 px at least) and
   contradicted by fewer than confirm it;
4. each chessboard corner next to a confirmed marker is predicted through the markers'
   homographies (the least-squares homography of both markers touching it where two are
   confirmed, else its marker's) and placed at the saddle point of the
   smoothed image (camkit's sub-pixel estimator, window an eleventh of the square's image
   size, 2 to 5 px), with its sigma; a corner that moves more than a tenth of a square (1.5
   px at least), that is not an X-junction on a circle inside the white margin (four
   alternating, point-symmetric sectors), or whose fit is over twice the median sigma, is
   dropped.

A corner is returned only next to a confirmed marker, so a board half out of the frame gives
every corner it shows beside a marker that confirms another.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Self

import numpy as np

from camkit._kernels import detect as detect_kernels
from camkit._kernels import markers as markers_kernels
from camkit._validate import as_positive_float, as_positive_int
from camkit.errors import ParameterError
from camkit.target.aruco import ArucoDictionary, get_dictionary
from camkit.target.base import Detection, Sheet, Target, register_target
from camkit.target.checkerboard import _half, _saddle_fit, _sample, _to_grey

__all__ = ["Charuco"]


@register_target
@dataclass(frozen=True, slots=True)
class Charuco(Target):
    """A ChArUco board: ``squares_x x squares_y`` squares of side ``square`` metres, a marker of
    side ``marker`` metres from ``dictionary`` in each white square (see the module docstring
    for the layout, OpenCV's).

    Examples
    --------
    >>> board = Charuco(5, 7, 0.04, 0.02, "DICT_6X6_250")
    >>> board.object_points().shape, board.n_markers
    ((24, 3), 17)
    """

    squares_x: int
    squares_y: int
    square: float
    marker: float
    dictionary: str = "DICT_5X5_100"
    legacy: bool = False

    name = "charuco"

    def __post_init__(self) -> None:
        sx = as_positive_int(self.squares_x, "squares_x")
        sy = as_positive_int(self.squares_y, "squares_y")
        if sx < 2 or sy < 2:
            raise ParameterError(f"squares_x, squares_y: expected at least 2x2 squares, got {sx}x{sy}")
        sq = as_positive_float(self.square, "square")
        mk = as_positive_float(self.marker, "marker")
        if mk >= sq:
            raise ParameterError(f"marker: expected a marker smaller than its square ({sq:g} m), got {mk:g} m")
        if not isinstance(self.legacy, bool):
            raise ParameterError(f"legacy: expected True or False, got {self.legacy!r}")
        d = get_dictionary(self.dictionary)
        for name, v in (("squares_x", sx), ("squares_y", sy), ("square", sq), ("marker", mk)):
            object.__setattr__(self, name, v)
        if self.n_markers > len(d):
            raise ParameterError(f"dictionary: a {sx}x{sy} board needs {self.n_markers} markers, more than the "
                                 f"{len(d)} of {self.dictionary}; choose a larger dictionary")

    # -- layout ------------------------------------------------------------------------------
    @property
    def aruco(self) -> ArucoDictionary:
        return get_dictionary(self.dictionary)

    def marker_squares(self) -> np.ndarray:
        """``(x, y)`` of the squares holding markers, (M, 2), in marker-id order."""
        y, x = np.mgrid[0:self.squares_y, 0:self.squares_x]
        odd = (x + y) % 2 == 1
        if self.legacy and self.squares_y % 2 == 0:
            odd = ~odd
        return np.stack([x[odd], y[odd]], axis=-1)

    @property
    def n_markers(self) -> int:
        n = self.squares_x * self.squares_y
        if self.legacy and self.squares_y % 2 == 0:
            return (n + 1) // 2
        return n // 2

    def marker_corners(self) -> np.ndarray:
        """Each marker's corners (top-left, top-right, bottom-right, bottom-left) in the board
        frame, (M, 4, 3)."""
        sq = self.marker_squares().astype(np.float64)
        off = (self.square - self.marker) / 2
        x0 = sq[:, 0] * self.square + off
        y0 = sq[:, 1] * self.square + off
        m = self.marker
        cx = np.stack([x0, x0 + m, x0 + m, x0], axis=-1)
        cy = np.stack([y0, y0, y0 + m, y0 + m], axis=-1)
        return np.stack([cx, cy, np.zeros_like(cx)], axis=-1)

    def object_points(self) -> np.ndarray:
        """The ChArUco (inner chessboard) corners, ((squares_x - 1) (squares_y - 1), 3), row
        by row: corner ``(x, y)`` at ``((x + 1) square, (y + 1) square, 0)``."""
        y, x = np.mgrid[1:self.squares_y, 1:self.squares_x]
        return np.stack([x.ravel() * self.square, y.ravel() * self.square, np.zeros(x.size)], axis=-1)

    def size_note(self) -> str:
        return (f"board ({self.squares_x}x{self.squares_y} squares, squares {self.square * 1000:g} mm, markers "
                f"{self.marker * 1000:g} mm, {self.dictionary})")

    def sheet(self) -> Sheet:
        """The black squares, and each marker's black cells, on white; a margin of one square."""
        s, sx, sy = self.square, self.squares_x, self.squares_y
        y, x = np.mgrid[0:sy, 0:sx]
        has = np.zeros((sy, sx), dtype=bool)
        ms = self.marker_squares()
        has[ms[:, 1], ms[:, 0]] = True
        bx, by = x[~has].astype(np.float64), y[~has].astype(np.float64)
        rects = [np.stack([bx * s, by * s, (bx + 1) * s, (by + 1) * s], axis=-1)]
        d = self.aruco
        n = d.marker_size + 2
        cell = self.marker / n
        origins = self.marker_corners()[:, 0, :2]
        for mid in range(len(ms)):  # one marker at a time: its black cells as rectangles
            r, c = np.nonzero(d.cells(mid) == 0)
            x0, y0 = origins[mid]
            rects.append(np.stack([x0 + c * cell, y0 + r * cell, x0 + (c + 1) * cell, y0 + (r + 1) * cell], axis=-1))
        label = (f"ChArUco {sx}x{sy} squares of {s * 1000:g} mm, markers {self.marker * 1000:g} mm, "
                 f"{self.dictionary}{', legacy pattern' if self.legacy else ''}. Print at 100 % (actual size).")
        return Sheet((-s, -s, (sx + 1) * s, (sy + 1) * s), np.concatenate(rects), label)

    @classmethod
    def example(cls) -> Self:
        """OpenCV's tutorial board: 5 x 7 squares of 40 mm, 20 mm markers, DICT_6X6_250."""
        return cls(5, 7, 0.04, 0.02, "DICT_6X6_250")

    def detect(self, image: np.ndarray) -> Detection:
        """The ChArUco corners in ``image`` (see the module docstring)."""
        return _detect(self, image)


# -- detection ---------------------------------------------------------------------------------


def _fit_homographies(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Least-squares homographies (normalised DLT, Hartley and Zisserman alg. 4.2) of K point
    sets, ``src`` (K, P, 2) to ``dst`` (K, P, 2), P >= 4, all at once: (K, 3, 3), NaN where a
    set is degenerate (its points coincide). Exact for four points in general position."""
    def normalise(p):
        c = p.mean(axis=1)
        d = np.sqrt(((p - c[:, None]) ** 2).sum(axis=2)).mean(axis=1)
        k = np.sqrt(2.0) / np.where(d > 1e-12, d, np.nan)
        T = np.zeros((len(p), 3, 3))
        T[:, 0, 0] = T[:, 1, 1] = k
        T[:, 0, 2], T[:, 1, 2], T[:, 2, 2] = -k * c[:, 0], -k * c[:, 1], 1.0
        return np.nan_to_num((p - c[:, None]) * k[:, None, None]), T

    a, Ts = normalise(src)
    b, Td = normalise(dst)
    K, P = a.shape[:2]
    A = np.zeros((K, 2 * P, 9))
    A[:, 0::2, 0:2], A[:, 0::2, 2] = a, 1.0
    A[:, 0::2, 6:8], A[:, 0::2, 8] = -b[:, :, :1] * a, -b[:, :, 0]
    A[:, 1::2, 3:5], A[:, 1::2, 5] = a, 1.0
    A[:, 1::2, 6:8], A[:, 1::2, 8] = -b[:, :, 1:2] * a, -b[:, :, 1]
    h = np.linalg.svd(A)[2][:, -1].reshape(K, 3, 3)
    ok = np.isfinite(Td).all(axis=(1, 2)) & np.isfinite(Ts).all(axis=(1, 2))
    H = np.full((K, 3, 3), np.nan)
    H[ok] = np.linalg.solve(Td[ok], h[ok] @ Ts[ok])
    return H


def _fit_homography(src: np.ndarray, dst: np.ndarray) -> np.ndarray | None:
    """:func:`_fit_homographies` of one point set, (P, 2) to (P, 2); None where degenerate."""
    H = _fit_homographies(src[None], dst[None])[0]
    return H if np.isfinite(H).all() else None


def _homography_misfit(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """For each of K point sets, ``src`` (K, P, 2) to ``dst`` (K, P, 2): the largest distance
    (in ``dst``'s units) by which the least-squares homography misses a point; inf where none
    is fitted."""
    H = _fit_homographies(src, dst)
    q = np.einsum("kij,kpj->kpi", H, np.concatenate([src, np.ones(src.shape[:2] + (1,))], axis=2))
    with np.errstate(divide="ignore", invalid="ignore"):
        miss = np.hypot(*(q[:, :, :2] / q[:, :, 2:] - dst).transpose(2, 0, 1)).max(axis=1)
    return np.where(np.isfinite(miss), miss, np.inf)


def _refine_patches(grey: np.ndarray, pts: np.ndarray, r: int, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """The saddle fit (window ``r``) of each point on the image smoothed by ``sigma``, the
    smoothing computed only on a patch around each point (the patches side by side in one
    mosaic): enough for the window, its bicubic support and the fit's moves."""
    half = r + 9
    side = 2 * half + 1
    n = len(pts)
    per_row = max(1, int(np.ceil(np.sqrt(n))))
    origin = np.floor(pts).astype(np.int64) - half
    tile = np.stack([np.arange(n) % per_row, np.arange(n) // per_row], axis=-1) * side
    mosaic = np.zeros((side * ((n + per_row - 1) // per_row), side * per_row))
    detect_kernels.blur_patches(grey, np.ascontiguousarray(origin), np.ascontiguousarray(tile), side, sigma, mosaic)
    shift = tile - origin
    q, sg = _saddle_fit(mosaic, pts + shift, r)
    return q - shift, sg


def _is_x_corner(grey: np.ndarray, pts: np.ndarray, size: np.ndarray, board: Charuco) -> np.ndarray:
    """Which points are chessboard X-corners: on a circle inside the white margin that keeps
    the markers away (0.6 of it, 1.5 px at least), the shade crosses its mean four times,
    with contrast, and is point-symmetric (opposite squares alike), as step 1 of the
    checkerboard detector asks; a marker's own corner or bit junction is not."""
    margin = 0.5 * (board.square - board.marker) / board.square * size
    rho = np.maximum(0.6 * margin, 1.5)
    ang = np.arange(32) * 2 * np.pi / 32
    v = _sample(grey, pts[:, :1] + rho[:, None] * np.cos(ang), pts[:, 1:] + rho[:, None] * np.sin(ang), "bilinear")
    sign = v > v.mean(axis=1, keepdims=True)
    changes = (sign != np.roll(sign, 1, axis=1)).sum(axis=1)
    contrast = v.max(axis=1) - v.min(axis=1)
    sym = np.abs(v - np.roll(v, 16, axis=1)).mean(axis=1) / np.maximum(contrast, 1e-12)
    return (changes == 4) & (contrast > 0.15) & (sym < 0.25)


def _apply(H: np.ndarray, p: np.ndarray) -> np.ndarray:
    q = np.c_[p, np.ones(len(p))] @ H.T
    return q[:, :2] / q[:, 2:]


def _read_markers(g: np.ndarray, quads: np.ndarray, d: ArucoDictionary) -> tuple[np.ndarray, np.ndarray]:
    """``(code ids, turns)`` of the markers in ``quads`` (K, 4, 2), clockwise corners; id -1
    where a quad holds no code. All quads at once: their homographies from the unit square,
    one sampling of every cell's 3 x 3 middle points and of the white margin around each."""
    K = len(quads)
    n = d.marker_size + 2
    unit = np.array([[0.0, 0.0], [n, 0.0], [n, n], [0.0, n]])
    Hs = _fit_homographies(np.broadcast_to(unit, quads.shape), quads)
    ok = np.isfinite(Hs).all(axis=(1, 2))
    Hs[~ok] = np.eye(3)  # read nothing from these: ``ok`` rejects them below
    ov, ou = np.meshgrid([0.3, 0.5, 0.7], [0.3, 0.5, 0.7], indexing="ij")  # 3 x 3 in each cell's middle
    cy, cx = np.mgrid[0:n, 0:n]
    cells = np.stack([(cx[:, :, None] + ou.ravel()).ravel(), (cy[:, :, None] + ov.ravel()).ravel()], axis=-1)
    # The white margin around the marker: half a cell outside each side's middle.
    ring = np.array([[n / 2, -0.5], [n + 0.5, n / 2], [n / 2, n + 0.5], [-0.5, n / 2]])
    pts = np.concatenate([cells, ring])
    p = (Hs @ np.c_[pts, np.ones(len(pts))].T).transpose(0, 2, 1)
    with np.errstate(divide="ignore", invalid="ignore"):  # a degenerate quad's rows: not read below
        px = p[:, :, :2] / p[:, :, 2:]
    vals = _sample(g, np.ascontiguousarray(px[:, :, 0].ravel()), np.ascontiguousarray(px[:, :, 1].ravel()),
                   "bilinear").reshape(K, len(pts))
    cell = vals[:, :n * n * 9].reshape(K, n, n, 9).mean(axis=3)
    white = np.median(vals[:, n * n * 9:], axis=1)
    border = np.concatenate([cell[:, 0], cell[:, -1], cell[:, 1:-1, 0], cell[:, 1:-1, -1]], axis=1)
    black = np.median(border, axis=1)
    t = 0.5 * (white + black)
    good = ok & np.isfinite(white) & (white - black > 0.15) & (np.mean(border < t[:, None], axis=1) >= 0.85)
    ids = np.full(K, -1, dtype=np.int64)
    turns = np.zeros(K, dtype=np.int64)
    if good.any():
        bits = (cell[good][:, 1:-1, 1:-1] > t[good][:, None, None]).astype(np.uint8)
        ids[good], turns[good], _ = d.identify_many(bits)
    return ids, turns


def _quads(g: np.ndarray, min_side: int) -> np.ndarray:
    """Quad candidates (K, 4, 2), clockwise in the image, from the dark regions of an adaptive
    threshold at three window sizes (a quad found again at another window kept once)."""
    H, W = g.shape
    dark = np.empty((H, W), dtype=np.bool_)
    labels = np.empty((H, W), dtype=np.int64)
    out: list[np.ndarray] = []
    ii = np.empty((H + 1, W + 1))
    markers_kernels.integral(g, ii)
    for r in sorted({max(3, min(H, W) // k) for k in (80, 30, 12)}):
        markers_kernels.dark_mask(g, ii, r, 0.03, dark)
        n = markers_kernels.label4(dark, labels)
        if n == 0:
            continue
        stats = np.empty((n, 5), dtype=np.int64)
        quads = np.zeros((n, 4, 2))
        markers_kernels.region_quads(labels, n, (min_side * min_side) // 2, (H * W) // 4, min_side, stats, quads)
        area = stats[:, 0].astype(np.float64)
        w = stats[:, 3] - stats[:, 1] + 1
        h = stats[:, 4] - stats[:, 2] + 1
        q = quads
        shoelace = 0.5 * np.sum(q[:, :, 0] * np.roll(q[:, :, 1], -1, axis=1)
                                - np.roll(q[:, :, 0], -1, axis=1) * q[:, :, 1], axis=1)
        # A quad, not a triangle or a blob: its four corners span most of the region's area.
        ok = (area > 0) & (np.maximum(w, h) <= 8 * np.minimum(w, h)) & (np.abs(shoelace) >= 0.6 * area)
        q = np.where((shoelace > 0)[:, None, None], q, q[:, ::-1])[ok]
        out.extend(q)
    if not out:
        return np.zeros((0, 4, 2))
    # One quad per marker: the windows find most markers more than once.
    allq = np.stack(out)
    centre = allq.mean(axis=1)
    span = np.ptp(allq, axis=1).max(axis=1)
    order = np.lexsort((centre[:, 1], centre[:, 0]))
    keep = np.ones(len(allq), dtype=bool)
    for i, a in enumerate(order):  # neighbours in x order only: a short scan per quad
        if not keep[a]:
            continue
        for b in order[i + 1:]:
            if centre[b, 0] - centre[a, 0] > 0.1 * span[a]:
                break
            if keep[b] and np.abs(allq[b] - allq[a]).max() < 0.05 * span[a] + 1.0:
                keep[b] = False
    return allq[keep]


#: Markers are looked for first at a level whose longer side is at most this (2x2 means), then
#: finer where that level reads too little; the corners are refined on the full image.
_MARKER_LEVEL_SIDE = 1600


def _detect(board: Charuco, image: np.ndarray) -> Detection:
    N = board.n_points
    full = _to_grey(image)
    levels = [(full, 1)]
    while max(levels[-1][0].shape) > _MARKER_LEVEL_SIDE:
        levels.append((_half(levels[-1][0]), levels[-1][1] * 2))
    d = board.aruco
    n_cells = d.marker_size + 2

    # 1-2. Markers: quads whose cells read as a code; each code's quads kept once (full-image
    # pixels). From the coarsest level down: a finer one is read where the coarse one gave
    # fewer than two markers or markers of under 2 px a cell across (bits blur together there).
    found: dict[int, list[np.ndarray]] = {}
    for g, factor in reversed(levels):
        quads = _quads(g, 2 * n_cells)  # two pixels a cell at least
        codes, turns = _read_markers(g, quads, d) if len(quads) else (np.zeros(0, np.int64), np.zeros(0, np.int64))
        level: dict[int, list[np.ndarray]] = {}
        for quad, code, k in zip(quads, codes, turns, strict=True):  # one entry per decoded quad
            if code < 0:
                continue
            # The code's corner j is the quad's corner (j - turns) % 4.
            corners = (quad[(np.arange(4) - k) % 4] + 0.5) * factor - 0.5
            span = float(np.ptp(corners, axis=0).max())
            same = level.setdefault(int(code), [])
            # One marker read at two windows: the same place (its centre within half its span).
            if not any(np.hypot(*(c.mean(axis=0) - corners.mean(axis=0))) < 0.5 * span for c in same):
                same.append(corners)
        if len(level) >= len(found):
            found = level  # the finer level's corners where it reads as much
        # A marker's narrowest side per cell, at this level.
        cells = [np.hypot(*np.diff(np.vstack([c[0], c[0][:1]]), axis=0).T).min() / factor / n_cells
                 for c in level.values()]
        if len(level) >= 2 and np.median(cells) >= 2.0:
            break
    # 3. Ids against the board: one marker per id, confirmed by a neighbour where it belongs.
    ms = board.marker_squares()
    obj = board.marker_corners()[:, :, :2]
    ids = [m for m, c in found.items() if m < len(ms) and len(c) == 1]
    if ids:
        hs = _fit_homographies(obj[ids], np.stack([found[m][0] for m in ids]))
        homs = {m: h for m, h in zip(ids, hs, strict=True) if np.isfinite(h).all()}
        ids = [m for m in ids if m in homs]
    else:
        homs = {}
    side_px = {m: np.sqrt(abs(0.5 * np.sum(found[m][0][:, 0] * np.roll(found[m][0][:, 1], -1)
                                         - np.roll(found[m][0][:, 0], -1) * found[m][0][:, 1])))
               * board.square / board.marker for m in ids}
    # Every pair of markers within two squares: one homography through both markers' eight
    # corners fits where both are where the layout puts them (perspective and distortion are
    # smooth over two squares).
    agree = dict.fromkeys(ids, 0)
    disagree = dict.fromkeys(ids, 0)
    pairs = [(m, j) for a, m in enumerate(ids) for j in ids[a + 1:] if np.abs(ms[j] - ms[m]).max() <= 2]
    if pairs:
        src = np.stack([np.concatenate([obj[m], obj[j]]) for m, j in pairs])
        dst = np.stack([np.concatenate([found[m][0], found[j][0]]) for m, j in pairs])
        worst = _homography_misfit(src, dst)
        for (m, j), w in zip(pairs, worst, strict=True):
            tol = max(2.0 * factor, 0.15 * min(side_px[m], side_px[j]))
            for a in (m, j):
                if w < tol:
                    agree[a] += 1
                else:
                    disagree[a] += 1
    confirmed = [m for m in ids if agree[m] >= 1 and agree[m] > disagree[m]]
    if not confirmed:
        why = ("no marker of the board" if not ids else
               f"{len(ids)} marker(s) of the board, none confirmed by a neighbour where the layout puts it")
        return Detection.not_found(N, f"not found: {why} (dictionary {board.dictionary})")
    # 4. Chessboard corners next to confirmed markers, predicted, then at their saddle points.
    sx = board.squares_x
    pred_sum = np.zeros((N, 2))
    pred_n = np.zeros(N)
    size = np.zeros(N)
    for m in confirmed:
        x, y = ms[m]
        for cx, cy in ((x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)):
            if 1 <= cx <= sx - 1 and 1 <= cy <= board.squares_y - 1:
                cid = (cy - 1) * (sx - 1) + (cx - 1)
                pred_sum[cid] += _apply(homs[m], np.array([[cx * board.square, cy * board.square]]))[0]
                pred_n[cid] += 1
                size[cid] = max(size[cid], side_px[m])
    cand = np.flatnonzero(pred_n > 0)
    pred = pred_sum[cand] / pred_n[cand, None]
    # Where two confirmed markers touch a corner (its four squares), the prediction is their
    # least-squares homography's (one marker's quad read a pixel off at a thin margin weighs
    # half; a wider neighbourhood bends away from a homography through a fisheye).
    conf_sq = ms[confirmed]
    for i, cid in enumerate(cand):  # one small fit per corner
        cx, cy = cid % (sx - 1) + 1, cid // (sx - 1) + 1
        near = [m for m, (x, y) in zip(confirmed, conf_sq, strict=True)
                if cx - 1 <= x <= cx and cy - 1 <= y <= cy]
        if len(near) >= 2:
            Hn = _fit_homography(np.concatenate([obj[m] for m in near]), np.concatenate([found[m][0] for m in near]))
            if Hn is not None:
                pred[i] = _apply(Hn, np.array([[cx * board.square, cy * board.square]]))[0]
    H, W = full.shape
    inside = (pred[:, 0] >= 2) & (pred[:, 0] <= W - 3) & (pred[:, 1] >= 2) & (pred[:, 1] <= H - 3)
    cand, pred = cand[inside], pred[inside]
    out = np.full((N, 2), np.nan)
    sig = np.full(N, np.nan)
    win = np.clip(np.round(size[cand] / 11.0), 2, 5 * factor).astype(int)
    for r in np.unique(win):  # one fit per window size
        k = win == r
        q, sg = _refine_patches(full, pred[k], int(r), 1.5 * factor)
        moved = np.hypot(*(q - pred[k]).T)
        ok = np.isfinite(moved) & np.isfinite(sg) & (moved <= np.maximum(1.5 * factor, 0.1 * size[cand[k]]))
        ok[ok] = _is_x_corner(full, q[ok], size[cand[k]][ok], board)
        out[cand[k][ok]] = q[ok]
        sig[cand[k][ok]] = sg[ok]
    good = np.isfinite(sig)
    if good.any():
        bad = good & (sig > 2.0 * np.median(sig[good]))
        out[bad] = np.nan
        sig[bad] = np.nan
    n_found = int(np.isfinite(out).all(axis=1).sum())
    if n_found == 0:
        return Detection.not_found(N, f"not found: {len(confirmed)} markers confirmed, but no corner beside them "
                                      "passes the saddle-point fit")
    window = int(np.median(win)) if len(win) else 0
    return Detection(True, out, sig, window,
                     f"found {n_found} of {N} corners from {len(confirmed)} markers (window {window} px)")
