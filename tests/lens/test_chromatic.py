"""Lateral chromatic aberration: exact inverse, simulate then correct, bad coefficients."""

from __future__ import annotations

import numpy as np
import pytest

from camkit.errors import ParameterError, ShapeError
from camkit.lens import LateralChromaticAberration
from camkit.resample import apply_chromatic, correct_chromatic

TCA = LateralChromaticAberration(vr=1.0008, cr=2e-4, br=3e-4, vb=0.9993, cb=-1e-4, bb=-2e-4, cx=330.0, cy=250.0)


@pytest.mark.parametrize("channel", ["red", "blue"])
def test_inverse_map_is_exact(channel):
    # Forward(inverse(p)) = p: the simulated position, magnified again, lands back on p.
    W, H = 640, 480
    inv = TCA.map(channel, W, H, inverse=True, dtype=np.float64)
    v, c, b = (TCA.vr, TCA.cr, TCA.br) if channel == "red" else (TCA.vb, TCA.cb, TCA.bb)
    norm = np.hypot(W, H) / 2
    d = inv - [TCA.cx, TCA.cy]
    r = np.hypot(d[..., 0], d[..., 1]) / norm
    fwd = np.array([TCA.cx, TCA.cy]) + d * (v + c * r + b * r * r)[..., None]
    yy, xx = np.mgrid[0:H, 0:W]
    err = np.hypot(fwd[..., 0] - xx, fwd[..., 1] - yy).max()
    assert err <= 0.01  # the promise
    assert err <= 1e-9  # what the Newton solve actually reaches


def test_magnification_direction():
    # Red magnified by vr > 1: a point green sees at radius 200 px appears further out in red.
    m = TCA.map("red", 640, 480)  # correction map: where red put the point
    d = m[250, 530] - [330.0, 250.0]
    assert d[0] > 200.0


def test_apply_then_correct_restores_a_smooth_image():
    H, W = 240, 320
    yy, xx = np.mgrid[0:H, 0:W] / 40.0
    img = np.stack([np.sin(xx) * np.cos(yy), np.cos(xx + yy), np.sin(xx - yy)], axis=-1) * 0.4 + 0.5
    tca = LateralChromaticAberration(vr=1.004, vb=0.996)
    sim = apply_chromatic(img, tca)
    assert np.abs(sim[..., 0] - img[..., 0]).max() > 1e-3  # the aberration is visible
    assert np.array_equal(sim[..., 1], img[..., 1])  # green is the reference
    back = correct_chromatic(sim, tca)
    inner = (slice(8, -8), slice(8, -8))
    # Two bicubic resamplings of a smooth image: 1e-4 of the value range.
    assert np.abs(back[inner] - img[inner]).max() < 1e-4


def test_uint8_and_rgba():
    img = np.random.default_rng(0).integers(0, 256, (50, 60, 4), dtype=np.uint8)
    out = apply_chromatic(img, TCA)
    assert out.dtype == np.uint8 and out.shape == img.shape
    assert np.array_equal(out[..., 3], img[..., 3])


def test_bad_input():
    with pytest.raises(ParameterError, match="vr: expected a positive scale"):
        LateralChromaticAberration(vr=0.0)
    with pytest.raises(ParameterError, match="cb: expected a finite"):
        LateralChromaticAberration(cb=float("nan"))
    with pytest.raises(ParameterError, match="fold over"):
        LateralChromaticAberration(vr=1.0, br=-1.0).map("red", 100, 100)
    with pytest.raises(ParameterError, match="channel: expected one of"):
        TCA.map("green", 10, 10)
    with pytest.raises(ShapeError, match="image: expected an RGB"):
        apply_chromatic(np.zeros((10, 10)), TCA)


def test_the_aberration_argument_is_checked():
    with pytest.raises(ParameterError, match="aberration: expected a LateralChromaticAberration"):
        apply_chromatic(np.zeros((10, 10, 3)), (1.001, 0.999))
