"""Is the AVX2 special case of the uint8 RGB halving still paying for itself? (issue 22, item 6)

The same 12 MP bicubic halving timed with ``camkit._kernels.simd_resize.HAS_AVX2`` True and
False, each in its own process with its own numba cache (the choice is made when the kernel is
compiled), the two alternated ``--rounds`` times; the outputs' checksums must be equal.

Run: ``python -m benchmarks.avx2_halving [--rounds 5]`` (on an AVX2 host).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

CHILD = """
import sys, time
import numpy as np
import camkit._kernels.simd_resize as simd
simd.HAS_AVX2 = sys.argv[1] == "1"
from camkit.resample import resize
img = np.random.default_rng(0).integers(0, 256, (3000, 4000, 3), dtype=np.uint8)
out = resize(img, width=2000, height=1500, interpolation="bicubic")
ts = []
for _ in range(15):
    t = time.perf_counter(); resize(img, width=2000, height=1500, interpolation="bicubic")
    ts.append(time.perf_counter() - t)
print(f"{np.median(ts) * 1e3:.3f} {int(out.astype(np.int64).sum())}")
"""


def main() -> None:
    p = argparse.ArgumentParser(prog="python -m benchmarks.avx2_halving")
    p.add_argument("--rounds", type=int, default=5)
    rounds = p.parse_args().rounds
    times: dict[str, list[float]] = {"1": [], "0": []}
    sums = set()
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(rounds):
            for flag in ("0", "1"):
                env = {**os.environ, "NUMBA_CACHE_DIR": os.path.join(tmp, flag)}
                out = subprocess.run([sys.executable, "-c", CHILD, flag], capture_output=True, text=True, env=env,
                                     check=True).stdout.split()
                times[flag].append(float(out[0]))
                sums.add(out[1])
    print(f"AVX2 path: {' '.join(f'{t:.2f}' for t in times['1'])} ms")
    print(f"float path: {' '.join(f'{t:.2f}' for t in times['0'])} ms")
    print("same bytes" if len(sums) == 1 else f"OUTPUTS DIFFER: {sums}")


if __name__ == "__main__":
    main()
