"""Printable targets at exact physical scale: PDF, SVG and PNG drawn by matplotlib.

Any :class:`~camkit.target.base.Target` prints from its :class:`~camkit.target.base.Sheet`
(black rectangles on white, metres). The page is either the target's own sheet (its marks, the
white margin around them and a label band), or a paper size (A4, A3, letter or any W x H) with
the marks centred on it. One data unit of the drawing is one millimetre of paper, and the figure
is exactly the page's size, so the vector files print every mark at its size when printed at
100 % ("actual size").
"""

from __future__ import annotations

import io
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camkit._atomic import write_atomic
from camkit._validate import as_positive_int
from camkit.errors import ParameterError
from camkit.target.base import Sheet, Target

__all__ = ["PAPER_SIZES_MM", "BoardLayout", "board_layout", "parse_paper", "write_board"]

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


@dataclass(frozen=True, slots=True)
class BoardLayout:
    """Where the target's marks lie on the page, millimetres, page frame (origin top-left, y
    down): the marks' bounding box starts at ``(x0_mm, y0_mm)``."""

    page_w_mm: float
    page_h_mm: float
    x0_mm: float
    y0_mm: float
    label_y_mm: float


def _marks_box(sheet: Sheet) -> tuple[float, float, float, float]:
    b = sheet.page_marks()
    return float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max())


def _as_target(target: object) -> Target:
    if not isinstance(target, Target):
        raise ParameterError(f"board: expected a camkit target (e.g. a Checkerboard), got {type(target).__name__}")
    return target


def board_layout(board: Target, paper: tuple[float, float] | None = None) -> BoardLayout:
    """The page and the target's place on it.

    Without ``paper``: the page is the target's sheet (its marks and the margin around them)
    plus a label band under it. With ``paper`` (width, height in mm): the marks are centred on
    the paper, turned to landscape when only that fits, with at least :data:`PAPER_MARGIN_MM`
    of white around them and the label band below; a target that does not fit raises a
    ParameterError giving the largest square (smallest mark) that would.
    """
    sheet = _as_target(board).sheet()
    bu0, bv0, bu1, bv1 = _marks_box(sheet)
    bw, bh = (bu1 - bu0) * 1000.0, (bv1 - bv0) * 1000.0
    if paper is None:
        u0, v0, u1, v1 = sheet.extent
        h = (v1 - v0) * 1000.0
        return BoardLayout((u1 - u0) * 1000.0, h + LABEL_BAND_MM, (bu0 - u0) * 1000.0, (bv0 - v0) * 1000.0,
                           h + LABEL_BAND_MM / 2)
    pw, ph = paper
    best = 0.0
    for w, h in ((pw, ph), (ph, pw)):
        avail_w, avail_h = w - 2 * PAPER_MARGIN_MM, h - 2 * PAPER_MARGIN_MM - LABEL_BAND_MM
        best = max(best, min(avail_w / bw, avail_h / bh))
        if bw <= avail_w + 1e-9 and bh <= avail_h + 1e-9:
            return BoardLayout(w, h, (w - bw) / 2, (h - LABEL_BAND_MM - bh) / 2,
                               h - PAPER_MARGIN_MM / 2 - LABEL_BAND_MM / 2)
    mark = float(np.min(np.minimum(sheet.black[:, 2] - sheet.black[:, 0], sheet.black[:, 3] - sheet.black[:, 1])))
    largest = math.floor(best * mark * 1000.0 * 10 + 1e-6) / 10
    raise ParameterError(f"square: a target of {bw:g} x {bh:g} mm (squares of {mark * 1000:g} mm) does not fit on "
                         f"{pw:g} x {ph:g} mm paper with {PAPER_MARGIN_MM:g} mm margins and the label; the largest "
                         f"square that fits is {largest:g} mm")


def _figure(sheet: Sheet, layout: BoardLayout):
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    mm_per_in = 25.4
    fig = Figure(figsize=(layout.page_w_mm / mm_per_in, layout.page_h_mm / mm_per_in))
    fig.patch.set_facecolor("white")
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(0.0, layout.page_w_mm)
    ax.set_ylim(layout.page_h_mm, 0.0)  # y down, as the page is read
    ax.set_axis_off()
    bu0, bv0, _, _ = _marks_box(sheet)
    mm = (sheet.page_marks() - [bu0, bv0, bu0, bv0]) * 1000.0 + [layout.x0_mm, layout.y0_mm, layout.x0_mm, layout.y0_mm]
    for x0, y0, x1, y1 in mm:
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor="black", edgecolor="none", linewidth=0.0,
                               antialiased=False, snap=False))
    # A light label, as far from the marks as the page allows: dark glyphs next to the target
    # would be X-corners and edges to any detector.
    ax.text(layout.page_w_mm / 2, layout.label_y_mm, sheet.label, ha="center", va="center", fontsize=6,
            color="0.7")
    return fig


def write_board(path: str | os.PathLike, board: Target, *, paper: str | tuple[float, float] | None = None,
                dpi: int = 300) -> Path:
    """Write a printable target, format from the suffix: ``.pdf`` or ``.svg`` (vector, exact
    size) or ``.png`` (``dpi`` pixels per inch, the density recorded in the file).

    Parameters
    ----------
    path : str or path
    board : Target
        A checkerboard, or any registered target.
    paper : "A4", "A3", "letter", "WxHmm", (width_mm, height_mm) or None
        Centre the target on this paper (see :func:`board_layout`); None: the page is the
        target's own sheet.
    dpi : int
        Pixels per inch of a PNG.

    The sheet carries the target's label (for a checkerboard: inner corners, square size and
    "print at 100 %"). Written atomically. Print at 100 % ("actual size"), then measure a
    square.
    """
    target = _as_target(board)
    p = Path(path)
    kind = p.suffix.lower()
    if kind not in (".pdf", ".svg", ".png"):
        raise ParameterError(f"path: expected a name ending in .pdf, .svg or .png, got {p.name!r}")
    dots = as_positive_int(dpi, "dpi")
    size = parse_paper(paper) if isinstance(paper, str) else paper
    if size is not None and (len(size) != 2 or not all(float(v) > 0 for v in size)):
        raise ParameterError(f"paper: expected a name or (width_mm, height_mm), got {paper!r}")
    layout = board_layout(target, None if size is None else (float(size[0]), float(size[1])))
    sheet = target.sheet()
    fig = _figure(sheet, layout)
    buf = io.BytesIO()
    meta = {"Title": sheet.label} if kind in (".pdf", ".svg") else None
    fig.savefig(buf, format=kind[1:], dpi=dots, facecolor="white", metadata=meta)
    return write_atomic(p, buf.getvalue())
