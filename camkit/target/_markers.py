"""The marker machinery the coded targets share (ChArUco, AprilGrid): dark quads of an
adaptive threshold, their cells read as codes of a dictionary, markers confirmed against the
board's layout by their neighbours, and X-junctions refined at their saddle points."""

from __future__ import annotations

import functools
import itertools
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, wait
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from camkit._alloc import scratch, work_array
from camkit._kernels import detect as detect_kernels
from camkit._kernels import markers as markers_kernels
from camkit.target._homography import apply_homographies, fit_homographies
from camkit.target.aruco import ArucoDictionary
from camkit.target.checkerboard import (
    _SIGMA_RATIO,
    RawGrey,
    _fit_noise_factors,
    _half,
    _image_noise,
    _saddle_design,
    _saddle_fit,
    _sample,
    _smoothed_patches,
    _stretched,
    _x_corners,
)


def refine_patches(grey: np.ndarray, pts: np.ndarray, r: int, sigma: float,
                   iters: int = 6, residuals: bool = False) -> tuple[np.ndarray, ...]:
    """The saddle fit (window ``r``, ``iters`` steps of at most a pixel) of each point on the
    image smoothed by ``sigma``, the smoothing computed only on a patch around each point (the
    patches side by side in one mosaic): enough for the window, its bicubic support and the
    fit's moves. ``(places, sigmas)``, and the fits' residuals' standard deviations with
    ``residuals`` (:func:`camkit.target.checkerboard._saddle_fit`)."""
    mosaic, shift = _smoothed_patches(grey, pts, r + iters + 3, sigma)
    q, *rest = _saddle_fit(mosaic, pts + shift, r, iters, residuals)
    return (q - shift, *rest)


#: The starts, in windows' radii about a prediction, of the fits :func:`better_saddle_near`
#: compares a fit with.
AROUND = np.array([[a, b] for a in (-1.0, 0.0, 1.0) for b in (-1.0, 0.0, 1.0) if a or b])


def better_saddle_near(grey: np.ndarray, pred: np.ndarray, q: np.ndarray, sig: np.ndarray, r: int,
                       sigma: float, reach: np.ndarray) -> np.ndarray:
    """Which saddle fits (window ``r``, smoothing ``sigma``) from the predictions ``pred`` (K, 2),
    ended at ``q`` with sigmas ``sig`` (K,), have a saddle that fits better (a smaller sigma)
    more than a pixel from them and within ``reach`` (K,) of the prediction, found by the fits
    started a window's radius about the prediction (:data:`AROUND`). A fit from a prediction
    ends at the saddle whose basin holds it; a junction with another saddle a few pixels off
    (a thin margin's crossing with a marker's bits, a small corner square's far side) can
    hold the prediction in the wrong basin."""
    if not len(pred):
        return np.zeros(0, dtype=bool)
    qa, sa = refine_patches(grey, (pred[:, None, :] + float(r) * AROUND).reshape(-1, 2), r, sigma)[:2]
    qa, sa = qa.reshape(len(pred), len(AROUND), 2), sa.reshape(len(pred), len(AROUND))
    apart = np.hypot(*(qa - q[:, None, :]).transpose(2, 0, 1)) > 1.0
    within = np.hypot(*(qa - pred[:, None, :]).transpose(2, 0, 1)) <= reach[:, None]
    return (np.isfinite(sa) & (sa < sig[:, None]) & apart & within).any(axis=1)


def is_x_corner(grey: np.ndarray, pts: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Which points are X-junctions: on a circle of radius ``rho`` (per point, pixels) the shade
    crosses its mean four times, with contrast, and is point-symmetric (opposite quadrants
    alike), as step 1 of the checkerboard detector asks; a marker's own corner or a junction
    of its bits is not."""
    return x_corner_shades(grey, pts, rho)[0]


def x_corner_shades(grey: np.ndarray, pts: np.ndarray, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`is_x_corner`, and the middle of the darkest and brightest shades on each circle
    (kernel :func:`camkit._kernels.markers.x_junctions`; the shades bilinear, as
    :func:`x_shades` judges them)."""
    img, a, b = _stretched(grey)
    pts = np.ascontiguousarray(pts, dtype=np.float64).reshape(-1, 2)
    rho = np.ascontiguousarray(np.broadcast_to(rho, (len(pts),)), dtype=np.float64)
    is_x, mid = np.empty(len(pts), dtype=bool), np.empty(len(pts))
    markers_kernels.x_junctions(img, a, b, pts, rho, _CIRCLE_COS, _CIRCLE_SIN, is_x, mid)
    return is_x, mid


#: The 32 places of :func:`x_corner_shades`' circle: their angles' cosines and sines.
_CIRCLE_COS, _CIRCLE_SIN = np.cos(np.arange(32) * 2 * np.pi / 32), np.sin(np.arange(32) * 2 * np.pi / 32)


def x_shades(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For shades ``v`` (K, 32) sampled round a closed curve about each corner (a circle, or an
    ellipse on a board seen aslant): whether they are an X-junction's (four alternating
    sectors about their mean, point-symmetric: the mean difference of opposite shades under
    a quarter of the contrast, which is 0.15 at least), and the middle of the darkest and
    brightest (kernel :func:`camkit._kernels.markers.x_verdicts`)."""
    v = np.ascontiguousarray(v, dtype=np.float64)
    is_x, mid = np.empty(len(v), dtype=bool), np.empty(len(v))
    markers_kernels.x_verdicts(v, is_x, mid)
    return is_x, mid


def read_markers(g: np.ndarray, quads: np.ndarray, d: ArucoDictionary, border: int = 1,
                 src: np.ndarray | None = None, bend: float = 0.0,
                 middles: tuple[float, ...] = (0.3, 0.5, 0.7)) -> tuple[np.ndarray, np.ndarray]:
    """``(code ids, turns)`` of the markers in ``quads`` (K, 4, 2), clockwise corners; id -1
    where a quad holds no code (:func:`read_markers_rims`)."""
    ids, turns, _ = read_markers_rims(g, quads, d, border, src, bend=bend, middles=middles)
    return ids, turns


def _division(shape: tuple[int, ...]) -> tuple[np.ndarray, float]:
    """The centre and the unit of radius of :func:`undistort`'s model on an image of ``shape``:
    the image's middle and half its diagonal."""
    H, W = shape[:2]
    return np.array([(W - 1) / 2.0, (H - 1) / 2.0]), 0.5 * float(np.hypot(W, H))


def undistort(p: np.ndarray, bend: float, shape: tuple[int, ...]) -> np.ndarray:
    """Pixels ``p`` (..., 2) of an image of ``shape`` taken through Fitzgibbon's one-parameter
    division model (CVPR 2001: undistorted = distorted / (1 + bend r^2)), its centre the
    image's middle and ``r`` in half diagonals: the pixels a lens without distortion (the same
    scale at the middle) would have put them at. ``bend`` < 0 is barrel (a fisheye's about
    -1.5), > 0 pincushion; 0 returns ``p``. NaN past the model's reach, where it folds back
    (``|bend| r^2 >= 1``: a barrel's undistorted radius grows without bound there, a
    pincushion's turns back). The checkerboard's ``_LensMap`` fits the same model with a free
    centre and a second term; it is not shared: that one is fitted by least squares and
    clamps at the fold, this one reads at set strengths about a fixed centre and refuses
    what lies past it."""
    p = np.asarray(p, dtype=np.float64)
    if not bend:
        return p
    c, R = _division(shape)
    d = (p - c) / R
    r2 = (d ** 2).sum(axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return c + R * d / np.where(abs(bend) * r2 < 1.0, 1.0 + bend * r2, np.nan)


def distort(u: np.ndarray, bend: float, shape: tuple[int, ...]) -> np.ndarray:
    """:func:`undistort`'s inverse: the pixels of undistorted pixels ``u`` (..., 2). The
    distorted radius solves ``bend r_u r^2 - r + r_u = 0``: ``r = 2 r_u / (1 + sqrt(1 - 4 bend
    r_u^2))`` (NaN beyond the model's reach)."""
    u = np.asarray(u, dtype=np.float64)
    if not bend:
        return u
    c, R = _division(shape)
    d = (u - c) / R
    with np.errstate(invalid="ignore"):
        f = 2.0 / (1.0 + np.sqrt(1.0 - 4.0 * bend * (d ** 2).sum(axis=-1, keepdims=True)))
    return c + R * d * f


#: A quad that reads as no code is read again with its corners refined where its border is
#: at least this dark (the fraction of the border's cells below the threshold; a marker's
#: reads 0.85 or more) and its contrast is a marker's: a quad a pixel off a slanted marker
#: keeps most of its border (0.68-0.93 in corpus view 878), noise's quads rarely do.
_RIM_TO_REFINE = 0.6


#: :func:`read_markers_rims` reads at most this many quads at once.
_READ_CHUNK = 4096


def _read_cells(g: np.ndarray, Hs: np.ndarray, pts: np.ndarray, n_cells: int,
                m: int) -> tuple[np.ndarray, np.ndarray]:
    """Each quad's cells and margin (kernel :func:`camkit._kernels.markers.read_cells`): the
    points ``pts`` (P, 2) through each homography ``Hs`` (K, 3, 3), bilinear on ``g`` (a
    :class:`RawGrey` through its stretch); (K, ``n_cells``) the means of each cell's ``m``
    points (the first ``n_cells * m``), (K,) the median of the rest (the margin's)."""
    cell, white = np.empty((len(Hs), n_cells)), np.empty(len(Hs))
    markers_kernels.read_cells(*_stretched(g), np.ascontiguousarray(Hs), np.ascontiguousarray(pts), n_cells, m, cell,
                               white)
    return cell, white


def _margin_points(n: int) -> np.ndarray:
    """The white margin around a marker of ``n`` cells: half a cell outside each side's middle."""
    return np.array([[n / 2, -0.5], [n + 0.5, n / 2], [n / 2, n + 0.5], [-0.5, n / 2]])


@functools.lru_cache(maxsize=16)
def _cell_points(n: int, middles: tuple[float, ...]) -> np.ndarray:
    """Where :func:`read_markers_rims` samples a marker of ``n`` x ``n`` cells (the marker
    spans ``[0, n]^2``): each cell's ``middles`` each way, cell by cell in raster order, then
    the margin's four points (:func:`_margin_points`). Read-only (shared between calls)."""
    ov, ou = np.meshgrid(middles, middles, indexing="ij")
    cy, cx = np.mgrid[0:n, 0:n]
    cells = np.stack([(cx[:, :, None] + ou.ravel()).ravel(), (cy[:, :, None] + ov.ravel()).ravel()], axis=-1)
    pts = np.concatenate([cells, _margin_points(n)])
    pts.flags.writeable = False
    return pts


@functools.lru_cache(maxsize=16)
def _rim_points(n: int, border: int) -> np.ndarray:
    """Where :func:`_rims` samples a marker of ``n`` cells with a border ``border`` wide: each
    border cell's middle, in raster order, then the margin's four points. Read-only."""
    cy, cx = np.mgrid[0:n, 0:n]
    rim = (cx < border) | (cy < border) | (cx >= n - border) | (cy >= n - border)
    pts = np.concatenate([np.stack([cx[rim] + 0.5, cy[rim] + 0.5], axis=-1), _margin_points(n)])
    pts.flags.writeable = False
    return pts


def read_markers_rims(g: np.ndarray, quads: np.ndarray, d: ArucoDictionary, border: int = 1,
                      src: np.ndarray | None = None, rim_contrast: float = 0.15,
                      bend: float = 0.0,
                      middles: tuple[float, ...] = (0.3, 0.5, 0.7)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(code ids, turns, rimmed)`` of the markers in ``quads`` (K, 4, 2), clockwise corners;
    id -1 where a quad holds no code; ``rimmed`` where its border is mostly dark
    (:data:`_RIM_TO_REFINE`) against a margin ``rim_contrast`` lighter, as a marker's. The
    quads at once: their homographies from the unit square, one sampling of every cell's middle
    points (3 x 3 by default: at ``middles`` of the cell each way; their mean read) and of the
    white margin around each. The code's cells are inside a black border ``border`` cells
    wide (1 for ArUco, 2 for Kalibr's AprilTags). ``src`` (K, 4, 2): where each quad's corners
    lie in the marker's cells (the marker spans ``[0, n]^2``), where not on the marker's own
    corners. ``bend``: where not 0, the markers are read through a lens of that strength
    (:func:`undistort`: a marker's cells lie on the homography of its undistorted corners).

    Read :data:`_READ_CHUNK` quads at a time (each quad's reading is its own): a cluttered
    12 MP image gives some hundred thousand quads to read again (an AprilGrid's fifteen ways
    of joined corner squares), whose thousand samples each would otherwise be held at once."""
    if len(quads) > _READ_CHUNK:
        parts = [read_markers_rims(g, quads[i:i + _READ_CHUNK], d, border,
                                   None if src is None else src[i:i + _READ_CHUNK], rim_contrast, bend, middles)
                 for i in range(0, len(quads), _READ_CHUNK)]
        ids, turns, rimmed = (np.concatenate(p) for p in zip(*parts, strict=True))
        return ids, turns, rimmed
    K = len(quads)
    n = d.marker_size + 2 * border
    unit = np.array([[0.0, 0.0], [n, 0.0], [n, n], [0.0, n]])
    Hs = fit_homographies(np.broadcast_to(unit, quads.shape) if src is None else src,
                          undistort(quads, bend, g.shape))
    ok = np.isfinite(Hs).all(axis=(1, 2))
    Hs[~ok] = np.eye(3)  # read nothing from these: ``ok`` rejects them below
    pts = _cell_points(n, tuple(middles))
    m = len(middles) ** 2
    if bend:
        p = (Hs @ np.c_[pts, np.ones(len(pts))].T).transpose(0, 2, 1)
        with np.errstate(divide="ignore", invalid="ignore"):  # a degenerate quad's rows: not read below
            px = p[:, :, :2] / p[:, :, 2:]
        px = distort(px, bend, g.shape)
        reach = np.isfinite(px).all(axis=(1, 2))
        ok &= reach
        px[~reach] = 0.0
        vals = _sample(g, np.ascontiguousarray(px[:, :, 0].ravel()), np.ascontiguousarray(px[:, :, 1].ravel()),
                       "bilinear").reshape(K, len(pts))
        cell = vals[:, :n * n * m].reshape(K, n, n, m).mean(axis=3)
        white = np.median(vals[:, n * n * m:], axis=1)
    else:
        cell, white = _read_cells(g, Hs, pts, n * n, m)
        cell = cell.reshape(K, n, n)
    nb = n - 2 * border
    good, rimmed = np.empty(K, dtype=bool), np.empty(K, dtype=bool)
    bits = np.empty((K, nb * nb), dtype=np.uint8)
    markers_kernels.cell_verdicts(np.ascontiguousarray(cell.reshape(K, n * n)), np.ascontiguousarray(white), ok, n,
                                  border, float(rim_contrast), _RIM_TO_REFINE, good, rimmed, bits)
    ids = np.full(K, -1, dtype=np.int64)
    turns = np.zeros(K, dtype=np.int64)
    if good.any():
        ids[good], turns[good], _ = d.identify_many(bits[good].reshape(-1, nb, nb))
    return ids, turns, rimmed


def _dark_runs(g: np.ndarray, ii: np.ndarray, r: int, c: float, opening: bool,
               cuts: tuple[np.ndarray, np.ndarray] | None) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """The runs of set pixels (kernel :func:`camkit._kernels.markers.mask_runs`) of one dark mask
    of :func:`find_quads` (window half side ``r``, ``c`` below its mean; opened and cut where
    asked). Serial kernels (``nogil``) wholly, on this thread's buffers: the masks are made on
    threads side by side."""
    dark = scratch("mask", g.shape, np.bool_)
    markers_kernels.dark_mask(g, ii, r, c, dark)
    if opening:
        opened = scratch("opened", dark.shape, np.bool_)
        markers_kernels.cross_filter(dark, False, opened)
        markers_kernels.cross_filter(opened, True, dark)
    if cuts is not None:
        dark[cuts] = False
    return markers_kernels.mask_runs(dark)


def _side_by_side(fn: Callable[[int], Any], n: int, helpers: int = 1,
                  then: Callable[[int, Any], np.ndarray] | None = None) -> list[np.ndarray]:
    """``[fn(0), ..., fn(n - 1)]``, the calls shared out between this thread and up to
    ``helpers`` of the pool's as each comes free (``fn`` runs ``nogil`` kernels). With
    ``then``, ``[then(i, fn(i)) for i ...]`` in two stages: every ``fn`` call is taken before
    any ``then`` call, and ``then(i, .)`` waits for ``fn(i)`` where another thread has it (so
    that one thread makes a mask's runs while another labels the runs of the mask before,
    and no thread waits for the last mask's whole work). The first error comes back after
    every call taken has ended."""
    out: list[np.ndarray] = [np.empty(0)] * n
    first: list[Any] = [None] * n
    done = [threading.Event() for _ in range(n)] if then is not None else []
    failed: set[int] = set()
    n_tasks = 2 * n if then is not None else n
    nxt = itertools.count()  # (next() on it is atomic under the GIL)

    def work() -> None:
        while (t := next(nxt)) < n_tasks:
            if then is None:
                out[t] = fn(t)
            elif t < n:
                try:
                    first[t] = fn(t)
                except BaseException:
                    failed.add(t)
                    raise
                finally:
                    done[t].set()
            else:
                done[t - n].wait()
                if t - n not in failed:  # (its error comes back from the thread that met it)
                    out[t - n] = then(t - n, first[t - n])

    running = [_pool().submit(work) for _ in range(min(n_tasks - 1, helpers, _POOL_THREADS))]
    try:
        work()
    finally:  # (the helpers read the caller's arrays: none outlives the call)
        wait(running)
    for h in running:
        h.result()
    return out


_POOL: ThreadPoolExecutor | None = None
#: The pool's threads: they and the caller's share the masks out (:func:`_side_by_side`).
_POOL_THREADS = max(1, min(3, (os.cpu_count() or 1) - 1))
#: :func:`find_quads` shares its masks out where an image has this many pixels at least; a
#: smaller one's (a patch where a marker is looked for again) are made on the caller's thread
#: (the pool's hand-over costs more than it saves on a small image: benchmarks/notes.md,
#: forty-seventh session).
_SIDE_BY_SIDE_MIN_PX = 40_000


def _forget_pool() -> None:
    """A forked child has none of its parent's threads: it starts its own pool (a task queued
    on the parent's would wait for ever)."""
    global _POOL
    _POOL = None


os.register_at_fork(after_in_child=_forget_pool)


def _pool() -> ThreadPoolExecutor:
    """The threads that make and label masks beside the caller's (:func:`_side_by_side`),
    started on first use."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=_POOL_THREADS, thread_name_prefix="camkit-quads")
    return _POOL


def find_quads(g: np.ndarray, min_side: int, opening: bool = False, radii: tuple[int, ...] | None = None,
               cuts: tuple[np.ndarray, np.ndarray] | None = None, integral: np.ndarray | None = None) -> np.ndarray:
    """Quad candidates (K, 4, 2), clockwise in the image, from the dark regions of an adaptive
    threshold at three window sizes (a quad found again at another window kept once). With
    ``opening``, the dark mask is opened by the 3 x 3 cross first, which parts regions that
    touch at a corner (an AprilGrid's tag and its corner squares) and keeps a border two cells
    wide at two pixels a cell, and each window is thresholded twice: 0.03 and 0.15 below the
    local mean (the stricter one parts junctions that blur joins). Each mask is made and its
    regions labelled on threads, the masks side by side (:func:`_side_by_side`). ``radii``: the
    windows' half sides, where not a fraction of the image's size (80th, 30th, 12th).
    ``cuts``: pixels (rows, columns) cleared from every dark mask (:func:`_junction_cuts`).
    ``integral``: ``g``'s integral image (:func:`camkit._kernels.markers.integral`), where
    already made."""
    H, W = g.shape
    ii = integral
    if ii is None:
        ii = scratch("integral", (H + 1, W + 1), np.float64)
        markers_kernels.integral(g, ii)
    offsets = (0.03, 0.15) if opening else (0.03,)
    if radii is None:
        radii = tuple(sorted({max(3, min(H, W) // k) for k in (80, 30, 12)}))
    masks = [(r, c) for r in radii for c in offsets]
    # Each mask made and its runs found, then its regions labelled: the two stages of every
    # mask shared out, the masks made first (_side_by_side).
    found = _side_by_side(lambda i: _dark_runs(g, ii, *masks[i], opening, cuts), len(masks),
                          _POOL_THREADS if H * W >= _SIDE_BY_SIDE_MIN_PX else 0,
                          then=lambda i, runs: markers_kernels.runs_quads(runs[1], runs[2], runs[3],
                                                                          (min_side * min_side) // 2, (H * W) // 4,
                                                                          min_side))
    out = [q for q in found if len(q)]
    if not out:
        return np.zeros((0, 4, 2))
    # One quad per marker: the windows find most markers more than once.
    allq = np.concatenate(out)
    centre = allq.mean(axis=1)
    span = np.ptp(allq, axis=1).max(axis=1)
    order = np.lexsort((centre[:, 1], centre[:, 0]))
    keep = np.ones(len(allq), dtype=bool)
    markers_kernels.unique_quads(allq, centre, span, order, keep)
    return allq[keep]


#: Markers are looked for first at a level whose longer side is at most this (2x2 means), then
#: finer where that level reads too little; the corners are refined on the full image.
MARKER_LEVEL_SIDE = 1600


#: The smallest cell (px) a marker is looked for with on the full image.
MIN_CELL_PX = 1.25


#: How far either way of an X-junction (px) :func:`_junction_cuts` cuts along its light sectors.
_CUT_REACH = 3.0


def _light_axis(v: np.ndarray) -> np.ndarray:
    """The angle (radians, image frame) of the axis through the light sectors of X-junctions
    whose profiles are ``v`` (K, M samples on a circle from the +x axis): the profile's second
    harmonic."""
    ang = np.arange(v.shape[1]) * 2.0 * np.pi / v.shape[1]
    return 0.5 * np.angle((v * np.exp(2j * ang)).sum(axis=1))


def _junction_cuts(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (rows, columns) that part the dark regions meeting at the X-junctions of ``g``
    (the checkerboard detector's X-corners): a line :data:`_CUT_REACH` either way of each
    along its light sectors' axis (the profile's second harmonic), drawn in half-pixel steps
    (8-connected, so no 4-connected region crosses it). An AprilGrid's tags meet their corner
    squares at such junctions; seen aslant and blurred, a junction's light sectors are thin
    wedges whose middle is darker than any threshold between black and white, and every tag
    joins its squares into chains (corpus views 186 and 273: 2 of 15 and 0 of 9 tags read;
    11 and 9 once cut)."""
    pts, v = _x_corners(np.ascontiguousarray(g, dtype=np.float64))[2:4]
    axis = _light_axis(v)
    t = np.arange(-_CUT_REACH, _CUT_REACH + 0.25, 0.5)
    x = np.rint(pts[:, :1] + t * np.cos(axis)[:, None]).astype(np.int64).ravel()
    y = np.rint(pts[:, 1:] + t * np.sin(axis)[:, None]).astype(np.int64).ravel()
    H, W = g.shape
    inside = (x >= 0) & (x < W) & (y >= 0) & (y < H)
    return y[inside], x[inside]


#: :func:`junction_quads`: the nearest X-junctions of each looked at as a quad's two sides (a
#: tag's neighbouring corners lie beyond its corner square's three and others of the codes;
#: on AprilGrid corpus view 926 its 8th-10th nearest, and 8 of 12 tags beyond the 10th).
_JUNCTION_NEIGHBOURS = 20
#: ... the fourth corner within this fraction of the longer side of where the other three put
#: it (a parallelogram: a small tag seen through perspective is one within a few percent) ...
_JUNCTION_CLOSE = 0.15
#: ... and each corner's dark axis (its profile's second harmonic) within this of the quad's
#: middle (the tag's dark sector faces its middle; the corner square's, the other way).
_JUNCTION_AXIS_DEG = 25.0


def junction_quads(g: np.ndarray) -> np.ndarray:
    """Quads (K, 4, 2), clockwise in the image, whose corners are X-junctions of ``g`` (the
    checkerboard detector's X-corners, refined at their saddle points): an AprilGrid's tags,
    whose corners are where they meet their corner squares. Where tags are small and blurred,
    the dark regions of a threshold join each tag with its squares and bound neither (AprilGrid
    corpus views 926 and 1117, tags of 20-26 px: quads 8-46 px off, 3 and 1 tags read) while
    the junctions are sharp saddles. Each junction with two of its
    :data:`_JUNCTION_NEIGHBOURS` nearest as two sides, 40 to 140 degrees apart and at most 2.5
    times as long one as the other, makes a quad where a junction lies at the parallelogram's
    fourth corner (:data:`_JUNCTION_CLOSE`) and each corner's dark axis points to the quad's
    middle (:data:`_JUNCTION_AXIS_DEG`)."""
    _, _, pts, v, _, _, why = _x_corners(np.ascontiguousarray(g, dtype=np.float64))
    none = np.zeros((0, 4, 2))
    if why or len(pts) < 4:
        return none
    ref, sg = refine_patches(g, pts, 2, 1.0)
    ok = np.isfinite(sg) & (np.hypot(*(ref - pts).T) <= 1.5)
    dark = _light_axis(v[ok]) + 0.5 * np.pi
    pts = ref[ok]
    if len(pts) < 4:
        return none
    tree = cKDTree(pts)
    k = min(_JUNCTION_NEIGHBOURS + 1, len(pts))
    nb = tree.query(pts, k=k)[1][:, 1:]
    xa, xb = np.triu_indices(k - 1, 1)
    i = np.repeat(np.arange(len(pts)), len(xa))
    a, b = nb[:, xa].ravel(), nb[:, xb].ravel()
    va, vb = pts[a] - pts[i], pts[b] - pts[i]
    la, lb = np.hypot(*va.T), np.hypot(*vb.T)
    cos = (va * vb).sum(axis=1) / np.maximum(la * lb, 1e-12)
    short, long_ = np.minimum(la, lb), np.maximum(la, lb)
    keep = (short >= 4.0) & (long_ <= 2.5 * short) & (np.abs(cos) <= np.cos(np.deg2rad(40.0)))
    i, a, b, long_ = i[keep], a[keep], b[keep], long_[keep]
    dc, c = tree.query(pts[a] + pts[b] - pts[i])
    keep = (dc <= _JUNCTION_CLOSE * long_) & (c != i) & (c != a) & (c != b)
    q = np.stack([i[keep], a[keep], c[keep], b[keep]], axis=1)
    if not len(q):
        return none
    q = q[np.unique(np.sort(q, axis=1), axis=0, return_index=True)[1]]  # each quad once
    to = pts[q].mean(axis=1)[:, None, :] - pts[q]
    off = np.angle(np.exp(2j * (np.arctan2(to[..., 1], to[..., 0]) - dark[q])))  # doubled: an axis
    q = pts[q[(np.abs(off) < 2.0 * np.deg2rad(_JUNCTION_AXIS_DEG)).all(axis=1)]]
    e1, e2 = q[:, 1] - q[:, 0], q[:, 3] - q[:, 0]
    turned = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    q[turned] = q[turned][:, [0, 3, 2, 1]]
    return q


def _swollen(n: int, b: float) -> np.ndarray:
    """The fifteen ways a quad can hold a marker of ``n`` cells with squares of ``b`` cells
    joined at some of its corners (diagonally off them, as an AprilGrid's corner squares):
    (15, 4, 2) places of the quad's corners in the marker's cells, fewest joined first."""
    unit = np.array([[0.0, 0.0], [n, 0.0], [n, n], [0.0, n]])
    out = np.array([[-b, -b], [b, -b], [b, b], [-b, b]])
    masks = sorted(range(1, 16), key=lambda m: (bin(m).count("1"), m))
    return np.stack([unit + out * ((m >> np.arange(4)) & 1)[:, None] for m in masks])


class _Pyramid:
    """:func:`find_markers`'s 2x2-mean pyramid of ``full`` (level ``k``: ``_half`` ``k`` times),
    down to a longer side of at most :data:`MARKER_LEVEL_SIDE`, each level made where first
    read: the coarsest is read first and is often the only one read (a 12 MP image's coarsest
    is two halvings down, made in one pass without the half level: :func:`quarter_mean`)."""

    def __init__(self, full: np.ndarray) -> None:
        n, side = 1, max(full.shape)
        while side > MARKER_LEVEL_SIDE:
            side //= 2
            n += 1
        self._levels: dict[int, np.ndarray] = {0: full}
        self._n = n

    def __len__(self) -> int:
        return self._n

    def level(self, k: int) -> np.ndarray:
        """Level ``k``, made once: from level ``k - 1`` where that is made; else in one pass
        from level ``k - 2`` where that is made; else from level ``k - 1``, made first."""
        if k not in self._levels:
            if k - 1 not in self._levels and k - 2 in self._levels:
                src = self._levels[k - 2]
                H, W = src.shape
                out = work_array((H // 4, W // 4), np.float64)
                if isinstance(src, RawGrey):
                    detect_kernels.quarter_mean(src.raw, src.a, src.b, out)
                else:
                    detect_kernels.quarter_mean(np.ascontiguousarray(src, dtype=np.float64), 1.0, 0.0, out)
                self._levels[k] = out
            else:
                self._levels[k] = _half(self.level(k - 1))
        return self._levels[k]


def find_markers(full: np.ndarray, d: ArucoDictionary, border: int = 1, corner_squares: float = 0.0,
                 noise: float | None = None) -> tuple[dict[int, list[np.ndarray]], int, np.ndarray]:
    """The markers of dictionary ``d`` in the grey image ``full``: for each code read, the
    corners of every quad that holds it, (4, 2) full-image pixels in the code's order
    (top-left, top-right, bottom-right, bottom-left of the marker as the dictionary draws it),
    the factor of the finest pyramid level read (the scale of the detail that is left), and
    that level's image.

    Quads (:func:`find_quads`) read as codes (:func:`read_markers`), their corners then moved to
    where their sides' edges meet (:func:`refine_quads`), from the coarsest level of
    a 2x2-mean pyramid (longer side at most :data:`MARKER_LEVEL_SIDE`) down: a finer level is
    read where the coarser gave fewer than two markers or markers of under 2 px a cell across
    (bits blur together there); a finer level's reading replaces a coarser one that read no
    more. On the full image, quads down to :data:`MIN_CELL_PX` a cell are looked for where
    three times the image's noise is at most half the stretch's range, and read where their
    border is a marker's (:func:`_rims`); without ``corner_squares``, a quad with a marker's
    border (three times the level's noise darker than its margin) that reads as no code is
    read again with its corners refined (:func:`_read_refined`). ``corner_squares`` (an
    AprilGrid's spacing, over the marker's side): the dark masks are cut at the X-junctions
    (:func:`_junction_cuts`); a quad that reads as nothing is read again as a marker with such
    squares joined at some of its corners (a blurred junction joins their dark regions), and
    kept with the marker's own corners; one that still reads as nothing is read through a
    lens (:func:`_read_bent`), and kept with its corners as found (not refined to straight
    edges). ``noise``: the image's (:func:`image_noise`), where already measured.
    """
    levels = _Pyramid(full)
    n_cells = d.marker_size + 2 * border
    found: dict[int, list[np.ndarray]] = {}
    for k in reversed(range(len(levels))):
        g, f = levels.level(k), 2 ** k
        ii = None
        if isinstance(g, RawGrey):  # (its integral image for find_quads in the same pass)
            ii = scratch("integral", (g.shape[0] + 1, g.shape[1] + 1), np.float64)
            g = g.dense(integral=ii)
        # Two pixels a cell at least where a finer level is left to read; on the full image,
        # down to :data:`MIN_CELL_PX` (refined quads read there: corpus view 883, markers of
        # 13 px, cells of 1.6) where the image's noise leaves such cells readable: their
        # border three times its sigma darker than their margin, and that at most half the
        # range from black to white (the stretch's 0 to 1).
        if noise is None:
            noise = image_noise(full)
        # A border three times the level's noise darker than its margin (a 2x2 mean halves it).
        contrast = max(0.15, 3.0 * noise / f)
        small_ok = f == 1 and contrast <= 0.5
        quads = find_quads(g, int(np.ceil(MIN_CELL_PX * n_cells)) if small_ok else 2 * n_cells, opening=border >= 2,
                           cuts=_junction_cuts(g) if corner_squares > 0 else None, integral=ii)
        if small_ok and len(quads):
            # The small quads (noise gives many) are read only where their border is a
            # marker's.
            small = np.ptp(quads, axis=1).min(axis=1) < 2 * n_cells
            if small.any():
                small[small] = ~_rims(g, quads[small], n_cells, border, contrast)
                quads = quads[~small]
        codes, turns, rimmed = (read_markers_rims(g, quads, d, border, rim_contrast=contrast) if len(quads)
                                else (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, bool)))
        if corner_squares > 0 and (codes < 0).any():
            quads, codes, turns = _read_swollen(g, quads, codes, turns, d, border, n_cells * corner_squares)
        bent = np.zeros(len(codes), dtype=bool)
        if corner_squares > 0 and (codes < 0).any():
            codes, turns, bent = _read_bent(g, quads, codes, turns, d, border)
        if corner_squares == 0 and ((codes < 0) & rimmed).any():
            quads, codes, turns = _read_refined(g, quads, codes, turns, rimmed, d, border)
        # The decoded quads' corners where their sides' edges meet (the region's extreme pixels
        # lie up to a cell off where blur widens or narrows it).
        # (Not those read through a lens: their sides bow, and lines through them miss the corners.)
        read = (codes >= 0) & ~bent
        if read.any():
            quads = quads.copy()
            quads[read] = refine_quads(g, quads[read], n_cells)
        level: dict[int, list[np.ndarray]] = {}
        # One entry per decoded quad; those read straight first (a marker read both ways keeps
        # its refined corners).
        # The code's corner j is the quad's corner (j - turns) % 4.
        turned = (np.take_along_axis(quads, ((np.arange(4) - turns[:, None]) % 4)[:, :, None], axis=1) + 0.5) * f - 0.5
        for j in np.argsort(bent, kind="stable").tolist():
            if codes[j] >= 0:
                add_marker(level, int(codes[j]), turned[j])
        if len(level) >= len(found):
            found = level  # the finer level's corners where it reads as much
        # A marker's narrowest side per cell, at this level (none finer left to read on the full
        # image).
        if k > 0 and len(level) >= 2 and np.median(narrowest_side(np.stack([c[0] for c in level.values()]))
                                                    / f / n_cells) >= 2.0:
            break
    return found, f, g


def refine_quads(grey: np.ndarray, quads: np.ndarray, n_cells: int, iters: int = 2) -> np.ndarray:
    """The markers' quads (K, 4, 2), clockwise in the image, their corners moved to where the
    lines of their four sides' edges meet. A quad from a dark region's extreme pixels lies
    off the marker by up to a cell where blur widens or narrows the region (1-2 px on markers
    of 15 px, blurred: their homography then puts the chessboard corners beside them 2-3 px
    off). Each side's edge (the black border against the white outside) is found across the
    side at eleven places between a fifth and four fifths along it, each at the strongest
    rise from dark to light within 0.8 of a cell either side (the next edges out and in, a
    black square beyond the margin and the code's bits, fall), to a tenth of a pixel by a
    parabola through the peak; a line is fitted through them (least squares, weighted by the
    rise), and again without those over 1.5 px (or 0.3 of a cell) off it where they are three
    at most and cells 3.75 px or more: near an obtuse corner seen at a slant the search can
    reach the next side's edge. The corners are where the lines fitted again meet, or where
    those put a corner over a cell from the quad's, where the first lines meet (kernel
    :func:`camkit._kernels.markers.refine_quads`). Run ``iters`` times; a round in which a
    corner would lie more than a cell from the quad's, or a side's edge is not found, is not
    taken. A quad that is not finite is returned as it came. A :class:`RawGrey` is read on a
    square around each quad only (its farthest corner, two to three cells and 3 px beyond)."""
    quads = np.asarray(quads, dtype=np.float64)
    out = quads.copy()
    ok = np.isfinite(quads).all(axis=(1, 2))
    if ok.any():
        q = np.ascontiguousarray(quads[ok])
        r = np.empty_like(q)
        if isinstance(grey, RawGrey):
            centre = q.mean(axis=1)
            reach = np.hypot(*(q - centre[:, None]).transpose(2, 0, 1)).max(axis=1)
            half = int(np.ceil((reach * (1.0 + 4.0 / n_cells)).max())) + 3
            # (An unblurred copy: a Gaussian of 1e-3 px has one tap.)
            mosaic, shift = _smoothed_patches(grey, centre, half, 1e-3)
            markers_kernels.refine_quads(mosaic, np.ascontiguousarray(q + shift[:, None]), int(n_cells),
                                         int(iters), r)
            r -= shift[:, None]
        else:
            markers_kernels.refine_quads(np.ascontiguousarray(grey, dtype=np.float64), q, int(n_cells), int(iters),
                                         r)
        out[ok] = r
    return out


def add_marker(found: dict[int, list[np.ndarray]], code: int, corners: np.ndarray) -> None:
    """Add a marker read as ``code`` at ``corners`` (4, 2) to ``found`` unless that code is there
    already at the same place (its centre within half its span): one marker read twice (at two
    windows, or one by one and as part of the board)."""
    same = found.setdefault(code, [])
    if same:
        span = float(np.ptp(corners, axis=0).max())
        if any(np.hypot(*(c.mean(axis=0) - corners.mean(axis=0))) < 0.5 * span for c in same):
            return
    same.append(corners)


def _rims(g: np.ndarray, quads: np.ndarray, n: int, border: int, contrast: float) -> np.ndarray:
    """Whether each quad (K, 4, 2) has a marker's border (``border`` cells wide on a marker of
    ``n`` cells): the border's cells, one sample each in their middles, mostly dark
    (:data:`_RIM_TO_REFINE`) against the white margin half a cell outside each side's middle,
    ``contrast`` lighter at least (medians). A quick look (a tenth of
    :func:`read_markers_rims`'s samples)."""
    unit = np.array([[0.0, 0.0], [n, 0.0], [n, n], [0.0, n]])
    Hs = fit_homographies(np.broadcast_to(unit, quads.shape), quads)
    ok = np.isfinite(Hs).all(axis=(1, 2))
    Hs[~ok] = np.eye(3)
    pts = _rim_points(n, border)
    r = len(pts) - 4
    vals, white = _read_cells(g, Hs, pts, r, 1)  # one sample a rim cell, and the margin's median
    out = np.empty(len(quads), dtype=bool)
    markers_kernels.rim_verdicts(vals, white, ok, float(contrast), _RIM_TO_REFINE, out)
    return out


def _read_refined(g: np.ndarray, quads: np.ndarray, codes: np.ndarray, turns: np.ndarray, rimmed: np.ndarray,
                  d: ArucoDictionary, border: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The quads that read as no code but have a marker's border (``rimmed``) read again with
    their corners where their sides' edges meet (:func:`refine_quads`): a region's extreme
    pixels lie up to a cell off the marker's corners, which shifts every sample of a marker
    seen at a slant, its cells 2 px across, by half a cell (corpus view 878's markers 16 and
    23 through a fisheye at 65 degrees). ArUco markers only: an AprilGrid's tag joins its
    corner squares' dark regions where blurred, and is read so instead (:func:`_read_swollen`);
    read after refining, one gave a corner 1.4 px off (AprilGrid corpus view 43)."""
    fail = np.flatnonzero((codes < 0) & rimmed)
    n = d.marker_size + 2 * border
    rq = refine_quads(g, quads[fail], n)
    moved = np.flatnonzero(np.abs(rq - quads[fail]).max(axis=(1, 2)) > 0)
    if not len(moved):
        return quads, codes, turns
    ids, tn = read_markers(g, rq[moved], d, border)
    hit = ids >= 0
    if not hit.any():
        return quads, codes, turns
    k = fail[moved[hit]]
    quads, codes, turns = quads.copy(), codes.copy(), turns.copy()
    quads[k], codes[k], turns[k] = rq[moved[hit]], ids[hit], tn[hit]
    return quads, codes, turns


def _read_swollen(g: np.ndarray, quads: np.ndarray, codes: np.ndarray, turns: np.ndarray, d: ArucoDictionary,
                  border: int, b: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The quads that read as no code read again as markers with squares of ``b`` cells joined
    at some corners (:func:`_swollen`, fewest first; all fifteen ways in one batch), their
    corners replaced by the marker's own where one way reads."""
    n = d.marker_size + 2 * border
    fail = np.flatnonzero(codes < 0)
    ways = _swollen(n, b)
    src = np.broadcast_to(ways[None], (len(fail), 15, 4, 2)).reshape(-1, 4, 2)
    q = np.repeat(quads[fail], 15, axis=0)
    ids, tn = read_markers(g, q, d, border, src)
    ids, tn = ids.reshape(len(fail), 15), tn.reshape(len(fail), 15)
    quads, codes, turns = quads.copy(), codes.copy(), turns.copy()
    hit = ids >= 0
    rows = np.flatnonzero(hit.any(axis=1))
    if not len(rows):
        return quads, codes, turns
    w = hit[rows].argmax(axis=1)  # the first way that reads (fewest corners joined)
    k = fail[rows]
    unit = np.array([[0.0, 0.0], [n, 0.0], [n, n], [0.0, n]])
    own = apply_homographies(fit_homographies(ways[w], quads[k]), np.broadcast_to(unit, (len(k), 4, 2)))
    ok = np.isfinite(own).all(axis=(1, 2))
    quads[k[ok]] = own[ok]
    codes[k[ok]], turns[k[ok]] = ids[rows[ok], w[ok]], tn[rows[ok], w[ok]]
    return quads, codes, turns


#: The lens strengths (:func:`undistort`'s ``bend``) a quad that reads as no code is read
#: through, weakest first: a fisheye's is about -1.5 (AprilGrid corpus view 28, every tag
#: within 0.07 of a cell of its cells there), and a tag reads within about 0.5 of it.
BENDS = (-0.5, 0.5, -1.0, -1.5, -2.0, -2.5, -3.0)


def _read_bent(g: np.ndarray, quads: np.ndarray, codes: np.ndarray, turns: np.ndarray, d: ArucoDictionary,
               border: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The quads that read as no code read again through lenses of the strengths
    :data:`BENDS` (:func:`read_markers`' ``bend``), the first that reads kept: through a
    fisheye a tag's sides bow by up to 1.7 of its cells, and the homography through its
    corners puts its middle cells a cell or more off (AprilGrid corpus view 28: 5 of 42 tags
    read so). Returns the codes, turns and which were read so."""
    codes, turns = codes.copy(), turns.copy()
    bent = np.zeros(len(codes), dtype=bool)
    for bend in BENDS:
        fail = np.flatnonzero(codes < 0)
        if not len(fail):
            break
        ids, tn = read_markers(g, quads[fail], d, border, bend=bend)
        codes[fail], turns[fail] = ids, tn
        bent[fail[ids >= 0]] = True
    return codes, turns, bent


def unconfirmed_reason(found: dict[int, list[np.ndarray]], n_markers: int, noun: str, whole: str) -> str:
    """Why nothing was confirmed, in words: no ``noun`` of the ``whole`` read, or how many were
    read and not confirmed by a neighbour."""
    n = sum(1 for m, c in found.items() if m < n_markers and len(c) == 1)
    if not n:
        return f"no {noun} of the {whole}"
    return f"{n} {noun}(s) of the {whole}, none confirmed by a neighbour where the layout puts it"


def quad_area(q: np.ndarray) -> np.ndarray:
    """The signed area of each quad ``q`` (..., 4, 2), by the shoelace formula (positive where
    the corners run clockwise in the image, y down)."""
    x, y = q[..., 0], q[..., 1]
    x1 = np.concatenate([x[..., 1:], x[..., :1]], axis=-1)
    y1 = np.concatenate([y[..., 1:], y[..., :1]], axis=-1)
    return 0.5 * np.sum(x * y1 - x1 * y, axis=-1)


def narrowest_side(q: np.ndarray) -> np.ndarray:
    """The shortest side of each quad ``q`` (..., 4, 2)."""
    return np.hypot(*np.moveaxis(q - np.roll(q, 1, axis=-2), -1, 0)).min(axis=-1)


def narrowest_width(q: np.ndarray) -> np.ndarray:
    """How narrow each quad ``q`` (..., 4, 2) is: its area over the longer mean of two
    opposite sides (for a parallelogram, the smaller distance between opposite sides). A
    quad seen obliquely is sheared: its sides stay long while it is narrow across them."""
    side = np.hypot(*np.moveaxis(q - np.roll(q, 1, axis=-2), -1, 0))  # side k: corners k-1, k
    longer = np.maximum(side[..., 0] + side[..., 2], side[..., 1] + side[..., 3]) / 2
    with np.errstate(divide="ignore", invalid="ignore"):  # a quad of one point: 0
        return np.nan_to_num(np.abs(quad_area(q)) / longer, nan=0.0)


def confirm_markers(found: dict[int, list[np.ndarray]], obj: np.ndarray, grid: np.ndarray, step: float,
                    factor: int, bend: float = 0.0,
                    shape: tuple[int, ...] = (0, 0)) -> tuple[list[int], dict[int, np.ndarray], dict[int, float]]:
    """The board's markers among ``found`` (:func:`find_markers`) that a neighbour confirms.

    ``obj`` (M, 4, 2): each of the board's markers' corners in the target frame, in the code's
    order; ``grid`` (M, 2): its integer place on the board's layout; ``step``: the layout's
    pitch over the marker's side. An id the board does not have is another board's; an id seen
    twice is dropped. Every pair of markers within two places of each other is tested: one
    homography through both markers' eight corners fits (within 15 % of a pitch, 2 px at the
    level read at least) where both are where the layout puts them (perspective and distortion
    are smooth over two places); a marker is confirmed by at least one pair that fits and more
    that fit than do not.

    ``bend`` (with the image's ``shape``): the corners are taken through :func:`undistort`
    first (a fisheye bends two tags' corners off one homography by more than that); the
    homographies returned are then to undistorted pixels.

    Returns (confirmed ids, each confirmed marker's homography target frame -> image, each
    marker's pitch in pixels)."""
    if bend:
        found = {m: [undistort(q, bend, shape) for q in c] for m, c in found.items()}
    ids = [m for m, c in found.items() if m < len(obj) and len(c) == 1]
    homs: dict[int, np.ndarray] = {}
    if ids:
        hs = fit_homographies(obj[ids], np.stack([found[m][0] for m in ids]))
        fin = np.isfinite(hs).all(axis=(1, 2)).tolist()
        homs = {m: h for m, h, f in zip(ids, hs, fin, strict=True) if f}
        ids = [m for m in ids if m in homs]
    pitch = (dict(zip(ids, (np.sqrt(np.abs(quad_area(np.stack([found[m][0] for m in ids])))) * step).tolist(),
                      strict=True)) if ids else {})
    while True:
        agree, disagree = _pair_votes(found, obj, grid, ids, pitch, factor)
        confirmed = [m for m, y, n in zip(ids, agree, disagree, strict=True) if y >= 1 and y > n]
        # One place, one marker: two confirmed markers on one quad (a code read with a bit
        # corrected as another's) cannot both be right. The one fewer pairs confirm goes (both
        # where as many confirm each), and the votes are counted again without it: two such
        # misreadings shifted alike confirm each other (rendered view 434 of the wide-board
        # probe: ARUCO_ORIGINAL markers 2 and 18 read also as 0 and 16, 4 squares off).
        votes = dict(zip(ids, agree.tolist(), strict=True))
        gone = _one_place_one_marker(found, confirmed, votes, pitch, step)
        if not gone:
            break
        ids = [m for m in ids if m not in gone]
    return confirmed, {m: homs[m] for m in confirmed}, pitch


def _pair_votes(found: dict[int, list[np.ndarray]], obj: np.ndarray, grid: np.ndarray, ids: list[int],
                pitch: dict[int, float], factor: int) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``ids``, how many of the pairs within two places of it fit one homography
    and how many do not (:func:`confirm_markers`)."""
    agree = np.zeros(len(ids), dtype=np.int64)
    disagree = np.zeros(len(ids), dtype=np.int64)
    if len(ids) >= 2:
        markers_kernels.pair_votes(np.ascontiguousarray(obj[ids], dtype=np.float64),
                                   np.stack([found[m][0] for m in ids]).astype(np.float64),
                                   np.ascontiguousarray(grid[ids], dtype=np.int64),
                                   np.array([pitch[m] for m in ids], dtype=np.float64), 2.0 * factor, agree, disagree)
    return agree, disagree


def _one_place_one_marker(found: dict[int, list[np.ndarray]], confirmed: list[int], votes: dict[int, int],
                          pitch: dict[int, float], step: float) -> set[int]:
    """The confirmed markers that share their place with another confirmed one (centres within
    half the smaller marker's side) and have fewer confirming pairs (``votes``) than it; both
    where they have as many."""
    if len(confirmed) < 2:
        return set()
    centre = np.stack([found[m][0] for m in confirmed]).mean(axis=1)
    side = np.array([pitch[m] for m in confirmed]) / step
    d = np.hypot(*(centre[:, None] - centre[None]).transpose(2, 0, 1))
    a, b = np.nonzero(np.triu(d < 0.5 * np.minimum(side[:, None], side[None]), k=1))
    gone: set[int] = set()
    for i, j in zip(a.tolist(), b.tolist(), strict=True):
        va, vb = votes[confirmed[i]], votes[confirmed[j]]
        if va <= vb:
            gone.add(confirmed[i])
        if vb <= va:
            gone.add(confirmed[j])
    return gone


def drop_poor_fits(out: np.ndarray, sig: np.ndarray, typical: TypicalSigma | None = None,
                   win: np.ndarray | None = None, sm: np.ndarray | None = None,
                   group: np.ndarray | None = None, res: np.ndarray | None = None) -> None:
    """Clear (NaN) the corners whose saddle fit's sigma is over ``_SIGMA_RATIO`` (twice) the
    typical sigma, as the checkerboard's: ``typical``'s for each corner's window ``win`` (N,),
    smoothing ``sm`` (N,) and group ``group`` (N,) (a fit's sigma depends on all three), else
    the median of all; with ``res`` (N,: the fits' residuals' standard deviations), kept where
    their residuals pass instead (:meth:`TypicalSigma.passes`)."""
    good = np.isfinite(sig)
    if good.any():
        if typical is None:
            bad = good & (sig > _SIGMA_RATIO * np.median(sig[good]))
        else:
            bad = good & ~typical.passes(sig, win, _SIGMA_RATIO, sm, group, res)
        out[bad] = np.nan
        sig[bad] = np.nan


#: A fit whose sigma is over the typical one but whose residuals are not is kept only where
#: its sigma is at most this (px; as the checkerboard's ``_MAX_CORNER_SIGMA``: under Gaussian
#: errors a pixel off with a chance of 0.03 %).
MAX_LOW_CONTRAST_SIGMA = 0.25


class TypicalSigma:
    """A typical saddle-fit sigma for each window, smoothing and group: the larger of the
    median of all the corners' own fits (``sig`` (K,), at ``pts`` (K, 2), fitted with windows
    ``win`` (K,) on the image ``full`` smoothed by ``sm`` (K,), default ``smoothing(win)``) and
    the median of the group's corners fitted with a window within a pixel of it, refitted with
    it (and that smoothing), computed once per triple. A fit's sigma grows with its window
    against the square (a quadratic follows the smoothed junction less far out: on a small,
    noisy board, squares of 25-29 px, twice as high with 3 px as with 2 px, the two windows its
    rounding gives), and with less smoothing (more of the noise is left), so a corner whose
    window rounds up is not judged by the others' smaller ones. Only corners with a window near
    it are refitted: a larger window on a smaller square fits worse still, and would excuse a
    poor fit. ``group`` (K,), default all one: corners whose surroundings differ in a way the
    fit sees (a ChArUco board's two chiralities: on a sheared board one has its markers in the
    acute sectors, beside the corner) are judged against their own kind.

    The same for the fits' residuals (their standard deviation, the sigma without the saddle's
    curvature), from the same corners refitted: a junction of less contrast than the others
    (thinner white margins under blur, on the far side of a tilted board) fits as well but
    places its saddle less surely, and its sigma alone would call it poor (seed 210 of the
    ChArUco corpus: a corner 0.04 px from the truth with 2.1 times the typical sigma)."""

    #: At most this many corners are refitted per window (evenly over those near it): a
    #: median needs no more, and the refits cost.
    MAX_REFITS = 16

    def __init__(self, full: np.ndarray, pts: np.ndarray, sig: np.ndarray, win: np.ndarray,
                 smoothing: Callable[[int], float], sm: np.ndarray | None = None,
                 group: np.ndarray | None = None, noise: float | None = None) -> None:
        self.noise = noise
        ok = np.isfinite(sig)
        self.full, self.pts, self.sig, self.win, self.smoothing = full, pts[ok], sig[ok], win[ok], smoothing
        self.sm = self._smoothings(win, sm)[ok]
        self.group = (np.zeros(len(sig), dtype=np.int64) if group is None else np.asarray(group))[ok]
        self.floor = float(np.median(sig[ok])) if ok.any() else np.inf
        self.cache: dict[tuple[int, float, int], tuple[float, float]] = {}

    def _smoothings(self, win: np.ndarray, sm: np.ndarray | None) -> np.ndarray:
        if sm is not None:
            return np.asarray(sm, dtype=np.float64)
        out = np.zeros(len(win))
        for r in np.unique(win):  # one smoothing per window
            out[win == r] = self.smoothing(int(r))
        return out

    def _typical(self, r: int, s: float, g: int) -> tuple[float, float]:
        if (r, s, g) not in self.cache:
            mine = self.group == g
            same = mine & (self.win == r) & (self.sm == s)  # fitted with them already: their own sigmas
            other = np.flatnonzero(mine & (np.abs(self.win - r) <= 1) & ~same)
            other = other[np.linspace(0, len(other) - 1, min(len(other), self.MAX_REFITS)).astype(int)]
            sg = self.sig[same]
            if len(other):
                sg = np.concatenate([sg, refine_patches(self.full, self.pts[other], r, s, iters=1)[1]])
            sg = sg[np.isfinite(sg)]
            # The residuals: the group's corners near the window, refitted with it.
            near = np.flatnonzero(mine & (np.abs(self.win - r) <= 1))
            near = near[np.linspace(0, len(near) - 1, min(len(near), self.MAX_REFITS)).astype(int)]
            rs = refine_patches(self.full, self.pts[near], r, s, iters=1, residuals=True)[2] if len(near) else near
            rs = rs[np.isfinite(rs)]
            self.cache[(r, s, g)] = (max(self.floor, float(np.median(sg))) if len(sg) else self.floor,
                                     float(np.median(rs)) if len(rs) else np.nan)
        return self.cache[(r, s, g)]

    def at(self, r: int, s: float | None = None, g: int = 0) -> float:
        """The typical sigma with window ``r``, smoothing ``s`` (default ``smoothing(r)``) in
        group ``g``; the floor (the median of all) where none of the group gives one."""
        return self._typical(r, self.smoothing(r) if s is None else float(s), g)[0]

    def residual_at(self, r: int, s: float | None = None, g: int = 0) -> float:
        """The typical residuals' standard deviation with window ``r``, smoothing ``s`` in group
        ``g``; NaN where none of the group has a window within a pixel of ``r``."""
        return self._typical(r, self.smoothing(r) if s is None else float(s), g)[1]

    def passes(self, sig: np.ndarray, win: np.ndarray, ratio: float, sm: np.ndarray | None = None,
               group: np.ndarray | None = None, res: np.ndarray | None = None,
               cap: float = MAX_LOW_CONTRAST_SIGMA) -> np.ndarray:
        """Which fits (sigmas ``sig`` (N,) with windows ``win`` (N,), smoothings ``sm`` (N,),
        default ``smoothing(win)``, in groups ``group`` (N,), default all one) are at most
        ``ratio`` times the typical sigma for their triple, or, given their residuals' standard
        deviations ``res`` (N,), whose residuals are at most ``ratio`` times the typical ones
        and whose sigma is at most ``cap`` (:data:`MAX_LOW_CONTRAST_SIGMA`); NaN sigmas do not pass. A
        triple is refitted only where one of its fits is over ``ratio`` times the floor (the
        typical sigma is never below it).

        Given the image's ``noise`` (per pixel, at construction), the sigma held to that bound
        is the one the noise gives through the fit (:func:`noise_sigma`), not the fit's own:
        residuals as typical as the board's are the quadratic's misfit to the junction as much
        as noise, and the fit's sigma takes them all for noise. Where the saddle is shallow
        (the junction's lines near parallel, a small window kept clear of the markers) it
        multiplies them into a sigma of 0.6-0.9 px on corners 0.05-0.15 px from the truth
        (seed 89 of the ChArUco corpus, noise-free)."""
        ok = np.isfinite(sig) & (sig <= ratio * self.floor)
        over = np.isfinite(sig) & ~ok
        if over.any():
            sm = self._smoothings(win, sm)
            grp = np.zeros(len(sig), dtype=np.int64) if group is None else np.asarray(group)
            for r, s, g in {(int(a), float(b), int(c)) for a, b, c in zip(win[over], sm[over], grp[over], strict=True)}:
                k = over & (win == r) & (sm == s) & (grp == g)
                typ, typ_res = self._typical(r, s, g)
                ok[k] = sig[k] <= ratio * typ
                if res is not None:
                    held = sig[k] if self.noise is None else noise_sigma(sig[k], res[k], r, s, self.noise)
                    with np.errstate(invalid="ignore"):
                        ok[k] |= (res[k] <= ratio * typ_res) & (held <= cap)
        return ok


def noise_sigma(sig: np.ndarray, res: np.ndarray, r: int, smoothing: float, noise: float) -> np.ndarray:
    """The sigma white noise of ``noise`` per pixel gives saddle fits with window ``r`` on the
    image smoothed by ``smoothing`` whose own sigmas (from their residuals, as if independent)
    are ``sig`` and residuals' standard deviations ``res`` (N,): the fit's sigma is
    ``sqrt(var (A^T A)^-1_33 S / 2)`` (S from the saddle's Hessian, var = res^2), the noise's
    ``sqrt(noise^2 (P K P^T)_33 S / 2)`` (:func:`_fit_noise_factors`: the smoothed noise's
    correlation K); so the ratio of the two scales ``sig``. NaN where ``sig`` is."""
    ata33 = _saddle_design(r)[1]
    var_grad = _fit_noise_factors(r, smoothing)[1][0]
    with np.errstate(divide="ignore", invalid="ignore"):
        return sig * noise * np.sqrt(var_grad / ata33) / res


def image_noise(grey: np.ndarray) -> float:
    """:func:`camkit.target.checkerboard._image_noise` of the image (a :class:`RawGrey` through
    its stretch), and a quarter of an 8-bit quantum at least (a noise-free render's
    differences are mostly 0: its rounding, 1 / sqrt(12) of a level, is the noise left)."""
    if isinstance(grey, RawGrey):
        return max(abs(grey.a) * _image_noise(grey.raw), 0.25 * abs(grey.a))
    return max(_image_noise(grey), 0.25 / 255.0)


def _local_fits(rel: np.ndarray, near: np.ndarray, wide: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """For each query k: the image point the map target -> image predicts at the query, fitted
    on the known points j (``rel`` (K, J, 2): j's target-frame place seen from k over the
    radius; ``near``/``wide`` (K, J): j within the radius / 1.6 radius and usable; ``pts``
    (J, 2)): quadratic on the near ones where eight or more, else on the wide ones where eight
    or more, else affine on four to seven wide ones; NaN where fewer. (K, 2)."""
    K = len(rel)
    terms = np.stack([np.ones(rel.shape[:2]), rel[..., 0], rel[..., 1], rel[..., 0] ** 2, rel[..., 0] * rel[..., 1],
                      rel[..., 1] ** 2], axis=-1)
    n_near, n_wide = near.sum(axis=1), wide.sum(axis=1)
    out = np.full((K, 2), np.nan)
    for nt, within, which in ((6, near, n_near >= 8), (6, wide, (n_near < 8) & (n_wide >= 8)),
                              (3, wide, (n_near < 8) & (n_wide >= 4) & (n_wide < 8))):
        k = np.flatnonzero(which)
        if not len(k):
            continue
        A = terms[k][:, :, :nt] * within[k][:, :, None]
        M = np.einsum("kji,kjl->kil", A, terms[k][:, :, :nt])
        b = np.einsum("kji,jc->kic", A, pts)
        ok = np.linalg.cond(M) < 1e10
        c = np.full((len(k), nt, 2), np.nan)
        c[ok] = np.linalg.solve(M[ok], b[ok])
        out[k] = c[:, 0, :]
    return out


def predict_points(obj: np.ndarray, pts: np.ndarray, query: np.ndarray, radius: float,
                   usable: np.ndarray | None = None) -> np.ndarray:
    """Image places of the target-frame points ``query`` (K, 2) from the found points (``obj``
    (N, 2), ``pts`` (N, 2)) around each (:func:`_local_fits`), those of ``usable`` (K, N) only
    where given; NaN where too few are near."""
    rel = (obj[None, :, :] - query[:, None, :]) / radius
    reach = np.abs(rel).max(axis=2)
    if usable is None:
        return _local_fits(rel, reach <= 1.0, reach <= 1.6, pts)
    return _local_fits(rel, (reach <= 1.0) & usable, (reach <= 1.6) & usable, pts)


def consistent_points(obj: np.ndarray, pts: np.ndarray, radius: float, tol: np.ndarray) -> np.ndarray:
    """Which of the found points (target-frame ``obj`` (N, 2), image ``pts`` (N, 2)) agree with
    their neighbours: each against the map fitted on the others around it (:func:`_local_fits`:
    a quadratic on those within ``radius`` in the target frame, or within ``1.6 radius``; an
    affine map from four to seven), missing it by at most ``tol`` (N,) pixels. The worst
    offender in its own neighbourhood goes first, round by round, so that one wrong point does
    not condemn its neighbours; a point with fewer than four neighbours cannot be checked and
    goes. Two points at one place (one X-junction given two labels) both go."""
    n = len(obj)
    keep = np.ones(n, dtype=bool)
    if n == 0:
        return keep
    d = np.hypot(*(pts[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    keep &= d.min(axis=1) > 0.5 * tol
    rel = (obj[None, :, :] - obj[:, None, :]) / radius  # (k, j, 2): j seen from k
    reach = np.abs(rel).max(axis=2)
    own = np.eye(n, dtype=bool)
    near = (reach <= 1.0) & ~own
    wide = (reach <= 1.6) & ~own
    for _ in range(8):
        res = np.full(n, np.inf)
        k = np.flatnonzero(keep)
        pred = _local_fits(rel[k], near[k] & keep[None, :], wide[k] & keep[None, :], pts)
        res[k] = np.hypot(*(pred - pts[k]).T)
        bad = keep & ~(res <= tol)
        if not bad.any():
            break
        ratio = np.where(bad, res / tol, 0.0)
        ratio[~np.isfinite(ratio)] = 1e300
        # The worst within its own neighbourhood goes.
        worst = bad & (ratio >= np.max(np.where(wide & keep[None, :], ratio[None, :], 0.0), axis=1))
        keep &= ~worst
    return keep


def neighbour_quads(obj: np.ndarray, grid: np.ndarray, quads: dict[int, np.ndarray],
                    misfit: dict[int, float] | None = None, bend: float = 0.0,
                    shape: tuple[int, ...] = (0, 0), only: np.ndarray | None = None) -> dict[int, np.ndarray]:
    """Where each of the board's markers should be, from its neighbours: for every marker with
    one or more markers of ``quads`` (id -> (4, 2) image corners) within one place of it on the
    layout ``grid`` (itself left out), its corners ``obj`` (M, 4, 2) through the least-squares
    homography of those neighbours' corners. One fit per marker, batched by neighbour count.
    ``misfit``, where given, is filled with each fit's largest miss of those corners (px).
    ``bend`` (with the image's ``shape``): fitted on the corners through :func:`undistort`,
    the places taken back through :func:`distort` (misses in undistorted pixels). ``only``:
    the markers wanted (booleans, M), where not all (each marker's fit is its own)."""
    have = np.array(sorted(quads), dtype=np.int64)
    if not len(have):
        return {}
    near = (np.abs(grid[:, None, :] - grid[None, have, :]).max(axis=2) <= 1) & (np.arange(len(grid))[:, None]
                                                                               != have[None, :])
    count = near.sum(axis=1)
    if only is not None:
        count[~only] = 0
    img = undistort(np.stack([quads[m] for m in have]), bend, shape)
    out: dict[int, np.ndarray] = {}
    for c in np.unique(count[count > 0]):  # one batched fit per neighbour count
        ms = np.flatnonzero(count == c)
        nb = np.stack([have[near[m]] for m in ms])  # (K, c)
        idx = np.searchsorted(have, nb)
        src = obj[nb].reshape(len(ms), 4 * c, 2)
        dst = img[idx].reshape(len(ms), 4 * c, 2)
        Hs = fit_homographies(src, dst)
        pred = distort(apply_homographies(Hs, obj[ms]), bend, shape)
        miss = np.hypot(*(apply_homographies(Hs, src) - dst).transpose(2, 0, 1)).max(axis=1)
        for m, q, e in zip(ms, pred, miss, strict=True):
            if np.isfinite(q).all():
                out[int(m)] = q
                if misfit is not None:
                    misfit[int(m)] = float(e)
    return out


def recover_markers(grey: np.ndarray, d: ArucoDictionary, border: int, obj: np.ndarray, grid: np.ndarray,
                    quads: dict[int, np.ndarray], bend: float = 0.0) -> dict[int, np.ndarray]:
    """The board's markers ``quads`` (id -> confirmed (4, 2) corners, full-image pixels) and
    those the neighbours find: a marker not among them (its quad not found, or merged with
    something beside it) is read where its neighbours put it (:func:`neighbour_quads`), or
    where that does not read, with those corners refined to its sides' edges
    (:func:`refine_quads`), and kept where it reads as its own id the right way up. Rounds
    until none is added, so that a row of markers is recovered from one side. ``bend``: the
    lens's (:func:`undistort`), for the neighbours' homography and the reading."""
    quads = dict(quads)
    H, W = grey.shape
    tried: set[int] = set()
    while len(quads) < len(obj):  # (every marker of the board there: none to look for)
        wanted = np.ones(len(obj), dtype=bool)
        wanted[[*quads, *tried]] = False
        pred = neighbour_quads(obj, grid, quads, bend=bend, shape=grey.shape, only=wanted)
        inside = [m for m, q in pred.items()
                  if (q >= 1).all() and (q[:, 0] <= W - 2).all() and (q[:, 1] <= H - 2).all()]
        if not inside:
            return quads
        tried.update(inside)
        q = np.stack([pred[m] for m in inside])
        ids, turns = read_markers(grey, q, d, border, bend=bend)
        # Through a wide lens the neighbours' homography puts a marker at the board's edge a
        # cell or more off: a quad that does not read is read again with its corners where its
        # sides' edges meet (corpus view 878: markers 5 and 11, 8-13 px across at 69 degrees).
        miss = np.flatnonzero((ids != np.asarray(inside)) | (turns != 0))
        if len(miss):
            rq = refine_quads(grey, q[miss], d.marker_size + 2 * border)
            ids2, turns2 = read_markers(grey, rq, d, border)
            q[miss], ids[miss], turns[miss] = rq, ids2, turns2
        # Where that does not read either (a prediction several pixels off: a fisheye's rim),
        # the marker's quad is looked for around it on the full image (a marker the coarser
        # level read no quad of: corpus view 100's markers 0, 5 and 11 at 75 degrees, 2-9 px off).
        for j in np.flatnonzero((ids != np.asarray(inside)) | (turns != 0)):  # a few markers, one by one
            got = _quad_near(grey, q[j], d, border, inside[j])
            if got is not None:
                q[j], ids[j], turns[j] = got, inside[j], 0
        added = False
        for m, i, k, qm in zip(inside, ids, turns, q, strict=True):
            if i == m and k == 0:
                quads[m] = qm
                added = True
        if not added:
            return quads
    return quads


def _quad_near(grey: np.ndarray, pred: np.ndarray, d: ArucoDictionary, border: int, m: int) -> np.ndarray | None:
    """Marker ``m``'s quad (4, 2) in its code's order, looked for on the square of the full
    image around its predicted corners ``pred`` (4, 2) that reaches a side beyond them: the
    quads of that patch (thresholded with windows of a quarter and a half of the marker's
    side), read as codes (and, with a marker's border, refined and read again), the one that
    reads as ``m`` with each corner within half a side of its prediction; None where none
    does."""
    H, W = grey.shape
    side = float(np.hypot(*(pred - np.roll(pred, 1, axis=0)).T).max())
    n = d.marker_size + 2 * border
    if not np.isfinite(side) or side < MIN_CELL_PX * n:
        return None
    lo = np.maximum(np.floor(pred.min(axis=0) - side), 0).astype(np.int64)
    hi = np.minimum(np.ceil(pred.max(axis=0) + side), [W - 1, H - 1]).astype(np.int64)
    if (hi - lo < 2 * side).any():
        return None
    if isinstance(grey, RawGrey):
        patch = grey.raw[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1] * grey.a + grey.b
    else:
        patch = np.array(grey[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1], dtype=np.float64)
    quads = find_quads(patch, int(np.ceil(MIN_CELL_PX * n)), opening=border >= 2,
                       radii=(max(3, int(side / 4)), max(3, int(side / 2))))
    if not len(quads):
        return None
    codes, turns, rimmed = read_markers_rims(patch, quads, d, border)
    if border == 1 and ((codes < 0) & rimmed).any():
        quads, codes, turns = _read_refined(patch, quads, codes, turns, rimmed, d, border)
    for k in np.flatnonzero(codes == m):
        q = quads[k][(np.arange(4) - turns[k]) % 4] + lo
        if (np.hypot(*(q - pred).T) <= 0.5 * side).all():
            return q
    return None


def extend_lattice(P: np.ndarray, X: np.ndarray, Y: np.ndarray, xs: np.ndarray,
                   ys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a board's lattice of points puts the places ``(X, Y)`` (column and row indices),
    and its steps there along the board's x (``u``) and y (``v``) per unit of the board frame,
    each (K, 2), NaN where unknown. ``P`` (rows, columns, 2): the points found, NaN where not,
    with three rows and columns of NaN around the board; ``xs``, ``ys``: the board-frame
    coordinate of each of its columns and rows (a rectilinear grid, not necessarily evenly
    spaced).

    The place completes a rectangle of three found points (a parallelogram in the image:
    exact to first order however perspective and the lens bend the board), the mean of every
    rectangle that gives one; else continues a row or column of three found points (Lagrange
    quadratic in the board coordinate) or two (linear), the mean of those."""
    def at(dx: int, dy: int) -> np.ndarray:
        return P[Y + dy, X + dx]

    par, quad, lin, us, vs = [], [], [], [], []
    with np.errstate(invalid="ignore"):
        for dx in (1, -1):
            for dy in (1, -1):
                a, b, d = at(dx, 0), at(0, dy), at(dx, dy)
                par.append(a + b - d)
                us.append((d - b) / (xs[X + dx] - xs[X])[:, None])
                vs.append((d - a) / (ys[Y + dy] - ys[Y])[:, None])
        for (ex, ey), steps in (((1, 0), us), ((-1, 0), us), ((0, 1), vs), ((0, -1), vs)):
            p1, p2, p3 = at(ex, ey), at(2 * ex, 2 * ey), at(3 * ex, 3 * ey)
            c = xs if ex else ys
            i = X if ex else Y
            e = ex + ey
            t0, t1, t2, t3 = (c[i][:, None], c[i + e][:, None], c[i + 2 * e][:, None], c[i + 3 * e][:, None])
            quad.append(p1 * ((t0 - t2) * (t0 - t3) / ((t1 - t2) * (t1 - t3)))
                        + p2 * ((t0 - t1) * (t0 - t3) / ((t2 - t1) * (t2 - t3)))
                        + p3 * ((t0 - t1) * (t0 - t2) / ((t3 - t1) * (t3 - t2))))
            lin.append(p1 + (p1 - p2) * ((t0 - t1) / (t1 - t2)))
            steps.append((p1 - p2) / (t1 - t2))

    def mean(vals: list[np.ndarray]) -> np.ndarray:
        v = np.stack(vals)
        n = np.isfinite(v[..., 0]).sum(axis=0)
        with np.errstate(invalid="ignore"):
            return np.where(n[:, None] > 0, np.nansum(v, axis=0) / np.maximum(n, 1)[:, None], np.nan)

    pred = mean(par)
    for more in (quad, lin):
        pred = np.where(np.isfinite(pred), pred, mean(more))
    return pred, mean(us), mean(vs)


def lattice_rounds(out: np.ndarray, nx: int, ny: int, xs: np.ndarray, ys: np.ndarray):
    """Rounds of growing a board's lattice of points (``out`` (ny nx, 2), row by row, NaN where
    not found; the caller writes the points it keeps into ``out`` between rounds). Each round
    yields ``(cand, pred, u, v, others)``: the points not found that have more found
    neighbours (of the eight around) than when last tried, where :func:`extend_lattice` puts
    them (``xs``, ``ys``: the board coordinates of the columns and rows, three beyond the
    board each side), its steps per board unit, and the places of each one's four neighbours
    along the rows and columns, (K, 4, 2). Ends when fewer than three points are found or no
    point has new neighbours."""
    tried_with = np.zeros(nx * ny, dtype=np.int64)
    for _ in range(2 * (nx + ny)):
        have = np.isfinite(out).all(axis=1)
        if have.sum() < 3:
            return
        P = np.full((ny + 6, nx + 6, 2), np.nan)
        P[3:-3, 3:-3] = out.reshape(ny, nx, 2)
        f = np.isfinite(P[..., 0])
        nb = sum(f[3 + dy:ny + 3 + dy, 3 + dx:nx + 3 + dx] for dy in (-1, 0, 1) for dx in (-1, 0, 1)
                 if dx or dy).ravel().astype(np.int64)
        cand = np.flatnonzero(~have & (nb > tried_with))
        if not len(cand):
            return
        tried_with[cand] = nb[cand]
        X, Y = cand % nx + 3, cand // nx + 3
        pred, u, v = extend_lattice(P, X, Y, xs, ys)
        others = np.stack([pred + u * (xs[X + 1] - xs[X])[:, None], pred + u * (xs[X - 1] - xs[X])[:, None],
                           pred + v * (ys[Y + 1] - ys[Y])[:, None], pred + v * (ys[Y - 1] - ys[Y])[:, None]], axis=1)
        yield cand, pred, u, v, others


def fit_inside(q: np.ndarray, r: int, shape: tuple[int, ...]) -> np.ndarray:
    """Which saddle fits at ``q`` (K, 2) with window ``r`` have the window and its bicubic
    support inside an image of ``shape``: past the edge the smoothing repeats the last row, and
    a junction cut by the edge is pulled off (a ChArUco corner 3 px from the edge, predicted
    within 0.02 px, fitted 1.9 px off: seed 901 of the corpus)."""
    H, W = shape[:2]
    m = r + 2
    return (q[:, 0] >= m) & (q[:, 0] <= W - 1 - m) & (q[:, 1] >= m) & (q[:, 1] <= H - 1 - m)


def apart_from_found(q: np.ndarray, found: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """Which of the new points ``q`` (K, 2) lie more than ``tol`` (K,) from every point of
    ``found`` (N, 2) and from each other: one junction, one label (a point that ends on
    another is that one)."""
    if not len(q):
        return np.zeros(0, dtype=bool)
    pts = np.concatenate([found, q])
    d = np.hypot(*(q[:, None] - pts[None]).transpose(2, 0, 1))
    d[np.arange(len(q)), len(found) + np.arange(len(q))] = np.inf
    return d.min(axis=1) > tol
