"""Printable checkerboards at exact physical scale: SVG, PDF and PNG, written by hand."""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np

from camkit._validate import as_positive_int
from camkit.calib.targets import Checkerboard
from camkit.errors import ParameterError
from camkit.io._atomic import write_atomic

__all__ = ["board_squares", "write_board"]

_PT_PER_M = 72.0 / 0.0254  # PDF user space: 1/72 inch


def board_squares(board: Checkerboard) -> list[tuple[float, float]]:
    """Top-left corners (metres, sheet frame: origin at the sheet's top-left, y down) of the
    black squares; every square has side ``board.square``. The top-left square is black."""
    s, m = board.square, board.margin
    return [(m + c * s, m + r * s) for r in range(board.inner_rows + 1) for c in range(board.inner_cols + 1)
            if (r + c) % 2 == 0]


def _sheet(board: Checkerboard) -> tuple[float, float]:
    u0, v0, u1, v1 = board.extent()
    return u1 - u0, v1 - v0


def _svg(board: Checkerboard) -> bytes:
    w, h = _sheet(board)
    mm = 1000.0
    rects = "".join(f'<rect x="{x * mm:.4f}" y="{y * mm:.4f}" width="{board.square * mm:.4f}" '
                    f'height="{board.square * mm:.4f}"/>' for x, y in board_squares(board))
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<svg xmlns="http://www.w3.org/2000/svg" '
            f'width="{w * mm:.4f}mm" height="{h * mm:.4f}mm" viewBox="0 0 {w * mm:.4f} {h * mm:.4f}">\n'
            f'<title>checkerboard {board.inner_cols}x{board.inner_rows} inner corners, '
            f'{board.square * mm:g} mm squares</title>\n'
            f'<rect width="100%" height="100%" fill="white"/>\n<g fill="black">{rects}</g>\n</svg>\n').encode()


def _pdf(board: Checkerboard) -> bytes:
    """One page the size of the sheet (PDF 1.4, ISO 32000-1 sec. 7 and 8.5: ``re`` and ``f``
    fill rectangles in points; print at 100 %, "actual size")."""
    w, h = _sheet(board)
    W, H = w * _PT_PER_M, h * _PT_PER_M
    s = board.square * _PT_PER_M
    ops = ["0 g"] + [f"{x * _PT_PER_M:.4f} {H - y * _PT_PER_M - s:.4f} {s:.4f} {s:.4f} re" for x, y in
                     board_squares(board)] + ["f"]
    content = "\n".join(ops).encode()
    objs = [b"<< /Type /Catalog /Pages 2 0 R >>",
            b"<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
            f"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {W:.4f} {H:.4f}] /Contents 4 0 R /Resources << >> >>"
            .encode(),
            b"<< /Length " + str(len(content)).encode() + b" >>\nstream\n" + content + b"\nendstream"]
    out = bytearray(b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n")
    offsets = []
    for k, body in enumerate(objs, start=1):
        offsets.append(len(out))
        out += f"{k} 0 obj\n".encode() + body + b"\nendobj\n"
    xref = len(out)
    out += f"xref\n0 {len(objs) + 1}\n0000000000 65535 f \n".encode()
    out += b"".join(f"{o:010d} 00000 n \n".encode() for o in offsets)
    out += f"trailer\n<< /Size {len(objs) + 1} /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n".encode()
    return bytes(out)


def _png(board: Checkerboard, dpi: int) -> bytes:
    """Whole pixels per square (``round(square * dpi / 25.4 mm)``), and a pHYs chunk giving the
    pixel density that makes a square exactly ``board.square`` when printed."""
    from camkit.io.images import _chunk

    px = max(round(board.square * dpi / 0.0254), 2)
    margin = round(board.margin / board.square * px)
    cols, rows = board.inner_cols + 1, board.inner_rows + 1
    h, w = rows * px + 2 * margin, cols * px + 2 * margin
    yy, xx = np.mgrid[0:h, 0:w]
    c, r = (xx - margin) // px, (yy - margin) // px
    black = (c >= 0) & (c < cols) & (r >= 0) & (r < rows) & ((c + r) % 2 == 0)
    img = np.where(black, 0, 255).astype(np.uint8)
    raw = np.concatenate([np.zeros((h, 1), np.uint8), img], axis=1).tobytes()
    ppm = round(px / board.square)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
            + _chunk(b"pHYs", struct.pack(">IIB", ppm, ppm, 1))
            + _chunk(b"IDAT", zlib.compress(raw, 9)) + _chunk(b"IEND", b""))


def write_board(path: str | os.PathLike, board: Checkerboard, *, dpi: int = 300) -> Path:
    """Write a printable board, format from the suffix: ``.svg`` and ``.pdf`` (vector, exact
    size: the page is the sheet, squares plus margin) or ``.png`` (``dpi`` pixels per inch,
    whole pixels per square; the file's pHYs chunk records the density that prints squares at
    exactly ``board.square``). Print at 100 % ("actual size"), then measure a square.
    Written atomically."""
    if not isinstance(board, Checkerboard):
        raise ParameterError(f"board: expected a Checkerboard, got {type(board).__name__}")
    p = Path(path)
    kind = p.suffix.lower()
    if kind == ".svg":
        data = _svg(board)
    elif kind == ".pdf":
        data = _pdf(board)
    elif kind == ".png":
        data = _png(board, as_positive_int(dpi, "dpi"))
    else:
        raise ParameterError(f"path: expected a name ending in .pdf, .svg or .png, got {p.name!r}")
    return write_atomic(p, data)
