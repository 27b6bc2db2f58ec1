"""The calibration job shared by ``camkit calibrate`` and ``camkit demo``: images in; camera
file, results file and report out."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from camkit.calib.calibrate import CalibrationResult, calibrate_images
from camkit.calib.targets import Checkerboard
from camkit.errors import ParameterError
from camkit.lens.base import CameraModel

__all__ = ["CalibrationJob", "calibrate_files"]


@dataclass(frozen=True, slots=True)
class CalibrationJob:
    result: CalibrationResult
    image_names: list[str]
    camera_file: Path | None
    results_file: Path | None
    report_file: Path | None


def calibrate_files(paths: Sequence[str | os.PathLike], board: Checkerboard, *, model: str = "brown-conrady",
                    camera_file: str | os.PathLike | None = None, results_file: str | os.PathLike | None = None,
                    report_file: str | os.PathLike | None = None, truth: CameraModel | None = None,
                    title: str = "Camera calibration",
                    progress: Callable[[str, int, int], None] | None = None) -> CalibrationJob:
    """Detect, calibrate and write what was asked for (each file atomically).

    ``progress(stage, done, total)`` is called during detection (stage ``"detect"``), then
    with 0 and 1 of 1 around the solve (``"calibrate"``) and the report (``"report"``). No
    output may be one of the inputs."""
    from camkit.io.camera_files import save_camera
    from camkit.io.results import write_results
    from camkit.report import write_report

    files = [Path(p) for p in paths]
    inputs = {f.resolve() for f in files}
    for name, out in (("camera_file", camera_file), ("results_file", results_file), ("report_file", report_file)):
        if out is not None and Path(out).resolve() in inputs:
            raise ParameterError(f"{name}: {out} is one of the input images; camkit never overwrites an input")
    names = [f.name if len({g.name for g in files}) == len(files) else str(f) for f in files]

    def det_progress(done: int, total: int) -> None:
        if progress is not None:
            progress("detect", done, total)
            if done == total:
                progress("calibrate", 0, 1)  # the solve starts when detection ends

    result = calibrate_images(files, board, model=model, progress=det_progress)
    if progress is not None:
        progress("calibrate", 1, 1)
    cam_path = res_path = rep_path = None
    if camera_file is not None:
        cam_path = save_camera(camera_file, result.model, rms_px=result.rms_px,
                               stddev=dict(result.stddev))
    if results_file is not None:
        res_path = write_results(results_file, result, names)
    if report_file is not None:
        if progress is not None:
            progress("report", 0, 1)
        rep_path = write_report(report_file, result, images=files, image_names=names, truth=truth, title=title)
        if progress is not None:
            progress("report", 1, 1)
    return CalibrationJob(result, names, cam_path, res_path, rep_path)
