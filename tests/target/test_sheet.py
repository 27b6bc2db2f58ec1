"""Board files: bad input names its argument (the files' scale is tested through the CLI)."""

from __future__ import annotations

import numpy as np
import pytest

from camkit.errors import CamkitError
from camkit.target import Checkerboard
from camkit.target.sheet import write_board


def test_black_squares_are_half_the_board_with_black_top_left():
    board = Checkerboard(9, 6, 0.025)
    sheet = board.sheet()
    assert len(sheet.black) == 35  # 10 x 7 squares, the top-left one black
    np.testing.assert_allclose(sheet.black[0], [-0.025, -0.025, 0.0, 0.0])  # it holds (-s/2, -s/2)
    np.testing.assert_allclose(sheet.extent, [-0.05, -0.05, 0.25, 0.175])  # a square's margin around


def test_raster_of_the_sheet_is_the_checker_pattern():
    """The sheet at 1 px per mm: each square 25 px, black where (row + col) is even, the
    margin white; and an inner corner's four squares alternate around (col, row) * 25 mm."""
    board = Checkerboard(4, 3, 0.025)
    img = board.sheet().raster(1000.0)
    assert img.shape == (4 * 25 + 2 * 25, 5 * 25 + 2 * 25)
    centres = img[25 + 12:25 + 4 * 25:25, 25 + 12:25 + 5 * 25:25]
    r, c = np.mgrid[0:4, 0:5]
    np.testing.assert_array_equal(centres == 0, (r + c) % 2 == 0)
    assert (img[:25] == 255).all() and (img[:, -25:] == 255).all()


@pytest.mark.parametrize("name,board,dpi,match", [
    ("b.jpg", Checkerboard(9, 6, 0.025), 300, "path: expected a name ending in .pdf, .svg or .png"),
    ("b.pdf", (9, 6), 300, "board: expected a camkit target"),
    ("b.png", Checkerboard(9, 6, 0.025), 0, "dpi"),
])
def test_bad_input(tmp_path, name, board, dpi, match):
    with pytest.raises(CamkitError, match=match):
        write_board(tmp_path / name, board, dpi=dpi)
    assert not (tmp_path / name).exists()


@pytest.mark.parametrize("paper,match", [("A5", "paper: expected A4, A3, letter or WxHmm"),
                                         ("0x200mm", "paper: expected a positive size"),
                                         ((210.0,), "paper: expected a name or"),
                                         ("A4", "largest square that fits is 26 mm")])
def test_bad_paper_is_refused_and_nothing_written(tmp_path, paper, match):
    board = Checkerboard(9, 6, 0.04 if paper == "A4" else 0.025)
    with pytest.raises(CamkitError, match=match):
        write_board(tmp_path / "b.pdf", board, paper=paper)
    assert not (tmp_path / "b.pdf").exists()


@pytest.mark.parametrize("density,match", [(0.0, "px_per_m: expected a positive"), (float("nan"), "px_per_m"),
                                           (1e9, "px_per_m: expected at most 32768 pixels a side")])
def test_sheet_rasters_refuse_a_bad_density(density, match):
    sheet = Checkerboard(9, 6, 0.025).sheet()
    for fn in (sheet.raster, sheet.coverage):
        with pytest.raises(CamkitError, match=match):
            fn(density)


def test_coverage_is_the_exact_area_of_each_mark():
    """A 1 mm square at 0.25 mm offsets, 1 texel per mm: coverages 0.75 x 0.75 etc., summing
    to the square's area in texels (1)."""
    from camkit.target import Sheet

    sheet = Sheet((0.0, 0.0, 0.003, 0.003), np.array([[0.00125, 0.00125, 0.00225, 0.00225]]), "")
    cov = sheet.coverage(1000.0)
    np.testing.assert_allclose(cov[1:3, 1:3], [[0.5625, 0.1875], [0.1875, 0.0625]])
    assert cov.sum() == pytest.approx(1.0)
