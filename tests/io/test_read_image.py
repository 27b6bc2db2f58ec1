"""Image reading: every supported PNG/TIFF/PNM variant agrees with what Pillow or OpenCV wrote;
damaged and unsupported files give a named ImageFileError."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from PIL import Image

from camkit.io import ImageFileError, read_image, write_png

RNG = np.random.default_rng(7)
# A smooth image plus noise, so every PNG filter type and LZW code-width change is exercised.
_yy, _xx = np.mgrid[0:61, 0:97]
GREY = ((_xx * 2 + _yy) % 256 + RNG.integers(0, 3, _xx.shape)).clip(0, 255).astype(np.uint8)
RGB = np.stack([GREY, 255 - GREY, (GREY // 2 + 60)], axis=-1).astype(np.uint8)
NOISE = RNG.integers(0, 256, (300, 257), dtype=np.uint8)


@pytest.mark.parametrize("img", [GREY, RGB, NOISE], ids=["grey", "rgb", "noise"])
@pytest.mark.parametrize("compression", [None, "tiff_lzw", "packbits", "tiff_deflate"])
def test_tiff_from_pillow(tmp_path, img, compression):
    path = tmp_path / "a.tif"
    Image.fromarray(img).save(path, compression=compression)
    assert np.array_equal(read_image(path), img)


@pytest.mark.parametrize("img", [GREY, RGB])
def test_tiff_lzw_with_predictor_and_tiles_from_opencv(tmp_path, img):
    path = str(tmp_path / "b.tif")
    bgr = img[:, :, ::-1] if img.ndim == 3 else img
    cv2.imwrite(path, bgr)  # OpenCV writes LZW with the horizontal predictor
    assert np.array_equal(read_image(path), img)


def test_tiff_16bit_big_endian(tmp_path):
    img = (GREY.astype(np.uint16) * 257 + 3)
    path = tmp_path / "c.tif"
    Image.frombytes("I;16B", img.shape[::-1], img.astype(">u2").tobytes()).save(path)
    assert np.array_equal(read_image(path), img)
    path2 = str(tmp_path / "d.tif")
    cv2.imwrite(path2, img)
    out = read_image(path2)
    assert out.dtype == np.uint16 and np.array_equal(out, img)


@pytest.mark.parametrize("mode", ["L", "RGB", "RGBA", "LA", "P", "1", "I;16"])
def test_png_from_pillow(tmp_path, mode):
    src = Image.fromarray(RGB).convert(mode) if mode != "I;16" else Image.fromarray(GREY.astype(np.uint16) * 200)
    path = tmp_path / "a.png"
    src.save(path)
    expected = np.asarray(src.convert("RGB") if mode == "P" else src)
    if mode == "1":
        expected = expected.astype(np.uint8) * 255
    assert np.array_equal(read_image(path), expected)


def test_png_optimised_filters_and_16bit_rgb(tmp_path):
    path = tmp_path / "o.png"
    Image.fromarray(RGB).save(path, optimize=True)  # Pillow then picks the filter per row
    assert np.array_equal(read_image(path), RGB)
    img16 = RNG.integers(0, 65536, (20, 30, 3)).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "p.png"), img16[:, :, ::-1])
    assert np.array_equal(read_image(tmp_path / "p.png"), img16)
    assert np.array_equal(read_image(write_png(tmp_path / "q.png", img16)), img16)


@pytest.mark.parametrize("ext,img", [(".pgm", GREY), (".ppm", RGB)])
def test_pnm(tmp_path, ext, img):
    path = tmp_path / f"a{ext}"
    Image.fromarray(img).save(path)
    assert np.array_equal(read_image(path), img)


def test_real_tiff(shared_data):
    img = read_image(shared_data / "bouguet_calib_example" / "Image1.tif")
    assert img.shape == (480, 640) and img.dtype == np.uint8
    assert np.array_equal(img, np.asarray(Image.open(shared_data / "bouguet_calib_example" / "Image1.tif")))


@pytest.mark.parametrize("content,match", [
    (b"", "not an image"),
    (b"hello world", "not an image"),
    (b"\xff\xd8\xff\xe0 jpeg", "JPEG"),
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR", "damaged"),
    (b"II*\x00\x08\x00\x00\x00\x00", "damaged"),
    (b"P5 10 10 255\n\x00", "cut short"),
])
def test_bad_files(tmp_path, content, match):
    path = tmp_path / "bad.png"
    path.write_bytes(content)
    with pytest.raises(ImageFileError, match=match) as info:
        read_image(path)
    assert "bad.png" in str(info.value)


def test_truncated_real_files(tmp_path):
    for name, save in (("t.png", lambda p: Image.fromarray(RGB).save(p)),
                       ("t.tif", lambda p: Image.fromarray(RGB).save(p, compression="tiff_lzw"))):
        p = tmp_path / name
        save(p)
        p.write_bytes(p.read_bytes()[: len(p.read_bytes()) * 2 // 3])
        with pytest.raises(ImageFileError, match=r"damaged|cut short"):
            read_image(p)


def test_missing_file(tmp_path):
    with pytest.raises(ImageFileError, match="cannot read"):
        read_image(tmp_path / "nope.png")


def test_tiled_tiff_built_by_hand(tmp_path):
    """A tiled, uncompressed grey TIFF (TIFF 6.0 sec. 15), written byte by byte here: 40x23
    pixels in 16x16 tiles, so the right and bottom tiles are padded."""
    import struct

    h, w, t = 23, 40, 16
    img = GREY[:h, :w]
    across, down = -(-w // t), -(-h // t)
    padded = np.zeros((down * t, across * t), np.uint8)
    padded[:h, :w] = img
    tiles = [padded[y * t:(y + 1) * t, x * t:(x + 1) * t].tobytes() for y in range(down) for x in range(across)]
    n_tags, n_tiles = 10, len(tiles)
    ifd = 8
    extra = ifd + 2 + 12 * n_tags + 4
    off_offsets, off_counts = extra, extra + 4 * n_tiles
    data_start = off_counts + 4 * n_tiles
    offsets = [data_start + t * t * k for k in range(n_tiles)]
    entries = [(256, 4, 1, w), (257, 4, 1, h), (258, 3, 1, 8), (259, 3, 1, 1), (262, 3, 1, 1), (277, 3, 1, 1),
               (322, 4, 1, t), (323, 4, 1, t), (324, 4, n_tiles, off_offsets), (325, 4, n_tiles, off_counts)]
    out = b"II*\x00" + struct.pack("<I", ifd) + struct.pack("<H", n_tags)
    for tag, typ, count, value in entries:
        out += struct.pack("<HHII", tag, typ, count, value) if typ == 4 else struct.pack("<HHIHH", tag, typ, count,
                                                                                          value, 0)
    out += struct.pack("<I", 0)
    out += struct.pack(f"<{n_tiles}I", *offsets) + struct.pack(f"<{n_tiles}I", *[t * t] * n_tiles)
    out += b"".join(tiles)
    (tmp_path / "tiled.tif").write_bytes(out)
    assert np.array_equal(np.asarray(Image.open(tmp_path / "tiled.tif")), img)  # the oracle agrees it is valid
    assert np.array_equal(read_image(tmp_path / "tiled.tif"), img)


def test_path_must_be_a_name():
    with pytest.raises(ImageFileError, match="path: expected a file name"):
        read_image(123)
