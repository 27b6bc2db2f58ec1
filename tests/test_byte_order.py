"""Arrays in big-endian byte order (FITS files, np.frombuffer(..., ">u2"), data from another
machine) give the same results as native ones: numba's kernels cannot type them, and each
public path used to fail inside a kernel with a TypingError."""

from __future__ import annotations

import numpy as np
import pytest

from camkit import resample, sensor
from camkit.render import default_camera, plan_views, render_checkerboard
from camkit.target import Checkerboard

BOARD = Checkerboard(7, 5, 0.03)


@pytest.fixture(scope="module")
def photo() -> np.ndarray:
    cam = default_camera("brown-conrady")
    pose = plan_views(cam, BOARD, 1, np.random.default_rng(2))[0]
    return render_checkerboard(cam, pose, BOARD)[0]


def _swapped(a: np.ndarray) -> np.ndarray:
    out = a.astype(a.dtype.newbyteorder(">" if a.dtype.byteorder in "=<" else "<"))
    assert not out.dtype.isnative and np.array_equal(out, a)
    return out


@pytest.mark.parametrize("dtype", [np.uint16, np.float32, np.float64])
def test_every_image_path_takes_the_other_byte_order(photo, dtype):
    img = (photo * (65535 if dtype == np.uint16 else 1)).astype(dtype)
    h, w = img.shape[:2]
    grid = np.dstack(np.meshgrid(np.arange(w) * 0.97 + 2.0, np.arange(h) * 1.01 + 0.5))
    calls = {
        "detect": lambda x: BOARD.detect(x).corners,
        "resize": lambda x: resample.resize(x, width=w // 2, height=h // 2),
        "warp_affine": lambda x: resample.warp_affine(x, [[0.9, 0.1, 3.0], [-0.1, 0.9, 5.0]], width=w, height=h),
        "remap": lambda x: resample.remap(x, grid),
        "demosaic": lambda x: sensor.demosaic(x, "RGGB"),
    }
    for name, call in calls.items():
        want = call(img)
        got = call(_swapped(img))
        np.testing.assert_array_equal(got, want, err_msg=name)
    np.testing.assert_array_equal(resample.remap(img, _swapped(grid)), resample.remap(img, grid))
    assert BOARD.detect(_swapped(img)).found
