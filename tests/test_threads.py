"""import camkit makes libgomp's idle workers sleep instead of spinning (docs/conventions.md,
"Threads"), unless the user chose a wait policy.

libgomp prints the settings it took at load time when OMP_DISPLAY_ENV=VERBOSE; the spin count
(300000 by default, 0 under OMP_WAIT_POLICY=PASSIVE) tells whether camkit's setting reached it,
which happens only if camkit set it before numba loaded libgomp.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest

SCRIPT = """
import numpy as np
import camkit
from camkit.resample import resize
import numba
resize(np.zeros((64, 64, 3), np.uint8), width=32, height=32)  # a parallel kernel: loads the pool
print("LAYER", numba.threading_layer())
"""


def _run(**env_extra) -> tuple[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMP_", "GOMP_"))}
    env.update(OMP_DISPLAY_ENV="VERBOSE", **env_extra)
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True,
                         timeout=600, env=env)
    layer = re.search(r"LAYER (\w+)", out.stdout).group(1)
    if layer != "omp":
        pytest.skip(f"numba's threading layer here is {layer!r}, not OpenMP: no wait policy to set")
    return out.stderr, layer


def _setting(stderr: str, name: str) -> str:
    m = re.search(rf"{name} = '([^']*)'", stderr)
    assert m, f"libgomp printed no {name}:\n{stderr}"
    return m.group(1)


def test_idle_workers_sleep_by_default():
    stderr, _ = _run()
    assert _setting(stderr, "GOMP_SPINCOUNT") == "0"  # libgomp's own default is 300000


def test_a_policy_the_user_set_wins():
    stderr, _ = _run(OMP_WAIT_POLICY="ACTIVE")
    assert _setting(stderr, "OMP_WAIT_POLICY") == "ACTIVE"
    assert _setting(stderr, "GOMP_SPINCOUNT") != "0"
