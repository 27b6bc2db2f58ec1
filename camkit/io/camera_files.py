"""Camera files: camkit's versioned JSON, OpenCV FileStorage YAML, ROS camera_info YAML, COLMAP
cameras.txt and Kalibr camchain YAML.

JSON is read by :mod:`json`, YAML by PyYAML's safe loader (with a constructor for OpenCV's
``!!opencv-matrix`` tag), so loading never executes anything from a file; every malformed file is
a ParameterError naming the file and what is wrong.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from camkit._atomic import write_atomic
from camkit.errors import ParameterError
from camkit.io._files import regular_file_size
from camkit.lens.base import MODELS, CameraModel
from camkit.lens.brown_conrady import BrownConrady
from camkit.lens.kannala_brandt import KannalaBrandt
from camkit.lens.opencv import from_opencv, from_opencv_fisheye, to_opencv
from camkit.lens.pinhole import Pinhole

__all__ = [
    "CAMERA_FORMAT_VERSION",
    "EXPORT_FORMATS",
    "export_camera",
    "kalibr_entry",
    "load_camera",
    "read_camera",
    "read_colmap_cameras",
    "read_opencv_yaml",
    "save_camera",
    "versioned_json",
    "write_colmap_cameras",
    "write_kalibr_yaml",
    "write_opencv_yaml",
    "write_ros_yaml",
]

CAMERA_FORMAT_VERSION = 1


def save_camera(path: str | os.PathLike, model: CameraModel, **extra: Any) -> Path:
    """Write ``{"format": "camkit-camera", "version": 1, "model": {type, width, height,
    parameters by name}, ...extra}`` as JSON (atomically). Pixel (0, 0) is the centre of the
    top-left pixel."""
    if not isinstance(model, CameraModel):
        raise ParameterError(f"model: expected a camkit camera model, got {type(model).__name__}")
    doc = {"format": "camkit-camera", "version": CAMERA_FORMAT_VERSION,
           "pixel_origin": "centre of the top-left pixel is (0, 0)", "model": model.to_dict(), **extra}
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


#: The largest camera or rig file read (bytes): COLMAP's cameras.txt for ten thousand cameras
#: is about a megabyte; a larger file is not one of these, and is not read whole into memory.
MAX_CAMERA_FILE_BYTES = 64 * 1024 * 1024


def _read_text(path: str | os.PathLike) -> str:
    """The text of a camera or rig file, after checking that it is a regular file of at most
    :data:`MAX_CAMERA_FILE_BYTES` (a FIFO would block forever, /dev/zero fill the memory)."""
    p = Path(path)
    size = regular_file_size(p, ParameterError, "a file", "camera file")
    if size > MAX_CAMERA_FILE_BYTES:
        limit = MAX_CAMERA_FILE_BYTES // 2**20
        raise ParameterError(f"{path}: expected a camera or rig file of at most {limit} MB, got "
                             f"{size / 2**20:.0f} MB")
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ParameterError(f"{path}: not a camera file (not text)") from None
    except OSError as exc:
        raise ParameterError(f"{path}: cannot read the camera file ({exc.strerror or exc})") from None


def versioned_json(path: str | os.PathLike, fmt: str, kind: str, max_version: int) -> dict[str, Any]:
    """A camkit JSON file's document, checked: valid JSON, ``"format": fmt`` and a version from
    1 to ``max_version`` (``kind`` names the file in messages: "camera", "rig")."""
    try:
        doc = json.loads(_read_text(path))
    except json.JSONDecodeError as exc:
        raise ParameterError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        raise ParameterError(f"{path}: not a camkit {kind} file (expected \"format\": \"{fmt}\")")
    version = doc.get("version")
    if not isinstance(version, int) or not 1 <= version <= max_version:
        raise ParameterError(f"{path}: unsupported {kind} file version {version!r} (this camkit reads 1.."
                             f"{max_version})")
    return doc


def load_camera(path: str | os.PathLike) -> CameraModel:
    """Read a camera written by :func:`save_camera` (any version up to the current)."""
    doc = versioned_json(path, "camkit-camera", "camera", CAMERA_FORMAT_VERSION)
    return model_from_dict(doc.get("model"), f"{path}: model")


# -- OpenCV FileStorage / ROS camera_info YAML ---------------------------------------------

def _fmt_matrix(name: str, m: np.ndarray) -> str:
    rows, cols = (1, m.size) if m.ndim == 1 else m.shape
    data = ", ".join(repr(float(v)) for v in m.ravel())
    return f"{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {data} ]\n"


def _opencv_form(model: CameraModel) -> tuple[np.ndarray, np.ndarray, str]:
    if isinstance(model, Pinhole):
        return model.K, np.zeros(5), "plumb_bob"
    if isinstance(model, BrownConrady | KannalaBrandt):
        K, dist = to_opencv(model)
        dmodel = "equidistant" if isinstance(model, KannalaBrandt) else (
            "plumb_bob" if dist.size == 5 else "rational_polynomial")
        return K, dist, dmodel
    raise ParameterError(f"model: expected a Pinhole, BrownConrady or KannalaBrandt, got {type(model).__name__}")


def write_opencv_yaml(path: str | os.PathLike, model: BrownConrady | KannalaBrandt | Pinhole) -> Path:
    """Write OpenCV FileStorage YAML, as OpenCV's calibration sample does: ``image_width``,
    ``image_height``, ``camera_matrix``, ``distortion_model`` (``plumb_bob``,
    ``rational_polynomial`` or ``equidistant``) and ``distortion_coefficients`` (the matrices
    tagged ``!!opencv-matrix``, so ``cv2.FileStorage`` reads them as matrices). Atomic."""
    K, dist, dmodel = _opencv_form(model)
    text = ("%YAML:1.0\n---\n" + f"image_width: {model.width}\nimage_height: {model.height}\n"
            + _fmt_matrix("camera_matrix", K) + f"distortion_model: {dmodel}\n"
            + _fmt_matrix("distortion_coefficients", dist))
    return write_atomic(path, text.encode())


def write_ros_yaml(path: str | os.PathLike, model: BrownConrady | KannalaBrandt | Pinhole, *,
                   camera_name: str = "camera") -> Path:
    """Write ROS ``camera_info`` YAML (the camera_calibration_parsers layout): ``image_width``,
    ``image_height``, ``camera_name``, ``camera_matrix``, ``distortion_model``,
    ``distortion_coefficients``, ``rectification_matrix`` (identity for one camera) and
    ``projection_matrix`` (``[K | 0]``), each matrix as ``rows``, ``cols``, ``data``. Atomic."""
    import yaml

    K, dist, dmodel = _opencv_form(model)

    def mat(m: np.ndarray) -> dict[str, Any]:
        m2 = m.reshape(1, -1) if m.ndim == 1 else m
        return {"rows": int(m2.shape[0]), "cols": int(m2.shape[1]), "data": [float(v) for v in m2.ravel()]}

    doc = {"image_width": int(model.width), "image_height": int(model.height), "camera_name": str(camera_name),
           "camera_matrix": mat(K), "distortion_model": dmodel, "distortion_coefficients": mat(dist),
           "rectification_matrix": mat(np.eye(3)), "projection_matrix": mat(np.c_[K, np.zeros(3)])}
    return write_atomic(path, yaml.safe_dump(doc, sort_keys=False, default_flow_style=None).encode())


class _SafeLoader:
    """PyYAML's SafeLoader plus OpenCV's ``!!opencv-matrix`` tag (a mapping: rows, cols, dt, data)."""

    _cls: Any = None

    @classmethod
    def get(cls) -> Any:
        if cls._cls is None:
            import yaml

            class Loader(yaml.SafeLoader):
                pass

            def opencv_matrix(loader: Any, node: Any) -> dict[str, Any]:
                return loader.construct_mapping(node, deep=True)

            Loader.add_constructor("tag:yaml.org,2002:opencv-matrix", opencv_matrix)
            cls._cls = Loader
        return cls._cls


def _load_yaml(path: str | os.PathLike) -> Any:
    import yaml

    text = _read_text(path)
    # OpenCV writes the directive as "%YAML:1.0", which YAML 1.1 parsers refuse; it carries
    # nothing else, so it is dropped.
    if text.startswith("%YAML:"):
        text = text.split("\n", 1)[1] if "\n" in text else ""
    try:
        return yaml.load(text, Loader=_SafeLoader.get())
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        line = f" at line {where.line + 1}" if where is not None else ""
        raise ParameterError(f"{path}: not valid YAML ({getattr(exc, 'problem', None) or exc}{line})") from None


def _matrix(doc: dict[str, Any], key: str, where: str) -> np.ndarray:
    node = doc.get(key)
    if not isinstance(node, dict) or "data" not in node:
        raise ParameterError(f"{where}: missing matrix {key!r} (with rows, cols, data)")
    data = node["data"]
    try:
        values = np.array([float(v) for v in data], dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"{where}: {key}.data: expected a list of numbers, got {data!r}") from None
    try:
        rows, cols = int(node.get("rows", 1)), int(node.get("cols", values.size))
    except (TypeError, ValueError):
        raise ParameterError(f"{where}: {key}: rows and cols must be integers") from None
    if rows * cols != values.size:
        raise ParameterError(f"{where}: {key}: {rows}x{cols} expected {rows * cols} values, got {values.size}")
    return values.reshape(rows, cols)


def read_opencv_yaml(path: str | os.PathLike) -> BrownConrady | KannalaBrandt:
    """Read a camera from OpenCV FileStorage or ROS camera_info YAML (``image_width``,
    ``image_height``, ``camera_matrix``, ``distortion_coefficients``, and
    ``distortion_model: equidistant`` for fisheye lenses)."""
    where = str(path)
    doc = _load_yaml(path)
    if not isinstance(doc, dict):
        raise ParameterError(f"{where}: expected a YAML mapping with image_width, image_height, camera_matrix, ...")
    return _from_opencv_doc(doc, where)


def _from_opencv_doc(doc: dict[str, Any], where: str) -> BrownConrady | KannalaBrandt:
    try:
        w, h = int(doc["image_width"]), int(doc["image_height"])
    except (KeyError, TypeError, ValueError):
        raise ParameterError(f"{where}: expected integer image_width and image_height") from None
    K = _matrix(doc, "camera_matrix", where)
    if K.shape != (3, 3):
        raise ParameterError(f"{where}: camera_matrix: expected 3x3, got {K.shape}")
    dist = _matrix(doc, "distortion_coefficients", where).ravel()
    kind = str(doc.get("distortion_model", "")).strip().strip('"')
    if kind in ("equidistant", "fisheye"):
        return from_opencv_fisheye(K, dist, width=w, height=h)
    return from_opencv(K, dist, width=w, height=h)


# -- COLMAP cameras.txt ---------------------------------------------------------------------

#: COLMAP's camera models camkit maps exactly (colmap/src/colmap/sensor/models.h), with their
#: parameter order after fx, fy, cx, cy (SIMPLE_* share one f).
_COLMAP = {"SIMPLE_PINHOLE": (), "PINHOLE": (), "SIMPLE_RADIAL": ("k1",), "RADIAL": ("k1", "k2"),
           "OPENCV": ("k1", "k2", "p1", "p2"), "FULL_OPENCV": ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
           "SIMPLE_RADIAL_FISHEYE": ("k1",), "RADIAL_FISHEYE": ("k1", "k2"),
           "OPENCV_FISHEYE": ("k1", "k2", "k3", "k4")}
# The models with one focal length, f (COLMAP's src/colmap/sensor/models.h): RADIAL and
# RADIAL_FISHEYE too, "f, cx, cy, k1, k2".
_COLMAP_ONE_FOCAL = ("SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL", "SIMPLE_RADIAL_FISHEYE", "RADIAL_FISHEYE")


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


def read_colmap_cameras(path: str | os.PathLike) -> dict[int, CameraModel]:
    """Read COLMAP's cameras.txt: ``{camera_id: model}``, pixel origin shifted back by -0.5.

    SIMPLE_PINHOLE and PINHOLE become :class:`Pinhole`; SIMPLE_RADIAL, RADIAL, OPENCV and
    FULL_OPENCV :class:`BrownConrady`; SIMPLE_RADIAL_FISHEYE, RADIAL_FISHEYE and OPENCV_FISHEYE
    :class:`KannalaBrandt` (COLMAP's fisheye models are equidistant with odd theta
    polynomials, as Kannala-Brandt). Other COLMAP models are refused by name."""
    where = str(path)
    out: dict[int, CameraModel] = {}
    for n, line in enumerate(_read_text(path).splitlines(), start=1):
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            continue
        if len(fields) < 5:
            raise ParameterError(f"{where}: line {n}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS..., got {line!r}")
        name = fields[1]
        if name not in _COLMAP:
            raise ParameterError(f"{where}: line {n}: COLMAP model {name} has no camkit form (expected one of "
                                 f"{', '.join(_COLMAP)})")
        try:
            cam_id, w, h = int(fields[0]), int(fields[2]), int(fields[3])
            p = [float(v) for v in fields[4:]]
        except ValueError:
            raise ParameterError(f"{where}: line {n}: expected integers and numbers, got {line!r}") from None
        dist = _COLMAP[name]
        n_f = 1 if name in _COLMAP_ONE_FOCAL else 2
        if len(p) != n_f + 2 + len(dist):
            raise ParameterError(f"{where}: line {n}: {name} takes {n_f + 2 + len(dist)} parameters, got {len(p)}")
        fx, fy = (p[0], p[0]) if n_f == 1 else (p[0], p[1])
        cx, cy = p[n_f] - 0.5, p[n_f + 1] - 0.5
        coeffs = dict(zip(dist, p[n_f + 2:], strict=True))
        common = {"fx": fx, "fy": fy, "cx": cx, "cy": cy, "width": w, "height": h}
        if "FISHEYE" in name:
            out[cam_id] = KannalaBrandt(**common, **coeffs)
        elif dist:
            out[cam_id] = BrownConrady(**common, **coeffs)
        else:
            out[cam_id] = Pinhole(**common)
    if not out:
        raise ParameterError(f"{where}: no camera lines in the COLMAP cameras.txt")
    return out


# -- Kalibr camchain YAML ---------------------------------------------------------------------


def write_kalibr_yaml(path: str | os.PathLike, model: CameraModel, *, name: str = "cam0") -> Path:
    """Write a Kalibr camchain entry: ``camera_model: pinhole``, ``intrinsics: [fu, fv, pu, pv]``,
    ``distortion_model`` ``radtan`` (k1 k2 p1 p2) or ``equidistant`` (k1..k4), and
    ``resolution: [w, h]`` (Kalibr's camchain format, wiki "Yaml formats"). Terms Kalibr cannot
    hold (skew, k3 and beyond for radtan) are refused rather than dropped."""
    import yaml

    doc = {name: kalibr_entry(model)}
    return write_atomic(path, yaml.safe_dump(doc, sort_keys=False, default_flow_style=None).encode())


def kalibr_entry(model: CameraModel) -> dict[str, Any]:
    """One camera of a Kalibr camchain, as a dictionary (see :func:`write_kalibr_yaml`)."""
    if model.skew != 0:
        raise ParameterError(f"model: Kalibr has no skew; got skew = {model.skew}")
    if isinstance(model, KannalaBrandt):
        dmodel, coeffs = "equidistant", [model.k1, model.k2, model.k3, model.k4]
    elif isinstance(model, BrownConrady):
        extra = [n for n in ("k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4") if getattr(model, n) != 0]
        if extra:
            raise ParameterError(f"model: Kalibr's radtan model holds k1, k2, p1, p2 only; {extra} are not zero "
                                 "(calibrate with --fix k3 for a Kalibr camera)")
        dmodel, coeffs = "radtan", [model.k1, model.k2, model.p1, model.p2]
    elif isinstance(model, Pinhole):
        dmodel, coeffs = "none", []
    else:
        raise ParameterError(f"model: expected a Pinhole, BrownConrady or KannalaBrandt, got {type(model).__name__}")
    return {"camera_model": "pinhole", "intrinsics": [float(model.fx), float(model.fy), float(model.cx),
                                                      float(model.cy)],
            "distortion_model": dmodel, "distortion_coeffs": [float(v) for v in coeffs],
            "resolution": [int(model.width), int(model.height)]}


def _from_kalibr_doc(doc: dict[str, Any], where: str) -> CameraModel:
    key = sorted(k for k in doc if isinstance(doc[k], dict) and "intrinsics" in doc[k])[0]
    d = doc[key]
    if d.get("camera_model") != "pinhole":
        raise ParameterError(f"{where}: {key}.camera_model {d.get('camera_model')!r} is not supported (pinhole only)")
    try:
        fx, fy, cx, cy = (float(v) for v in d["intrinsics"])
        w, h = (int(v) for v in d["resolution"])
        coeffs = [float(v) for v in d.get("distortion_coeffs", [])]
    except (KeyError, TypeError, ValueError):
        raise ParameterError(f"{where}: {key}: expected intrinsics [fu, fv, pu, pv] and resolution [w, h]") from None
    common = {"fx": fx, "fy": fy, "cx": cx, "cy": cy, "width": w, "height": h}
    dm = d.get("distortion_model", "none")
    if dm == "radtan" and len(coeffs) == 4:
        return BrownConrady(**common, **dict(zip(("k1", "k2", "p1", "p2"), coeffs, strict=True)))
    if dm == "equidistant" and len(coeffs) == 4:
        return KannalaBrandt(**common, **dict(zip(("k1", "k2", "k3", "k4"), coeffs, strict=True)))
    if dm == "none" and not coeffs:
        return Pinhole(**common)
    raise ParameterError(f"{where}: {key}: distortion_model {dm!r} with {len(coeffs)} coefficients is not supported "
                         "(radtan or equidistant with 4)")


# -- any camera file ---------------------------------------------------------------------------


def read_camera(path: str | os.PathLike) -> CameraModel:
    """A camera from any file camkit knows, recognised by content: camkit JSON
    (:func:`load_camera`), OpenCV FileStorage or ROS camera_info YAML, a Kalibr camchain (its
    first camera) or COLMAP cameras.txt (its first camera)."""
    text = _read_text(path).lstrip()
    if text.startswith("{"):
        return load_camera(path)
    if _looks_colmap(text):
        cams = read_colmap_cameras(path)
        return cams[min(cams)]
    doc = _load_yaml(path)
    if isinstance(doc, dict) and "camera_matrix" in doc:
        return _from_opencv_doc(doc, str(path))
    if isinstance(doc, dict) and any(isinstance(v, dict) and "intrinsics" in v for v in doc.values()):
        return _from_kalibr_doc(doc, str(path))
    raise ParameterError(f"{path}: not a camera file camkit reads (expected camkit JSON, OpenCV/ROS YAML, a Kalibr "
                         "camchain or COLMAP cameras.txt)")


def _looks_colmap(text: str) -> bool:
    for line in text.splitlines():
        f = line.split()
        if f and not f[0].startswith("#"):
            return len(f) >= 5 and f[0].isdigit() and f[1] in _COLMAP
    return False


#: ``camkit export --to`` formats.
EXPORT_FORMATS = ("json", "opencv", "ros", "colmap", "kalibr")


def export_camera(model: CameraModel, path: str | os.PathLike, to: str) -> Path:
    """Write ``model`` in one of :data:`EXPORT_FORMATS` (atomically)."""
    if to == "json":
        return save_camera(path, model)
    if to == "opencv":
        return write_opencv_yaml(path, model)  # type: ignore[arg-type]
    if to == "ros":
        return write_ros_yaml(path, model)  # type: ignore[arg-type]
    if to == "colmap":
        return write_colmap_cameras(path, [model])
    if to == "kalibr":
        return write_kalibr_yaml(path, model)
    raise ParameterError(f"to: expected one of {', '.join(EXPORT_FORMATS)}, got {to!r}")
