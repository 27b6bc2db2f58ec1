"""The built-in demonstration that ``camkit demo`` runs: simulate a realistic calibration
dataset with a known camera, calibrate it through the same path as ``camkit calibrate``, and
compare the estimate with the truth."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from camkit._repr import summary_repr
from camkit.lens.base import CameraModel
from camkit.pipeline import CalibrationJob, calibrate_files
from camkit.render.effects import Defocus, Effects, Exposure
from camkit.target import Checkerboard

__all__ = ["DEMO_BOARD", "DemoResult", "demo_effects", "run_demo"]

#: The demo's board: 9x6 inner corners, 30 mm squares.
DEMO_BOARD = Checkerboard.example()


@dataclass(frozen=True, slots=True)
class DemoResult:
    truth: CameraModel
    job: CalibrationJob
    out_dir: Path
    image_dir: Path

    def __repr__(self) -> str:
        return summary_repr(self)


def demo_effects(camera: CameraModel) -> Effects:
    """What the demo's camera does to light: a 4.8 mm f/2.8 lens focused at 0.45 m (thin-lens
    defocus elsewhere), 20000 photons at white in 10 ms, an EMVA 1288 sensor behind an RGGB
    mosaic, and Malvar-He-Cutler demosaicing (the lens distortion is the camera model's own)."""
    from camkit.sensor import EMVA1288Sensor

    return Effects(defocus=Defocus(focal_length=0.0048, f_number=2.8, focus_distance=0.45,
                                   pixel_pitch=0.0048 / camera.fx),
                   exposure=Exposure(photons_at_white=20000.0, exposure_time=0.01),
                   sensor=EMVA1288Sensor(), cfa="RGGB", demosaic="malvar")


def run_demo(out_dir: str | os.PathLike = "camkit-demo", *, views: int = 15, seed: int = 0,
             progress: Callable[[str, int, int], None] | None = None) -> DemoResult:
    """Simulate ``views`` images of :data:`DEMO_BOARD` through the built-in Brown-Conrady
    camera (``camkit.render.default_camera``) with :func:`demo_effects`, write them to
    ``out_dir/images``, and calibrate them with :func:`camkit.pipeline.calibrate_files`,
    writing ``camera.json``, ``results.json`` and ``report.html`` into ``out_dir``.

    ``progress(stage, done, total)`` is called with stage ``"render"`` and then the
    pipeline's stages."""
    import subprocess
    import sys

    from camkit._validate import as_positive_int
    from camkit.errors import ParameterError
    from camkit.render.dataset import default_camera, simulate_dataset

    views = as_positive_int(views, "views")
    if views < 3:
        raise ParameterError(f"views: expected at least 3 (calibration needs 3 orientations of the board), got {views}")

    # On a first run most of the time is numba compiling; compile the detection side in a
    # second process while this one renders.
    warm = subprocess.Popen([sys.executable, "-m", "camkit._warm"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    truth = default_camera("brown-conrady")
    images = out / "images"

    def render_progress(done: int, total: int) -> None:
        if progress is not None:
            progress("render", done, total)

    simulate_dataset(images, truth, DEMO_BOARD, views, seed=seed, effects=demo_effects(truth),
                     progress=render_progress)
    try:
        warm.wait(timeout=120)
    except subprocess.TimeoutExpired:  # pragma: no cover - never needed in practice
        warm.kill()
    paths = sorted(images.glob("view_*.png"))[:views]
    job = calibrate_files(paths, DEMO_BOARD, camera_file=out / "camera.json", results_file=out / "results.json",
                          report_file=out / "report.html", truth=truth,
                          title="camkit demo: calibration of a simulated camera", progress=progress)
    return DemoResult(truth, job, out, images)
