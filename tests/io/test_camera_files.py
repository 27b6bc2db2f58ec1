"""Camera files: JSON round trips, OpenCV YAML both ways (OpenCV as oracle), ROS
camera_info, COLMAP's 0.5 px shift, malformed files refused."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from camkit.errors import ParameterError
from camkit.io import (
    export_camera,
    load_camera,
    read_camera,
    read_colmap_cameras,
    read_opencv_yaml,
    save_camera,
    write_colmap_cameras,
    write_kalibr_yaml,
    write_opencv_yaml,
    write_ros_yaml,
)
from camkit.lens import BrownConrady, KannalaBrandt, Pinhole
from camkit.render import default_camera

MODELS = [default_camera(n) for n in ("pinhole", "brown-conrady", "kannala-brandt")]


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
def test_json_round_trip(tmp_path, model):
    p = save_camera(tmp_path / "cam.json", model, note="test")
    assert load_camera(p) == model
    doc = json.loads(p.read_text())
    assert doc["version"] == 1 and doc["model"]["type"] == model.name and doc["note"] == "test"


def test_json_malformed(tmp_path):
    p = tmp_path / "bad.json"
    cases = [
        ("{not json", "not valid JSON"),
        (json.dumps({"format": "other"}), "not a camkit camera file"),
        (json.dumps({"format": "camkit-camera", "version": 99, "model": {}}), "unsupported camera file version"),
        (json.dumps({"format": "camkit-camera", "version": 1, "model": {"type": "nope"}}), "model.type: expected"),
        (json.dumps({"format": "camkit-camera", "version": 1,
                     "model": {"type": "pinhole", "width": 10, "height": 10, "fx": 1, "fy": 1, "cx": 0, "cy": 0,
                               "kk1": 0.1}}), "unknown keys ['kk1']"),
        (json.dumps({"format": "camkit-camera", "version": 1,
                     "model": {"type": "pinhole", "width": 10, "height": 10, "fx": -1, "fy": 1, "cx": 0,
                               "cy": 0}}), "fx: expected a positive"),
    ]
    for text, needle in cases:
        p.write_text(text)
        with pytest.raises(ParameterError) as info:
            load_camera(p)
        assert needle in str(info.value)


@pytest.mark.parametrize("model", MODELS[1:], ids=lambda m: m.name)
def test_opencv_yaml_both_ways(tmp_path, model):
    p = write_opencv_yaml(tmp_path / "cam.yaml", model)
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)  # OpenCV reads what we write
    K, d = model.to_opencv()
    assert np.allclose(fs.getNode("camera_matrix").mat(), K)
    assert np.allclose(fs.getNode("distortion_coefficients").mat().ravel(), d)
    assert int(fs.getNode("image_width").real()) == model.width
    fs.release()
    assert read_opencv_yaml(p) == model
    # ... and we read what OpenCV writes.
    q = tmp_path / "cv.yaml"
    fs = cv2.FileStorage(str(q), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", model.width)
    fs.write("image_height", model.height)
    fs.write("camera_matrix", K)
    if isinstance(model, KannalaBrandt):
        fs.write("distortion_model", "equidistant")
    fs.write("distortion_coefficients", d.reshape(1, -1))
    fs.release()
    assert read_opencv_yaml(q) == model


def test_ros_camera_info(tmp_path):
    p = tmp_path / "ros.yaml"
    p.write_text("""image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [430.215550, 0.000000, 306.691343,
         0.000000, 430.531693, 227.224800, 0.000000, 0.000000, 1.000000]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.337586, 0.111612, -0.000218, -0.000679, 0.000000]
""")
    cam = read_opencv_yaml(p)
    assert isinstance(cam, BrownConrady) and cam.fx == 430.21555 and cam.k1 == -0.337586 and cam.width == 640


def test_ros_camera_info_of_rectified_images_has_no_distortion(tmp_path):
    """A camera_info for rectified images (or a simulator's) writes an empty D: no distortion,
    as ROS and OpenCV take it (it was refused as 'expected 4, 5, 8, 12 or 14 coefficients')."""
    p = tmp_path / "rect.yaml"
    p.write_text("image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
                 "  data: [500, 0, 320, 0, 500, 240, 0, 0, 1]\ndistortion_model: plumb_bob\n"
                 "distortion_coefficients:\n  rows: 1\n  cols: 0\n  data: []\n")
    cam = read_opencv_yaml(p)
    assert isinstance(cam, BrownConrady) and cam.fx == 500.0 and not cam.params()[5:].any()


def test_a_fifo_a_folder_or_a_huge_file_is_refused_before_reading(tmp_path):
    """A camera or rig path that is not a regular file is refused at once: a named pipe made
    read_camera wait forever for a writer, and a huge file was read whole into memory."""
    import os
    import threading

    from camkit.io import read_rig

    fifo = tmp_path / "camera.yaml"
    os.mkfifo(fifo)
    big = tmp_path / "big.json"
    with open(big, "wb") as f:
        f.truncate(65 * 2**20)  # sparse: nothing written
    errors = {}

    def attempt():
        for name, path in (("fifo", fifo), ("folder", tmp_path), ("big", big)):
            for read in (read_camera, read_rig):
                try:
                    read(path)
                except ParameterError as exc:
                    errors[name, read.__name__] = str(exc)

    t = threading.Thread(target=attempt, daemon=True)
    t.start()
    t.join(10)
    assert not t.is_alive(), "reading a named pipe as a camera file blocked"
    assert errors["fifo", "read_camera"] == errors["fifo", "read_rig"] == f"{fifo}: expected a file, got not a regular file"
    assert errors["folder", "read_camera"] == f"{tmp_path}: expected a file, got a folder"
    assert errors["big", "read_rig"] == f"{big}: expected a camera or rig file of at most 64 MB, got 65 MB"


def test_yaml_malformed(tmp_path):
    p = tmp_path / "bad.yaml"
    for text, needle in [("image_width: 640\n", "image_height"),
                         ("image_width: 640\nimage_height: 480\n", "missing matrix 'camera_matrix'"),
                         ("image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 2]\n",
                          "3x3 expected 9 values"),
                         ("!!python/object/apply:os.system [ls]\n", "not valid YAML"),
                         ("image_width: [1\n", "not valid YAML")]:
        p.write_text(text)
        with pytest.raises(ParameterError) as info:
            read_opencv_yaml(p)
        assert needle in str(info.value)


def test_colmap_export_shifts_the_origin(tmp_path):
    p = write_colmap_cameras(tmp_path / "cameras.txt", MODELS)
    rows = [ln.split() for ln in p.read_text().splitlines() if not ln.startswith("#")]
    assert [r[1] for r in rows] == ["PINHOLE", "FULL_OPENCV", "OPENCV_FISHEYE"]
    for r, m in zip(rows, MODELS, strict=True):
        assert float(r[6]) - 0.5 == pytest.approx(m.cx) and float(r[7]) - 0.5 == pytest.approx(m.cy)
    with pytest.raises(ParameterError, match="COLMAP has no skew"):
        write_colmap_cameras(tmp_path / "x.txt", [Pinhole(fx=1.0, fy=1.0, cx=0, cy=0, skew=0.1, width=2, height=2)])


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
def test_ros_camera_info_round_trip_has_every_field(tmp_path, model):
    import yaml

    p = write_ros_yaml(tmp_path / "ros.yaml", model, camera_name="front")
    doc = yaml.safe_load(p.read_text())
    assert list(doc) == ["image_width", "image_height", "camera_name", "camera_matrix", "distortion_model",
                         "distortion_coefficients", "rectification_matrix", "projection_matrix"]
    assert doc["camera_name"] == "front" and doc["rectification_matrix"]["data"] == list(np.eye(3).ravel())
    assert (doc["projection_matrix"]["rows"], doc["projection_matrix"]["cols"]) == (3, 4)
    back = read_camera(p)
    if isinstance(model, Pinhole):  # a pinhole travels as plumb_bob with zero coefficients
        assert (back.fx, back.fy, back.cx, back.cy) == (model.fx, model.fy, model.cx, model.cy)
    else:
        assert back == model


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
def test_colmap_round_trip(tmp_path, model):
    p = write_colmap_cameras(tmp_path / "cameras.txt", [model, model])
    cams = read_colmap_cameras(p)
    assert sorted(cams) == [1, 2]
    back = cams[1]
    assert type(back) is type(model)
    for name in model.param_names:
        assert getattr(back, name) == pytest.approx(getattr(model, name), abs=1e-12), name
    assert read_camera(p) == back


def test_colmap_simple_models_and_errors(tmp_path):
    p = tmp_path / "cameras.txt"
    p.write_text("# header\n1 SIMPLE_RADIAL 640 480 500.0 320.5 240.5 -0.1\n2 SIMPLE_PINHOLE 640 480 500 320 240\n")
    cams = read_colmap_cameras(p)
    assert isinstance(cams[1], BrownConrady) and cams[1].fx == cams[1].fy == 500.0 and cams[1].cx == 320.0
    assert cams[1].k1 == -0.1 and isinstance(cams[2], Pinhole)
    # RADIAL and RADIAL_FISHEYE have one focal length too: "f, cx, cy, k1, k2" (COLMAP's
    # sensor/models.h); they were read as six parameters and refused.
    p.write_text("3 RADIAL 3072 2304 2559.81 1536 1152 -0.0205 0.001\n"
                 "4 RADIAL_FISHEYE 640 480 300 320.5 240.5 0.02 -0.003\n")
    cams = read_colmap_cameras(p)
    assert isinstance(cams[3], BrownConrady) and cams[3].fx == cams[3].fy == 2559.81 and cams[3].cx == 1535.5
    assert (cams[3].k1, cams[3].k2) == (-0.0205, 0.001)
    assert isinstance(cams[4], KannalaBrandt) and cams[4].fy == 300.0 and (cams[4].k1, cams[4].k2) == (0.02, -0.003)
    p.write_text("1 THIN_PRISM_FISHEYE 640 480 1 2 3 4 5 6 7 8 9 10 11 12\n")
    with pytest.raises(ParameterError, match="COLMAP model THIN_PRISM_FISHEYE has no camkit form"):
        read_colmap_cameras(p)
    p.write_text("1 PINHOLE 640 480 500 500 320\n")
    with pytest.raises(ParameterError, match="PINHOLE takes 4 parameters, got 3"):
        read_colmap_cameras(p)


def test_kalibr_round_trip_and_refusals(tmp_path):
    for model in (MODELS[2], BrownConrady(fx=500.0, fy=501.0, cx=320.0, cy=240.0, k1=-0.2, k2=0.05, p1=1e-3,
                                          p2=-2e-3, width=640, height=480)):
        p = write_kalibr_yaml(tmp_path / "camchain.yaml", model)
        assert read_camera(p) == model
    with pytest.raises(ParameterError, match=r"radtan model holds k1, k2, p1, p2 only; \['k3'\]"):
        write_kalibr_yaml(tmp_path / "x.yaml", MODELS[1])


@pytest.mark.parametrize("to", ["json", "opencv", "ros", "colmap", "kalibr"])
def test_export_then_read_back(tmp_path, to):
    model = MODELS[2]  # Kannala-Brandt: every format holds it exactly
    p = export_camera(model, tmp_path / f"cam.{to}", to)
    assert read_camera(p) == model


def test_read_camera_refuses_other_files(tmp_path):
    p = tmp_path / "notes.yaml"
    p.write_text("shopping: [milk, bread]\n")
    with pytest.raises(ParameterError, match="not a camera file camkit reads"):
        read_camera(p)
    p.write_bytes(bytes(range(256)))
    with pytest.raises(ParameterError, match="not a camera file"):
        read_camera(p)
