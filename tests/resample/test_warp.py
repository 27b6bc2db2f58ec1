"""Warps: identity, agreement with remap through the equivalent map, OpenCV as oracle."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from camkit.errors import ParameterError
from camkit.resample import remap, warp_affine, warp_perspective

RNG = np.random.default_rng(99)
IMG = RNG.integers(0, 256, (90, 120, 3), dtype=np.uint8)
A = np.array([[0.9, 0.12, 5.0], [-0.08, 1.05, -3.0]])
HOM = np.array([[0.95, 0.05, 4.0], [-0.03, 1.02, 2.0], [2e-4, -1e-4, 1.0]])


def _grid(h, w):
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    return np.stack([xx, yy, np.ones_like(xx)], -1)


@pytest.mark.parametrize("dtype", [np.uint8, np.float32])
@pytest.mark.parametrize("method", ["nearest", "bilinear", "bicubic", "lanczos3"])
def test_warps_equal_remap_with_the_equivalent_map(dtype, method):
    img = IMG.astype(dtype)
    inv = np.linalg.inv(np.vstack([A, [0, 0, 1]]))
    mp = (_grid(80, 100) @ inv.T)[..., :2]
    tol = 1 if dtype == np.uint8 else 1e-4
    ours = warp_affine(img, A, width=100, height=80, interpolation=method).astype(np.float64)
    assert np.abs(ours - remap(img, mp, interpolation=method)).max() <= tol
    invh = np.linalg.inv(HOM)
    q = _grid(80, 100) @ invh.T
    mp = q[..., :2] / q[..., 2:]
    ours = warp_perspective(img, HOM, width=100, height=80, interpolation=method).astype(np.float64)
    assert np.abs(ours - remap(img, mp, interpolation=method)).max() <= tol


def test_identity():
    assert np.array_equal(warp_affine(IMG, [[1, 0, 0], [0, 1, 0]], width=120, height=90), IMG)
    assert np.array_equal(warp_perspective(IMG, np.eye(3) * 2.0, width=120, height=90), IMG)


def test_agrees_with_opencv():
    ours = warp_affine(IMG, A, width=100, height=80)
    ref = cv2.warpAffine(IMG, A, (100, 80), flags=cv2.INTER_LINEAR)
    assert np.abs(ours.astype(int) - ref).max() <= 1
    ours = warp_perspective(IMG, HOM, width=100, height=80)
    ref = cv2.warpPerspective(IMG, HOM, (100, 80), flags=cv2.INTER_LINEAR)
    assert np.abs(ours.astype(int) - ref).max() <= 1


def test_beyond_the_horizon_is_fill():
    # A strong perspective puts part of the output's preimage behind the horizon (w <= 0).
    H = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0.02, 1.0]])
    out = warp_perspective(IMG.astype(np.float64), H, width=120, height=200, fill_value=-1)
    assert (out[-1] == -1).all()


def test_bad_input():
    with pytest.raises(ParameterError, match="A: expected an invertible affine map"):
        warp_affine(IMG, [[1, 2, 0], [2, 4, 0]], width=10, height=10)
    with pytest.raises(ParameterError, match="H: expected an invertible homography"):
        warp_perspective(IMG, np.zeros((3, 3)), width=10, height=10)
    with pytest.raises(ParameterError, match="width: expected a positive integer"):
        warp_affine(IMG, A, width=0, height=10)
    with pytest.raises(ValueError, match="A: expected shape"):
        warp_affine(IMG, np.eye(3), width=10, height=10)


@pytest.mark.parametrize("border", ["constant", "replicate", "reflect"])
def test_uint8_rgb_bilinear_fast_path_far_from_the_origin(border):
    # The uint8 RGB bilinear kernel computes warped positions in float32 and handles the
    # pixels needing border rules in a second pass: at 4000 px it must still agree with the
    # float64 path (the same warp of the image as float64, rounded) within 1 level. An output
    # 3997 wide: the second pass scans its marks 8 at a time, and 5 are left over.
    img = RNG.integers(0, 256, (160, 4000, 3), dtype=np.uint8)
    hom = np.array([[1.01, 0.02, -30.0], [0.01, 0.97, 6.0], [3e-6, 2e-5, 1.0]])
    aff = np.array([[0.999, 0.004, 12.5], [-0.003, 1.02, -4.25]])
    for warp, m in ((warp_perspective, hom), (warp_affine, aff)):
        ours = warp(img, m, width=3997, height=160, border=border, fill_value=(1, 2, 3))
        ref = warp(img.astype(np.float64), m, width=3997, height=160, border=border, fill_value=(1, 2, 3))
        assert np.abs(ours - np.clip(np.floor(ref + 0.5), 0, 255)).max() <= 1
        if border == "constant":  # both kinds of pixel are there: inside, and the fill value
            filled = (ours == [1, 2, 3]).all(axis=-1).mean()
            assert 0.001 < filled < 0.5


def test_uint8_rgb_beyond_the_horizon_is_fill():
    H = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0.02, 1.0]])
    out = warp_perspective(IMG, H, width=120, height=200, fill_value=(9, 8, 7))
    assert (out[-1] == [9, 8, 7]).all()
