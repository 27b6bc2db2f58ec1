"""Resize with proper filtering: enlarging interpolates, shrinking low-pass filters first."""

from __future__ import annotations

import functools
import math
from typing import Any

import numba
import numpy as np

from camkit._kernels import resize as resize_kernels
from camkit._validate import as_finite_float, as_image, as_positive_int, check_choice
from camkit.resample.kernels import DEFAULT_BICUBIC_A, INTERPOLATIONS, kernel, kernel_support

__all__ = ["RESIZE_INTERPOLATIONS", "resize", "resize_weights"]

RESIZE_INTERPOLATIONS = (*INTERPOLATIONS, "area")


def resize_weights(n_in: int, n_out: int, interpolation: str, *, antialias: bool = True,
                   bicubic_a: float = DEFAULT_BICUBIC_A) -> tuple[np.ndarray, np.ndarray]:
    """The weight table of one axis: ``(starts (n_out,), weights (n_out, K))``.

    Output index ``j`` sits at input coordinate ``x_j = (j + 0.5) n_in / n_out - 0.5`` (pixel
    centres at integers, image edges aligned). When shrinking (scale ``s = n_in / n_out > 1``)
    with ``antialias``, the kernel is stretched by ``s`` (``w_i = k((i - x_j) / s)``), so its
    cut-off moves to the new Nyquist frequency; "area" weighs each input pixel by its overlap
    with the output pixel's footprint (exact means for integer factors). Taps outside the
    image are dropped and the rest renormalised to sum to 1, so a constant stays constant.
    """
    method = check_choice(interpolation, RESIZE_INTERPOLATIONS, "interpolation")
    scale = n_in / n_out
    x = (np.arange(n_out) + 0.5) * scale - 0.5
    if method == "nearest":
        idx = np.clip(np.floor(x + 0.5).astype(np.int64), 0, n_in - 1)
        return idx, np.ones((n_out, 1))
    stretch = scale if (antialias and scale > 1.0) or method == "area" else 1.0
    support = (0.5 if method == "area" else kernel_support(method)) * stretch
    # Input pixel i contributes where the kernel is non-zero at its centre, |i - x| < support;
    # for "area" where its extent [i - 0.5, i + 0.5] overlaps [x - support, x + support].
    reach = support + (0.5 if method == "area" else 0.0)
    # The first integer above x - reach; an open interval of length 2 reach holds at most
    # ceil(2 reach) integers, so that many taps suffice (8, not 9, when halving with bicubic).
    first = np.floor(x - reach).astype(np.int64) + 1
    K = max(int(np.ceil(2 * reach)), 1)
    idx = first[:, None] + np.arange(K)[None, :]
    t = idx - x[:, None]
    if method == "area":
        lo = np.maximum(t - 0.5, -support)
        hi = np.minimum(t + 0.5, support)
        w = np.maximum(hi - lo, 0.0)
    else:
        w = kernel(method, t / stretch, bicubic_a=bicubic_a)
    w = np.where((idx >= 0) & (idx < n_in), w, 0.0)
    w /= w.sum(axis=1, keepdims=True)
    # Shift every window inside the image so kernels never bounds-check.
    starts = np.clip(first, 0, max(n_in - K, 0))
    shift = first - starts
    out_w = np.zeros((n_out, max(K, 1)))
    K_eff = min(K, n_in)
    for d in np.unique(shift):
        rows = shift == d
        src = w[rows]
        cols = np.arange(K) + d  # position of each original tap in the shifted window
        keep = (cols >= 0) & (cols < K_eff)
        out_w[np.ix_(rows, cols[keep])] += src[:, keep]
    return starts, np.ascontiguousarray(out_w[:, :K_eff])


_FUSED: dict[tuple[int, ...], Any] = {}
#: Tap counts the shrinking kernel is compiled for; a table is padded with zero taps up to
#: the next one (a handful of variants, not one per output size).
_TAPS = (1, 2, 4, 8, 12, 16, 24, 32)


_ENLARGE: dict[tuple[int, ...], Any] = {}
#: The enlarging kernel's periodic path: at most this many phases (outputs per period) and
#: input pixels per period (the full-rate filtering does ``Q`` times the decimated work).
_MAX_PHASES, _MAX_STEP = 8, 4


def _cached(table: dict[tuple[int, ...], Any], factory: Any, *key: int) -> Any:
    """``factory(*key)``, built on first use and kept (numba caches the machine code on disk)."""
    if key not in table:
        table[key] = factory(*key)
    return table[key]


def _fused_kernel(ky: int, kx: int, c: int, step: int) -> Any:
    """The shrinking kernel for (vertical taps, shared horizontal taps or 0, channels, shrink
    factor); factors above 4 are passed at run time instead of compiled in (a known stride
    lets the output loop vectorise: 2x)."""
    return _cached(_FUSED, resize_kernels.make_vertical_horizontal, ky, kx, c, step if kx and step <= 4 else 0)


def _padded(starts: np.ndarray, weights: np.ndarray, n_in: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The table with its windows widened (zero taps) to the next count in ``_TAPS`` and moved
    to stay inside the input; None where that count exceeds the input or the largest."""
    K = weights.shape[1]
    K_new = next((t for t in _TAPS if t >= K), None)
    if K_new is None or K_new > n_in:
        return None
    if K_new == K:
        return starts, weights
    new_starts = np.minimum(starts, n_in - K_new)
    out = np.zeros((len(starts), K_new))
    shift = starts - new_starts
    for d in np.unique(shift):
        rows = shift == d
        out[rows, d:d + K] = weights[rows]
    return new_starts, out


def _periodic(starts: np.ndarray, weights: np.ndarray, n_in: int, n_out: int, max_p: int,
              max_q: int) -> tuple[np.ndarray, np.ndarray, int, int, int]:
    """Where n_out / n_in = P / Q in lowest terms with small P and Q, the weights repeat every
    P outputs, which start Q inputs further on: output ``c0 + P m + p`` (0 <= m < M) starts at
    ``pfirst[p] + Q m`` with the weights ``pw[p]``. Returns ``(pw (P, K), pfirst (P,), Q, c0,
    M)`` for the longest such run around the middle (M == 0 when there is none, or when P or
    Q exceed ``max_p``, ``max_q``), which the kernels filter at the full input rate in SIMD
    (see ``_kernels.resize``)."""
    g = math.gcd(n_in, n_out)
    P, Q = n_out // g, n_in // g
    none = (weights[:1], starts[:1], 1, 0, 0)
    if P > max_p or Q > max_q or n_out < 8 * P:
        return none
    mid = (n_out // 2) // P * P
    pw = weights[mid:mid + P]
    pfirst = starts[mid:mid + P] - Q * (mid // P)  # output P m + p would start at pfirst[p] + Q m
    c = np.arange(n_out)
    same = (starts == pfirst[c % P] + Q * (c // P)) & (np.abs(weights - pw[c % P]).max(axis=1) <= 1e-12)
    bad = np.flatnonzero(~same)
    lo = int(bad[bad < mid].max()) + 1 if (bad < mid).any() else 0
    hi = int(bad[bad >= mid].min()) if (bad >= mid).any() else n_out
    m0, m1 = -(-lo // P), hi // P
    if m1 <= m0:
        return none
    return np.ascontiguousarray(pw), (pfirst + Q * m0).astype(np.int64), Q, m0 * P, m1 - m0


@functools.lru_cache(maxsize=32)
def _plan(H: int, W: int, h: int, w: int, interpolation: str, antialias: bool, a: float) -> tuple:
    """The weight tables of a resize (and, when shrinking vertically with a compiled tap
    count, the padded vertical table and the shared horizontal weights), read-only and kept
    for the last 32 geometries: building them costs a sizeable fraction of the filtering
    itself, and a batch of photos shares one geometry."""
    sy, wy = resize_weights(H, h, interpolation, antialias=antialias, bicubic_a=a)
    sx, wx = resize_weights(W, w, interpolation, antialias=antialias, bicubic_a=a)
    if h < H:  # (pw (K,), step, first, c0, c1) for the shrinking kernel, or None
        pw, pfirst, q, c0, m = _periodic(sx, wx, W, w, 1, W)
        padded = _padded(sy, wy, H)
        if padded is None or (m and pw.shape[1] not in _TAPS):
            shared = None
        else:
            sy, wy = padded
            shared = (np.ascontiguousarray(pw[0]), q, int(pfirst[0]) - q * c0, c0, c0 + m)  # first: of output 0
    else:  # (pw (P, K), pfirst (P,), Q, c0, M) for the enlarging kernel; M = 0 for the tables
        # (also where the width stays: one table-driven kernel per tap count serves every
        # geometry without a short period, so fewer variants get compiled)
        shared = _periodic(sx, wx, W, w, _MAX_PHASES if w != W else 0, _MAX_STEP)
    for arr in (sy, wy, sx, wx, shared[0] if shared else sy):
        arr.flags.writeable = False
    return sy, wy, sx, wx, shared


def resize(image: np.ndarray, *, width: int, height: int, interpolation: str = "bicubic",
           antialias: bool = True, bicubic_a: float = DEFAULT_BICUBIC_A) -> np.ndarray:
    """Resize an image to ``width x height``.

    Enlarging interpolates with the chosen kernel. Shrinking with ``antialias=True`` (the
    default) stretches the kernel by the scale factor, so nothing above the new Nyquist
    frequency survives to alias (as Pillow does; OpenCV's INTER_LINEAR/INTER_CUBIC do not).
    ``interpolation="area"`` averages each output pixel's footprint: shrinking by 2 is the
    exact 2x2 mean. Separable: one pass per axis, float32 in between (float64 for float64
    images); integer outputs are rounded and saturated.

    Parameters
    ----------
    image : ndarray, (H, W) or (H, W, C), C in 1..4; uint8, uint16, float32 or float64
    width, height : int
    interpolation : {"nearest", "bilinear", "bicubic", "lanczos3", "area"}
    antialias : bool
    bicubic_a : float

    Returns
    -------
    ndarray, (height, width[, C]), the dtype of ``image``

    Examples
    --------
    >>> import numpy as np
    >>> img = np.arange(16, dtype=np.float64).reshape(4, 4)
    >>> resize(img, width=2, height=2, interpolation="area")
    array([[ 2.5,  4.5],
           [10.5, 12.5]])
    """
    img = as_image(image, "image")
    w = as_positive_int(width, "width")
    h = as_positive_int(height, "height")
    a = as_finite_float(bicubic_a, "bicubic_a")
    check_choice(interpolation, RESIZE_INTERPOLATIONS, "interpolation")
    img3 = np.ascontiguousarray(img if img.ndim == 3 else img[:, :, None])
    H, W, C = img3.shape
    is_int = img.dtype.kind == "u"
    hi = float(np.iinfo(img.dtype).max) if is_int else 0.0
    zero = np.float64(0.0) if img.dtype == np.float64 else np.float32(0.0)
    # The kernels write their blocks of output rows from first touch (measured faster than
    # touching the pages in NumPy first, benchmarks/notes.md; remap's kernels take them in a
    # parallel pass first).
    out = np.empty((h, w, C), img.dtype)
    # The vertical pass runs along whole rows (vectorised); the horizontal pass is the costly
    # one, so it runs on whichever has fewer rows: per output row, straight from the vertical
    # sum, when shrinking vertically; once per input row, into a ring of rows, otherwise.
    sy, wy, sx, wx, shared = _plan(H, W, h, w, interpolation, bool(antialias), a)
    src = img3.reshape(H, W * C)
    if h >= H:
        pw, pfirst, q, c0, m = shared
        p, kx = (pw.shape[0], pw.shape[1]) if m else (0, 0)
        _cached(_ENLARGE, resize_kernels.make_horizontal_vertical, kx, wy.shape[1], C, p, q if m else 1)(
            src, sy, wy, sx, wx, pw, pfirst, c0, m, zero, is_int, hi, out,
            max(1, min(h // 32, 4 * numba.get_num_threads())))
    elif shared is not None:
        pw, step, first, c0, c1 = shared
        kernel = _fused_kernel(wy.shape[1], len(pw) if c0 < c1 else 0, C, step)
        kernel(src, sy, wy, sx, wx, zero, is_int, hi, out, pw, step, first, c0, c1)
    else:  # very long kernels (large shrink factors): the tables, taps unknown to the compiler
        resize_kernels.vertical_horizontal(src, sy, wy, sx, wx, zero, is_int, hi, out)
    return out if img.ndim == 3 else out[:, :, 0]
