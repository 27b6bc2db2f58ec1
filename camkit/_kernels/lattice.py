"""Kernels for the checkerboard's lattice: growing it from a seed corner, checking each corner
against its neighbours, reading what lies past its sides.

A lattice lives in a grid ``G`` of candidate indices (-1 where empty), ``G[a, b]`` holding the
corner at lattice position (a, b). Local maps from lattice to image are the quadratic (or, with
too few neighbours, affine) polynomials of ``calib.detect``: terms 1, a, b, a^2, ab, b^2 in
lattice coordinates relative to the position being predicted or checked.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from camkit._kernels.remap import keys4

#: A seed's edge neighbours are looked for up to this many times its neighbour spacing (the
#: median distance to its four nearest corners). Under a steep tilt the four nearest all lie
#: along the foreshortened axis, one and two steps away, and the step along the other axis is
#: two to three times their median.
_SEED_REACH = 3.5
#: How many of the seed's nearest corners are tried as its row and column neighbours.
_SEED_NEAREST = 12
_COS20 = math.cos(math.radians(20.0))


@njit(cache=True, nogil=True, error_model="numpy")
def bilinear(img: np.ndarray, x: float, y: float) -> float:  # pragma: no cover - numba
    """Bilinear sample at (x, y), pixel centres at integers, edge pixels replicated."""
    H, W = img.shape
    fx, fy = math.floor(x), math.floor(y)
    tx, ty = x - fx, y - fy
    x0 = min(max(int(fx), 0), W - 1)
    x1 = min(max(int(fx) + 1, 0), W - 1)
    y0 = min(max(int(fy), 0), H - 1)
    y1 = min(max(int(fy) + 1, 0), H - 1)
    top = img[y0, x0] * (1.0 - tx) + img[y0, x1] * tx
    bot = img[y1, x0] * (1.0 - tx) + img[y1, x1] * tx
    return top * (1.0 - ty) + bot * ty


@njit(cache=True, nogil=True, error_model="numpy")
def sample_points(img: np.ndarray, x: np.ndarray, y: np.ndarray, cubic: bool,
                  out: np.ndarray) -> None:  # pragma: no cover - numba
    """``out[i]`` = the image at (x[i], y[i]): bilinear, or bicubic (Keys, a = -0.5, as
    ``resample.remap``'s default), edge pixels replicated."""
    H, W = img.shape
    for i in range(x.shape[0]):
        if not cubic:
            out[i] = bilinear(img, x[i], y[i])
            continue
        fx, fy = math.floor(x[i]), math.floor(y[i])
        wx = keys4(x[i] - fx, -0.5)
        wy = keys4(y[i] - fy, -0.5)
        acc = 0.0
        for j in range(4):
            yy = min(max(int(fy) - 1 + j, 0), H - 1)
            row = 0.0
            for m in range(4):
                xx = min(max(int(fx) - 1 + m, 0), W - 1)
                row += wx[m] * img[yy, xx]
            acc += wy[j] * row
        out[i] = acc


@njit(cache=True, nogil=True, error_model="numpy")
def _members(G: np.ndarray, pts: np.ndarray, a: int, b: int, reach: int, exclude: bool, rel: np.ndarray,
             P: np.ndarray) -> tuple[int, int, int]:  # pragma: no cover - numba
    """The members of ``G`` within ``reach`` of (a, b) (without (a, b) itself if ``exclude``):
    their lattice offsets from (a, b) into ``rel`` and image places into ``P``; returns their
    number and how many steps they span along either axis."""
    S0, S1 = G.shape
    m = 0
    lo_a, hi_a, lo_b, hi_b = reach + 1, -reach - 1, reach + 1, -reach - 1
    for da in range(-reach, reach + 1):
        for db in range(-reach, reach + 1):
            if exclude and da == 0 and db == 0:
                continue
            aa, bb = a + da, b + db
            if aa < 0 or bb < 0 or aa >= S0 or bb >= S1 or G[aa, bb] < 0:
                continue
            k = G[aa, bb]
            rel[m, 0], rel[m, 1] = da, db
            P[m, 0], P[m, 1] = pts[k, 0], pts[k, 1]
            lo_a, hi_a = min(lo_a, da), max(hi_a, da)
            lo_b, hi_b = min(lo_b, db), max(hi_b, db)
            m += 1
    return m, hi_a - lo_a, hi_b - lo_b


@njit(cache=True, nogil=True, error_model="numpy")
def local_fit(G: np.ndarray, pts: np.ndarray, a: int, b: int, reach: int, exclude: bool, min_count: int,
              coef: np.ndarray) -> int:  # pragma: no cover - numba
    """Fit the map lattice -> image on the members of ``G`` within ``reach`` of (a, b) (without
    (a, b) itself if ``exclude``), in coordinates relative to (a, b). Writes the (6, 2)
    coefficients into ``coef`` (the quadratic terms zero for an affine fit) and returns 2 for a
    quadratic fit (seven or more members spanning two steps on both axes), 1 for an affine one
    (``min_count`` or more members spanning a step on both axes), 0 where they do not pin a map
    down."""
    rel = np.empty(((2 * reach + 1) ** 2, 2))
    P = np.empty(((2 * reach + 1) ** 2, 2))
    m, span_a, span_b = _members(G, pts, a, b, reach, exclude, rel, P)
    if m < min_count or span_a < 1 or span_b < 1:
        return 0
    quadratic = m >= 7 and span_a >= 2 and span_b >= 2
    nt = 6 if quadratic else 3
    A = np.empty((m, nt))
    for i in range(m):
        da, db = rel[i, 0], rel[i, 1]
        A[i, 0] = 1.0
        A[i, 1] = da
        A[i, 2] = db
        if quadratic:
            A[i, 3] = da * da
            A[i, 4] = da * db
            A[i, 5] = db * db
    coef[:] = 0.0
    if not _normal_solve(A, P, m, nt, coef):
        # The members lie on a curve of the fit's own kind (a row and a column for the
        # quadratic terms): no unique fit. The least-squares solution of least norm, as before.
        coef[:nt] = np.linalg.lstsq(A, np.ascontiguousarray(P[:m]))[0]
    return 2 if quadratic else 1


@njit(cache=True, nogil=True, error_model="numpy")
def _normal_solve(A: np.ndarray, P: np.ndarray, m: int, nt: int,
                  coef: np.ndarray) -> bool:  # pragma: no cover - numba
    """The least-squares solution of ``A[:m] @ coef[:nt] = P[:m]`` (two right-hand sides)
    through the normal equations and their Cholesky factor, written into ``coef``; False
    (``coef`` untouched) where a pivot falls below 1e-9 of the largest diagonal term. The
    designs of :func:`local_fit` hold small integer lattice offsets, so they are either
    deficient (a zero pivot, up to rounding) or well conditioned, and the normal equations
    lose nothing there that a QR or SVD solution would keep (the cost of numba's LAPACK
    wrappers for so few unknowns: benchmarks/notes.md, forty-eighth session)."""
    N = np.zeros((nt, nt))
    r = np.zeros((nt, 2))
    for i in range(m):
        for p in range(nt):
            r[p, 0] += A[i, p] * P[i, 0]
            r[p, 1] += A[i, p] * P[i, 1]
            for q in range(p + 1):
                N[p, q] += A[i, p] * A[i, q]
    top = 0.0
    for p in range(nt):
        top = max(top, N[p, p])
    L = np.zeros((nt, nt))
    for p in range(nt):
        for q in range(p + 1):
            acc = N[p, q]
            for k in range(q):
                acc -= L[p, k] * L[q, k]
            if p == q:
                if not acc > 1e-9 * top:
                    return False
                L[p, p] = math.sqrt(acc)
            else:
                L[p, q] = acc / L[q, q]
    for c in range(2):  # L y = r, then L^T x = y
        y = np.empty(nt)
        for p in range(nt):
            acc = r[p, c]
            for k in range(p):
                acc -= L[p, k] * y[k]
            y[p] = acc / L[p, p]
        for p in range(nt - 1, -1, -1):
            acc = y[p]
            for k in range(p + 1, nt):
                acc -= L[k, p] * coef[k, c]
            coef[p, c] = acc / L[p, p]
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _one_line_and_a_point(rel: np.ndarray, m: int) -> bool:  # pragma: no cover - numba
    """Whether all but at most one of the ``m`` lattice offsets in ``rel`` lie on one line:
    then no four are in general position and a homography through them is not fixed (its
    null space has two dimensions or more). Such a line holds two of any three members, so it
    is one of the lines through two of the first three."""
    for i, j in ((0, 1), (0, 2), (1, 2)):
        ux, uy = rel[j, 0] - rel[i, 0], rel[j, 1] - rel[i, 1]
        off = 0
        for k in range(m):
            if ux * (rel[k, 1] - rel[i, 1]) - uy * (rel[k, 0] - rel[i, 0]) != 0.0:
                off += 1
        if off <= 1:
            return True
    return False


@njit(cache=True, nogil=True, error_model="numpy")
def local_homography(G: np.ndarray, pts: np.ndarray, a: int, b: int, reach: int,
                     out: np.ndarray) -> bool:  # pragma: no cover - numba
    """The homography lattice -> image fitted (normalised DLT) on the members of ``G`` within
    ``reach`` of (a, b), (a, b) itself excluded, in coordinates relative to it: writes the
    predicted place and the lengths of a step along either lattice axis there into ``out``
    (x, y, step_a, step_b) and returns True, or False where fewer than five members span a
    step on both axes, all but one lie on a line (a homography is then not fixed), or the
    fit is degenerate. Unlike a polynomial, it follows the steps' shrinking or growing
    towards a vanishing point, which a plane seen through a pinhole shows exactly and a
    fisheye's rim locally."""
    rel = np.empty(((2 * reach + 1) ** 2, 2))
    P = np.empty(((2 * reach + 1) ** 2, 2))
    m, span_a, span_b = _members(G, pts, a, b, reach, True, rel, P)
    if m < 5 or span_a < 1 or span_b < 1:
        return False
    mx, my, sc = 0.0, 0.0, 0.0
    for i in range(m):
        mx += P[i, 0] / m
        my += P[i, 1] / m
    for i in range(m):
        sc += math.hypot(P[i, 0] - mx, P[i, 1] - my) / m
    if not sc > 0:
        return False
    if _one_line_and_a_point(rel, m):
        return False
    # The DLT's null vector: the eigenvector of M^T M of least eigenvalue (M: two rows per
    # member), the right singular vector of M that an SVD of M gives, to rounding (the SVD's
    # cost: benchmarks/notes.md, forty-eighth session). M^T M is accumulated without forming M.
    N = np.zeros((9, 9))
    row = np.empty(9)
    for i in range(m):
        u, v = rel[i, 0], rel[i, 1]
        for w in range(2):
            c = ((P[i, 0] - mx) if w == 0 else (P[i, 1] - my)) / sc
            row[:] = 0.0
            row[3 * w], row[3 * w + 1], row[3 * w + 2] = u, v, 1.0
            row[6], row[7], row[8] = -c * u, -c * v, -c
            for p in range(9):
                if row[p] != 0.0:
                    for q in range(9):
                        N[p, q] += row[p] * row[q]
    h = np.linalg.eigh(N)[1][:, 0]
    if not abs(h[8]) > 1e-12:
        return False
    x0, y0 = h[2] / h[8], h[5] / h[8]
    # d(x, y)/d(a) and d(x, y)/d(b) at the relative origin, back in pixels.
    sa = sc * math.hypot((h[0] - x0 * h[6]) / h[8], (h[3] - y0 * h[6]) / h[8])
    sb = sc * math.hypot((h[1] - x0 * h[7]) / h[8], (h[4] - y0 * h[7]) / h[8])
    out[0], out[1], out[2], out[3] = mx + sc * x0, my + sc * y0, sa, sb
    return math.isfinite(out[0]) and math.isfinite(out[1]) and sa > 0 and sb > 0


@njit(cache=True, nogil=True, error_model="numpy")
def _nearest(pts: np.ndarray, x: float, y: float) -> tuple[int, float]:  # pragma: no cover - numba
    best, bd = -1, np.inf
    for k in range(pts.shape[0]):
        d = (pts[k, 0] - x) ** 2 + (pts[k, 1] - y) ** 2
        if d < bd:
            best, bd = k, d
    return best, math.sqrt(bd)


@njit(cache=True, nogil=True, error_model="numpy")
def neighbour_spacing(pts: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
    """Median distance from each point to its four nearest others (1 where it has none)."""
    n = pts.shape[0]
    if n < 2:
        out[:] = 1.0
        return
    k = min(4, n - 1)
    d = np.empty(n)
    for i in range(n):
        for j in range(n):
            d[j] = math.hypot(pts[j, 0] - pts[i, 0], pts[j, 1] - pts[i, 1])
        d[i] = np.inf
        out[i] = np.median(np.sort(d)[:k])


@njit(cache=True, nogil=True, error_model="numpy")
def _edge_shades(img: np.ndarray, x0: float, y0: float, x1: float, y1: float, ox: float,
                 oy: float) -> tuple[float, float, float]:  # pragma: no cover - numba
    """The shade at ``(ox, oy)`` beside the link from (x0, y0) to (x1, y1) less the shade at
    ``-(ox, oy)``, a quarter, a half and three quarters along it: the test of
    :func:`_seed_cross` and :func:`_links_along_edges` that a link runs along an edge."""
    d = [0.0, 0.0, 0.0]
    for i in range(3):
        f = 0.25 * (i + 1)
        mx, my = x0 + f * (x1 - x0), y0 + f * (y1 - y0)
        d[i] = bilinear(img, mx + ox, my + oy) - bilinear(img, mx - ox, my - oy)
    return d[0], d[1], d[2]


@njit(cache=True, nogil=True, error_model="numpy")
def _seed_cross(pts: np.ndarray, seed: int, a1: int, a2: int, b1: int, b2: int, img: np.ndarray,
                contrast: float, offset: float) -> bool:  # pragma: no cover - numba
    """Whether ``a1 - seed - a2`` and ``b1 - seed - b2`` are a row and a column of a checker
    lattice through ``seed``: the two lines cross at 20 degrees or more, and each of the four
    links runs along an edge between a black and a white square. The shade is taken ``offset``
    (three tenths for a plain checkerboard; less where the white squares hold markers) of the
    other line's step either side of the link at a quarter, a half and three
    quarters of its length (inside the two squares beside the edge), and must differ by 0.4 of
    the seed's ``contrast``, the same way round each time. A diagonal link's middle is a
    square's centre, with the same shade either side, and fails; so does a link two steps long,
    whose middle is a corner, and a link across a square to a corner one column and two rows on
    (a sheared basis of the same corners: its middle lies on an edge, its quarter points do
    not)."""
    ax = 0.5 * (pts[a1, 0] - pts[a2, 0])
    ay = 0.5 * (pts[a1, 1] - pts[a2, 1])
    bx = 0.5 * (pts[b1, 0] - pts[b2, 0])
    by = 0.5 * (pts[b1, 1] - pts[b2, 1])
    na, nb = math.hypot(ax, ay), math.hypot(bx, by)
    if abs(ax * bx + ay * by) > _COS20 * na * nb:
        return False
    sx, sy = pts[seed, 0], pts[seed, 1]
    for t in range(4):
        k = a1 if t == 0 else a2 if t == 1 else b1 if t == 2 else b2
        ox, oy = (bx, by) if t < 2 else (ax, ay)
        first = 0.0
        for diff in _edge_shades(img, sx, sy, pts[k, 0], pts[k, 1], offset * ox, offset * oy):
            if abs(diff) < 0.4 * contrast or diff * first < 0:
                return False
            first = diff
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _diamond_homography(pts: np.ndarray, a1: int, a2: int, b1: int, b2: int,
                        h: np.ndarray) -> bool:  # pragma: no cover - numba
    """``h`` (8: the homography's first eight entries, the ninth 1) that maps lattice positions
    (1, 0), (-1, 0), (0, 1), (0, -1) about a seed to the corners ``a1``, ``a2``, ``b1``,
    ``b2``; False where those four leave it undetermined (three on a line)."""
    A = np.zeros((8, 8))
    r = np.empty(8)
    for i in range(4):
        k = a1 if i == 0 else a2 if i == 1 else b1 if i == 2 else b2
        u = 1.0 if i == 0 else -1.0 if i == 1 else 0.0
        v = 1.0 if i == 2 else -1.0 if i == 3 else 0.0
        x, y = pts[k, 0], pts[k, 1]
        A[2 * i, 0], A[2 * i, 1], A[2 * i, 2], A[2 * i, 6], A[2 * i, 7] = u, v, 1.0, -u * x, -v * x
        A[2 * i + 1, 3], A[2 * i + 1, 4], A[2 * i + 1, 5], A[2 * i + 1, 6], A[2 * i + 1, 7] = u, v, 1.0, -u * y, -v * y
        r[2 * i], r[2 * i + 1] = x, y
    return _solve_lu(A, r, h)


@njit(cache=True, nogil=True, error_model="numpy")
def _seed_diagonals(pts: np.ndarray, used: np.ndarray, taken: np.ndarray, seed: int, R: int,
                    G: np.ndarray) -> int:  # pragma: no cover - numba
    """Put the seed's diagonal neighbours into ``G`` where its edge neighbours place them (within
    a third of a step) and return how many were there: the parallelogram of the seed and two
    of them (exact for an affine view), else the homography of the four
    (:func:`_diamond_homography`, exact for a plane seen in perspective). On a board seen
    steeply, its steps shrinking by a third from one row to the next, the parallelogram missed
    by more than a third of the shorter step; under a lens the homography can miss where the
    parallelogram does not (benchmarks/notes.md, forty-ninth session)."""
    found = 0
    h = np.empty(8)
    proj = _diamond_homography(pts, G[R + 1, R], G[R - 1, R], G[R, R + 1], G[R, R - 1], h)
    for da in (1, -1):
        for db in (1, -1):
            ka, kb = G[R + da, R], G[R, R + db]
            step = min(math.hypot(pts[ka, 0] - pts[seed, 0], pts[ka, 1] - pts[seed, 1]),
                       math.hypot(pts[kb, 0] - pts[seed, 0], pts[kb, 1] - pts[seed, 1]))
            k, dist = _nearest(pts, pts[ka, 0] + pts[kb, 0] - pts[seed, 0], pts[ka, 1] + pts[kb, 1] - pts[seed, 1])
            if proj and not dist <= step / 3.0:
                den = h[6] * da + h[7] * db + 1.0
                if den > 0.0:
                    k, dist = _nearest(pts, (h[0] * da + h[1] * db + h[2]) / den, (h[3] * da + h[4] * db + h[5]) / den)
            if dist <= step / 3.0 and not taken[k] and not used[k]:
                G[R + da, R + db] = k
                taken[k] = True
                found += 1
    return found


_EDGE_STEPS = ((1, 0), (-1, 0), (0, 1), (0, -1))
#: A grown link's shades either side must differ by this fraction of its corners' contrast.
_LINK_CONTRAST = 0.2


@njit(cache=True, nogil=True, error_model="numpy")
def _links_along_edges(pts: np.ndarray, G: np.ndarray, img: np.ndarray, contrast: np.ndarray, k: int, a: int,
                       b: int, coef: np.ndarray, sign0: float, R: int,
                       offset: float) -> bool:  # pragma: no cover - numba
    """Whether candidate ``k``, taken at lattice position (a, b), is linked to each of its edge
    neighbours already in ``G`` along an edge between a black and a white square, the right
    way round: a quarter, a half and three quarters along the link, the shades ``offset`` of
    the other axis's step (``coef``'s, the local map at (a, b)) either side differ by a fifth
    of the two corners' lower contrast, with the sign the checker's alternation gives (``sign0``:
    the sign across the seed's edges, the seed at (R, R)). A corner of another pattern beside
    the board (a second board past a narrow margin, a sheet over the board) that happens to lie
    where the lattice's next corner would is not joined to it: its link crosses squares, not
    along an edge, or the edge's colours are the wrong way round."""
    for t in range(4):
        da, db = _EDGE_STEPS[t]
        aa, bb = a + da, b + db
        if not (0 <= aa < G.shape[0] and 0 <= bb < G.shape[1]) or G[aa, bb] < 0:
            continue
        m = G[aa, bb]
        # The square on the + side of the edge (+b for a link along a, +a for one along b)
        # starts at the edge's lower end; its colour alternates with a + b.
        lo = min(a, aa) + b if da != 0 else a + min(b, bb)
        want = sign0 if (lo - 2 * R) % 2 == 0 else -sign0
        ox, oy = (coef[2, 0], coef[2, 1]) if da != 0 else (coef[1, 0], coef[1, 1])
        ox, oy = offset * ox, offset * oy
        thr = _LINK_CONTRAST * min(contrast[k], contrast[m])
        for diff in _edge_shades(img, pts[m, 0], pts[m, 1], pts[k, 0], pts[k, 1], ox, oy):
            if diff * want < thr:
                return False
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def grow(pts: np.ndarray, spacing: np.ndarray, used: np.ndarray, img: np.ndarray, contrast: np.ndarray, seed: int,
         G: np.ndarray, offset: float) -> int:  # pragma: no cover - numba
    """Grow a lattice from corner ``seed`` into ``G`` (square, odd side; the seed at its centre)
    and return how many corners it holds (1 where the seed's neighbourhood fails its checks).

    The seed's four edge neighbours come first: among its twelve nearest free candidates
    (0.3 to 3.5 of its ``spacing`` away), pairs nearly opposite through the seed are lines
    through it, and the shortest two lines that pass :func:`_seed_cross` (``offset``; each link runs along
    an edge between a black and a white square) and put three of the four diagonal neighbours
    where a corner is (within a third of a step of where the parallelogram of the seed and
    two of them, or the homography of the four, puts them: :func:`_seed_diagonals`) are its
    row and column. No direction measured at the corner itself is needed: under a steep tilt
    or at a fisheye's rim the profile circle's edge directions are 20 degrees off or more.
    Then position after position next to the lattice is predicted from the members within
    two steps (quadratic or
    affine map, else the straight continuation of a row or column) and takes the candidate
    nearest the prediction if it lies within a third of the local step, is free and, where
    the position has a map, is linked to each neighbour already in the lattice along an edge
    the right way round (:func:`_links_along_edges`); where two positions want one candidate,
    the nearer wins. ``contrast``: each candidate's (its profile circle's range). Where five or more members fix a local
    homography (:func:`local_homography`), it predicts the position too: it takes over where
    the polynomial finds no candidate (steps that shrink or grow from one to the next, towards
    a vanishing point or a fisheye's rim, which a polynomial extrapolates badly), and where
    the two predictions take different candidates the position is left for a later round (a
    rim's displaced junction one square along a row is nearer the polynomial's prediction
    than the corner itself: real fisheye view 20). A position is tried again only when it
    has gained neighbours to predict it from."""
    n = pts.shape[0]
    S = G.shape[0]
    R = S // 2
    G[:] = -1
    taken = np.zeros(n, dtype=np.bool_)
    G[R, R] = seed
    taken[seed] = True
    d = np.empty(n)
    for j in range(n):
        d[j] = math.hypot(pts[j, 0] - pts[seed, 0], pts[j, 1] - pts[seed, 1])
    order = np.argsort(d, kind="mergesort")
    # Candidate links: the nearest free corners, in pairs through the seed (one step either way
    # along a row or column: the two vectors nearly opposite), shortest pairs first.
    m = 0
    near = np.empty(_SEED_NEAREST, dtype=np.int64)
    for ii in range(1, n):
        k = order[ii]
        if d[k] >= _SEED_REACH * spacing[seed] or m == _SEED_NEAREST:
            break
        if d[k] > 0.3 * spacing[seed] and not taken[k] and not used[k]:
            near[m] = k
            m += 1
    pa = np.empty(m * m, dtype=np.int64)
    pb = np.empty(m * m, dtype=np.int64)
    plen = np.empty(m * m)
    n_pairs = 0
    sx, sy = pts[seed, 0], pts[seed, 1]
    for i in range(m):
        for j in range(i + 1, m):
            a, b = near[i], near[j]
            ux, uy = pts[a, 0] - sx, pts[a, 1] - sy
            vx, vy = pts[b, 0] - sx, pts[b, 1] - sy
            mean = 0.5 * (d[a] + d[b])
            if ux * vx + uy * vy < 0 and math.hypot(ux + vx, uy + vy) <= 0.4 * mean:
                pa[n_pairs], pb[n_pairs], plen[n_pairs] = a, b, d[a] + d[b]
                n_pairs += 1
    porder = np.argsort(plen[:n_pairs], kind="mergesort")
    found_diag = 0
    for i1 in range(n_pairs):
        for i2 in range(i1 + 1, n_pairs):
            p, q = porder[i1], porder[i2]
            if _seed_cross(pts, seed, pa[p], pb[p], pa[q], pb[q], img, contrast[seed], offset):
                G[R + 1, R], G[R - 1, R], G[R, R + 1], G[R, R - 1] = pa[p], pb[p], pa[q], pb[q]
                for k in (pa[p], pb[p], pa[q], pb[q]):
                    taken[k] = True
                found_diag = _seed_diagonals(pts, used, taken, seed, R, G)
                if found_diag >= 3:
                    break
                for aa in range(R - 1, R + 2):
                    for bb in range(R - 1, R + 2):
                        if G[aa, bb] >= 0 and G[aa, bb] != seed:
                            taken[G[aa, bb]] = False
                        G[aa, bb] = -1
                G[R, R] = seed
        if found_diag >= 3:
            break
    if found_diag < 3:
        return 1
    count = 5 + found_diag
    # The sign of the shade across the seed's edges, + side minus - side (the square (R, R) to
    # (R + 1, R + 1) against its neighbour towards -b): the alternation fixes it on every edge.
    ka, kb = G[R + 1, R], G[R, R + 1]
    cx = pts[seed, 0] + 0.5 * (pts[ka, 0] - pts[seed, 0]) + 0.5 * (pts[kb, 0] - pts[seed, 0])
    cy = pts[seed, 1] + 0.5 * (pts[ka, 1] - pts[seed, 1]) + 0.5 * (pts[kb, 1] - pts[seed, 1])
    sign0 = 1.0 if bilinear(img, cx, cy) > bilinear(img, cx - (pts[kb, 0] - pts[seed, 0]),
                                                    cy - (pts[kb, 1] - pts[seed, 1])) else -1.0
    tried = np.full((S, S), -1, dtype=np.int64)
    claim_d = np.empty(n)
    claim_a = np.empty(n, dtype=np.int64)
    claim_b = np.empty(n, dtype=np.int64)
    coef = np.empty((6, 2))
    hom = np.empty(4)
    grew = True
    while grew:
        grew = False
        claim_d[:] = np.inf
        for a in range(S):
            for b in range(S):
                if G[a, b] >= 0:
                    continue
                edge = False
                for t in range(4):
                    aa, bb = a + _EDGE_STEPS[t][0], b + _EDGE_STEPS[t][1]
                    if 0 <= aa < S and 0 <= bb < S and G[aa, bb] >= 0:
                        edge = True
                if not edge:
                    continue
                n_near = 0
                for da in range(-2, 3):
                    for db in range(-2, 3):
                        aa, bb = a + da, b + db
                        if 0 <= aa < S and 0 <= bb < S and G[aa, bb] >= 0:
                            n_near += 1
                if tried[a, b] == n_near:
                    continue  # nothing new to predict it from
                tried[a, b] = n_near
                kind = local_fit(G, pts, a, b, 2, True, 3, coef)
                if kind > 0:
                    px, py = coef[0, 0], coef[0, 1]
                    step = min(math.hypot(coef[1, 0], coef[1, 1]), math.hypot(coef[2, 0], coef[2, 1]))
                else:  # the straight continuation of a row or column
                    step = -1.0
                    for t in range(4):
                        da, db = _EDGE_STEPS[t]
                        a1, b1, a2, b2 = a - da, b - db, a - 2 * da, b - 2 * db
                        if 0 <= a2 < S and 0 <= b2 < S and 0 <= a1 < S and 0 <= b1 < S \
                                and G[a1, b1] >= 0 and G[a2, b2] >= 0:
                            p1, p2 = G[a1, b1], G[a2, b2]
                            ex, ey = pts[p1, 0] - pts[p2, 0], pts[p1, 1] - pts[p2, 1]
                            px, py = pts[p1, 0] + ex, pts[p1, 1] + ey
                            step = math.hypot(ex, ey)
                            break
                    if step < 0:
                        continue
                k, dist = _nearest(pts, px, py)
                if local_homography(G, pts, a, b, 2, hom):  # a second prediction, by a homography
                    kh, dh = _nearest(pts, hom[0], hom[1])
                    sh = min(hom[2], hom[3])
                    if dist <= step / 3.0:
                        if dh <= sh / 3.0 and kh != k:
                            continue
                    else:
                        k, dist, step = kh, dh, sh
                if not dist <= step / 3.0 or taken[k] or used[k]:
                    continue
                if kind > 0 and not _links_along_edges(pts, G, img, contrast, k, a, b, coef, sign0, R, offset):
                    continue
                if dist < claim_d[k]:
                    claim_d[k] = dist
                    claim_a[k] = a
                    claim_b[k] = b
        for k in range(n):
            if claim_d[k] < np.inf:
                G[claim_a[k], claim_b[k]] = k
                taken[k] = True
                count += 1
                grew = True
    return count


@njit(cache=True, nogil=True, error_model="numpy")
def assemble(pts: np.ndarray, img: np.ndarray, contrast: np.ndarray, order: np.ndarray, side: int,
             owner: np.ndarray, coord: np.ndarray, offset: float) -> int:  # pragma: no cover - numba
    """Grow lattices (:func:`grow`, in a grid of ``side``, ``offset`` for its edge test) from
    the candidates in ``order``;
    corners of a lattice of five or more seed no other. Writes each candidate's lattice number
    into ``owner`` (-1: none) and its lattice position into ``coord``; stops once nine tenths
    of the candidates are used. Returns the number of lattices."""
    n = pts.shape[0]
    spacing = np.empty(n)
    neighbour_spacing(pts, spacing)
    used = np.zeros(n, dtype=np.bool_)
    G = np.empty((side, side), dtype=np.int64)
    owner[:] = -1
    n_lattices = 0
    n_used = 0
    for seed in order:
        if used[seed]:
            continue
        c = grow(pts, spacing, used, img, contrast, seed, G, offset)
        if c < 5:
            continue
        for a in range(side):
            for b in range(side):
                k = G[a, b]
                if k >= 0:
                    used[k] = True
                    owner[k] = n_lattices
                    coord[k, 0] = a
                    coord[k, 1] = b
                    n_used += 1
        n_lattices += 1
        if n_used > 0.9 * n:
            break
    return n_lattices


@njit(cache=True, nogil=True, error_model="numpy")
def consistent(G: np.ndarray, q: np.ndarray, tol: np.ndarray, keep: np.ndarray) -> None:  # pragma: no cover - numba
    """Clear ``keep[k]`` for the corners of ``G`` (indices into ``q``) that miss the map fitted
    on their neighbours within two steps, themselves left out (quadratic, or affine from four
    or more), by more than ``tol[k]`` pixels, or that have too few neighbours to be checked. The
    worst within its own neighbourhood goes first, for up to eight rounds, so that one wrong
    corner does not condemn its neighbours."""
    S0, S1 = G.shape
    res = np.zeros(q.shape[0])
    coef = np.empty((6, 2))
    for _ in range(8):
        any_bad = False
        for a in range(S0):
            for b in range(S1):
                k = G[a, b]
                if k < 0:
                    continue
                # The nearest ring where it pins a quadratic down (seven or more of the eight
                # neighbours: it follows a fisheye's bend, which a quadratic over two steps
                # does not), else the corners within two steps.
                if local_fit(G, q, a, b, 1, True, 7, coef) != 2 and local_fit(G, q, a, b, 2, True, 4, coef) == 0:
                    res[k] = np.inf
                else:
                    res[k] = math.hypot(coef[0, 0] - q[k, 0], coef[0, 1] - q[k, 1])
                if res[k] > tol[k]:
                    any_bad = True
        if not any_bad:
            return
        drop = np.zeros(q.shape[0], dtype=np.bool_)
        for a in range(S0):
            for b in range(S1):
                k = G[a, b]
                if k < 0 or not res[k] > tol[k]:
                    continue
                worst = True
                for da in range(-2, 3):
                    for db in range(-2, 3):
                        aa, bb = a + da, b + db
                        if 0 <= aa < S0 and 0 <= bb < S1 and G[aa, bb] >= 0 \
                                and res[G[aa, bb]] / tol[G[aa, bb]] > res[k] / tol[k]:
                            worst = False
                if worst:
                    drop[k] = True
        for a in range(S0):
            for b in range(S1):
                k = G[a, b]
                if k >= 0 and drop[k]:
                    keep[k] = False
                    G[a, b] = -1


@njit(cache=True, nogil=True, error_model="numpy")
def border_samples(G: np.ndarray, q: np.ndarray, s: np.ndarray, axis: int, side: int, near: np.ndarray,
                   far: np.ndarray, beyond: np.ndarray, far_sides: np.ndarray,
                   close: np.ndarray, inner: np.ndarray) -> None:  # pragma: no cover - numba
    """The shade half a square and one and a half squares out from the lattice's side ``side``
    (-1: low, +1: high) of lattice axis ``axis``, at each square along it (``near`` and ``far``
    hold one entry a square: between the corners j and j + 1 of the outer line), from the map
    fitted on the corners within two steps of the corner j (NaN where no map; infinity where the
    point lies outside the image or within 2 px of its edge). ``beyond`` (one row a square, x
    and y) gets where the lattice's next corner past corner j would be, one step out (NaN where
    no map; infinity where it lies outside the image or within 2 px of its edge).
    ``far_sides`` (one row a square) gets the shade one and a half squares out as ``far`` does,
    three tenths and seven tenths of the way along the square instead of half; ``close`` (one
    entry a square) the shade 1.2 squares out, half way along (a fifth of a square past the
    outer squares: a narrow margin's); ``inner`` (one entry a square) the shade half a square in,
    the lattice's own last squares, half way along."""
    H, W = s.shape
    S = G.shape
    edge = 0 if side < 0 else S[axis] - 1
    coef = np.empty((6, 2))
    for j in range(near.shape[0]):
        near[j] = np.nan
        far[j] = np.nan
        beyond[j, 0] = np.nan
        beyond[j, 1] = np.nan
        far_sides[j, 0] = np.nan
        far_sides[j, 1] = np.nan
        close[j] = np.nan
        inner[j] = np.nan
        a, b = (edge, j) if axis == 0 else (j, edge)
        if local_fit(G, q, a, b, 2, False, 4, coef) == 0:
            continue
        for t in range(7):
            depth = 0.5 if t == 0 else (1.0 if t == 2 else (1.2 if t == 5 else (-0.5 if t == 6 else 1.5)))
            across = 0.5 if t < 2 or t >= 5 else (0.0 if t == 2 else (0.3 if t == 3 else 0.7))
            ra = side * depth if axis == 0 else across
            rb = side * depth if axis == 1 else across
            x = coef[0, 0] + coef[1, 0] * ra + coef[2, 0] * rb + coef[3, 0] * ra * ra + coef[4, 0] * ra * rb \
                + coef[5, 0] * rb * rb
            y = coef[0, 1] + coef[1, 1] * ra + coef[2, 1] * rb + coef[3, 1] * ra * ra + coef[4, 1] * ra * rb \
                + coef[5, 1] * rb * rb
            inside = 2 <= x <= W - 3 and 2 <= y <= H - 3
            if t == 2:
                beyond[j, 0] = x if inside else np.inf
                beyond[j, 1] = y if inside else np.inf
                continue
            v = bilinear(s, x, y) if inside else np.inf
            if t == 0:
                near[j] = v
            elif t == 1:
                far[j] = v
            elif t == 5:
                close[j] = v
            elif t == 6:
                inner[j] = v
            else:
                far_sides[j, t - 3] = v


@njit(cache=True, nogil=True, error_model="numpy")
def lens_map(P: np.ndarray, g: np.ndarray, g0x: float, g0y: float, gs: float,
             out: np.ndarray) -> None:  # pragma: no cover - numba
    """The lattice points ``g`` (N, 2) under each parameter vector of ``P`` (K, 12) of the
    checkerboard's lens model (``target.checkerboard._LensMap``) into ``out`` (K, N, 2): the
    lattice centred on (g0x, g0y) and scaled by 1 / ``gs``, the homography of ``P[:8]`` (its
    last entry 1), the division model's inverse with strength ``P[8]`` and the radial term
    ``P[9]`` about the centre ``P[10:12]``. Non-finite where the homography sends a point to
    infinity, as IEEE arithmetic gives it."""
    for k in range(P.shape[0]):
        cx, cy = P[k, 10], P[k, 11]
        for i in range(g.shape[0]):
            a = (g[i, 0] - g0x) / gs
            b = (g[i, 1] - g0y) / gs
            hx = a * P[k, 0] + b * P[k, 1] + P[k, 2]
            hy = a * P[k, 3] + b * P[k, 4] + P[k, 5]
            hw = a * P[k, 6] + b * P[k, 7] + 1.0
            ux = hx / hw - cx
            uy = hy / hw - cy
            t = 1.0 - 4.0 * P[k, 8] * (ux * ux + uy * uy)
            if t < 0.0:
                t = 0.0
            s = 2.0 / (1.0 + math.sqrt(t))
            dx, dy = ux * s, uy * s
            f = 1.0 + P[k, 9] * (dx * dx + dy * dy)
            out[k, i, 0] = cx + dx * f
            out[k, i, 1] = cy + dy * f


@njit(cache=True, nogil=True, error_model="numpy")
def _lens_residuals(p: np.ndarray, g: np.ndarray, qn: np.ndarray, g0x: float, g0y: float, gs: float,
                    P: np.ndarray, m: np.ndarray, r: np.ndarray) -> float:  # pragma: no cover - numba
    """``r`` = the lens model's map of ``g`` under ``p`` (its first ``len(p)`` of 12
    parameters, the rest 0; ``P`` (1, 12) and ``m`` (1, N, 2) are work space) less ``qn``,
    flattened; returns ``r @ r``, or inf where a residual is not finite."""
    P[0, :] = 0.0
    P[0, :p.shape[0]] = p
    lens_map(P, g, g0x, g0y, gs, m)
    cost = 0.0
    finite = True
    for i in range(g.shape[0]):
        for c in range(2):
            v = m[0, i, c] - qn[i, c]
            r[2 * i + c] = v
            if not math.isfinite(v):
                finite = False
            cost += v * v
    return cost if finite else np.inf


@njit(cache=True, nogil=True, error_model="numpy")
def _solve_lu(A: np.ndarray, b: np.ndarray, x: np.ndarray) -> bool:  # pragma: no cover - numba
    """``x`` = the solution of ``A x = b`` by Gaussian elimination with partial pivoting (``A``
    and ``b`` are overwritten); False where a pivot is exactly zero (the matrix singular, as
    LAPACK's gesv reports it)."""
    n = A.shape[0]
    for k in range(n):
        piv, best = k, abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > best:
                piv, best = i, abs(A[i, k])
        if best == 0.0:
            return False
        if piv != k:
            for j in range(n):
                A[k, j], A[piv, j] = A[piv, j], A[k, j]
            b[k], b[piv] = b[piv], b[k]
        for i in range(k + 1, n):
            f = A[i, k] / A[k, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= f * A[k, j]
                b[i] -= f * b[k]
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= A[i, j] * x[j]
        x[i] = acc / A[i, i]
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def lens_fit(p0: np.ndarray, g: np.ndarray, qn: np.ndarray, g0x: float, g0y: float, gs: float,
             max_iter: int, p: np.ndarray) -> bool:  # pragma: no cover - numba
    """Fit the lens model (:func:`lens_map`'s first ``len(p0)`` parameters) to the image points
    ``qn`` (N, 2, centred and scaled as the map gives them) of the lattice points ``g``:
    Levenberg-Marquardt from ``p0`` into ``p``, with Marquardt's scaling (the damping on the
    diagonal of J^T J, from 1e-3, times ten on a step that does not lower the cost, a tenth
    after one that does), a forward-difference Jacobian (steps 1e-7 of each parameter, at
    least 1e-7), at most ``max_iter`` iterations; it stops where a step lowers the cost by
    1e-12 of it or less, or moves no parameter by more than 1e-12 of the largest, or where the
    damping passes 1e12. False (``p`` = ``p0``) where the start's residuals are not finite."""
    n, N = p0.shape[0], g.shape[0]
    P = np.zeros((1, 12))
    m = np.empty((1, N, 2))
    r = np.empty(2 * N)
    r_new = np.empty(2 * N)
    r_h = np.empty(2 * N)
    J = np.empty((2 * N, n))
    A = np.empty((n, n))
    grad = np.empty(n)
    M = np.empty((n, n))
    rhs = np.empty(n)
    step = np.empty(n)
    trial = np.empty(n)
    p[:] = p0
    cost = _lens_residuals(p, g, qn, g0x, g0y, gs, P, m, r)
    if not math.isfinite(cost):
        return False
    damping = 1e-3
    for _ in range(max_iter):
        for j in range(n):
            h = 1e-7 * max(abs(p[j]), 1.0)
            trial[:] = p
            trial[j] = p[j] + h
            _lens_residuals(trial, g, qn, g0x, g0y, gs, P, m, r_h)
            for i in range(2 * N):
                J[i, j] = (r_h[i] - r[i]) / h
        for a in range(n):
            acc = 0.0
            for i in range(2 * N):
                acc += J[i, a] * r[i]
            grad[a] = acc
            for b in range(a + 1):
                acc = 0.0
                for i in range(2 * N):
                    acc += J[i, a] * J[i, b]
                A[a, b] = acc
                A[b, a] = acc
        while True:
            for a in range(n):
                for b in range(n):
                    M[a, b] = A[a, b]
                M[a, a] += damping * max(A[a, a], 1e-12)
                rhs[a] = -grad[a]
            if _solve_lu(M, rhs, step):
                for a in range(n):
                    trial[a] = p[a] + step[a]
                new = _lens_residuals(trial, g, qn, g0x, g0y, gs, P, m, r_new)
            else:
                new = np.inf
            if new < cost:
                break
            damping *= 10.0
            if damping > 1e12:
                return True
        big_p, big_s = 0.0, 0.0
        for a in range(n):
            p[a] = trial[a]
            big_p = max(big_p, abs(p[a]))
            big_s = max(big_s, abs(step[a]))
        decrease = cost - new
        cost = new
        r[:] = r_new
        damping = max(damping / 10.0, 1e-12)
        if decrease <= 1e-12 * max(cost, 1e-300) or big_s <= 1e-12 * big_p:
            break
    return True
