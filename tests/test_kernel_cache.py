"""Compiled kernels are cached on disk: a second process loads them instead of compiling.

Not a timing test: it reads numba's own cache statistics in a fresh interpreter.
"""

from __future__ import annotations

import json
import subprocess
import sys

SCRIPT = """
import json, numpy as np
from camkit._kernels import remap as remap_kernels
from camkit.resample import remap, warp_perspective
img = np.zeros((8, 8, 3), np.uint8)
remap(img, np.zeros((4, 4, 2), np.float32))                   # uint8 RGB bilinear kernel (SIMD)
remap(img, np.zeros((4, 4, 2), np.float32), interpolation="bicubic")  # uint8 RGB, 3 channels (SIMD)
remap(img.astype(np.float32), np.zeros((4, 4, 2)), interpolation="bicubic")
warp_perspective(img[..., :2], np.eye(3), width=4, height=4, interpolation="lanczos3")
warp_perspective(img, np.eye(3), width=4, height=4, interpolation="lanczos3")
# The detection kernels' serial and parallel twins: one function, two closures (their int is
# in the cache key), each loaded as its own.
from camkit._kernels import markers as markers_kernels
src = np.random.default_rng(0).random((2, 4, 2))
out = np.empty((2, 3, 3))
markers_kernels._fit_homographies_serial(src, src + 1.0, out)
markers_kernels._fit_homographies_parallel(src, src + 1.0, out)
used = [remap_kernels.BILINEAR_U8C3["map"].main, remap_kernels.RGB["map"][2], remap_kernels.REMAP[2], remap_kernels.WARP_PERSPECTIVE[3],
        remap_kernels.RGB["perspective"][3], markers_kernels._fit_homographies_serial,
        markers_kernels._fit_homographies_parallel]
print(json.dumps([[sum(d.stats.cache_hits.values()), sum(d.stats.cache_misses.values())] for d in used]))
"""


def _run() -> list[list[int]]:
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True,
                         timeout=600)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_second_process_loads_kernels_from_cache():
    _run()  # compiles (or loads) and writes the cache
    stats = _run()
    for hits, misses in stats:
        assert hits >= 1 and misses == 0, stats
