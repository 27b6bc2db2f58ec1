"""The calibration results file (``camkit calibrate --json``)."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from camkit._atomic import write_atomic
from camkit.calib.result import RESULTS_FORMAT_VERSION, CalibrationResult
from camkit.errors import ParameterError

__all__ = ["RESULTS_FORMAT_VERSION", "camera_info", "orientation_note", "results_to_dict", "write_results"]



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
    """:meth:`CalibrationResult.to_dict`, plus what the image files say: with ``image_info``
    (:class:`camkit.io.ImageInfo` per image), ``camera_info`` holds the EXIF camera, lens and
    focal lengths, and each view its EXIF ``orientation`` when not 1."""
    if not isinstance(result, CalibrationResult):
        raise ParameterError(f"result: expected a CalibrationResult, got {type(result).__name__}")
    doc = result.to_dict(image_names)
    for i, entry in enumerate(doc["views"]):
        if image_info is not None and i < len(image_info) and image_info[i] is not None \
                and image_info[i].orientation != 1:
            entry["exif_orientation"] = int(image_info[i].orientation)
    doc["camera_info"] = camera_info(image_info)
    return doc


def write_results(path: str | os.PathLike, result: Any, image_names: Sequence[str] | None = None,
                  image_info: Sequence[Any] | None = None) -> Path:
    """Write :func:`results_to_dict` as JSON, atomically."""
    doc = results_to_dict(result, image_names, image_info)
    return write_atomic(path, (json.dumps(doc, indent=2) + "\n").encode())
