"""One place that checks input.

Each helper takes the user's value and the argument's public name, and returns a clean NumPy
array (float64 for geometry) or raises a :class:`~camkit.errors.CamkitError` whose message
names the argument, what was expected and what came.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np

from camkit.errors import ParameterError, ShapeError

__all__ = [
    "as_finite_float",
    "as_matrix",
    "as_points",
    "as_positive_float",
    "as_positive_int",
    "as_real_array",
    "as_rotation_matrix",
    "check_choice",
]

_ROTATION_TOL = 1e-6


def _kind_of(x: Any) -> str:
    if isinstance(x, np.ndarray):
        return f"array of dtype {x.dtype}"
    return type(x).__name__


def as_real_array(x: Any, name: str) -> np.ndarray:
    """Return ``x`` as a float64 array, refusing complex, boolean, object and string input."""
    if isinstance(x, np.ndarray):
        arr = x
    else:
        try:
            arr = np.asarray(x)
        except (ValueError, TypeError) as exc:  # ragged nested sequences
            raise ShapeError(f"{name}: expected a real numeric array, got {_kind_of(x)} ({exc})")\
                from None
    if arr.dtype.kind not in "iuf":
        raise ShapeError(f"{name}: expected a real numeric array, got {_kind_of(arr)}")
    return np.asarray(arr, dtype=np.float64)


def _check_finite(arr: np.ndarray, name: str) -> None:
    if arr.size and not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ParameterError(
            f"{name}: expected finite values, got {arr[tuple(bad)]} at index {tuple(int(i) for i in bad)}"
        )


def as_points(x: Any, k: int, name: str, *, finite: bool = True, nan_rows: bool = False) -> np.ndarray:
    """Return ``x`` as a float64 array of shape ``(..., k)``.

    Parameters
    ----------
    x : array_like, (..., k)
        Points on the last axis.
    k : int
        Required length of the last axis.
    name : str
        Argument name for error messages.
    finite : bool
        Refuse NaN and infinities (the default).
    nan_rows : bool
        Let rows that are entirely NaN through: camkit's own marker for "no value" (a point
        that could not be projected), which mapping functions pass on as NaN rows. A row
        that mixes NaN with numbers, or holds an infinity, is still refused.
    """
    arr = as_real_array(x, name)
    if arr.ndim == 0 or arr.shape[-1] != k:
        raise ShapeError(f"{name}: expected shape (..., {k}), got {arr.shape}")
    if finite and arr.size:
        ok = np.isfinite(arr)
        if not ok.all():
            if nan_rows:
                marker = np.isnan(arr).all(axis=-1, keepdims=True)
                ok |= marker
            if not ok.all():
                bad = tuple(int(i) for i in np.argwhere(~ok)[0])
                note = " (a row entirely NaN is allowed as a 'no value' marker)" if nan_rows else ""
                raise ParameterError(f"{name}: expected finite values{note}, got {arr[bad]} at index {bad}")
    return arr


def as_matrix(x: Any, shape: Sequence[int], name: str, *, finite: bool = True) -> np.ndarray:
    """Return ``x`` as a float64 array of exactly ``shape``."""
    arr = as_real_array(x, name)
    if arr.shape != tuple(shape):
        raise ShapeError(f"{name}: expected shape {tuple(shape)}, got {arr.shape}")
    if finite:
        _check_finite(arr, name)
    return arr


def as_rotation_matrix(x: Any, name: str, *, batched: bool = False) -> np.ndarray:
    """Return ``x`` as float64 rotation matrices, checking orthonormality and det = +1.

    With ``batched=False`` the shape must be exactly (3, 3); with ``batched=True`` it is
    (..., 3, 3). The tolerance is 1e-6 on ``R R^T - I`` (max abs), which admits matrices
    written with 7 significant digits and refuses reflections and shears.
    """
    arr = as_real_array(x, name)
    if batched:
        if arr.ndim < 2 or arr.shape[-2:] != (3, 3):
            raise ShapeError(f"{name}: expected shape (..., 3, 3), got {arr.shape}")
    elif arr.shape != (3, 3):
        raise ShapeError(f"{name}: expected shape (3, 3), got {arr.shape}")
    _check_finite(arr, name)
    if arr.size:
        err = np.abs(arr @ np.swapaxes(arr, -1, -2) - np.eye(3)).max(axis=(-1, -2))
        worst = float(np.max(err))
        if worst > _ROTATION_TOL:
            raise ParameterError(
                f"{name}: expected a rotation matrix (R R^T = I), got max |R R^T - I| = {worst:.3g}"
            )
        det = np.linalg.det(arr)
        if np.any(det < 0):
            raise ParameterError(
                f"{name}: expected a rotation matrix with det(R) = +1, got a reflection "
                f"(det = {float(np.min(det)):.6g})"
            )
    return arr


def as_finite_float(x: Any, name: str) -> float:
    """Return ``x`` as a finite Python float."""
    if type(x) is float and math.isfinite(x):  # the common case, without the ABC checks below
        return x
    if isinstance(x, bool) or not isinstance(x, numbers.Real | np.ndarray):
        raise ParameterError(f"{name}: expected a finite real number, got {_kind_of(x)}")
    if isinstance(x, np.ndarray):
        if x.shape != () or x.dtype.kind not in "iuf":
            raise ParameterError(f"{name}: expected a finite real number, got {_kind_of(x)} "
                                 f"of shape {x.shape}")
        x = x.item()
    value = float(x)
    if not np.isfinite(value):
        raise ParameterError(f"{name}: expected a finite real number, got {value}")
    return value


def as_positive_float(x: Any, name: str) -> float:
    """Return ``x`` as a finite float > 0."""
    value = as_finite_float(x, name)
    if value <= 0:
        raise ParameterError(f"{name}: expected a positive number, got {value}")
    return value


def as_positive_int(x: Any, name: str) -> int:
    """Return ``x`` as a Python int >= 1 (integral floats such as 640.0 are refused)."""
    if isinstance(x, bool) or not isinstance(x, numbers.Integral):
        raise ParameterError(f"{name}: expected a positive integer, got {x!r} ({_kind_of(x)})")
    value = int(x)
    if value < 1:
        raise ParameterError(f"{name}: expected a positive integer, got {value}")
    return value


def check_choice(x: Any, choices: Sequence[str], name: str) -> str:
    """Return ``x`` if it is one of ``choices``; else raise naming the valid ones."""
    if not isinstance(x, str) or x not in choices:
        raise ParameterError(f"{name}: expected one of {', '.join(map(repr, choices))}, got {x!r}")
    return x


IMAGE_DTYPES = (np.uint8, np.uint16, np.float32, np.float64)


def as_image(img: Any, name: str, *, max_channels: int = 4) -> np.ndarray:
    """Return ``img`` as an (H, W) or (H, W, C) array of a supported dtype (uint8, uint16,
    float32, float64), C in 1..max_channels, H and W >= 1. The dtype is kept; data in the other
    byte order are copied to the machine's."""
    if not isinstance(img, np.ndarray):
        raise ShapeError(f"{name}: expected a NumPy array (H, W) or (H, W, C), got {_kind_of(img)}")
    if img.dtype.type not in IMAGE_DTYPES:
        raise ShapeError(
            f"{name}: expected dtype uint8, uint16, float32 or float64, got {img.dtype}"
        )
    if img.ndim not in (2, 3) or (img.ndim == 3 and not 1 <= img.shape[2] <= max_channels):
        raise ShapeError(
            f"{name}: expected shape (H, W) or (H, W, C) with C in 1..{max_channels}, got {img.shape}"
        )
    if img.shape[0] < 1 or img.shape[1] < 1:
        raise ShapeError(f"{name}: expected a non-empty image, got shape {img.shape}")
    if not img.dtype.isnative:   # big-endian data (FITS, np.frombuffer(..., '>u2')): kernels read native order
        img = img.astype(img.dtype.newbyteorder("="))
    return img


def check_same_size(first: tuple[int, ...] | None, img: np.ndarray, name: str, note: str = "") -> tuple[int, ...]:
    """The (H, W) of a series of images: ``img``'s where ``first`` is None, else ``first``
    after checking ``img`` has it (a ShapeError naming ``name``, and ``note`` such as the file
    name, otherwise: one calibration is for one camera mode)."""
    size = tuple(img.shape[:2])
    if first is None:
        return size
    if size != tuple(first):
        raise ShapeError(f"{name}: expected the size of the first image, {first[1]}x{first[0]}, got "
                         f"{size[1]}x{size[0]}{note}; one calibration is for one camera mode")
    return tuple(first)
