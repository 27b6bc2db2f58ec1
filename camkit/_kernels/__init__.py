"""Numba kernels on plain, contiguous float64 arrays. No validation lives here.

Every kernel is ``@njit(cache=True, nogil=True, error_model="numpy")``: IEEE inf and NaN,
never a Python exception from inside a kernel; ``parallel=True`` where the work is large.
Public functions validate, reshape to the kernel's layout, call it and reshape back.
"""
