"""resize: constants, exact area means, aliasing leak, passband, agreement with Pillow."""

from __future__ import annotations

import os
import subprocess
import sys

import cv2
import numpy as np
import pytest
from numba import njit
from PIL import Image

from camkit._kernels.simd_resize import HALF_KEYS_256, HAS_AVX2, split_even_odd_c3, vertical_even_odd_c3
from camkit.errors import ParameterError
from camkit.resample import RESIZE_INTERPOLATIONS, resize, resize_weights


def _sine(freq, width=1024, rows=16):
    x = np.arange(width)
    return np.tile(np.sin(2 * np.pi * freq * x) * 0.4 + 0.5, (rows, 1))


def _leak(out, img):
    mid = out[out.shape[0] // 2, 16:-16]
    return mid.std() / img[0].std()


@pytest.mark.parametrize("interpolation", ["lanczos3", "bilinear"])
@pytest.mark.parametrize(("factor", "freq"), [(2, 0.40), (4, 0.30)])
def test_aliasing_leak(interpolation, factor, freq):
    # The measure of the issue: a sine above the new Nyquist frequency must vanish.
    img = _sine(freq)
    out = resize(img, width=1024 // factor, height=16 // factor, interpolation=interpolation)
    assert _leak(out, img) <= 0.03


@pytest.mark.parametrize(("factor", "freq"), [(2, 0.40), (4, 0.30)])
def test_aliasing_leak_bicubic_equals_pillow(factor, freq):
    # Keys' kernel (a = -0.5) stretched by the factor passes 3.3 % at 0.40 cycles/pixel when
    # halving (its frequency response there); Pillow's BICUBIC, the same filter, leaks the same.
    img = _sine(freq)
    out = resize(img, width=1024 // factor, height=16 // factor, interpolation="bicubic")
    ref = np.asarray(Image.fromarray(img.astype(np.float32), mode="F").resize(
        (1024 // factor, 16 // factor), Image.BICUBIC))
    assert abs(_leak(out, img) - _leak(ref, img)) < 1e-3
    assert _leak(out, img) <= (0.034 if factor == 2 else 0.03)


@pytest.mark.parametrize(("interpolation", "factor"), [("bicubic", 2), ("bicubic", 4), ("lanczos3", 2),
                                                       ("lanczos3", 4), ("bilinear", 2), ("area", 2)])
def test_passband(interpolation, factor):
    # 0.0625 cycles/pixel is well inside the new band: it must pass nearly untouched. (A
    # triangle stretched by 4 passes only sinc^2(1/4) = 0.81 of it: bilinear is not tested at 4.)
    img = _sine(0.0625)
    out = resize(img, width=1024 // factor, height=16 // factor, interpolation=interpolation)
    assert _leak(out, img) >= 0.9


def test_opencv_linear_aliases_for_contrast():
    img = _sine(0.40)
    out = cv2.resize(img, (512, 8), interpolation=cv2.INTER_LINEAR)
    assert _leak(out, img) > 0.2  # measured 0.31: why antialiasing matters


@pytest.mark.parametrize("interpolation", RESIZE_INTERPOLATIONS)
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
@pytest.mark.parametrize("size", [(13, 7), (97, 71), (40, 30)])
def test_constant_stays_constant(interpolation, dtype, size):
    img = np.full((30, 40, 3), 77, dtype=dtype)
    out = resize(img, width=size[0], height=size[1], interpolation=interpolation)
    assert out.dtype == img.dtype and out.shape == (size[1], size[0], 3)
    assert np.abs(out.astype(np.float64) - 77).max() <= (0 if np.dtype(dtype).kind == "u" else 1e-4)


def test_area_half_is_exact_mean():
    rng = np.random.default_rng(0)
    img = rng.uniform(0, 1, (30, 40, 2))
    out = resize(img, width=20, height=15, interpolation="area")
    expect = img.reshape(15, 2, 20, 2, 2).mean(axis=(1, 3))
    assert np.allclose(out, expect, atol=1e-14)
    u8 = rng.integers(0, 256, (30, 40), dtype=np.uint8)
    out8 = resize(u8, width=20, height=15, interpolation="area")
    # Float32 accumulation then round-half-up: within one level of the exact mean.
    assert np.abs(out8 - u8.reshape(15, 2, 20, 2).mean(axis=(1, 3))).max() <= 0.5 + 1e-4


def test_close_to_pillow_bicubic():
    rng = np.random.default_rng(1)
    img = (rng.uniform(0, 1, (60, 80, 3)) * 255).astype(np.uint8)
    img = cv2.GaussianBlur(img, (0, 0), 1.5)  # natural-image smoothness
    for size in [(40, 30), (120, 90), (33, 21)]:
        ours = resize(img, width=size[0], height=size[1]).astype(int)
        ref = np.asarray(Image.fromarray(img).resize(size, Image.BICUBIC)).astype(int)
        # Same kernel (Keys a = -0.5, stretched when shrinking); Pillow rounds in 8-bit fixed
        # point between passes.
        assert np.abs(ours - ref).max() <= 2


def test_weights_tables():
    starts, w = resize_weights(10, 5, "bilinear")
    assert np.allclose(w.sum(axis=1), 1.0)
    assert (starts >= 0).all() and (starts + w.shape[1] <= 10).all()
    starts, w = resize_weights(3, 100, "lanczos3")
    assert (starts + w.shape[1] <= 3).all()


def test_enlarging_interpolates_like_remap():
    from camkit.resample import remap

    rng = np.random.default_rng(2)
    img = rng.uniform(0, 1, (12, 16))
    out = resize(img, width=32, height=24, interpolation="bicubic")
    yy, xx = np.mgrid[0:24, 0:32]
    mp = np.stack([(xx + 0.5) / 2 - 0.5, (yy + 0.5) / 2 - 0.5], -1).astype(np.float64)
    ref = remap(img, mp, interpolation="bicubic", border="replicate")
    inner = (slice(4, -4), slice(4, -4))
    assert np.abs(out[inner] - ref[inner]).max() < 1e-6


def test_bad_input():
    img = np.zeros((10, 10))
    with pytest.raises(ParameterError, match="width: expected a positive integer"):
        resize(img, width=0, height=5)
    with pytest.raises(ParameterError, match="interpolation: expected one of"):
        resize(img, width=5, height=5, interpolation="cubic")


def _separable(img, h, w, interpolation="bicubic", bicubic_a=-0.5):
    """The resize written as two float64 matrix products from the weight tables (the
    reference the kernels must equal): rows of Ry and Rx hold each output's taps."""
    H, W = img.shape[:2]
    sy, wy = resize_weights(H, h, interpolation, bicubic_a=bicubic_a)
    sx, wx = resize_weights(W, w, interpolation, bicubic_a=bicubic_a)
    Ry = np.zeros((h, H))
    Rx = np.zeros((w, W))
    for j in range(h):
        Ry[j, sy[j]:sy[j] + wy.shape[1]] = wy[j]
    for j in range(w):
        Rx[j, sx[j]:sx[j] + wx.shape[1]] = wx[j]
    return np.einsum("yY,YXc,xX->yxc", Ry, img.astype(np.float64), Rx)


@pytest.mark.parametrize(("h", "w"), [(32, 32), (100, 90), (40, 150)])
def test_float64_images_are_filtered_in_float64(h, w):
    # The passes accumulate in float64 for float64 images: the result equals the separable
    # filter as two float64 matrix products (it once accumulated the vertical pass in
    # float32: errors of 5e-5 on values near 1000).
    rng = np.random.default_rng(3)
    img = rng.random((64, 64, 2)) + 1000.0
    out = resize(img, width=w, height=h, interpolation="bicubic")
    assert np.abs(out - _separable(img, h, w)).max() < 1e-9


# Each case compiles its own kernel (taps, channels and period are compile-time constants),
# so the grid is a cross, not a product: every method at 3/2 in RGB, bicubic at the other
# geometries, and bicubic at 3/2 with 1 and 4 channels.
_ENLARGE_CASES = ([(m, (40, 64, 60, 96), 3) for m in RESIZE_INTERPOLATIONS]
                  + [("bicubic", g, 3) for g in [(40, 64, 80, 160), (40, 64, 40, 72), (33, 41, 97, 57),
                                                 (40, 64, 40, 64)]]
                  + [("bicubic", (40, 64, 60, 96), c) for c in (1, 4)])


def _check_float64_and_uint8(img, h, w, interpolation="bicubic", uint8=True):
    """resize equals the separable reference: float64 to 1e-9, uint8 within rounding
    (0.5 + float32 error)."""
    out = resize(img, width=w, height=h, interpolation=interpolation)
    assert out.shape == (h, w, img.shape[2])
    assert np.abs(out - _separable(img, h, w, interpolation)).max() < 1e-9
    if uint8:
        u8 = (img * 255).round().astype(np.uint8)
        ref8 = np.clip(_separable(u8, h, w, interpolation), 0, 255)
        assert np.abs(resize(u8, width=w, height=h, interpolation=interpolation) - ref8).max() <= 0.5 + 1e-3


@pytest.mark.parametrize(("interpolation", "geometry", "C"), _ENLARGE_CASES)
def test_enlarging_matches_the_separable_filter(interpolation, geometry, C):
    # Widths 96/64 (3 outputs per 2 inputs), 160/64 (5/2), 72/64 (9/8: too many phases for the
    # polyphase path), 57/41 and 64/64: the polyphase path and the weight tables for the
    # others must both give the separable filter; uint8 checked on the benchmarked case
    # (RGB bicubic 3/2) only.
    H, W, h, w = geometry
    img = np.random.default_rng(4).random((H, W, C))
    _check_float64_and_uint8(img, h, w, interpolation, uint8=(interpolation, geometry, C) == _ENLARGE_CASES[2])


@pytest.mark.parametrize(("H", "W"), [(66, 64), (20, 34), (24, 100)])
def test_halving_matches_the_separable_filter(H, W):
    # The halving kernel makes two output rows per iteration where their input windows are
    # STEP rows apart (and one at a time near the borders and for an odd last row): 33 output
    # rows from 66 exercise all three. In RGB it splits each vertical sum into even and odd
    # pixels, 16 at a time (SIMD for float32) and the rest one by one: widths 64, 34 and 100
    # leave 16, 2 and 4 pixels for the scalar tail. uint8 RGB takes four rows per iteration
    # where their windows are STEP apart (6 of the 9 groups of 4 from 66 rows, 1 of 3 from 20
    # and from 24), summed 8 pixels at a time and stored split (widths 34 and 100 leave 2 and
    # 4 pixels to the scalar sums); its horizontal filter makes 8 values at a time (84, 39 and
    # 138 values between the border outputs: a rest of 4, 7 and 2).
    _check_float64_and_uint8(np.random.default_rng(5).random((H, W, 3)), H // 2, W // 2)


@njit(cache=True)
def _split(row, width, dst, odd_at):  # pragma: no cover - numba
    split_even_odd_c3(row, width, dst, odd_at)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("width", [1, 2, 16, 17, 18, 33, 50, 51, 67])
def test_even_odd_split_of_rgb_rows(dtype, width):
    # The split of the halving kernel: the SIMD blocks of 16 pixels (float32) and the scalar
    # rest must put pixel 2q at 3q and pixel 2q + 1 at odd_at + 3q, and write nothing else.
    row = np.arange(1, 3 * width + 1, dtype=dtype)
    n_even = (width + 1) // 2
    dst = np.full(3 * width + 5, -1.0, dtype)
    _split(row, width, dst, 3 * n_even)
    px = row.reshape(width, 3)
    assert np.array_equal(dst[:3 * n_even], px[0::2].ravel())
    assert np.array_equal(dst[3 * n_even:3 * width], px[1::2].ravel())
    assert np.all(dst[3 * width:] == -1.0)


@njit(cache=True)
def _vsum(src, s, w, eo, odd_at):  # pragma: no cover - numba
    return vertical_even_odd_c3(src, s, w, eo, odd_at, 8, 2, 4)


@pytest.mark.parametrize("width", [16, 37, 50])
@pytest.mark.parametrize("keys", [True, False])
def test_fused_vertical_sums_of_the_uint8_halving(width, keys):
    # Four rows of sums from 14 uint8 RGB rows, stored split into even and odd pixels. With
    # Keys' halving weights (a = -0.5, away from the borders) an AVX2 host sums exactly in
    # integers and stores the sums times 256 (16 pixels a block, the rest in scalar code:
    # widths 16, 37 and 50 leave 0, 5 and 2); other weights take the float sums, stored as
    # they are.
    rng = np.random.default_rng(7)
    src = rng.integers(0, 256, (16, 3 * width), dtype=np.uint8)
    taps = np.array(HALF_KEYS_256) / 256 if keys else rng.normal(0.0, 0.3, 8)
    w = np.tile(taps, (4, 1)).astype(np.float32)
    n_even = (width + 1) // 2
    eo = np.full((4, 3 * width), np.nan, np.float32)
    scale = _vsum(src, 1, w, eo, 3 * n_even)
    assert scale == (256.0 if keys and HAS_AVX2 else 1.0)
    for t in range(4):
        sums = (w[t].astype(np.float64) @ src[1 + 2 * t:9 + 2 * t].astype(np.float64)) * scale
        px = sums.reshape(width, 3)
        tol = 0.0 if scale == 256.0 else 1e-3  # integer sums are exact
        assert np.abs(eo[t, :3 * n_even] - px[0::2].ravel()).max() <= tol
        assert np.abs(eo[t, 3 * n_even:] - px[1::2].ravel()).max() <= tol


def test_uint8_halving_with_other_weights_matches_the_separable_filter():
    # a = -0.75: not Keys' a = -0.5 weights, so the uint8 RGB halving sums in float32
    img = (np.random.default_rng(8).random((66, 100, 3)) * 255).round().astype(np.uint8)
    out = resize(img, width=50, height=33, bicubic_a=-0.75)
    ref = np.clip(_separable(img, 33, 50, bicubic_a=-0.75), 0, 255)
    assert np.abs(out - ref).max() <= 0.5 + 1e-3


@pytest.mark.parametrize(("H", "W", "h", "w"), [(66, 64, 33, 64), (30, 64, 45, 32)])
def test_mixed_directions_match_the_separable_filter(H, W, h, w):
    # Shrinking rows with the width kept (the shrinking kernel with a step of 1, two rows per
    # iteration) and enlarging rows while halving the width (the enlarging kernel with one
    # phase every 2 inputs).
    _check_float64_and_uint8(np.random.default_rng(6).random((H, W, 3)), h, w, uint8=False)


_GENERIC = """
import sys
import numpy as np
from camkit._kernels.simd_resize import HAS_AVX2
from camkit.resample import resize
img = (np.random.default_rng(9).random((66, 100, 3)) * 255).round().astype(np.uint8)
np.save(sys.argv[1], resize(img, width=50, height=33))
print(HAS_AVX2)
"""


def test_halving_for_a_cpu_without_avx2(tmp_path):
    # numba compiling for a generic CPU (NUMBA_CPU_NAME=generic, as for caches shared between
    # machines) has no AVX2: the halving must leave out the integer sums' vpmaddwd there (LLVM
    # cannot select it: the process would abort) and give the same image within rounding.
    env = dict(os.environ, NUMBA_CPU_NAME="generic", NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    out = tmp_path / "out.npy"
    run = subprocess.run([sys.executable, "-c", _GENERIC, str(out)], env=env, capture_output=True, text=True,
                         timeout=900)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip().splitlines()[-1] == "False"
    img = (np.random.default_rng(9).random((66, 100, 3)) * 255).round().astype(np.uint8)
    here = resize(img, width=50, height=33)
    assert np.abs(np.load(out).astype(int) - here).max() <= 1
