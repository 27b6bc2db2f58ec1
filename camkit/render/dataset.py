"""Simulated calibration datasets: views planned as a careful photographer would take them,
rendered with the chosen effects, written with their exact ground truth."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from camkit._atomic import write_atomic
from camkit._validate import as_positive_int
from camkit.errors import EstimationError, ParameterError
from camkit.geometry.pose import Pose
from camkit.geometry.rotation import matrix_from_rvec
from camkit.io.images import write_png
from camkit.lens.base import MODELS, CameraModel, get_model
from camkit.render.effects import Effects, render_view
from camkit.target import Target

__all__ = ["camera_to_dict", "default_camera", "plan_views", "simulate_dataset"]


def plan_views(camera: CameraModel, board: Target, n: int, rng: np.random.Generator, *,
               tilt_deg: tuple[float, float] = (10.0, 50.0), fill: tuple[float, float] = (0.35, 0.6),
               max_tries: int = 200) -> list[Pose]:
    """Poses ``cam_from_target`` for ``n`` views: board centres spread over the image on a
    jittered grid (so corners cover it, corners included), each board tilted by an angle in
    ``tilt_deg`` about a random axis in its plane and rolled at random, at a distance where it
    spans a fraction ``fill`` of the image width, its printed face towards the camera
    (:attr:`~camkit.target.Sheet.v_up`); every inner corner visible.
    """
    n = as_positive_int(n, "n")
    if not isinstance(rng, np.random.Generator):
        raise ParameterError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
    W, H = camera.width, camera.height
    pts = board.object_points()
    centre = pts.mean(axis=0)
    sheet = board.sheet()
    marks = sheet.black  # the printed pattern's width (a checkerboard's squares)
    # The printed face towards the camera: a target whose y runs up its page (z towards the
    # viewer) is turned half about its x axis.
    face = np.diag([1.0, -1.0, -1.0]) if sheet.v_up else np.eye(3)
    span = float(marks[:, 2].max() - marks[:, 0].min())
    g = int(np.ceil(np.sqrt(n)))
    cells = [((i + 0.5) / g, (j + 0.5) / g) for j in range(g) for i in range(g)]
    rng.shuffle(cells)
    poses = []
    for k in range(n):
        cu, cv = cells[k % len(cells)]
        for _ in range(max_tries):
            px = np.array([(0.15 + 0.7 * (cu + rng.uniform(-0.5, 0.5) / g)) * (W - 1),
                           (0.15 + 0.7 * (cv + rng.uniform(-0.5, 0.5) / g)) * (H - 1)])
            ray = camera.unproject(px)
            if not np.isfinite(ray).all() or ray[2] <= 0.2:
                continue
            frac = rng.uniform(*fill)
            dist = span * camera.fx / (frac * W)
            phi = rng.uniform(0, 2 * np.pi)
            tilt = np.radians(rng.uniform(*tilt_deg))
            R = matrix_from_rvec([0.0, 0.0, rng.uniform(-0.5, 0.5)]) @ matrix_from_rvec(
                tilt * np.array([np.cos(phi), np.sin(phi), 0.0])) @ face
            t = ray * dist / ray[2] - R @ centre
            pose = Pose(R, t)
            c = camera.project(pose.apply(pts))
            margin = 0.02 * W
            if (np.isfinite(c).all() and (c[:, 0] > margin).all() and (c[:, 0] < W - 1 - margin).all()
                    and (c[:, 1] > margin).all() and (c[:, 1] < H - 1 - margin).all()):
                poses.append(pose)
                break
        else:
            raise EstimationError(
                f"could not place view {k} with every corner inside the image in {max_tries} tries: "
                "use a smaller board, a wider lens, or a smaller fill"
            )
    return poses


def camera_to_dict(camera: CameraModel) -> dict[str, Any]:
    """``{"type", "width", "height", and every parameter by name}`` (:meth:`CameraModel.to_dict`)."""
    return camera.to_dict()


def file_scale(effects: Effects | None, bit_depth: int) -> tuple[float, int | None]:
    """(scale, sensor bits): a file sample is ``round(value * scale)``, where value is the
    rendered image (0..1 without a sensor) or the sensor's count (0..2^bits - 1), so that white
    lands at the top of the file's range (255 or 65535), as a viewer expects."""
    top = 255.0 if bit_depth == 8 else 65535.0
    sensor = effects.sensor if effects is not None else None
    if sensor is None:
        return top, None
    return top / float(sensor.max_dn), int(sensor.bit_depth)


def to_file_image(img: np.ndarray, scale: float, bit_depth: int) -> np.ndarray:
    dtype = np.uint8 if bit_depth == 8 else np.uint16
    top = np.iinfo(dtype).max
    return np.clip(np.floor(img.astype(np.float64) * scale + 0.5), 0, top).astype(dtype)


def view_record(name: str, pose: Pose, truth: Any) -> dict[str, Any]:
    """A view's entry in a dataset's truth: the image name, ``cam_from_target`` (rotation
    vector, translation) and every target point's exact pixel (None where not projectable)
    and visibility."""
    return {
        "image": name,
        "cam_from_target": {"rvec": pose.rvec.tolist(), "t": pose.t.tolist()},
        "corners_px": [None if not np.isfinite(c).all() else c.tolist() for c in truth.corners_px],
        "visible": truth.visible.tolist(),
    }


def dataset_header(camera: CameraModel, board: Target, seed: int, bit_depth: int, sensor_bits: int | None,
                   scale: float, version: int = 1) -> dict[str, Any]:
    """What a dataset's truth says of the whole dataset (docs/file_formats.md)."""
    return {
        "format": "camkit-simulated-dataset",
        "version": version,
        "seed": seed,
        "camera": camera_to_dict(camera),
        "board": board.to_dict(),
        "pixel_origin": "centre of the top-left pixel is (0, 0)",
        "bit_depth": bit_depth,
        "sensor_bit_depth": sensor_bits,
        "scale": scale,
    }


def simulate_dataset(out_dir: str | os.PathLike, camera: CameraModel, board: Target, views: int, *,
                     seed: int, effects: Effects | None = None, progress: Any = None, bit_depth: int = 8) -> Path:
    """Render ``views`` planned views and write ``view_XXX.png`` and ``truth.json`` into
    ``out_dir`` (created if needed). Reproducible: the same seed gives the same bytes.

    Files are 8-bit (``bit_depth=8``, the default) or 16-bit, white at the top of the file's
    range: a sensor's count ``v`` (0..2^bits - 1) is written as ``round(v * scale)``, a render
    without a sensor (0..1) as ``round(x * scale)``; ``truth.json`` records ``bit_depth``,
    ``sensor_bit_depth`` and ``scale``.

    ``truth.json`` holds the camera (type, size, parameters), the target (``board``: its type
    and fields), and per view the image name, the pose (rotation vector and translation of
    ``cam_from_target``), every target point's exact pixel position (null where not
    projectable) and its visibility. Any registered target (a checkerboard, a ChArUco board).
    Returns the folder.
    """
    if bit_depth not in (8, 16):
        raise ParameterError(f"bit_depth: expected 8 or 16, got {bit_depth!r}")
    scale, sensor_bits = file_scale(effects, bit_depth)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    poses = plan_views(camera, board, views, rng)
    records = []
    for k, pose in enumerate(poses):
        img, truth = render_view(camera, pose, board, effects, rng=rng)
        name = f"view_{k:03d}.png"
        write_png(out / name, to_file_image(img, scale, bit_depth))
        records.append(view_record(name, pose, truth))
        if progress is not None:
            progress(k + 1, len(poses))
    doc = {**dataset_header(camera, board, seed, bit_depth, sensor_bits, scale), "views": records}
    write_atomic(out / "truth.json", json.dumps(doc, indent=1).encode())
    return out


def default_camera(model: str = "brown-conrady") -> CameraModel:
    """The registry model's realistic example (:meth:`CameraModel.example`): 1280x960, 4.8 um
    pixels behind a 4.8 mm lens (fx = 1000 px), with a moderate barrel lens or a fisheye."""
    if model not in MODELS:
        raise ParameterError(f"model: expected one of {', '.join(map(repr, sorted(MODELS)))}, got {model!r}")
    return get_model(model).example()
