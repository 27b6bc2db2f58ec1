"""Image files, read and written here directly (zlib from the standard library), so camkit
needs no imaging library: PNG read and write; baseline TIFF (uncompressed, LZW, PackBits,
Deflate) and binary PGM/PPM read."""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np

from camkit._validate import as_image
from camkit.errors import ImageFileError, ShapeError
from camkit.io._atomic import write_atomic

__all__ = ["IMAGE_SUFFIXES", "ImageFileError", "read_image", "write_png"]


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def write_png(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write a uint8 or uint16 image, (H, W) grey or (H, W, 3) RGB, as PNG (W3C PNG
    specification, 3rd ed.: 8- or 16-bit, no interlace, filter 0).

    The file is written to a temporary name in the same folder and renamed into place, so a
    reader never sees half a file and an existing file is replaced only when the new one is
    complete. Returns the path.
    """
    img = as_image(image, "image", max_channels=3)
    if img.dtype not in (np.uint8, np.uint16):
        raise ShapeError(f"image: expected uint8 or uint16 for PNG, got {img.dtype}")
    if img.ndim == 3 and img.shape[2] == 2:
        raise ShapeError(f"image: expected 1 or 3 channels for PNG, got {img.shape}")
    h, w = img.shape[:2]
    colour_type = 2 if img.ndim == 3 and img.shape[2] == 3 else 0
    depth = 8 if img.dtype == np.uint8 else 16
    data = np.ascontiguousarray(img if img.ndim == 2 or img.shape[2] == 3 else img[:, :, 0])
    if depth == 16:
        data = data.astype(">u2")  # PNG stores big-endian samples
    rows = data.reshape(h, -1).view(np.uint8)
    raw = np.concatenate([np.zeros((h, 1), np.uint8), rows], axis=1).tobytes()
    png = (b"\x89PNG\r\n\x1a\n"
           + _chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, colour_type, 0, 0, 0))
           + _chunk(b"IDAT", zlib.compress(raw, 6)) + _chunk(b"IEND", b""))
    return write_atomic(path, png)


#: File name endings ``read_image`` understands.
IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".pgm", ".ppm", ".pnm")


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file into an array, as stored: (H, W) grey or (H, W, C) with C = 2 (grey
    and alpha), 3 (RGB) or 4 (RGBA); uint8 or uint16 (16-bit files).

    Formats, recognised by their content, not their name: PNG (every colour type, bit depths
    1-16, not interlaced), TIFF (baseline: strips or tiles, uncompressed, LZW, PackBits or
    Deflate, horizontal predictor, 8 or 16 bits, grey, RGB or palette), binary PGM/PPM.
    JPEG is not read: convert such files to PNG first.

    Raises
    ------
    ImageFileError
        The file is not an image of these formats, is damaged, or uses an unsupported variant;
        the message names the file and the reason.
    """
    if not isinstance(path, str | os.PathLike):
        raise ImageFileError(f"path: expected a file name (str or path), got {type(path).__name__}")
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ImageFileError(f"{p}: cannot read the file ({exc.strerror or exc})") from None
    try:
        if data[:8] == b"\x89PNG\r\n\x1a\n":
            return _read_png(data, p)
        if data[:4] in (b"II*\x00", b"MM\x00*"):
            return _read_tiff(data, p)
        if data[:2] in (b"P5", b"P6"):
            return _read_pnm(data, p)
    except ImageFileError:
        raise
    except (struct.error, zlib.error, IndexError, ValueError) as exc:
        raise ImageFileError(f"{p}: damaged image file ({exc})") from None
    if data[:3] == b"\xff\xd8\xff":
        raise ImageFileError(f"{p}: JPEG files are not read by camkit; convert to PNG or TIFF "
                             "(e.g. with any image viewer) and try again")
    raise ImageFileError(f"{p}: not an image file camkit reads (expected PNG, TIFF, PGM or PPM)")


def _read_png(data: bytes, p: Path) -> np.ndarray:
    from camkit._kernels.codecs import png_unfilter

    pos, idat, ihdr, palette, trns = 8, [], None, None, None
    while pos + 8 <= len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if len(body) != n:
            raise ImageFileError(f"{p}: damaged PNG (chunk {kind!r} is cut short)")
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"PLTE":
            palette = np.frombuffer(body, np.uint8).reshape(-1, 3)
        elif kind == b"tRNS":
            trns = body
        elif kind == b"IEND":
            break
        pos += 12 + n
    if ihdr is None or not idat:
        raise ImageFileError(f"{p}: damaged PNG (no IHDR or no image data)")
    w, h, depth, ctype, _, _, interlace = ihdr
    channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}.get(ctype)
    if channels is None or depth not in (1, 2, 4, 8, 16) or w == 0 or h == 0:
        raise ImageFileError(f"{p}: damaged PNG (colour type {ctype}, bit depth {depth}, {w}x{h})")
    if interlace:
        raise ImageFileError(f"{p}: interlaced (Adam7) PNG is not supported; save it without interlacing")
    bits = channels * depth
    stride = (w * bits + 7) // 8
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), np.uint8)
    if raw.size < h * (stride + 1):
        raise ImageFileError(f"{p}: damaged PNG (image data is cut short)")
    rows = png_unfilter(raw, h, stride, max(bits // 8, 1))
    if rows.shape[0] != h:
        raise ImageFileError(f"{p}: damaged PNG (invalid row filter)")
    if depth == 16:
        img = rows.view(">u2").astype(np.uint16).reshape(h, w, channels)
    elif depth == 8:
        img = rows.reshape(h, w, channels)
    else:
        img = np.unpackbits(rows, axis=1).reshape(h, -1, depth)[:, :w]
        img = (img * (1 << np.arange(depth - 1, -1, -1, dtype=np.uint8))).sum(axis=2, dtype=np.uint8)
        if ctype == 0:
            img = (img.astype(np.uint16) * 255 // ((1 << depth) - 1)).astype(np.uint8)
        img = img[:, :, None]
    if ctype == 3:
        if palette is None:
            raise ImageFileError(f"{p}: damaged PNG (palette image without a palette)")
        idx = img[:, :, 0]
        if idx.max() >= len(palette):
            raise ImageFileError(f"{p}: damaged PNG (palette index out of range)")
        img = palette[idx]
        if trns is not None:
            alpha = np.full(len(palette), 255, np.uint8)
            alpha[:len(trns)] = np.frombuffer(trns, np.uint8)[:len(palette)]
            img = np.concatenate([img, alpha[idx][:, :, None]], axis=2)
    return np.ascontiguousarray(img[:, :, 0] if img.shape[2] == 1 else img)


_TIFF_TYPES = {1: "B", 2: "s", 3: "H", 4: "I", 16: "Q"}


def _read_tiff(data: bytes, p: Path) -> np.ndarray:
    from camkit._kernels.codecs import packbits_decode, tiff_lzw_decode

    e = "<" if data[:2] == b"II" else ">"
    (ifd,) = struct.unpack(e + "I", data[4:8])
    (n,) = struct.unpack(e + "H", data[ifd:ifd + 2])
    tags: dict[int, tuple] = {}
    for k in range(n):
        tag, typ, count, value = struct.unpack(e + "HHI4s", data[ifd + 2 + 12 * k: ifd + 14 + 12 * k])
        code = _TIFF_TYPES.get(typ)
        if code is None:
            continue
        size = struct.calcsize(code) * count
        raw = value[:size] if size <= 4 else data[struct.unpack(e + "I", value)[0]:][:size]
        tags[tag] = raw.rstrip(b"\0") if code == "s" else struct.unpack(e + code * count, raw)

    def get(tag: int, default=None):
        v = tags.get(tag)
        return default if v is None else v
    w, h = get(256, (0,))[0], get(257, (0,))[0]
    bps = get(258, (1,))
    spp = get(277, (1,))[0]
    comp = get(259, (1,))[0]
    photometric = get(262, (1,))[0]
    planar = get(284, (1,))[0]
    predictor = get(317, (1,))[0]
    fmt = get(339, (1,))[0]
    if w == 0 or h == 0:
        raise ImageFileError(f"{p}: damaged TIFF (no image size)")
    if len(set(bps)) != 1 or bps[0] not in (8, 16) or fmt != 1:
        raise ImageFileError(f"{p}: TIFF with {bps} bits per sample (format {fmt}) is not supported; "
                             "expected 8- or 16-bit unsigned samples")
    if planar != 1 and spp > 1:
        raise ImageFileError(f"{p}: planar (non-interleaved) TIFF is not supported")
    if comp not in (1, 5, 8, 32946, 32773):
        raise ImageFileError(f"{p}: TIFF compression {comp} is not supported (expected none, LZW, "
                             "Deflate or PackBits)")
    if photometric not in (0, 1, 2, 3):
        raise ImageFileError(f"{p}: TIFF photometric interpretation {photometric} is not supported")
    itemsize = bps[0] // 8
    dtype = np.dtype(e + ("u1" if itemsize == 1 else "u2"))

    def decode(chunk: bytes, expected: int) -> np.ndarray:
        buf = np.frombuffer(chunk, np.uint8)
        if comp == 1:
            return buf[:expected]
        if comp == 5:
            return tiff_lzw_decode(buf, expected)
        if comp == 32773:
            return packbits_decode(buf, expected)
        return np.frombuffer(zlib.decompress(chunk), np.uint8)[:expected]

    if 322 in tags:  # tiled
        tw, th = get(322)[0], get(323)[0]
        offsets, counts = get(324), get(325)
        across = -(-w // tw)
        img = np.zeros((-(-h // th) * th, across * tw, spp), dtype)
        for k, (o, c) in enumerate(zip(offsets, counts, strict=False)):
            tile = decode(data[o:o + c], tw * th * spp * itemsize)
            if tile.size != tw * th * spp * itemsize:
                raise ImageFileError(f"{p}: damaged TIFF (tile {k} is cut short)")
            tile = tile.view(dtype).reshape(th, tw, spp)
            if predictor == 2:
                tile = np.cumsum(tile, axis=1, dtype=tile.dtype)
            ty, tx = divmod(k, across)
            img[ty * th:(ty + 1) * th, tx * tw:(tx + 1) * tw] = tile
        img = img[:h, :w]
    else:
        offsets, counts = get(273), get(279)
        if offsets is None:
            raise ImageFileError(f"{p}: damaged TIFF (no strip offsets)")
        rps = min(get(278, (h,))[0], h)
        if counts is None:
            counts = (len(data),) * len(offsets)
        parts, row_bytes = [], w * spp * itemsize
        for k, (o, c) in enumerate(zip(offsets, counts, strict=False)):
            rows = min(rps, h - k * rps)
            if rows <= 0:
                break
            strip = decode(data[o:o + c], rows * row_bytes)
            if strip.size != rows * row_bytes:
                raise ImageFileError(f"{p}: damaged TIFF (strip {k} is cut short)")
            strip = strip.view(dtype).reshape(rows, w, spp)
            if predictor == 2:
                strip = np.cumsum(strip, axis=1, dtype=strip.dtype)
            parts.append(strip)
        img = np.concatenate(parts, axis=0)
        if img.shape[0] != h:
            raise ImageFileError(f"{p}: damaged TIFF (image data is cut short)")
    img = img.astype(img.dtype.newbyteorder("="), copy=False)
    if photometric == 0:  # white is zero
        img = np.iinfo(img.dtype).max - img
    if photometric == 3:
        cmap = get(320)
        if cmap is None:
            raise ImageFileError(f"{p}: damaged TIFF (palette image without a colour map)")
        n_colours = 1 << bps[0]
        lut = np.array(cmap, np.uint16).reshape(3, n_colours).T
        img = lut[img[:, :, 0]]  # TIFF colour maps are 16-bit
        if itemsize == 1:
            img = (img >> 8).astype(np.uint8)
    return np.ascontiguousarray(img[:, :, 0] if img.shape[2] == 1 else img)


def _read_pnm(data: bytes, p: Path) -> np.ndarray:
    fields, pos = [], 2
    while len(fields) < 3:
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        start = pos
        while not data[pos:pos + 1].isspace():
            pos += 1
        fields.append(int(data[start:pos]))
    pos += 1
    w, h, maxval = fields
    if w <= 0 or h <= 0 or not 0 < maxval < 65536:
        raise ImageFileError(f"{p}: damaged PGM/PPM header ({w}x{h}, maxval {maxval})")
    channels = 3 if data[:2] == b"P6" else 1
    dtype = np.dtype(np.uint8) if maxval < 256 else np.dtype(">u2")
    count = w * h * channels
    if len(data) - pos < count * dtype.itemsize:
        raise ImageFileError(f"{p}: damaged PGM/PPM (image data is cut short)")
    img = np.frombuffer(data, dtype, count, pos).astype(dtype.newbyteorder("=")).reshape(h, w, channels)
    return img[:, :, 0] if channels == 1 else img
