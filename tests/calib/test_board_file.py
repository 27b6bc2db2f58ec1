"""Board files: bad input names its argument (the files' scale is tested through the CLI)."""

from __future__ import annotations

import pytest

from camkit.calib import Checkerboard
from camkit.calib.board_file import board_squares, write_board
from camkit.errors import CamkitError


def test_black_squares_are_half_the_board_with_black_top_left():
    board = Checkerboard(9, 6, 0.025)
    squares = board_squares(board)
    assert len(squares) == 35 and squares[0] == (0.025, 0.025)


@pytest.mark.parametrize("name,board,dpi,match", [
    ("b.jpg", Checkerboard(9, 6, 0.025), 300, "path: expected a name ending in .pdf, .svg or .png"),
    ("b.pdf", (9, 6), 300, "board: expected a Checkerboard"),
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
