"""The calibration results file (``camkit calibrate --json``)."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from camkit._atomic import write_atomic
from camkit.errors import ParameterError

__all__ = ["RESULTS_FORMAT_VERSION", "camera_info", "orientation_note", "results_to_dict", "write_results"]

RESULTS_FORMAT_VERSION = 1


def _num(x: float) -> float | None:
    """JSON has no NaN: a value that does not exist is null."""
    return None if not math.isfinite(x) else float(x)


def camera_info(image_info: Sequence[Any] | None) -> dict[str, Any]:
    """The camera and lens the images' EXIF names (make, model, lens, focal length in mm and
    its 35 mm equivalent), from the first image that has each field; and the images whose EXIF
    orientation is not 1 (a viewer shows them turned; camkit works on the stored grid)."""
    out: dict[str, Any] = {}
    turned = []
    for info in image_info or ():
        if info is None:
            continue
        for k, v in info.exif_dict().items():
            if k != "orientation":
                out.setdefault(k, v)
        if info.orientation != 1:
            turned.append({"image": info.path.name, "orientation": int(info.orientation)})
    if turned:
        out["rotated_images"] = turned
    return out


def orientation_note(image_info: Sequence[Any] | None) -> str | None:
    """One sentence for the CLI and the report when some images carry an EXIF orientation other
    than 1, else None."""
    turned = [i for i in image_info or () if i is not None and i.orientation != 1]
    if not turned:
        return None
    names = ", ".join(i.path.name for i in turned[:3]) + (" ..." if len(turned) > 3 else "")
    return (f"{len(turned)} image(s) have EXIF orientation other than 1 ({names}): a viewer shows them turned, "
            "camkit calibrates the stored pixel grid, and the camera file describes that grid")


def results_to_dict(result: Any, image_names: Sequence[str] | None = None,
                    image_info: Sequence[Any] | None = None) -> dict[str, Any]:
    """``{"model": {type, width, height, parameters by name}, "rms_px", "std_px": [x, y],
    "views": [{"image", "found", "n_corners", "rms_px"}], "stddev": {parameter: sigma}}``,
    plus the format version, convergence, rejected corners and views, and per view the pose
    (``cam_from_target`` as a rotation vector and translation, metres) and the camera's
    yaw/pitch/roll relative to the board (degrees).

    ``views`` has one entry per input view (or image): ``found`` is false and ``rms_px`` null
    for a view that was left out. With ``image_info`` (:class:`camkit.io.ImageInfo` per
    image), ``camera_info`` holds the EXIF camera, lens and focal lengths, and each view its
    EXIF ``orientation`` when not 1."""
    from camkit.calib.calibrate import CalibrationResult

    if not isinstance(result, CalibrationResult):
        raise ParameterError(f"result: expected a CalibrationResult, got {type(result).__name__}")
    dets = result.detections
    n_inputs = len(dets) if dets is not None else max((*result.view_indices, *(i for i, _ in
                                                                               result.rejected_views)), default=-1) + 1
    if image_names is not None and len(image_names) != n_inputs:
        raise ParameterError(f"image_names: expected {n_inputs} names, one per input view, got {len(image_names)}")
    names = list(image_names) if image_names is not None else [f"view {i}" for i in range(n_inputs)]
    pos = {v: k for k, v in enumerate(result.view_indices)}
    ypr = result.view_ypr_deg()
    reasons = dict(result.rejected_views)
    views = []
    for i in range(n_inputs):
        entry: dict[str, Any] = {"image": names[i]}
        if i in pos:
            k = pos[i]
            seen = ~(result.residuals[k] != result.residuals[k]).any(axis=1)  # corners used (not NaN)
            pose = result.poses[k]
            entry.update(found=True, n_corners=int(seen.sum()), rms_px=_num(float(result.view_rms_px[k])),
                         rvec=[float(v) for v in pose.rvec], t_m=[float(v) for v in pose.t],
                         camera_ypr_deg=[float(v) for v in ypr[k]])
        else:
            n = dets[i].n_found if dets is not None else int(np.isfinite(result.image_points[i]).all(axis=1).sum())
            entry.update(found=False, n_corners=int(n), rms_px=None, reason=reasons.get(i, ""))
        if image_info is not None and i < len(image_info) and image_info[i] is not None \
                and image_info[i].orientation != 1:
            entry["exif_orientation"] = int(image_info[i].orientation)
        views.append(entry)
    return {
        "format": "camkit-calibration", "version": RESULTS_FORMAT_VERSION,
        "model": result.model.to_dict(),
        "rms_px": _num(result.rms_px), "std_px": [_num(result.std_px[0]), _num(result.std_px[1])],
        "views": views,
        "stddev": {k: _num(v) for k, v in result.stddev.items()},
        "converged": bool(result.converged), "iterations": int(result.iterations), "message": result.message,
        "rejected_corners": [{"view": int(v), "corner": int(c), "reason": r} for v, c, r in result.rejected],
        "rms_definition": "sqrt(mean over corners of dx^2 + dy^2), as OpenCV's calibrateCamera",
        "camera_info": camera_info(image_info),
    }


def write_results(path: str | os.PathLike, result: Any, image_names: Sequence[str] | None = None,
                  image_info: Sequence[Any] | None = None) -> Path:
    """Write :func:`results_to_dict` as JSON, atomically."""
    doc = results_to_dict(result, image_names, image_info)
    return write_atomic(path, (json.dumps(doc, indent=2) + "\n").encode())
