"""``camkit calibrate-rig`` and ``camkit rectify`` (issue 24, item 3) on real files: the
Bumblebee2 stereo pairs, and rendered pairs written as PNG."""

from __future__ import annotations

import json
import shutil
import subprocess

import numpy as np
import pytest

from camkit.cli.main import main
from camkit.geometry.pose import Pose
from camkit.io import read_image, read_rig, write_png
from camkit.lens import BrownConrady
from camkit.render import simulate_rig
from camkit.target import Checkerboard


def test_calibrate_rig_and_rectify_the_bumblebee_pairs(shared_data, tmp_path, capsys):
    src = shared_data / "real_boards" / "boofcv_bumblebee" / "images"
    left, right = tmp_path / "L", tmp_path / "R"
    left.mkdir()
    right.mkdir()
    for f in src.glob("*_left*.jpg"):
        shutil.copy(f, left / f.name.replace("_left", "_"))
    for f in sorted(src.glob("*_right*.jpg"))[:-1]:  # one right image missing: paired by name, not order
        shutil.copy(f, right / f.name.replace("_right", "_"))
    out = tmp_path / "out"
    code = main(["calibrate-rig", "--camera", "left", str(left), "--camera", "right", str(right), "--board", "6x4",
                 "--square", "30mm", "--pair-by", r"(\d+)\.jpg$", "-o", str(out / "rig.json"), "--opencv",
                 str(out / "stereo.yml"), "--kalibr", str(out / "camchain.yaml"), "--fix", "k3", "--report",
                 str(out / "report.html")])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "Pairing" in text and "11 instants" in text
    doc = json.loads((out / "rig.json").read_text())
    assert doc["format"] == "camkit-rig"
    rig = read_rig(out / "rig.json")
    assert rig.names == ("left", "right")
    assert abs(np.linalg.norm(rig.relative_pose("left", "right").t) - 0.12) < 0.001
    assert read_rig(out / "stereo.yml").relative_pose(0, 1).allclose(rig.relative_pose(0, 1), atol=1e-9)
    assert read_rig(out / "camchain.yaml").relative_pose(0, 1).allclose(rig.relative_pose(0, 1), atol=1e-9)
    # Rectify three pairs: the rectified images put the board's corners on the same rows.
    lp = sorted(left.glob("*.jpg"))[:3]
    rp = sorted(right.glob("*.jpg"))[:3]
    for k, (a, b) in enumerate(zip(lp, rp, strict=True)):
        shutil.copy(a, tmp_path / f"pair_l{k}.jpg")
        shutil.copy(b, tmp_path / f"pair_r{k}.jpg")
    code = main(["rectify", str(out / "rig.json"), str(tmp_path / "pair_l*.jpg"), str(tmp_path / "pair_r*.jpg"),
                 "-o", str(tmp_path / "rect")])
    assert code == 0, capsys.readouterr().out
    board = Checkerboard(inner_cols=6, inner_rows=4, square=0.03)
    rows = []
    for k in range(3):
        dl = board.detect(read_image(tmp_path / "rect" / "left" / f"pair_l{k}.png"))
        dr = board.detect(read_image(tmp_path / "rect" / "right" / f"pair_r{k}.png"))
        if dl.found and dr.found:
            rows.append(dl.corners[:, 1] - dr.corners[:, 1])
    assert rows, "the board was not found in any rectified pair"
    assert np.sqrt(np.nanmean(np.concatenate(rows) ** 2)) < 0.3
    assert (tmp_path / "rect" / "stereo.yml").is_file()
    _check_report_in_a_browser(out / "report.html", tmp_path)


def _check_report_in_a_browser(report, tmp_path):
    text = report.read_text()
    for head in ("The rig", "The rig from above", "RMS per instant", "A rectified pair", "Camera left",
                 "Camera right"):
        assert f"<h2>{head}" in text, head
    browser = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome", "chrome")
                    if shutil.which(n)), None)
    if browser is None:
        pytest.skip("no Chromium on this machine (.ci/run installs Debian's chromium package where it can); "
                    "the rig report's browser check was not run")
    shot = tmp_path / "shot.png"
    proc = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           f"--screenshot={shot}", "--window-size=1200,3200", report.resolve().as_uri()],
                          capture_output=True, text=True, timeout=120, check=False)
    assert shot.exists(), proc.stderr[-2000:]
    img = read_image(shot)[:, :, :3].astype(np.int32)
    # The embedded figures were decoded: the rectified pair's photos fill many rows with colour.
    coloured = (img.max(axis=2) - img.min(axis=2)) > 40
    assert (coloured.mean(axis=1) > 0.2).sum() > 200


def test_rectify_refuses_unpaired_inputs_and_keeps_inputs(tmp_path, capsys):
    cam = BrownConrady(fx=300.0, fy=300.0, cx=159.5, cy=119.5, width=320, height=240, k1=-0.05)
    board = Checkerboard(inner_cols=5, inner_rows=4, square=0.03)
    inst = simulate_rig([cam, cam], [Pose.identity(), Pose.from_rvec([0, 0, 0], [-0.1, 0, 0])], board, 2, seed=0)
    for k, i in enumerate(inst):
        for side, img in zip("lr", i.images, strict=True):
            write_png(tmp_path / f"{side}{k}.png", (np.clip(img, 0, 1) * 255).astype(np.uint8))
    from camkit.calib import CameraRig
    from camkit.io import save_rig

    save_rig(tmp_path / "rig.json", CameraRig(("a", "b"), (cam, cam),
                                             (Pose.identity(), Pose.from_rvec([0, 0, 0], [-0.1, 0, 0]))))
    code = main(["rectify", str(tmp_path / "rig.json"), str(tmp_path / "l*.png"), str(tmp_path / "r0.png"),
                 "-o", str(tmp_path / "out")])
    assert code != 0
    assert "as many right images as left ones" in capsys.readouterr().err
    code = main(["rectify", str(tmp_path / "rig.json"), str(tmp_path / "l*.png"), str(tmp_path / "r*.png"),
                 "-o", str(tmp_path / "out"), "--mode", "full"])
    assert code == 0
    assert sorted(p.name for p in (tmp_path / "out" / "a").iterdir()) == ["l0.png", "l1.png"]
    assert not list((tmp_path / "out").rglob("*.tmp*"))


def test_calibrate_rig_bad_arguments(tmp_path, capsys):
    (tmp_path / "a").mkdir()
    write_png(tmp_path / "a" / "x.png", np.zeros((8, 8), np.uint8))
    code = main(["calibrate-rig", "--camera", "left", str(tmp_path / "a"), "--board", "6x4", "--square", "30mm"])
    assert code != 0 and "two or more cameras" in capsys.readouterr().err
    code = main(["calibrate-rig", "--camera", "l", str(tmp_path / "a"), "--camera", "r", str(tmp_path / "a"),
                 "--board", "6x4", "--square", "30mm", "--kalibr", str(tmp_path / "c.yaml")])
    assert code != 0 and "--fix k3" in capsys.readouterr().err
    code = main(["calibrate-rig", "--camera", "l", str(tmp_path / "a"), "--camera", "l", str(tmp_path / "a"),
                 "--board", "6x4", "--square", "30mm"])
    assert code != 0 and "given twice" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["rectify", "rig.json", "a", "b", "-o", "x", "--mode", "2"])


def test_a_damaged_or_odd_sized_file_leaves_its_camera_out_of_that_instant(tmp_path, capsys):
    """As ``camkit calibrate`` leaves such files out: a truncated left image and a right image
    of another size are each left out of their instant, with the reason (printed, in the job
    and in that camera's rejected_views); the other cameras' images of those instants count."""
    from camkit.errors import ParameterError
    from camkit.pipeline import calibrate_rig_files

    cam = BrownConrady(fx=300.0, fy=300.0, cx=159.5, cy=119.5, width=320, height=240, k1=-0.05)
    board = Checkerboard(inner_cols=5, inner_rows=4, square=0.03)
    rig_poses = [Pose.identity(), Pose.from_rvec([0, 0, 0], [-0.1, 0, 0])]
    inst = simulate_rig([cam, cam], rig_poses, board, 6, seed=0)
    for k, i in enumerate(inst):
        for side, img in zip("lr", i.images, strict=True):
            write_png(tmp_path / f"{side}{k}.png", (np.clip(img, 0, 1) * 255).astype(np.uint8))
    (tmp_path / "l2.png").write_bytes((tmp_path / "l2.png").read_bytes()[:2000])
    write_png(tmp_path / "r4.png", np.pad(read_image(tmp_path / "r4.png"), ((0, 2), (0, 2)), mode="edge"))
    code = main(["calibrate-rig", "--camera", "left", str(tmp_path / "l*.png"), "--camera", "right",
                 str(tmp_path / "r*.png"), "--board", "5x4", "--square", "30mm", "-o", str(tmp_path / "rig.json")])
    text = " ".join(capsys.readouterr().out.split())
    assert code == 0, text
    assert "camera left, instant 2: left out:" in text and "damaged PNG file" in text
    assert ("camera right, instant 4: left out: 322x242, where the other 5 images are 320x240 (one calibration is "
            "for one camera mode)") in text
    job = calibrate_rig_files({"left": sorted(tmp_path.glob("l*.png")), "right": sorted(tmp_path.glob("r*.png"))},
                              board)
    assert [(c, k) for c, k, _ in job.left_out] == [(0, 2), (1, 4)]
    left, right = job.result.cameras
    assert 2 not in left.view_indices and 4 not in right.view_indices and 4 in left.view_indices
    assert dict(left.rejected_views)[2] == job.left_out[0][2] and dict(right.rejected_views)[4] == job.left_out[1][2]
    assert abs(np.linalg.norm(job.result.cam_from_rig[1].t) - 0.1) < 0.002
    with pytest.raises(ParameterError, match=r"--camera left: none of this camera's 1 images could be read; the first: "):
        calibrate_rig_files({"left": [tmp_path / "l2.png"], "right": [tmp_path / "r0.png"]}, board)
