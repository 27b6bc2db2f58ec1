"""The pipeline, the only place where paths become arrays: each image decoded once (the report
gets the thumbnails kept while detecting), outputs checked before work, the undistortion of
files; and the report leaves the caller's matplotlib alone."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import camkit.io.images
from camkit.errors import CamkitError
from camkit.io import write_png
from camkit.lens import BrownConrady
from camkit.pipeline import THUMBNAIL_WIDTH, calibrate_files, undistort_files
from camkit.render import plan_views, render_checkerboard
from camkit.target import Checkerboard

BOARD = Checkerboard(7, 5, 0.03)
CAM = BrownConrady(fx=420.0, fy=420.0, cx=319.5, cy=239.5, k1=-0.15, k2=0.03, width=640, height=480)


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    folder = tmp_path_factory.mktemp("photos")
    paths = []
    for k, pose in enumerate(plan_views(CAM, BOARD, 6, np.random.default_rng(7))):
        img, _ = render_checkerboard(CAM, pose, BOARD)
        paths.append(write_png(folder / f"v{k}.png", np.clip(img * 255 + 0.5, 0, 255).astype(np.uint8)))
    return paths


def test_each_image_is_read_and_decoded_once_and_the_report_gets_thumbnails(photos, tmp_path, monkeypatch):
    calls, decoded = [], []
    real, real_decode = camkit.io.images._read_bytes, camkit.io.images._decode_image

    def counting(path, *args, **kwargs):
        calls.append(path)
        return real(path, *args, **kwargs)

    def counting_decode(data, path, *args):
        decoded.append(path)
        return real_decode(data, path, *args)

    monkeypatch.setattr(camkit.io.images, "_read_bytes", counting)
    monkeypatch.setattr(camkit.io.images, "_decode_image", counting_decode)
    seen = {}
    import camkit.report.html as html

    real_thumb = html._thumb

    def spy(img, width, full_width):
        seen.setdefault("widths", []).append(img.shape[1])
        return real_thumb(img, width, full_width)

    monkeypatch.setattr(html, "_thumb", spy)
    job = calibrate_files(photos, BOARD, report_file=tmp_path / "r.html", results_file=tmp_path / "r.json")
    assert sorted(map(str, calls)) == sorted(map(str, photos))  # once each: pixels, EXIF, report
    assert sorted(map(str, decoded)) == sorted(map(str, photos))
    assert [i.width for i in job.image_info] == [640] * len(photos)  # the EXIF reading got its bytes
    assert seen["widths"] == [THUMBNAIL_WIDTH] * len(photos)  # the report drew the kept thumbnails
    assert job.result.rms_px < 0.1 and len(job.result.detections) == len(photos)
    assert (tmp_path / "r.html").stat().st_size > 10_000


def test_an_image_of_another_size_is_left_out_with_the_reason(photos, tmp_path):
    """One calibration is for one camera mode: an image of another size than most (Udacity's
    CarND set has two 1281x721 images among eighteen 1280x720) is left out, named with its size
    in the views' reasons, and the others calibrate; where no size has a majority, which is the
    camera's is not clear, and the sizes are listed."""
    from camkit.io import read_image

    big = read_image(photos[0])
    odd = write_png(tmp_path / "odd.png", np.pad(big, ((0, 1), (0, 1)), mode="edge"))  # the board found in it
    assert BOARD.detect(read_image(odd)).found
    job = calibrate_files([*photos, odd], BOARD)
    w, h = big.shape[1], big.shape[0]
    reason = f"left out: {w + 1}x{h + 1}, where the other 6 images are {w}x{h} (one calibration is for one camera mode)"
    assert job.result.rejected_views == [(6, reason)] and len(job.result.poses) == 6
    assert job.result.detections[6].found  # what the detector found is kept, for the report
    assert job.result.rms_px == pytest.approx(calibrate_files(photos, BOARD).result.rms_px, abs=1e-9)
    small = [write_png(tmp_path / f"s{k}.png", np.zeros((100, 120), np.uint8)) for k in range(3)]
    with pytest.raises(CamkitError, match=rf"images: expected one size for all images \(one calibration is for one "
                                          rf"camera mode\), got {w}x{h} \(3 images\), 120x100 \(3 images\); calibrate "
                                          r"each camera mode on its own"):
        calibrate_files([*photos[:3], *small], BOARD)


def test_images_turned_a_quarter_are_named_as_copies_turned_upright(photos, tmp_path):
    """A phone's photos exported turned upright by their orientation tag have sizes that are
    each other's turned a quarter: the reason says so, and where to find the files that fit."""
    from camkit.io import read_image

    big = read_image(photos[0])
    w, h = big.shape[1], big.shape[0]
    turned = [write_png(tmp_path / f"t{k}.png", np.rot90(read_image(photos[k])).copy()) for k in range(3)]
    job = calibrate_files([*photos, turned[0]], BOARD)
    assert job.result.rejected_views == [(6, f"left out: {h}x{w}, where the other 6 images are {w}x{h} (the same "
                                              "size turned a quarter: copies turned upright by their orientation tag, "
                                              "where camkit reads rows as the sensor stored them; use the camera's "
                                              "original files)")]
    with pytest.raises(CamkitError, match=rf"got {w}x{h} \(3 images\), {h}x{w} \(3 images\); the same size turned a "
                                          "quarter: copies turned upright"):
        calibrate_files([*photos[:3], *turned], BOARD)


def test_a_damaged_file_is_left_out_with_the_reason(photos, tmp_path):
    """A damaged image among many (a truncated JPEG, text named .png) stops nothing: it is left
    out with what the reader said, in the views' reasons, and the report labels its place;
    where no image can be read the job says so."""
    import json

    cut = tmp_path / "cut.png"
    cut.write_bytes(photos[0].read_bytes()[:3000])
    text = tmp_path / "notes.png"
    text.write_text("taken on Tuesday")
    job = calibrate_files([*photos, cut, text], BOARD, report_file=tmp_path / "r.html",
                          results_file=tmp_path / "r.json")
    reasons = dict(job.result.rejected_views)
    assert set(reasons) == {6, 7} and len(job.result.poses) == 6
    assert reasons[6].startswith(f"left out: {cut}: damaged PNG file")
    assert reasons[7].startswith(f"left out: {text}: not an image file camkit reads")
    assert job.result.rms_px == pytest.approx(calibrate_files(photos, BOARD).result.rms_px, abs=1e-9)
    views = json.loads((tmp_path / "r.json").read_text())["views"]
    assert [v["reason"] for v in views[6:]] == [reasons[6], reasons[7]]
    assert "damaged PNG file" in (tmp_path / "r.html").read_text()
    with pytest.raises(CamkitError, match=rf"paths: none of the 2 images could be read; the first: {cut}: damaged"):
        calibrate_files([cut, text], BOARD)


def test_undistort_files_checks_everything_before_the_first_write(photos, tmp_path):
    out = tmp_path / "out"
    job = undistort_files(photos[:2], CAM, out)
    assert [p.name for p in job.written] == ["v0.png", "v1.png"] and job.new_model.is_pinhole
    assert all(p.is_file() for p in job.written)
    # Two inputs with one stem: refused before anything is written (the folder is not made).
    twin = tmp_path / "twin" / "v0.png"
    twin.parent.mkdir()
    twin.write_bytes(photos[0].read_bytes())
    with pytest.raises(CamkitError, match="two inputs have the same name"):
        undistort_files([photos[0], twin], CAM, tmp_path / "never")
    assert not (tmp_path / "never").exists()
    with pytest.raises(CamkitError, match=r"out_dir: .* is one of the input images"):
        undistort_files([photos[0]], CAM, photos[0].parent)


def test_the_report_leaves_the_callers_matplotlib_backend_alone(tmp_path):
    """The report draws on its own Figures: a process that chose a backend keeps it, and
    pyplot (global state) is never imported."""
    code = textwrap.dedent(f"""
        import sys
        import matplotlib
        matplotlib.use("svg")
        import numpy as np
        from camkit.calib import calibrate
        from camkit.render import default_camera, plan_views
        from camkit.report import write_report
        from camkit.target import Checkerboard
        board, cam = Checkerboard(9, 6, 0.03), default_camera("brown-conrady")
        obj = board.object_points()
        poses = plan_views(cam, board, 5, np.random.default_rng(3))
        res = calibrate([obj] * 5, [cam.project(p.apply(obj)) for p in poses], width=cam.width, height=cam.height)
        write_report({str(tmp_path / 'r.html')!r}, res)
        print(matplotlib.get_backend(), "matplotlib.pyplot" in sys.modules)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["svg", "False"]


def test_bad_arguments_are_named(photos, tmp_path):
    from camkit.calib import calibrate_detections
    from camkit.errors import ParameterError

    with pytest.raises(ParameterError, match="board: expected a camkit target"):
        calibrate_files(photos, (7, 5))
    with pytest.raises(ParameterError, match="paths: no images given"):
        calibrate_files([], BOARD)
    with pytest.raises(ParameterError, match="model: expected a camkit camera model"):
        undistort_files(photos[:1], "camera.json", tmp_path / "u")
    with pytest.raises(ParameterError, match="detections: expected a non-empty list of Detection"):
        calibrate_detections([], BOARD, width=640, height=480)
    with pytest.raises(ParameterError, match="detections: expected a non-empty list of Detection"):
        calibrate_detections([np.zeros((35, 2))], BOARD, width=640, height=480)
    assert not (tmp_path / "u").exists()
