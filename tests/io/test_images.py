"""PNG writing: Pillow reads back exactly what was written; writes are atomic."""

from __future__ import annotations

import os

import cv2
import numpy as np
import pytest
from PIL import Image

from camkit.errors import ShapeError
from camkit.io import write_png


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("shape", [(7, 11), (7, 11, 2), (7, 11, 3), (7, 11, 4), (1, 1)])
def test_round_trip_through_pillow(tmp_path, dtype, shape):
    img = np.random.default_rng(0).integers(0, np.iinfo(dtype).max, shape, endpoint=True).astype(dtype)
    path = write_png(tmp_path / "a.png", img)
    if dtype == np.uint16 and len(shape) == 3 and shape[2] >= 3:
        # Pillow reads 16-bit colour as 8-bit; OpenCV keeps the depth (in BGR(A) order).
        bgr = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        back = np.concatenate([bgr[:, :, 2::-1], bgr[:, :, 3:]], axis=2)
    elif dtype == np.uint16 and len(shape) == 3:
        pytest.skip("neither oracle reads 16-bit grey+alpha PNG; tests/io/test_read_image.py round-trips it")
    else:
        back = np.asarray(Image.open(path))
    assert back.shape == img.shape and np.array_equal(back.astype(np.int64), img.astype(np.int64))


def test_replaces_atomically_and_leaves_no_temporary(tmp_path):
    p = tmp_path / "x.png"
    write_png(p, np.zeros((4, 4), np.uint8))
    write_png(p, np.full((4, 4), 9, np.uint8))
    assert np.asarray(Image.open(p)).max() == 9
    assert sorted(os.listdir(tmp_path)) == ["x.png"]
    assert (p.stat().st_mode & 0o777) == 0o666 & ~_umask()


def test_a_missing_folder_is_named_not_the_temporary_file(tmp_path):
    """The write goes through a temporary file beside the target; where the folder does not
    exist, the error names the file asked for and its folder (it named the temporary file)."""
    target = tmp_path / "absent" / "x.png"
    with pytest.raises(FileNotFoundError, match=rf"{target}: cannot write: the folder {target.parent} does not "
                                                r"exist$") as info:
        write_png(target, np.zeros((4, 4), np.uint8))
    assert ".x.png." not in str(info.value)


def _umask():
    m = os.umask(0)
    os.umask(m)
    return m


def test_bad_input_leaves_the_old_file(tmp_path):
    p = tmp_path / "keep.png"
    write_png(p, np.zeros((4, 4), np.uint8))
    before = p.read_bytes()
    with pytest.raises(ShapeError, match="image: expected uint8 or uint16"):
        write_png(p, np.zeros((4, 4)))
    with pytest.raises(ShapeError, match=r"image: expected shape \(H, W\) or \(H, W, C\) with C in 1..4"):
        write_png(p, np.zeros((4, 4, 5), np.uint8))
    assert p.read_bytes() == before
