"""Output arrays for the parallel kernels."""

from __future__ import annotations

import numpy as np

from camkit._kernels import remap as remap_kernels

__all__ = ["new_image"]


def new_image(shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
    """An output array whose pages are already touched, by both cores (one byte per page), so
    that a parallel kernel writing every pixel does not take a fresh allocation's first-touch
    page faults on one core. benchmarks/notes.md has the measurements that keep it."""
    out = np.empty(shape, dtype=dtype)
    remap_kernels.touch_pages(out.reshape(-1).view(np.uint8))
    return out
