"""The Kannala-Brandt fisheye lens (OpenCV's fisheye module)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from camkit._kernels import kannala_brandt as kannala_brandt_kernels
from camkit._kernels import maps as maps_kernels
from camkit.lens.base import CameraModel, register_model

__all__ = ["KannalaBrandt"]

_TOL_PX = 1e-10


@register_model
@dataclass(frozen=True, slots=True, kw_only=True)
class KannalaBrandt(CameraModel):
    """Fisheye lens: the image radius is a polynomial in the angle off the optical axis.

    With ``theta = atan2(sqrt(X^2 + Y^2), Z)`` (valid beyond 90 degrees off-axis)::

        theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
        (xd, yd) = theta_d (X, Y) / sqrt(X^2 + Y^2)
        u = fx xd + skew yd + cx,   v = fy yd + cy

    J. Kannala and S. S. Brandt, "A generic camera model and calibration method for
    conventional, wide-angle, and fish-eye lenses", IEEE TPAMI 28(8), 2006,
    doi:10.1109/TPAMI.2006.153; the same equations as OpenCV's ``cv2.fisheye`` (whose ``alpha``
    is ``skew / fx``). With all ``k = 0`` it is the equidistant projection ``r = f theta``.

    The model is one-to-one while ``theta_d`` increases; ``valid_theta`` is the largest angle
    (at most pi) up to which it does. Beyond it, ``project`` and ``unproject`` give NaN.

    Examples
    --------
    >>> import numpy as np
    >>> cam = KannalaBrandt(fx=300.0, fy=300.0, cx=639.5, cy=479.5, width=1280, height=960,
    ...                     k1=0.01)
    >>> ray = cam.unproject([[1279.0, 479.5]])    # right edge: 117 degrees off-axis
    >>> round(float(np.degrees(np.arccos(ray[0, 2]))), 1)
    117.2
    """

    name: ClassVar[str] = "kannala-brandt"
    param_names: ClassVar[tuple[str, ...]] = ("fx", "fy", "cx", "cy", "skew", "k1", "k2", "k3", "k4")
    #: Held by calibration unless freed: skew (k1..k4 are fitted, as OpenCV's fisheye module does).
    default_fixed: ClassVar[tuple[str, ...]] = ("skew",)
    param_groups: ClassVar[dict[str, tuple[str, ...]]] = {
        "focal": ("fx", "fy"),
        "principal_point": ("cx", "cy"),
        "skew": ("skew",),
        "distortion": ("k1", "k2", "k3", "k4"),
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
    k4: float = 0.0
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def start_projection(cls) -> str:
        return "equidistant"

    @classmethod
    def example(cls) -> KannalaBrandt:
        """1280x960 behind a fisheye lens, fx = 400 px."""
        return cls(fx=400.0, fy=400.2, cx=641.3, cy=478.2, k1=0.02, k2=-0.005, k3=0.001, k4=-0.0002,
                   width=1280, height=960)

    def _map_from_rays(self, M: np.ndarray, out: np.ndarray) -> bool:
        maps_kernels.pinhole_to_kannala_brandt(np.ascontiguousarray(M, dtype=np.float64), self._intr(), self._coeffs(),
                                      self.valid_theta, out)
        return True

    def to_opencv(self) -> tuple[np.ndarray, np.ndarray]:
        """``(K, dist)`` for OpenCV; see :func:`camkit.lens.to_opencv`."""
        from camkit.lens.opencv import to_opencv

        return to_opencv(self)

    def _coeffs(self) -> np.ndarray:
        return np.array([self.k1, self.k2, self.k3, self.k4])

    @property
    def valid_theta(self) -> float:
        """Largest angle off-axis (radians, at most pi) where the model is one-to-one."""
        t = self._cache.get("t_valid")
        if t is None:
            t = float(kannala_brandt_kernels.valid_theta(self._coeffs(), 1 << 16))
            self._cache["t_valid"] = t
        return t

    def _project_rows(self, pts: np.ndarray) -> np.ndarray:
        out = np.empty((pts.shape[0], 2))
        kannala_brandt_kernels.project(pts, self._intr(), self._coeffs(), self.valid_theta, out)
        return out

    def _unproject_rows(self, px: np.ndarray) -> np.ndarray:
        out = np.empty((px.shape[0], 3))
        c = self._coeffs()
        t_valid = self.valid_theta
        td_valid = float(kannala_brandt_kernels.theta_d(t_valid, c)[0])
        tol = _TOL_PX / max(self.fx, self.fy)
        kannala_brandt_kernels.unproject(px, self._intr(), c, t_valid, td_valid, tol, out)
        return out

    def _jacobian_rows(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        uv, dp, dk = self._jacobian_buffers(pts.shape[0])
        kannala_brandt_kernels.project_jacobian(pts, self._intr(), self._coeffs(), self.valid_theta, uv, dp, dk)
        return uv, dp, dk


