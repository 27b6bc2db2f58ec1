"""The contract every calibration target keeps, and the registry of targets by name.

A target is a frozen, slotted dataclass that knows three things about itself:

- its points: ``object_points() -> (N, 3)`` in the target frame (metres, z = 0 on a planar
  target), point ``i`` carrying id ``i``;
- how to find them: ``detect(image) -> Detection``, the points seen with their ids, pixels
  and per-point sigma, or "not found" with the reason;
- what to print: ``sheet() -> Sheet``, its black marks on white paper in the target frame,
  from which :mod:`camkit.target.sheet` writes PDF, SVG and PNG files and :mod:`camkit.render`
  renders any target it has no faster path for.

Calibration, the simulator and the board printer see targets only through this contract. A new
target is one module with one class and its ``@register_target`` line (docs/extending.md).
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import Any, ClassVar, Self, TypeVar

import numpy as np

from camkit._registry import Registry
from camkit._repr import summary_repr
from camkit._validate import as_positive_float
from camkit.errors import ParameterError

__all__ = ["TARGETS", "Detection", "Sheet", "Target", "get_target", "register_target"]


@dataclass(frozen=True, slots=True, eq=False)
class Detection:
    """The points of a target found in one image.

    Attributes
    ----------
    found : bool
        The target was identified (some points may still be missing).
    corners : ndarray, (N, 2)
        Pixel positions in the order of ``target.object_points()`` (row ``i`` is point id
        ``i``); NaN rows for points not seen (covered, outside the image, not checked).
    sigma_px : ndarray, (N,)
        Per-point standard deviation of the position, per axis (NaN where not seen): from the
        sub-pixel fit, and for the checkerboard the larger of that and what the image's
        measured noise leaves, grown by the reading of the light's gradient across it, or the
        symmetric point's where a corner was moved there (see
        :func:`camkit.target.detect_corners`, steps 8-9).
    window_px : int
        Half-size of the sub-pixel window chosen for this image (0 where none was).
    message : str
        What was found, or why nothing was.
    board_seen : (int, int) or None
        Where the target was not found because the image shows a whole board of another size
        (a checkerboard's lattice of corners with the board's border seen on all four sides):
        that board's points along its two axes (for a checkerboard, its inner corners, in the
        order of the target's ``cols x rows`` where the two can be told apart); else None.
    """

    found: bool
    corners: np.ndarray
    sigma_px: np.ndarray
    window_px: int
    message: str
    board_seen: tuple[int, int] | None = None

    def __repr__(self) -> str:
        return summary_repr(self, n_found=self.n_found)

    @property
    def ids(self) -> np.ndarray:
        """Ids of the points seen, (M,) int64, ascending."""
        return np.flatnonzero(np.isfinite(self.corners).all(axis=1))

    @property
    def pixels(self) -> np.ndarray:
        """Pixel positions of the points seen, (M, 2), in the order of :attr:`ids`."""
        return self.corners[self.ids]

    @property
    def sigma(self) -> np.ndarray:
        """Per-point sigma of the points seen, (M,), in the order of :attr:`ids`."""
        return self.sigma_px[self.ids]

    @property
    def n_found(self) -> int:
        return int(np.isfinite(self.corners).all(axis=1).sum())

    @classmethod
    def not_found(cls, n_points: int, message: str, window_px: int = 0,
                  board_seen: tuple[int, int] | None = None) -> Detection:
        """A detection of nothing, with the reason (and the size of a whole board of another
        size seen, where one was)."""
        return cls(False, np.full((n_points, 2), np.nan), np.full(n_points, np.nan), window_px, message, board_seen)


#: The largest raster side :meth:`Sheet.raster` and :meth:`Sheet.coverage` make (pixels).
MAX_RASTER_SIDE = 32768


def _density(px_per_m: Any, extent: tuple[float, float, float, float]) -> float:
    d = as_positive_float(px_per_m, "px_per_m")
    side = max(extent[2] - extent[0], extent[3] - extent[1]) * d
    if side > MAX_RASTER_SIDE:
        raise ParameterError(f"px_per_m: expected at most {MAX_RASTER_SIDE} pixels a side, got {side:.0f} "
                             f"({d:g} px/m over the sheet's {max(extent[2] - extent[0], extent[3] - extent[1]):g} m)")
    return d


@dataclass(frozen=True, slots=True, eq=False)
class Sheet:
    """A target's printed face: black axis-aligned rectangles on white paper.

    Attributes
    ----------
    extent : tuple of 4 floats
        ``(u_min, v_min, u_max, v_max)`` of the paper in the target frame, metres (x along u,
        y along v; the target's z = 0 plane).
    black : ndarray, (K, 4)
        ``(u0, v0, u1, v1)`` of each black rectangle, metres, target frame.
    label : str
        One line printed under the target (what it is, its size, "print at 100 %").
    v_up : bool
        False (the default): the target's y axis runs down the printed page, so its z axis
        points away from a camera that sees the printed face (OpenCV's boards). True: y runs
        up the page and z points at such a camera (Kalibr's AprilGrid). The printed page and
        :meth:`raster` follow it; :meth:`coverage` is always in the target frame.
    """

    extent: tuple[float, float, float, float]
    black: np.ndarray
    label: str
    v_up: bool = False

    def page_marks(self) -> np.ndarray:
        """The black rectangles as the page shows them, (K, 4): ``(u0, v0, u1, v1)`` with v
        measured down the page from the extent's ``v_min`` (the target frame's own rectangles
        unless :attr:`v_up`, where they are mirrored top to bottom within the extent)."""
        if not self.v_up:
            return self.black
        lo, hi = self.extent[1], self.extent[3]
        b = self.black
        return np.stack([b[:, 0], lo + hi - b[:, 3], b[:, 2], lo + hi - b[:, 1]], axis=-1)

    def raster(self, px_per_m: float) -> np.ndarray:
        """The printed page as a uint8 image (255 white, 0 black), ``px_per_m`` pixels per
        metre, the pixel grid aligned with the extent's top-left (pixel ``(i, j)`` covers
        ``u_min + [j, j + 1] / px_per_m`` and, down the page, :meth:`page_marks`' ``v_min + [i,
        i + 1] / px_per_m``). Rectangle edges are rounded to whole pixels: choose a density
        where the marks' sizes are whole numbers of pixels for an exact raster."""
        px_per_m = _density(px_per_m, self.extent)
        u0, v0, u1, v1 = self.extent
        W = max(1, round((u1 - u0) * px_per_m))
        H = max(1, round((v1 - v0) * px_per_m))
        img = np.full((H, W), 255, dtype=np.uint8)
        r = np.rint((self.page_marks() - [u0, v0, u0, v0]) * px_per_m).astype(np.int64)
        r[:, [0, 2]] = np.clip(r[:, [0, 2]], 0, W)
        r[:, [1, 3]] = np.clip(r[:, [1, 3]], 0, H)
        for a, b, c, d in r:  # one slice per mark, not per pixel
            img[b:d, a:c] = 0
        return img

    def coverage(self, px_per_m: float) -> np.ndarray:
        """The fraction of each texel the marks cover, float64 in [0, 1], texel ``(i, j)``
        covering ``(u_min, v_min) + ([j, j + 1], [i, i + 1]) / px_per_m`` in the target frame
        (:meth:`raster`'s grid unless :attr:`v_up`): exact box-filtered area, so an edge
        between texel boundaries keeps its position (a texture that rounds it to a boundary
        moves corners by up to half a texel)."""
        px_per_m = _density(px_per_m, self.extent)
        u0, v0, u1, v1 = self.extent
        W = max(1, round((u1 - u0) * px_per_m))
        H = max(1, round((v1 - v0) * px_per_m))
        out = np.zeros((H, W))
        r = (self.black - [u0, v0, u0, v0]) * px_per_m
        for a, b, c, d in r:  # one block per mark: the outer product of its 1-D edge coverages
            ja, jc = max(int(np.floor(a)), 0), min(int(np.ceil(c)), W)
            ib, id_ = max(int(np.floor(b)), 0), min(int(np.ceil(d)), H)
            if ja >= jc or ib >= id_:
                continue
            j = np.arange(ja, jc)
            i = np.arange(ib, id_)
            cx = np.clip(np.minimum(c, j + 1) - np.maximum(a, j), 0.0, 1.0)
            cy = np.clip(np.minimum(d, i + 1) - np.maximum(b, i), 0.0, 1.0)
            out[ib:id_, ja:jc] += cy[:, None] * cx[None, :]
        return np.minimum(out, 1.0)


class Target(abc.ABC):
    """Base of every calibration target; see the module docstring for the contract.

    Subclasses are frozen, slotted dataclasses with the class attribute ``name`` (the registry
    key) and implement :meth:`object_points`, :meth:`detect`, :meth:`sheet` and
    :meth:`example`.
    """

    __slots__ = ()

    name: ClassVar[str]

    @abc.abstractmethod
    def object_points(self) -> np.ndarray:
        """The target's points in its own frame, (N, 3), metres; row ``i`` is id ``i``."""

    @property
    def n_points(self) -> int:
        return int(self.object_points().shape[0])

    @abc.abstractmethod
    def detect(self, image: np.ndarray) -> Detection:
        """The target's points in ``image`` (grey or colour, any dtype camkit reads)."""

    @abc.abstractmethod
    def sheet(self) -> Sheet:
        """The printed face."""

    def extent(self) -> tuple[float, float, float, float]:
        """``(u_min, v_min, u_max, v_max)`` of the printed sheet, metres, target frame."""
        return self.sheet().extent

    def to_dict(self) -> dict[str, Any]:
        """``{"type": name, and every field by name}``: what a dataset's truth records."""
        import dataclasses

        return {"type": self.name, **{f.name: getattr(self, f.name) for f in dataclasses.fields(self)}}  # type: ignore[arg-type]

    def size_note(self) -> str:
        """What a user should check when the target is not found: its size as they gave it
        (completes "Check the ...")."""
        return f"target's size and layout ({self!r})"

    def seen_note(self, board_seen: tuple[int, int]) -> str:
        """A whole board of another size that a detection saw (:attr:`Detection.board_seen`),
        in the target's own terms (completes "a whole board of ...")."""
        return f"{board_seen[0]}x{board_seen[1]} points"

    @classmethod
    @abc.abstractmethod
    def example(cls) -> Self:
        """A typical instance: what the command line, the demo and the contract test use."""


TARGETS: Registry = Registry("target")  # name -> Target subclass

_T = TypeVar("_T", bound="type[Target]")


def register_target(cls: _T) -> _T:
    """Class decorator: add a target to :data:`TARGETS` under its ``name``."""
    return TARGETS.register(cls)


def get_target(name: Any) -> type[Target]:
    """The target class registered as ``name`` (for example ``"checkerboard"``)."""
    return TARGETS.lookup(name)
