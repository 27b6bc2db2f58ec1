"""Numba kernels on plain, contiguous float64 arrays. No validation lives here.

Every kernel is ``@njit(cache=True, nogil=True)`` and ``parallel=True`` where the work is
large. Public functions validate, reshape to the kernel's layout, call it and reshape back.
"""
