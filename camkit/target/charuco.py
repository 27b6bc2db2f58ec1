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
   it, three window sizes), 4-connected; each region the size of a marker (two pixels a cell
   at least, and on the full image down to 1.25 where the image's noise leaves such cells
   readable, their border read first) gives a quad (the farthest pixel from its centre, the
   farthest from that, and the farthest from the line through both on either side);
2. the quad's cells are sampled through the homography of the unit square (3 x 3 samples in
   the middle of each cell), thresholded halfway between the black border and the white
   margin around the marker; a border that is not black, or bits more than the dictionary's
   correction away from every code in all four turns, reject the quad; a quad read has its
   corners moved to where the lines of its sides' edges meet
   (:func:`~camkit.target._markers.refine_quads`), and a quad with a marker's border that
   reads as nothing is read again so (its extreme pixels a pixel off a slanted marker's
   corners shift every sample half a cell at two pixels a cell);
3. the markers' ids are checked against the board: an id the board does not have is
   another board's; an id seen twice is dropped; and each marker must be confirmed by a
   neighbour (another marker within two squares such that one homography maps both markers'
   board corners onto their eight image corners within 15 % of a square, 2 px at least) and
   contradicted by fewer than confirm it. On a board with an even number of rows, where the
   markers confirm more under the other ``legacy`` setting (OpenCV's layout before or since
   4.6, which moves markers a square along their rows), the board is not found (its labels
   would be a square off). Where fewer than six are confirmed (markers too
   small or blurred to read one by one), the board is read as a whole: the chessboard's
   lattice of X-junctions (the checkerboard detector's steps 1-2, its links tested for a black
   and a white square either side inside the white margin too), each square bounded by four
   of its corners sampled at the code's cells, and every placement of the lattice on the
   board (four turns, every shift) scored by the correlation of its marker squares with the
   codes it puts there; the best is taken only where it stands :data:`_BOARD_Z` standard
   deviations above chance and :data:`_BOARD_MARGIN` above the next placement, and its
   markers are confirmed as those read one by one. A marker not read is read where its
   confirmed neighbours put it, or where that does not read, at its sides' edges there, or
   at a quad looked for on the full image around that place
   (:func:`~camkit.target._markers.recover_markers`), and kept where it reads as its id the
   right way up;
4. each chessboard corner next to a confirmed marker is predicted from them (where both
   markers touching it are confirmed, the midpoint of their corners nearest it, which lie
   either side of it on a diagonal, else its marker's homography) and placed at the saddle
   point of the smoothed image
   (camkit's sub-pixel estimator, window an eleventh of the square's image size, 2 to 5 px,
   smoothing 1.5 px, both less where they would reach the corner's markers: on a sheared
   board the markers in the acute sectors come near it), with its sigma; a corner that
   moves more than a tenth of a square (1.5 px at least), that is not an X-junction on a
   circle inside the white margin (four alternating, point-symmetric sectors; where the
   markers in the acute sectors of a sheared board come nearer than the margin's width, a
   circle clear of them is tried too, and where both fail, a circle on the board through
   the corner's steps: seen 70-80 degrees from square on, an image circle all but misses
   the acute sectors), whose
   colours on that circle disagree with its label (dark towards its black squares, light
   towards its white ones: where blur joins two thin margins, their crossing beside a
   marker is a saddle too), or whose fit's sigma is over twice the typical one for its
   window, smoothing and kind of corner (:class:`~camkit.target._markers.TypicalSigma`: the
   median of the corners beside markers, or where higher, of those of its kind with a window
   within a pixel of it refitted with it; a fit's sigma grows with its window, and on a
   sheared board the corners with their markers in the acute sectors fit worse), is dropped;
5. the chessboard past the markers read (markers too small, blurred or hidden to read): round
   by round, each corner next to found ones is predicted from them on the board (completing a
   square of three found corners, else continuing a row or column), found at its saddle point
   on the markers' pyramid level (a window and smoothing of a fifth and a twelfth of a square,
   the window kept clear of the corner's markers; where none fits, from the prediction)
   and then on the full image, and kept where it lies within 0.15 of a square of its
   prediction, twice as near it as its neighbours' predicted places, on no other found
   corner, with its black squares dark where the lattice puts them, and passes the tests of
   step 4, its sigma judged as there or, where over, its residuals (at most twice the
   typical) with the sigma the image's noise gives its fit at most a quarter of a pixel;
   where no coarse window fits, the fits started a window's radius about the prediction find
   no saddle that fits better (a smaller sigma) within the reach and over a pixel from it (a
   corner refused so has two saddles in reach, and is not tried again in a later round).
   Each corner's sigma is its fit's own (its residuals taken as noise): where the quadratic
   misfits a shallow saddle it overstates the error (0.6-0.9 px at 0.05-0.15 px off: corpus
   view 89) and is an upper bound.
6. the corners still missing with four or more of their eight neighbours found, or fewer
   and a confirmed marker in one of their squares: predicted by the neighbours' local map
   (with fewer than four, the homography of the neighbours and the markers' corners: a
   corner at the board's edge or beside two unread markers) and placed at their point of
   symmetry (the checkerboard's step 9), read out to 0.7 of the box inside the markers'
   black borders, where the board is point-symmetric about the corner; kept within 0.15 of
   a square of the prediction, with residuals of a symmetric junction (at most twice those
   of the board's found corners placed the same way, or of its noise where higher, and 0.02
   of the board's range), a sigma of at most 0.1 px (the estimator's own), an X-junction
   with its label's colours, on no other corner (more than half the way to its nearest
   neighbour on the board from every found corner). The saddle fit's small window leaves sheared or noisy
   junctions beside markers a poor fit (corpus view 98: sigmas 0.74-0.79 px); the symmetric
   point reads the junction's edges and the markers' borders.
7. a corner beside markers whose fit in step 4 found no saddle near its prediction, and that
   no later step found: searched for from that prediction with a window of a third of its
   clearance from the markers and as much smoothing as keeps clear of them (a twelfth of the
   square at most), then refined and tested as growth's corners. Through a fisheye the
   markers of squares 200 px across predict their corners a few pixels off, beyond the fine
   fit's window of at most 5 px.
8. light: a shadow's edge or uneven light across a corner moves its saddle point (up to a
   pixel on OpenCV's tutorial photos half in a shadow). The light within the fit's reach is
   read from pairs of places mirrored through the corner, where the board is plain (the
   white squares' margins, the black squares), as a slope of its level and of its strength
   (:func:`_light`); where it is beyond its noise and fits those places, the corner's patch is
   divided by it and the saddle fitted again, its sigma grown by the reading's; where it is
   there but does not fit (an occluder, light that bends within the squares), the corner
   stays, the move it implies added to its sigma (dropped where that passes a quarter of a
   pixel, as the checkerboard drops corners). Corners placed by their point of symmetry
   (step 6) are not read again.
9. margins too thin: where a corner's narrower white margin (between a black square's edge
   and the marker beside it, through the square's steps measured from its found neighbours
   or its markers) is under :data:`_MIN_MARGIN_PX` across, the fit sees the markers' borders
   and its residuals are no longer taken for noise: its sigma must pass as in step 4
   (:func:`_drop_unresolved`).

Every returned corner is labelled by markers read where the board's layout puts them, directly
or through a chain of squares from one, so a board half out of the frame gives every corner it
shows that is joined to a confirmed marker.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Self

import numpy as np

from camkit._kernels import detect as detect_kernels
from camkit._kernels import markers as markers_kernels
from camkit._validate import as_positive_float, as_positive_int
from camkit.errors import ParameterError
from camkit.target._homography import apply_homographies, fit_homographies
from camkit.target._markers import (
    TypicalSigma,
    add_marker,
    apart_from_found,
    better_saddle_near,
    confirm_markers,
    drop_poor_fits,
    find_markers,
    fit_inside,
    image_noise,
    lattice_rounds,
    quad_area,
    recover_markers,
    refine_patches,
    unconfirmed_reason,
    x_corner_shades,
    x_shades,
)
from camkit.target.aruco import ArucoDictionary, get_dictionary
from camkit.target.base import Detection, Sheet, Target, register_target
from camkit.target.checkerboard import (
    _MAX_CORNER_SIGMA,
    _SHADE_CHI2,
    _SHADE_MAX_SHIFT,
    _SHADE_MISFIT,
    _SIGMA_RATIO,
    _SYM_SMOOTHING,
    _grid_spacing,
    _lattices,
    _local_maps,
    _local_steps,
    _map_ends,
    _saddle_design,
    _saddle_fit,
    _sample,
    _smoothed_patches,
    _split_map,
    _stretched,
    _symmetry_sigma,
    _to_grey,
)

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

    @property
    def n_points(self) -> int:
        """The inner chessboard's corners, ``(squares_x - 1) (squares_y - 1)``: as many as
        :meth:`object_points` has rows, without making them."""
        return (self.squares_x - 1) * (self.squares_y - 1)

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


@functools.lru_cache(maxsize=32)
def _layout(board: Charuco) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The board's marker squares (M, 2), its markers' corners on the board ((M, 4, 2), x and
    y in metres) and which of its squares hold a marker ((squares_y, squares_x) booleans),
    read-only: a detection reads them many times, and a board (frozen) keeps its layout."""
    ms = board.marker_squares()
    obj = np.ascontiguousarray(board.marker_corners()[:, :, :2])
    white = np.zeros((board.squares_y, board.squares_x), dtype=bool)
    white[ms[:, 1], ms[:, 0]] = True
    for a in (ms, obj, white):
        a.flags.writeable = False
    return ms, obj, white


def _other_layout(board: Charuco, found: dict[int, list[np.ndarray]], factor: int) -> str:
    """Where markers were read but none is where ``board``'s layout puts it: the layout they
    fit, among the two mistakes a user makes with a board (the squares counted the other way
    round; OpenCV's layout before 4.6, ``legacy``, which differs on boards with an even number
    of rows), as a clause to add to the reason; "" where none fits (or nothing was read)."""
    if not any(m < board.n_markers and len(c) == 1 for m, c in found.items()):
        return ""
    turned = (board.squares_y, board.squares_x)
    options = [(turned, board.legacy, f"a {turned[0]}x{turned[1]}-square board (the squares counted the other way "
                                      "round)")]
    for sx, sy in ((board.squares_x, board.squares_y), turned):
        if sy % 2 == 0:  # legacy changes the layout only where the rows are even
            flip = ("OpenCV's layout before 4.6 (legacy=True)" if not board.legacy
                    else "OpenCV's layout since 4.6 (legacy=False)")
            options.append(((sx, sy), not board.legacy, f"a {sx}x{sy}-square board in {flip}"))
    for (sx, sy), legacy, words in options:
        if _n_confirmed(replace(board, squares_x=sx, squares_y=sy, legacy=legacy), found, factor) >= 2:
            return f"; the markers read fit {words}"
    return ""


def _n_confirmed(layout: Charuco, found: dict[int, list[np.ndarray]], factor: int) -> int:
    """How many of the markers read (``found``) confirm each other where ``layout`` puts them."""
    return len(confirm_markers(found, _layout(layout)[1], _layout(layout)[0],
                               layout.square / layout.marker, factor)[0])


def _detect(board: Charuco, image: np.ndarray) -> Detection:
    N = board.n_points
    full = _to_grey(image, lazy=True)
    # 1-2. Markers: quads whose cells read as a code.
    noise = image_noise(full)
    found, factor, level = find_markers(full, board.aruco, noise=noise)
    # 3. Ids against the board: one marker per id, confirmed by a neighbour where it belongs.
    ms, obj, _ = _layout(board)
    confirmed, homs, side_px = confirm_markers(found, obj, ms, board.square / board.marker, factor)
    if confirmed and board.squares_y % 2 == 0:
        # The legacy setting moves every marker by one square along its row, but for the rows'
        # ends: a board read with the wrong setting confirms most of its markers, shifted, and
        # labels every corner one square off. Where the other setting confirms more, the
        # setting given is not the board's.
        n_other = _n_confirmed(replace(board, legacy=not board.legacy), found, factor)
        if n_other > len(confirmed):
            layout = "since 4.6 (legacy=False)" if board.legacy else "before 4.6 (legacy=True)"
            return Detection.not_found(N, f"not found: the markers read fit OpenCV's layout {layout} better than "
                                          f"the board's ({n_other} confirmed against {len(confirmed)}): its labels "
                                          "would be a square off")
    if len(confirmed) < _READ_BOARD_BELOW:
        # Too few markers read one by one: the board's markers read together, through its
        # chessboard lattice.
        for mid, quads in _read_board(board, level, factor).items():
            for q in quads:
                add_marker(found, mid, q)
        confirmed, homs, side_px = confirm_markers(found, obj, ms, board.square / board.marker, factor)
    if not confirmed:
        why = unconfirmed_reason(found, len(ms), "marker", "board")
        return Detection.not_found(N, f"not found: {why} (dictionary {board.dictionary})"
                                      f"{_other_layout(board, found, factor)}")
    # Markers not read (blurred, or their quad not found) where their confirmed neighbours put
    # them: kept where they read as their own id, the right way up.
    quads = recover_markers(full, board.aruco, 1, obj, ms, {m: found[m][0] for m in confirmed})
    extra = [m for m in quads if m not in homs]
    if extra:
        hs = fit_homographies(obj[extra], np.stack([quads[m] for m in extra]))
        for m, h, q in zip(extra, hs, (quads[m] for m in extra), strict=True):
            if np.isfinite(h).all():
                homs[m] = h
                found[m] = [q]
                side_px[m] = float(np.sqrt(abs(quad_area(q)))) * board.square / board.marker
                confirmed.append(m)
    # 4. Chessboard corners next to confirmed markers, predicted, then at their saddle points.
    # Each corner's place and a square's steps along the board's x and y there (from half a
    # square either side), through each touching marker's homography, averaged. Where two
    # confirmed markers touch a corner (its four squares), the steps along the board are their
    # least-squares homography's (one marker's quad read a pixel off at a thin margin weighs
    # half; a wider neighbourhood bends away from a homography through a fisheye), and the
    # place the midpoint of their corners nearest it: they lie either side of it on a
    # diagonal, a margin's diagonal away on the board, so it is their midpoint to second order
    # in that distance, whatever the lens (through a fisheye the homography of both puts it
    # 3-10 px off on squares of 100 px, the midpoint 0.8-1.9: seed 220). Kernel
    # :func:`~camkit._kernels.markers.charuco_predictions`.
    s = board.square
    conf = np.asarray(confirmed)
    five, size, touched = np.empty((N, 5, 2)), np.empty(N), np.empty(N)
    markers_kernels.charuco_predictions(np.ascontiguousarray(ms[conf], dtype=np.int64),
                                        np.stack([homs[m] for m in confirmed]),
                                        np.array([side_px[m] for m in confirmed], dtype=np.float64),
                                        np.ascontiguousarray(obj[conf]), np.stack([found[m][0] for m in confirmed]),
                                        board.squares_x, board.squares_y, s, _STEP_OFFSETS * s, five, size, touched)
    cand = np.flatnonzero(touched > 0)
    five = five[cand]
    pred = five[:, 0]
    u, v = five[:, 1] - five[:, 2], five[:, 3] - five[:, 4]
    H, W = full.shape
    inside = (pred[:, 0] >= 2) & (pred[:, 0] <= W - 3) & (pred[:, 1] >= 2) & (pred[:, 1] <= H - 3)
    cand, pred, u, v = cand[inside], pred[inside], u[inside], v[inside]
    out = np.full((N, 2), np.nan)
    sig = np.full(N, np.nan)
    win_of = np.zeros(N, dtype=np.int64)  # each found corner's window, smoothing and residuals
    sm_of = np.zeros(N)
    res_of = np.full(N, np.nan)
    clear = _clearance(board, cand, u, v)
    win, smooth = _windows(size[cand], clear, factor)

    def fit(groups: list[tuple[int, float, np.ndarray]]) -> np.ndarray:
        """Fit the corners of each group (window ``r``, smoothing ``sm``, ``k``: a mask of
        ``cand``; the groups apart), keep those that pass; return the mask of those whose fit
        found no saddle near."""
        k = np.zeros(len(cand), dtype=bool)
        q = np.empty((len(cand), 2))
        sg = np.empty(len(cand))
        res = np.empty(len(cand))
        rk = np.zeros(len(cand), dtype=np.int64)
        smk = np.zeros(len(cand))
        for r, sm, g in groups:
            q[g], sg[g], res[g] = refine_patches(full, pred[g], int(r), sm, residuals=True)
            rk[g], smk[g] = r, sm
            k |= g
        q, sg, res, rk, smk = q[k], sg[k], res[k], rk[k], smk[k]
        moved = np.hypot(*(q - pred[k]).T)
        near = np.isfinite(moved) & np.isfinite(sg) & (moved <= np.maximum(1.5 * factor, 0.1 * size[cand[k]]))
        ok = near & fit_inside(q, rk, full.shape)
        # On a circle inside the white margin that keeps the markers away (_x_test).
        kk = np.flatnonzero(k)[ok]
        x, mid, rho, ob = _x_test(board, full, q[ok], size[cand[k]][ok], clear[k][ok], u[kk], v[kk])
        kk = kk[x]
        x[x] = _colours_on_circle(board, full, cand[kk], q[ok][x], u[kk], v[kk], mid[x], rho[x], ob[x])
        ok[ok] = x
        out[cand[k][ok]] = q[ok]
        sig[cand[k][ok]] = sg[ok]
        win_of[cand[k][ok]] = rk[ok]
        sm_of[cand[k][ok]] = smk[ok]
        res_of[cand[k][ok]] = res[ok]
        lost = np.zeros(len(cand), dtype=bool)
        lost[np.flatnonzero(k)[~near]] = True
        return lost

    # A fit whose smoothing was lessened to keep clear of the markers, and that found no saddle
    # near its prediction, is tried again at the full smoothing where nothing later finds the
    # corner (below), and kept where its fit passes as growth's do. Where the white squares
    # are slivers a few pixels thick (a board seen 70-80 degrees from square on), the lesser
    # smoothing leaves two thin light lines crossing, no quadratic's saddle near (corpus view
    # 595, squares of 40 px, margins of 2-3 px: at 1 px none, or one 7 px off; at 1.5 px one
    # within 0.12 px of the truth). Tried earlier, before growth and step 6, it took corners
    # that they find nearer the truth (0.02-0.09 px against 0.19-0.50 px).
    s0 = _FULL_SMOOTHING * factor
    # One saddle fit per window and smoothing; the tests after it all at once.
    lost = fit([(r, sm, (win == r) & (smooth == sm))
                for r, sm in sorted(set(zip(win.tolist(), smooth.tolist(), strict=True)))])
    retry = lost & (smooth < s0)
    # A fit's sigma grows with its window (a quadratic follows the smoothed junction less far
    # out): each corner's is judged against the corners beside markers, those with about its
    # window refitted with it where their fits there are poorer.
    chir = _chirality(board, np.arange(N))
    typical = TypicalSigma(full, out, sig, win_of, lambda r: 1.5 * factor, sm_of, chir, noise)
    # 5. The chessboard beyond the markers read: corners next to found ones, predicted from
    # the found corners around them, kept where they pass the same tests. Poor fits go first,
    # so that none seeds the growth. A grown corner whose sigma is over the typical one is
    # kept where its fit's residuals are not (a junction of less contrast fits as well, its
    # saddle less sure: TypicalSigma), up to a quarter-pixel sigma from the image's noise
    # (the residuals' misfit, which the fit's own sigma counts as noise, moves no saddle of a
    # point-symmetric junction: _markers.noise_sigma); not a corner beside
    # markers, which passes fewer tests: one marker's blurred quad, its corner read 3.6 px
    # off, can predict the chessboard corner onto the white margin beside it, where the fit
    # finds a saddle that passes the circle's tests (seed 55 of the corpus: 6.8 px off,
    # squares of 20 px). Dropped here, such a corner is tried again from its neighbours (and
    # where their prediction is too near the image's edge for growth's coarse search, from its
    # own fit: _grow).
    fitted = out.copy()
    drop_poor_fits(out, sig, typical, win_of, sm_of, chir)
    _grow(board, full, level, factor, out, sig, win_of, sm_of, res_of, typical,
          np.where(np.isfinite(out), np.nan, fitted))
    drop_poor_fits(out, sig, typical, win_of, sm_of, chir, res_of)
    _recover_symmetric(board, full, factor, out, sig, noise, {m: found[m][0] for m in confirmed})
    retry &= ~np.isfinite(out[cand]).all(axis=1)
    if retry.any():
        fit([(r, s0, retry & (win == r)) for r in np.unique(win[retry]).tolist()])
        c = cand[retry]
        c = c[np.isfinite(out[c]).all(axis=1)]
        poor = ~typical.passes(sig[c], win_of[c], _SIGMA_RATIO, sm_of[c], chir[c], res_of[c])
        out[c[poor]] = np.nan
        sig[c[poor]] = np.nan
    _from_homographies(board, full, level, factor, out, sig, win_of, sm_of, res_of, typical)
    # 7. Corners beside markers that their markers predict beyond the fine fit's reach.
    _from_wider_search(board, full, level, factor, cand[lost], pred[lost], size[cand[lost]], clear[lost], u[lost],
                       v[lost], out, sig, win_of, sm_of, res_of, typical)
    # 8. Light that changes across a corner (a shadow's edge, uneven light) moves its saddle
    # (corners it leaves too uncertain are dropped: counted after it).
    _light(board, full, out, sig, win_of, sm_of, noise)
    # 9. Corners beside margins too thin for a misfit to be taken for noise: poor fits go.
    _drop_unresolved(board, out, sig, cand, u, v, typical, win_of, sm_of, chir)
    n_found = int(np.isfinite(out).all(axis=1).sum())
    if n_found == 0:
        return Detection.not_found(N, f"not found: {len(confirmed)} markers confirmed, but no corner beside them "
                                      "passes the saddle-point fit")
    window = int(np.median(win)) if len(win) else 0
    return Detection(True, out, sig, window,
                     f"found {n_found} of {N} corners from {len(confirmed)} markers (window {window} px)")



def _from_wider_search(board: Charuco, full: np.ndarray, level: np.ndarray, factor: int, cand: np.ndarray,
                       pred: np.ndarray, size: np.ndarray, clear: np.ndarray, u: np.ndarray, v: np.ndarray,
                       out: np.ndarray, sig: np.ndarray, win_of: np.ndarray, sm_of: np.ndarray,
                       res_of: np.ndarray, typical: TypicalSigma) -> None:
    """Step 7: the corners ``cand`` beside markers whose fit found no saddle near their markers'
    prediction ``pred`` (squares of ``size`` px, ``clear`` px from the markers, a square's
    steps ``u``, ``v``), those still not found (``out`` NaN), searched for first with a window
    of a third of the clearance and as much smoothing as keeps clear of the markers too (a
    twelfth of the square at most), ending at most a tenth of a square from the prediction;
    then refined and held to the tests of growth's corners (:func:`_place_corners`, the
    neighbours' places a square either way). On large squares through a fisheye the markers
    predict such a corner a few pixels off, beyond the fine fit's window of at most 5 px, and
    growth's parallelogram further (corpus view 1521, squares of 190-270 px, markers 50 px away:
    4.8 and 5.8 px off, growth's 21 and 38 px); growth's own coarse search, a twelfth of the
    square's smoothing, would reach the markers."""
    k = np.flatnonzero(~np.isfinite(out[cand]).all(axis=1))
    if not len(k):
        return
    rk = np.clip(np.floor(clear[k] / 3.0), 0, 25).astype(int)
    smk = np.minimum((clear[k] - rk) / 2.5, size[k] / 12.0)
    go = (rk >= 2) & (smk >= _FULL_SMOOTHING * factor)
    start = np.full((len(k), 2), np.nan)
    for r in np.unique(rk[go]):
        g = np.flatnonzero(go & (rk == r))
        steps = int(np.clip(np.ceil(0.1 * size[k[g]].max()), 6, 25))
        q, _ = refine_patches(full, pred[k[g]], int(r), float(smk[g].min()), iters=steps)
        near = np.hypot(*(q - pred[k[g]]).T) <= 0.1 * size[k[g]]
        start[g[near]] = q[near]
    ok = np.isfinite(start).all(axis=1)
    k, start = k[ok], start[ok]
    if len(k):
        others = np.stack([pred[k] + u[k], pred[k] - u[k], pred[k] + v[k], pred[k] - v[k]], axis=1)
        _place_corners(board, full, level, factor, cand[k], pred[k], size[k], out, sig, others, u[k], v[k],
                       win_of, sm_of, res_of, typical, start)


def _recover_symmetric(board: Charuco, full: np.ndarray, factor: int, out: np.ndarray, sig: np.ndarray, noise: float,
                       quads: dict[int, np.ndarray]) -> None:
    """Step 6 of the detection: the corners still missing beside found ones, placed at their
    point of symmetry (the checkerboard's step 9, :func:`camkit.target.checkerboard._symmetric`),
    round by round while corners are added.

    A ChArUco corner is point-symmetric on the board out to the marker's black border in the
    white squares (the two markers beside it sit alike in their squares), so the samples
    reach :data:`_SYM_BOX` of that box: where blur or shear leaves the saddle fit's small
    window a poor fit, the symmetric point still reads the junction's four edges and the
    markers' borders. A missing corner with four or more of its eight neighbours found is
    predicted by their local map and kept where the symmetric point lies within 0.15 of a
    square of that prediction, its residuals are at most twice the board's own (the median
    over its found corners placed the same way: blur, JPEG and the lens's bending between the
    neighbours leave even a found corner's samples a few hundredths of the board's range from
    symmetric; the image's noise where higher) plus :data:`_SYM_MISFIT` (a marker's bits in
    reach, an occluder, another junction make it asymmetric), its sigma is at most
    :data:`_MAX_RECOVERED_SIGMA`, it is an X-junction with its label's colours on a circle
    clear of the markers, and it lies on no other corner.

    The symmetric point is sought from the map's centre; where that search fails (leaves the
    image's patch, or does not converge), it is sought again from the saddle fit nearest the
    centre (window as step 4's, full smoothing), where that lies within 0.15 of a square of it,
    and held to the same tests. On a sheared board the Gauss-Newton steps of the point-symmetry
    have a narrow basin across the slivers: corpus view 1150's corner 1 (fisheye, 70 degrees
    from square on, noise) had its map's centre 2.3 px off and its search failed; from the
    saddle fit (0.6 px off, refused by its sigma) it ends 0.05 px from the truth."""
    nx = board.squares_x - 1
    margin = 0.5 * (board.square - board.marker) / board.square
    box = margin + board.marker / board.square / (board.aruco.marker_size + 2)  # the border's inner edge
    reach = _SYM_BOX * box
    level = None
    for _ in range(_RECOVER_ROUNDS):
        found = np.isfinite(out).all(axis=1)
        if found.sum() < 5 or found.all():
            return
        spacing = _grid_spacing(out, nx)
        if not np.isfinite(spacing):
            return
        missing = np.flatnonzero(~found)
        maps = _neighbour_maps(out, nx, spacing, reach, missing, False, board, quads)
        got = _symmetric_points(full, out, nx, spacing, reach, missing, centre_known=False, maps=maps)
        if got is None:
            return
        cand, pos, cov, wres, centre, du, dv, size = got
        # Those whose search failed, again from the saddle nearest the map's centre.
        again = np.flatnonzero(~np.isfinite(pos).all(axis=1))
        if len(again):
            clear = _clearance(board, cand[again], du[again], dv[again])
            win, _ = _windows(size[again], clear, factor)
            q = np.full((len(again), 2), np.nan)
            for r in np.unique(win):
                k = win == r
                q[k] = refine_patches(full, centre[again[k]], int(r), _FULL_SMOOTHING * factor)[0]
            near = np.isfinite(q).all(axis=1) & (np.hypot(*(q - centre[again]).T) <= 0.15 * size[again])
            rows = np.searchsorted(missing, cand[again[near]])  # (their maps: as in the first search)
            got2 = _symmetric_points(full, out, nx, spacing, reach, cand[again[near]], centre_known=False,
                                     start=q[near], maps=tuple(m[rows] for m in maps))
            if got2 is not None:
                at = again[near][np.isin(cand[again[near]], got2[0])]
                pos[at], cov[at], wres[at] = got2[1], got2[2], got2[3]
        with np.errstate(invalid="ignore"):
            sigma = _symmetry_sigma(cov[:, :3], cov[:, 3:], wres, noise, _map_ends(spacing, reach)[1])
            ok = (np.isfinite(pos).all(axis=1) & (np.hypot(*(pos - centre).T) <= 0.15 * size)
                  & (sigma <= _MAX_RECOVERED_SIGMA))
        if level is None and ok.any():
            # The board's own asymmetry: its found corners (an even sample of them), placed the
            # same way (read in the first round, and only where a corner passes the other
            # tests: where none does, the step ends here).
            idx = np.flatnonzero(found)
            idx = idx[np.unique(np.linspace(0, len(idx) - 1, min(len(idx), _SYM_REFERENCE)).astype(np.int64))]
            ref = _symmetric_points(full, out, nx, spacing, reach, idx, centre_known=True)
            level = noise
            if ref is not None and np.isfinite(ref[3]).any():
                level = max(noise, float(np.nanmedian(ref[3])))
        if level is not None:
            with np.errstate(invalid="ignore"):
                ok &= wres <= 2.0 * level + _SYM_MISFIT
        if ok.any():
            k = np.flatnonzero(ok)
            x, mid, rho, ob = _x_test(board, full, pos[k], size[k], _clearance(board, cand[k], du[k], dv[k]),
                                      du[k], dv[k])
            k, mid, rho, ob = k[x], mid[x], rho[x], ob[x]
            k = k[_colours_on_circle(board, full, cand[k], pos[k], du[k], dv[k], mid, rho, ob)]
            # Half the way to its nearest neighbour on the board: on a sheared board a diagonal
            # neighbour lies nearer than a side's length (corpus view 975, 75 degrees: 14 px
            # against 41).
            near = np.fmin(size[k], np.fmin(np.hypot(*(du[k] + dv[k]).T), np.hypot(*(du[k] - dv[k]).T)))
            k = k[apart_from_found(pos[k], out[found], 0.5 * near)]
        else:
            k = np.zeros(0, dtype=np.int64)
        if not len(k):
            return
        out[cand[k]] = pos[k]
        sig[cand[k]] = sigma[k]


def _neighbour_maps(out: np.ndarray, nx: int, spacing: float, reach: float, idx: np.ndarray, centre_known: bool,
                    board: Charuco | None = None,
                    quads: dict[int, np.ndarray] | None = None) -> tuple[np.ndarray, ...]:
    """The local maps of the corners ``idx`` of the lattice ``out`` (a row of ``nx``) from their
    neighbours (:func:`~camkit.target.checkerboard._local_maps`), with the ``board`` and its
    confirmed markers' ``quads`` from their neighbours and markers' corners where those are
    too few (:func:`_marker_maps`): ``(a, b, usable, centre, du, dv)``, one row per corner."""
    a, b, usable, centre, du, dv = _local_maps(out, nx, spacing, reach, centre_known=centre_known, only=idx)
    if board is not None and quads and not usable.all():
        rest = np.flatnonzero(~usable)
        got = _marker_maps(board, out, idx[rest], quads, spacing, reach)
        a[rest], b[rest], usable[rest], centre[rest], du[rest], dv[rest] = got
    return a, b, usable, centre, du, dv


def _symmetric_points(full: np.ndarray, out: np.ndarray, nx: int, spacing: float, reach: float, idx: np.ndarray,
                      centre_known: bool, board: Charuco | None = None,
                      quads: dict[int, np.ndarray] | None = None,
                      start: np.ndarray | None = None,
                      maps: tuple[np.ndarray, ...] | None = None) -> tuple[np.ndarray, ...] | None:
    """The corners ``idx`` of the lattice ``out`` (a row of ``nx``), each at its point of
    symmetry out to ``reach`` squares on its neighbours' local map (with the corner itself
    where ``centre_known``), started from the map's centre (or from ``start``, (len(idx), 2),
    each within 0.15 of a square of it): ``(which of idx, place, covariance (xx, xy, yy) per
    unit noise and the normal matrix (xx, xy, yy) side by side (K, 6), residuals' noise, the
    map's centre, a square's steps along the board's x and y, the smaller step's length)``,
    for the corners with a map whose samples lie inside the image and squares of 6 px or
    more; None where none has. With the ``board`` and its confirmed markers' ``quads``, a
    corner with too few neighbours for a map has one from its neighbours and its markers'
    corners (:func:`_neighbour_maps`). ``maps``: those maps, where already made."""
    H, W = full.shape
    if maps is None:
        maps = _neighbour_maps(out, nx, spacing, reach, idx, centre_known, board, quads)
    a, b, usable, centre, du, dv = maps
    size = np.fmin(np.hypot(*du.T), np.hypot(*dv.T))
    with np.errstate(invalid="ignore"):
        extent = np.maximum(np.abs(a).max(axis=(1, 2)), np.abs(b).max(axis=(1, 2))) + 0.15 * size + 4
        sel = np.flatnonzero(usable & np.isfinite(size) & (size >= 6)
                             & (centre[:, 0] >= extent) & (centre[:, 0] <= W - 1 - extent)
                             & (centre[:, 1] >= extent) & (centre[:, 1] <= H - 1 - extent))
    if not len(sel):
        return None
    a, b, centre, du, dv, size, extent = a[sel], b[sel], centre[sel], du[sel], dv[sel], size[sel], extent[sel]
    p0 = centre if start is None else start[sel]
    half = int(np.ceil(extent.max()))
    mosaic, shift = _smoothed_patches(full, p0, half, _SYM_SMOOTHING)
    pos = np.empty((len(sel), 2))
    cov = np.empty((len(sel), 3))
    wres = np.empty(len(sel))
    normal = np.empty((len(sel), 3))
    detect_kernels.symmetry_refine(mosaic, detect_kernels.gaussian_taps(_SYM_SMOOTHING),
                                   np.ascontiguousarray(p0 + shift), np.ascontiguousarray(a),
                                   np.ascontiguousarray(b), np.full(len(sel), a.shape[1], dtype=np.int64),
                                   np.zeros((len(sel), 2)), 20, 1e-3, pos, cov, wres, normal, np.empty((len(sel), 4)))
    if start is not None:
        # Each patch holds the samples of points within 0.15 of a square of its start
        # (``extent``); one that ends farther from a start that is not the map's centre (which
        # the caller's test bounds) read pixels of the next patch.
        with np.errstate(invalid="ignore"):
            pos[np.hypot(*(pos - shift - p0).T) > 0.15 * size] = np.nan
    return idx[sel], pos - shift, np.concatenate([cov, normal], axis=1), wres, centre, du, dv, size


def _marker_maps(board: Charuco, out: np.ndarray, idx: np.ndarray, quads: dict[int, np.ndarray], spacing: float,
                 reach: float) -> tuple[np.ndarray, ...]:
    """Local maps (as :func:`~camkit.target.checkerboard._local_maps` returns them, one row per
    corner of ``idx``) of corners with a confirmed marker (``quads``: id -> (4, 2) image
    corners) in one of their four squares: the homography of their found neighbours
    (3 x 3) and their markers' corners, four points or more, usable where it misses none of
    them by more than :data:`_MARKER_MAP_MISFIT` of a square. A corner at the board's edge, or
    beside two unread markers, has too few neighbours for a map of its own (corpus view 98:
    one to three)."""
    nx, ny = board.squares_x - 1, board.squares_y - 1
    K = len(idx)
    ends, k = _map_ends(spacing, reach)
    scale = max(float(spacing), 1.0)
    mapped = np.full((K, len(ends), 2), np.nan)
    cx, cy = idx % nx, idx // nx
    # The neighbours: board offsets (squares) and places, NaN where not found.
    offs = np.array([(dc, dr) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dc or dr], dtype=np.float64)
    nc, nr = cx[:, None] + offs[None, :, 0].astype(np.int64), cy[:, None] + offs[None, :, 1].astype(np.int64)
    inb = (nc >= 0) & (nc < nx) & (nr >= 0) & (nr < ny)
    pix = np.where(inb[..., None], out[np.where(inb, nr * nx + nc, 0)], np.nan)  # (K, 8, 2)
    src = [np.broadcast_to(offs, (K, 8, 2))]
    dst = [pix]
    # The markers in the corner's four squares (X, Y), X in {cx, cx + 1}, Y in {cy, cy + 1}
    # (the corner is at (cx + 1, cy + 1) squares): their corners, from the corner.
    ms, obj, _ = _layout(board)
    at = np.full((board.squares_y, board.squares_x), -1)
    at[ms[:, 1], ms[:, 0]] = np.arange(len(ms))
    obj = obj / board.square  # (M, 4, 2) squares
    have = np.zeros(len(ms), dtype=bool)
    img = np.full((len(ms), 4, 2), np.nan)
    mids = np.fromiter(quads, dtype=np.int64, count=len(quads))
    have[mids] = True
    img[mids] = np.stack(list(quads.values()))
    any_marker = np.zeros(K, dtype=bool)
    for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):
        mid = at[cy + dy, cx + dx]  # (K,)
        ok = (mid >= 0) & have[np.maximum(mid, 0)]
        any_marker |= ok
        m = np.maximum(mid, 0)
        src.append(obj[m] - np.stack([cx + 1, cy + 1], axis=-1)[:, None].astype(np.float64))
        dst.append(np.where(ok[:, None, None], img[m], np.nan))
    src_all = np.concatenate(src, axis=1)  # (K, 24, 2)
    dst_all = np.concatenate(dst, axis=1)
    valid = np.isfinite(dst_all).all(axis=2)
    count = valid.sum(axis=1)
    for c in np.unique(count[(count >= 4) & any_marker]):  # one batched fit per number of points
        rows = np.flatnonzero((count == c) & any_marker)
        order = np.argsort(~valid[rows], axis=1, kind="stable")[:, :c]  # the valid points first
        s_ = np.take_along_axis(src_all[rows], order[..., None], axis=1)
        d_ = np.take_along_axis(dst_all[rows], order[..., None], axis=1)
        Hs = fit_homographies(s_, d_)
        miss = np.hypot(*(apply_homographies(Hs, s_) - d_).transpose(2, 0, 1)).max(axis=1)
        with np.errstate(invalid="ignore"):
            good = np.isfinite(miss) & (miss <= _MARKER_MAP_MISFIT * scale)
        if good.any():
            mapped[rows[good]] = apply_homographies(Hs[good], np.broadcast_to(ends, (int(good.sum()),) + ends.shape))
    return _split_map(mapped, k, scale)


#: A map from a corner's neighbours and its markers' corners is used where its homography
#: misses none of them by more than this fraction of a square.
_MARKER_MAP_MISFIT = 0.1


#: Step 4's places about a corner, in squares: the corner, and half a square either way along the
#: board's x and y.
_STEP_OFFSETS = np.array([[0.0, 0.0], [0.5, 0.0], [-0.5, 0.0], [0.0, 0.5], [0.0, -0.5]])


#: Step 6 reaches this fraction of the box around a corner inside which a ChArUco board is
#: point-symmetric (to the markers' black borders' inner edges): blur carries the bits in.
_SYM_BOX = 0.7
#: ... keeps a symmetric point whose residuals are at most twice the board's own (its found
#: corners', or its noise where higher) plus this (the stretched grey's units: a board spans
#: about 1) ...
_SYM_MISFIT = 0.02
#: ... and whose sigma is at most this (px): a corner placed so is labelled by its
#: neighbours alone, and must lie well within a pixel of its junction.
_MAX_RECOVERED_SIGMA = 0.1
#: ... in at most this many rounds. The board's own residuals are measured on this many of its
#: found corners (evenly spread).
_RECOVER_ROUNDS = 3
_SYM_REFERENCE = 64


#: Where fewer markers than this are confirmed one by one, the board is read as a whole (with
#: three to five, the corners beside them may not link up: seed 428 of the corpus, squares of
#: 25 px with noise, four markers in two pairs at the board's ends gave 8 of 36 corners, read
#: as a board 36).
_READ_BOARD_BELOW = 6
#: A board read as a whole is accepted where its best placement's score is at least this many
#: standard deviations of a wrong placement's (each marker's correlation with its code, summed
#: over the markers and scaled to unit variance where the bits do not match) ...
_BOARD_Z = 8.0
#: ... and this many above the next best placement.
_BOARD_MARGIN = 6.0


def _read_board(board: Charuco, g: np.ndarray, f: int) -> dict[int, list[np.ndarray]]:
    """Markers too small or blurred to read one by one, read together (:func:`_lattice_reads`):
    a lattice's best placement where its score is :data:`_BOARD_Z` standard deviations of a
    wrong placement's and :data:`_BOARD_MARGIN` above the next (a wrong placement correlates
    each marker with another's code, which the dictionary keeps apart). Returns the markers'
    corners as :func:`find_markers` does (full-image pixels, the code's order)."""
    out: dict[int, list[np.ndarray]] = {}
    for z, second, ids, corners in _lattice_reads(board, g):
        if z >= _BOARD_Z and z - second >= _BOARD_MARGIN:
            for mid, q in zip(ids, corners, strict=True):
                out.setdefault(int(mid), []).append((q + 0.5) * f - 0.5)
    return out


def _lattice_reads(board: Charuco, g: np.ndarray) -> Iterator[tuple[float, float, np.ndarray, np.ndarray]]:
    """The chessboard's lattices in ``g`` (the checkerboard detector's X-corners and lattice
    growth, :func:`~camkit.target.checkerboard._lattices`, its seed links tested inside the
    white margin and at the checkerboard's offset), their corners at their saddle points, and
    every square bounded by four of them sampled at the code's cells through its corners; each
    placement of a lattice on the board (four turns, every shift that keeps its corners on the
    board's inner corners, all but a tenth of them at most a line beyond) puts a marker's code
    on the squares it maps to marker squares, and is
    scored by their correlation. Yields, per lattice, ``(z, second, ids, corners)``: its best
    placement's score (each marker square's correlation with its code times the square root
    of its bits, summed, over the square root of their number: about a standard normal where
    nothing matches), the next best's, the ids placed and the markers' corners ((K, 4, 2),
    pixels of ``g``, the code's order)."""
    d = board.aruco
    n = d.marker_size + 2
    inner = d.marker_size
    s, m = board.square, board.marker
    lo = (s - m) / (2 * s)
    unit = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    c = (np.arange(inner) + 1.5) / n * (m / s) + lo  # the code's cell middles, in squares
    cx, cy = np.meshgrid(c, c)
    cell_pts = np.stack([cx.ravel(), cy.ravel()], axis=-1)
    codes = d.codes.reshape(len(d), -1).astype(np.float64)
    codes = (codes - codes.mean(axis=1, keepdims=True)) / np.maximum(codes.std(axis=1, keepdims=True), 1e-9)
    ms = board.marker_squares()
    at = np.full((board.squares_y, board.squares_x), -1)
    at[ms[:, 1], ms[:, 0]] = np.arange(len(ms))
    at_pad = np.pad(at, 1, constant_values=-1)  # a line beyond the board either side: no marker
    codes = codes[:len(ms)]
    nx, ny = board.squares_x - 1, board.squares_y - 1
    # The lattice's seed links are checked for a black and a white square either side of them:
    # inside the white margin where the markers are sharp (they start beyond it), and at the
    # checkerboard's three tenths of a square where they blur to grey.
    seen: set[bytes] = set()
    for pts, lat in _lattices(g, max(nx, ny), (min(0.3, 0.6 * lo), 0.3)):
        key = np.ascontiguousarray(pts[np.lexsort(pts.T)]).tobytes()
        if len(pts) < 4 or key in seen:  # (both offsets grow the same lattice where both hold)
            continue
        seen.add(key)
        G = np.full(tuple(lat.max(axis=0) + 2), -1, dtype=np.int64)
        G[lat[:, 0], lat[:, 1]] = np.arange(len(lat))
        # The squares with four corners, in the lattice's slot order (i, j), (i+1, j), (i+1, j+1),
        # (i, j+1).
        i, j = np.nonzero((G[:-1, :-1] >= 0) & (G[1:, :-1] >= 0) & (G[1:, 1:] >= 0) & (G[:-1, 1:] >= 0))
        if len(i) < 2:
            continue
        four = np.stack([G[i, j], G[i + 1, j], G[i + 1, j + 1], G[i, j + 1]], axis=-1)
        spacing = float(np.median(np.hypot(*(pts[four[:, 1]] - pts[four[:, 0]]).T)))
        r = int(np.clip(round(spacing / 11.0), 2, 5))
        ref, sg = refine_patches(g, pts, r, 1.0)
        ref = np.where((np.isfinite(sg) & (np.hypot(*(ref - pts).T) <= 0.15 * spacing))[:, None], ref, pts)
        quad = ref[four]  # (S, 4, 2)
        # The lattice's frame turned as the image (the board is seen from its front): its first
        # axis to its second clockwise (y down).
        e1, e2 = quad[:, 1] - quad[:, 0], quad[:, 3] - quad[:, 0]
        if np.median(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0:
            i, j = j, i
            quad = quad[:, [0, 3, 2, 1]]
            lat = lat[:, ::-1]
        Hs = fit_homographies(np.broadcast_to(unit, quad.shape), quad)
        okH = np.isfinite(Hs).all(axis=(1, 2))
        Hs[~okH] = np.eye(3)
        cells = apply_homographies(Hs, np.broadcast_to(cell_pts, (len(quad), len(cell_pts), 2)))
        v = _sample(g, cells[..., 0], cells[..., 1], "bilinear").reshape(len(quad), inner, inner)
        best: list[tuple[float, int, int, int]] = []
        for R in range(4):
            vb = np.rot90(v, -R, axes=(1, 2)).reshape(len(v), -1)
            sd = vb.std(axis=1)
            vb = (vb - vb.mean(axis=1, keepdims=True)) / np.maximum(sd, 1e-12)[:, None]
            score = vb @ codes.T / inner  # (squares, markers): unit variance where unrelated
            score[(sd < 1e-9) | ~okH] = 0.0
            # The lattice's corners and squares' middles turned R quarter turns: (x, y) -> (-y, x).
            pc, sq = lat.astype(np.int64), np.stack([i, j], axis=-1) * 2 + 1  # middles, in half squares
            for _ in range(R):
                pc = np.stack([-pc[:, 1], pc[:, 0]], axis=-1)
                sq = np.stack([-sq[:, 1], sq[:, 0]], axis=-1)
            # Every shift that keeps its corners on the board's inner corners, or all but a
            # tenth of them (and one at least) a line beyond: a lattice may take in a point off
            # the board (seed 289: a tenth column of one point on a board of nine).
            spare = max(1, len(pc) // 10)
            for tx in range(-pc[:, 0].min(), nx - pc[:, 0].max() + 2):
                for ty in range(-pc[:, 1].min(), ny - pc[:, 1].max() + 2):
                    off = ((pc[:, 0] + tx < 1) | (pc[:, 0] + tx > nx) | (pc[:, 1] + ty < 1)
                           | (pc[:, 1] + ty > ny)).sum()
                    if off > spare:
                        continue
                    bx, by = (sq[:, 0] - 1) // 2 + tx, (sq[:, 1] - 1) // 2 + ty  # the board's squares
                    ids = at_pad[by + 1, bx + 1]
                    has = ids >= 0
                    if has.sum() < 2:
                        continue
                    z = float(score[np.flatnonzero(has), ids[has]].sum() / np.sqrt(has.sum()))
                    best.append((z, R, tx, ty))
        if not best:
            continue
        best.sort(key=lambda t: -t[0])
        z, R, tx, ty = best[0]
        second = best[1][0] if len(best) > 1 else 0.0
        sq = np.stack([i, j], axis=-1) * 2 + 1
        for _ in range(R):
            sq = np.stack([-sq[:, 1], sq[:, 0]], axis=-1)
        ids = at_pad[(sq[:, 1] - 1) // 2 + ty + 1, (sq[:, 0] - 1) // 2 + tx + 1]
        has = (ids >= 0) & okH
        mk = apply_homographies(Hs[has], np.broadcast_to(unit * (m / s) + lo, (int(has.sum()), 4, 2)))
        # The code's corner b (the board's slot) is the lattice's slot b - R.
        yield z, second, ids[has], mk[:, (np.arange(4) - R) % 4]


#: How far (in squares) a corner grown past the markers may lie from its prediction.
_REACH = 0.15


def _square_signs(board: Charuco, cand: np.ndarray) -> np.ndarray:
    """+1 where corner ``cand``'s square on its (+x, +y) side is black, -1 where it holds a
    marker (white)."""
    nx = board.squares_x - 1
    cx, cy = cand % nx + 1, cand // nx + 1
    return np.where(_layout(board)[2][cy, cx], -1.0, 1.0)


def _chirality(board: Charuco, cand: np.ndarray) -> np.ndarray:
    """0 or 1 for the corners ``cand``: which of the board's two kinds of corner each is (its
    markers on its (+x, -y) and (-x, +y) sides, or on the other two). On a sheared board one
    kind has its markers in the acute sectors, nearer the corner, and its saddle fits are
    poorer (seed 55 of the corpus, squares of 18 px: sigmas of 0.10-0.11 px against 0.04-0.05
    for the other kind, both within 0.05 px of the truth)."""
    return (_square_signs(board, cand) > 0).astype(np.int64)


def _clearance(board: Charuco, cand: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """How far (pixels) each corner ``cand`` lies from its two markers, through the local steps
    ``u``, ``v`` (K, 2: a square's steps along the board's x and y there); inf where a step is
    unknown (a lattice's edge)."""
    lo = (board.square - board.marker) / (2 * board.square)  # a marker's near side, in squares
    clear = np.empty(len(cand))
    # Each marker's four sides, its corners in squares through the local steps (the corner at 0):
    # the markers on the corner's (+x, -y sign) and (-x, +y sign) sides.
    markers_kernels.marker_clearance(_square_signs(board, cand), lo, 1.0 - lo,
                                     np.ascontiguousarray(u, dtype=np.float64),
                                     np.ascontiguousarray(v, dtype=np.float64), clear)
    return clear


def _x_test(board: Charuco, grey: np.ndarray, q: np.ndarray, size: np.ndarray, clear: np.ndarray | None,
            u: np.ndarray | None = None,
            v: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`x_corner_shades` about corners placed at ``q`` (K, 2), of squares ``size`` px
    across, lying ``clear`` px from their markers (:func:`_clearance`), (K,) each: (is an
    X-junction, its shades' middle, the circle's radius, whether on the board's circle). The
    circle is 0.6 of the white margin (1.5 px at least); where that fails and the markers
    come nearer the corner than the margin's width, it is tried again at 0.6 of their
    distance. On a sheared board the markers in the acute sectors come that near (corpus view
    257, squares of 58 px, margins of 7 px: their borders 4 px away), and a circle that
    crosses them meets four dark sectors, not two; on a blurred board of small squares a
    circle of 1.5-2 px does not yet reach the squares' shades (view 390), so the margin's
    circle is tried first. ``clear`` None: the margin's circle alone. Where both fail and
    ``u``, ``v`` (K, 2: a square's steps along the board's x and y there) are given, a circle
    on the board is tried (:func:`_board_shades`; the radius returned is then in squares)."""
    margin = 0.5 * (board.square - board.marker) / board.square * size
    rho = np.maximum(0.6 * margin, 1.5)
    x, mid = x_corner_shades(grey, q, rho)
    on_board = np.zeros(len(q), dtype=bool)
    if clear is None:
        return x, mid, rho, on_board
    near = np.maximum(0.6 * clear, 1.5)
    again = np.flatnonzero(~x & (near < rho))
    if len(again):
        x2, mid2 = x_corner_shades(grey, q[again], near[again])
        x[again], mid[again], rho[again] = x2, mid2, near[again]
    if u is not None and v is not None and not x.all():
        again = np.flatnonzero(~x)
        r = _X_BOARD * 0.5 * (board.square - board.marker) / board.square
        x2, mid2 = _board_shades(grey, q[again], u[again], v[again], r)
        x[again], mid[again], rho[again], on_board[again] = x2, mid2, r, x2
    return x, mid, rho, on_board


#: The X-test's circle on the board: this fraction of the white margin around a corner.
_X_BOARD = 0.6


def _board_shades(grey: np.ndarray, q: np.ndarray, u: np.ndarray, v: np.ndarray,
                  r: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`x_corner_shades` on a circle of ``r`` squares on the board about each corner
    ``q`` (K, 2), through its steps ``u``, ``v`` (K, 2): an ellipse in the image. Seen 70-80
    degrees from square on, a board's squares meet at angles of 20 degrees: an image circle
    small enough to stay inside the white margins has one or no sample in the acute
    sectors, and one as large as the margin's widest part crosses into the markers there
    (corpus views 89, 491, 842: eight changes of shade). The board's circle gives each square
    a quarter of its samples and stays inside the margin all round."""
    ang = np.arange(32) * 2 * np.pi / 32
    c, s = np.cos(ang)[None], np.sin(ang)[None]
    return x_shades(_sample(grey, q[:, None, 0] + r * (c * u[:, None, 0] + s * v[:, None, 0]),
                            q[:, None, 1] + r * (c * u[:, None, 1] + s * v[:, None, 1]), "bilinear"))


#: The saddle fit's smoothing (Gaussian sigma, pixels of the level the markers were read on)
#: where the markers are far enough from the corner (:func:`_windows`).
_FULL_SMOOTHING = 1.5


def _windows(size: np.ndarray, clear: np.ndarray, factor: int) -> tuple[np.ndarray, np.ndarray]:
    """The saddle fit's window and smoothing for corners of squares ``size`` px across lying
    ``clear`` px from their markers (:func:`_clearance`), (K,) each: an eleventh of the size (2
    to 5 ``factor`` px) and 1.5 ``factor`` px, narrower and less (to 2 px and 1 px, in quarter
    pixels) where the window and 2.5 smoothing sigmas would reach the markers. On a sheared
    board the markers in the acute sectors come near the corner (seed 100 of the corpus,
    noise-free, squares of 50 px: 5-10 px against 15-28 px for the corners of the other
    chirality), and a fit that sees their borders moves 0.2-0.4 px."""
    s0 = _FULL_SMOOTHING * factor
    r = np.clip(np.minimum(np.round(size / 11.0), np.floor(clear - 2.5 * s0)), 2, 5 * factor).astype(int)
    sm = np.clip(np.floor((clear - r) / 2.5 * 4) / 4, 1.0, s0)
    return r, sm


def _dark_squares(board: Charuco, grey: np.ndarray, cand: np.ndarray, q: np.ndarray, u: np.ndarray,
                  v: np.ndarray, mid: np.ndarray) -> np.ndarray:
    """Which corners ``cand`` placed at ``q`` (K, 2) have their board's two black squares where
    the lattice's steps ``u``, ``v`` (pixels per square along the board's x and y, (K, 2)) put
    them: nine points of each, a fifth to a half of a square from the corner along each step
    (near enough for the lattice's local steps to hold through a fisheye), all darker than
    ``mid`` (K,), the middle of the shades on the X-test's circle (:func:`x_corner_shades`).
    A black square is one shade throughout; a junction of a marker's bits, or the next corner
    along a row or column (whose black squares are this one's marker squares), is not."""
    sign = _square_signs(board, cand)
    f = np.array([0.2, 0.35, 0.5])
    a, b = (g.ravel() for g in np.meshgrid(f, f))
    a = np.concatenate([a, -a])  # (18,): the (+, +) square's points, then the (-, -) square's
    b = np.concatenate([b, -b])
    pts = q[:, None] + a[None, :, None] * u[:, None] + (sign[:, None] * b[None])[..., None] * v[:, None]
    dark = _sample(grey, pts[..., 0], pts[..., 1], "bilinear")
    return dark.max(axis=1) < mid


def _colours_on_circle(board: Charuco, grey: np.ndarray, cand: np.ndarray, q: np.ndarray, u: np.ndarray,
                       v: np.ndarray, mid: np.ndarray, rho: np.ndarray,
                       on_board: np.ndarray | None = None) -> np.ndarray:
    """Which corners ``cand`` placed at ``q`` (K, 2) are, on the X-test's circle (radius ``rho``
    (K,), shades' middle ``mid`` (K,), :func:`x_corner_shades`), dark along the bisectors
    of the sectors of their two black squares and light along those of their two white ones
    (``u``, ``v``: a square's steps along the board's x and y, (K, 2); only their directions
    near the corner matter, so a marker's homography through a fisheye serves). Where blur
    joins two thin white margins, their crossing beside a marker is a saddle with four
    alternating sectors a few pixels from the corner; it is dark towards the marker's border,
    where the corner has a white square. ``on_board``: the corners whose circle is on the
    board (:func:`_board_shades`, ``rho`` in squares), read at 45 degrees on it."""
    # Along each sector's bisector (the unit steps' sum: a sheared square's diagonal runs close
    # to its long side), towards the black squares (two), then the white ones (kernel
    # :func:`~camkit._kernels.markers.circle_colours`).
    img, a, b = _stretched(grey)
    out = np.empty(len(cand), dtype=bool)
    markers_kernels.circle_colours(img, a, b, np.ascontiguousarray(q, dtype=np.float64),
                                   np.ascontiguousarray(u, dtype=np.float64), np.ascontiguousarray(v, dtype=np.float64),
                                   _square_signs(board, cand), np.ascontiguousarray(mid, dtype=np.float64),
                                   np.ascontiguousarray(np.broadcast_to(rho, (len(cand),)), dtype=np.float64),
                                   np.zeros(len(cand), dtype=bool) if on_board is None else np.asarray(on_board, bool),
                                   out)
    return out


#: A white margin narrower than this (px, across it) beside a corner lets the saddle fit see
#: the markers' borders: a light band of width w between two dark edges keeps
#: erf(w / (2 sqrt(2) s)) of its contrast under the fit's least smoothing s = 1 px
#: (:func:`_windows`), under half below 1.35 px.
_MIN_MARGIN_PX = 1.35


def _margins(board: Charuco, out: np.ndarray, cand: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Each corner's narrower white margin across (px; the light band between a black square's
    edge and the marker beside it), (N,): ``(square - marker) / (2 square)`` of the height of
    the parallelogram of a square's steps along the board's x and y over its longer side. The
    steps are measured from the corner's found neighbours in ``out`` (the mean of the steps
    either way that are found), else taken from its markers' homographies (``u``, ``v`` (K, 2)
    at the corners ``cand`` beside confirmed markers); NaN where a step is known neither way
    (or the corner is not found)."""
    nx, ny = board.squares_x - 1, board.squares_y - 1
    g = out.reshape(ny, nx, 2)
    steps = []
    for axis in (1, 0):
        d = np.diff(g, axis=axis)
        ok = np.isfinite(d).all(axis=2)
        d = np.where(ok[..., None], d, 0.0)
        total = np.zeros_like(g)
        n = np.zeros((ny, nx))
        lo, hi = [slice(None)] * 2, [slice(None)] * 2
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        for sl in (tuple(lo), tuple(hi)):  # the step to the next corner, and from the last
            total[sl] += d
            n[sl] += ok
        with np.errstate(invalid="ignore"):
            steps.append((total / n[..., None]).reshape(-1, 2))  # NaN where neither neighbour is found
    su, sv = steps
    for st, given in ((su, u), (sv, v)):
        miss = ~np.isfinite(st[cand]).all(axis=1)
        st[cand[miss]] = given[miss]
    cross = np.abs(su[:, 0] * sv[:, 1] - su[:, 1] * sv[:, 0])
    longer = np.maximum(np.hypot(*su.T), np.hypot(*sv.T))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(np.isfinite(out).all(axis=1), (board.square - board.marker) / (2 * board.square) * cross
                        / longer, np.nan)


def _drop_unresolved(board: Charuco, out: np.ndarray, sig: np.ndarray, cand: np.ndarray, u: np.ndarray,
                     v: np.ndarray, typical: TypicalSigma, win_of: np.ndarray, sm_of: np.ndarray,
                     chir: np.ndarray) -> None:
    """Step 9 of the detection: drop (NaN in ``out``, ``sig``) the corners placed by their
    saddle fit (``win_of`` > 0) whose narrower white margin (px across: :func:`_margins`, with
    ``cand``, ``u``, ``v``) is under :data:`_MIN_MARGIN_PX`, and whose fit's sigma is over
    :data:`_SIGMA_RATIO` times ``typical``'s for its window, smoothing ``sm_of`` and kind
    ``chir``: there the residuals' route (:meth:`TypicalSigma.passes`) is closed. It rests on
    a misfit that moves no saddle of a point-symmetric junction; a fit that sees the markers'
    borders past a thin margin, and through perspective or a fisheye sees them unevenly, can
    settle where a marker's corner meets the margin with residuals as low as the board's (the
    wide-board probe's view 616: markers of 80 % of the square, margins of 1.1 px, a fit 1.6 px
    off, even from the truth, its sigma 11 times the typical). Seen square on, such corners fit
    well and stay (squares of 20 px, margins of 1 px: within 0.12 px of the truth)."""
    k = np.flatnonzero(np.isfinite(out).all(axis=1) & (win_of > 0))
    k = k[~typical.passes(sig[k], win_of[k], _SIGMA_RATIO, sm_of[k], chir[k])]
    if not len(k):
        return
    drop = k[_margins(board, out, cand, u, v)[k] < _MIN_MARGIN_PX]
    out[drop] = np.nan
    sig[drop] = np.nan


def _measured_steps(board: Charuco, out: np.ndarray, cand: np.ndarray, q: np.ndarray, u: np.ndarray,
                    v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The steps along the board's x and y at corners ``cand`` placed at ``q`` (K, 2), measured
    from their found neighbours (``out``, NaN where not found): the mean of the steps to the
    next corner either way along each axis that is found, where it is within half and one
    and a half times the predicted step ``u``, ``v`` (K, 2) and within 30 degrees of it, or where
    that step was not predicted (NaN: beside a single row or column), about as long as the
    other step (half to one and a half times) and at 45-135 degrees to it; the predicted step
    elsewhere. Extrapolated past the last found corner through a fisheye's rim,
    the predicted step runs long (seed 28 of the corpus: 55 px where the corner's neighbour
    lies 41 px away), and half of it reached past the next square."""
    nx = board.squares_x - 1
    col = cand % nx
    steps = []
    for pred, other, (lo_ok, hi_ok, d) in ((u, v, (col > 0, col < nx - 1, 1)),
                                            (v, u, (cand >= nx, cand < len(out) - nx, nx))):
        got = np.zeros_like(pred)
        n = np.zeros(len(cand))
        for has, nb, sgn in ((hi_ok, cand + d, 1.0), (lo_ok, cand - d, -1.0)):
            p = np.where(has[:, None], out[np.clip(nb, 0, len(out) - 1)], np.nan)
            st = sgn * (p - q)
            ln, lp = np.hypot(*st.T), np.hypot(*pred.T)
            cos = (st * pred).sum(axis=1) / np.maximum(ln * lp, 1e-12)
            good = np.isfinite(ln) & (ln >= 0.5 * lp) & (ln <= 1.5 * lp) & (cos >= np.cos(np.radians(30.0)))
            # Where this step was not predicted (beside a single row or column), the measured one
            # where it is about as long as the other step and at 45-135 degrees to it.
            lo2 = np.hypot(*other.T)
            cos_o = np.abs((st * other).sum(axis=1)) / np.maximum(ln * lo2, 1e-12)
            good |= (~np.isfinite(lp) & np.isfinite(ln) & (ln >= 0.5 * lo2) & (ln <= 1.5 * lo2)
                     & (cos_o <= np.cos(np.radians(45.0))))
            got[good] += st[good]
            n += good
        steps.append(np.where((n > 0)[:, None], got / np.maximum(n, 1)[:, None], pred))
    return steps[0], steps[1]


def _place_corners(board: Charuco, full: np.ndarray, level: np.ndarray, factor: int, cand: np.ndarray,
                   pred: np.ndarray, size: np.ndarray, out: np.ndarray, sig: np.ndarray,
                   others: np.ndarray, u: np.ndarray, v: np.ndarray, win_of: np.ndarray,
                   sm_of: np.ndarray, res_of: np.ndarray, typical: TypicalSigma,
                   start_at: np.ndarray | None = None, ambiguous: np.ndarray | None = None) -> None:
    """Refine the corners ``cand`` from their predictions ``pred`` (squares of ``size`` px
    across) at their saddle points and keep (in ``out``, ``sig``) those that move at most a
    tenth of a square (1.5 px at least) from their saddle on a coarser scale, at most
    :data:`_REACH` of a square in all, and are X-junctions on a circle inside the white
    margin. The coarser saddle (on ``level``, the image the markers were read
    on, ``factor`` times smaller: a window and smoothing of a fifth and a twelfth of the
    square, the window no wider than keeps clear of the corner's markers, as many steps as
    the reach takes; skipped where no window of 2 px fits) finds a corner that the corners beside it
    predict a few pixels off, as through a fisheye's rim; where it is skipped, the fits started
    a window's radius about the prediction must find no saddle that fits
    better (a smaller sigma) within the reach and more than a pixel from the fit. ``others`` (K, 4, 2): the places
    of each corner's neighbours along the board's rows and columns as predicted with it; a
    corner must end at least twice as near its own place as any of theirs (a neighbour's
    junction is not taken for it). Its two black squares must be dark where ``u``, ``v`` (a
    square's steps along the board's x and y) put them (:func:`_dark_squares`), and its
    fit's sigma at most :data:`_SIGMA_RATIO` times ``typical`` for its window (recorded in
    ``win_of``), or its residuals (recorded in ``res_of``) at most that times the typical ones
    with the sigma the image's noise gives the fit at most a quarter of a pixel
    (:meth:`TypicalSigma.passes`, :func:`~camkit.target._markers.noise_sigma`). ``start_at``
    (K, 2; NaN where none): where given, the fine fit starts there, with no coarse search (the
    tests still measure from ``pred``). ``ambiguous`` (N,): where given, set for the corners
    refused for a better-fitting saddle beside their fit."""
    size_l = size / factor
    pred_l = (pred + 0.5) / factor - 0.5
    clear = _clearance(board, cand, u, v)
    # The coarse window and smoothing, kept clear of the markers as the fine fit's (a coarse fit
    # that sees them drifts off the corner: squares of 17 px with margins of 2 px, 1-5 px); where
    # no window fits, the search starts from the prediction.
    rc = np.clip(np.minimum(np.round(size_l / 5.0), np.floor(clear / factor - 2.5 * np.maximum(1.5, size_l / 12.0))),
                 0, 25).astype(int)
    start = np.where((rc < 2)[:, None], pred, np.nan)
    if start_at is not None:
        given = np.isfinite(start_at).all(axis=1)
        rc[given] = 0
        start[given] = start_at[given]
    for r in np.unique(rc[rc >= 2]):
        k = np.flatnonzero(rc == r)
        sgm = max(1.5, float(np.median(size_l[k])) / 12.0)
        steps = int(np.clip(np.ceil(_REACH * size_l[k].max()), 6, 40))
        q, _ = refine_patches(level, pred_l[k], int(r), sgm, iters=steps)
        near = np.hypot(*(q - pred_l[k]).T) <= _REACH * size_l[k]
        start[k[near]] = (q[near] + 0.5) * factor - 0.5
    win, smooth = _windows(size, clear, factor)
    for r, sm in sorted(set(zip(win.tolist(), smooth.tolist(), strict=True))):  # one fit per window and smoothing
        k = np.flatnonzero((win == r) & (smooth == sm) & np.isfinite(start).all(axis=1))
        if not len(k):
            continue
        q, sg, res = refine_patches(full, start[k], int(r), sm, residuals=True)
        moved = np.hypot(*(q - start[k]).T)
        own = np.hypot(*(q - pred[k]).T)
        moved[own > _REACH * size[k]] = np.inf
        # (A neighbour not predicted, as beside a single row or column, sets no bound: the
        # reach does.)
        theirs = np.fmin.reduce(np.hypot(*(q[:, None] - others[k]).transpose(2, 0, 1)), axis=1, initial=np.inf)
        moved[~(2.0 * own < theirs)] = np.inf
        ok = np.isfinite(moved) & typical.passes(sg, np.full(len(k), r), _SIGMA_RATIO, np.full(len(k), sm),
                                                 _chirality(board, cand[k]), res) & (
            moved <= np.maximum(1.5 * factor, 0.1 * size[k])) & fit_inside(q, int(r), full.shape)
        # Without a coarse search, the fit from the prediction ends on the saddle whose basin
        # holds it: the fits from a window's radius about the prediction must find none that fits
        # better (a smaller sigma), within the reach and more than a pixel from it. On thin margins
        # (markers of 85-90 % of the square) seen through a fisheye's rim, a prediction 2 px off
        # led a fit of 2 px to a crossing of margin and bits 2.8-3.5 px from the corner, sigma
        # 0.28-0.53 px, where the fits about it found the corner, 0.06-0.15 (wide-board probe
        # views 116 and 410).
        plain = ok & (rc[k] < 2)
        if start_at is not None:
            plain &= ~np.isfinite(start_at[k]).all(axis=1)
        if plain.any():
            w = np.flatnonzero(plain)
            w = w[better_saddle_near(full, pred[k][w], q[w], sg[w], int(r), sm, _REACH * size[k][w])]
            ok[w] = False
            if ambiguous is not None:
                ambiguous[cand[k][w]] = True
        # (Not the circle clear of the markers: a grown corner's prediction is only its
        # neighbours', and through a fisheye's rim, where the squares are slivers, a circle of
        # 1.7-3 px passes junctions of the markers' bits 5-8 px off: corpus views 390 and 491.)
        x, mid, rho, _ = _x_test(board, full, q[ok], size[k][ok], None)
        c, qx, ux, vx = cand[k][ok][x], q[ok][x], u[k][ok][x], v[k][ok][x]
        um, vm = _measured_steps(board, out, c, qx, ux, vx)
        x[x] = (_dark_squares(board, full, c, qx, um, vm, mid[x])
                & _colours_on_circle(board, full, c, qx, um, vm, mid[x], rho[x]))
        ok[ok] = x
        # One junction, one label: a corner that ends on another found corner (or on another
        # candidate's) is that corner, not this one.
        ok[ok] = apart_from_found(q[ok], out[np.isfinite(out).all(axis=1)], np.maximum(1.5 * factor,
                                                                                      0.25 * size[k][ok]))
        out[cand[k][ok]] = q[ok]
        sig[cand[k][ok]] = sg[ok]
        win_of[cand[k][ok]] = r
        sm_of[cand[k][ok]] = sm
        res_of[cand[k][ok]] = res[ok]


def _grow(board: Charuco, full: np.ndarray, level: np.ndarray, factor: int, out: np.ndarray,
          sig: np.ndarray, win_of: np.ndarray, sm_of: np.ndarray, res_of: np.ndarray,
          typical: TypicalSigma, dropped: np.ndarray | None = None) -> None:
    """Add the chessboard corners next to found ones (``out``, NaN where not found), round by
    round: each predicted from the found corners beside it on the board (:func:`extend_lattice`),
    refined and tested as the corners beside markers (:func:`_place_corners`). A corner is
    tried again only once more of its neighbours are found. Where the markers are too small
    or blurred to read, the squares still carry the corners' labels from those read.

    ``dropped`` (N, 2; NaN where none): the fits of corners beside markers that the sigma test
    dropped before growth. Where growth's coarse search would reach past the image's edge, such
    a corner is refined from that fit instead of not at all, and held to growth's tests (its
    residuals may excuse its sigma there). Growth's prediction is a parallelogram of its
    neighbours, extrapolated at the board's corner: through a barrel lens at the image's edge
    it fell 6 px off (corpus view 1164, corner 36, squares of 57-75 px), and the fit from
    there ran towards the edge; the dropped fit was 0.03 px from the truth, its sigma 2.04
    times the typical one where its residuals were 1.44 times."""
    nx, ny = board.squares_x - 1, board.squares_y - 1
    H, W = full.shape
    s = board.square
    xs, ys = s * np.arange(-2, nx + 4), s * np.arange(-2, ny + 4)  # the padded lattice's board places
    if not np.isfinite(sig).any():
        return
    # A grown corner's fit is no poorer than the final test (drop_poor_fits) allows: one that
    # is would seed the next round's predictions before that test removed it.
    # A corner whose fit had a better-fitting saddle beside it has two saddles within its reach:
    # it is not tried again (a later prediction, a few pixels off, led into the other's basin,
    # and the fits about it did not find the first fitting better: wide-board view 618, 3 px).
    ambiguous = np.zeros(len(out), dtype=bool)
    for cand, pred, u, v, others in lattice_rounds(out, nx, ny, xs, ys):
        u, v = u * s, v * s  # a square's steps
        size = np.fmin(np.hypot(*u.T), np.hypot(*v.T))
        # The coarse search's window and reach inside the image (its edges replicated beyond
        # would make a saddle there); elsewhere only a dropped corner, from its own fit.
        edge = 0.35 * size + 2
        coarse = ((pred[:, 0] >= edge) & (pred[:, 0] <= W - 1 - edge) & (pred[:, 1] >= edge)
                  & (pred[:, 1] <= H - 1 - edge))
        start = np.full((len(cand), 2), np.nan) if dropped is None else dropped[cand]
        start[coarse] = np.nan
        inside = (np.isfinite(pred).all(axis=1) & np.isfinite(size) & (size >= 4)
                  & (coarse | np.isfinite(start).all(axis=1)) & ~ambiguous[cand])
        if not inside.any():
            continue
        _place_corners(board, full, level, factor, cand[inside], pred[inside], size[inside], out, sig,
                       others[inside], u[inside], v[inside], win_of, sm_of, res_of, typical, start[inside],
                       ambiguous)


#: A corner is placed from the homography of the found corners around it
#: (:func:`_from_homographies`) only where that homography misses none of them by more than
#: this fraction of a square (half a pixel at least): through a lens that bends the board
#: over four squares, it does not.
_HOMOGRAPHY_MISFIT = 0.03


def _from_homographies(board: Charuco, full: np.ndarray, level: np.ndarray, factor: int, out: np.ndarray,
                       sig: np.ndarray, win_of: np.ndarray, sm_of: np.ndarray, res_of: np.ndarray,
                       typical: TypicalSigma) -> None:
    """Last, the corners still not found (``out``, NaN) that have six or more found within two
    rows and columns, not on a line, whose least-squares homography misses none of them by
    more than :data:`_HOMOGRAPHY_MISFIT` of a square: predicted by it and refined and tested
    as growth's (:func:`_place_corners`). Growth predicts a corner from a parallelogram of
    three found neighbours, exact to first order only: on a board seen 76 degrees from square
    on the squares shrink by a fifth from one to the next, and it put corpus view 598's corner
    12 4 px off, between light lines crossing 6-8 px apart (squares of 24 px: the fit took the
    next crossing); the homography of the nine found around put it 0.02 px off. Nothing grows
    from the corners placed here: a parallelogram from them, a few pixels off on a blurred
    board, led the fit onto a blur's saddle 7.5 px from a corner (view 390, corner 23)."""
    nx, ny = board.squares_x - 1, board.squares_y - 1
    s = board.square
    have = np.isfinite(out).all(axis=1)
    cand = np.flatnonzero(~have)
    if not len(cand) or have.sum() < 6:
        return
    obj = board.object_points()[:, :2]
    d = np.arange(-2, 3)
    dx, dy = (a.ravel() for a in np.meshgrid(d, d))
    keep = (dx != 0) | (dy != 0)
    dx, dy = dx[keep], dy[keep]
    X, Y = cand[:, None] % nx + dx, cand[:, None] // nx + dy  # (K, 24)
    inside = (X >= 0) & (X < nx) & (Y >= 0) & (Y < ny)
    idx = np.where(inside, Y * nx + X, 0)
    use = inside & have[idx]
    count = use.sum(axis=1)
    # Each corner's place, a square's steps either way along the board's x and y, and its four
    # neighbours along the rows and columns, through its homography.
    offsets = np.array([[0.0, 0.0], [0.5, 0.0], [-0.5, 0.0], [0.0, 0.5], [0.0, -0.5],
                        [1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]) * s
    at = np.full((len(cand), len(offsets), 2), np.nan)
    miss = np.full(len(cand), np.inf)
    for c in np.unique(count[count >= 6]):  # one batched fit per number of corners around
        rows = np.flatnonzero(count == c)
        nb = np.stack([idx[r][use[r]] for r in rows])  # (R, c)
        Hs = fit_homographies(obj[nb], out[nb])
        m = np.hypot(*(apply_homographies(Hs, obj[nb]) - out[nb]).transpose(2, 0, 1)).max(axis=1)
        miss[rows] = np.where(np.isfinite(m), m, np.inf)
        at[rows] = apply_homographies(Hs, obj[cand[rows]][:, None] + offsets[None])
    pred, u, v, others = at[:, 0], at[:, 1] - at[:, 2], at[:, 3] - at[:, 4], at[:, 5:]
    size = np.fmin(np.hypot(*u.T), np.hypot(*v.T))
    H, W = full.shape
    edge = 0.35 * size + 2  # the coarse search's window and reach inside the image, as growth's
    ok = (np.isfinite(at).all(axis=(1, 2)) & (size >= 4) & (miss <= np.maximum(0.5, _HOMOGRAPHY_MISFIT * size))
          & (pred[:, 0] >= edge) & (pred[:, 0] <= W - 1 - edge) & (pred[:, 1] >= edge) & (pred[:, 1] <= H - 1 - edge))
    if ok.any():
        _place_corners(board, full, level, factor, cand[ok], pred[ok], size[ok], out, sig, others[ok], u[ok], v[ok],
                       win_of, sm_of, res_of, typical)


#: Step 8's light is read as far out as the saddle fit sees: its window and this many of its
#: smoothing's sigmas (farther, a shadow's sharp edge a square away is read as a slope at the
#: corner, where the fit sees none) ...
_LIGHT_REACH = 2.5
#: ... each place's shade the mean over a box (5 x 5 samples) reaching this fraction of its
#: distance to the nearest edge (the pattern's or a marker's) ...
_LIGHT_BOX = 0.5
#: ... read only where the places lie at least this far (px) from every edge: nearer, the
#: corner's own offset, through the edges' blur, reads as light. On rendered ChArUco corpus
#: views 0-119 under a shadow's edge (``benchmarks.charuco_corpus --shadow``), 95th percentile
#: of the noise-free views' errors 0.2376 px without step 8, 0.1171 / 0.0789 / 0.0732 px at 3 /
#: 2 / 1.5 px; the same views without a shadow: 0.0266 px at each (benchmarks/notes.md,
#: forty-fifth session).
_LIGHT_CLEAR = 2.0
#: Each box's 5 x 5 samples (:data:`_LIGHT_BOX`), in its half-sides (x fastest).
_BOX_X, _BOX_Y = (np.ascontiguousarray(a.ravel()) for a in np.meshgrid((np.arange(5) - 2.0) / 2.0,
                                                                       (np.arange(5) - 2.0) / 2.0))


def _light(board: Charuco, full: np.ndarray, out: np.ndarray, sig: np.ndarray, win_of: np.ndarray,
           sm_of: np.ndarray, noise: float) -> None:
    """Step 8 of the detection: each corner placed by its saddle fit (``win_of``, ``sm_of``: its
    window and smoothing) is placed again where light that changes across it (a shadow's edge,
    uneven light, a glare's slope) moved its saddle, its sigma grown by the light's reading
    (``out``, ``sig`` updated).

    The light is read where the board is plain and point-symmetric about the corner, and as
    far out as the fit sees (its window and :data:`_LIGHT_REACH` smoothing sigmas): in each of
    the four squares, five places off the corner's two edges by half that reach (or half the
    margin round the markers, where that is narrower: in the white squares the places lie on
    the margin, clear of the markers), one by the corner and two further along each edge.
    Each place and its mirror image through the corner hold the same pattern (the markers'
    black borders too), so half their difference is the light's alone: with light
    ``(1 + m . d)`` times the pattern plus ``a . d`` (a shadow multiplies, a glare adds), half
    the difference of the pair at ``+-d`` is ``M (m . d) + a . d``, ``M`` the pair's mean
    shade. Ten pairs, white and black ones (the two shades tell ``m`` from ``a``) and along
    two directions at least, fit the four numbers (weighted least squares, each shade's
    variance the image's noise or its box's spread, over the box's samples; scaled up by the
    residuals' chi-square per degree of freedom where over 1). Where the places lie nearer
    than :data:`_LIGHT_CLEAR` to an edge (a narrow margin, small squares), nothing is read.

    Where the light's reading is beyond its noise (a chi-square over
    :data:`~camkit.target.checkerboard._SHADE_CHI2`) and the pairs fit it (an RMS within three
    of their noise's sigmas plus :data:`~camkit.target.checkerboard._SHADE_MISFIT` of the
    squares' half-contrast), the corner's patch is divided by the light (to first order: the
    smoothing's own term, sigma^2 ``m . grad``, taken out too) and its saddle fitted again.
    The move counts where it is beyond its own noise (the reading's covariance through the
    saddle's first-order response, a chi-square over the same bar): noise and JPEG's blocks
    read as a faint light that moves nothing worth its noise (on rendered views without a
    shadow, taking every move of a light read beyond its noise put the noise-free views' 95th
    percentile from 0.0266 to 0.0280 px; with this bar at 9 or 4, 0.0270 and 0.0271). It is kept
    where it is at most :data:`~camkit.target.checkerboard._SHADE_MAX_SHIFT` of the window,
    the corner's sigma grown by the reading's. Where the light is there but the pairs do not
    fit it (an occluder over a square, light that bends within the squares), or the move
    would be larger, the corner stays, that move added to its sigma; where its sigma then
    passes :data:`~camkit.target.checkerboard._MAX_CORNER_SIGMA`, or the refit finds no
    saddle near, it is dropped (rendered views 145 and 213 under a shadow's edge: corners
    1.3-1.6 px off, their sigmas grown from 0.05-0.14 to 1.0-1.5 px).

    A first-order correction of the saddle alone (the gradient times the fit's inverse
    Hessian, as the checkerboard's step 8) found 70 % of the move on a rendered junction: the
    fit's window follows its saddle, and on a junction that is no quadratic that moves it
    further; the refit finds it whole (0.003 px left at a slope of 3 % per pixel)."""
    nx, ny = board.squares_x - 1, board.squares_y - 1
    found = np.isfinite(out).all(axis=1)
    if found.sum() < 2:
        return
    e1, e2 = _local_steps(out, nx, ny)
    idx = np.flatnonzero(found & (win_of > 0) & np.isfinite(e1).all(axis=1) & np.isfinite(e2).all(axis=1))
    if not len(idx):
        return
    c, e1, e2 = out[idx], e1[idx], e2[idx]
    margin = (board.square - board.marker) / (2 * board.square)
    # The light the fit sees: within its window and smoothing's reach. The places lie that far
    # out, half of it off the corner's two edges (px, across them), less where the margin is
    # narrower (half its width: as far from the marker). On the (+x, +y) and (+x, -y) sides, in
    # squares: across each edge that clearance, along it 0, half the reach and the reach
    # further, at most half a square; their mirrors on the other two. Each place's box of
    # 5 x 5 samples gives its mean and spread, and the four numbers are fitted from the ten
    # pairs, each corner's fit its own (kernel :func:`~camkit._kernels.markers.light_reading`).
    reach = win_of[idx] + _LIGHT_REACH * sm_of[idx]
    K = len(idx)
    img, sa, sb = _stretched(full)
    d = np.empty((K, 10, 2))
    theta, cov = np.empty((K, 4)), np.empty((K, 4, 4))
    fits, read = np.empty(K, dtype=bool), np.empty(K, dtype=bool)
    markers_kernels.light_reading(img, sa, sb, np.ascontiguousarray(c), np.ascontiguousarray(e1),
                                  np.ascontiguousarray(e2), np.ascontiguousarray(reach, dtype=np.float64), margin,
                                  _LIGHT_CLEAR, _LIGHT_BOX, _BOX_X, _BOX_Y, float(noise), _SHADE_MISFIT, _SHADE_CHI2,
                                  d, theta, cov, fits, read)
    if not read.any():
        return
    idx, c, theta, cov, fits = idx[read], c[read], theta[read], cov[read], fits[read]
    # The refit with the light read; the move's covariance through the first-order response
    # of the saddle to each of the light's four numbers (:func:`_light_refit`).
    shift = np.full((len(idx), 2), np.nan)
    J = np.zeros((len(idx), 2, 4))
    for sm in np.unique(sm_of[idx]).tolist():
        k = np.flatnonzero(sm_of[idx] == sm)
        q, J[k] = _light_refit(full, c[k], win_of[idx[k]], float(sm), theta[k])
        shift[k] = q - c[k]
    scov = J @ cov @ J.transpose(0, 2, 1)
    # The move counts where it is beyond its own noise (a light read beyond its noise can still
    # move the saddle less than that: then the corner stays as it was); it is taken where the
    # light fits and the move is small. In doubt (the light is there but not as read, or moves
    # the saddle further than the fit reaches), the move is added to the corner's sigma, and
    # where that passes the checkerboard's bar (or the refit found no saddle, its move
    # unknown) the corner is dropped (kernel :func:`~camkit._kernels.markers.light_verdicts`).
    markers_kernels.light_verdicts(idx, c, shift, scov, fits, win_of[idx], _SHADE_MAX_SHIFT, _SHADE_CHI2,
                                   _MAX_CORNER_SIGMA, out, sig)


def _light_refit(full: np.ndarray, pts: np.ndarray, r: np.ndarray, sm: float, theta: np.ndarray,
                 iters: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """The saddle fit (windows ``r`` (K,), smoothing ``sm``) of each point ``pts`` (K, 2) on the
    image with light ``theta`` (K, 4: ``m``, ``a`` of :func:`_light`, per px from the point)
    divided out around it: on each point's smoothed patch, ``(v - a . d - sm^2 m . grad v) /
    (1 + m . d)``, ``d`` the offset from the point (the smoothing of ``(m . d) v`` is ``m . d``
    times the smoothed ``v`` plus ``sm^2 m . grad v``; kernel
    :func:`~camkit._kernels.detect.light_divide`). Returns the places (NaN where the fit found
    no saddle near) and how far each of the light's four numbers moves them (K, 2, 4: px per
    unit), to first order (the change of the fit's linear terms through its inverse Hessian:
    :func:`~camkit._kernels.detect.light_response`), scaled by how much further the refit
    moved than that predicts (the fit's window follows its saddle; 1 to 2 times)."""
    half = int(r.max()) + iters + 3
    mosaic, shift = _smoothed_patches(full, pts, half, sm)
    side = 2 * half + 1
    origin = (np.floor(pts).astype(np.int64) - half + shift.astype(np.int64))  # each patch's top-left in the mosaic
    at = pts - np.floor(pts) + half  # each point within its patch
    fixed = np.zeros_like(mosaic)
    detect_kernels.light_divide(mosaic, origin, at, theta, sm * sm, side, fixed)
    q = np.empty_like(pts)
    quad, lin = np.empty((len(pts), 3)), np.empty((len(pts), 4, 2))
    for w in np.unique(r).tolist():
        g = np.flatnonzero(r == w)
        q[g] = _saddle_fit(fixed, pts[g] + shift[g], w, iters)[0] - shift[g]
        # First order: each number's change of the patch, fitted on the window about the
        # point's nearest pixel, moves the saddle by H^-1 times its change of the linear terms
        # (kernel :func:`~camkit._kernels.markers.light_jacobian`, below).
        qg, lg = np.empty((len(g), 3)), np.empty((len(g), 4, 2))
        detect_kernels.light_response(mosaic, origin[g], at[g], sm * sm, side, w, _saddle_design(w)[0], qg, lg)
        quad[g], lin[g] = qg, lg
    J = np.empty((len(pts), 2, 4))
    markers_kernels.light_jacobian(quad, lin, np.ascontiguousarray(theta), q, np.ascontiguousarray(pts), J)
    return q, J
