"""The Brown-Conrady lens: radial and tangential distortion, with OpenCV's rational and
thin-prism terms."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from camkit._kernels import brown_conrady as brown_conrady_kernels
from camkit._kernels import maps as maps_kernels
from camkit._validate import as_points
from camkit.lens.base import CameraModel, register_model

__all__ = ["BrownConrady"]

# Newton stops when the pixel residual is below this; the promise is 1e-9 px.
_TOL_PX = 1e-10


@register_model
@dataclass(frozen=True, slots=True, kw_only=True)
class BrownConrady(CameraModel):
    """Pinhole projection followed by Brown-Conrady distortion, as OpenCV models it.

    With ideal normalised coordinates ``x = X/Z, y = Y/Z`` and ``r^2 = x^2 + y^2``::

        rad = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
        xd  = x rad + 2 p1 x y + p2 (r^2 + 2 x^2) + s1 r^2 + s2 r^4
        yd  = y rad + p1 (r^2 + 2 y^2) + 2 p2 x y + s3 r^2 + s4 r^4
        u   = fx xd + skew yd + cx,   v = fy yd + cy

    The polynomial maps **ideal to distorted** coordinates, so ``project`` is a direct
    evaluation and ``unproject`` ("correcting" a distorted point) solves the equations by
    Newton's method (D. C. Brown, "Decentering distortion of lenses", Photogrammetric
    Engineering 32(3), 1966; A. E. Conrady, MNRAS 79, 1919; the rational and thin-prism terms
    as in OpenCV's calib3d documentation).

    The map is only a lens where it is one-to-one. The model computes the largest disk of
    ideal radius ``r_valid`` on which it is (positive rational denominator, positive Jacobian
    determinant, distorted radius growing outward, sampled over 64 directions), searched up to
    three times the image's corner radius. Outside that disk ``project`` and ``unproject``
    return NaN rows rather than a silently wrong answer.

    Parameters
    ----------
    fx, fy, cx, cy, skew : float
        Intrinsics in pixels; pixel (0, 0) is the centre of the top-left pixel.
    width, height : int
        Image size in pixels.
    k1, k2, k3 : float
        Radial numerator coefficients.
    p1, p2 : float
        Tangential (decentering) coefficients.
    k4, k5, k6 : float
        Radial denominator (rational model) coefficients.
    s1, s2, s3, s4 : float
        Thin-prism coefficients.

    Examples
    --------
    >>> cam = BrownConrady(fx=800.0, fy=800.0, cx=319.5, cy=239.5, width=640, height=480,
    ...                    k1=-0.25, k2=0.1)
    >>> px = cam.project([[0.3, 0.2, 1.0]])
    >>> bool(abs(cam.project(cam.unproject(px)) - px).max() < 1e-9)
    True
    """

    name: ClassVar[str] = "brown-conrady"
    param_names: ClassVar[tuple[str, ...]] = (
        "fx", "fy", "cx", "cy", "skew",
        "k1", "k2", "k3", "p1", "p2", "k4", "k5", "k6", "s1", "s2", "s3", "s4",
    )
    #: Held by calibration unless freed: skew, and the terms beyond k1, k2, p1, p2, k3 (OpenCV's
    #: default 5-coefficient model).
    default_fixed: ClassVar[tuple[str, ...]] = ("skew", "k4", "k5", "k6", "s1", "s2", "s3", "s4")
    linear_start_terms: ClassVar[tuple[str, ...]] = ("k1", "k2")
    param_groups: ClassVar[dict[str, tuple[str, ...]]] = {
        "focal": ("fx", "fy"),
        "principal_point": ("cx", "cy"),
        "skew": ("skew",),
        "radial": ("k1", "k2", "k3"),
        "tangential": ("p1", "p2"),
        "rational": ("k4", "k5", "k6"),
        "thin_prism": ("s1", "s2", "s3", "s4"),
        "distortion": ("k1", "k2", "k3", "p1", "p2", "k4", "k5", "k6", "s1", "s2", "s3", "s4"),
    }

    fx: float
    fy: float
    cx: float
    cy: float
    skew: float = 0.0
    width: int
    height: int
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k4: float = 0.0
    k5: float = 0.0
    k6: float = 0.0
    s1: float = 0.0
    s2: float = 0.0
    s3: float = 0.0
    s4: float = 0.0
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def example(cls) -> BrownConrady:
        """1280x960, fx = 1000 px (4.8 um pixels behind a 4.8 mm lens), moderate barrel
        distortion and a little decentring."""
        return cls(fx=1000.0, fy=1000.5, cx=641.3, cy=478.2, k1=-0.25, k2=0.08, k3=-0.01, p1=4e-4, p2=-3e-4,
                   width=1280, height=960)

    def for_points(self, points_cam: Any) -> BrownConrady:
        """A copy whose valid radius is searched only out to 2 % beyond the farthest of these
        camera points' ideal radii (32 directions, 64 steps, each failing step bisected),
        instead of the default scan (64 x 512 directions and steps over three times the image
        corner's radius): an optimiser evaluates its trial models a dozen times per fit and
        needs the model one-to-one only as far as its points reach."""
        pts = as_points(points_cam, 3, "points_cam", finite=False).reshape(-1, 3)
        z = pts[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.hypot(pts[:, 0], pts[:, 1]) / z
        r = r[(z > 0) & np.isfinite(r)]
        coeffs = self._coeffs()
        if r.size == 0 or not coeffs.any():
            return self
        out = copy.copy(self)  # the same validated fields; a cache of its own
        object.__setattr__(out, "_cache", {"r_valid": float(
            brown_conrady_kernels.valid_radius(coeffs, 1.02 * float(r.max()), 32, 64))})
        return out

    def _map_from_rays(self, M: np.ndarray, out: np.ndarray) -> bool:
        maps_kernels.pinhole_to_brown_conrady(np.ascontiguousarray(M, dtype=np.float64), self._intr(), self._coeffs(),
                                     self._r2_valid(), out)
        return True

    # -- plain arrays for the kernels ----------------------------------------------------
    def to_opencv(self) -> tuple[np.ndarray, np.ndarray]:
        """``(K, dist)`` for OpenCV; see :func:`camkit.lens.to_opencv`."""
        from camkit.lens.opencv import to_opencv

        return to_opencv(self)

    def _coeffs(self) -> np.ndarray:
        return np.array([self.k1, self.k2, self.k3, self.k4, self.k5, self.k6,
                         self.p1, self.p2, self.s1, self.s2, self.s3, self.s4])

    def corner_radius(self) -> float:
        """Largest distorted normalised radius of the image's corners (pixel edges)."""
        u = np.array([-0.5, self.width - 0.5])
        v = np.array([-0.5, self.height - 0.5])
        yd = (v - self.cy) / self.fy
        xd = (u[:, None] - self.cx - self.skew * yd[None, :]) / self.fx
        return float(np.sqrt((xd**2 + yd[None, :] ** 2).max()))

    @property
    def valid_radius(self) -> float:
        """Ideal normalised radius ``r_valid`` of the disk on which the model is one-to-one
        (``inf`` without distortion)."""
        r = self._cache.get("r_valid")
        if r is None:
            c = self._coeffs()
            if not c.any():
                r = float("inf")
            else:
                r_search = max(1.5, 3.0 * self.corner_radius())
                r = float(brown_conrady_kernels.valid_radius(c, r_search, 64, 512))
            self._cache["r_valid"] = r
        return r

    def _r2_valid(self) -> float:
        r = self.valid_radius
        return r * r if np.isfinite(r) else np.inf

    def _project_rows(self, pts: np.ndarray) -> np.ndarray:
        out = np.empty((pts.shape[0], 2))
        brown_conrady_kernels.project(pts, self._intr(), self._coeffs(), self._r2_valid(), out)
        return out

    def _unproject_rows(self, px: np.ndarray) -> np.ndarray:
        out = np.empty((px.shape[0], 3))
        tol = _TOL_PX / max(self.fx, self.fy)
        brown_conrady_kernels.unproject(px, self._intr(), self._coeffs(), self._r2_valid(), tol, out)
        return out

    def _jacobian_rows(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        uv, dp, dk = self._jacobian_buffers(pts.shape[0])
        brown_conrady_kernels.project_jacobian(pts, self._intr(), self._coeffs(), self._r2_valid(), uv, dp, dk)
        return uv, dp, dk
