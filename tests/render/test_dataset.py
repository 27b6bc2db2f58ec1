"""Simulated datasets: planned views, reproducible bytes, truth.json, the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from camkit.cli.main import main
from camkit.errors import EstimationError
from camkit.geometry import Pose
from camkit.render import Effects, Exposure, default_camera, plan_views, simulate_dataset
from camkit.sensor import EMVA1288Sensor
from camkit.target import Checkerboard

BOARD = Checkerboard(9, 6, 0.03)


def test_planned_views_cover_the_image_with_tilted_boards():
    cam = default_camera("brown-conrady")
    poses = plan_views(cam, BOARD, 15, np.random.default_rng(0))
    corners = np.concatenate([cam.project(p.apply(BOARD.object_points())) for p in poses])
    assert np.isfinite(corners).all()
    # Every quarter of the image holds corners, and the corners reach near each border.
    for qx in (0, 1):
        for qy in (0, 1):
            sel = ((corners[:, 0] >= qx * 640) & (corners[:, 0] < (qx + 1) * 640)
                   & (corners[:, 1] >= qy * 480) & (corners[:, 1] < (qy + 1) * 480))
            assert sel.sum() > 50
    assert corners[:, 0].min() < 200 and corners[:, 0].max() > 1080
    tilts = [np.degrees(np.arccos(abs(p.R[2, 2]))) for p in poses]  # angle between board and image plane
    assert min(tilts) >= 9.0 and max(tilts) <= 51.0


def test_same_seed_same_bytes(tmp_path):
    cam = default_camera("pinhole").replace(width=320, height=240, cx=160.0, cy=120.0, fx=250.0, fy=250.0)
    fx = Effects(exposure=Exposure(photons_at_white=5000.0, exposure_time=0.01), sensor=EMVA1288Sensor())
    a = simulate_dataset(tmp_path / "a", cam, BOARD, 3, seed=11, effects=fx)
    b = simulate_dataset(tmp_path / "b", cam, BOARD, 3, seed=11, effects=fx)
    c = simulate_dataset(tmp_path / "c", cam, BOARD, 3, seed=12, effects=fx)
    names = sorted(p.name for p in a.iterdir())
    assert names == ["truth.json", "view_000.png", "view_001.png", "view_002.png"]
    for n in names:
        assert (a / n).read_bytes() == (b / n).read_bytes()
    assert (a / "view_000.png").read_bytes() != (c / "view_000.png").read_bytes()


def test_truth_json_matches_the_render(tmp_path):
    cam = default_camera("brown-conrady")
    out = simulate_dataset(tmp_path, cam, BOARD, 2, seed=5)
    doc = json.loads((out / "truth.json").read_text())
    assert doc["camera"]["type"] == "brown-conrady" and doc["camera"]["k1"] == cam.k1
    v = doc["views"][1]
    pose = Pose.from_rvec(v["cam_from_target"]["rvec"], v["cam_from_target"]["t"])
    expect = cam.project(pose.apply(BOARD.object_points()))
    assert np.allclose(np.array(v["corners_px"]), expect, atol=1e-9)
    img = np.asarray(Image.open(out / v["image"]))
    assert img.shape == (960, 1280) and img.dtype == np.uint8


def test_cli_simulate(tmp_path, capsys):
    rc = main(["simulate", "--views", "2", "--board", "7x5", "--square", "35mm", "--model", "kannala-brandt",
               "--seed", "3", "-o", str(tmp_path), "--noise", "--bayer", "GRBG", "--demosaic", "raw",
               "--bit-depth", "16"])
    assert rc == 0
    doc = json.loads((tmp_path / "truth.json").read_text())
    assert doc["board"] == {"type": "checkerboard", "inner_cols": 7, "inner_rows": 5, "square": 0.035,
                            "margin": 0.035}
    raw = np.asarray(Image.open(tmp_path / "view_000.png"))
    assert raw.ndim == 2 and raw.dtype == np.uint16  # the raw 12-bit mosaic, scaled to 16 bits
    assert doc["bit_depth"] == 16 and doc["sensor_bit_depth"] == 12
    counts = np.round(raw / doc["scale"])  # every sample is a 12-bit count times the recorded scale
    assert counts.max() <= 4095 and np.abs(np.floor(counts * doc["scale"] + 0.5) - raw).max() == 0
    assert "wrote 2 images" in capsys.readouterr().out


def test_impossible_plan_is_refused():
    cam = default_camera("pinhole")
    with pytest.raises(EstimationError, match="could not place view"):
        plan_views(cam, Checkerboard(9, 6, 0.03), 1, np.random.default_rng(0), fill=(3.0, 3.5), max_tries=5)
