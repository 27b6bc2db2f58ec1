"""Remap: sample an image at arbitrary positions given by a map."""

from __future__ import annotations

from typing import Any

import numpy as np

from camkit._alloc import new_image
from camkit._kernels import remap as remap_kernels
from camkit._validate import as_finite_float, as_image, as_real_array, check_choice
from camkit.errors import ParameterError, ShapeError
from camkit.resample.kernels import DEFAULT_BICUBIC_A, interpolation_code

__all__ = ["BORDERS", "remap", "undistort_image"]

BORDERS = ("constant", "replicate", "reflect")


def _fill_vector(fill_value: Any, channels: int) -> np.ndarray:
    f = as_real_array(fill_value, "fill_value")
    if f.shape == ():
        f = np.full(channels, float(f))
    elif f.shape != (channels,):
        raise ShapeError(
            f"fill_value: expected a number or {channels} values (one per channel), got shape {f.shape}"
        )
    if not np.isfinite(f).all():
        raise ParameterError(f"fill_value: expected finite values, got {f.tolist()}")
    return np.ascontiguousarray(f, dtype=np.float64)


def _int_range(dtype: np.dtype) -> tuple[bool, float, float]:
    if dtype.kind == "u":
        info = np.iinfo(dtype)
        return True, float(info.min), float(info.max)
    return False, 0.0, 0.0


def pick_kernel(family: str, method: int, img3: np.ndarray):
    """The kernel for a source of coordinates ('map', 'affine', 'perspective') and a method;
    uint8 RGB has its own kernels: bilinear in two phases per row, whose int32 offsets hold
    images below 2 GiB (larger ones take the general kernel), bicubic and Lanczos-3 compiled
    for 3 channels."""
    if method == 1 and img3.dtype == np.uint8 and img3.shape[2] == 3 and img3.size < 2**31:
        return remap_kernels.BILINEAR_U8C3[family]
    if method >= 2 and img3.dtype == np.uint8 and img3.shape[2] == 3:
        return remap_kernels.RGB[family][method]
    tables = {"map": remap_kernels.REMAP, "affine": remap_kernels.WARP_AFFINE,
              "perspective": remap_kernels.WARP_PERSPECTIVE}
    return tables[family][method]


def accumulator_zero(dtype: np.dtype) -> np.floating:
    """float64 arithmetic for float64 images, float32 for the rest (exact enough for 16-bit
    data: a float32 sum of weighted uint16 values is within 0.01 of the float64 one)."""
    return np.float64(0.0) if dtype == np.float64 else np.float32(0.0)


def sampling_setup(image: Any, interpolation: str, border: str, fill_value: Any, bicubic_a: float):
    """Validate the arguments every resampling function shares; return the image as
    (H, W, C), the kernel code, border code, fill vector and integer output range."""
    img = as_image(image, "image")
    method = interpolation_code(interpolation)
    border_code = BORDERS.index(check_choice(border, BORDERS, "border"))
    a = as_finite_float(bicubic_a, "bicubic_a")
    img3 = img if img.ndim == 3 else img[:, :, None]
    fill = _fill_vector(fill_value, img3.shape[2])
    return img, np.ascontiguousarray(img3), method, border_code, a, fill, _int_range(img.dtype)


def remap(image: np.ndarray, map_xy: Any, *, interpolation: str = "bilinear", border: str = "constant",
          fill_value: Any = 0, bicubic_a: float = DEFAULT_BICUBIC_A) -> np.ndarray:
    """Sample ``image`` at the positions in ``map_xy``: ``out[r, c] = image(map_xy[r, c])``.

    Parameters
    ----------
    image : ndarray, (H, W) or (H, W, C), C in 1..4
        uint8, uint16, float32 or float64.
    map_xy : ndarray, (H_out, W_out, 2), float32 or float64
        ``map_xy[..., 0]`` is x (column), ``map_xy[..., 1]`` is y (row); pixel centres at
        integers. NaN or infinite entries (points no lens maps there) give ``fill_value``.
    interpolation : {"nearest", "bilinear", "bicubic", "lanczos3"}
    border : {"constant", "replicate", "reflect"}
        What taps outside the image read: ``fill_value`` ("constant", which blends into the
        edge pixels as OpenCV's BORDER_CONSTANT does), the nearest edge pixel ("replicate"),
        or the image mirrored about its outer edge, ``c b a | a b c`` ("reflect", OpenCV's
        BORDER_REFLECT, SciPy's "reflect").
    fill_value : float or sequence of C floats
    bicubic_a : float
        Keys' parameter, -0.5 by default (OpenCV uses -0.75).

    Returns
    -------
    ndarray, (H_out, W_out) or (H_out, W_out, C), the dtype of ``image``
        Integer outputs are rounded to nearest and saturated. A map with H_out or W_out = 0
        gives an empty image of that shape.

    Examples
    --------
    >>> import numpy as np
    >>> img = np.arange(12, dtype=np.float64).reshape(3, 4)
    >>> remap(img, np.array([[[1.5, 1.0], [0.0, 2.0]]]))
    array([[5.5, 8. ]])
    """
    img, img3, method, border_code, a, fill, (is_int, lo, hi) = sampling_setup(
        image, interpolation, border, fill_value, bicubic_a)
    if not isinstance(map_xy, np.ndarray) or map_xy.dtype.type not in (np.float32, np.float64):
        got = map_xy.dtype if isinstance(map_xy, np.ndarray) else type(map_xy).__name__
        raise ShapeError(f"map_xy: expected a float32 or float64 array, got {got}")
    if map_xy.ndim != 3 or map_xy.shape[2] != 2:
        raise ShapeError(f"map_xy: expected shape (H_out, W_out, 2), got {map_xy.shape}")
    if not map_xy.dtype.isnative:
        map_xy = map_xy.astype(map_xy.dtype.newbyteorder("="))
    out_shape = (*map_xy.shape[:2], img3.shape[2])
    out = new_image(out_shape, img.dtype)
    if out.size:
        pick_kernel("map", method, img3)(img3, np.ascontiguousarray(map_xy), a, border_code, fill,
                                         is_int, lo, hi, accumulator_zero(img.dtype), out)
    return out if img.ndim == 3 else out[:, :, 0]


def undistort_image(image: np.ndarray, model: Any, new_model: Any = None, *,
                    interpolation: str = "bilinear", border: str = "constant", fill_value: Any = 0,
                    bicubic_a: float = DEFAULT_BICUBIC_A) -> np.ndarray:
    """Remove a lens's distortion: :func:`remap` through
    :func:`camkit.resample.maps.undistort_map` ``(model, new_model)``.

    ``new_model`` defaults to a pinhole with the model's intrinsics and size; choose one with
    :func:`camkit.resample.maps.optimal_pinhole` to keep all pixels (``alpha=1``) or only
    valid ones (``alpha=0``). Output pixels that no source ray reaches get ``fill_value``.
    The image must have the model's size (a ShapeError otherwise).
    """
    from camkit.resample.maps import undistort_map

    img = as_image(image, "image")
    # A model describes the pixels of the image size it was calibrated at; an image of another
    # size (a resized copy, another sensor mode) would be remapped through the wrong pixels.
    width, height = getattr(model, "width", None), getattr(model, "height", None)
    if width is not None and (img.shape[1], img.shape[0]) != (width, height):
        raise ShapeError(f"image: expected {width}x{height} (the size the camera model describes), got "
                         f"{img.shape[1]}x{img.shape[0]}; calibrate the camera at this size")
    return remap(img, undistort_map(model, new_model), interpolation=interpolation, border=border,
                 fill_value=fill_value, bicubic_a=bicubic_a)
