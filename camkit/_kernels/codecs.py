"""Kernels for image file decoding: PNG row filters, TIFF LZW and PackBits."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def png_unfilter(raw: np.ndarray, height: int, stride: int, bpp: int) -> np.ndarray:  # pragma: no cover - numba
    """Undo the PNG row filters (None, Sub, Up, Average, Paeth; W3C PNG spec. sec. 7.3 and 9).

    ``raw`` is the inflated byte stream: per row one filter-type byte and ``stride`` bytes.
    ``bpp`` is the number of bytes per complete pixel (at least 1). Returns (height, stride)
    uint8, or an array with a first row of length 0 when a filter type is invalid."""
    out = np.zeros((height, stride), np.uint8)
    for y in range(height):
        base = y * (stride + 1)
        ftype = raw[base]
        if ftype > 4:
            return np.zeros((0, 0), np.uint8)
        for x in range(stride):
            v = np.int32(raw[base + 1 + x])
            a = np.int32(out[y, x - bpp]) if x >= bpp else np.int32(0)
            b = np.int32(out[y - 1, x]) if y > 0 else np.int32(0)
            c = np.int32(out[y - 1, x - bpp]) if (y > 0 and x >= bpp) else np.int32(0)
            if ftype == 1:
                v += a
            elif ftype == 2:
                v += b
            elif ftype == 3:
                v += (a + b) >> 1
            elif ftype == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                if pa <= pb and pa <= pc:
                    v += a
                elif pb <= pc:
                    v += b
                else:
                    v += c
            out[y, x] = np.uint8(v & 0xFF)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def tiff_lzw_decode(data: np.ndarray, expected: int) -> np.ndarray:  # pragma: no cover - numba
    """Decode one TIFF LZW strip (TIFF 6.0 sec. 13: MSB-first codes of 9-12 bits, ClearCode 256,
    EndOfInformation 257, the code width growing one code early). Stops at ``expected`` bytes
    or at EOI; returns what was decoded (shorter when the stream is corrupt)."""
    out = np.zeros(expected, np.uint8)
    # The string table as (prefix code, last byte, length); strings are rebuilt backwards.
    prefix = np.zeros(4096, np.int32)
    last = np.zeros(4096, np.uint8)
    length = np.zeros(4096, np.int32)
    for i in range(256):
        prefix[i] = -1
        last[i] = i
        length[i] = 1
    n_codes = 258
    width = 9
    bitpos = 0
    nbits = data.size * 8
    pos = 0
    old = -1
    while bitpos + width <= nbits and pos < expected:
        code = 0
        for k in range(width):
            byte = data[(bitpos + k) >> 3]
            code = (code << 1) | ((byte >> (7 - ((bitpos + k) & 7))) & 1)
        bitpos += width
        if code == 257:
            break
        if code == 256:
            n_codes = 258
            width = 9
            old = -1
            continue
        if old == -1:
            if code > 255:
                break
            out[pos] = code
            pos += 1
            old = code
            continue
        if code < n_codes:
            cur = code
        elif code == n_codes:
            cur = old
        else:
            break  # corrupt stream
        c = cur
        while prefix[c] != -1:
            c = prefix[c]
        first = last[c]
        ln = length[cur]
        c = cur
        for k in range(ln - 1, -1, -1):
            if pos + k < expected:
                out[pos + k] = last[c]
            c = prefix[c]
        pos += ln
        if code == n_codes:  # the KwKwK case: the string of ``old`` plus its own first byte
            if pos < expected:
                out[pos] = first
            pos += 1
        pos = min(pos, expected)
        if n_codes < 4096:
            prefix[n_codes] = old
            last[n_codes] = first
            length[n_codes] = length[old] + 1
            n_codes += 1
            if n_codes + 1 >= (1 << width) and width < 12:
                width += 1
        old = code
    return out[:pos]


@njit(cache=True, nogil=True, error_model="numpy")
def packbits_decode(data: np.ndarray, expected: int) -> np.ndarray:  # pragma: no cover - numba
    """Decode PackBits (TIFF 6.0 sec. 9); returns up to ``expected`` bytes."""
    out = np.zeros(expected, np.uint8)
    i = 0
    pos = 0
    n = data.size
    while i < n and pos < expected:
        h = np.int32(data[i])
        if h > 127:
            h -= 256
        i += 1
        if h >= 0:
            cnt = min(h + 1, expected - pos, n - i)
            for k in range(cnt):
                out[pos + k] = data[i + k]
            pos += cnt
            i += h + 1
        elif h != -128:
            if i >= n:
                break
            cnt = min(1 - h, expected - pos)
            for k in range(cnt):
                out[pos + k] = data[i]
            pos += cnt
            i += 1
    return out[:pos]
