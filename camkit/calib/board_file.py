"""Printable checkerboards at exact physical scale: PDF, SVG and PNG drawn by matplotlib.

The page is either the board's own sheet (squares, the white margin around them and a label
band), or a paper size (A4, A3, letter or any W x H) with the board centred on it. One data unit
of the drawing is one millimetre of paper, and the figure is exactly the page's size, so the
vector files print each square at ``board.square`` when printed at 100 % ("actual size").
"""

from __future__ import annotations

import io
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

from camkit._validate import as_positive_int
from camkit.calib.targets import Checkerboard
from camkit.errors import ParameterError
from camkit.io._atomic import write_atomic

__all__ = ["PAPER_SIZES_MM", "BoardLayout", "board_layout", "board_squares", "parse_paper", "write_board"]

#: Paper sizes, portrait, in millimetres (ISO 216 for A4 and A3; US letter is 8.5 x 11 in).
PAPER_SIZES_MM = {"A4": (210.0, 297.0), "A3": (297.0, 420.0), "letter": (215.9, 279.4)}

#: White kept around the squares on a paper page, mm: most printers cannot print the outer ~5 mm,
#: and detectors need a quiet zone outside the outer squares.
PAPER_MARGIN_MM = 10.0
#: Height of the label band under the board (at the foot of a paper page), mm.
LABEL_BAND_MM = 8.0


def parse_paper(text: str) -> tuple[float, float]:
    """``"A4"``, ``"A3"``, ``"letter"`` (any case) or ``"WxHmm"`` (e.g. ``"300x200mm"``) as a
    portrait (width, height) in millimetres."""
    if not isinstance(text, str):
        raise ParameterError(f"paper: expected A4, A3, letter or WxHmm, got {text!r}")
    for name, size in PAPER_SIZES_MM.items():
        if text.strip().lower() == name.lower():
            return size
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*x\s*([0-9]*\.?[0-9]+)\s*mm\s*", text.lower())
    if not m:
        raise ParameterError(f"paper: expected A4, A3, letter or WxHmm (e.g. 300x200mm), got {text!r}")
    w, h = float(m.group(1)), float(m.group(2))
    if not (w > 0 and h > 0):
        raise ParameterError(f"paper: expected a positive size, got {text!r}")
    return w, h


def board_squares(board: Checkerboard) -> list[tuple[float, float]]:
    """Top-left corners (metres, sheet frame: origin at the sheet's top-left, y down) of the
    black squares on the board's own sheet; every square has side ``board.square``. The
    top-left square is black."""
    s, m = board.square, board.margin
    return [(m + c * s, m + r * s) for r in range(board.inner_rows + 1) for c in range(board.inner_cols + 1)
            if (r + c) % 2 == 0]


@dataclass(frozen=True, slots=True)
class BoardLayout:
    """Where the board lies on the page, millimetres, page frame (origin top-left, y down)."""

    page_w_mm: float
    page_h_mm: float
    x0_mm: float
    y0_mm: float
    square_mm: float
    label_y_mm: float


def board_layout(board: Checkerboard, paper: tuple[float, float] | None = None) -> BoardLayout:
    """The page and the board's place on it.

    Without ``paper``: the page is the sheet (squares, ``board.margin`` around them) plus a
    label band under it. With ``paper`` (width, height in mm): the board is centred on the paper,
    turned to landscape when only that fits, with at least :data:`PAPER_MARGIN_MM` of white
    around the squares and the label band below; a board that does not fit raises a
    ParameterError giving the largest square that would.
    """
    s = board.square * 1000.0
    cols, rows = board.inner_cols + 1, board.inner_rows + 1
    bw, bh = cols * s, rows * s
    if paper is None:
        m = board.margin * 1000.0
        return BoardLayout(bw + 2 * m, bh + 2 * m + LABEL_BAND_MM, m, m, s, bh + 2 * m + LABEL_BAND_MM / 2)
    pw, ph = paper
    best = 0.0
    for w, h in ((pw, ph), (ph, pw)):
        avail_w, avail_h = w - 2 * PAPER_MARGIN_MM, h - 2 * PAPER_MARGIN_MM - LABEL_BAND_MM
        best = max(best, min(avail_w / cols, avail_h / rows))
        if bw <= avail_w + 1e-9 and bh <= avail_h + 1e-9:
            x0 = (w - bw) / 2
            y0 = (h - LABEL_BAND_MM - bh) / 2
            return BoardLayout(w, h, x0, y0, s, h - PAPER_MARGIN_MM / 2 - LABEL_BAND_MM / 2)
    largest = math.floor(best * 10) / 10
    raise ParameterError(f"square: a board of {cols}x{rows} squares of {s:g} mm ({bw:g} x {bh:g} mm) does not fit on "
                         f"{pw:g} x {ph:g} mm paper with {PAPER_MARGIN_MM:g} mm margins and the label; the largest "
                         f"square that fits is {largest:g} mm")


def _label(board: Checkerboard) -> str:
    s = board.square * 1000.0
    return (f"checkerboard {board.inner_cols}x{board.inner_rows} inner corners "
            f"({board.inner_cols + 1}x{board.inner_rows + 1} squares), squares {s:g} mm. "
            "Print at 100 % (actual size) and measure a square.")


def _figure(board: Checkerboard, layout: BoardLayout):
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    mm_per_in = 25.4
    fig = Figure(figsize=(layout.page_w_mm / mm_per_in, layout.page_h_mm / mm_per_in))
    fig.patch.set_facecolor("white")
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(0.0, layout.page_w_mm)
    ax.set_ylim(layout.page_h_mm, 0.0)  # y down, as the page is read
    ax.set_axis_off()
    s = layout.square_mm
    for r in range(board.inner_rows + 1):
        for c in range(board.inner_cols + 1):
            if (r + c) % 2 == 0:
                ax.add_patch(Rectangle((layout.x0_mm + c * s, layout.y0_mm + r * s), s, s, facecolor="black",
                                       edgecolor="none", linewidth=0.0, antialiased=False, snap=False))
    # A light label, as far from the squares as the page allows: dark glyphs next to the board
    # would be X-corners and edges to any detector.
    ax.text(layout.page_w_mm / 2, layout.label_y_mm, _label(board), ha="center", va="center", fontsize=6,
            color="0.7")
    return fig


def write_board(path: str | os.PathLike, board: Checkerboard, *, paper: str | tuple[float, float] | None = None,
                dpi: int = 300) -> Path:
    """Write a printable board, format from the suffix: ``.pdf`` or ``.svg`` (vector, exact size)
    or ``.png`` (``dpi`` pixels per inch, the density recorded in the file).

    Parameters
    ----------
    path : str or path
    board : Checkerboard
    paper : "A4", "A3", "letter", "WxHmm", (width_mm, height_mm) or None
        Centre the board on this paper (see :func:`board_layout`); None: the page is the
        board's own sheet.
    dpi : int
        Pixels per inch of a PNG.

    The sheet carries a label: inner corners, square size and "print at 100 %". Written
    atomically. Print at 100 % ("actual size"), then measure a square.
    """
    if not isinstance(board, Checkerboard):
        raise ParameterError(f"board: expected a Checkerboard, got {type(board).__name__}")
    p = Path(path)
    kind = p.suffix.lower()
    if kind not in (".pdf", ".svg", ".png"):
        raise ParameterError(f"path: expected a name ending in .pdf, .svg or .png, got {p.name!r}")
    dots = as_positive_int(dpi, "dpi")
    size = parse_paper(paper) if isinstance(paper, str) else paper
    if size is not None and (len(size) != 2 or not all(float(v) > 0 for v in size)):
        raise ParameterError(f"paper: expected a name or (width_mm, height_mm), got {paper!r}")
    layout = board_layout(board, None if size is None else (float(size[0]), float(size[1])))
    fig = _figure(board, layout)
    buf = io.BytesIO()
    meta = {"Title": _label(board)} if kind in (".pdf", ".svg") else None
    fig.savefig(buf, format=kind[1:], dpi=dots, facecolor="white", metadata=meta)
    return write_atomic(p, buf.getvalue())
