"""Exposure: exposure value, equivalent settings, and motion blur.

An exposure lets light in through an aperture of area proportional to ``1/N^2`` for a time
``t``; the exposure value ``EV = log2(N^2 / t)`` (at ISO 100) is the same for every pair of
settings that admits the same light. One stop is a factor of two.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from camkit._validate import as_real_array
from camkit.errors import ParameterError
from camkit.optics.thin_lens import _out, _positive

__all__ = ["equivalent_exposure", "exposure_value", "motion_blur_px", "relative_exposure_stops"]


def exposure_value(f_number: Any, exposure_time: Any, iso: Any = 100) -> Any:
    """``EV = log2(N^2 / t) - log2(ISO / 100)``: the light-value that meters quote.

    >>> round(exposure_value(16.0, 1 / 125), 2)
    14.97
    """
    N = _positive(f_number, "f_number")
    t = _positive(exposure_time, "exposure_time")
    s = _positive(iso, "iso")
    return _out(np.log2(N * N / t) - np.log2(s / 100.0))


def equivalent_exposure(f_number: Any, exposure_time: Any, *, new_f_number: Any = None,
                        new_exposure_time: Any = None) -> Any:
    """The other half of a setting that admits the same light: give exactly one of
    ``new_f_number`` (returns the exposure time) or ``new_exposure_time`` (returns the
    f-number). ``t / N^2`` is kept: one stop more time is one stop less aperture area.

    >>> equivalent_exposure(8.0, 1 / 250, new_f_number=5.6) * 500    # f/5.6 needs about 1/500 s
    0.98
    >>> round(equivalent_exposure(8.0, 1 / 250, new_exposure_time=1 / 1000), 1)
    4.0
    """
    N = _positive(f_number, "f_number")
    t = _positive(exposure_time, "exposure_time")
    if (new_f_number is None) == (new_exposure_time is None):
        raise ParameterError("give exactly one of new_f_number and new_exposure_time")
    if new_f_number is not None:
        N2 = _positive(new_f_number, "new_f_number")
        return _out(t * (N2 / N) ** 2)
    t2 = _positive(new_exposure_time, "new_exposure_time")
    return _out(N * np.sqrt(t2 / t))


def relative_exposure_stops(f_number_a: Any, exposure_time_a: Any, f_number_b: Any, exposure_time_b: Any,
                            iso_a: Any = 100, iso_b: Any = 100) -> Any:
    """How many stops more exposure setting b gives than setting a:
    ``log2((t_b / N_b^2) ISO_b / ((t_a / N_a^2) ISO_a))``.

    >>> relative_exposure_stops(8.0, 1 / 250, 8.0, 1 / 125)
    1.0
    """
    ea = _positive(exposure_time_a, "exposure_time_a") / _positive(f_number_a, "f_number_a") ** 2
    eb = _positive(exposure_time_b, "exposure_time_b") / _positive(f_number_b, "f_number_b") ** 2
    return _out(np.log2(eb * _positive(iso_b, "iso_b") / (ea * _positive(iso_a, "iso_a"))))


def motion_blur_px(image_velocity_px_per_s: Any, exposure_time: Any) -> Any:
    """Length of the blur streak in pixels: image speed times exposure time.

    ``image_velocity_px_per_s`` may be a speed or a vector on the last axis; the result is its
    length times ``exposure_time``.

    >>> motion_blur_px(2000.0, 1 / 500)
    4.0
    >>> motion_blur_px([300.0, 400.0], 0.01)
    5.0
    """
    v = as_real_array(image_velocity_px_per_s, "image_velocity_px_per_s")
    if not np.isfinite(v).all():
        raise ParameterError("image_velocity_px_per_s: expected finite values")
    t = _positive(exposure_time, "exposure_time")
    speed = np.abs(v) if v.ndim == 0 else np.linalg.norm(v, axis=-1)
    return _out(speed * t)
