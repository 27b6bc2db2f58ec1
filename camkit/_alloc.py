"""Output arrays for the parallel kernels, and work arrays kept per thread between calls."""

from __future__ import annotations

import math
import threading

import numpy as np

from camkit._kernels import remap as remap_kernels

__all__ = ["new_image", "scratch"]


def new_image(shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
    """An output array whose pages are already touched, by both cores (one byte per page), so
    that a parallel kernel writing every pixel does not take a fresh allocation's first-touch
    page faults on one core. benchmarks/notes.md has the measurements that keep it."""
    out = np.empty(shape, dtype=dtype)
    remap_kernels.touch_pages(out.reshape(-1).view(np.uint8))
    return out


_SCRATCH = threading.local()

#: :func:`scratch` keeps at most this many bytes per thread (a 12 MP image's marker level,
#: 1000 x 750, needs 6 MB for its integral image and 0.75 MB a mask); what does not fit is made
#: afresh each time.
SCRATCH_MAX_BYTES = 16 << 20


def scratch(name: str, shape: tuple[int, ...], dtype: type, touched: bool = False) -> np.ndarray:
    """A work array of ``shape`` (contents undefined) from this thread's buffer ``name``, kept
    between calls while this thread's buffers fit in :data:`SCRATCH_MAX_BYTES`: a fresh
    allocation's pages are faulted in as they are first written, inside the kernel that writes
    them (benchmarks/notes.md, forty-sixth session, has the measure). Grows where a larger one
    is asked for. A name is one array at a time on its thread: the caller's use of it ends before the
    name is asked for again there. What does not fit is made afresh (``touched``: by
    :func:`new_image`)."""
    n = math.prod(shape) * np.dtype(dtype).itemsize
    bufs = getattr(_SCRATCH, "bufs", None)
    if bufs is None:
        bufs = _SCRATCH.bufs = {}
    buf = bufs.get(name)
    if buf is None or buf.size < n:
        kept = sum(b.size for k, b in bufs.items() if k != name)
        if kept + n > SCRATCH_MAX_BYTES:
            return new_image(shape, np.dtype(dtype)) if touched else np.empty(shape, dtype=dtype)
        buf = bufs[name] = np.empty(n, dtype=np.uint8)
    return buf[:n].view(dtype).reshape(shape)
