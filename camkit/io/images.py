"""Image files. PNG is written here directly (zlib from the standard library), so writing a
dataset needs no imaging library."""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np

from camkit._validate import as_image
from camkit.errors import ShapeError
from camkit.io._atomic import write_atomic

__all__ = ["write_png"]


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
