"""The simulator: one 1280x960 view, noise-free and with every effect (no peer: absolute
targets from the simulator issue, <= 0.3 s and <= 1.5 s)."""

from __future__ import annotations

import numpy as np

from benchmarks.harness import Case, median_time
from camkit.geometry import Pose
from camkit.lens import LateralChromaticAberration
from camkit.render import Defocus, Effects, Exposure, Motion, default_camera, render_checkerboard, render_view
from camkit.sensor import EMVA1288Sensor
from camkit.target import Checkerboard


def cases() -> list[Case]:
    return []


def extra_tables() -> str:
    cam = default_camera("brown-conrady")  # 1280x960
    board = Checkerboard(9, 6, 0.03)
    pose = Pose.from_ypr(np.radians([20.0, -15.0, 5.0]), [-0.12, -0.07, 0.6])
    every = Effects(
        chromatic=LateralChromaticAberration(vr=1.0006, vb=0.9994),
        defocus=Defocus(focal_length=0.0048, f_number=2.0, focus_distance=0.5, pixel_pitch=4.8e-6),
        motion=Motion(linear_velocity=(0.05, 0.0, 0.0), exposure_time=0.01, samples=5),
        exposure=Exposure(photons_at_white=20000.0, exposure_time=0.01),
        sensor=EMVA1288Sensor(), cfa="RGGB", demosaic="menon")
    plain = median_time(lambda: render_checkerboard(cam, pose, board), repeats=7)
    full = median_time(lambda: render_view(cam, pose, board, every, rng=np.random.default_rng(0)), repeats=5)
    rows = [("render a view, noise-free", plain, 0.3),
            ("render a view, every effect (motion x5, defocus, chromatic, sensor, RGGB, Menon)", full, 1.5)]
    lines = ["| simulator, 1280x960 Brown-Conrady | camkit median | target | |", "|---|---|---|---|"]
    for name, t, target in rows:
        lines.append(f"| {name} | {t:.3f} s | <= {target} s | {'met' if t <= target else 'MISSED'} |")
    return "\n".join(lines) + "\n"
