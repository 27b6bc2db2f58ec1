"""The pinhole camera: a perspective projection with no distortion."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from camkit._kernels import maps as maps_kernels
from camkit._kernels import transform as transform_kernels
from camkit._validate import as_finite_float, as_positive_float, as_positive_int, as_real_array
from camkit.errors import ParameterError
from camkit.lens.base import CameraModel, register_model

__all__ = ["Pinhole"]


def _pitch_pair(pixel_pitch: Any) -> tuple[float, float]:
    arr = as_real_array(pixel_pitch, "pixel_pitch")
    if arr.shape == ():
        p = as_positive_float(float(arr), "pixel_pitch")
        return p, p
    if arr.shape == (2,):
        return (as_positive_float(float(arr[0]), "pixel_pitch[0]"),
                as_positive_float(float(arr[1]), "pixel_pitch[1]"))
    raise ParameterError(f"pixel_pitch: expected a number or (width, height), got shape {arr.shape}")


@register_model
@dataclass(frozen=True, slots=True, kw_only=True)
class Pinhole(CameraModel):
    """Pinhole camera: ``lambda [u, v, 1]^T = K [X, Y, Z]^T`` with ``K = [[fx, skew, cx],
    [0, fy, cy], [0, 0, 1]]``.

    Parameters
    ----------
    fx, fy : float
        Focal lengths in pixels (> 0): focal length / pixel pitch along x and y.
    cx, cy : float
        Principal point in pixels, pixel (0, 0) at the centre of the top-left pixel.
    skew : float
        ``K[0, 1]``; 0 for every modern sensor.
    width, height : int
        Image size in pixels.

    Examples
    --------
    >>> cam = Pinhole(fx=800.0, fy=800.0, cx=319.5, cy=239.5, width=640, height=480)
    >>> cam.project([[0.1, -0.05, 2.0]])
    array([[359.5, 219.5]])
    >>> cam.unproject_depth([[359.5, 219.5]], 2.0)
    array([[ 0.1 , -0.05,  2.  ]])
    """

    name: ClassVar[str] = "pinhole"
    param_names: ClassVar[tuple[str, ...]] = ("fx", "fy", "cx", "cy", "skew")
    #: Held by calibration unless freed.
    default_fixed: ClassVar[tuple[str, ...]] = ("skew",)
    is_pinhole: ClassVar[bool] = True
    param_groups: ClassVar[dict[str, tuple[str, ...]]] = {
        "focal": ("fx", "fy"),
        "principal_point": ("cx", "cy"),
        "skew": ("skew",),
        "distortion": (),
    }

    fx: float
    fy: float
    cx: float
    cy: float
    skew: float = 0.0
    width: int
    height: int

    @classmethod
    def example(cls) -> Pinhole:
        """1280x960, fx = 1000 px (4.8 um pixels behind a 4.8 mm lens)."""
        return cls(fx=1000.0, fy=1000.5, cx=641.3, cy=478.2, width=1280, height=960)

    def _map_from_rays(self, M: np.ndarray, out: np.ndarray) -> bool:
        maps_kernels.pinhole_to_pinhole(np.ascontiguousarray(M, dtype=np.float64), self._intr(), out)
        return True

    @classmethod
    def from_physical(cls, *, focal_length: float, pixel_pitch: Any, width: int, height: int,
                      principal_point: Any = None, skew: float = 0.0) -> Pinhole:
        """A pinhole camera from the lens's focal length and the sensor's pixel pitch.

        ``fx = focal_length / pitch_x``, ``fy = focal_length / pitch_y``.

        Parameters
        ----------
        focal_length : float
            Metres (a 50 mm lens is 0.050).
        pixel_pitch : float or (float, float)
            Metres per pixel; one number for square pixels or (width, height).
        width, height : int
            Image size in pixels.
        principal_point : (float, float), optional
            Pixels; the image centre ``((width - 1) / 2, (height - 1) / 2)`` by default.

        Examples
        --------
        >>> cam = Pinhole.from_physical(focal_length=0.004, pixel_pitch=2e-6, width=640, height=480)
        >>> round(cam.fx, 9), round(cam.fy, 9), cam.cx, cam.cy
        (2000.0, 2000.0, 319.5, 239.5)
        """
        f = as_positive_float(focal_length, "focal_length")
        px, py = _pitch_pair(pixel_pitch)
        w = as_positive_int(width, "width")
        h = as_positive_int(height, "height")
        if principal_point is None:
            cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
        else:
            pp = as_real_array(principal_point, "principal_point")
            if pp.shape != (2,):
                raise ParameterError(f"principal_point: expected (cx, cy), got shape {pp.shape}")
            cx = as_finite_float(pp[0], "principal_point[0]")
            cy = as_finite_float(pp[1], "principal_point[1]")
        return cls(fx=f / px, fy=f / py, cx=cx, cy=cy, skew=skew, width=w, height=h)

    def focal_length_m(self, pixel_pitch: Any) -> float:
        """The focal length in metres, ``fx * pitch_x`` (the reverse of :meth:`from_physical`).

        Raises :class:`~camkit.errors.ParameterError` when ``fx * pitch_x`` and
        ``fy * pitch_y`` disagree by more than 1e-6 relative: the pitch given does not fit.

        >>> Pinhole(fx=2000.0, fy=2000.0, cx=0.0, cy=0.0, width=8, height=8).focal_length_m(2e-6)
        0.004
        """
        px, py = _pitch_pair(pixel_pitch)
        f_x, f_y = self.fx * px, self.fy * py
        if abs(f_x - f_y) > 1e-6 * max(f_x, f_y):
            raise ParameterError(
                f"pixel_pitch: fx * pitch_x = {f_x:.6g} m but fy * pitch_y = {f_y:.6g} m; "
                "give the pitch as (width, height) for non-square pixels"
            )
        return f_x

    def _project_rows(self, pts: np.ndarray) -> np.ndarray:
        out = np.empty((pts.shape[0], 2))
        transform_kernels.pinhole_project(pts, self.fx, self.fy, self.cx, self.cy, self.skew, out)
        return out

    def _unproject_rows(self, px: np.ndarray) -> np.ndarray:
        out = np.empty((px.shape[0], 3))
        transform_kernels.pinhole_unproject(px, self.fx, self.fy, self.cx, self.cy, self.skew, out)
        return out

    def _jacobian_rows(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        X, Y, Z = pts[:, 0], pts[:, 1], pts[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            iz = np.where(Z > 0, 1.0 / Z, np.nan)
        x, y = X * iz, Y * iz
        n = pts.shape[0]
        uv = np.empty((n, 2))
        uv[:, 0] = self.fx * x + self.skew * y + self.cx
        uv[:, 1] = self.fy * y + self.cy
        dp = np.zeros((n, 2, 3))
        dp[:, 0, 0] = self.fx * iz
        dp[:, 0, 1] = self.skew * iz
        dp[:, 0, 2] = -(self.fx * x + self.skew * y) * iz
        dp[:, 1, 1] = self.fy * iz
        dp[:, 1, 2] = -self.fy * y * iz
        dk = np.zeros((n, 2, 5))
        dk[:, 0, 0] = x
        dk[:, 0, 2] = 1.0
        dk[:, 0, 4] = y
        dk[:, 1, 1] = y
        dk[:, 1, 3] = 1.0
        bad = ~(Z > 0)
        dk[bad] = np.nan
        return uv, dp, dk
