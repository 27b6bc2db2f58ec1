"""Compile (into numba's on-disk cache) the kernels of the calibration pipeline: detection,
thumbnails, projection with Jacobians; and let matplotlib build its font cache.
``camkit demo`` runs this in a second process on a first run, so compilation overlaps with
rendering on another core; once the caches are filled it only loads and exits. Run as
``python -m camkit._warm``.

It first compiles the kernels that the demo's renderer meets last in its first view (Malvar
demosaicing, rotation to a vector): the renderer is still compiling its own when they are
done, and numba looks in its cache when a kernel is first called, so the main process loads
them instead of compiling them a second time (benchmarks/notes.md, issue 20)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np


def warm_render_tail() -> None:
    from camkit.geometry.rotation import rvec_from_matrix
    from camkit.sensor.demosaic import demosaic

    demosaic(np.full((8, 8), 1000, dtype=np.uint16), "RGGB", "malvar")
    rvec_from_matrix(np.eye(3))


def warm_pipeline() -> None:
    import matplotlib.font_manager  # noqa: F401 - a first import builds matplotlib's font cache

    from camkit.io import read_image, write_png
    from camkit.lens import BrownConrady
    from camkit.resample import resize
    from camkit.target import Checkerboard, detect_corners

    # A fronto-parallel 5x4 board drawn with NumPy (no render kernels), 24 px squares.
    sq, cols, rows = 24, 6, 5
    yy, xx = np.mgrid[0:rows * sq + 2 * sq, 0:cols * sq + 2 * sq]
    u, v = (xx - sq) // sq, (yy - sq) // sq
    inside = (u >= 0) & (u < cols) & (v >= 0) & (v < rows)
    img = np.where(inside & ((u + v) % 2 == 0), 30, 220).astype(np.uint8)
    rgb = np.repeat(img[:, :, None], 3, axis=2)
    with tempfile.TemporaryDirectory() as tmp:
        back = read_image(write_png(Path(tmp) / "w.png", rgb))
    detect_corners(back, Checkerboard(cols - 1, rows - 1, 0.03))
    resize(back, width=40, height=30, interpolation="area")
    cam = BrownConrady(fx=500.0, fy=500.0, cx=100.0, cy=80.0, width=200, height=160, k1=-0.1)
    pts = np.array([[0.01, 0.02, 1.0], [-0.1, 0.05, 0.8]])
    cam.project_with_jacobian(pts)
    cam.unproject(cam.project(pts))


if __name__ == "__main__":  # pragma: no cover - run in a child process
    warm_render_tail()
    warm_pipeline()
