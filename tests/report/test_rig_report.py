"""The rig report (issue 24, item 3): its sections, and bad input refused."""

from __future__ import annotations

import numpy as np
import pytest

from camkit.calib import calibrate_rig
from camkit.errors import ParameterError
from camkit.geometry.pose import Pose
from camkit.lens import BrownConrady
from camkit.render import simulate_rig
from camkit.report import write_rig_report
from camkit.target import Checkerboard


@pytest.fixture(scope="module")
def rig_and_pair():
    cam = BrownConrady(fx=300.0, fy=300.0, cx=159.5, cy=119.5, width=320, height=240, k1=-0.05)
    board = Checkerboard(inner_cols=6, inner_rows=4, square=0.03)
    poses = [Pose.identity(), Pose.from_rvec([0.0, -0.01, 0.0], [-0.1, 0.0, 0.0])]
    inst = simulate_rig([cam, cam], poses, board, 6, seed=0, fill=(0.5, 0.6))
    rng = np.random.default_rng(0)
    views = [[i.corners_px[c] + rng.normal(0, 0.05, i.corners_px[c].shape) for i in inst] for c in range(2)]
    return calibrate_rig(views, board, sizes=(320, 240), names=("l", "r")), inst[0].images


def test_sections_and_atomic_write(rig_and_pair, tmp_path):
    rig, pair = rig_and_pair
    path = write_rig_report(tmp_path / "rig.html", rig, pair=pair, instant_names=[f"i{k}" for k in range(6)])
    text = path.read_text()
    for head in ("The rig", "The rig from above", "RMS per instant", "A rectified pair", "Camera l", "Camera r"):
        assert f"<h2>{head}" in text
    assert text.count("data:image/png;base64,") == 3
    assert not list(tmp_path.glob("*.tmp*"))
    # Without a pair, no rectified section.
    assert "A rectified pair" not in write_rig_report(tmp_path / "b.html", rig).read_text()


def test_bad_input(rig_and_pair, tmp_path):
    rig, pair = rig_and_pair
    with pytest.raises(ParameterError, match="result"):
        write_rig_report(tmp_path / "x.html", rig.cameras[0])
    with pytest.raises(ParameterError, match="pair"):
        write_rig_report(tmp_path / "x.html", rig, pair=[pair[0][:100], pair[1]])
    with pytest.raises(ParameterError, match="instant_names"):
        write_rig_report(tmp_path / "x.html", rig, instant_names=["a"])
