"""Calibration targets."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camkit._validate import as_finite_float, as_positive_float, as_positive_int
from camkit.errors import ParameterError

__all__ = ["Checkerboard"]


@dataclass(frozen=True, slots=True)
class Checkerboard:
    """A planar checkerboard: ``inner_cols x inner_rows`` inner corners, squares of side
    ``square`` metres, a white margin around the outer squares.

    The board frame has its origin at the first inner corner, x along the columns, y along
    the rows, z = 0 on the board (so z points away from a camera that sees its printed face
    in the usual orientation). Inner corner ``(col, row)`` is at ``(col * square, row *
    square, 0)``. There are ``(inner_cols + 1) x (inner_rows + 1)`` squares; the one at the top
    left (containing ``(-square/2, -square/2)``) is black.

    Examples
    --------
    >>> board = Checkerboard(9, 6, 0.025)
    >>> board.object_points().shape
    (54, 3)
    >>> board.object_points()[10]    # column 1 of row 1
    array([0.025, 0.025, 0.   ])
    """

    inner_cols: int
    inner_rows: int
    square: float
    margin: float | None = None

    def __post_init__(self) -> None:
        cols = as_positive_int(self.inner_cols, "inner_cols")
        rows = as_positive_int(self.inner_rows, "inner_rows")
        if cols < 2 or rows < 2:
            raise ParameterError(
                f"inner_cols, inner_rows: expected at least 2x2 inner corners, got {cols}x{rows}"
            )
        object.__setattr__(self, "inner_cols", cols)
        object.__setattr__(self, "inner_rows", rows)
        object.__setattr__(self, "square", as_positive_float(self.square, "square"))
        margin = self.square if self.margin is None else as_finite_float(self.margin, "margin")
        if margin < 0:
            raise ParameterError(f"margin: expected a value >= 0, got {margin}")
        object.__setattr__(self, "margin", margin)

    @property
    def n_corners(self) -> int:
        return self.inner_cols * self.inner_rows

    def object_points(self) -> np.ndarray:
        """Inner corners in the board frame, (N, 3), row by row (column index fastest)."""
        c, r = np.meshgrid(np.arange(self.inner_cols), np.arange(self.inner_rows))
        return np.stack([c.ravel() * self.square, r.ravel() * self.square, np.zeros(c.size)], axis=-1)

    def extent(self) -> tuple[float, float, float, float]:
        """``(u_min, v_min, u_max, v_max)`` of the printed sheet (squares plus margin), metres."""
        s, m = self.square, self.margin
        return (-s - m, -s - m, self.inner_cols * s + m, self.inner_rows * s + m)
