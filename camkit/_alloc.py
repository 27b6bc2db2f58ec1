"""Output arrays for the parallel kernels, and work arrays kept per thread between calls."""

from __future__ import annotations

import math
import mmap
import sys
import threading

import numpy as np

from camkit._kernels import remap as remap_kernels

__all__ = ["new_image", "scratch", "work_array"]


def new_image(shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
    """An output array whose pages are already touched, by both cores (one byte per page), so
    that a parallel kernel writing every pixel does not take a fresh allocation's first-touch
    page faults on one core. benchmarks/notes.md has the measurements that keep it."""
    out = np.empty(shape, dtype=dtype)
    remap_kernels.touch_pages(out.reshape(-1).view(np.uint8))
    return out


#: NumPy advises huge pages for every array of this many bytes or more.
_HUGE_ADVICE_BYTES = 1 << 22


def work_array(shape: tuple[int, ...], dtype: np.dtype | type, touched: bool = False) -> np.ndarray:
    """A work array (contents undefined); one of :data:`_HUGE_ADVICE_BYTES` or more on memory of
    its own that is not advised for huge pages, unmapped when the array goes.

    NumPy advises huge pages for every array of 4 MiB or more (``MADV_HUGEPAGE``). Where the
    kernel's ``transparent_hugepage/defrag`` setting is ``madvise`` (the common default) and no
    huge page is free, each first touch of such memory waits while the kernel compacts memory
    (numpy/numpy issue 31590). A detection's work arrays are fresh memory on every call (glibc
    maps blocks of over 32 MiB afresh and unmaps them when freed: mallopt(3)), so the wait
    comes back call after call; on small pages their first touch costs a little more where
    huge pages are free, and the same every time (a 12 MP and a 2 MP checkerboard detection
    measured: benchmarks/notes.md, fifty-sixth session). Smaller arrays, and other systems,
    get ``np.empty``. ``touched``: the pages faulted in by both cores first
    (:func:`new_image`)."""
    dt = np.dtype(dtype)
    n = math.prod(shape) * dt.itemsize
    if n < _HUGE_ADVICE_BYTES or not sys.platform.startswith("linux"):
        out = np.empty(shape, dtype=dt)
    else:
        try:
            buf = mmap.mmap(-1, n, flags=mmap.MAP_PRIVATE)
        except (OSError, OverflowError) as e:  # as np.empty says it
            raise MemoryError(f"Unable to allocate {n / 2**30:.2f} GiB for a work array with shape {tuple(shape)} "
                              f"and data type {dt} ({e})") from e
        out = np.frombuffer(buf, dtype=dt).reshape(shape)
    if touched:
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
    name is asked for again there. What does not fit is made afresh (:func:`work_array`; ``touched``:
    its pages faulted in by both cores)."""
    n = math.prod(shape) * np.dtype(dtype).itemsize
    bufs = getattr(_SCRATCH, "bufs", None)
    if bufs is None:
        bufs = _SCRATCH.bufs = {}
    buf = bufs.get(name)
    if buf is None or buf.size < n:
        kept = sum(b.size for k, b in bufs.items() if k != name)
        if kept + n > SCRATCH_MAX_BYTES:
            return work_array(shape, dtype, touched)
        buf = bufs[name] = np.empty(n, dtype=np.uint8)
    return buf[:n].view(dtype).reshape(shape)
