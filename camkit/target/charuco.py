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
   board corners onto their eight image corners within 8 % of a square, 2 px at least) and
   contradicted by fewer than confirm it;
4. each chessboard corner next to a confirmed marker is predicted through the markers'
   homographies (averaged over the markers around it) and placed at the saddle point of the
   smoothed image (camkit's sub-pixel estimator, window an eleventh of the square's image
   size, 2 to 5 px), with its sigma; a corner that moves more than a fifth of a square, or
   whose fit is over twice the median sigma, is dropped.

A corner is returned only next to a confirmed marker, so a board half out of the frame gives
every corner it shows beside a marker that confirms another.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Self

import numpy as np

from camkit._kernels import detect as detect_kernels
from camkit._validate import as_positive_float, as_positive_int
from camkit.errors import ParameterError
from camkit.target.aruco import ArucoDictionary, get_dictionary
from camkit.target.base import Detection, Sheet, Target, register_target
from camkit.target.checkerboard import _saddle_fit, _sample, _to_grey

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


def _box_mean(g: np.ndarray, r: int) -> np.ndarray:
    """Mean of g over the (2r+1)^2 window around each pixel (clipped at the borders), from an
    integral image."""
    H, W = g.shape
    ii = np.zeros((H + 1, W + 1))
    ii[1:, 1:] = g.cumsum(axis=0).cumsum(axis=1)
    y0 = np.clip(np.arange(H) - r, 0, H)
    y1 = np.clip(np.arange(H) + r + 1, 0, H)
    x0 = np.clip(np.arange(W) - r, 0, W)
    x1 = np.clip(np.arange(W) + r + 1, 0, W)
    tot = ii[y1][:, x1] - ii[y0][:, x1] - ii[y1][:, x0] + ii[y0][:, x0]
    return tot / ((y1 - y0)[:, None] * (x1 - x0)[None, :])


def _quad(ys: np.ndarray, xs: np.ndarray) -> np.ndarray | None:
    """Four corners of a region (pixel coordinates), ordered clockwise in the image starting
    anywhere; None where it is not a quad (a corner missing)."""
    p = np.stack([xs, ys], axis=-1).astype(np.float64)
    c = p.mean(axis=0)
    a = p[np.argmax(((p - c) ** 2).sum(axis=1))]
    b = p[np.argmax(((p - a) ** 2).sum(axis=1))]
    d = b - a
    side = d[0] * (p[:, 1] - a[1]) - d[1] * (p[:, 0] - a[0])
    if side.max() <= 0 or side.min() >= 0:
        return None
    e, f = p[np.argmax(side)], p[np.argmin(side)]
    q = np.array([a, e, b, f])
    area = 0.5 * np.sum(q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1])
    if area < 0:
        q = q[::-1]
    # A quad, not a triangle or a blob: the four corners span most of the region's area.
    if abs(area) < 0.6 * len(xs):
        return None
    return q


def _homography(src: np.ndarray, dst: np.ndarray) -> np.ndarray | None:
    """The homography taking 4 points ``src`` (4, 2) to ``dst`` (4, 2) (8 x 8 linear system)."""
    A = np.zeros((8, 8))
    b = np.zeros(8)
    for i in range(4):  # four correspondences: the rows of the system
        x, y = src[i]
        u, v = dst[i]
        A[2 * i] = [x, y, 1, 0, 0, 0, -u * x, -u * y]
        A[2 * i + 1] = [0, 0, 0, x, y, 1, -v * x, -v * y]
        b[2 * i], b[2 * i + 1] = u, v
    try:
        h = np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return None
    return np.append(h, 1.0).reshape(3, 3)


def _fit_homography(src: np.ndarray, dst: np.ndarray) -> np.ndarray | None:
    """Least-squares homography (normalised DLT) taking ``src`` (K, 2) to ``dst`` (K, 2)."""
    def norm(p):
        c = p.mean(axis=0)
        d = np.sqrt(((p - c) ** 2).sum(axis=1)).mean()
        if d < 1e-12:
            return None
        k = np.sqrt(2.0) / d
        return np.array([[k, 0, -k * c[0]], [0, k, -k * c[1]], [0, 0, 1.0]])

    Ts, Td = norm(src), norm(dst)
    if Ts is None or Td is None:
        return None
    a, b = _apply(Ts, src), _apply(Td, dst)
    K = len(a)
    A = np.zeros((2 * K, 9))
    A[0::2, 0:2], A[0::2, 2] = a, 1.0
    A[0::2, 6:8], A[0::2, 8] = -b[:, :1] * a, -b[:, 0]
    A[1::2, 3:5], A[1::2, 5] = a, 1.0
    A[1::2, 6:8], A[1::2, 8] = -b[:, 1:2] * a, -b[:, 1]
    h = np.linalg.svd(A)[2][-1].reshape(3, 3)
    return np.linalg.solve(Td, h @ Ts)


def _apply(H: np.ndarray, p: np.ndarray) -> np.ndarray:
    q = np.c_[p, np.ones(len(p))] @ H.T
    return q[:, :2] / q[:, 2:]


def _read_marker(g: np.ndarray, quad: np.ndarray, d: ArucoDictionary) -> tuple[int, int] | None:
    """``(code id, turns)`` of the marker in ``quad`` (clockwise corners), or None."""
    n = d.marker_size + 2
    H = _homography(np.array([[0.0, 0.0], [n, 0.0], [n, n], [0.0, n]]), quad)
    if H is None:
        return None
    ov, ou = np.meshgrid([0.3, 0.5, 0.7], [0.3, 0.5, 0.7], indexing="ij")  # 3 x 3 in each cell's middle
    cy, cx = np.mgrid[0:n, 0:n]
    uu = (cx[:, :, None] + ou.ravel()).ravel()
    vv = (cy[:, :, None] + ov.ravel()).ravel()
    px = _apply(H, np.stack([uu, vv], axis=-1))
    vals = _sample(g, px[:, 0], px[:, 1], "bilinear").reshape(n, n, 9).mean(axis=2)
    # The white margin around the marker: half a cell outside each side's middle.
    ring = np.array([[n / 2, -0.5], [n + 0.5, n / 2], [n / 2, n + 0.5], [-0.5, n / 2]])
    white = float(np.median(_sample(g, *_apply(H, ring).T, "bilinear")))
    border = np.concatenate([vals[0], vals[-1], vals[1:-1, 0], vals[1:-1, -1]])
    black = float(np.median(border))
    if not white - black > 0.15:
        return None
    t = 0.5 * (white + black)
    if np.mean(border < t) < 0.85:
        return None
    found = d.identify((vals[1:-1, 1:-1] > t).astype(np.uint8))
    return None if found is None else found[:2]


def _detect(board: Charuco, image: np.ndarray) -> Detection:
    N = board.n_points
    g = _to_grey(image)
    H, W = g.shape
    d = board.aruco
    from scipy import ndimage

    # 1-2. Marker candidates at three threshold windows; each decoded quad kept once.
    found: dict[int, list[np.ndarray]] = {}
    n_cells = d.marker_size + 2
    min_side = 2 * n_cells  # two pixels a cell at least
    for r in sorted({max(3, min(H, W) // k) for k in (80, 30, 12)}):
        dark = g < _box_mean(g, r) - 0.03
        labels, n = ndimage.label(dark)
        if n == 0:
            continue
        areas = np.bincount(labels.ravel(), minlength=n + 1)[1:]
        for k, sl in enumerate(ndimage.find_objects(labels)):  # one region at a time (quad fit)
            if sl is None or not (min_side * min_side * 0.5 <= areas[k] <= 0.25 * H * W):
                continue
            h, w = sl[0].stop - sl[0].start, sl[1].stop - sl[1].start
            if min(h, w) < min_side or max(h, w) > 8 * min(h, w):
                continue
            ys, xs = np.nonzero(labels[sl] == k + 1)
            quad = _quad(ys + sl[0].start, xs + sl[1].start)
            if quad is None:
                continue
            got = _read_marker(g, quad, d)
            if got is None:
                continue
            code, turns = got
            # The code's corner j is the quad's corner (j - turns) % 4.
            corners = quad[(np.arange(4) - turns) % 4]
            same = found.setdefault(code, [])
            if not any(np.abs(c - corners).max() < 0.2 * np.sqrt(areas[k]) for c in same):
                same.append(corners)
    # 3. Ids against the board: one marker per id, confirmed by a neighbour where it belongs.
    ms = board.marker_squares()
    obj = board.marker_corners()[:, :, :2]
    ids = [m for m, c in found.items() if m < len(ms) and len(c) == 1]
    homs = {m: _homography(obj[m], found[m][0]) for m in ids}
    ids = [m for m in ids if homs[m] is not None]
    side_px = {m: np.sqrt(abs(0.5 * np.sum(found[m][0][:, 0] * np.roll(found[m][0][:, 1], -1)
                                         - np.roll(found[m][0][:, 0], -1) * found[m][0][:, 1])))
               * board.square / board.marker for m in ids}
    confirmed = []
    for m in ids:
        agree = disagree = 0
        for j in ids:
            if j == m or np.abs(ms[j] - ms[m]).max() > 2:
                continue
            # Both markers where the layout puts them: one homography through their eight
            # corners fits (perspective and distortion are smooth over two squares).
            src = np.concatenate([obj[m], obj[j]])
            dst = np.concatenate([found[m][0], found[j][0]])
            Hmj = _fit_homography(src, dst)
            worst = np.inf if Hmj is None else float(np.hypot(*(_apply(Hmj, src) - dst).T).max())
            if worst < max(2.0, 0.08 * min(side_px[m], side_px[j])):
                agree += 1
            else:
                disagree += 1
        if agree >= 1 and agree > disagree:
            confirmed.append(m)
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
    inside = (pred[:, 0] >= 2) & (pred[:, 0] <= W - 3) & (pred[:, 1] >= 2) & (pred[:, 1] <= H - 3)
    cand, pred = cand[inside], pred[inside]
    s = np.empty_like(g)
    detect_kernels.gaussian_blur(g, 1.5, s)
    out = np.full((N, 2), np.nan)
    sig = np.full(N, np.nan)
    win = np.clip(np.round(size[cand] / 11.0), 2, 5).astype(int)
    for r in np.unique(win):  # one fit per window size (at most four)
        k = win == r
        q, sg = _saddle_fit(s, pred[k], int(r))
        moved = np.hypot(*(q - pred[k]).T)
        ok = np.isfinite(moved) & np.isfinite(sg) & (moved <= 0.2 * size[cand[k]])
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
