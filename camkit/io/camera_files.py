"""Camera files: camkit's versioned JSON, OpenCV/ROS YAML, COLMAP cameras.txt.

Readers parse the text themselves (no YAML or pickle loader), so loading never executes
anything from a file, and every malformed file is a ParameterError naming what is wrong.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from camkit.errors import ParameterError
from camkit.io._atomic import write_atomic
from camkit.lens.base import MODELS, CameraModel
from camkit.lens.brown_conrady import BrownConrady
from camkit.lens.kannala_brandt import KannalaBrandt
from camkit.lens.opencv import from_opencv, from_opencv_fisheye, to_opencv
from camkit.lens.pinhole import Pinhole

__all__ = ["CAMERA_FORMAT_VERSION", "load_camera", "read_opencv_yaml", "save_camera", "write_colmap_cameras",
           "write_opencv_yaml"]

CAMERA_FORMAT_VERSION = 1


def _camera_dict(model: CameraModel) -> dict[str, Any]:
    out: dict[str, Any] = {"type": model.name, "width": model.width, "height": model.height}
    out.update({n: float(getattr(model, n)) for n in model.param_names})
    return out


def save_camera(path: str | os.PathLike, model: CameraModel, **extra: Any) -> Path:
    """Write ``{"format": "camkit-camera", "version": 1, "model": {type, width, height,
    parameters by name}, ...extra}`` as JSON (atomically). Pixel (0, 0) is the centre of the
    top-left pixel."""
    if not isinstance(model, CameraModel):
        raise ParameterError(f"model: expected a camkit camera model, got {type(model).__name__}")
    doc = {"format": "camkit-camera", "version": CAMERA_FORMAT_VERSION,
           "pixel_origin": "centre of the top-left pixel is (0, 0)", "model": _camera_dict(model), **extra}
    return write_atomic(path, (json.dumps(doc, indent=2) + "\n").encode())


def model_from_dict(d: Any, where: str = "model") -> CameraModel:
    """A model from ``{"type", "width", "height", parameters by name}``; unknown or missing
    keys are errors (a misspelt parameter is never silently ignored)."""
    if not isinstance(d, dict):
        raise ParameterError(f"{where}: expected an object with type, width, height and parameters")
    kind = d.get("type")
    if kind not in MODELS:
        raise ParameterError(f"{where}.type: expected one of {sorted(MODELS)}, got {kind!r}")
    cls = MODELS[kind]
    allowed = {"type", "width", "height", *cls.param_names}
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise ParameterError(f"{where}: unknown keys {unknown} for a {kind} camera")
    for key in ("width", "height", "fx", "fy", "cx", "cy"):
        if key not in d:
            raise ParameterError(f"{where}: missing {key!r}")
    kwargs = {k: v for k, v in d.items() if k != "type"}
    return cls(**kwargs)


def load_camera(path: str | os.PathLike) -> CameraModel:
    """Read a camera written by :func:`save_camera` (any version up to the current)."""
    try:
        doc = json.loads(Path(path).read_text())
    except json.JSONDecodeError as exc:
        raise ParameterError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(doc, dict) or doc.get("format") != "camkit-camera":
        raise ParameterError(f"{path}: not a camkit camera file (expected \"format\": \"camkit-camera\")")
    version = doc.get("version")
    if not isinstance(version, int) or not 1 <= version <= CAMERA_FORMAT_VERSION:
        raise ParameterError(f"{path}: unsupported camera file version {version!r} (this camkit reads 1.."
                             f"{CAMERA_FORMAT_VERSION})")
    return model_from_dict(doc.get("model"), f"{path}: model")


# -- OpenCV FileStorage / ROS camera_info YAML ---------------------------------------------

def _fmt_matrix(name: str, m: np.ndarray, opencv: bool) -> str:
    rows, cols = (1, m.size) if m.ndim == 1 else m.shape
    data = ", ".join(repr(float(v)) for v in m.ravel())
    tag = " !!opencv-matrix" if opencv else ""
    dt = "\n   dt: d" if opencv else ""
    return f"{name}:{tag}\n   rows: {rows}\n   cols: {cols}{dt}\n   data: [ {data} ]\n"


def write_opencv_yaml(path: str | os.PathLike, model: BrownConrady | KannalaBrandt | Pinhole) -> Path:
    """Write ``image_width``, ``image_height``, ``camera_matrix``, ``distortion_model`` and
    ``distortion_coefficients`` as OpenCV's calibration sample and ROS camera_info do
    (``plumb_bob``/``rational_polynomial`` for Brown-Conrady, ``equidistant`` for fisheye)."""
    if isinstance(model, Pinhole):
        K, dist, dmodel = model.K, np.zeros(5), "plumb_bob"
    elif isinstance(model, BrownConrady | KannalaBrandt):
        K, dist = to_opencv(model)
        dmodel = "equidistant" if isinstance(model, KannalaBrandt) else (
            "plumb_bob" if dist.size == 5 else "rational_polynomial")
    else:
        raise ParameterError(f"model: expected a Pinhole, BrownConrady or KannalaBrandt, got {type(model).__name__}")
    text = ("%YAML:1.0\n---\n" + f"image_width: {model.width}\nimage_height: {model.height}\n"
            + _fmt_matrix("camera_matrix", K, True) + f"distortion_model: {dmodel}\n"
            + _fmt_matrix("distortion_coefficients", dist, True))
    return write_atomic(path, text.encode())


_LINE = re.compile(r"^(\s*)([A-Za-z_][A-Za-z0-9_]*)\s*:\s*(.*?)\s*$")


def _parse_yaml_subset(text: str, where: str) -> dict[str, Any]:
    """The YAML that OpenCV's FileStorage and ROS camera_info write: 'key: value' lines,
    one level of nesting by indentation, and flow lists '[a, b, ...]' that may span lines.
    Tags (!!opencv-matrix) are ignored; nothing is evaluated."""
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith(("#", "%", "---"))]
    out: dict[str, Any] = {}
    parent: str | None = None
    i = 0
    while i < len(lines):
        m = _LINE.match(lines[i])
        if not m:
            raise ParameterError(f"{where}: cannot read line {lines[i]!r}")
        indent, key, value = len(m.group(1)), m.group(2), m.group(3)
        if value.startswith("!!"):
            value = value.split(None, 1)[1] if " " in value else ""
        if value.startswith("[") and "]" not in value:
            while "]" not in value:
                i += 1
                if i >= len(lines):
                    raise ParameterError(f"{where}: unterminated list for {key!r}")
                value += " " + lines[i].strip()
        if indent == 0:
            parent = None
            if value == "":
                out[key] = {}
                parent = key
            else:
                out[key] = value
        else:
            if parent is None:
                raise ParameterError(f"{where}: unexpected indented key {key!r}")
            out[parent][key] = value
        i += 1
    return out


def _number_list(value: Any, where: str) -> np.ndarray:
    if not isinstance(value, str) or not (value.startswith("[") and value.endswith("]")):
        raise ParameterError(f"{where}: expected a list [a, b, ...], got {value!r}")
    try:
        return np.array([float(v) for v in value[1:-1].replace("\n", " ").split(",") if v.strip()])
    except ValueError:
        raise ParameterError(f"{where}: expected numbers, got {value!r}") from None


def _matrix(doc: dict[str, Any], key: str, where: str) -> np.ndarray:
    node = doc.get(key)
    if not isinstance(node, dict) or "data" not in node:
        raise ParameterError(f"{where}: missing matrix {key!r} (with rows, cols, data)")
    data = _number_list(node["data"], f"{where}: {key}.data")
    try:
        rows, cols = int(node.get("rows", 1)), int(node.get("cols", data.size))
    except ValueError:
        raise ParameterError(f"{where}: {key}: rows and cols must be integers") from None
    if rows * cols != data.size:
        raise ParameterError(f"{where}: {key}: {rows}x{cols} expected {rows * cols} values, got {data.size}")
    return data.reshape(rows, cols)


def read_opencv_yaml(path: str | os.PathLike) -> BrownConrady | KannalaBrandt:
    """Read a camera from OpenCV FileStorage or ROS camera_info YAML (``image_width``,
    ``image_height``, ``camera_matrix``, ``distortion_coefficients``, and
    ``distortion_model: equidistant`` for fisheye lenses)."""
    where = str(path)
    doc = _parse_yaml_subset(Path(path).read_text(), where)
    try:
        w, h = int(doc["image_width"]), int(doc["image_height"])
    except (KeyError, ValueError):
        raise ParameterError(f"{where}: expected integer image_width and image_height") from None
    K = _matrix(doc, "camera_matrix", where)
    if K.shape != (3, 3):
        raise ParameterError(f"{where}: camera_matrix: expected 3x3, got {K.shape}")
    dist = _matrix(doc, "distortion_coefficients", where).ravel()
    kind = str(doc.get("distortion_model", "")).strip().strip('"')
    if kind in ("equidistant", "fisheye"):
        return from_opencv_fisheye(K, dist, width=w, height=h)
    return from_opencv(K, dist, width=w, height=h)


def write_colmap_cameras(path: str | os.PathLike, models: list[CameraModel]) -> Path:
    """Write COLMAP's cameras.txt (camera ids from 1). COLMAP puts pixel (0, 0) at the corner
    of the top-left pixel, so cx and cy are shifted by +0.5. Models: PINHOLE, OPENCV
    (k1 k2 p1 p2), FULL_OPENCV (and k3..k6), OPENCV_FISHEYE; skew and thin-prism terms have
    no COLMAP form and are refused."""
    lines = ["# Camera list with one line of data per camera:",
             "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
             f"# Number of cameras: {len(models)}"]
    for i, m in enumerate(models, start=1):
        if not isinstance(m, CameraModel):
            raise ParameterError(f"models[{i - 1}]: expected a camkit camera model, got {type(m).__name__}")
        if m.skew != 0:
            raise ParameterError(f"models[{i - 1}]: COLMAP has no skew; got skew = {m.skew}")
        base = [m.fx, m.fy, m.cx + 0.5, m.cy + 0.5]
        if isinstance(m, KannalaBrandt):
            name, extra = "OPENCV_FISHEYE", [m.k1, m.k2, m.k3, m.k4]
        elif isinstance(m, BrownConrady):
            if any(getattr(m, s) != 0 for s in ("s1", "s2", "s3", "s4")):
                raise ParameterError(f"models[{i - 1}]: COLMAP has no thin-prism terms (s1..s4)")
            if any(getattr(m, s) != 0 for s in ("k3", "k4", "k5", "k6")):
                name, extra = "FULL_OPENCV", [m.k1, m.k2, m.p1, m.p2, m.k3, m.k4, m.k5, m.k6]
            else:
                name, extra = "OPENCV", [m.k1, m.k2, m.p1, m.p2]
        else:
            name, extra = "PINHOLE", []
        lines.append(" ".join([str(i), name, str(m.width), str(m.height), *(repr(float(v)) for v in base + extra)]))
    return write_atomic(path, ("\n".join(lines) + "\n").encode())
