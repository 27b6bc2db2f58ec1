"""Rig files: camkit's versioned rig JSON, OpenCV's stereo FileStorage YAML and Kalibr's
camchain YAML with ``T_cn_cnm1``.

As for camera files, JSON is read by :mod:`json` and YAML by PyYAML's safe loader; every
malformed file is a ParameterError naming the file and what is wrong; files are written
atomically (a temporary file, then a rename).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from camkit._atomic import write_atomic
from camkit.calib.rig import RIG_FORMAT_VERSION, CameraRig, RigResult
from camkit.errors import ParameterError
from camkit.geometry.pose import Pose
from camkit.io.camera_files import (
    _fmt_matrix,
    _from_kalibr_doc,
    _from_opencv_doc,
    _load_yaml,
    _matrix,
    _opencv_form,
    _read_text,
    kalibr_entry,
    model_from_dict,
    versioned_json,
)
from camkit.stereo.rectify import rectify

__all__ = ["load_rig", "read_kalibr_camchain", "read_opencv_stereo_yaml", "read_rig", "save_rig",
           "write_kalibr_camchain", "write_opencv_stereo_yaml"]


def _as_rig(rig: Any) -> CameraRig:
    if isinstance(rig, RigResult):
        return rig.rig
    if isinstance(rig, CameraRig):
        return rig
    raise ParameterError(f"rig: expected a CameraRig or a RigResult, got {type(rig).__name__}")


def save_rig(path: str | os.PathLike, rig: CameraRig | RigResult) -> Path:
    """Write camkit's rig JSON (atomically): ``{"format": "camkit-rig", "version": 1,
    "cameras": [{"name", "model": {type, width, height, parameters}, "cam_from_rig": {"rvec",
    "t_m"}}]}``, and with a :class:`~camkit.calib.RigResult` everything
    :meth:`RigResult.to_dict` gives (sigmas, baselines, RMS). docs/file_formats.md has the
    layout."""
    if isinstance(rig, RigResult):
        doc = rig.to_dict()
    else:
        r = _as_rig(rig)
        doc = {"format": "camkit-rig", "version": RIG_FORMAT_VERSION, "reference": r.names[0],
               "cameras": [{"name": n, "model": m.to_dict(),
                            "cam_from_rig": {"rvec": [float(v) for v in p.rvec], "t_m": [float(v) for v in p.t]}}
                           for n, m, p in zip(r.names, r.models, r.cam_from_rig, strict=True)]}
    doc["pixel_origin"] = "centre of the top-left pixel is (0, 0)"
    return write_atomic(path, (json.dumps(doc, indent=2) + "\n").encode())


def _vector(x: Any, n: int, where: str) -> np.ndarray:
    try:
        v = np.array([float(a) for a in x])
    except (TypeError, ValueError):
        raise ParameterError(f"{where}: expected {n} numbers, got {x!r}") from None
    if v.shape != (n,) or not np.isfinite(v).all():
        raise ParameterError(f"{where}: expected {n} finite numbers, got {x!r}")
    return v


def load_rig(path: str | os.PathLike) -> CameraRig:
    """Read a rig written by :func:`save_rig` (any version up to the current)."""
    doc = versioned_json(path, "camkit-rig", "rig", RIG_FORMAT_VERSION)
    cams = doc.get("cameras")
    if not isinstance(cams, list) or len(cams) < 1:
        raise ParameterError(f"{path}: cameras: expected a list with one entry per camera")
    names, models, poses = [], [], []
    for k, c in enumerate(cams):
        where = f"{path}: cameras[{k}]"
        if not isinstance(c, dict) or not isinstance(c.get("name"), str) or not isinstance(c.get("cam_from_rig"),
                                                                                           dict):
            raise ParameterError(f"{where}: expected an object with name, model and cam_from_rig")
        names.append(c["name"])
        models.append(model_from_dict(c.get("model"), f"{where}.model"))
        p = c["cam_from_rig"]
        poses.append(Pose.from_rvec(_vector(p.get("rvec"), 3, f"{where}.cam_from_rig.rvec"),
                                    _vector(p.get("t_m"), 3, f"{where}.cam_from_rig.t_m")))
    return CameraRig(tuple(names), tuple(models), tuple(poses))


# -- OpenCV stereo FileStorage ------------------------------------------------------------------


def write_opencv_stereo_yaml(path: str | os.PathLike, rig: CameraRig | RigResult, *, left: int | str = 0,
                             right: int | str = 1, mode: str | float = "valid") -> Path:
    """Write a stereo pair as OpenCV FileStorage YAML with the names of OpenCV's stereo sample
    (``stereo_calib.cpp``: ``M1, D1, M2, D2`` and ``R, T, R1, R2, P1, P2, Q``), in one file:
    ``R, T`` map the left camera's frame into the right's (``stereoCalibrate``'s), ``R1 ... Q``
    are camkit's rectification (:func:`camkit.stereo.rectify` with ``mode``; the rotations are
    ``stereoRectify``'s). Both cameras must be Brown-Conrady or pinhole (OpenCV's fisheye
    stereo files keep D as four values: Kannala-Brandt pairs are written the same way, with
    ``distortion_model: equidistant``)."""
    r = _as_rig(rig)
    a, b = r.index(left), r.index(right)
    ml, mr = r.models[a], r.models[b]
    K1, D1, dm1 = _opencv_form(ml)
    K2, D2, dm2 = _opencv_form(mr)
    if dm1 != dm2 and "equidistant" in (dm1, dm2):
        raise ParameterError("rig: one camera is a fisheye (Kannala-Brandt) and the other is not; OpenCV's stereo "
                             "files hold one kind")
    right_from_left = r.relative_pose(b, a)
    rect = rectify(ml, mr, right_from_left.inverse(), mode=mode)
    text = ("%YAML:1.0\n---\n" + f"image_width: {ml.width}\nimage_height: {ml.height}\n"
            + f"distortion_model: {dm1}\n"
            + _fmt_matrix("M1", K1) + _fmt_matrix("D1", D1) + _fmt_matrix("M2", K2) + _fmt_matrix("D2", D2)
            + _fmt_matrix("R", right_from_left.R) + _fmt_matrix("T", right_from_left.t.reshape(3, 1))
            + _fmt_matrix("R1", rect.rect_from_left) + _fmt_matrix("R2", rect.rect_from_right)
            + _fmt_matrix("P1", rect.P_left) + _fmt_matrix("P2", rect.P_right) + _fmt_matrix("Q", rect.Q))
    return write_atomic(path, text.encode())


def read_opencv_stereo_yaml(path: str | os.PathLike, *, size: tuple[int, int] | None = None) -> CameraRig:
    """A stereo rig (cameras ``left`` and ``right``, the left at the rig's origin) from OpenCV
    FileStorage YAML holding ``M1, D1, M2, D2, R, T`` (``R, T``: left frame into right, as
    ``stereoCalibrate`` gives them); the image size from ``image_width``/``image_height`` or
    ``size``. Rectification entries, if any, are not needed (``camkit.stereo.rectify`` makes
    them)."""
    where = str(path)
    doc = _load_yaml(path)
    if not isinstance(doc, dict) or not {"M1", "D1", "M2", "D2", "R", "T"} <= set(doc):
        raise ParameterError(f"{where}: expected an OpenCV stereo file with M1, D1, M2, D2, R and T")
    if size is not None:
        w, h = size
    else:
        try:
            w, h = int(doc["image_width"]), int(doc["image_height"])
        except (KeyError, TypeError, ValueError):
            raise ParameterError(f"{where}: no image_width/image_height; pass size=(width, height)") from None
    models = []
    for k in ("1", "2"):
        sub = {"image_width": w, "image_height": h, "camera_matrix": doc[f"M{k}"],
               "distortion_coefficients": doc[f"D{k}"], "distortion_model": doc.get("distortion_model", "")}
        models.append(_from_opencv_doc(sub, f"{where}: M{k}/D{k}"))
    R = _matrix(doc, "R", where)
    T = _matrix(doc, "T", where).ravel()
    if R.shape != (3, 3) or T.shape != (3,):
        raise ParameterError(f"{where}: R and T: expected 3x3 and 3 values, got {R.shape} and {T.shape}")
    try:
        right_from_left = Pose(R, T)
    except ParameterError as exc:
        raise ParameterError(f"{where}: R: {exc}") from None
    return CameraRig(("left", "right"), tuple(models), (Pose.identity(), right_from_left))


# -- Kalibr camchain ----------------------------------------------------------------------------


def write_kalibr_camchain(path: str | os.PathLike, rig: CameraRig | RigResult) -> Path:
    """Write a Kalibr camchain (wiki "Yaml formats"): ``cam0``, ``cam1``, ... each with its
    intrinsics (as :func:`~camkit.io.write_kalibr_yaml`), ``rostopic`` named after the camera,
    and for ``cam1`` onwards ``T_cn_cnm1``, the 4x4 transform from the previous camera's frame
    into this one's. Atomic."""
    import yaml

    r = _as_rig(rig)
    doc: dict[str, Any] = {}
    for k, (name, m) in enumerate(zip(r.names, r.models, strict=True)):
        entry = kalibr_entry(m)
        if k > 0:
            T = r.relative_pose(k, k - 1).matrix
            entry["T_cn_cnm1"] = [[float(v) for v in row] for row in T]
        entry["rostopic"] = f"/{name}/image_raw"
        doc[f"cam{k}"] = entry
    return write_atomic(path, yaml.safe_dump(doc, sort_keys=False, default_flow_style=None).encode())


def read_kalibr_camchain(path: str | os.PathLike) -> CameraRig:
    """A rig from a Kalibr camchain: ``cam0``, ``cam1``, ... in order, ``cam0`` at the rig's
    origin, each next camera placed by its ``T_cn_cnm1``; camera names from their
    ``rostopic`` (``/left/image_raw`` gives ``left``) or ``camN``."""
    where = str(path)
    doc = _load_yaml(path)
    keys = sorted((k for k in doc if isinstance(k, str) and k.startswith("cam") and k[3:].isdigit()),
                  key=lambda k: int(k[3:])) if isinstance(doc, dict) else []
    if not keys or keys != [f"cam{i}" for i in range(len(keys))]:
        raise ParameterError(f"{where}: expected a Kalibr camchain with cam0, cam1, ... entries")
    names, models, poses = [], [], [Pose.identity()]
    for i, k in enumerate(keys):
        entry = doc[k]
        models.append(_from_kalibr_doc({k: entry}, where))
        topic = str(entry.get("rostopic", "")).strip("/").split("/")
        name = topic[0] if topic and topic[0] else k
        names.append(name if name not in names else k)
        if i > 0:
            if "T_cn_cnm1" not in entry:
                raise ParameterError(f"{where}: {k}: missing T_cn_cnm1 (its pose relative to cam{i - 1})")
            try:
                T = np.array(entry["T_cn_cnm1"], dtype=np.float64)
            except (TypeError, ValueError):
                raise ParameterError(f"{where}: {k}.T_cn_cnm1: expected a 4x4 matrix of numbers") from None
            if T.shape != (4, 4):
                raise ParameterError(f"{where}: {k}.T_cn_cnm1: expected a 4x4 matrix, got shape {T.shape}")
            try:
                step = Pose.from_matrix(T)
            except ParameterError as exc:
                raise ParameterError(f"{where}: {k}.T_cn_cnm1: {exc}") from None
            poses.append(step @ poses[-1])
    return CameraRig(tuple(names), tuple(models), tuple(poses))


def read_rig(path: str | os.PathLike) -> CameraRig:
    """A rig from any rig file camkit knows, recognised by content: camkit rig JSON, OpenCV
    stereo YAML (M1 ... T) or a Kalibr camchain with two or more cameras."""
    text = _read_text(path).lstrip()
    if text.startswith("{"):
        return load_rig(path)
    doc = _load_yaml(path)
    if isinstance(doc, dict) and "M1" in doc and "T" in doc:
        return read_opencv_stereo_yaml(path)
    if isinstance(doc, dict) and "cam1" in doc:
        return read_kalibr_camchain(path)
    raise ParameterError(f"{path}: not a rig file camkit reads (expected camkit rig JSON, OpenCV stereo YAML with "
                         "M1, D1, M2, D2, R, T, or a Kalibr camchain with cam0 and cam1)")
