"""CFA and demosaicing: sampled sites kept, flat colours right for every pattern, agreement
with colour-demosaicing (Bilinear, Malvar2004, Menon2007) as oracle, bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from camkit.errors import ParameterError, ShapeError
from camkit.sensor import DEMOSAIC_METHODS, PATTERNS, cfa_masks, demosaic, mosaic, three_layer

RNG = np.random.default_rng(5)


def _import_colour_demosaicing():
    """Import the oracle, undoing the change of NumPy's global print options that importing
    'colour' makes (it would alter every later doctest's output in this process)."""
    opts = np.get_printoptions()
    import colour_demosaicing

    np.set_printoptions(**opts)
    return colour_demosaicing


def _smooth_rgb(h=48, w=64):
    yy, xx = np.mgrid[0:h, 0:w] / 9.0
    return np.stack([np.sin(xx) * 0.3 + 0.5, np.cos(yy + xx / 2) * 0.3 + 0.5, np.sin(yy) * 0.3 + 0.5], -1)


@pytest.mark.parametrize("pattern", PATTERNS)
@pytest.mark.parametrize("method", DEMOSAIC_METHODS)
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
def test_sampled_sites_are_kept(pattern, method, dtype):
    if np.dtype(dtype).kind == "u":
        raw = RNG.integers(0, np.iinfo(dtype).max, (30, 41), endpoint=True).astype(dtype)
    else:
        raw = RNG.uniform(0, 1, (30, 41)).astype(dtype)
    rgb = demosaic(raw, pattern, method)
    assert rgb.dtype == raw.dtype and rgb.shape == (30, 41, 3)
    assert np.array_equal(mosaic(rgb, pattern), raw)


@pytest.mark.parametrize("pattern", PATTERNS)
@pytest.mark.parametrize("method", DEMOSAIC_METHODS)
def test_flat_colour_patches(pattern, method):
    # A flat colour is reconstructed exactly by every method and pattern (no colour swap).
    for colour in ([0.8, 0.2, 0.1], [0.1, 0.7, 0.3], [0.2, 0.3, 0.9]):
        rgb = np.broadcast_to(np.array(colour), (20, 24, 3)).copy()
        out = demosaic(mosaic(rgb, pattern), pattern, method)
        assert np.allclose(out, rgb, atol=1e-12)
        u8 = (rgb * 255).round().astype(np.uint8)
        assert np.array_equal(demosaic(mosaic(u8, pattern), pattern, method), u8)


def test_masks_and_mosaic():
    m = cfa_masks(4, 4, "GBRG")
    assert m.sum(axis=-1).tolist() == np.ones((4, 4)).tolist()
    assert m[0, 0, 1] and m[0, 1, 2] and m[1, 0, 0] and m[1, 1, 1]
    assert m[..., 1].sum() == 8  # half the sites are green
    assert cfa_masks(2, 3, "three-layer").all()
    rgb = _smooth_rgb()
    assert np.array_equal(three_layer(rgb), rgb)
    raw = mosaic(rgb, "BGGR")
    assert raw[0, 0] == rgb[0, 0, 2] and raw[1, 1] == rgb[1, 1, 0] and raw[0, 1] == rgb[0, 1, 1]


@pytest.mark.parametrize(("method", "oracle"), [("bilinear", "demosaicing_CFA_Bayer_bilinear"),
                                                ("malvar", "demosaicing_CFA_Bayer_Malvar2004"),
                                                ("menon", "demosaicing_CFA_Bayer_Menon2007")])
def test_agrees_with_colour_demosaicing(method, oracle):
    cd = _import_colour_demosaicing()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rgb = _smooth_rgb(60, 80)
        rgb[20:40, 30:50] = [0.9, 0.1, 0.2]  # an edge for the directional method to find
        for pattern in PATTERNS:
            raw = mosaic(rgb, pattern)
            ref = getattr(cd, oracle)(raw, pattern)
            ours = demosaic(raw, pattern, method)
            inner = (slice(4, -4), slice(4, -4))
            if method == "menon":
                # Same algorithm; near-tie direction decisions may flip with summation order:
                # compare the reconstruction error instead of every pixel.
                e_ours = np.mean((ours[inner] - rgb[inner]) ** 2)
                e_ref = np.mean((ref[inner] - rgb[inner]) ** 2)
                assert e_ours <= e_ref * 1.01
                assert np.mean(np.abs(ours[inner] - ref[inner]) > 1e-9) < 0.01
            else:
                assert np.allclose(ours[inner], ref[inner], atol=1e-12)


def test_quality_order_on_a_textured_image():
    rgb = _smooth_rgb(96, 128)
    rgb[::8] *= 0.6  # stripes: edges along x
    raw = mosaic(rgb, "RGGB")
    err = {m: np.mean((demosaic(raw, "RGGB", m) - rgb)[4:-4, 4:-4] ** 2) for m in DEMOSAIC_METHODS}
    assert err["menon"] < err["malvar"] < err["bilinear"]


@pytest.mark.parametrize(
    ("call", "exc", "needle"),
    [
        (lambda: demosaic(np.zeros((4, 4, 3))), ShapeError, "raw: expected a single-channel mosaic"),
        (lambda: demosaic(np.zeros((1, 4))), ShapeError, "raw: expected at least 2x2"),
        (lambda: demosaic(np.zeros((4, 4), np.int16)), ShapeError, "raw: expected dtype"),
        (lambda: demosaic(np.zeros((4, 4)), "RGBG"), ParameterError, "pattern: expected one of"),
        (lambda: demosaic(np.zeros((4, 4)), method="vng"), ParameterError, "method: expected one of"),
        (lambda: mosaic(np.zeros((4, 4))), ShapeError, "rgb: expected"),
        (lambda: cfa_masks(0, 4, "RGGB"), ParameterError, "height: expected a positive integer"),
    ],
)
def test_bad_input(call, exc, needle):
    with pytest.raises(exc) as info:
        call()
    assert needle in str(info.value)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("shape", [(2, 2), (2, 3), (3, 4), (4, 5), (7, 9), (31, 40)])
def test_integer_kernels_equal_the_float_formulas(dtype, shape):
    # The integer fast paths (branch-free passes per Bayer phase, weights x 16) must give exactly
    # the float formulas' round-half-up result, borders included.
    from camkit._kernels import demosaic as demosaic_kernels
    from camkit.sensor.cfa import pattern_code

    rng = np.random.default_rng(shape[0] * 100 + shape[1])
    hi = np.iinfo(dtype).max
    for pattern in ("RGGB", "BGGR", "GRBG", "GBRG"):
        raw = rng.integers(0, hi + 1, shape).astype(dtype)
        for method, kernel in (("bilinear", demosaic_kernels.bilinear), ("malvar", demosaic_kernels.malvar)):
            ref = np.empty((*shape, 3), dtype)
            kernel(raw, pattern_code(pattern), True, float(hi), ref)
            assert np.array_equal(demosaic(raw, pattern, method=method), ref), (pattern, method)


@pytest.mark.parametrize("dtype", [np.uint8, np.float32, np.float64])
def test_menon_strips_agree_with_one_pass(dtype):
    # The streaming kernel cuts the image into horizontal strips (min(H // 64, 8) of them) and
    # starts each strip's pipeline early; the rows must not depend on where the cuts fall.
    # The 256-row image runs as 4 strips, its top 128 rows as 2 and its top 64 as 1; away
    # from the cropped images' bottom border (each stage reaches ~10 rows) all agree exactly.
    rng = np.random.default_rng(7)
    rgb = _smooth_rgb(256, 90)
    rgb = np.clip(rgb + 0.05 * rng.standard_normal(rgb.shape), 0, 1)
    raw = mosaic(rgb, "GRBG")
    raw = (raw * 255).round().astype(np.uint8) if dtype == np.uint8 else raw.astype(dtype)
    full = demosaic(raw, "GRBG", "menon")
    for rows in (128, 64):
        part = demosaic(raw[:rows], "GRBG", "menon")
        assert np.array_equal(part[: rows - 16], full[: rows - 16]), rows
