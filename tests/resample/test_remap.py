"""remap against the float64 NumPy reference; borders, dtypes, channels, bad input."""

from __future__ import annotations

import ctypes
import mmap
import sys

import cv2
import numpy as np
import pytest
from numba import njit

from camkit._kernels.simd_gather import unzip_xy
from camkit.errors import CamkitError, ParameterError, ShapeError
from camkit.resample import INTERPOLATIONS, kernel, remap, warp_affine, warp_perspective

from .reference import remap_reference, to_dtype

RNG = np.random.default_rng(2024)
H, W = 23, 31


def _image(dtype, channels):
    shape = (H, W) if channels == 0 else (H, W, channels)
    if np.dtype(dtype).kind == "u":
        return RNG.integers(0, np.iinfo(dtype).max, size=shape, endpoint=True).astype(dtype)
    return RNG.uniform(0, 1, size=shape).astype(dtype)


def _map(h=17, w=19, spread=4.0, dtype=np.float64):
    # Positions inside, near and beyond the borders, at arbitrary fractions.
    x = RNG.uniform(-spread, W - 1 + spread, size=(h, w))
    y = RNG.uniform(-spread, H - 1 + spread, size=(h, w))
    return np.stack([x, y], axis=-1).astype(dtype)


@pytest.mark.parametrize("method", INTERPOLATIONS)
@pytest.mark.parametrize("border", ["constant", "replicate", "reflect"])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
@pytest.mark.parametrize("channels", [0, 1, 2, 3, 4])
def test_agrees_with_reference(method, border, dtype, channels):
    img = _image(dtype, channels)
    mp = _map()
    fill = 0.25 if np.dtype(dtype).kind == "f" else 7
    out = remap(img, mp, interpolation=method, border=border, fill_value=fill)
    assert out.dtype == img.dtype and out.shape == mp.shape[:2] + img.shape[2:]
    ref = to_dtype(remap_reference(img, mp, method, border, fill), dtype)
    diff = np.abs(out.astype(np.float64) - ref)
    if np.dtype(dtype).kind == "u":
        # Float32 accumulation (float32 weights in the uint8 RGB vector code) can move
        # a value across a rounding boundary: at most 1 level.
        assert diff.max() <= 1
    else:
        # float32 arithmetic on values of size 1: 1e-5 absolute.
        assert diff.max() <= 1e-5


@pytest.mark.parametrize("method", INTERPOLATIONS)
def test_integer_positions_reproduce_pixels(method):
    img = _image(np.float64, 3)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    out = remap(img, np.stack([xx, yy], -1), interpolation=method)
    assert np.allclose(out, img, atol=1e-12)


def test_float32_map_and_uint8_rgb_fast_path_match_opencv():
    img = RNG.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    yy, xx = np.mgrid[0:100, 0:140].astype(np.float32)
    mp = np.stack([xx * 1.07 + 3.3 + np.sin(yy / 9), yy * 0.93 + 2.1], -1).astype(np.float32)
    ours = remap(img, mp)
    ref = cv2.remap(img, np.ascontiguousarray(mp[..., 0]), np.ascontiguousarray(mp[..., 1]),
                    cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    assert np.abs(ours.astype(int) - ref).max() <= 1  # OpenCV's weights are fixed-point (1/32 px)


def test_borders_explicitly():
    img = np.array([[1.0, 2.0, 3.0]])
    at = lambda x, border: remap(img, np.array([[[x, 0.0]]]), interpolation="nearest", border=border,  # noqa: E731
                                 fill_value=-9)[0, 0]
    assert at(-1, "constant") == -9 and at(3, "constant") == -9
    assert at(-1, "replicate") == 1 and at(5, "replicate") == 3
    assert at(-1, "reflect") == 1 and at(-2, "reflect") == 2 and at(3, "reflect") == 3 and at(4, "reflect") == 2
    # Constant border blends into the edge pixel (as OpenCV's BORDER_CONSTANT).
    half = remap(img, np.array([[[-0.5, 0.0]]]), border="constant", fill_value=0)[0, 0]
    assert half == pytest.approx(0.5)


def test_nan_in_map_gives_fill_value():
    img = _image(np.uint8, 3)
    mp = _map(dtype=np.float32)
    mp[2, 3] = np.nan
    mp[4, 5, 0] = np.inf
    for method in INTERPOLATIONS:
        out = remap(img, mp, interpolation=method, fill_value=(1, 2, 3))
        assert out[2, 3].tolist() == [1, 2, 3] and out[4, 5].tolist() == [1, 2, 3]


def test_saturation_not_wraparound():
    step = np.zeros((4, 8), np.uint8)
    step[:, 4:] = 255
    xs = np.linspace(2.5, 5.5, 13)
    mp = np.stack([xs, np.ones_like(xs)], -1)[None]
    for a in (-0.5, -0.75):
        out = remap(step, mp, interpolation="bicubic", bicubic_a=a)
        ref = remap_reference(step, mp, "bicubic", a=a)
        assert ref.min() < 0 and ref.max() > 255  # the kernel overshoots...
        assert out.min() == 0 and out.max() == 255  # ...and the output saturates


def test_empty_output_and_views():
    img = _image(np.float32, 3)
    assert remap(img, np.zeros((0, 5, 2))).shape == (0, 5, 3)
    # Non-contiguous inputs are accepted.
    view = _image(np.float64, 3)[:, ::2]
    mp = _map(spread=0.0)
    mp[..., 0] = np.clip(mp[..., 0], 0, view.shape[1] - 1)
    assert np.allclose(remap(view, mp), remap_reference(view, mp), atol=1e-12)


def test_kernels_sum_and_shape():
    t = np.linspace(-4, 4, 801)
    for name in INTERPOLATIONS:
        k = kernel(name, t)
        assert k[400] == 1.0
    # Keys with a = -0.5 interpolates quadratics exactly (third-order accurate).
    xs = np.arange(10.0)
    vals = 0.3 * xs**2 - xs + 2
    img = np.tile(vals, (3, 1))
    x = np.array([[[4.37, 1.0]]])
    assert remap(img, x, interpolation="bicubic")[0, 0] == pytest.approx(0.3 * 4.37**2 - 4.37 + 2, abs=1e-12)


@pytest.mark.parametrize(
    ("call", "exc", "needle"),
    [
        (lambda: remap(np.zeros((4, 4)), np.zeros((4, 4))), ShapeError, "map_xy: expected shape (H_out, W_out, 2)"),
        (lambda: remap(np.zeros((4, 4)), np.zeros((4, 4, 2), np.int32)), ShapeError, "map_xy: expected a float32 or float64"),
        (lambda: remap(np.zeros((4, 4), np.int32), np.zeros((4, 4, 2))), ShapeError, "image: expected dtype uint8"),
        (lambda: remap(np.zeros((4, 4), bool), np.zeros((4, 4, 2))), ShapeError, "image: expected dtype"),
        (lambda: remap(np.zeros((4, 4, 5)), np.zeros((4, 4, 2))), ShapeError, "image: expected shape (H, W) or (H, W, C)"),
        (lambda: remap(np.zeros((0, 4)), np.zeros((4, 4, 2))), ShapeError, "image: expected a non-empty image"),
        (lambda: remap([[1, 2]], np.zeros((4, 4, 2))), ShapeError, "image: expected a NumPy array"),
        (lambda: remap(np.zeros((4, 4, 3)), np.zeros((4, 4, 2)), fill_value=(1, 2)), ShapeError, "fill_value: expected a number or 3"),
        (lambda: remap(np.zeros((4, 4)), np.zeros((4, 4, 2)), fill_value=np.nan), ParameterError, "fill_value: expected finite"),
        (lambda: remap(np.zeros((4, 4)), np.zeros((4, 4, 2)), interpolation="cubic"), ParameterError, "interpolation: expected one of"),
        (lambda: remap(np.zeros((4, 4)), np.zeros((4, 4, 2)), border="wrap"), ParameterError, "border: expected one of"),
        (lambda: remap(np.zeros((4, 4)), np.zeros((4, 4, 2)), bicubic_a=np.inf), ParameterError, "bicubic_a: expected a finite"),
    ],
)
def test_bad_input(call, exc, needle):
    with pytest.raises(exc) as info:
        call()
    assert isinstance(info.value, CamkitError)
    assert needle in str(info.value)


def _image_before_an_unreadable_page(shape):
    """A uint8 array whose last byte is the last one before a page that may not be read (Linux):
    a kernel that reads past the image's end crashes instead of reading garbage quietly."""
    page = mmap.PAGESIZE
    nbytes = int(np.prod(shape))
    npages = -(-nbytes // page) + 1
    buf = mmap.mmap(-1, npages * page, prot=mmap.PROT_READ | mmap.PROT_WRITE)
    start = (npages - 1) * page - nbytes
    arr = np.frombuffer(buf, np.uint8, count=nbytes, offset=start).reshape(shape)
    addr = arr.ctypes.data + nbytes
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mprotect.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    assert libc.mprotect(ctypes.c_void_p(addr), page, 0) == 0  # PROT_NONE
    return arr, buf


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="needs mprotect (Linux)")
@pytest.mark.parametrize("method", ["bilinear", "bicubic", "lanczos3"])
@pytest.mark.parametrize("family", ["map", "affine", "perspective"])
def test_uint8_rgb_vector_loads_stay_inside_the_image(method, family):
    # The uint8 RGB kernels load whole vectors per row of taps; near the image's end they must
    # fall back to scalar loads. Every position of the last rows and columns, against the
    # float64 reference; an image that ends where unreadable memory begins.
    src = RNG.integers(0, 256, (12, 14, 3), dtype=np.uint8)
    img, buf = _image_before_an_unreadable_page(src.shape)
    np.frombuffer(buf, np.uint8)[-mmap.PAGESIZE - img.size:-mmap.PAGESIZE] = src.reshape(-1)
    yy, xx = np.mgrid[6.0:11.0:0.25, 0.0:13.0:0.25]
    mp = np.stack([xx + 0.1, yy + 0.05], -1)
    ref = to_dtype(remap_reference(src, mp, method, "replicate", 0), np.uint8)
    if family == "map":
        out = remap(img, mp.astype(np.float32), interpolation=method, border="replicate")
    else:  # the same grid as a warp (which takes destination <- source)
        A = np.linalg.inv(np.array([[0.25, 0.0, 0.1], [0.0, 0.25, 6.05], [0.0, 0.0, 1.0]]))
        warp = warp_affine if family == "affine" else warp_perspective
        out = warp(img, A[:2] if family == "affine" else A, width=mp.shape[1], height=mp.shape[0],
                   interpolation=method, border="replicate")
    assert np.abs(out.astype(int) - ref).max() <= 1


@pytest.mark.parametrize("method", ["bilinear", "bicubic"])
@pytest.mark.parametrize("border", ["constant", "reflect"])
@pytest.mark.parametrize("w", [19, 37])
def test_uint8_rgb_with_a_float32_map(method, border, w):
    # The uint8 RGB kernels split each row of a float32 map into x and y with vector shuffles
    # (8 pixels at a time; widths 19 and 37 leave 3 and 5 to the scalar rest), and bilinear
    # stores 4 bytes for every pixel but a row's last: all against the float64 reference,
    # NaN and positions outside among them.
    img = _image(np.uint8, 3)
    mp = _map(h=9, w=w, dtype=np.float32)
    mp[2, 5] = np.nan
    mp[4, -1, 0] = np.nan
    out = remap(img, mp, interpolation=method, border=border, fill_value=7)
    ref = to_dtype(remap_reference(img, mp.astype(np.float64), method, border, 7), np.uint8)
    assert np.abs(out.astype(int) - ref).max() <= 1
    assert (out[2, 5] == 7).all() and (out[4, -1] == 7).all()


@njit(cache=True)
def _unzip(flat, start, n, xs, ys):  # pragma: no cover - numba
    unzip_xy(flat, start, n, xs, ys)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 16, 23])
def test_map_rows_split_into_x_and_y(dtype, n):
    # xs[k] = flat[start + 2k], ys[k] = flat[start + 2k + 1]: blocks of 8 in SIMD (float32) and
    # the rest scalar, nothing written past n.
    flat = np.arange(2 * n + 6, dtype=dtype)
    xs = np.full(n + 3, -1.0, dtype)
    ys = np.full(n + 3, -1.0, dtype)
    _unzip(flat, 4, n, xs, ys)
    assert np.array_equal(xs[:n], flat[4:4 + 2 * n:2])
    assert np.array_equal(ys[:n], flat[5:5 + 2 * n:2])
    assert np.all(xs[n:] == -1.0) and np.all(ys[n:] == -1.0)
