"""The checkerboard target and its detector: X-corners, the board's lattice, sub-pixel saddle points."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Self

import numpy as np

from camkit._alloc import scratch, work_array
from camkit._kernels import detect as detect_kernels
from camkit._kernels import lattice as lattice_kernels
from camkit._kernels import markers as markers_kernels
from camkit._validate import as_finite_float, as_image, as_positive_float, as_positive_int
from camkit.errors import ParameterError, ShapeError
from camkit.target._homography import fit_homographies
from camkit.target.base import Detection, Sheet, Target, register_target

__all__ = ["Checkerboard", "detect_corners"]


@register_target
@dataclass(frozen=True, slots=True)
class Checkerboard(Target):
    """A planar checkerboard: ``inner_cols x inner_rows`` inner corners, squares of side
    ``square`` metres, a white margin around the outer squares.

    The board frame has its origin at the first inner corner, x along the columns, y along
    the rows, z = 0 on the board (so z points away from a camera that sees its printed face
    in the usual orientation). Inner corner ``(col, row)`` is at ``(col * square, row *
    square, 0)``. There are ``(inner_cols + 1) x (inner_rows + 1)`` squares; the one at the top
    left (containing ``(-square/2, -square/2)``) is black.

    Examples
    --------
    >>> board = Checkerboard(9, 6, 0.025)
    >>> board.object_points().shape
    (54, 3)
    >>> board.object_points()[10]    # column 1 of row 1
    array([0.025, 0.025, 0.   ])
    """

    inner_cols: int
    inner_rows: int
    square: float
    margin: float | None = None

    def __post_init__(self) -> None:
        cols = as_positive_int(self.inner_cols, "inner_cols")
        rows = as_positive_int(self.inner_rows, "inner_rows")
        if cols < 2 or rows < 2:
            raise ParameterError(
                f"inner_cols, inner_rows: expected at least 2x2 inner corners, got {cols}x{rows}"
            )
        object.__setattr__(self, "inner_cols", cols)
        object.__setattr__(self, "inner_rows", rows)
        object.__setattr__(self, "square", as_positive_float(self.square, "square"))
        margin = self.square if self.margin is None else as_finite_float(self.margin, "margin")
        if margin < 0:
            raise ParameterError(f"margin: expected a value >= 0, got {margin}")
        object.__setattr__(self, "margin", margin)

    @property
    def n_corners(self) -> int:
        return self.inner_cols * self.inner_rows

    def object_points(self) -> np.ndarray:
        """Inner corners in the board frame, (N, 3), row by row (column index fastest)."""
        c, r = np.meshgrid(np.arange(self.inner_cols), np.arange(self.inner_rows))
        return np.stack([c.ravel() * self.square, r.ravel() * self.square, np.zeros(c.size)], axis=-1)

    name = "checkerboard"

    def extent(self) -> tuple[float, float, float, float]:
        """``(u_min, v_min, u_max, v_max)`` of the printed sheet (squares plus margin), metres."""
        s, m = self.square, self.margin
        return (-s - m, -s - m, self.inner_cols * s + m, self.inner_rows * s + m)

    def sheet(self) -> Sheet:
        """The printed face: ``(inner_cols + 1) x (inner_rows + 1)`` squares, the top-left one
        black, and the white margin around them."""
        s = self.square
        r, c = np.mgrid[0:self.inner_rows + 1, 0:self.inner_cols + 1]
        black = ((r + c) % 2 == 0).ravel()
        u0, v0 = (c.ravel()[black] - 1) * s, (r.ravel()[black] - 1) * s
        label = (f"checkerboard {self.inner_cols}x{self.inner_rows} inner corners "
                 f"({self.inner_cols + 1}x{self.inner_rows + 1} squares), squares {s * 1000.0:g} mm. "
                 "Print at 100 % (actual size) and measure a square.")
        return Sheet(self.extent(), np.stack([u0, v0, u0 + s, v0 + s], axis=-1), label)

    def size_note(self) -> str:
        return f"board size (inner corners {self.inner_cols}x{self.inner_rows}, not squares)"

    def seen_note(self, board_seen: tuple[int, int]) -> str:
        return f"{board_seen[0]}x{board_seen[1]} inner corners"

    def detect(self, image: np.ndarray) -> Detection:
        """The inner corners in ``image``: :func:`detect_corners`."""
        return detect_corners(image, self)

    @classmethod
    def example(cls) -> Self:
        """The board the demo uses: 9 x 6 inner corners, 30 mm squares."""
        return cls(9, 6, 0.030)


_SIGMA = 1.5  # smoothing for the saddle response (pixels)
_PROFILE_RADIUS = 4.0  # circle on which an X-corner shows four alternating sectors
_MAX_CANDIDATES = 5000
#: Candidates are the local maxima of the saddle response above the first of these fractions of
#: its maximum under which they number fewer than ``_MAX_CANDIDATES`` (clutter or noise raises
#: it; the strongest are then kept, wherever they lie in the image). The response of an
#: X-junction grows with the square of its contrast and falls with its shear: the dimmed,
#: foreshortened squares at a fisheye's rim, or the half of a board in a shadow, respond with
#: 0.02-0.05 of the lit squares' response (at 0.05 they were never candidates:
#: benchmarks/notes.md, forty-fourth session).
_RESPONSE_FLOORS = (0.02, 0.05, 0.1, 0.2, 0.4)
#: ... but a candidate under this fraction must show the full contrast floor
#: (:data:`_MIN_CONTRAST` of the image's range), and the contrast floor lowered for faint boards
#: is read from the candidates over it: where a whole board is faint (a backlit board, a tenth
#: of the range under JPEG), its weakest corners are too poor to place (rendered corpus view 68:
#: a board 15 grey levels deep at JPEG quality 67, its weakest corners up to 1.2 px off).
_STRONG_RESPONSE = 0.05
#: Growth may take X-corners down to this fraction of the full contrast floor
#: (:data:`_MIN_CONTRAST`; a board's half in a shadow: its corners a fifth as deep as the lit
#: half's); only those over the floor seed it. Only where the floor is the full one (the image
#: holds X-corners of full contrast: the lit half): where it is lowered for faint X-like
#: points, the fainter ones are poorly placed corners or artefacts (rendered corpus view 68, a
#: board 15 grey levels deep under JPEG: a corner 1.2 px off; probe view 3046, a small board
#: smeared by a 20 px motion blur: a lattice of 45 points between its corners).
_WEAK_CONTRAST = 0.3
#: The saddle fit's window half-size is the corner spacing over this (2 to 5 px).
_SPACING_PER_WINDOW = 11.0


class RawGrey:
    """A one-channel uint8 image seen as its stretched grey, ``raw * a + b``, without making
    the float64 image (96 MB at 12 MP): the coded targets' detectors read it on a coarser
    level and in small patches only. :func:`_sample`, :func:`_half` and the marker module's
    patch fits take it as they take a float64 image; the stretch is affine, so sampling or
    averaging ``raw`` and then stretching gives the same values. :meth:`dense` makes the
    float64 image where a whole one is needed."""

    __slots__ = ("_dense", "a", "b", "raw", "shape")

    def __init__(self, raw: np.ndarray, a: float, b: float) -> None:
        self.raw, self.a, self.b = raw, a, b
        self.shape: tuple[int, int] = raw.shape
        self._dense: np.ndarray | None = None

    def dense(self, integral: np.ndarray | None = None) -> np.ndarray:
        """The float64 grey image (made once, in this thread's work buffer ``"dense"``
        (:func:`camkit._alloc.scratch`): a detection's own, on its thread; one grey at a time).
        ``integral`` (H + 1, W + 1): filled with the grey's integral image too (as
        :func:`camkit._kernels.markers.integral` makes it; in the same pass where the grey is
        made here)."""
        if self._dense is None:
            g = scratch("dense", self.shape, np.float64, touched=True)
            if integral is not None:
                markers_kernels.grey_integral(self.raw, -self.b / self.a, self.a, g, integral)
                self._dense = g
                return g
            detect_kernels.grey_mean(self.raw[:, :, None], 1.0, -self.b / self.a, self.a, g)
            self._dense = g
        if integral is not None:
            markers_kernels.integral(self._dense, integral)
        return self._dense


def _stretched(grey: np.ndarray) -> tuple[np.ndarray, float, float]:
    """What a kernel reads for ``grey``: its pixels and the stretch ``a * v + b`` that gives the
    grey (a :class:`RawGrey`'s uint8 image and its stretch; a float image as float64, 1, 0)."""
    if isinstance(grey, RawGrey):
        return grey.raw, grey.a, grey.b
    return np.ascontiguousarray(grey, dtype=np.float64), 1.0, 0.0


def _to_grey(image: np.ndarray, lazy: bool = False, with_step: bool = False) -> np.ndarray:
    """The image as float64 grey (the mean of R, G and B; alpha ignored), stretched so that its
    1st percentile is 0 and its 99th is 1. ``lazy``: a one-channel uint8 image comes back as
    a :class:`RawGrey` (the same values, made where read). ``with_step``: returns ``(grey,
    step)``, ``step`` one level of the file's integer samples in the grey's units (0.0 for a
    float image)."""
    img = as_image(image, "image")
    if img.dtype.kind == "f" and not np.isfinite(img).all():
        bad = int(np.count_nonzero(~np.isfinite(img)))
        raise ShapeError(f"image: expected finite values, got {bad} NaN or infinite sample(s) of {img.size}")
    scale = 1.0 / np.iinfo(img.dtype).max if img.dtype.kind == "u" else 1.0
    img3 = img if img.ndim == 3 else img[:, :, None]
    # The 1st and 99th percentiles set black and white; on a large image a regular subsample of
    # about 250 000 pixels pins them down as well, at a fraction of the cost. The subsample's
    # grey is computed as the kernel computes every pixel's, then the whole image in one pass.
    step = max(1, int(np.sqrt(img.shape[0] * img.shape[1] / 250_000)))
    if img.dtype == np.uint8:  # the percentiles from the histogram of channel sums, exactly
        n = 3 if img3.shape[2] >= 3 else 1
        hist = np.zeros(255 * n + 1, dtype=np.int64)
        detect_kernels.channel_sum_histogram(img3, step, hist)
        lo, hi = _hist_percentiles(hist, scale / n, (1.0, 99.0))
    else:
        sub = np.empty(img3[::step, ::step].shape[:2])
        detect_kernels.grey_mean(np.ascontiguousarray(img3[::step, ::step]), scale, 0.0, 1.0, sub)
        lo, hi = np.percentile(sub, [1, 99])
    inv = 1.0 / max(float(hi - lo), 1e-12)
    if lazy and img.dtype == np.uint8 and img3.shape[2] < 3:
        return RawGrey(np.ascontiguousarray(img3[:, :, 0]), scale * inv, -float(lo) * inv)  # type: ignore[return-value]
    g = work_array(img.shape[:2], np.float64, touched=True)
    detect_kernels.grey_mean(img3, scale, float(lo), inv, g)
    if with_step:
        return g, (scale * inv if img.dtype.kind == "u" else 0.0)  # type: ignore[return-value]
    return g


def _hist_percentiles(hist: np.ndarray, unit: float, qs: tuple[float, ...]) -> list[float]:
    """``np.percentile`` (its default, linear interpolation between order statistics) of the
    values ``v * unit`` counted ``hist[v]`` times."""
    cum = np.cumsum(hist)
    n = int(cum[-1])
    out = []
    for q in qs:
        pos = q / 100.0 * (n - 1)
        i = int(np.floor(pos))
        a, b = np.searchsorted(cum, [i, min(i + 1, n - 1)], side="right") * unit
        t = pos - i
        out.append(float(a + (b - a) * t if t < 0.5 else b - (b - a) * (1.0 - t)))
    return out


def _sample(img: np.ndarray, x: np.ndarray, y: np.ndarray, interpolation: str) -> np.ndarray:
    """The image at points (x, y) of any shape, bilinear or bicubic, edges replicated."""
    out = np.empty(np.broadcast_shapes(x.shape, y.shape))
    xb, yb = np.broadcast_arrays(x, y)
    raw = isinstance(img, RawGrey)
    lattice_kernels.sample_points(img.raw if raw else np.ascontiguousarray(img, dtype=np.float64),
                                  np.ascontiguousarray(xb, dtype=np.float64).ravel(),
                                  np.ascontiguousarray(yb, dtype=np.float64).ravel(), interpolation == "bicubic",
                                  out.ravel())
    if raw:
        out *= img.a
        out += img.b
    return out


def _profiles(s: np.ndarray, pts: np.ndarray, n: int = 32, radius: float = _PROFILE_RADIUS) -> np.ndarray:
    ang = np.arange(n) * 2 * np.pi / n
    return _sample(s, pts[:, :1] + radius * np.cos(ang), pts[:, 1:] + radius * np.sin(ang), "bilinear")


def _x_shape(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which profiles ``v`` (from :func:`_profiles`) have an X-corner's shape: the circle
    crosses four alternating sectors, point-symmetric. Returns (shape, contrast, asymmetry)."""
    sign = v > v.mean(axis=1, keepdims=True)
    changes = (sign != np.roll(sign, 1, axis=1)).sum(axis=1)
    contrast = v.max(axis=1) - v.min(axis=1)
    sym = np.abs(v - np.roll(v, v.shape[1] // 2, axis=1)).mean(axis=1) / np.maximum(contrast, 1e-12)
    return (changes == 4) & (sym < 0.25), contrast, sym


def _x_test(v: np.ndarray, min_contrast: float) -> tuple[np.ndarray, np.ndarray]:
    """Which profiles ``v`` are X-corners (:func:`_x_shape`, contrast over ``min_contrast``).
    Returns (is X-corner, asymmetry)."""
    shape, contrast, sym = _x_shape(v)
    return shape & (contrast > min_contrast), sym


#: An X-corner's contrast (on the image stretched from its 1st to 99th percentile) must pass
#: this where the image holds X-corners of full contrast...
_MIN_CONTRAST = 0.15
#: ... and this fraction of the strongest X-like points' contrast where it does not (a board in
#: shade beside a window: its black and white span a tenth of the image's range)...
_MIN_CONTRAST_FRACTION = 0.3
#: ... but never less than this many times the noise left in the smoothed image.
_NOISE_FACTOR = 10.0


def _contrast_floor(contrast: np.ndarray, noise: float) -> float:
    """The contrast an X-corner must pass: ``_MIN_CONTRAST`` where the X-like points' 90th
    percentile contrast is high, down to ``_MIN_CONTRAST_FRACTION`` of it where all are faint,
    and never below ``_NOISE_FACTOR`` times ``noise`` (the smoothed image's noise)."""
    top = float(np.percentile(contrast, 90)) if len(contrast) else 1.0
    return max(min(_MIN_CONTRAST, _MIN_CONTRAST_FRACTION * top), _NOISE_FACTOR * noise)


#: About how many neighbour differences :func:`_image_noise` takes its median over.
_NOISE_SAMPLES = 500_000


def _image_noise(grey: np.ndarray) -> float:
    """The noise's standard deviation per pixel: the median absolute difference of horizontal
    neighbours (every fourth row; on a large image every 4m-th, m odd, for about half a
    million differences: as many as a 2 MP image gives, and the median's error under 0.2 %),
    as a Gaussian's sigma (1.4826 MAD, over sqrt 2 for the difference). JPEG's smoothing of
    flat areas makes it read low."""
    m = max(1, -(-grey.size // (4 * _NOISE_SAMPLES))) | 1
    if grey.dtype == np.uint8:
        # The median of the integer differences from their histogram (kernel
        # difference_histogram): the same value, at a fraction of the time.
        hist = np.zeros(256, dtype=np.int64)
        detect_kernels.difference_histogram(np.ascontiguousarray(grey), 4 * m, hist)
        cs = np.cumsum(hist)
        size = int(cs[-1])
        if not size:
            return float("nan")
        mid = 0.5 * float(np.searchsorted(cs, (size - 1) // 2, side="right")
                          + np.searchsorted(cs, size // 2, side="right"))
        return float(1.4826 * mid / np.sqrt(2.0))
    d = np.abs(np.diff(grey[::4 * m].astype(np.float64), axis=1))  # (a uint8 image's differences wrap)
    return float(1.4826 * np.median(d) / np.sqrt(2.0))


def _quad_design(r: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The (2r+1)^2 window's offsets dx, dy (row-major) and the quadratic's design matrix
    A, its columns dx^2, dx dy, dy^2, dx, dy, 1."""
    oy, ox = np.mgrid[-r:r + 1, -r:r + 1].astype(np.float64)
    dx, dy = ox.ravel(), oy.ravel()
    return dx, dy, np.stack([dx * dx, dx * dy, dy * dy, dx, dy, np.ones_like(dx)], -1)


@functools.lru_cache(maxsize=32)
def _saddle_design(r: int) -> tuple[np.ndarray, float]:
    """The (2r+1)^2 window's quadratic (:func:`_quad_design`): its design matrix's
    pseudo-inverse (6, (2r+1)^2) and the (3, 3) element of (A^T A)^-1, which a linear term's
    variance per unit residual variance is (read only)."""
    A = _quad_design(r)[2]
    pinv = np.linalg.pinv(A)
    pinv.setflags(write=False)
    return pinv, float(np.linalg.inv(A.T @ A)[3, 3])


def _saddle_fit(s: np.ndarray, pts: np.ndarray, r: int, iters: int = 6,
                residuals: bool = False) -> tuple[np.ndarray, ...]:
    """Saddle point of a quadratic fitted on a (2r+1)^2 window centred on each estimate
    (sampled bicubically, so the window is symmetric about it); per-corner sigma from the
    fit's residuals propagated through the saddle equations, NaN where the fit has not
    converged (its saddle still half a pixel or more from the window's centre after ``iters``
    steps of at most a pixel: no saddle near the estimate). With ``residuals``, also the
    residuals' standard deviation (the sigma without the saddle's curvature: how well a
    quadratic describes the window, whatever the junction's contrast), NaN where the sigma is
    (kernel :func:`camkit._kernels.detect.saddle_fit`)."""
    pinv, cvar = _saddle_design(int(r))
    pts = np.ascontiguousarray(pts, dtype=np.float64).reshape(-1, 2)
    q = np.empty_like(pts)
    sigma = np.empty(len(pts))
    resid = np.empty(len(pts))
    detect_kernels.saddle_fit(np.ascontiguousarray(s, dtype=np.float64), pts, int(r), int(iters), pinv, cvar, q,
                              sigma, resid)
    if residuals:
        return q, sigma, resid
    return q, sigma


def _assemble(pts: np.ndarray, max_side: int, img: np.ndarray, contrast: np.ndarray,
              offset: float = 0.3, seeds: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """The corners' lattices: grown (:func:`camkit._kernels.lattice.grow`) from the corners in
    turn, most central first; corners in a grown lattice seed no other. Growth stays within
    ``max_side + 2`` positions of its seed either way (a lattice that reaches that far is
    longer than the board, and is refused later as such). ``offset``: how far either side of a
    seed's links their squares' shades are taken, in steps (0.3; less where the white squares
    hold markers). Returns (indices into pts, lattice coordinates from 0) for each lattice,
    largest first."""
    order = np.argsort(np.hypot(*(pts - np.median(pts, axis=0)).T), kind="stable")
    if seeds is not None:  # only these seed a lattice; growth may take any
        order = order[seeds[order]]
    side = 2 * (max_side + 2) + 1
    owner = np.empty(len(pts), dtype=np.int64)
    coord = np.empty((len(pts), 2), dtype=np.int64)
    n = lattice_kernels.assemble(np.ascontiguousarray(pts), img, np.ascontiguousarray(contrast), order, side,
                                 owner, coord, offset)
    out = []
    for k in range(n):
        idx = np.flatnonzero(owner == k)
        out.append((idx, coord[idx] - coord[idx].min(axis=0)))
    return sorted(out, key=lambda t: -len(t[0]))


def _grid(g: np.ndarray, margin: int = 0) -> np.ndarray:
    """Lattice coordinates (from 0) as a grid of indices into them, -1 where empty."""
    G = np.full(tuple(g.max(axis=0) + 1 + margin) if len(g) else (1, 1), -1, dtype=np.int64)
    G[g[:, 0], g[:, 1]] = np.arange(len(g))
    return G


def detect_corners(image: np.ndarray, board: Checkerboard) -> Detection:
    """Find the inner corners of a checkerboard, in the order of ``board.object_points()``.

    1. X-corners: local maxima of the saddle response ``-(Ixx Iyy - Ixy^2)`` of the image
       smoothed with sigma = 1.5 px (over 0.02 of its maximum, or more where clutter gives
       over 5000: :data:`_RESPONSE_FLOORS`), kept where a circle of radius 4 px around them crosses
       four alternating sectors that are point-symmetric (true inner corners; the board's
       outer edge against the background is not), with contrast: 0.15 of the image's range
       (1st to 99th percentile), or, where the X-like points are fainter (a board in shade
       beside a bright window), 0.3 of their 90th percentile contrast; ten times the smoothed
       image's noise at least.
    2. Lattice: grown from a seed corner (an X-corner of step 1; growth may also take X-corners
       down to 0.3 of the contrast floor where that is the full one, such as the corners of a
       board's half in a shadow)
       with a row and a column through it: two pairs of
       its nearest corners, each pair nearly opposite through it, whose four links run along
       edges (a quarter, half and three quarters along each link the squares either side
       differ, the same way round: a diagonal link, a link two steps long and a sheared one
       fail) and whose square of nine is complete; then position after position is predicted
       from the lattice around it (a quadratic map of lattice to image: perspective and lens
       distortion; where a local homography is fixed too, it takes over where the quadratic
       finds no candidate and must agree where both do: steps that shrink towards a vanishing
       point or a fisheye's rim) and takes the candidate nearest the prediction within a third
       of the local step, where its link to each neighbour already in the lattice runs along
       an edge between a black and a white square, the right way round for the alternation
       (a quarter, a half and three quarters along, the shades either side differ by a fifth
       of the corners' contrast, with the sign the seed's squares give: a second pattern past
       a narrow margin, or a sheet over the board, does not join the lattice where one of its
       corners happens to lie near the next place). Lattices are grown from every corner not
       yet in one; each of at least half the size of the largest that could be the board (not more than two lines
       longer than it either way round) goes through steps 3-6, and where two pass as the
       board (the board and a second pattern), the one whose border is seen on more sides,
       less the sides where it runs out of the image, wins; on a tie the board is not found.
    3. Sub-pixel: the saddle point of a quadratic fitted on a window centred on each corner, the
       window's half-size an eleventh of the corner spacing (2 to 5 px); each corner's sigma
       from the fit's residuals. A corner whose sigma is over twice the board's median
       is not a clean junction (an occluder's edge, glare) and is dropped; so is one whose
       surroundings, on a circle of 0.15 of the spacing, are not point-symmetric (a finger's
       edge beside it pulls the fit a pixel off, too little for step 4 to see).
    4. Verification: every corner against the quadratic map fitted on its neighbours (the
       eight around it where seven or more are there, else those within two steps), itself
       left out; corners that miss it by more than 8 % of the spacing (0.6 px at least), or
       that cannot be checked, are dropped, worst first. A corner dropped there is put back
       where a model of the whole lattice (a homography and radial distortion, fitted on the
       corners that passed and trusted only where it predicts its own outer corners left out)
       predicts it within the same tolerance: a board near a fisheye's rim bends more than a
       quadratic follows. Where corners stay dropped, one such model is also fitted on the
       whole lattice, the corner it misses worst going each time until every corner left is
       within the tolerance; where three in four or more are left and it predicts its own
       outer corners left out, they are kept (at a fisheye's rim the squares can grow so fast
       that the local check keeps too few for the first model to start from). The largest
       group of corners linked as neighbours is kept (a group across a whole hidden row is
       not joined: nothing checks the count across it).
    5. Labels: the lattice is made right-handed in the image (the printed face is seen). A
       lattice the board's size is labelled as it is, unless the checker pattern goes on past
       one end. A shorter one (part of the board hidden or outside the image) is placed
       against the side where the board's border is seen: half a square out, the outer
       squares alternate; one and a half out, the plain light margin (squares alternating
       the other way there mean the pattern goes on; where no X-corner lies one step out, each
       such square must be one colour across its width, as a second pattern past a narrow
       margin is not). A side beyond which
       the lattice had corners that step 4 dropped is never taken for the border (the
       pattern goes on there), nor one whose outer squares light washes out (under 0.7 of the
       contrast of the lattice's last squares, the dark ones lifted by over 0.4 of it: a glare,
       past which burnt-out squares are as plain and light as a margin). Where neither end
       shows it, or the lattice fits the board either way round, the board is not found.
       One step past each side, where the pattern's next corners would be, X-corners at the
       places inside the image (their circle a quarter of the spacing where that is under
       4 px) mean the pattern goes on (a row missed, or a larger pattern),
       whatever the shades say; a lattice as long as the board with the pattern going on
       past an end is not found. A lattice one line longer than the board (a board with one
       more corner printed than declared) loses its weaker outer line only where the pattern
       is seen to end on all four sides (the places one step out mostly inside the image,
       with no X-corner): the whole printed pattern is in view; the labels along that axis
       are then fixed up to that shift, which a calibration absorbs into the view's pose.
       A lattice shorter than the board, or running out of the image, is labelled only
       where no other checker pattern is in view: four or more X-corners as strong as the
       board's away from it mean one is, and the lattice may be part of it (a second board
       cut by the image's edge looks like a part of this one).
    6. Colours: where the half-turn changes the squares' colours (``inner_cols +
       inner_rows`` odd) they decide it, with square (0, 0) black as :class:`Checkerboard`
       defines it; otherwise either print (black or white corner squares) is accepted and
       corner (0, 0) is the end nearer the image's top-left, as OpenCV leaves it. A square
       board's quarter-turn follows its colours the same way. Each colour is read against the
       corner's own squares (its two diagonals' squares compared, half a step out), so that a
       shadow over part of the board does not turn its white squares black. Labels whose
       colours disagree (under 80 % of the probed corners) are not returned.
    7. Scale: where the board was not found, or found with corners missing and squares of 40 px
       or more, steps 1-6 run again on the image halved (2x2 means), and again, as long as the
       smaller side keeps 120 px; the corners found at a level are refined on the full image
       with the smoothing and window scaled by the factor (smoothing only patches around the
       corners) and tested there for point symmetry again, also against the board's own
       corners (over four times their median asymmetry, where that passes 0.05, is not a
       clean junction: an occluder's edge that the coarse level's circle blurred). The level
       that labels the most corners wins (the finest on a tie). Where the board is found whole
       at full resolution but step 9 drops every corner as too uncertain (a screen's pixel
       grid, heavy noise), the coarser levels, which average that out, are looked at then.
       Squares from about 10 px to the whole frame thus meet the detector at 10-40 px.
    8. Noise: each corner's sigma is the larger of the fit's (from its residuals) and the
       image noise's (:func:`_noise_sigma`: the noise measured in the light squares' middles,
       in the band the fit sees, through each corner's own fit). Where that noise is under
       one level of the file's samples, the middles were flattened (JPEG leaves its error
       beside the edges, where the fit reads) or the image has no noise: each corner's noise
       is then read from the residuals of its own point-symmetric fit (step 9), through the
       same fit.
       Light: light that changes across a corner (a glare's slope, uneven light) moves its
       saddle point by ``H^-1 g`` (``g`` the light's gradient, ``H`` the fit's Hessian). The
       gradient is read from the squares around the corner (their shades at their middles and
       halfway to them, a plane and a contrast fitted: :func:`_shading_shift`) and the corner
       shifted back, its sigma grown by the reading's; only where the gradient is beyond its
       noise (what the plane misses counting as noise: a screen's moire), and the shift within a
       quarter of the fit's window. Where the light is there but no plane fits the shades
       (light that bends within a square, an occluder over one) or the shift would be larger,
       the corner stays and that shift is its sigma. Where a light square is clipped at the
       image's ceiling (a glare burnt out), the gradient is read along each diagonal from its
       own squares, and a corner it could move stays, its sigma grown by 1.4 times that shift
       (where a dark square is clipped too, the plane's reading stands). Light is smooth over
       more than a square, and under noise four squares do not read a vignetting's slope: where
       the shades of the squares within three of the corner (a 6x6 block, their middles) lie on
       a plane of light, that plane's slope replaces the four squares' reading, as read, not
       only where it passes its noise (:func:`_board_light`). A corner by the
       image's edge, its squares' middles outside, is read half as far out. Where a board found
       at a coarser level has corners the light leaves in doubt by more than a quarter of a
       pixel, it is fitted again with the smoothing halved (down to 1.5 px, the window with it)
       as far as the image's noise leaves its saddle points 0.02 px uncertain (median), and
       read again (:func:`_finer`: ``H`` falls with the square of the smoothing, and the light
       moves a sharp corner's saddle point less).
    9. Symmetry: where the noise leaves a corner's saddle point more than 0.02 px uncertain
       (a dim, noisy or JPEG-compressed board), the corner moves to the point through which
       the image around it, out to 0.3 of a square on the board, is point-symmetric, as a
       checkerboard is about each inner corner (:func:`_symmetric`, after Schoeps et al.,
       CVPR 2020): it reads the squares' edges along their length where the saddle fit reads
       a few pixels, so the noise moves it less, and the corner takes its sigma (which counts
       the noise in the gradients the fit reads: where that noise is half of them, the point
       has none). The board's outermost corners, and corners beside hidden ones, take their
       map of the board from a block of found corners near them. Where the two estimates disagree
       beyond their sigmas the saddle point stays. Below 0.02 px (twice
       the symmetric point's own error on noise-free renders) the saddle point stays too:
       noise is not what limits such a corner, and on clean real photos the two estimators
       differ systematically (benchmarks/notes.md, fourteenth session). Where the noise is
       read beside each corner (step 8: a flattened file), whose residuals carry the model's
       misfit too, the bar is 0.05 px. The light's gradient read in step 8 is taken off the
       symmetric fit too (a linear light is not point-symmetric), its uncertainty carried into
       the point's sigma; a corner the light leaves in doubt is not moved.
       Then a corner whose sigma passes a quarter of a pixel is dropped (it could lie a pixel
       off: a board too dim for its noise, light that bends across it); where fewer than four
       are left the board is not found, and the message says why.

    Corners not seen (fingers over them, outside the image, failing the check) are NaN rows.
    Grey, RGB(A) and 16-bit images are accepted. An image without a board gives
    ``found=False`` quickly, with the reason in ``message``.
    """
    if not isinstance(board, Checkerboard):
        raise ParameterError(f"board: expected a Checkerboard, got {type(board).__name__}")
    grey, step = _to_grey(image, with_step=True)
    noise = _image_noise(grey)
    best, best_factor = _coarser_levels(grey, board, _detect(grey, board, noise))
    if not best.found:
        return best
    result = _drop_noisy(grey, best, board, best_factor, noise, step)
    if not result.found and best_factor == 1:
        # Every corner found at full resolution too uncertain to keep (a screen's pixel grid,
        # heavy noise): the coarser levels, which average it out, were not looked at, as the
        # board was whole there. Look at them now.
        again, factor = _coarser_levels(grey, board, Detection.not_found(len(best.corners), result.message,
                                                                          best.window_px))
        if again.found:
            retry = _drop_noisy(grey, again, board, factor, noise, step)
            if retry.found:
                return retry
    return result


def _coarser_levels(grey: np.ndarray, board: Checkerboard, best: Detection) -> tuple[Detection, int]:
    """Step 7 of :func:`detect_corners`: from ``best`` (the full resolution's detection), the
    coarser levels while the board is not found, or found with corners missing and squares of
    ``_COARSER_FROM_PX`` or more; returns the detection that labels most corners (refined at
    full resolution) and its level's factor."""
    level = grey
    factor = best_factor = 1
    n_corners = board.inner_cols * board.inner_rows
    while (best.n_found < n_corners and min(level.shape) >= 2 * _MIN_PYRAMID_SIDE
           and (not best.found or _corner_spacing(best.corners, board) >= _COARSER_FROM_PX * factor)):
        # Large squares (a 300-dpi scan, a 24 MP photo of a near board, a sharp board upscaled):
        # the smoothing and profile circle see edges, not corners. Look again at half the
        # resolution, refine at full resolution, and keep the level that labels most corners.
        level = _half(level)
        factor *= 2
        coarse = _detect(level, board)
        if coarse.found:
            full = _refine_full(grey, coarse, factor, board)
            if full.found and (not best.found or full.n_found > best.n_found):
                best, best_factor = full, factor
    return best, best_factor


#: The pyramid stops before an image side falls under this many pixels.
_MIN_PYRAMID_SIDE = 120
#: A board found with corners missing is looked for at the next coarser level only where its
#: squares span this many pixels or more at the current one (smaller squares lose detail there).
_COARSER_FROM_PX = 40.0


def _corner_spacing(corners: np.ndarray, board: Checkerboard) -> float:
    """Median distance between neighbouring labelled corners (NaN where none are)."""
    return _grid_spacing(corners, board.inner_cols)


def _grid_spacing(corners: np.ndarray, cols: int) -> float:
    """:func:`_corner_spacing` of a lattice of ``cols`` columns, labelled row by row."""
    idx = np.flatnonzero(np.isfinite(corners).all(axis=1))
    return _lattice_spacing(np.stack([idx % cols, idx // cols], axis=-1), corners[idx], default=float("nan"))


def _half(img: np.ndarray) -> np.ndarray:
    """The 2x2 mean: pixel (x, y) of the half image covers full-resolution pixels 2x..2x+1."""
    out = work_array((img.shape[0] // 2, img.shape[1] // 2), np.float64)
    if isinstance(img, RawGrey):
        detect_kernels.half_mean(img.raw, out)
        out *= img.a
        out += img.b
        return out
    detect_kernels.half_mean(np.ascontiguousarray(img, dtype=np.float64), out)
    return out


def _refine_full(grey: np.ndarray, coarse: Detection, factor: int, board: Checkerboard) -> Detection:
    """Corners found at 1/factor resolution, refined on the full image: positions mapped back
    (x_full = (x + 0.5) * factor - 0.5), then the saddle fit with the smoothing and window scaled
    by the factor; a corner that moves more than ``factor`` pixels is dropped (NaN) (step 8 may
    fit them again finer: :func:`_finer`)."""
    cols, rows = board.inner_cols, board.inner_rows
    c = (coarse.corners + 0.5) * factor - 0.5
    seen = np.isfinite(c).all(axis=1)
    spacing = _corner_spacing(c, board)
    if not np.isfinite(spacing):
        spacing = 11.0 * factor
    r = int(np.clip(round(spacing / _SPACING_PER_WINDOW), 2, 5 * factor))
    # The smoothing scaled by the factor, computed only on a patch around each corner: enough
    # for the fit's window, its bicubic support and the fit's moves (at most a pixel each of
    # six iterations).
    # The patches also hold the circle of the point-symmetry test about a corner moved by up
    # to the factor (and the bilinear samples' second pixel).
    half = max(r + 9, int(np.ceil(max(2.0, _ASYMMETRY_CIRCLE * spacing))) + factor + 2)
    mosaic, shift = _smoothed_patches(grey, c[seen], half, _SIGMA * factor)
    refined, sig = _saddle_fit(mosaic, c[seen] + shift, r)
    out = np.full_like(c, np.nan)
    sigma = np.full(len(c), np.nan)
    moved = np.hypot(*(refined - shift - c[seen]).T)
    ok = np.isfinite(moved) & (moved <= factor) & _fits_well(sig)
    # The point-symmetry test of step 3 again, on the full image's detail, against the board's
    # own corners: the coarse level's circle blurs an occluder's edge that touches a corner.
    if ok.any():
        asym = _asymmetry(mosaic, refined[ok], spacing)
        limit = min(_MAX_ASYMMETRY, max(_ASYMMETRY_FLOOR, _ASYMMETRY_TIMES * float(np.median(asym))))
        ok[np.flatnonzero(ok)[asym > limit]] = False
    refined -= shift
    keep = np.flatnonzero(seen)[ok]
    # The check of step 4 again, at full resolution (a corner drawn onto a finger's edge there).
    gk = np.stack([keep % cols, keep // cols], axis=-1)
    good = _checked(gk, refined[ok], spacing, grey.shape)
    out[keep[good]] = refined[ok][good]
    sigma[keep[good]] = sig[ok][good]
    # The refined lattice may not bend more than the coarse one did (a corner drawn a step off
    # at full resolution); how much the coarse one bends was judged there (a fisheye's rim
    # bends a whole board: real fisheye view 26 enlarged 2x, 0.107 of its triples).
    if _bent_fraction(out.reshape(rows, cols, 2)) > max(0.1, _bent_fraction(c.reshape(rows, cols, 2))):
        return Detection.not_found(len(c), f"not found: the lattice found at 1/{factor} resolution is "
                                           "inconsistent at full resolution", r)
    found = int(np.isfinite(out).all(axis=1).sum())
    if found < 4:
        return Detection.not_found(len(c), f"not found: of the corners found at 1/{factor} resolution, {found} pass "
                                           "the checks at full resolution", r)
    return Detection(True, out, sigma, r, f"found {found} of {cols * rows} corners at 1/{factor} resolution, "
                           f"refined at full resolution (window {r} px)")


#: A board refined from a coarser level whose light leaves corners in doubt is fitted again at
#: the finest smoothing (halving from the coarse level's, down to ``_SIGMA``) at which the
#: image's noise leaves its corners' saddle points this uncertain or less (median, px):
#: ``_SYM_FROM_SIGMA``, below which noise is not what limits a corner (step 9).
_FINER_NOISE = 0.02


def _finer(grey: np.ndarray, det: Detection, factor: int, board: Checkerboard,
           image_noise: float) -> tuple[Detection, float] | None:
    """A board found at 1/``factor`` resolution and refined with that level's smoothing
    (``_SIGMA * factor``, window ``det.window_px``), fitted again at a finer scale: the
    smoothing halved, and the window with it (2 px at least), as far as ``_SIGMA``, at the
    finest scale at which the image's noise (:func:`_noise_sigma`) leaves the board's corners
    ``_FINER_NOISE`` px uncertain or less (median). Returns the detection and its smoothing,
    or None where no finer scale qualifies.

    Light that changes across a corner moves its saddle point by ``H^-1 g``, and the Hessian
    ``H`` of a sharp junction falls with the square of the scale it is read at: a glare's slope
    over a sharp board of 105 px squares refined from the 1/4 level (smoothing 6 px, window 10)
    put its corners 0.7-1.6 px off; at 1.5 px and a window of 2-3, 0.03-0.2 px
    (benchmarks/notes.md, thirty-eighth session). :func:`_drop_noisy` calls this only where
    the light leaves a corner in doubt at the coarse scale beyond ``_MAX_CORNER_SIGMA``
    (:func:`_shading_shift`: it would be dropped). Elsewhere the coarse fit stands: a finer fit
    reads JPEG's error beside the edges, which the noise measured in the squares' middles does
    not show. A corner whose fit at the finer scale fails or moves more than ``factor`` px is
    dropped: its coarse place is what the light moved."""
    cols, rows = board.inner_cols, board.inner_rows
    coarse_smoothing = _SIGMA * factor
    corners, r = det.corners, det.window_px
    seen = np.isfinite(corners).all(axis=1)
    scales = []
    s = coarse_smoothing / 2
    while s >= _SIGMA - 1e-9:
        scales.append((s, max(2, round(r * s / coarse_smoothing))))
        s /= 2
    for s, rs in reversed(scales):  # the finest first
        noise = _noise_sigma(grey, corners, cols, rows, rs, s, image_noise)[0][seen]
        noise = noise[np.isfinite(noise)]
        if len(noise) < 4 or np.median(noise) > _FINER_NOISE:
            continue
        mosaic, shift = _smoothed_patches(grey, corners[seen], rs + 9, s)
        refined, sig = _saddle_fit(mosaic, corners[seen] + shift, rs)
        refined -= shift
        moved = np.hypot(*(refined - corners[seen]).T)
        ok = np.isfinite(moved) & (moved <= factor) & _fits_well(sig)
        if ok.sum() < 4:
            return None
        out, out_sigma = np.full_like(corners, np.nan), np.full(len(corners), np.nan)
        keep = np.flatnonzero(seen)[ok]
        out[keep] = refined[ok]
        out_sigma[keep] = sig[ok]
        return Detection(True, out, out_sigma, rs, f"{det.message}; the light left corners in doubt: fitted again "
                                                   f"at {s:g} px (window {rs} px), {int(ok.sum())} kept"), s
    return None


def _smoothed_patches(grey: np.ndarray, pts: np.ndarray, half: int, smoothing: float) -> tuple[np.ndarray, np.ndarray]:
    """The image smoothed (Gaussian, ``smoothing`` px) on a square of ``2 half + 1`` pixels
    around each point only, the squares side by side in one mosaic (a :class:`RawGrey` is
    stretched after the blur: the stretch is affine and the blur's taps sum to one). Returns
    (mosaic, shift): a point ``p`` of the image is at ``p + shift[i]`` in point i's square."""
    side = 2 * half + 1
    n = len(pts)
    per_row = max(1, int(np.ceil(np.sqrt(n))))
    origin = np.floor(pts).astype(np.int64) - half
    tile = np.stack([np.arange(n) % per_row, np.arange(n) // per_row], axis=-1) * side
    mosaic = np.zeros((side * max(1, (n + per_row - 1) // per_row), side * per_row))
    raw = isinstance(grey, RawGrey)
    detect_kernels.blur_patches(grey.raw if raw else grey, np.ascontiguousarray(origin), np.ascontiguousarray(tile),
                                side, smoothing, mosaic)
    if raw:
        mosaic *= grey.a
        mosaic += grey.b
    return mosaic, (tile - origin).astype(np.float64)


#: A corner whose position the image's noise leaves more uncertain than this (one-sigma per
#: axis, px) is dropped. Under Gaussian errors it lies more than a pixel from where it is
#: returned with a chance of exp(-1 / (2 sigma^2)): 0.03 % at a quarter of a pixel, 1 % at a
#: third. The margin covers the noise read low (JPEG keeps more of it beside edges than in
#: the flat middles where it is measured: up to about twice).
_MAX_CORNER_SIGMA = 0.25
#: Each light square's middle is compared with this many nearest; with no more light middles
#: than this, the noise is the whole image's.
_MIN_NOISE_SQUARES = 4


def _square_grid(corners: np.ndarray, cols: int, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Every square of the board, (rows + 1) x (cols + 1), the outer ones included (their outer
    corners continued one step from the two lines inside): its middle and the distance from
    the middle to the nearest of its sides, NaN where one of its corners is unknown. Returns
    ((rows + 1, cols + 1, 2), (rows + 1, cols + 1))."""
    G = np.full((rows + 2, cols + 2, 2), np.nan)
    G[1:-1, 1:-1] = corners.reshape(rows, cols, 2)
    G[0, 1:-1] = 2 * G[1, 1:-1] - G[2, 1:-1]
    G[-1, 1:-1] = 2 * G[-2, 1:-1] - G[-3, 1:-1]
    G[:, 0] = 2 * G[:, 1] - G[:, 2]
    G[:, -1] = 2 * G[:, -2] - G[:, -3]
    ring = np.stack([G[:-1, :-1], G[:-1, 1:], G[1:, 1:], G[1:, :-1]], axis=2)  # (rows + 1, cols + 1, 4, 2)
    mid = ring.mean(axis=2)
    e = np.roll(ring, -1, axis=2) - ring
    w = mid[:, :, None] - ring
    with np.errstate(divide="ignore", invalid="ignore"):
        dist = np.abs(e[..., 0] * w[..., 1] - e[..., 1] * w[..., 0]) / np.hypot(e[..., 0], e[..., 1])
    clear = np.nan_to_num(dist, nan=0.0).min(axis=2)
    clear[~np.isfinite(mid).all(axis=2)] = np.nan
    return mid, clear


def _square_middles(corners: np.ndarray, cols: int, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The middle of every square with its four corners known (:func:`_square_grid`) and the
    distance from each middle to the nearest of its square's sides. Returns ((M, 2), (M,))."""
    mid, clear = _square_grid(corners, cols, rows)
    known = np.isfinite(mid).all(axis=2)
    return mid[known], clear[known]


@functools.lru_cache(maxsize=64)
def _fit_noise_factors(r: int, smoothing: float) -> tuple[float, tuple[float, float]]:
    """For unit white noise smoothed by a Gaussian of ``smoothing`` px (correlation K between
    pixels d apart: exp(-d^2 / (4 s^2)) / (4 pi s^2)) and the quadratic fitted on a
    (2r+1)^2 window (design A, fit P = (A^T A)^-1 A^T): the residuals' mean square,
    tr(R K R^T) / n = (tr K - tr((A^T A)^-1 A^T K A)) / n (R = I - A P is a symmetric
    projector), and the variances of the two gradient terms, the 33 and 44 entries of
    P K P^T = (A^T A)^-1 A^T K A (A^T A)^-1. K is separable and the design's columns are
    products of powers of x and y, so A^T K A comes from the 1-D kernel alone (no n x n
    matrix)."""
    t = np.arange(-r, r + 1, dtype=np.float64)
    k1 = np.exp(-(t[:, None] - t[None]) ** 2 / (4 * smoothing * smoothing))
    powers = [(2, 0), (1, 1), (0, 2), (1, 0), (0, 1), (0, 0)]  # x^i y^j, the columns of A
    m1 = np.stack([t ** e for e in range(3)])  # 1-D monomials
    g = m1 @ k1 @ m1.T  # (x^i)^T k1 (x^i')
    h = m1 @ m1.T
    AKA = np.array([[g[i, k] * g[j, l] for k, l in powers] for i, j in powers]) / (4 * np.pi * smoothing * smoothing)
    AtA_inv = np.linalg.inv(np.array([[h[i, k] * h[j, l] for k, l in powers] for i, j in powers]))
    n = len(t) ** 2
    resid = (n / (4 * np.pi * smoothing * smoothing) - float(np.trace(AtA_inv @ AKA))) / n
    PKP = AtA_inv @ AKA @ AtA_inv
    return float(resid), (float(PKP[3, 3]), float(PKP[4, 4]))

def _noise_sigma(grey: np.ndarray, corners: np.ndarray, cols: int, rows: int, r: int,
                 smoothing: float, image_noise: float) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """Each corner's one-sigma (per axis, px) from the image's noise, NaN where it has no
    saddle, the white pixel noise ``w`` measured on the board, each corner's sigma per
    unit of white noise (the first output is ``w`` times it), and the inverse of each
    corner's saddle Hessian (its elements 11, 12, 22; NaN rows where it has none). The sigma is what the
    fit's residuals miss (they take the smoothed noise as independent, and on a dim board
    under JPEG read tens of times low).

    The noise is measured where the board is flat, in the band the fit sees: the same
    quadratic on the same window of the image smoothed the same way, at the middles of the
    light squares (dark ones may be clipped at black) whose sides clear the window by two
    smoothing sigmas. Each middle's residuals, less the median of its four nearest
    neighbours' (the squares' edges reach in alike), give a white noise's variance w^2
    through the smoothing's correlation K: the residuals' mean square is w^2 tr(R K R^T) / n,
    R the fit's residual operator and n the window's pixels. Middles over four times the
    median (an occluder, text) do not count. Where no more than ``_MIN_NOISE_SQUARES`` light
    middles qualify (small or foreshortened squares), and as a floor, w is the whole image's
    noise, ``image_noise`` (:func:`_image_noise`, which JPEG's flattened areas and clipped
    pixels pull low).
    Then w^2 P K P^T (P the fit) is the variance of the fit's gradient terms, and each
    corner's Hessian turns it into the saddle point's.
    """
    sigma = np.full(len(corners), np.nan)
    seen = np.isfinite(corners).all(axis=1)
    if seen.sum() == 0:
        return sigma, image_noise, sigma.copy(), np.full((len(corners), 3), np.nan)
    mid, clear = _square_middles(corners, cols, rows)
    h, w = grey.shape[:2]
    margin = r + 3
    use = ((clear >= r + 2.0 * smoothing) & (mid[:, 0] >= margin) & (mid[:, 1] >= margin)
           & (mid[:, 0] <= w - 1 - margin) & (mid[:, 1] <= h - 1 - margin))
    mid = mid[use]
    m = len(mid)
    pts = np.concatenate([mid, corners[seen]])
    mosaic, shift = _smoothed_patches(grey, pts, r + 3, smoothing)
    dx, dy, A = _quad_design(r)
    P = _saddle_design(r)[0]
    q = pts + shift
    vals = _sample(mosaic, q[:, :1] + dx, q[:, 1:] + dy, "bicubic")
    coef = vals @ P.T
    resid_factor, var_grad = _fit_noise_factors(r, smoothing)
    white = image_noise ** 2
    light = coef[:m, 5] >= np.median(coef[:m, 5]) if m else np.zeros(0, dtype=bool)
    if light.sum() > _MIN_NOISE_SQUARES:
        res = (vals[:m] - coef[:m] @ A.T)[light]
        ml = mid[light]
        near = np.argsort(np.hypot(*(ml[:, None] - ml[None]).transpose(2, 0, 1)), axis=1)[:, 1:_MIN_NOISE_SQUARES + 1]
        res = res - np.median(res[near], axis=1)
        v = (res * res).mean(axis=1)
        # The neighbours' median adds about half a neighbour's variance to each middle's.
        white = max(white, float(v[v <= 4.0 * np.median(v)].mean() / resid_factor / (1.0 + 0.5 / _MIN_NOISE_SQUARES)))
    var_d, var_e = var_grad
    a, b, cc = coef[m:, 0], coef[m:, 1], coef[m:, 2]
    det = 4 * a * cc - b * b
    inverse = np.full((len(corners), 3), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):  # a flat fit: no sigma
        h11, h12, h22 = 2 * cc / det, -b / det, 2 * a / det
        sigma[seen] = np.sqrt(0.5 * (var_d * (h11 * h11 + h12 * h12) + var_e * (h12 * h12 + h22 * h22)))
    inverse[seen] = np.stack([h11, h12, h22], axis=-1)
    return sigma * np.sqrt(white), float(np.sqrt(white)), sigma, inverse


def _sym2(m: np.ndarray) -> np.ndarray:
    """Symmetric 2x2 matrices (K, 2, 2) from their elements (xx, xy, yy) as columns (K, 3)."""
    return np.stack([m[:, [0, 1]], m[:, [1, 2]]], axis=-2)


def _local_steps(corners: np.ndarray, cols: int, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Each corner's lattice steps along the board's columns and rows (px, (N, 2) each): central
    differences, one-sided where a neighbour is missing, the board's median where both are."""
    C = corners.reshape(rows, cols, 2)
    steps = []
    for axis in (1, 0):
        fwd = np.diff(C, axis=axis)
        back = np.full(C.shape, np.nan)
        ahead = np.full(C.shape, np.nan)
        if axis == 1:
            back[:, 1:], ahead[:, :-1] = fwd, fwd
        else:
            back[1:], ahead[:-1] = fwd, fwd
        one = np.where(np.isfinite(back), back, ahead)
        e = np.where(np.isfinite(back) & np.isfinite(ahead), 0.5 * (back + ahead), one)
        e = e.reshape(-1, 2)
        missing = ~np.isfinite(e).all(axis=1)
        if missing.any() and (~missing).any():
            e[missing] = np.median(e[~missing], axis=0)
        steps.append(e)
    return steps[0], steps[1]


#: Step 8's shading: each place's shade is the mean of the pixels in a box reaching this
#: fraction of the step from it.
_SHADE_RADIUS = 0.12
#: ... the light's gradient counts where it is beyond its noise: its chi-square (2 degrees of
#: freedom) over this (0.03 % by chance; at 9, a screen's moire read as light moved corners of
#: a probe view 1.1-1.4 px, benchmarks/notes.md, thirty-sixth session).
_SHADE_CHI2 = 16.0
#: ... and a plane describes the light where the eight places miss it by at most three of their
#: noise's sigmas plus this fraction of the squares' half-contrast (RMS): more is an occluder
#: over a square, a second pattern, or light that bends within a square (a glare's spot).
_SHADE_MISFIT = 0.1
#: ... and the shift it implies is at most this fraction of the saddle fit's window half-size.
_SHADE_MAX_SHIFT = 0.25
#: Where a corner's places lie outside the image (a corner by its edge), they are read this
#: fraction of the way out (a quarter and half a step from the corner; glare probe view 3009,
#: benchmarks/notes.md, thirty-eighth session).
_SHADE_NEAR_EDGE = 0.5
#: The image is clipped where a plateau of its pixels shares its maximum, this many and this
#: fraction of them at least (an unclipped image's maximum is a few pixels); pixels there are at
#: its ceiling, and clipped shades do not measure the light.
_CLIP_PLATEAU = 16
_CLIP_PLATEAU_FRACTION = 1e-4


def _clip_ceiling(img: np.ndarray) -> float:
    """The image's ceiling where it is clipped (a plateau of ``_CLIP_PLATEAU`` pixels, and
    ``_CLIP_PLATEAU_FRACTION`` of them, at its maximum), else ``inf``."""
    ceiling = float(img.max())
    if np.count_nonzero(img >= ceiling) < max(_CLIP_PLATEAU, _CLIP_PLATEAU_FRACTION * img.size):
        return np.inf
    return ceiling


def _shading_shift(grey: np.ndarray, corners: np.ndarray, cols: int, rows: int, inverse: np.ndarray,
                   white: float, r: int, ceiling: float | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Step 8 of :func:`detect_corners`: how far a gradient of the light moves each saddle point,
    the variance (px^2, per axis) that reading adds to the corner's (zero and NaN where the
    light's gradient is not read beyond its noise), the gradient (shade per px, (N, 2)) and its
    covariance ((N, 3): xx, xy, yy) where the corner was shifted (zeros elsewhere), and which
    corners the light leaves in doubt (below).

    A saddle point is the stationary point of the quadratic fitted around it, and light that
    changes linearly across the corner (a glare's slope, uneven light) adds its gradient ``g``
    to the fit's linear terms: the saddle point lies ``H^-1 g`` from the junction (``H`` the
    fit's Hessian; ``inverse``: :func:`_noise_sigma`'s). The fit cannot tell that gradient from
    the junction's own; the squares around it can: the two light squares differ by the
    gradient along their diagonal, the two dark ones along the other. Each square's shade is
    read at its middle and halfway to it (the mean of the pixels in a box reaching
    ``_SHADE_RADIUS`` of a step from the nearest pixel), and a plane and a contrast for each
    ring (the inner places may lie in the edges' blur) fitted to the eight (least squares,
    three degrees of freedom to spare). Each shade's noise is the white noise ``white``, or
    the box's own spread where that is more (texture within the squares: a screen's grid),
    over its pixels, or what the plane misses where that is more (moire); the shift's
    variance is that, propagated.

    The shift is made where the gradient's chi-square passes ``_SHADE_CHI2``, the plane fits
    the eight shades (``_SHADE_MISFIT``) and the shift is within ``_SHADE_MAX_SHIFT`` of the
    fit's window half-size ``r``. Where the gradient is there but no plane fits (light that
    bends within a square, an occluder over a square) or the shift would be larger, the
    corner is not shifted and the shift the gradient implies is its variance: how far the
    light may have moved it. Where a place lies outside the image (a corner by its edge), the
    places are read ``_SHADE_NEAR_EDGE`` of the way out; where one still does, or the shades show no
    contrast beyond three of its sigmas, nothing is read.

    Clipped light (a glare burnt out to the image's ceiling) hides the gradient: where a light
    square's places hold pixels at the ceiling, the gradient is read along each diagonal from
    its own squares (the light one's a lower bound), and where it is beyond its noise the
    corner is in doubt, its variance twice the square of the shift it implies (where a dark
    square's places hold such pixels too, the plane's reading stands). ``ceiling``: the image's
    :func:`_clip_ceiling`, where the caller has read it (else it is read here)."""
    n = len(corners)
    shift = np.zeros((n, 2))
    var = np.full(n, np.nan)
    gradient = np.zeros((n, 2))
    gcov = np.zeros((n, 3))
    doubt = np.zeros(n, dtype=bool)
    nothing = shift, var, gradient, gcov, doubt
    seen = np.isfinite(corners).all(axis=1) & np.isfinite(inverse).all(axis=1)
    if seen.sum() < 2:
        return nothing
    e1, e2 = _local_steps(corners, cols, rows)
    idx = np.flatnonzero(seen & np.isfinite(e1).all(axis=1) & np.isfinite(e2).all(axis=1))
    c, e1, e2 = corners[idx], e1[idx], e2[idx]
    # Two places in each square: its middle and halfway to it along the diagonal; the first two
    # squares of each ring one colour, the last two the other.
    signs = np.array([[1.0, 1.0], [-1.0, -1.0], [1.0, -1.0], [-1.0, 1.0]] * 2)
    t = np.repeat([1.0, 0.5], 4)
    colour = np.array([1.0, 1.0, -1.0, -1.0] * 2)
    h, w = grey.shape[:2]

    def places(scale: float) -> tuple[np.ndarray, ...]:
        """The boxes' centres (K, 8) and half-sizes, ``scale`` of the way out to them."""
        d = (0.5 * t * scale)[None, :, None] * (signs[None, :, :1] * e1[:, None] + signs[None, :, 1:] * e2[:, None])
        rad = _SHADE_RADIUS * np.minimum(np.hypot(*e1.T), np.hypot(*e2.T))[:, None] * t * scale  # (K, 8)
        # Each place's shade: the mean over a box of pixels (2b + 1 wide) about it (point samples
        # alias with a screen's pixel grid).
        b = np.maximum(1, np.round(rad)).astype(np.int64)
        cx = np.round(c[:, None, 0] + d[..., 0]).astype(np.int64)
        cy = np.round(c[:, None, 1] + d[..., 1]).astype(np.int64)
        inside = ((cx - b >= 0) & (cx + b <= w - 1) & (cy - b >= 0) & (cy + b <= h - 1)).all(axis=1)
        return cx, cy, b, inside

    cx, cy, b, inside = places(1.0)
    # A corner near the image's edge, its squares' middles outside: read half as far out.
    if not inside.all():
        hx, hy, hb, hin = places(_SHADE_NEAR_EDGE)
        near = ~inside & hin
        cx[near], cy[near], b[near] = hx[near], hy[near], hb[near]
        inside |= near
    d = np.stack([cx - c[:, None, 0], cy - c[:, None, 1]], axis=-1)  # the boxes' centres
    k = len(idx)
    M = np.concatenate([np.ones((k, 8, 1)), d, np.broadcast_to((colour * (t == 1.0))[None, :, None], (k, 8, 1)),
                        np.broadcast_to((colour * (t == 0.5))[None, :, None], (k, 8, 1))], axis=2)
    MtM = np.einsum("kai,kaj->kij", M, M)
    # The squares are not flattened to a line (the design then has full rank).
    cross = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    l1, l2 = np.hypot(*e1.T), np.hypot(*e2.T)
    ok = inside & (cross > 0.05 * l1 * l2) & (np.minimum(l1, l2) >= 4.0)
    if not ok.any():
        return nothing
    idx, M, MtM, b, cx, cy = idx[ok], M[ok], MtM[ok], b[ok], cx[ok], cy[ok]
    img = np.ascontiguousarray(grey.dense() if isinstance(grey, RawGrey) else grey, dtype=np.float64)
    if ceiling is None:
        ceiling = _clip_ceiling(img)
    shade, spread, clip = np.empty(cx.shape), np.empty(cx.shape), np.empty(cx.shape)
    detect_kernels.box_means(img, cx.ravel(), cy.ravel(), b.ravel(), ceiling, shade.ravel(),
                             spread.ravel(), clip.ravel())
    n_px = (2 * b + 1) ** 2
    P = np.linalg.solve(MtM, M.transpose(0, 2, 1))  # (K, 5, 8)
    sol = np.einsum("kij,kj->ki", P, shade)
    # Each shade's variance: the white noise, or the pixels' own spread where that is more
    # (texture within the squares: a screen's grid, print), over the box's pixels.
    var_white = white ** 2 / n_px
    var_shade = np.fmax(white ** 2, spread) / n_px
    res = shade - np.einsum("kaj,kj->ka", M, sol)
    misfit = np.sqrt((res * res).sum(axis=1) / 3.0)
    # What the plane misses counts as the shades' noise where it is more (texture within the
    # squares: a screen's moire, print, JPEG's blocks).
    cov = np.einsum("kia,ka,kja->kij", P, np.fmax(var_shade, misfit[:, None] ** 2), P)
    contrast = np.abs(sol[:, 3])
    gx, gy = sol[:, 1], sol[:, 2]
    cg = cov[:, 1:3, 1:3]
    dg = cg[:, 0, 0] * cg[:, 1, 1] - cg[:, 0, 1] ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        quad = cg[:, 1, 1] * gx * gx - 2 * cg[:, 0, 1] * gx * gy + cg[:, 0, 0] * gy * gy
        chi2 = np.where(dg > 0, quad / dg, np.inf)
    read = (contrast > 3.0 * np.sqrt(cov[:, 3, 3])) & (chi2 > _SHADE_CHI2)
    hv = inverse[idx]
    Hi = _sym2(hv)
    implied = np.einsum("kij,kj->ki", Hi, sol[:, 1:3])
    plane = misfit <= 3.0 * np.sqrt(var_white.mean(axis=1)) + _SHADE_MISFIT * contrast
    # The quadratic describes the junction within its window: a shift past a quarter of it is
    # no first-order correction (motion blur of 8-20 px, read as light, gave 1 px at half).
    plane &= np.hypot(*implied.T) <= _SHADE_MAX_SHIFT * r
    cs = Hi @ cg @ Hi.transpose(0, 2, 1)
    moved = read & plane
    bent = read & ~plane
    # Where a light square is clipped at the image's ceiling (a glare burnt out), the plane's
    # reading is biased. The light's gradient is then read along each diagonal from its own
    # square's four places: the dark squares' slope as it is, the light ones' a lower bound
    # where one of them is clipped (nothing where both are). Where either slope is beyond its
    # noise the corner is in doubt, not shifted, with twice the square of the shift they imply
    # as its variance (what clipping hides taken as large as what is seen). Where a dark
    # square's places hold clipped pixels too, no diagonal is whole and the plane's reading
    # stands (a square narrower than the step, its middle in the sheet's margin: real
    # opencv_right right05 lost a corner 0.08 px from OpenCV's to a rule that dropped them).
    first_light = shade[:, colour > 0].mean(axis=1) > shade[:, colour < 0].mean(axis=1)
    light = np.where(first_light[:, None], colour > 0, colour < 0)
    clipped = ((clip > 0) & light).any(axis=1) & ~((clip > 0) & ~light).any(axis=1)
    if clipped.any():
        moved &= ~clipped
        bent &= ~clipped
        k = int(clipped.sum())
        dirs, slopes, sloped = np.empty((k, 2, 2)), np.empty((k, 2)), np.zeros(k, dtype=bool)
        for n_, own in enumerate((np.where(first_light[clipped, None], [2, 3, 6, 7], [0, 1, 4, 5]),
                                  np.where(first_light[clipped, None], [0, 1, 4, 5], [2, 3, 6, 7]))):
            at = np.take_along_axis(M[clipped, :, 1:3], own[..., None], axis=1)  # the boxes' centres
            u = at[:, 0] - at[:, 1]
            u /= np.maximum(np.hypot(*u.T), 1e-12)[:, None]
            along = np.einsum("kaj,kj->ka", at, u)
            along -= along.mean(axis=1, keepdims=True)
            ss = np.maximum((along * along).sum(axis=1), 1e-12)
            slope = (along * np.take_along_axis(shade[clipped], own, axis=1)).sum(axis=1) / ss
            slope_var = (along * along * np.take_along_axis(var_shade[clipped], own, axis=1)).sum(axis=1) / ss ** 2
            dirs[:, n_], slopes[:, n_] = u, slope
            sloped |= slope * slope > _SHADE_CHI2 * slope_var
        # The two diagonals' directions fix the gradient (near-parallel ones: the slopes as they are).
        g = np.linalg.solve(np.where(np.abs(np.linalg.det(dirs))[:, None, None] > 0.05, dirs, np.eye(2)),
                            slopes[..., None])[..., 0]
        moves = (np.einsum("kij,kj->ki", Hi[clipped], g) ** 2).sum(axis=1)
        where = idx[clipped]
        var[where[sloped]] = 2.0 * moves[sloped]
        doubt[where[sloped]] = True
    shift[idx[moved]] = implied[moved]
    var[idx[moved]] = 0.5 * (cs[moved, 0, 0] + cs[moved, 1, 1])
    gradient[idx[moved]] = sol[moved, 1:3]
    gcov[idx[moved]] = np.stack([cg[moved, 0, 0], cg[moved, 0, 1], cg[moved, 1, 1]], axis=-1)
    var[idx[bent]] = (implied[bent] ** 2).sum(axis=1)
    doubt[idx[bent]] = True
    return shift, var, gradient, gcov, doubt


#: Step 8's light over the board: each corner's gradient of the light is read from the squares
#: within this many squares of it each way (a plane over a 6x6 block of them). On the stress
#: corpus's seeds 0-1999, 95th percentile with noise 0.1041 px with step 8's four squares alone;
#: with the block's slope given to step 9, 0.0992 / 0.0978 / 0.0973 / 0.0976 px over blocks of
#: 4x4 / 6x6 / 8x8 / 12x12 squares and 0.1005 px with a quadratic over 6x6; 0.0971 px with the
#: saddle point shifted by it too (benchmarks/notes.md, fortieth session).
_LIGHT_SQUARES = 3
#: ... each square's shade the mean over a box about its middle reaching this fraction of the
#: way to its nearest side (half-diagonal 0.5: clear of its edges' blur).
_LIGHT_BOX = 0.35
#: ... and a plane describes the light where the squares miss it by at most three of their
#: noise's sigmas plus this fraction of the squares' half-contrast (RMS): more is an occluder,
#: a glare's spot, a shadow's edge, a second pattern. Half step 8's ``_SHADE_MISFIT``: 36 box
#: means are each read far better than step 8's eight places. On the corpus 0.05 and 0.1 give
#: the same figures; on the glare probe's seeds 3000-3199 the 95th percentile is 0.2007 px at
#: 0.05 and 0.2044 at 0.1 (benchmarks/notes.md, fortieth session).
_LIGHT_MISFIT = 0.05


def _board_light(grey: np.ndarray, corners: np.ndarray, cols: int, rows: int, inverse: np.ndarray, white: float,
                 r: int, step: float, local: tuple[np.ndarray, ...], ceiling: float | None = None
                 ) -> tuple[np.ndarray, ...]:
    """Step 8 again over more of the board: each corner's gradient of the light read from the
    squares around it, in place of :func:`_shading_shift`'s (``local``, the same five arrays)
    wherever it can be read. Returns the five arrays of :func:`_shading_shift`.

    :func:`_shading_shift` reads the gradient from the corner's own four squares, at most
    three quarters of a square from it, and keeps it only where it is beyond its noise (a
    chi-square of ``_SHADE_CHI2``): under noise or JPEG the vignetting's and the uneven
    light's slope (a tenth to a third of a percent of the contrast per pixel) is not, and the
    point of symmetry (step 9) of a blurred corner lies its ``sens`` times that slope off (on
    stress view 1496 a drawing of the exact pattern with the fitted slope reproduced a
    corner's 0.07 px offset to 0.001 px; benchmarks/notes.md, thirty-ninth session). Light is
    smooth over far more than a square. Here every square of the board with its four corners
    known (the outer ones' outer corners continued a step: :func:`_square_grid`) gives
    one shade: the mean over a box about its middle reaching ``_LIGHT_BOX`` of the way to its
    nearest side, its variance the larger of the white noise ``white``, the box's own spread
    and a quantisation's (``step`` squared over 12) over its pixels; boxes outside the image
    or holding pixels clipped at the image's ceiling give none. Each corner's squares within
    ``_LIGHT_SQUARES`` each way (a 6x6 block, less at the board's edges) are fitted (weighted
    least squares) with a plane for their mean level and one for their half-contrast, the
    colour the squares' checker parity; the first plane's slope is the gradient, its
    covariance the fit's (scaled up by the residuals' chi-square per degree of freedom where
    that is above 1). It stands where the plane fits (``_LIGHT_MISFIT``), at least three
    degrees of freedom are left, and the saddle point's shift it implies, ``H^-1 g``, is within
    ``_SHADE_MAX_SHIFT`` of the fit's window half-size ``r``; the saddle point is then shifted
    by that, with its variance, and the gradient goes to step 9. The gradient is read to a
    tenth or less of the four squares' noise, so it is used as read, without a chi-square's
    bar. Corners the local reading leaves in doubt (a clipped glare, light that bends within a
    square) stay as it left them. ``ceiling``: as for :func:`_shading_shift`."""
    shift, var, gradient, gcov, doubt = (a.copy() for a in local)
    n = len(corners)
    if n < 4 or not np.isfinite(corners).any():
        return shift, var, gradient, gcov, doubt
    mid, clear = _square_grid(corners, cols, rows)
    h, w = grey.shape[:2]
    known = np.isfinite(mid).all(axis=2) & np.isfinite(clear)
    half = np.where(known, np.round(_LIGHT_BOX * np.where(known, clear, 0.0)), 0).astype(np.int64)
    cx = np.round(np.where(known, mid[..., 0], -1.0)).astype(np.int64)
    cy = np.round(np.where(known, mid[..., 1], -1.0)).astype(np.int64)
    box = known & (half >= 1) & (cx - half >= 0) & (cy - half >= 0) & (cx + half <= w - 1) & (cy + half <= h - 1)
    at = np.flatnonzero(box.ravel())
    if len(at) < 7:
        return shift, var, gradient, gcov, doubt
    img = np.ascontiguousarray(grey.dense() if isinstance(grey, RawGrey) else grey, dtype=np.float64)
    if ceiling is None:
        ceiling = _clip_ceiling(img)
    mean, spread, clip = np.empty(len(at)), np.empty(len(at)), np.empty(len(at))
    detect_kernels.box_means(img, cx.ravel()[at], cy.ravel()[at], half.ravel()[at], ceiling, mean, spread, clip)
    shade = np.full(box.size, np.nan)
    shade[at] = np.where(clip > 0, np.nan, mean)
    shade_var = np.full(box.size, np.inf)
    shade_var[at] = np.fmax(np.fmax(white ** 2, spread), step * step / 12.0) / (2 * half.ravel()[at] + 1) ** 2
    shade, shade_var = shade.reshape(box.shape), shade_var.reshape(box.shape)
    sr, sc = np.mgrid[0:rows + 1, 0:cols + 1]
    parity = np.where((sr + sc) % 2 == 0, 1.0, -1.0)
    # Corner (i, j) lies between squares i, i + 1 (rows) and j, j + 1 (columns) of the
    # (rows + 1) x (cols + 1) squares; its block reaches _LIGHT_SQUARES of them each way.
    k = np.arange(-_LIGHT_SQUARES + 1, _LIGHT_SQUARES + 1)
    ci, cj = np.divmod(np.arange(n), cols)
    ri, rj = ci[:, None] + k, cj[:, None] + k  # the block's square rows and columns, (N, 2 _LIGHT_SQUARES)
    inb = (((ri >= 0) & (ri <= rows))[:, :, None] & ((rj >= 0) & (rj <= cols))[:, None, :]).reshape(n, -1)
    qi = np.repeat(np.clip(ri, 0, rows), len(k), axis=1)
    qj = np.tile(np.clip(rj, 0, cols), (1, len(k)))
    s, v, col = shade[qi, qj], shade_var[qi, qj], parity[qi, qj]
    d = mid[qi, qj] - corners[:, None]
    have = inb & np.isfinite(s) & np.isfinite(d).all(axis=2) & np.isfinite(corners).all(axis=1)[:, None]
    d = np.where(have[..., None], d, 0.0)
    M = np.stack([np.ones(s.shape), d[..., 0], d[..., 1], col, col * d[..., 0], col * d[..., 1]], axis=-1)
    M = M * have[..., None]
    wt = np.where(have, 1.0 / np.where(have, v, 1.0), 0.0)
    s = np.where(have, s, 0.0)
    count = have.sum(axis=1)
    MtW = M.transpose(0, 2, 1) * wt[:, None, :]
    A = MtW @ M
    with np.errstate(invalid="ignore"):
        # Both colours and a spread of places in two directions: the design has full rank.
        cond = np.linalg.cond(np.where((count >= 9)[:, None, None], A, np.eye(6)))
    idx = np.flatnonzero((count >= 9) & (cond < 1e12))
    if len(idx) == 0:
        return shift, var, gradient, gcov, doubt
    Ai = np.linalg.inv(A[idx])
    sol = (Ai @ (MtW[idx] @ s[idx, :, None]))[..., 0]
    res = (s[idx] - np.einsum("kaj,kj->ka", M[idx], sol)) * have[idx]
    dof = count[idx] - 6
    chi2 = (res * res * wt[idx]).sum(axis=1) / dof
    misfit = np.sqrt((res * res).sum(axis=1) / dof)
    noise = np.sqrt((np.where(have[idx], v[idx], 0.0)).sum(axis=1) / count[idx])
    contrast = np.abs(sol[:, 3])
    cov = Ai * np.fmax(chi2, 1.0)[:, None, None]
    cg = cov[:, 1:3, 1:3]
    Hi = _sym2(np.nan_to_num(inverse[idx]))
    implied = np.einsum("kij,kj->ki", Hi, sol[:, 1:3])
    cs = Hi @ cg @ Hi.transpose(0, 2, 1)
    use = ((misfit <= 3.0 * noise + _LIGHT_MISFIT * contrast) & (contrast > 0) & ~doubt[idx]
           & np.isfinite(inverse[idx]).all(axis=1) & (np.hypot(*implied.T) <= _SHADE_MAX_SHIFT * r))
    at = idx[use]
    shift[at] = implied[use]
    var[at] = 0.5 * (cs[use, 0, 0] + cs[use, 1, 1])
    gradient[at] = sol[use, 1:3]
    gcov[at] = np.stack([cg[use, 0, 0], cg[use, 0, 1], cg[use, 1, 1]], axis=-1)
    return shift, var, gradient, gcov, doubt


def _drop_noisy(grey: np.ndarray, det: Detection, board: Checkerboard, factor: int, image_noise: float,
                step: float = 0.0) -> Detection:
    """Steps 8-9 of :func:`detect_corners`: each corner's sigma is the larger of the fit's and
    the noise's (:func:`_noise_sigma`); corners shifted for the light's gradient
    (:func:`_shading_shift`), their sigma grown by its reading's; corners moved to their point of symmetry
    (:func:`_symmetric`) take that estimate's; corners over ``_MAX_CORNER_SIGMA`` are
    dropped. ``step``: one level of the file's samples in the grey's units; where the noise
    measured on the board is below it, the flat squares were flattened (JPEG) and the noise
    is read beside each corner instead (:func:`_symmetric`'s ``unit``). ``factor``: the pyramid
    level the corners were found at (their fit's smoothing ``_SIGMA * factor``); where the light
    leaves a corner of such a board in doubt by more than ``_MAX_CORNER_SIGMA``, the board is
    fitted again finer (:func:`_finer`) and read again."""
    cols, rows = board.inner_cols, board.inner_rows
    ceiling = _clip_ceiling(grey.dense() if isinstance(grey, RawGrey) else grey)  # read once, for every reading

    def read_light(det: Detection, smoothing: float) -> tuple[np.ndarray, ...]:
        """Step 8's readings of ``det`` fitted at ``smoothing``: the noise's (:func:`_noise_sigma`:
        sigma, white, unit) and the light's (:func:`_shading_shift`, :func:`_board_light`)."""
        noise, white, unit, inverse = _noise_sigma(grey, det.corners, cols, rows, det.window_px, smoothing,
                                                   image_noise)
        local = _shading_shift(grey, det.corners, cols, rows, inverse, white, det.window_px, ceiling=ceiling)
        return (noise, white, unit, *_board_light(grey, det.corners, cols, rows, inverse, white, det.window_px, step,
                                                  local, ceiling=ceiling))

    noise, white, unit, shift, shift_var, gradient, gcov, doubt = read_light(det, _SIGMA * factor)
    if factor > 1 and (doubt & (shift_var > _MAX_CORNER_SIGMA ** 2)).any():
        finer = _finer(grey, det, factor, board, image_noise)
        if finer is not None:
            det = finer[0]
            noise, white, unit, shift, shift_var, gradient, gcov, doubt = read_light(det, finer[1])
    sigma = np.fmax(det.sigma_px, noise)
    shifted = det.corners + shift
    moved = np.isfinite(shift_var)
    sigma[moved] = np.sqrt(sigma[moved] ** 2 + shift_var[moved])
    corners, sigma = _symmetric(grey, shifted, sigma, noise, cols, white, unit if white < step else None,
                                (gradient, gcov, doubt))
    det = Detection(True, corners, sigma, det.window_px, det.message)
    noisy = np.isfinite(det.corners).all(axis=1) & (sigma > _MAX_CORNER_SIGMA)
    if not noisy.any():
        return Detection(True, det.corners, sigma, det.window_px, det.message)
    worst = float(sigma[noisy].max())
    corners = det.corners.copy()
    corners[noisy] = np.nan
    sigma[noisy] = np.nan
    found = int(np.isfinite(corners).all(axis=1).sum())
    why = (f"the image's noise or light leaves {int(noisy.sum())} corners more than a quarter of a pixel "
           f"uncertain (sigma up to {worst:.2f} px: too little contrast for the noise, or light that bends "
           "across the corner)")
    if found < 4:
        return Detection.not_found(len(corners), f"not found: {why}", det.window_px)
    return Detection(True, corners, sigma, det.window_px, f"{det.message}; {found} kept: {why}")


#: Step 9: the samples reach this fraction of a square from the corner each way, in the
#: board's local coordinates (0.35-0.45 fitted fisheye views worse: the 3x3 neighbourhood's
#: quadratic stops following the rim; benchmarks/notes.md, fourteenth session).
_SYM_REACH = 0.3
#: ... spaced about this many pixels apart (at most ``_SYM_MAX_HALF`` to a side of the grid).
_SYM_STEP_PX = 0.7
_SYM_MAX_HALF = 40
#: ... on the corners whose saddle point the noise measured in the squares' middles leaves
#: more uncertain than this (px): twice the symmetric point's own error on noise-free renders
#: (about 0.01 px median). On clean photos the two estimators differ systematically (Bouguet's
#: set: 0.13 px median, and the calibration's principal point 0.9 px apart, when every corner
#: moved), and there the saddle point stays: 3.6 % of Bouguet's corners pass 0.02 px. On the
#: stress corpus's seeds 0-499 / 1000-1499 the noisy views' 95th percentile was 0.105 / 0.122 px
#: at 0.05, 0.099 / 0.116 at 0.02 (benchmarks/notes.md, thirty-fourth session).
_SYM_FROM_SIGMA = 0.02
#: ... or, where the middles were flattened (JPEG) and the noise is read from each corner's own
#: symmetric residuals, which carry the model's misfit too, more than this (at 0.02 the
#: noise-free renders' corners moved too: their 95th percentile 0.038 -> 0.046 px, seeds
#: 1000-1499).
_SYM_FROM_SIGMA_FLAT = 0.05
#: ... on the image smoothed by this Gaussian sigma (px): the gradients' noise otherwise
#: inflates the normal matrix and the sigma reads low on dim boards.
_SYM_SMOOTHING = 1.0
#: ... and, for a corner moved there that has a whole 3x3 block of found corners near it, again
#: out to this fraction of a square, kept where its sigma is the smaller (benchmarks/notes.md,
#: thirty-first session).
_SYM_WIDE_REACH = 0.7
#: ... an edge corner's map from the whole 3x3 block a corner inward, where that block's
#: quadratic misses its corners by at most this (px, RMS) plus ``_SYM_BLOCK_NOISE`` times
#: their sigma: more says the lens bends the map faster than a quadratic follows a square
#: beyond it (fisheye rims: 0.16 px off on a noise-free view without this test).
_SYM_BLOCK_MISFIT = 0.03
_SYM_BLOCK_NOISE = 1.5
#: ... the block shifted by at most this many corners each way (a corner beside a hidden one:
#: at 1, 95th percentile with noise 0.0947 / 0.1196 px on the corpus's seeds 0-999 / 1000-1999,
#: at 2, 0.0945 / 0.1195, noise-free unchanged; benchmarks/notes.md, thirty-eighth session).
_SYM_BLOCK_SHIFT = 2
#: ... a block of which this many of its nine corners were found, where no whole one is near (a
#: quadratic has six coefficients a coordinate, and :func:`_local_maps` fits one on eight too):
#: at 9 the corpus's 95th percentile with noise was 0.1046 px over seeds 0-1999, at 8 0.1041,
#: one more eligible board found (benchmarks/notes.md, thirty-ninth session).
_SYM_BLOCK_LEAST = 8
#: The symmetric point replaces the saddle point only within this distance of it (px), besides
#: three of their combined sigmas: at half a pixel, the noisiest saddle points (0.4-1.1 px
#: off on a dim board under noise of a quarter of its contrast) kept the bound, and their
#: symmetric points, 0.02-0.29 px off, were dropped (benchmarks/notes.md, thirty-second session).
_SYM_AGREE_PX = 1.0


#: The symmetric point's normal matrix is read on the noisy image, and the gradients' noise
#: adds to it (about ``2 pairs c noise^2`` on its diagonal, :func:`_gradient_noise`): its
#: sigma is divided by the root of the signal's share, and where the noise's share is this or
#: more the point has no sigma and does not move (the fit follows the noise: a dim board under
#: noise of half its contrast gave points 0.6-2.6 px off with sigmas of 0.12-0.25 px, the share
#: 0.8-1.1; on the stress corpus's seeds 0-150 every share was under 0.2 and the sigmas held,
#: benchmarks/notes.md, thirty-fifth session).
_SYM_MAX_NOISE_SHARE = 0.5


@functools.lru_cache(maxsize=8)
def _gradient_noise(smoothing: float) -> float:
    """The variance, per unit white pixel noise, of one gradient sample of
    :func:`camkit._kernels.detect.symmetry_refine` (the bilinear interpolant of the central
    differences of the image smoothed by ``smoothing``), averaged over the sample's place
    within its pixel: its weights on the pixels are separable, so their sum of squares is the
    product of the two axes'."""
    taps = detect_kernels.gaussian_taps(smoothing)
    f = (np.arange(8) + 0.5) / 8
    along = [np.sum(np.convolve(np.convolve([1 - t, t], [0.5, 0.0, -0.5]), taps) ** 2) for t in f]
    across = [np.sum(np.convolve([1 - t, t], taps) ** 2) for t in f]
    return float(np.mean(along) * np.mean(across))


def _symmetry_sigma(cov: np.ndarray, normal: np.ndarray, wres: np.ndarray, noise: float | np.ndarray,
                    pairs: int | np.ndarray, smoothing: float = _SYM_SMOOTHING) -> np.ndarray:
    """The sigma (px) of points of :func:`camkit._kernels.detect.symmetry_refine` (its ``cov``,
    ``normal`` and ``wres``, ``pairs`` pairs each): the linearised estimator's per unit noise
    times the larger of the white pixel noise ``noise`` and what the residuals imply, over the
    root of the signal's share of the normal matrix; NaN where the noise's share reaches
    ``_SYM_MAX_NOISE_SHARE``. The share counts ``noise`` alone: the residuals carry the
    model's misfit too (a real photo's print and lens), which is in the image's gradients as
    signal, not noise."""
    with np.errstate(invalid="ignore", divide="ignore"):
        share = 2.0 * pairs * _gradient_noise(smoothing) * noise ** 2 / (0.5 * (normal[:, 0] + normal[:, 2]))
        sigma = np.sqrt(0.5 * (cov[:, 0] + cov[:, 2])) * np.fmax(wres, noise) / np.sqrt(1.0 - share)
        return np.where(share < _SYM_MAX_NOISE_SHARE, sigma, np.nan)


def _quad_basis(x: np.ndarray) -> np.ndarray:
    """The quadratic monomials 1, u, v, u^2, u v, v^2 of board offsets ``x`` (..., 2): (..., 6)."""
    u, v = x[..., 0], x[..., 1]
    return np.stack([np.ones(u.shape), u, v, u * u, u * v, v * v], axis=-1)


def _local_maps(corners: np.ndarray, cols: int, spacing: float, reach: float = _SYM_REACH,
                centre_known: bool = True, only: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """Each corner's map of its board neighbourhood: board offsets (du, dv) in squares to
    pixels, fitted on the labelled corners of its 3x3 neighbourhood (a quadratic in du, dv
    where eight or nine are there: perspective and the lens's bending; a homography where
    five to seven are). Returns the offsets ``a`` = map(u) - map(0) and ``b`` = map(-u) -
    map(0), (N, M, 2), for the half grid ``u`` of :func:`_symmetric` out to ``reach``
    squares, which corners have a map, map(0) (N, 2) and a square's steps there along the
    columns and the rows (N, 2) each. ``centre_known=False``: the maps of corners not found
    too, from their neighbours alone (four at least; map(0) then predicts the corner).
    ``only``: the corners (indices) whose maps are wanted; the rows returned are theirs."""
    n = len(corners)
    rows = n // cols
    grid = np.full((rows + 2, cols + 2, 2), np.nan)
    grid[1:-1, 1:-1] = corners.reshape(rows, cols, 2)
    src = np.array([(dc, dr) for dr in (-1, 0, 1) for dc in (-1, 0, 1)], dtype=np.float64)  # (9, 2)
    dst = np.stack([grid[1 + dr:rows + 1 + dr, 1 + dc:cols + 1 + dc].reshape(n, 2) for dc, dr in src.astype(int)],
                   axis=1)  # (N, 9, 2)
    pts = corners
    if only is not None:
        dst, pts = dst[only], corners[only]
    have = np.isfinite(dst).all(axis=2)
    if centre_known:
        have &= np.isfinite(pts).all(axis=1)[:, None]
    count = have.sum(axis=1)
    scale = max(float(spacing), 1.0)
    with np.errstate(invalid="ignore"):  # a corner with no neighbour: no reference, no map
        ref = np.where(np.isfinite(pts), pts,
                       np.nansum(np.where(have[..., None], dst, 0.0), axis=1) / np.maximum(count, 1)[:, None])
    rel = np.where(have[..., None], (dst - np.nan_to_num(ref)[:, None]) / scale, 0.0)
    ends, k = _map_ends(spacing, reach)
    mapped = np.full((len(pts), len(ends), 2), np.nan)
    quad = count >= 8
    if quad.any():
        Q = _quad_basis(src)
        Qw = Q[None] * have[quad][:, :, None]
        coef = np.linalg.solve(Qw.transpose(0, 2, 1) @ Q[None], Qw.transpose(0, 2, 1) @ rel[quad])  # (K, 6, 2)
        mapped[quad] = _quad_basis(ends)[None] @ coef
    homog = (count >= (5 if centre_known else 4)) & ~quad  # four points and the centre, or four around it
    if homog.any():
        h = have[homog]
        r = rel[homog]
        x, y = src[:, 0][None], src[:, 1][None]
        zero, one = np.zeros_like(r[..., 0]), np.ones_like(r[..., 0])
        xb, yb = np.broadcast_to(x, r[..., 0].shape), np.broadcast_to(y, r[..., 0].shape)
        ru, rv = r[..., 0], r[..., 1]
        eq_u = np.stack([xb, yb, one, zero, zero, zero, -ru * xb, -ru * yb, -ru], axis=-1)
        eq_v = np.stack([zero, zero, zero, xb, yb, one, -rv * xb, -rv * yb, -rv], axis=-1)
        A = np.concatenate([eq_u, eq_v], axis=1) * np.concatenate([h, h], axis=1)[..., None]
        _, sv, vt = np.linalg.svd(A)
        H = vt[:, -1].reshape(-1, 3, 3)
        ok_h = sv[:, -2] > 1e-6 * sv[:, 0]
        e = np.concatenate([ends, np.ones((len(ends), 1))], axis=1) @ H.transpose(0, 2, 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            pm = e[..., :2] / e[..., 2:]
        pm[~ok_h] = np.nan
        mapped[homog] = pm
    mapped *= scale
    a, b, usable, centre, du, dv = _split_map(mapped, k, scale)
    return a, b, usable, ref + centre, du, dv


def _block_maps(corners: np.ndarray, cols: int, spacing: float, reach: float,
                only: np.ndarray, corner_sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The local maps of :func:`_local_maps` (``a``, ``b``, usable) for the corners ``only``,
    each a quadratic fitted on a whole 3x3 block of found corners near it: its own
    neighbourhood where that is whole, else the nearest block shifted up to
    ``_SYM_BLOCK_SHIFT`` corners (an edge corner's, inward; a corner beside a hidden one's);
    where no whole block is that near, the nearest with ``_SYM_BLOCK_LEAST`` of its nine
    corners found, fitted on those.
    Only the quadratic's second-order terms shape the mirrored pairs (a
    linear map mirrors every offset to its negative), and a quadratic's are the same over
    the whole plane, so a shifted block serves where the lens's bending changes little
    over a square: where its quadratic misses the block's corners by no more than
    ``_SYM_BLOCK_MISFIT`` plus ``_SYM_BLOCK_NOISE`` times their RMS ``corner_sigma``.
    Corners in no such block have no map."""
    n = len(corners)
    rows = n // cols
    P = _SYM_BLOCK_SHIFT
    found = np.zeros((rows + 2 * P + 2, cols + 2 * P + 2), dtype=bool)
    found[P + 1:-P - 1, P + 1:-P - 1] = np.isfinite(corners).all(axis=1).reshape(rows, cols)
    # count[r, c]: how many of the 3x3 block centred on corner (r - P, c - P) (P rows and columns of
    # padding) were found
    count = np.zeros((rows + 2 * P, cols + 2 * P), dtype=np.int64)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            count += found[1 + dr:rows + 2 * P + 1 + dr, 1 + dc:cols + 2 * P + 1 + dc]
    r, c = np.divmod(only, cols)
    # (dc, dr), the nearest blocks first
    shifts = sorted(((dc, dr) for dr in range(-P, P + 1) for dc in range(-P, P + 1)),
                    key=lambda t: (max(abs(t[0]), abs(t[1])), abs(t[0]) + abs(t[1]), abs(t[0]), -t[0], -t[1]))
    shift = np.zeros((len(only), 2), dtype=np.int64)
    ok = np.zeros(len(only), dtype=bool)
    for least in (9, _SYM_BLOCK_LEAST):
        for dc, dr in shifts:
            take = ~ok & (count[r + P + dr, c + P + dc] >= least)
            shift[take] = (dc, dr)
            ok |= take
    src = np.array([(dc, dr) for dr in (-1, 0, 1) for dc in (-1, 0, 1)], dtype=np.int64)  # (9, 2)
    off = src[None] + shift[:, None]  # (K, 9, 2): the block's corners relative to the corner
    rr = np.clip(r[:, None] + off[..., 1], 0, rows - 1)
    cc = np.clip(c[:, None] + off[..., 0], 0, cols - 1)
    inside = ((r[:, None] + off[..., 1] >= 0) & (r[:, None] + off[..., 1] < rows)
              & (c[:, None] + off[..., 0] >= 0) & (c[:, None] + off[..., 0] < cols))
    scale = max(float(spacing), 1.0)
    rel = (corners[rr * cols + cc] - corners[only][:, None]) / scale  # (K, 9, 2)
    have = inside & np.isfinite(rel).all(axis=2)
    rel = np.where(have[..., None], rel, 0.0)
    ends, k = _map_ends(spacing, reach)
    mapped = np.full((len(only), len(ends), 2), np.nan)
    if ok.any():
        Q = _quad_basis(off[ok].astype(np.float64))  # (K', 9, 6)
        Qw = Q * have[ok][..., None]
        coef = np.linalg.solve(Qw.transpose(0, 2, 1) @ Q, Qw.transpose(0, 2, 1) @ rel[ok])  # (K', 6, 2)
        mapped[ok] = _quad_basis(ends)[None] @ coef * scale
        res2 = ((Q @ coef - rel[ok]) ** 2).sum(axis=2) * have[ok]
        misfit = np.sqrt(res2.sum(axis=1) / have[ok].sum(axis=1)) * scale  # px
        moved = np.any(shift[ok] != 0, axis=1)
        with np.errstate(invalid="ignore"):
            spread = np.sqrt(np.nanmean(np.where(have[ok], corner_sigma[(rr * cols + cc)[ok]], np.nan) ** 2, axis=1))
            bent = moved & ~(misfit <= _SYM_BLOCK_MISFIT + _SYM_BLOCK_NOISE * spread)
        ok[np.flatnonzero(ok)[bent]] = False
    a, b, usable = _split_map(mapped, k, scale)[:3]
    return a, b, usable & ok


def _map_ends(spacing: float, reach: float) -> tuple[np.ndarray, int]:
    """The board offsets (squares) a local map is read at, (2 k + 5, 2): 0, the half grid ``u``
    of :func:`_symmetric` out to ``reach`` squares (``k`` points, about :data:`_SYM_STEP_PX`
    apart on squares of ``spacing`` px), ``-u``, and half a square either way along the
    columns and the rows."""
    return _map_ends_of(max(2, min(_SYM_MAX_HALF, round(reach * spacing / _SYM_STEP_PX))), reach)


@functools.lru_cache(maxsize=64)
def _map_ends_of(m: int, reach: float) -> tuple[np.ndarray, int]:
    """:func:`_map_ends` for ``m`` points a side out to ``reach`` (read-only: shared)."""
    t = np.arange(-m, m + 1) * (reach / m)
    uu, vv = np.meshgrid(t, t)
    u = np.stack([uu.ravel(), vv.ravel()], axis=1)
    u = u[(u[:, 0] > 0) | ((u[:, 0] == 0) & (u[:, 1] > 0))]
    steps = np.array([[0.5, 0.0], [-0.5, 0.0], [0.0, 0.5], [0.0, -0.5]])
    ends = np.concatenate([np.zeros((1, 2)), u, -u, steps])
    ends.flags.writeable = False
    return ends, len(u)


def _split_map(mapped: np.ndarray, k: int, scale: float) -> tuple[np.ndarray, ...]:
    """A local map read at :func:`_map_ends` ((N, 2 k + 5, 2) pixels) as ``(a, b, usable,
    map(0), du, dv)`` (see :func:`_local_maps`)."""
    a = mapped[:, 1:k + 1] - mapped[:, :1]
    b = mapped[:, k + 1:2 * k + 1] - mapped[:, :1]
    h = mapped[:, 2 * k + 1:]
    du, dv = h[:, 0] - h[:, 1], h[:, 2] - h[:, 3]
    # A homography through four points, three of them on a line, collapses the neighbourhood
    # to a point (steps of 1e-13 px): no map.
    with np.errstate(invalid="ignore"):
        spread = np.abs(du[:, 0] * dv[:, 1] - du[:, 1] * dv[:, 0]) > 1e-6 * scale * scale
    usable = np.isfinite(a).all(axis=(1, 2)) & np.isfinite(b).all(axis=(1, 2)) & spread
    return a, b, usable, mapped[:, 0], du, dv


class _SmoothedCrop:
    """The image smoothed by a Gaussian (:func:`camkit._kernels.detect.gaussian_blur`) over the
    part of it that point searches read: :meth:`covering` smooths the box around the points
    (``reach`` px of samples each way, ``_CROP_WANDER`` px for the search's steps and the
    kernel's 3 px of border) once, and again only where a later call reaches outside it. Its
    pixels are the whole image's smoothed pixels. A 12 MP photo's board covers a part of the
    frame, and its corners were each tried on the whole frame smoothed."""

    def __init__(self, grey: np.ndarray, sigma: float) -> None:
        self.grey, self.sigma = np.ascontiguousarray(grey, dtype=np.float64), sigma
        self.box: tuple[int, int, int, int] | None = None  # x0, y0, x1, y1 (exclusive)
        self.img = np.empty((0, 0))

    def covering(self, pts: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """(smoothed box, its origin (x, y) in the image) covering ``pts`` (K, 2) ``reach`` px each way."""
        H, W = self.grey.shape
        m = reach + _CROP_WANDER + 3
        with np.errstate(invalid="ignore"):
            lo = np.nanmin(pts, axis=0, initial=np.inf) - m
            hi = np.nanmax(pts, axis=0, initial=-np.inf) + m
        want = (int(np.clip(np.floor(lo[0]), 0, W)), int(np.clip(np.floor(lo[1]), 0, H)),
                int(np.clip(np.ceil(hi[0]) + 1, 0, W)), int(np.clip(np.ceil(hi[1]) + 1, 0, H)))
        box = self.box
        if box is None or not (box[0] <= want[0] and box[1] <= want[1] and box[2] >= want[2] and box[3] >= want[3]):
            if box is not None:
                want = (min(box[0], want[0]), min(box[1], want[1]), max(box[2], want[2]), max(box[3], want[3]))
            self.img = work_array((max(want[3] - want[1], 0), max(want[2] - want[0], 0)), np.float64)
            if self.img.size:
                detect_kernels.gaussian_blur(self.grey, self.sigma, self.img, want[0], want[1])
            self.box = want
        return self.img, np.array(self.box[:2], dtype=np.float64)


#: How far (px) a point search of :func:`_symmetric` may step from its start and still read
#: the pixels :class:`_SmoothedCrop` smoothed for it (a search that walks further is treated
#: as one that left the image: no point; it would lie beyond ``_SYM_AGREE_PX`` of its start
#: unless it came back).
_CROP_WANDER = 4.0


def _symmetric(grey: np.ndarray, corners: np.ndarray, sigma: np.ndarray, noise_sigma: np.ndarray, cols: int,
               white: float, unit: np.ndarray | None = None,
               light: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Step 9 of :func:`detect_corners`: each corner moved to the point through which the image
    around it is point-symmetric on the board (a checkerboard is, about every inner corner),
    where that estimate agrees with the saddle point; returns (corners, sigma).

    The idea is the "refinement by symmetry" of Schoeps, Larsson, Pollefeys and Sattler, "Why
    Having 10,000 Parameters in Your Camera Model is Better Than Twelve" (CVPR 2020,
    arXiv:1912.02908): pairs of samples mirrored through the corner in the board's
    coordinates see the same shade, and the corner is where their differences' sum of
    squares is least. They fit a homography per feature; here the board's local map is fixed
    from the labelled neighbours (:func:`_local_maps`, out to ``_SYM_REACH`` of a square,
    a quadratic that follows the lens's bending) and only the corner moves
    (:func:`camkit._kernels.detect.symmetry_refine`, on the image smoothed by
    ``_SYM_SMOOTHING`` so that the noise does not enter the gradients). It reads the squares'
    edges along a third of their length where the saddle fit reads a window of 2-5 px, so
    the image's noise moves it less. It runs on the corners whose ``noise_sigma`` (the
    saddle fit's, step 8) passes ``_SYM_FROM_SIGMA``. Its sigma is the linearised
    estimator's through the smoothing and the bilinear weights, times the larger of the
    board's white noise ``white`` and what the final residuals imply (model misfit, an
    occluder in the window), over the root of the signal's share of its normal matrix
    (:func:`_symmetry_sigma`: the noise in the gradients adds to it; where the noise makes
    half of it, the fit follows the noise and the point has no sigma). The saddle point
    stays where the symmetric point lies more than three of their combined sigmas and a
    tenth of a pixel from it, or more than ``_SYM_AGREE_PX``, or cannot be placed (a sample
    outside the image, no map). A corner with fewer than five of its 3x3 neighbourhood found
    (a board's outermost corners, a corner beside hidden ones) takes the map of a block near
    it (:func:`_block_maps`, as the wide fit below; before the thirty-ninth session such
    corners kept their saddle points: 3994 of the corpus's 71028 noisy corners, 754 of them
    over 0.1 px).
    A corner so moved that has a 3x3 block of found corners near it is fitted again out to
    ``_SYM_WIDE_REACH`` of a square (the board is point-symmetric about an inner corner out
    to a whole square each way; the noise moves a fit over more of the edges less), on that
    block's quadratic map (:func:`_block_maps`: an edge corner's homography through five to
    seven neighbours does not follow the lens that far, 0.08 px off on a noise-free barrel
    view), and that point is kept where it too agrees with the saddle point and its sigma is
    the smaller.

    ``light`` (step 8's :func:`_shading_shift`: each corner's light gradient, its covariance,
    and which corners the light leaves in doubt): the gradient is taken off each mirrored pair
    (a linear light is not point-symmetric) and its covariance carried into the point's sigma
    through the kernel's ``sens``; a corner in doubt is not moved.

    ``unit`` (each corner's saddle-point sigma per unit of white noise, :func:`_noise_sigma`)
    is given where the noise measured in the squares' middles is below one level of the file:
    the flat squares were flattened (JPEG keeps its error beside the edges, where the fit
    reads, and none in the middles), and ``noise_sigma`` says nothing. Every corner is then
    tried, and its saddle point's noise is ``unit`` times the larger of ``white`` and the noise
    its own symmetric residuals imply; that decides, in place of ``noise_sigma`` and against
    ``_SYM_FROM_SIGMA_FLAT``, whether it moves, and is the sigma of a corner left at its saddle point."""
    seen = np.isfinite(corners).all(axis=1)
    with np.errstate(invalid="ignore"):
        noisy = (seen & (noise_sigma > _SYM_FROM_SIGMA)) if unit is None else seen
    if light is None:
        light = (np.zeros((len(corners), 2)), np.zeros((len(corners), 3)), np.zeros(len(corners), dtype=bool))
    gradient, gcov, doubt = light
    noisy &= ~doubt
    if seen.sum() < 5 or not noisy.any():
        return corners, sigma
    spacing = _grid_spacing(corners, cols)
    if not np.isfinite(spacing):
        return corners, sigma
    idx = np.flatnonzero(noisy)
    a, b, usable = _local_maps(corners, cols, spacing, only=idx)[:3]
    if not usable.all():  # fewer than five of its 3x3 neighbourhood found: a block near it
        ab, bb, okb = _block_maps(corners, cols, spacing, _SYM_REACH, idx[~usable], sigma)
        lack = np.flatnonzero(~usable)
        a[lack[okb]], b[lack[okb]] = ab[okb], bb[okb]
        usable[lack[okb]] = True
    a, b, use = a[usable], b[usable], idx[usable]
    if len(use) == 0:
        return corners, sigma
    taps = detect_kernels.gaussian_taps(_SYM_SMOOTHING)
    smoothed = _SmoothedCrop(grey, _SYM_SMOOTHING)
    # The first box smoothed covers the wider second search too (its maps, fitted on other
    # corners, may reach a little further: a fifth more).
    narrow = max(np.abs(a).max(initial=0.0), np.abs(b).max(initial=0.0))
    wide_reach = 1.2 * narrow * max(_SYM_WIDE_REACH / _SYM_REACH, 1.0)

    def refine(k: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The corners ``use[k]`` at their point of symmetry on the maps ``a``, ``b``: (points,
        sigma, the white noise their residuals imply)."""
        p, cv, wr, nm = np.empty((len(k), 2)), np.empty((len(k), 3)), np.empty(len(k)), np.empty((len(k), 3))
        sens = np.empty((len(k), 4))
        img, origin = smoothed.covering(corners[use[k]], max(np.abs(a).max(initial=0.0), np.abs(b).max(initial=0.0),
                                                             wide_reach))
        detect_kernels.symmetry_refine(img, taps, np.ascontiguousarray(corners[use[k]] - origin),
                                       np.ascontiguousarray(a), np.ascontiguousarray(b),
                                       np.full(len(k), a.shape[1], dtype=np.int64),
                                       np.ascontiguousarray(gradient[use[k]]), 20, 1e-3, p, cv, wr, nm, sens)
        p += origin
        # The light's gradient taken off is uncertain: (J^T J)^-1 sens carries its covariance.
        det_n = nm[:, 0] * nm[:, 2] - nm[:, 1] ** 2
        with np.errstate(invalid="ignore", divide="ignore"):
            ni = _sym2(np.stack([nm[:, 2], -nm[:, 1], nm[:, 0]], axis=-1)) / det_n[:, None, None]
        D = ni @ sens.reshape(-1, 2, 2)
        gc = gcov[use[k]]
        C = _sym2(gc)
        cd = D @ C @ D.transpose(0, 2, 1)
        extra = np.where(gc.any(axis=1), 0.5 * (cd[:, 0, 0] + cd[:, 1, 1]), 0.0)
        return p, np.sqrt(_symmetry_sigma(cv, nm, wr, white, a.shape[1]) ** 2 + extra), wr

    pos, sym_sigma, wres = refine(np.arange(len(use)), a, b)
    out, sig = corners.copy(), sigma.copy()
    with np.errstate(invalid="ignore"):
        if unit is not None:  # the noise beside each corner (see above), read at the saddle fit's scale
            local = unit[use] * np.fmax(wres, white)
            sig[use] = np.where(np.isfinite(local), np.fmax(sigma[use], local), sigma[use])

    def agreeing(p: np.ndarray, s: np.ndarray, k: np.ndarray) -> np.ndarray:
        """Which of the points ``p`` (sigma ``s``) for the corners ``use[k]`` agree with their saddle points."""
        with np.errstate(invalid="ignore"):
            move = np.hypot(*(p - corners[use[k]]).T)
            return (move <= np.minimum(0.1 + 3.0 * np.hypot(sig[use[k]], s), _SYM_AGREE_PX)) & np.isfinite(s)

    agree = agreeing(pos, sym_sigma, np.arange(len(use)))
    if unit is not None:
        agree &= local > _SYM_FROM_SIGMA_FLAT
    wide = np.flatnonzero(agree)
    if len(wide) and _SYM_WIDE_REACH > _SYM_REACH:
        aw, bw, okw = _block_maps(corners, cols, spacing, _SYM_WIDE_REACH, use[wide], sigma)
        wide, aw, bw = wide[okw], aw[okw], bw[okw]
        posw, sw = refine(wide, aw, bw)[:2]
        with np.errstate(invalid="ignore"):
            better = (sw < sym_sigma[wide]) & agreeing(posw, sw, wide)
        pos[wide[better]], sym_sigma[wide[better]] = posw[better], sw[better]
    out[use[agree]] = pos[agree]
    sig[use[agree]] = sym_sigma[agree]
    return out, sig


def _x_corners(grey: np.ndarray, noise: float | None = None, weak: bool = False,
               floors: tuple[float, ...] = _RESPONSE_FLOORS) -> tuple:
    """Step 1 of :func:`detect_corners` on one resolution: ``(smoothed image, saddle response,
    X-corners (K, 2) integer pixels, their profiles (K, 32), symmetry (K,), the contrast floor,
    why none)``; ``why`` is "" where candidates were found (``noise``: the image's, where
    already measured). ``weak``: where the floor is the full one, the X-corners under it but
    over :data:`_WEAK_CONTRAST` of it (and the noise's floor) are returned too, and an eighth
    output says which candidates pass the floor (only those seed a lattice). ``floors``: the
    response floors tried in turn (:data:`_RESPONSE_FLOORS`)."""
    s = work_array(grey.shape, np.float64)
    detect_kernels.gaussian_blur(grey, _SIGMA, s)
    R = work_array(s.shape, np.float64)
    detect_kernels.saddle_response(s, R)
    none = np.zeros((0, 2))
    rmax = float(R.max())
    if not rmax > 0:
        return s, R, none, np.zeros((0, 32)), np.zeros(0), 0.0, "not found: no saddle points in the image"
    buf = np.empty((_MAX_CANDIDATES, 2), dtype=np.int64)
    for floor in floors:
        n = detect_kernels.local_maxima(R, 3, floor * rmax, buf)
        if n < _MAX_CANDIDATES:
            break
    if n < 4:
        return s, R, none, np.zeros((0, 32)), np.zeros(0), 0.0, "not found: fewer than 4 corner candidates"
    pts = buf[:n].astype(np.float64)
    v = _profiles(s, pts)
    shape, contrast, sym = _x_shape(v)
    strong = R[pts[:, 1].astype(np.int64), pts[:, 0].astype(np.int64)] > _STRONG_RESPONSE * rmax
    noise = _image_noise(grey) if noise is None else noise
    min_contrast = _contrast_floor(contrast[shape & strong], noise / (2.0 * np.sqrt(np.pi) * _SIGMA))
    floor = np.where(strong, min_contrast, max(min_contrast, _MIN_CONTRAST))
    ok = shape & (contrast > floor)
    if not weak:
        return s, R, pts[ok], v[ok], sym[ok], min_contrast, ""
    low = ok.copy()
    if min_contrast >= _MIN_CONTRAST:  # the full floor: the image holds X-corners of full contrast
        low |= shape & (contrast > max(_WEAK_CONTRAST * _MIN_CONTRAST,
                                       _NOISE_FACTOR * noise / (2.0 * np.sqrt(np.pi) * _SIGMA)))
    return s, R, pts[low], v[low], sym[low], min_contrast, "", ok[low]


def _lattices(grey: np.ndarray, max_side: int,
              offsets: tuple[float, ...] = (0.3,)) -> list[tuple[np.ndarray, np.ndarray]]:
    """The checker lattices of X-corners in ``grey`` (steps 1-2 of :func:`detect_corners`,
    growth within ``max_side + 2`` places of each seed), grown once for each of ``offsets``
    (:func:`_assemble`'s) from the same X-corners: ``(points (K, 2) integer pixels, lattice
    coordinates (K, 2) from 0)`` each, largest first for each offset. The lattice's axes may
    run either way round in the image."""
    g = np.ascontiguousarray(grey, dtype=np.float64)
    # From 0.05 of the strongest response: the coded targets that read their boards from these
    # lattices place their corners from the markers; the lower floor changed no ChArUco corner
    # over corpus views 0-249 and only gave growth more candidates to try.
    s, R, pts, v, _, _, why = _x_corners(g, floors=_RESPONSE_FLOORS[1:])
    if why or len(pts) < 4:
        return []
    most = max(3 * (max_side + 1) ** 2, 500)
    if len(pts) > most:  # clutter or noise: the strongest (bounds the time)
        keep = np.argsort(-R[pts[:, 1].astype(np.int64), pts[:, 0].astype(np.int64)])[:most]
        pts, v = pts[keep], v[keep]
    return [(pts[idx], c) for off in offsets
            for idx, c in _assemble(pts, max_side, s, v.max(axis=1) - v.min(axis=1), off)]


def _detect(grey: np.ndarray, board: Checkerboard, noise: float | None = None) -> Detection:
    """Steps 1-4 of :func:`detect_corners` on one resolution (``noise``: the image's, where
    already measured)."""
    cols, rows = board.inner_cols, board.inner_rows
    n_corners = cols * rows

    def fail(msg: str, window: int = 0) -> Detection:
        return Detection.not_found(n_corners, msg, window)

    found = _x_corners(grey, noise, weak=True)
    s, R, pts, v, sym, min_contrast, why = found[:7]
    if why:
        return fail(why)
    seeds = found[7]
    if seeds.sum() < min(4, n_corners):
        return fail(f"not found: {int(seeds.sum())} X-corners")
    strength = R[pts[:, 1].astype(np.int64), pts[:, 0].astype(np.int64)]
    if len(pts) > max(3 * n_corners, 500):  # clutter or noise: keep the strongest (bounds the time)
        keep = np.argsort(-(strength + np.where(seeds, strength.max(), 0.0)))[:max(3 * n_corners, 500)]
        pts, v, sym, seeds, strength = pts[keep], v[keep], sym[keep], seeds[keep], strength[keep]
    # Linking needs only the integer positions (+-0.5 px against the corner spacing); the
    # sub-pixel fit runs once, on the lattice's corners, below.
    lattices = _assemble(pts, max(cols, rows), s, v.max(axis=1) - v.min(axis=1), seeds=seeds)
    if not lattices or len(lattices[0][0]) < 4:
        return fail("not found: the corners form no lattice")
    # Each lattice of half the largest's size or more is checked and labelled in turn. Where
    # more than one passes (the board and a second pattern, e.g. a larger board cut by the
    # image's edge to the board's size), the one whose border is seen on more sides wins: its
    # extent is shown, not assumed.
    # A lattice more than two lines longer than the board either way round (a larger pattern
    # in view) is refused as such, and does not set that size: a small board beside a large
    # second board is still looked at.
    small, large = sorted((cols, rows))
    fits = [len(idx) for idx, g in lattices
            if sorted(g.max(axis=0) + 1)[0] <= small + 2 and sorted(g.max(axis=0) + 1)[1] <= large + 2]
    reference = fits[0] if fits else len(lattices[0][0])
    results = []
    for idx, g in lattices:
        if len(idx) < max(4, 0.5 * reference):
            break
        det, borders, open_end = _label(s, grey.shape, pts[idx], sym[idx], g, board, min_contrast)
        results.append((det, borders, open_end))
        if det.found and borders == 4:
            break
    passed = sorted(((b, d.n_found, -i) for i, (d, b, _) in enumerate(results) if d.found), reverse=True)
    if len(passed) > 1 and passed[0][0] == passed[1][0]:
        det = results[-passed[0][2]][0]
        return Detection.not_found(n_corners, f"not found: {len(passed)} patterns in the image pass as the "
                                              f"{cols}x{rows} board, with their borders seen on as many sides "
                                              "(another board in view?)", det.window_px)
    if not passed:
        return results[0][0]
    det, borders, open_end = results[-passed[0][2]]
    if open_end:
        # The lattice is shorter than the board, or runs out of the image: its labels rest on
        # its being this board. Where other X-corners as strong as the board's lie away from
        # it, another checker pattern is in view, of which this lattice may be a part as well.
        contrast = v.max(axis=1) - v.min(axis=1)
        c = det.corners[np.isfinite(det.corners).all(axis=1)]
        spacing = _corner_spacing(det.corners, board)
        near = np.hypot(*(pts[:, None, :] - c[None]).transpose(2, 0, 1)).min(axis=1)
        on_board = near <= 2.0
        # As strong in response too: the weak candidates that may only join a lattice
        # (:data:`_STRONG_RESPONSE`) are not counted (X-like points along a shelf's lit edges
        # past a board that fills the frame: real plantcv_wide set, at the 1/4 level).
        strong = strength > _STRONG_RESPONSE * float(R.max())
        stray = (near > 1.5 * spacing) & (contrast >= 0.5 * np.median(contrast[on_board])) & strong & seeds \
            if on_board.any() else np.zeros(len(pts), dtype=bool)
        # Only strays in a pattern count: each with two others 0.3 to 3 board steps away (the
        # scattered X-like points of a cluttered scene have none).
        p = pts[stray]
        gap = np.hypot(*(p[:, None, :] - p[None]).transpose(2, 0, 1))
        stray[stray] = ((gap >= 0.3 * spacing) & (gap <= 3.0 * spacing)).sum(axis=1) >= 2
        if stray.sum() >= _STRAY_X_CORNERS:
            return Detection.not_found(
                n_corners, "not found: the corners seen run out of the image or are fewer than the board's, and "
                           f"another checker pattern is in view ({int(stray.sum())} X-corners in a pattern, as strong "
                           "as the board's, away from it), so the lattice's labels are not fixed", det.window_px)
    return det


#: Strong X-corners in a pattern, away from a board cut by the image's edge or placed by its
#: border, that mean another checker pattern is in view.
_STRAY_X_CORNERS = 4


def _label(s: np.ndarray, shape: tuple[int, ...], pts: np.ndarray, sym: np.ndarray, g: np.ndarray,
           board: Checkerboard, min_contrast: float = _MIN_CONTRAST) -> tuple[Detection, int, bool]:
    """Steps 3-6 of :func:`detect_corners` on one lattice (candidates ``pts``, lattice
    coordinates ``g``): the detection, on how many of its four sides the board's border was
    seen (less the sides that run out of the image), and whether the lattice is shorter than
    the board or runs out of the image (its labels then rest on its being this board)."""
    cols, rows = board.inner_cols, board.inner_rows
    n_corners = cols * rows

    def fail(msg: str, window: int = 0, seen: tuple[int, int] | None = None) -> tuple[Detection, int, bool]:
        return Detection.not_found(n_corners, msg, window, seen), 0, False

    spacing = _lattice_spacing(g, pts)
    r = int(np.clip(round(spacing / _SPACING_PER_WINDOW), 2, 5))
    q, sig = _saddle_fit(s, pts, r)
    moved = np.hypot(*(q - pts).T)
    keep = np.isfinite(moved) & (moved <= max(1.5, 0.25 * spacing)) & _fits_well(sig)
    keep[keep] = _point_symmetric(s, q[keep], spacing)
    sub = np.flatnonzero(keep)
    keep[sub] = _checked(g[sub], q[sub], spacing, shape)
    g_all = g
    g, q, sig, symq = g[keep], q[keep], sig[keep], sym[keep]
    kept = np.flatnonzero(keep)
    if len(g):
        part = _largest_part(g)
        g, q, sig, symq = g[part], q[part], sig[part], symq[part]
        kept = kept[part]
    if len(g) < 4:
        return fail("not found: the corners form no consistent lattice", r)
    # The lattice's corners that the checks dropped: X-corners linked to the board through its
    # squares' edges, so the pattern goes on where they lie (kept in the same coordinates).
    dropped = np.delete(g_all, kept, axis=0) - g.min(axis=0)
    g = g - g.min(axis=0)
    M = np.linalg.lstsq(np.c_[g, np.ones(len(g))], q, rcond=None)[0]
    if M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0] < 0:  # make the labelling right-handed in the image
        dropped[:, 1] = g[:, 1].max() - dropped[:, 1]
        g[:, 1] = g[:, 1].max() - g[:, 1]
    ext = g.max(axis=0) + 1
    # The board's orientation on the lattice: the one needing the fewest lines trimmed. A
    # lattice longer than the board by a line or two is a board with more corners than were
    # declared (Bouguet's example board: 14 corners printed, 13 declared), or the pattern's own
    # outer corners against a dark background; the weaker outer line goes (fewer corners, less
    # point-symmetric), and the labels along that axis are fixed only up to that shift, which
    # a calibration absorbs into the view's pose.
    options = sorted(((max(ext[0] - t[0], 0) + max(ext[1] - t[1], 0), k, t)
                      for k, t in enumerate(((cols, rows), (rows, cols)))))
    if options[0][0] == 0:  # where the lattice fits the board as it is, nothing is trimmed
        options = [o for o in options if o[0] == 0]
        if len(options) == 2 and options[0][2] != options[1][2] and not any(
                (ext == np.asarray(o[2])).all() for o in options):
            # A partial lattice that fits the board either way round: which axis is which is
            # not fixed by the lattice itself, and a misread border would turn the labels.
            return fail(f"not found: the {ext[0]}x{ext[1]} corners seen fit the {cols}x{rows} board either way "
                        "round; part of the board is hidden or outside the image", r,
                        _other_board(s, g, q, spacing, min_contrast, (cols, rows)))
    else:
        # Longer than the board by one line along one axis and exactly as long along the other
        # (a board with one more corner printed than declared); anything else is not this board.
        options = [o for o in options if o[0] == 1 and (ext[0] == o[2][0] or ext[1] == o[2][1])][:1]
    placed = None
    why = ""
    for _, _, tgt in options:
        gt, keep_t = g.copy(), np.ones(len(g), dtype=bool)
        trimmed = [False, False]
        for ax in (0, 1):
            while gt[keep_t, ax].max() - gt[keep_t, ax].min() + 1 > tgt[ax]:
                lo = keep_t & (gt[:, ax] == gt[keep_t, ax].min())
                hi = keep_t & (gt[:, ax] == gt[keep_t, ax].max())
                score_lo = (lo.sum(), -float(np.mean(symq[lo])))
                score_hi = (hi.sum(), -float(np.mean(symq[hi])))
                keep_t &= ~(lo if score_lo < score_hi else hi)
                trimmed[ax] = True
        if any(trimmed):
            # Only a lattice whose pattern is not seen to go on past either end of that axis, nor
            # to run out of the image there: either is a larger pattern (a second board cut by
            # the image's edge) as much as a board printed one line longer.
            whole, ended = _border_evidence(s, g, q, spacing, min_contrast)
            ax = 0 if trimmed[0] else 1
            if {"more", "outside"} & {whole[(ax, -1)], whole[(ax, 1)]} or not all(ended.values()):
                why = (f"the corner lattice is {ext[0]}x{ext[1]}, larger than the board's {cols}x{rows}, and the "
                       "pattern goes on past it or out of the image (another pattern, or the board's size is not "
                       "the one given)")
                continue
        gk = gt[keep_t] - gt[keep_t].min(axis=0)
        sides, ended = _border_evidence(s, gk, q[keep_t], spacing, min_contrast)
        for key, seen_end in ended.items():
            if sides[key] == "outside" and seen_end:
                sides[key] = "ends"
        # Along an axis where the lattice is shorter than the board, a side beyond which the
        # lattice had corners that the checks dropped (a fisheye's rim bends them off the
        # neighbours' map) is where the board goes on, whatever the shades past it say: those
        # shades were read on the dropped corners' squares (real fisheye 23, blurred). Two of
        # them at least (or the whole side where it is one corner long): one X-corner of
        # something else linked at the lattice's end (a second board touching it, a blurred
        # junction) is not the board going on, and it turned a side seen to end into one
        # that goes on (benchmarks/notes.md, thirty-fifth session).
        dk = dropped - gt[keep_t].min(axis=0)
        for ax in (0, 1):
            if gk[:, ax].max() + 1 < tgt[ax]:
                need = min(2, int(gk[:, 1 - ax].max()) + 1)
                if (dk[:, ax] < 0).sum() >= need:
                    sides[(ax, -1)] = "more"
                if (dk[:, ax] > gk[:, ax].max()).sum() >= need:
                    sides[(ax, 1)] = "more"
        for ax in (0, 1):
            if trimmed[ax]:
                sides[(ax, -1)] = sides[(ax, 1)] = "trimmed"
        off, why = _place(gk.max(axis=0) + 1, tgt, sides)
        if off is not None:
            placed = tgt, off
            borders = sum(v == "border" for v in sides.values()) - sum(v == "outside" for v in sides.values())
            open_end = tuple(gk.max(axis=0) + 1) != tgt or "outside" in sides.values()
            g, q, sig = gk, q[keep_t], sig[keep_t]
            break
    if placed is None:
        why = why or (f"the corner lattice is {ext[0]}x{ext[1]}, larger than the board's {cols}x{rows} "
                      "(another pattern joins it, or the board's size is not the one given)")
        return fail(f"not found: {why}", r, _other_board(s, g, q, spacing, min_contrast, (cols, rows)))
    tgt, off = placed
    g = g + np.asarray(off)
    if tgt != (cols, rows):  # the lattice's first axis runs along the board's rows: turn it
        g = np.stack([g[:, 1], tgt[0] - 1 - g[:, 0]], axis=-1)
    # Colours (see _colour_agreement): each probe reads a square whose colour the labels predict.
    agree = _colour_agreement(s, g, q)
    if agree is None:
        return fail("not found: the squares' colours cannot be read (too few corners with a diagonal neighbour)", r)
    if cols == rows and agree < 0.5:
        # A square board turned by a quarter: the same lattice, the colours swapped when the
        # side is odd. Turn the labels (right-handedness is kept).
        g = np.stack([cols - 1 - g[:, 1], g[:, 0]], axis=-1)
        agree = 1.0 - agree
    if (cols + rows) % 2 == 1:
        # The half-turn swaps the colours: they decide it.
        if agree < 0.5:
            g = np.stack([cols - 1 - g[:, 0], rows - 1 - g[:, 1]], axis=-1)
        agree = max(agree, 1.0 - agree)
    else:
        # The half-turn keeps the colours; a print with the colours the other way round (white
        # where Checkerboard has black) is as good. Corner (0, 0) is the end nearer the image's
        # top-left, as OpenCV leaves it.
        agree = max(agree, 1.0 - agree)
        lab = {(int(a), int(b)): p for (a, b), p in zip(g, q, strict=True)}
        M = np.linalg.lstsq(np.c_[g, np.ones(len(g))], q, rcond=None)[0]
        c00 = lab.get((0, 0), M[2])
        c11 = lab.get((cols - 1, rows - 1), M[2] + (cols - 1) * M[0] + (rows - 1) * M[1])
        if c00 @ [1.0, 1.0] > c11 @ [1.0, 1.0]:
            g = np.stack([cols - 1 - g[:, 0], rows - 1 - g[:, 1]], axis=-1)
    if agree < 0.8:
        return fail(f"not found: the corners' labels disagree with the squares' colours ({agree:.0%} agree)", r)
    out = np.full((n_corners, 2), np.nan)
    sigma = np.full(n_corners, np.nan)
    flat = g[:, 1] * cols + g[:, 0]
    out[flat] = q
    sigma[flat] = sig
    inside = ((out[:, 0] >= 0) & (out[:, 0] <= shape[1] - 1) & (out[:, 1] >= 0)
              & (out[:, 1] <= shape[0] - 1))
    out[~inside] = np.nan
    sigma[~inside] = np.nan
    found = int(np.isfinite(out).all(axis=1).sum())
    return Detection(True, out, sigma, r, f"found {found} of {n_corners} corners (window {r} px)"), borders, open_end


#: A corner whose saddle fit leaves residuals this many times the board's median (its sigma)
#: is not a clean X-junction (an occluder's edge, a glare, a second pattern) and is dropped.
_SIGMA_RATIO = 2.0


#: A refined corner whose surroundings are this far from point-symmetric (mean difference
#: between opposite points of a circle, over the circle's contrast) is not a clean X-junction.
_MAX_ASYMMETRY = 0.15
#: ... and at full resolution, after a board found at a coarser level is refined there, a
#: corner is also dropped past ``_ASYMMETRY_TIMES`` the board's median asymmetry where that is
#: over ``_ASYMMETRY_FLOOR``: a finger's tip touching a corner of a 14 MP board (squares of
#: 85 px) left it 0.136 from symmetric and 1.5 px off, its 25 neighbours at most 0.012
#: (benchmarks/notes.md, thirty-second session).
_ASYMMETRY_TIMES = 4.0
_ASYMMETRY_FLOOR = 0.05
#: The circle of the point-symmetry test, as a fraction of the corners' spacing (2 px at least).
_ASYMMETRY_CIRCLE = 0.15


def _asymmetry(s: np.ndarray, q: np.ndarray, spacing: float) -> np.ndarray:
    """How far from point-symmetric the image ``s`` is about each of ``q`` (K, 2): the mean
    difference between opposite points of a circle of ``_ASYMMETRY_CIRCLE`` of the spacing
    (2 px at least), over the circle's contrast."""
    n = 32
    ang = np.arange(n) * 2 * np.pi / n
    rad = max(2.0, _ASYMMETRY_CIRCLE * spacing)
    v = _sample(s, q[:, :1] + rad * np.cos(ang), q[:, 1:] + rad * np.sin(ang), "bilinear")
    contrast = np.maximum(v.max(axis=1) - v.min(axis=1), 1e-12)
    return np.abs(v - np.roll(v, n // 2, axis=1)).mean(axis=1) / contrast


def _point_symmetric(s: np.ndarray, q: np.ndarray, spacing: float) -> np.ndarray:
    """Which refined corners ``q`` are point-symmetric X-junctions (:func:`_asymmetry` within
    ``_MAX_ASYMMETRY``): a finger or other occluder's edge near a corner breaks the
    symmetry and pulls the saddle fit off the junction (a pixel and more), while the checks
    against the lattice, which must follow a fisheye's bend, cannot see so small a shift."""
    return _asymmetry(s, q, spacing) <= _MAX_ASYMMETRY


def _fits_well(sig: np.ndarray) -> np.ndarray:
    """Corners whose saddle fit is as clean as the board's others (sigma within _SIGMA_RATIO
    of their median)."""
    ok = np.isfinite(sig)
    if ok.any():
        ok &= sig <= _SIGMA_RATIO * np.median(sig[ok])
    return ok


def _lattice_spacing(g: np.ndarray, p: np.ndarray, default: float = 11.0) -> float:
    """Median image distance between lattice neighbours (``default`` where there are none)."""
    if len(g) == 0:
        return default
    G = _grid(g, margin=1)
    here = G[:-1, :-1]
    d = []
    for there in (G[1:, :-1], G[:-1, 1:]):
        both = (here >= 0) & (there >= 0)
        d.append(np.hypot(*(p[there[both]] - p[here[both]]).T))
    d = np.concatenate(d)
    return float(np.median(d)) if d.size else default


def _check_tol(spacing: float) -> float:
    """The tolerance (pixels) of :func:`_consistent` and :func:`_lens_rescue` for a lattice of
    ``spacing`` pixels: 8 % of it, 0.6 px at least."""
    return max(0.6, 0.08 * spacing)


def _consistent(g: np.ndarray, q: np.ndarray, spacing: float) -> np.ndarray:
    """Which corners agree with their lattice neighbours: each corner against the quadratic
    map (lattice to image) fitted on the corners within two steps of it, itself left out. A
    quadratic follows perspective and lens distortion over a few squares; a corner placed on
    something else (a finger's edge, a second pattern, text) misses it by a fraction of a
    square. The worst offenders go first, round by round, so that one wrong corner does not
    condemn its neighbours. Where fewer than seven neighbours span the neighbourhood, an
    affine map from four or more is the test; a corner with fewer cannot be checked and goes
    (a label that cannot be checked is not returned). The tolerance is 8 % of the spacing,
    0.6 px at least. (A looser one for corners with a clean saddle fit, 10-12 %, finds more
    fisheye boards but lets wrong corners that support each other through.)"""
    keep = np.ones(len(g), dtype=bool)
    tol = np.full(len(g), _check_tol(spacing))
    if len(g):
        lattice_kernels.consistent(_grid(g), np.ascontiguousarray(q, dtype=np.float64), tol, keep)
    return keep


def _checked(g: np.ndarray, q: np.ndarray, spacing: float, shape: tuple[int, ...]) -> np.ndarray:
    """Step 4's check of the lattice corners ``q`` (lattice coordinates ``g``): which pass the
    local check (:func:`_consistent`), are put back by the lens model fitted on those
    (:func:`_lens_rescue`), or, where some stay dropped, are kept by the lens model fitted on
    the whole lattice (:func:`_lens_consensus`)."""
    tol = _check_tol(spacing)
    passed = _lens_rescue(g, q, _consistent(g, q, spacing), tol, shape)
    if not passed.all():
        passed |= _lens_consensus(g, q, tol, shape)
    return passed


def _lens_rescue(g: np.ndarray, q: np.ndarray, keep: np.ndarray, tol: float | np.ndarray,
                 shape: tuple[int, ...], min_span: float = 2.0, back: float = np.inf) -> np.ndarray:
    """``keep`` with the corners that failed a local check (:func:`_consistent`; the AprilGrid's
    :func:`~camkit.target._markers.consistent_points`) put back where a global model of the
    lattice's image, fitted on the corners that passed, predicts them within the same
    tolerance ``tol`` (pixels: one for all, or (N,) one per corner), and within ``back``
    pixels.

    A quadratic over two steps cannot follow a board near a fisheye's rim (squares growing 1.5
    times a step); a lens can be modelled. The model (:class:`_LensMap`) is a homography (the
    board's plane seen in perspective) followed by radial distortion about a free centre, the
    division model of Fitzgibbon (CVPR 2001) with a second term. It is trusted only where it
    predicts what it was not fitted on: the outer corners of those that passed, a quarter at a
    time, are left out, the model fitted on the rest, and each must come within its
    tolerance (the rescued corners are predicted the same way, out of the fit). At least ten
    corners must pass, spanning ``min_span`` units of ``g`` (lattice steps for the
    checkerboard: two) both ways; the centre is free from twenty."""
    tol = np.broadcast_to(np.asarray(tol, dtype=np.float64), (len(g),))
    for _ in range(3):  # the corners put back help fit the model that judges the rest
        more = _lens_rescue_once(g, q, keep, tol, shape, min_span, back)
        if more.sum() == keep.sum():
            break
        keep = more
    return keep


def _lens_rescue_once(g: np.ndarray, q: np.ndarray, keep: np.ndarray, tol: np.ndarray,
                      shape: tuple[int, ...], min_span: float, back: float) -> np.ndarray:
    if keep.all() or keep.sum() < 10 or np.ptp(g[keep], axis=0).min() < min_span:
        return keep
    gk, qk, tk = g[keep].astype(np.float64), q[keep], tol[keep]
    lm = _LensMap(shape, len(gk) >= 20, gk)
    p = lm.fit(gk, qk, near=4.0 * float(np.median(tk)))
    if p is None:
        return keep
    if not _predicts_outer(lm, p, gk, qk, tk):
        return keep
    drop = np.flatnonzero(~keep)
    miss = np.hypot(*(lm.predict(p, g[drop].astype(np.float64)) - q[drop]).T)
    out = keep.copy()
    out[drop[miss <= np.minimum(tol[drop], back)]] = True
    return out


def _lens_consensus(g: np.ndarray, q: np.ndarray, tol: float, shape: tuple[int, ...],
                    min_span: float = 2.0) -> np.ndarray:
    """The corners that one global model of the lattice's image (:class:`_LensMap`) fitted on
    the whole lattice predicts within ``tol`` pixels: the worst missed goes, the model is
    fitted again on the rest, until every corner left is within the tolerance; then the model
    must predict its own outer corners, a quarter at a time, left out of the fit (as
    :func:`_lens_rescue` trusts it). None kept where fewer than ten corners, or fewer than
    three in four of the lattice's, are left, or they span less than ``min_span`` lattice
    steps either way.

    Near a strong fisheye's rim the squares grow so fast from one step to the next that the
    local check (:func:`_consistent`) keeps too few corners for :func:`_lens_rescue`'s model to
    start from (real fisheye view 22 shrunk to a half: 6 of its 24 corners), while a lens model
    fitted on all of them misses none by more than half a pixel. A corner on something else (an
    occluder's edge, a second pattern) or linked a step off misses the model by a fraction of a
    square and is the first to go."""
    n = len(g)
    out = np.zeros(n, dtype=bool)
    if n < 10:
        return out
    gf = g.astype(np.float64)
    idx = np.arange(n)
    p = None
    while len(idx) >= max(10, 0.75 * n):
        if np.ptp(gf[idx], axis=0).min() < min_span:
            return out
        lm = _LensMap(shape, len(idx) >= 20, gf[idx])
        p = lm.fit(gf[idx], q[idx], plain=True)
        if p is None:
            return out
        miss = np.hypot(*(lm.predict(p, gf[idx]) - q[idx]).T)
        worst = int(np.argmax(miss))
        if miss[worst] <= tol:
            break
        idx = np.delete(idx, worst)
        p = None
    if p is None:
        return out
    if _predicts_outer(lm, p, gf[idx], q[idx], np.full(len(idx), tol)):
        out[idx] = True
    return out


def _predicts_outer(lm: _LensMap, p: np.ndarray, g: np.ndarray, q: np.ndarray, tol: np.ndarray) -> bool:
    """Whether the lens model ``p`` (of ``lm``, fitted on all of ``g``, ``q``) predicts its own
    outer corners from the rest: four folds, each a quarter of the outer corners left out of
    the fit, every one within its tolerance ``tol`` (pixels, one per corner)."""
    lo, hi = g.min(axis=0), g.max(axis=0)
    outer = np.flatnonzero((g == lo).any(axis=1) | (g == hi).any(axis=1))
    for k in range(min(4, len(outer))):
        held = outer[k::4]
        rest = np.ones(len(g), dtype=bool)
        rest[held] = False
        pk = lm.fit(g[rest], q[rest], start=p)
        if pk is None or not np.all(np.hypot(*(lm.predict(pk, g[held]) - q[held]).T) <= tol[held]):
            return False
    return True


def _lens_veto(g: np.ndarray, q: np.ndarray, keep: np.ndarray, shape: tuple[int, ...], floor: float,
               spread: float, min_span: float, rounds: int = 8) -> np.ndarray:
    """``keep`` without the corners that a global model of the lattice's image (:class:`_LensMap`,
    a homography where no lens bends it), fitted on all those kept, misses by more than
    ``floor`` pixels and ``spread`` times the fit's robust spread (1.4826 times the median
    miss): the worst first, the model fitted again without it, at most ``rounds`` times.
    Where the model cannot follow the image (a lens beyond it, a board not flat) the spread is
    large and nothing goes. At least twenty corners spanning ``min_span`` units of ``g`` both
    ways, else ``keep`` as it is. The AprilGrid's last word on a corner a local check let
    through: a local map is fitted on its few neighbours, all on one side at the grid's edge,
    and must allow for a lens there; this model is fitted on all of them."""
    keep = keep.copy()
    for _ in range(rounds):
        idx = np.flatnonzero(keep)
        if len(idx) < 20 or np.ptp(g[idx], axis=0).min() < min_span:
            break
        lm = _LensMap(shape, True, g[idx])
        p = lm.fit(g[idx], q[idx], plain=True)
        if p is None:
            break
        miss = np.hypot(*(lm.predict(p, g[idx]) - q[idx]).T)
        worst = int(np.argmax(miss))
        if not miss[worst] > max(floor, spread * 1.4826 * float(np.median(miss))):
            break
        keep[idx[worst]] = False
    return keep


class _LensMap:
    """Lattice -> image through a homography H and radial distortion about a centre c:
    ``u = H(g) - c``, ``d = u * 2 / (1 + sqrt(1 - 4 l1 |u|^2))`` (the point whose division-model
    undistortion ``d / (1 + l1 |d|^2)`` is u), then ``x = c + d (1 + l2 |d|^2)``, in
    coordinates centred on the image and scaled by half its larger side."""

    def __init__(self, shape: tuple[int, ...], free_centre: bool, lattice: np.ndarray) -> None:
        self.centre = np.array([shape[1] - 1, shape[0] - 1]) / 2.0
        self.f = max(shape[:2]) / 2.0
        self.n = 12 if free_centre else 9  # l2 and c held at 0 unless the centre is free
        # The lattice centred and scaled too (the homography's entries of one size: LM then
        # converges in a few steps, not a hundred).
        self.g0 = lattice.mean(axis=0)
        self.gs = max(float(np.sqrt(((lattice - self.g0) ** 2).sum(axis=1).mean())), 1e-9)

    def _map(self, p: np.ndarray, g: np.ndarray) -> np.ndarray:
        return self._map_many(p[None], g)[0]

    def _map_many(self, P: np.ndarray, g: np.ndarray) -> np.ndarray:
        """The map of the lattice points ``g`` (N, 2) under each parameter vector of ``P``
        (K, 9 or 12): (K, N, 2), in the centred, scaled image coordinates (kernel
        :func:`camkit._kernels.lattice.lens_map`, which :func:`~camkit._kernels.lattice.lens_fit`
        calls for its residuals too)."""
        full = np.zeros((len(P), 12))
        full[:, :P.shape[1]] = P
        out = np.empty((len(P), len(g), 2))
        lattice_kernels.lens_map(full, np.ascontiguousarray(g, dtype=np.float64), float(self.g0[0]),
                                 float(self.g0[1]), self.gs, out)
        return out

    def fit(self, g: np.ndarray, q: np.ndarray, start: np.ndarray | None = None,
            near: float = np.inf, plain: bool = False) -> np.ndarray | None:
        """Least squares (Levenberg-Marquardt, :func:`camkit._kernels.lattice.lens_fit`) from
        ``start``, else from the best of a few division-model strengths with a homography each
        (the division model undistorts in closed form); None where that best start misses a
        point by more than ``near`` pixels (no such lens is near), where it is the undistorted
        one and ``plain`` is false (a homography: the local quadratic check already follows
        it), or where the fit fails."""
        qn = (q - self.centre) / self.f
        gn = (g - self.g0) / self.gs
        if start is None:
            lams = np.array([0.0, -0.25, -0.5, -0.75, -1.0])
            und = qn[None] / (1.0 + lams[:, None, None] * (qn * qn).sum(axis=1)[None, :, None])
            Hs = fit_homographies(np.broadcast_to(gn, und.shape), und)  # one batch, five strengths
            best_start, best_miss = None, np.inf
            for lam, H0 in zip(lams, Hs, strict=True):
                if not (np.isfinite(H0).all() and abs(H0[2, 2]) > 1e-12):
                    continue
                p0 = np.r_[(H0 / H0[2, 2]).ravel()[:8], lam, np.zeros(self.n - 9)]
                miss = float(np.max(np.hypot(*((self._map(p0, g) - qn) * self.f).T)))
                if miss < best_miss:
                    best_start, best_miss = p0, miss
            if best_start is None or not best_miss <= near or (best_start[8] == 0.0 and not plain):
                return None
            start = best_start
        p = np.empty(len(start))
        ok = lattice_kernels.lens_fit(np.asarray(start, dtype=np.float64), np.ascontiguousarray(g, dtype=np.float64),
                                      np.ascontiguousarray(qn), float(self.g0[0]), float(self.g0[1]), self.gs, 40, p)
        return p if ok else None

    def predict(self, p: np.ndarray, g: np.ndarray) -> np.ndarray:
        return self._map(p, g) * self.f + self.centre


def _largest_part(g: np.ndarray) -> np.ndarray:
    """Indices of the largest group of lattice corners linked to each other as neighbours
    (diagonals included). Two groups apart by a whole hidden row or column are not joined:
    nothing between them checks that the walk kept its count across the gap."""
    from scipy import ndimage

    G = _grid(g)
    labels, n = ndimage.label(G >= 0, structure=np.ones((3, 3), dtype=bool))
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    sizes = np.bincount(labels.ravel())[1:]
    return np.sort(G[labels == 1 + int(np.argmax(sizes))])


#: The circle on which a place one step past the lattice is tested for an X-corner: this
#: fraction of the spacing where that is under the detector's 4 px (squares of 10-16 px). It
#: stays within the four squares around the place; the 4 px circle of 0.36 of an 11 px square
#: crossed a narrow margin onto the board's dark frame and read X-corners there (real
#: opencv_right photos at a third of their size: whole boards refused as "the pattern goes on").
_STEP_OUT_RADIUS = 0.25


def _border_evidence(s: np.ndarray, g: np.ndarray, q: np.ndarray, spacing: float, min_contrast: float = _MIN_CONTRAST,
                     ) -> tuple[dict[tuple[int, int], str], dict[tuple[int, int], bool]]:
    """What lies beyond each side of the lattice: ``"border"`` (the row of outer squares, then
    the sheet's plain margin), ``"more"`` (the checker pattern goes on: corners were missed
    there) or ``"unknown"`` (outside the image, hidden, or too faint to say).

    Along a side, half a square out from the last corners lie the board's outer squares,
    alternating black and white; one and a half squares out lies the margin, uniform and as
    light as the white squares, where the board ends, or squares alternating the other way
    where it does not (changing colour across the outer squares' middle shade, not only
    shade: a dark background past a narrow margin is not more pattern; beyond half of the
    outer squares each way, or three in four where no place one step out holds an X-corner,
    and there each such square one colour at three tenths, half and seven tenths of its
    width). The margin is also read 1.2 squares out, a fifth past the outer squares: a narrow
    margin (a print trimmed close) lies there and not at one and a half.
    Positions come from the quadratic lattice map fitted near each sample.
    One step out, where the pattern's next corners would be, X-corners (on a circle of a
    quarter of the spacing where that is under 4 px) at most of the places inside the image
    mean ``"more"`` whatever the shades say; where most of those places are
    inside the image and hold no X-corner, the pattern is seen to end there (the second dict,
    True), even where the margin beyond is outside the image or dark.
    Keys: (axis, -1) for the low side of lattice axis ``axis``, (axis, +1) for the high side."""
    G = _grid(g)
    ext = g.max(axis=0)
    qc = np.ascontiguousarray(q, dtype=np.float64)
    out: dict[tuple[int, int], str] = {}
    ended: dict[tuple[int, int], bool] = {}
    for axis in (0, 1):
        for side in (-1, 1):
            near_a = np.empty(int(ext[1 - axis]))
            far_a = np.empty_like(near_a)
            step = np.empty((len(near_a), 2))
            far_sides = np.empty((len(near_a), 2))
            close_a = np.empty_like(near_a)
            inner_a = np.empty_like(near_a)
            lattice_kernels.border_samples(G, qc, s, axis, side, near_a, far_a, step, far_sides, close_a, inner_a)
            # One step out, where the pattern's next corners would be: X-corners at most of the
            # places there inside the image (even one) mean the pattern goes on, whatever the
            # shades say; none at most of them, with at least half the places inside, mean it
            # is seen to end.
            inside = np.isfinite(step).all(axis=1)
            ended[(axis, side)] = False
            no_x = False
            if inside.any():
                radius = min(_PROFILE_RADIUS, _STEP_OUT_RADIUS * spacing)
                is_x = _x_test(_profiles(s, step[inside], radius=radius), min_contrast)[0]
                if is_x.mean() >= 0.5:
                    out[(axis, side)] = "more"
                    continue
                ended[(axis, side)] = inside.sum() >= 2 and inside.sum() >= 0.5 * len(step)
                no_x = ended[(axis, side)] and not is_x.any()
            ok = np.isfinite(near_a) & np.isfinite(far_a)
            beyond = np.isinf(near_a) | np.isinf(far_a)
            far_sides = far_sides[ok]
            if ok.sum() < 2 or beyond.sum() > ok.sum():
                out[(axis, side)] = "outside" if beyond.sum() > ok.sum() else "unknown"
                continue
            sign = np.where(np.arange(len(near_a)) % 2 == 0, 1.0, -1.0)[ok]
            n_, f_ = near_a[ok], far_a[ok]
            a_near = float(np.mean(sign * (n_ - n_.mean())))
            a_far = float(np.mean(sign * (f_ - f_.mean())))
            contrast = float(n_.max() - n_.min())
            ordered = np.sort(n_)
            white = float(np.mean(ordered[len(n_) // 2:]))
            black = float(np.mean(ordered[:max(len(n_) // 2, 1)]))
            # Squares alternating the other way change colour, not only shade: beyond the dark
            # outer squares most far samples are light, and beyond the light ones most are dark
            # (a margin over a dark background, where a fisheye's rim throws the far samples
            # past the sheet, varies in shade but stays dark: real fisheye 26).
            mid = 0.5 * (white + black)
            dark = n_ < mid
            # Where the places one step out hold no X-corner at all, the colours must change
            # beyond three in four of the outer squares (clutter past a narrow margin changes
            # beyond half by chance: real opencv_right at a third of its size); else half.
            most = 0.75 if no_x else 0.5
            f_light, f_dark = f_ > mid, f_ < mid
            if no_x:
                # And each far square must be one colour across its width (three tenths, half and
                # seven tenths along it): a second pattern past a narrow margin, at its own scale
                # and angle, matches the alternation at the squares' middles by chance where a
                # side has two or three squares (a 3x3 board beside a larger one).
                f_light &= (far_sides > mid).all(axis=1)
                f_dark &= (far_sides < mid).all(axis=1)
            recoloured = bool(dark.any() and (~dark).any() and np.mean(f_light[dark]) >= most
                              and np.mean(f_dark[~dark]) >= most)
            if abs(a_near) < 0.1 * max(contrast, 1e-9) or contrast < min_contrast * (0.1 / _MIN_CONTRAST):
                out[(axis, side)] = "unknown"
            elif a_far * a_near < 0 and abs(a_far) > 0.4 * abs(a_near) and recoloured:
                out[(axis, side)] = "more"
            else:
                # The plain light margin, half a square past the outer squares, or where that
                # lies past a narrow margin (a print trimmed close), a fifth of a square past.
                out[(axis, side)] = "unknown"
                if _washed_out(n_, inner_a[ok], dark):
                    continue
                for f_m in (f_, close_a[ok]):
                    if not np.isfinite(f_m).all():
                        continue
                    a_m = float(np.mean(sign * (f_m - f_m.mean())))
                    plain = abs(a_m) < 0.25 * abs(a_near)
                    light = float(np.mean(f_m)) > black + 0.7 * (white - black)
                    if plain and light:
                        out[(axis, side)] = "border"
                        break
    return out, ended


#: A side whose outer squares keep under this fraction of the contrast of the lattice's last
#: squares, their dark squares lifted by over ``_WASHED_LIFT`` of it, is washed out by light (a
#: glare): on the rendered corpus's true borders the outer squares keep 0.72 of that contrast or
#: more where their dark squares are lifted by over a third of it; at probe view 3029's glare
#: 0.60, lifted by 0.62 (benchmarks/notes.md, thirty-seventh session).
_WASHED_CONTRAST = 0.7
_WASHED_LIFT = 0.4


def _washed_out(near: np.ndarray, inner: np.ndarray, dark: np.ndarray) -> bool:
    """Whether light washes the pattern out towards a side: the outer squares (shades
    ``near``, ``dark`` where dark) keep under ``_WASHED_CONTRAST`` of the contrast of the
    lattice's last squares (``inner``, half a square in, the other colour), their dark squares
    lifted by over ``_WASHED_LIFT`` of it. A glare on the print does that, and past it the
    burnt-out squares are as plain and as light as a margin (probe view 3029 came back
    half-turned on such a side)."""
    if not (np.isfinite(inner).all() and dark.any() and (~dark).any()):
        return False
    d_in, l_in = float(np.mean(inner[~dark])), float(np.mean(inner[dark]))
    contrast = l_in - d_in
    if contrast <= 0.0:
        return False
    d_out, l_out = float(np.mean(near[dark])), float(np.mean(near[~dark]))
    return l_out - d_out < _WASHED_CONTRAST * contrast and d_out - d_in > _WASHED_LIFT * contrast


def _other_board(s: np.ndarray, g: np.ndarray, q: np.ndarray, spacing: float, min_contrast: float,
                 size: tuple[int, int]) -> tuple[int, int] | None:
    """The inner corners of the whole board a lattice (coordinates ``g`` from 0, corners ``q``)
    is, where its border is seen on all four sides and it is not the ``size`` (cols, rows)
    asked for: in the order of ``size``'s (the longer first where cols >= rows). Else None. A
    failure says it, so that a miscounted board size can be named."""
    ext = [int(e) for e in g.max(axis=0) + 1]
    if sorted(ext) == sorted(size):
        return None
    sides, _ = _border_evidence(s, g, q, spacing, min_contrast)
    if not all(v == "border" for v in sides.values()):
        return None
    a, b = sorted(ext, reverse=size[0] >= size[1])
    return (a, b)


def _place(ext: np.ndarray, tgt: tuple[int, int], sides: dict) -> tuple[tuple[int, int] | None, str]:
    """Where a lattice of ``ext`` corners sits in a board of ``tgt`` corners, from the evidence
    at its sides: a lattice as long as the board needs no border but must not have the
    pattern going on past either end; a shorter one is placed against the side where the
    board's border is seen, the other side showing no border. Returns (offset, "") or (None,
    why not)."""
    off = [0, 0]
    names = ("columns", "rows")
    for axis in (0, 1):
        lo, hi = sides[(axis, -1)], sides[(axis, 1)]
        n, want = int(ext[axis]), int(tgt[axis])
        if n == want:
            if "more" in (lo, hi) and "trimmed" not in (lo, hi):
                return None, (f"the lattice has the board's {want} {names[axis]} but the pattern goes on past one "
                              "end (a row of corners missed there, another seen elsewhere)")
            continue
        if lo == "border" and hi != "border":
            off[axis] = 0
        elif hi == "border" and lo != "border":
            off[axis] = want - n
        elif lo == "border" and hi == "border":
            return None, (f"the lattice has {n} of the board's {want} {names[axis]} between two borders "
                          "(another pattern, or a board of another size)")
        else:
            return None, (f"only {n} of the board's {want} {names[axis]} are seen and neither end shows the "
                          "board's border, so their labels are not fixed (part of the board is hidden or "
                          "outside the image)")
    return (off[0], off[1]), ""


def _colour_agreement(s: np.ndarray, g: np.ndarray, q: np.ndarray) -> float | None:
    """Fraction of the probed corners whose squares' shades match Checkerboard's colours for
    the labels ``g``: at each corner (a, b) whose neighbours (a + 1, b + 1), (a + 1, b) and
    (a, b + 1) are seen, the two squares on its diagonal through (a - 1, b - 1), black when
    a + b is even, against the two on its other diagonal, half a step out along each. Each
    corner's squares are compared with each other, not with a level for the whole board: a
    shadow over part of the board, or a light's fall-off, dims both pairs alike (real photos
    half in shadow: their shaded white squares read as darker than the lit black ones). Where
    fewer than two corners have those neighbours, each square probed on the first diagonal is
    read against the middle of all those shades."""
    G = _grid(g - g.min(axis=0), margin=1)
    here, diag = G[:-1, :-1], G[1:, 1:]
    right, down = G[1:, :-1], G[:-1, 1:]
    both = (here >= 0) & (diag >= 0)
    if both.sum() < 2:
        return None
    full = both & (right >= 0) & (down >= 0)
    if full.sum() >= 2:
        k, j, e1, e2 = here[full], diag[full], right[full], down[full]
        d, e = q[j] - q[k], q[e1] - q[e2]
        probe = np.ascontiguousarray(np.concatenate([q[k] - 0.5 * d, q[k] + 0.5 * d, q[k] + 0.5 * e, q[k] - 0.5 * e]),
                                     dtype=np.float64)
        shade = _sample(s, probe[:, 0], probe[:, 1], "bilinear").reshape(4, -1)
        dark = shade[0] + shade[1] < shade[2] + shade[3]
    else:
        k, j = here[both], diag[both]
        probe = np.ascontiguousarray(q[k] + 0.5 * (q[k] - q[j]), dtype=np.float64)
        shade = _sample(s, probe[:, 0], probe[:, 1], "bilinear")
        dark = shade < 0.5 * (shade.max() + shade.min())
    return float(np.mean(dark == ((g[k, 0] + g[k, 1]) % 2 == 0)))


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
