"""Rig files (issue 24, item 4): camkit rig JSON, OpenCV stereo YAML and Kalibr camchains,
written and read back, read by OpenCV's own FileStorage, and malformed files refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

from camkit.calib import CameraRig
from camkit.errors import ParameterError
from camkit.geometry.pose import Pose
from camkit.io import (
    load_rig,
    read_kalibr_camchain,
    read_opencv_stereo_yaml,
    read_rig,
    save_rig,
    write_kalibr_camchain,
    write_opencv_stereo_yaml,
)
from camkit.lens import BrownConrady, KannalaBrandt
from camkit.stereo import rectify

LEFT = BrownConrady(fx=800.0, fy=801.0, cx=639.5, cy=479.5, width=1280, height=960, k1=-0.1, k2=0.02, p1=1e-4)
RIGHT = BrownConrady(fx=820.0, fy=815.0, cx=630.0, cy=470.0, width=1280, height=960, k1=-0.12, k2=0.03)
THIRD = BrownConrady(fx=790.0, fy=790.0, cx=640.0, cy=480.0, width=1280, height=960, k1=-0.05)
RIGHT_FROM_LEFT = Pose.from_rvec([0.01, -0.02, 0.005], [-0.12, 0.001, 0.002])
RIG = CameraRig(("left", "right", "top"), (LEFT, RIGHT, THIRD),
                (Pose.identity(), RIGHT_FROM_LEFT, Pose.from_rvec([0.0, 0.03, -0.01], [0.01, -0.1, 0.0])))


def _same(a: CameraRig, b: CameraRig, atol: float = 1e-12) -> None:
    assert len(a.names) == len(b.names)
    for k in range(len(a.names)):
        assert type(a.models[k]) is type(b.models[k])
        np.testing.assert_allclose(a.models[k].params(), b.models[k].params(), atol=atol)
        for j in range(len(a.names)):
            assert a.relative_pose(k, j).allclose(b.relative_pose(k, j), atol=atol)


def test_json_round_trip(tmp_path) -> None:
    path = save_rig(tmp_path / "rig.json", RIG)
    doc = json.loads(path.read_text())
    assert doc["format"] == "camkit-rig" and doc["version"] == 1
    back = load_rig(path)
    assert back.names == RIG.names
    _same(back, RIG)
    assert read_rig(path).names == RIG.names
    assert not list(tmp_path.glob("*.tmp*"))


def test_opencv_stereo_yaml_is_read_by_opencv_and_back(tmp_path) -> None:
    cv2 = pytest.importorskip("cv2")
    path = write_opencv_stereo_yaml(tmp_path / "stereo.yml", RIG, left="left", right="right")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    R, T, M1, Q = (fs.getNode(k).mat() for k in ("R", "T", "M1", "Q"))
    fs.release()
    np.testing.assert_allclose(R, RIGHT_FROM_LEFT.R, atol=1e-14)
    np.testing.assert_allclose(T.ravel(), RIGHT_FROM_LEFT.t, atol=1e-14)
    np.testing.assert_allclose(M1, LEFT.K)
    np.testing.assert_allclose(Q, rectify(LEFT, RIGHT, RIGHT_FROM_LEFT.inverse()).Q)
    back = read_opencv_stereo_yaml(path)
    assert back.names == ("left", "right")
    _same(back, CameraRig(("left", "right"), (LEFT, RIGHT), (Pose.identity(), RIGHT_FROM_LEFT)), atol=1e-12)
    assert read_rig(path).names == ("left", "right")


def test_a_file_written_by_opencv_is_read(tmp_path) -> None:
    cv2 = pytest.importorskip("cv2")
    path = str(tmp_path / "cv.yml")
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 1280)
    fs.write("image_height", 960)
    for k, v in (("M1", LEFT.K), ("D1", np.array([[LEFT.k1, LEFT.k2, LEFT.p1, LEFT.p2, LEFT.k3]])), ("M2", RIGHT.K),
                 ("D2", np.array([[RIGHT.k1, RIGHT.k2, RIGHT.p1, RIGHT.p2, RIGHT.k3]])),
                 ("R", np.array(RIGHT_FROM_LEFT.R)), ("T", np.array(RIGHT_FROM_LEFT.t).reshape(3, 1))):
        fs.write(k, v)
    fs.release()
    back = read_opencv_stereo_yaml(path)
    _same(back, CameraRig(("left", "right"), (LEFT, RIGHT), (Pose.identity(), RIGHT_FROM_LEFT)), atol=1e-9)


def test_kalibr_camchain_round_trip_and_chain(tmp_path) -> None:
    yaml = pytest.importorskip("yaml")
    path = write_kalibr_camchain(tmp_path / "camchain.yaml", RIG)
    doc = yaml.safe_load(path.read_text())
    assert list(doc) == ["cam0", "cam1", "cam2"]
    # T_cn_cnm1 of cam1 maps cam0's frame into cam1's: the right camera from the left.
    np.testing.assert_allclose(np.array(doc["cam1"]["T_cn_cnm1"]), RIGHT_FROM_LEFT.matrix, atol=1e-15)
    assert doc["cam2"]["rostopic"] == "/top/image_raw"
    back = read_kalibr_camchain(path)
    assert back.names == RIG.names
    _same(back, RIG)
    fish = KannalaBrandt(fx=300.0, fy=300.0, cx=320.0, cy=240.0, width=640, height=480, k1=0.01, k2=-0.002)
    r2 = CameraRig(("a", "b"), (fish, fish), (Pose.identity(), Pose.from_rvec([0, 0, 0], [-0.1, 0, 0])))
    _same(read_rig(write_kalibr_camchain(tmp_path / "fish.yaml", r2)), r2)


def test_malformed_files_are_refused(tmp_path) -> None:
    p = tmp_path / "bad.json"
    p.write_text('{"format": "camkit-rig", "version": 1, "cameras": [{"name": "a"}]}')
    with pytest.raises(ParameterError, match=r"cameras\[0\]"):
        load_rig(p)
    p.write_text('{"format": "camkit-rig", "version": 9, "cameras": []}')
    with pytest.raises(ParameterError, match="version"):
        load_rig(p)
    y = tmp_path / "bad.yaml"
    y.write_text("cam0: {camera_model: pinhole, intrinsics: [1, 1, 1, 1], resolution: [10, 10]}\n"
                 "cam1: {camera_model: pinhole, intrinsics: [1, 1, 1, 1], resolution: [10, 10]}\n")
    with pytest.raises(ParameterError, match="T_cn_cnm1"):
        read_kalibr_camchain(y)
    y.write_text("M1: 1\n")
    with pytest.raises(ParameterError, match="not a rig file"):
        read_rig(y)
    with pytest.raises(ParameterError, match="rig"):
        save_rig(tmp_path / "x.json", LEFT)
