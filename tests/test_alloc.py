"""camkit._alloc.work_array: large work arrays on memory not advised for huge pages."""

from __future__ import annotations

import gc
import os
import sys

import numpy as np
import pytest

from camkit._alloc import _HUGE_ADVICE_BYTES, scratch, work_array


def _mapping(addr: int) -> tuple[int, int, list[str]] | None:
    """``(start, end, VmFlags)`` of this process's mapping that holds ``addr``
    (/proc/self/smaps), or None where none does."""
    span = None
    with open("/proc/self/smaps") as f:
        for line in f:
            head = line.split()[0]
            if "-" in head and not head.endswith(":"):
                lo, hi = (int(x, 16) for x in head.split("-"))
                span = (lo, hi) if lo <= addr < hi else None
            elif span is not None and head == "VmFlags:":
                return span[0], span[1], line.split()[1:]
    return None


def _page_inside(a: np.ndarray) -> int:
    """The address of the first whole page inside ``a``'s data."""
    return (a.ctypes.data + 4095) // 4096 * 4096


def test_a_large_work_array_is_ordinary_memory_of_its_shape():
    """Shape, dtype, writable, C-contiguous, aligned to a page; small ones are ``np.empty``'s;
    ``touched`` leaves it usable; scratch hands out one where its bound is passed."""
    for shape, dt in (((1500, 1000), np.float64), ((3000, 4000), np.uint8), ((7,), np.int64), ((0, 5), np.float64)):
        a = work_array(shape, dt, touched=True)
        assert a.shape == shape and a.dtype == dt and a.flags.writeable and a.flags.c_contiguous
        a[...] = 3
        assert (a == 3).all()
    big = work_array((1500, 1000), np.float64)
    assert big.ctypes.data % 4096 == 0
    assert work_array((10, 10), np.float64).base is None  # np.empty's own
    assert big.nbytes >= _HUGE_ADVICE_BYTES
    assert work_array((1000, 500), np.float64).base is None  # 4 MB: under NumPy's advice
    huge = scratch("test-alloc", (2000, 2000), np.float64)  # past SCRATCH_MAX_BYTES: made afresh
    assert huge.shape == (2000, 2000)
    if sys.platform.startswith("linux"):
        assert huge.base is not None  # a work array's own mapping


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux only: elsewhere np.empty's own error")
def test_a_work_array_too_large_for_memory_is_a_memory_error():
    """As ``np.empty`` says it: MemoryError, naming the size and shape (not the mapping's OSError)."""
    for shape in ((2**20, 2**20), (2**40, 2**30)):  # 8 TiB; past any address space
        with pytest.raises(MemoryError, match="work array with shape"):
            work_array(shape, np.float64)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux only: /proc/self/smaps and MADV_HUGEPAGE")
def test_large_work_arrays_are_not_advised_for_huge_pages_and_are_returned():
    """NumPy marks its arrays of 4 MiB or more MADV_HUGEPAGE ("hg" in the mapping's VmFlags);
    a work array of that size is on a mapping without it, and the mapping goes when the array
    does (no memory kept)."""
    a = work_array((1024, 1024), np.float64)  # 8 MiB
    at = _page_inside(a)
    m = _mapping(at)
    assert m is not None and "hg" not in m[2], m
    assert m[1] - m[0] >= a.nbytes  # its own mapping
    # The check can tell: NumPy's own array of the same size carries the advice, where NumPy
    # gives it (NUMPY_MADVISE_HUGEPAGE unset, kernel 4.6 or later, built with huge pages).
    from numpy._core import multiarray

    if multiarray._get_madvise_hugepage() and os.path.isdir("/sys/kernel/mm/transparent_hugepage"):
        b = np.empty((1024, 1024))
        mb = _mapping(_page_inside(b))
        assert mb is not None and "hg" in mb[2], mb
    del a
    gc.collect()
    assert _mapping(at) != m  # unmapped with the array
