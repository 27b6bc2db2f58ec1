"""Lateral chromatic aberration: each colour is magnified slightly differently.

A lens whose refractive index depends on wavelength images red, green and blue at slightly
different scales: colour fringes grow toward the image corners. The model is a radial
magnification of red and blue relative to green, a polynomial in the radius, in the form of
lensfun's ``poly3`` TCA model::

    r_c = r (v_c + c_c r + b_c r^2),   c in {red, blue}

where ``r`` is the distance from the optical centre normalised by half the image diagonal
(here; 1 at the corners of an image centred on the axis) and ``r_c`` where channel ``c``
images a point that green images at ``r``.

The model gives each channel's remap map (:meth:`LateralChromaticAberration.map`); resampling
an image with it is :func:`camkit.resample.apply_chromatic` and
:func:`camkit.resample.correct_chromatic` (the lens room computes where light goes, the
resampling room moves pixels).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from camkit._kernels import chromatic as chromatic_kernels
from camkit._validate import as_finite_float, as_positive_int, check_choice
from camkit.errors import ParameterError

__all__ = ["LateralChromaticAberration"]

_CHANNELS = {"red": 0, "blue": 2}


@dataclass(frozen=True, slots=True, kw_only=True)
class LateralChromaticAberration:
    """Radial magnification of red and blue relative to green (see the module docstring).

    Parameters
    ----------
    vr, cr, br : float
        Red: ``r_red = r (vr + cr r + br r^2)``.
    vb, cb, bb : float
        Blue, likewise.
    cx, cy : float, optional
        Optical centre in pixels; the image centre ``((W - 1)/2, (H - 1)/2)`` by default.

    The magnification ``r s(r)`` must increase with ``r`` out to 1.5 times the image's corner
    radius (else the channel would fold over itself); :meth:`map` checks this.

    Examples
    --------
    >>> import numpy as np
    >>> tca = LateralChromaticAberration(vr=1.001, vb=0.999)
    >>> img = np.zeros((101, 101, 3))
    >>> img[50, 90] = 1.0                       # a white dot 40 px right of the centre
    >>> from camkit.resample import apply_chromatic
    >>> out = apply_chromatic(img, tca, interpolation="bilinear")
    >>> [round(float(np.argmax(out[50, :, ch]) + 0.0), 1) for ch in range(3)]
    [90.0, 90.0, 90.0]
    >>> m = tca.map("red", 101, 101, inverse=True)
    >>> round(float(m[50, 90, 0]) - 50, 4)      # red samples the scene 40/1.001 px out
    39.96
    """

    vr: float = 1.0
    cr: float = 0.0
    br: float = 0.0
    vb: float = 1.0
    cb: float = 0.0
    bb: float = 0.0
    cx: float | None = None
    cy: float | None = None

    def __post_init__(self) -> None:
        for name in ("vr", "cr", "br", "vb", "cb", "bb"):
            object.__setattr__(self, name, as_finite_float(getattr(self, name), name))
        for name in ("vr", "vb"):
            if getattr(self, name) <= 0:
                raise ParameterError(f"{name}: expected a positive scale, got {getattr(self, name)}")
        for name in ("cx", "cy"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, as_finite_float(getattr(self, name), name))

    def _coeffs(self, channel: str) -> tuple[float, float, float]:
        ch = check_choice(channel, tuple(_CHANNELS), "channel")
        return (self.vr, self.cr, self.br) if ch == "red" else (self.vb, self.cb, self.bb)

    def map(self, channel: str, width: int, height: int, *, inverse: bool = False,
            dtype: Any = np.float32) -> np.ndarray:
        """The (H, W, 2) remap map of one channel.

        ``inverse=False`` (correction): output pixel ``p`` samples the observed channel where
        the lens put it, ``centre + (p - centre) s(r)``. ``inverse=True`` (simulation): output
        pixel ``p`` samples the sharp image at the radius that the lens magnifies onto ``p``,
        found by Newton's method to 1e-14 in normalised radius (far below 0.01 px).
        """
        v, c, b = self._coeffs(channel)
        w = as_positive_int(width, "width")
        h = as_positive_int(height, "height")
        dt = np.dtype(dtype)
        if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
            raise ParameterError(f"dtype: expected float32 or float64, got {dt}")
        cx = (w - 1) / 2.0 if self.cx is None else self.cx
        cy = (h - 1) / 2.0 if self.cy is None else self.cy
        norm = np.hypot(w, h) / 2.0
        corners = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [-0.5, h - 0.5], [w - 0.5, h - 0.5]])
        r_hi = 1.5 * float(np.hypot(corners[:, 0] - cx, corners[:, 1] - cy).max()) / norm
        rr = np.linspace(0.0, r_hi, 4097)
        if np.any(v + 2 * c * rr + 3 * b * rr * rr <= 0):
            raise ParameterError(
                f"{channel}: r (v + c r + b r^2) with (v, c, b) = ({v}, {c}, {b}) does not increase "
                f"out to r = {r_hi:.3g} (1.5 times the corner radius): the channel would fold over"
            )
        out = np.empty((h, w, 2), dtype=dt)
        chromatic_kernels.radial_map(cx, cy, norm, v, c, b, bool(inverse), r_hi, out)
        return out

    def channels(self) -> dict[str, int]:
        """The channels the aberration moves, name to RGB index (green is the reference)."""
        return {name: ch for name, ch in _CHANNELS.items() if self._coeffs(name) != (1.0, 0.0, 0.0)}
