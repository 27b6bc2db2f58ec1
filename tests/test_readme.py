"""The README's Python examples run as printed, from the checkout, and give the values their
comments state."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BLOCKS = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)


def _run(block: str, monkeypatch) -> dict:
    monkeypatch.chdir(ROOT)              # the examples' paths are relative to the checkout
    namespace: dict = {"__name__": "readme"}
    exec(compile(block, "README.md", "exec"), namespace)
    return namespace


def _block(word: str) -> str:
    found = [b for b in BLOCKS if word in b]
    assert len(found) == 1, f"README.md: expected one Python block using {word}, found {len(found)}"
    return found[0]


def test_the_taste_runs_and_gives_its_values(monkeypatch):
    ns = _run(_block("depth_of_field"), monkeypatch)
    assert ns["cam"].fov_deg().horizontal_deg == pytest.approx(39.5978, abs=1e-4)   # "39.597..."
    near, far = ns["depth_of_field"](0.050, 2.0, 3.0, 0.03e-3)
    assert (round(near, 2), round(far, 2)) == (2.80, 3.23)


def test_the_stereo_example_runs_on_the_bumblebee_pairs(shared_data, monkeypatch):
    ns = _run(_block("calibrate_rig"), monkeypatch)
    rig = ns["rig"]
    # The comments' values: a Bumblebee2's baseline is 12 cm (Point Grey's specification).
    assert rig.baseline_m[1] == pytest.approx(0.1202, abs=5e-4)
    assert rig.baseline_sigma_m[1] == pytest.approx(0.00008, abs=5e-5)
    assert ns["points"].points.shape == (24, 3) and ns["points"].covariance.shape == (24, 3, 3)


def test_every_python_block_is_run_by_a_test():
    assert len(BLOCKS) == 2, "README.md has a new Python block: run it in tests/test_readme.py"
