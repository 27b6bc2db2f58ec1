"""Image reading: every supported variant agrees with what Pillow, OpenCV or tifffile wrote (the
oracles); damaged and unsupported files give a named ImageFileError (tests/io/test_hostile_files.py
holds the hostile corpus and the fuzzing)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from PIL import Image

from camkit.errors import ParameterError, ShapeError
from camkit.io import ImageFileError, read_image, read_image_and_info, read_image_info, write_image, write_png

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
    (b"", "empty"),
    (b"hello world", "not an image"),
    (b"\xff\xd8\xff\xe0 jpeg", "damaged JPEG"),
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR", "damaged PNG"),
    (b"II*\x00\x08\x00\x00\x00\x00", "damaged"),
    (b"P5 10 10 255\n\x00", "damaged PPM"),
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
        for read in (read_image, read_image_and_info):
            with pytest.raises(ImageFileError, match=r"damaged"):
                read(p)


def test_missing_file(tmp_path):
    for read in (read_image, read_image_and_info):
        with pytest.raises(ImageFileError, match=r"nope\.png: cannot read the file"):
            read(tmp_path / "nope.png")


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


# -- the formats cameras and phones write, through their oracles --------------------------------


@pytest.mark.parametrize("fmt,ext,exact", [("JPEG", ".jpg", False), ("BMP", ".bmp", True),
                                           ("WEBP", ".webp", True), ("PNG", ".png", True)])
@pytest.mark.parametrize("img", [GREY, RGB], ids=["grey", "rgb"])
def test_pillow_formats_agree_with_pillow(tmp_path, fmt, ext, exact, img):
    if fmt == "WEBP" and img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)  # WebP stores colour only
    path = tmp_path / ("A" + ext.upper())  # suffixes in any case
    kwargs = {"quality": 90} if fmt == "JPEG" else ({"lossless": True} if fmt == "WEBP" else {})
    Image.fromarray(img).save(path, format=fmt, **kwargs)
    out = read_image(path)
    oracle = np.asarray(Image.open(path))
    assert out.dtype == np.uint8 and out.shape == img.shape
    assert np.array_equal(out, oracle)
    if exact:
        assert np.array_equal(out, img)
    else:  # JPEG at quality 90 on a smooth image: within a few grey levels of the original
        assert np.abs(out.astype(int) - img).mean() < 3.0


def test_jpeg_agrees_with_opencv(tmp_path):
    """Pillow and OpenCV both decode with libjpeg(-turbo); their pixels agree within 1 level
    (they may differ in the chroma upsampling rounding)."""
    path = tmp_path / "cv.jpg"
    cv2.imwrite(str(path), RGB[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 85])
    ours = read_image(path).astype(int)
    theirs = cv2.imread(str(path), cv2.IMREAD_COLOR)[:, :, ::-1].astype(int)
    assert ours.shape == theirs.shape and np.abs(ours - theirs).max() <= 1


def test_cmyk_jpeg_becomes_rgb(tmp_path):
    path = tmp_path / "cmyk.jpg"
    Image.fromarray(RGB).convert("CMYK").save(path, quality=95)
    out = read_image(path)
    assert out.shape == RGB.shape and out.dtype == np.uint8


def test_16bit_colour_png_and_tiff_keep_16_bits(tmp_path):
    """Pillow reads 16-bit colour as 8 bits: camkit must not (OpenCV is the oracle)."""
    img16 = RNG.integers(0, 65536, (20, 30, 3)).astype(np.uint16)
    for ext in (".png", ".tif"):
        path = str(tmp_path / f"c16{ext}")
        cv2.imwrite(path, img16[:, :, ::-1])
        out = read_image(path)
        assert out.dtype == np.uint16 and np.array_equal(out, img16), ext


def test_float_tiff_through_tifffile(tmp_path):
    import tifffile

    f = RNG.random((9, 13, 3)).astype(np.float32)
    tifffile.imwrite(tmp_path / "f.tif", f, photometric="rgb", compression="zlib")
    out = read_image(tmp_path / "f.tif")
    assert out.dtype == np.float32 and np.array_equal(out, f)


def test_palette_and_white_is_zero_tiff(tmp_path):
    Image.fromarray(RGB).convert("P").save(tmp_path / "p.tif")
    assert np.array_equal(read_image(tmp_path / "p.tif"), np.asarray(Image.open(tmp_path / "p.tif").convert("RGB")))
    import tifffile

    tifffile.imwrite(tmp_path / "w.tif", GREY, photometric="miniswhite")
    assert np.array_equal(read_image(tmp_path / "w.tif"), 255 - GREY)


def test_max_pixels_is_settable(tmp_path):
    path = tmp_path / "a.png"
    Image.fromarray(GREY).save(path)
    with pytest.raises(ImageFileError, match=r"a.png: 97x61 .* over the limit"):
        read_image(path, max_pixels=1000)
    assert read_image(path, max_pixels=97 * 61).shape == GREY.shape
    with pytest.raises(ParameterError, match="max_pixels: expected a positive integer"):
        read_image(path, max_pixels=0)


def test_image_info_and_exif(tmp_path):
    """EXIF as a phone writes it: orientation 6 (turned 90 degrees), make, model, lens and focal
    lengths; the pixels come as stored, not turned."""
    exif = Image.Exif()
    exif[0x0112] = 6
    exif[0x010F] = "Camkit"
    exif[0x0110] = "Phone 1"
    sub = exif.get_ifd(0x8769)
    sub[0xA434] = "back camera 4.25mm f/1.8"
    sub[0x920A] = 4.25
    sub[0xA405] = 26
    path = tmp_path / "phone.jpg"
    Image.fromarray(RGB).save(path, exif=exif, quality=95)
    info = read_image_info(path)
    assert (info.format, info.width, info.height, info.orientation) == ("JPEG", 97, 61, 6)
    assert (info.make, info.model, info.lens) == ("Camkit", "Phone 1", "back camera 4.25mm f/1.8")
    assert info.focal_length_mm == pytest.approx(4.25) and info.focal_length_35mm == 26
    assert info.exif_dict()["orientation"] == 6
    assert read_image(path).shape == RGB.shape  # stored grid, not the displayed one
    both_img, both_info = read_image_and_info(path)  # one read of the file, the same two answers
    assert np.array_equal(both_img, read_image(path)) and both_info == info
    bare = tmp_path / "bare.png"
    Image.fromarray(GREY).save(bare)
    info = read_image_info(bare)
    assert info.orientation == 1 and info.make is None and info.exif_dict() == {}


# -- camera RAW ---------------------------------------------------------------------------------


def test_dng_mosaic_pattern_and_levels(tmp_path, dng_writer):
    pytest.importorskip("rawpy", reason="camera RAW needs the optional extra camkit[raw] (rawpy)")
    from camkit.io import read_raw

    mosaic = RNG.integers(64, 4000, (32, 48)).astype(np.uint16)
    for cfa, name in (((0, 1, 1, 2), "RGGB"), ((1, 0, 2, 1), "GRBG"), ((2, 1, 1, 0), "BGGR")):
        path = tmp_path / f"{name}.DNG"
        dng_writer(path, mosaic, cfa=cfa)
        raw = read_raw(path)
        assert raw.pattern == name and np.array_equal(raw.mosaic, mosaic)
        assert np.array_equal(raw.black_level, np.full((2, 2), 64.0)) and raw.white_level == 4095
        assert np.allclose(raw.white_balance, [2.0, 1.0, 1.25])  # 1 / AsShotNeutral, green = 1
        assert raw.normalised()[0, 0] == pytest.approx((mosaic[0, 0] - 64) / (4095 - 64), rel=1e-6)


def test_dng_read_image_is_camkit_demosaic(tmp_path, dng_writer):
    """read_image on a RAW file: black subtracted, white at 65535, as-shot white balance, then
    camkit's own demosaic; the sampled values pass through unchanged."""
    pytest.importorskip("rawpy", reason="camera RAW needs the optional extra camkit[raw] (rawpy)")
    from camkit.sensor import demosaic, mosaic

    # A grey scene seen through the filters with the camera's channel gains 1/wb.
    wb = np.array([2.0, 1.0, 1.25])
    scene = np.clip(0.2 + 0.6 * (GREY[:32, :48] / 255.0), 0, 1)
    rgb = np.repeat(scene[:, :, None], 3, axis=2) / wb
    m = mosaic(rgb, "RGGB")
    counts = np.round(64 + m * (4095 - 64)).astype(np.uint16)
    dng_writer(tmp_path / "grey.dng", counts)
    out = read_image(tmp_path / "grey.dng")
    assert out.dtype == np.uint16 and out.shape == (32, 48, 3)
    expected_mosaic = np.round(np.clip((counts - 64.0) / (4095 - 64) * mosaic(np.ones((32, 48, 3)) * wb, "RGGB"),
                                       0, 1) * 65535).astype(np.uint16)
    assert np.array_equal(mosaic(out, "RGGB"), expected_mosaic)
    assert np.array_equal(out, demosaic(expected_mosaic, "RGGB", "menon"))
    # White balance applied: the grey scene comes out grey (within the quantisation and the
    # demosaic's interpolation on a smooth image).
    assert np.abs(out[4:-4, 4:-4, 0].astype(int) - out[4:-4, 4:-4, 1]).mean() < 400


def test_raw_without_rawpy_says_how_to_install(tmp_path, monkeypatch):
    import builtins

    real = builtins.__import__

    def no_rawpy(name, *a, **k):
        if name == "rawpy":
            raise ImportError("no rawpy")
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_rawpy)
    (tmp_path / "x.nef").write_bytes(b"II*\x00\x08\x00\x00\x00" + bytes(64))
    with pytest.raises(ImageFileError, match=r"camkit\[raw\]"):
        read_image(tmp_path / "x.nef")


# -- writing ------------------------------------------------------------------------------------


@pytest.mark.parametrize("ext", [".png", ".tif"])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_write_image_round_trips(tmp_path, ext, dtype, channels):
    shape = (7, 11) if channels == 1 else (7, 11, channels)
    img = RNG.integers(0, np.iinfo(dtype).max, shape, endpoint=True).astype(dtype)
    out = read_image(write_image(tmp_path / f"a{ext}", img))
    assert out.dtype == img.dtype and np.array_equal(out, img)


def test_write_float_tiff_and_jpeg(tmp_path):
    f = RNG.random((5, 6)).astype(np.float32)
    assert np.array_equal(read_image(write_image(tmp_path / "f.tiff", f)), f)
    back = read_image(write_image(tmp_path / "a.JPG", RGB, quality=95))
    assert np.abs(back.astype(int) - RGB).mean() < 2.0
    with pytest.raises(ParameterError, match=r"path: expected a name ending in .png"):
        write_image(tmp_path / "a.gif", RGB)
    with pytest.raises(ShapeError, match="for JPEG"):
        write_image(tmp_path / "a.jpg", RGB.astype(np.uint16))


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_png_level_is_lossless_and_trades_size(tmp_path, dtype):
    # A smooth ramp with a little noise: every zlib level gives the same pixels, and level 9
    # a file no larger than level 0 (which stores the rows uncompressed).
    yy, xx = np.mgrid[0:64, 0:96]
    ramp = (xx * 2 + yy + RNG.integers(0, 3, (64, 96)))[:, :, None] * np.array([1, 2, 3])
    img = ramp.astype(dtype)
    sizes = {}
    for level in (0, 1, 9):
        p = write_image(tmp_path / f"l{level}.png", img, png_level=level)
        assert np.array_equal(read_image(p), img)
        sizes[level] = p.stat().st_size
    assert sizes[9] <= sizes[1] < sizes[0]
    for bad in (-1, 10, 1.5, True, "1"):
        with pytest.raises(ParameterError, match=r"png_level: expected an integer 0\.\.9"):
            write_png(tmp_path / "bad.png", img, png_level=bad)
    assert not (tmp_path / "bad.png").exists()
