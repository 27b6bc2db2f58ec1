"""The command line: demo (the whole pipeline on a simulated camera), calibrate on the real
set, board files at exact scale, undistort, the lens calculators; errors are reported, not
raised, and inputs are never overwritten."""

from __future__ import annotations

import json
import re
import shutil
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest

from camkit.calib import Checkerboard, detect_corners
from camkit.cli.main import main
from camkit.io import load_camera, read_image, save_camera, write_png
from camkit.render import default_camera, plan_views, render_checkerboard
from camkit.resample import optimal_pinhole


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "camkit-demo"
    assert main(["demo", "-o", str(out)]) == 0
    return out


def test_demo_calibrates_the_simulated_camera(demo_dir):
    truth = default_camera("brown-conrady")
    cam = load_camera(demo_dir / "camera.json")
    # Acceptance of issue 7 (10b) through the demo's full path: defocus, noise, Bayer, demosaicing.
    assert abs(cam.fx / truth.fx - 1) < 5e-4 and abs(cam.fy / truth.fy - 1) < 5e-4
    assert abs(cam.cx - truth.cx) < 0.3 and abs(cam.cy - truth.cy) < 0.3
    assert len(list((demo_dir / "images").glob("view_*.png"))) == 15
    res = json.loads((demo_dir / "results.json").read_text())
    assert len(res["views"]) == 15 and all(v["found"] for v in res["views"])
    html = (demo_dir / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 6 and "<td>fx</td>" in html


def test_demo_prints_estimate_next_to_truth(demo_dir, capsys):
    # The fixture's output was captured by an earlier test; run the printing part again cheaply.
    assert main(["demo", "-o", str(demo_dir), "--views", "6", "--seed", "3"]) == 0
    out = capsys.readouterr().out
    assert "Estimated and true parameters" in out and "report.html" in out
    row = re.search(r"fx\s+│\s+([\d.]+)\s+│\s+[\d.e-]+\s+│\s+([\d.]+)", out)
    assert row and abs(float(row.group(1)) - float(row.group(2))) < 1.0


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def test_report_renders_in_a_real_browser(demo_dir, tmp_path):
    browser = _chromium()
    if browser is None:
        pytest.skip("no Chromium on this machine (.ci/run installs Debian's chromium package where it can); "
                    "the report's browser check was not run")
    shot = tmp_path / "shot.png"
    proc = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           f"--screenshot={shot}", "--window-size=1200,5000",
                           (demo_dir / "report.html").resolve().as_uri()],
                          capture_output=True, text=True, timeout=120, check=False)
    assert shot.exists(), proc.stderr[-2000:]
    img = read_image(shot)[:, :, :3].astype(np.int32)
    # Rendered figures: many coloured pixels (the colour maps), not just black text on white.
    coloured = (img.max(axis=2) - img.min(axis=2)) > 60
    assert coloured.mean() > 0.05, f"only {coloured.mean():.3f} of the page is coloured"
    # And the embedded images were decoded: blocks of the page far below the text are coloured.
    rows = coloured.mean(axis=1)
    assert (rows > 0.2).sum() > 500


def test_calibrate_real_set_writes_the_results_format(shared_data, tmp_path, capsys):
    files = sorted((shared_data / "bouguet_calib_example").glob("Image*.tif"))
    args = ["calibrate", *map(str, files), "--board", "12x13", "--square", "30mm", "-o", str(tmp_path / "cam.json"),
            "--json", str(tmp_path / "res.json"), "--report", str(tmp_path / "rep.html")]
    assert main(args) == 0
    assert "20 of 20 views used" in capsys.readouterr().out
    doc = json.loads((tmp_path / "res.json").read_text())
    assert {"model", "rms_px", "std_px", "views", "stddev"} <= set(doc)
    assert doc["model"]["type"] == "brown-conrady" and doc["model"]["width"] == 640
    assert {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"} <= set(doc["model"])
    assert len(doc["views"]) == 20 and doc["views"][0]["image"] == files[0].name
    assert {"image", "found", "n_corners", "rms_px"} <= set(doc["views"][0])
    assert abs(doc["model"]["fx"] - 657.46) < 0.5 and max(doc["std_px"]) <= 0.15
    assert set(doc["stddev"]) == {"fx", "fy", "cx", "cy", "k1", "k2", "k3", "p1", "p2"}
    assert load_camera(tmp_path / "cam.json").fx == doc["model"]["fx"]


def test_calibrate_never_overwrites_an_input(tmp_path, capsys):
    img = tmp_path / "a.png"
    write_png(img, np.zeros((20, 20), np.uint8))
    before = img.read_bytes()
    assert main(["calibrate", str(img), "--board", "9x6", "--square", "25mm", "--report", str(img)]) == 1
    assert "never overwrites an input" in capsys.readouterr().err
    assert img.read_bytes() == before


def _png_chunks(data):
    pos, out = 8, {}
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        out.setdefault(kind, []).append(data[pos + 8:pos + 8 + n])
        pos += 12 + n
    return out


def test_board_files_print_at_exact_scale(tmp_path):
    for ext in ("pdf", "svg", "png"):
        assert main(["board", "--inner", "9x6", "--square", "25mm", "-o", str(tmp_path / f"b.{ext}")]) == 0
    # Sheet: 10x7 squares of 25 mm plus a 25 mm margin each side = 300 x 225 mm.
    pdf = (tmp_path / "b.pdf").read_bytes()
    box = re.search(rb"/MediaBox \[0 0 ([\d.]+) ([\d.]+)\]", pdf)
    assert float(box.group(1)) == pytest.approx(300 / 25.4 * 72, abs=1e-3)
    assert float(box.group(2)) == pytest.approx(225 / 25.4 * 72, abs=1e-3)
    assert pdf.count(b" re\n") == 35  # 70 squares, half of them black
    xref = int(pdf.rsplit(b"startxref\n", 1)[1].split(b"\n")[0])
    assert pdf[xref:xref + 4] == b"xref"
    offsets = [int(line[:10]) for line in pdf[xref:].split(b"\n")[3:7]]
    assert [pdf[o:o + 7] for o in offsets] == [b"%d 0 obj" % k for k in range(1, 5)]  # the xref table is right
    svg = (tmp_path / "b.svg").read_text()
    assert 'width="300.0000mm"' in svg and 'height="225.0000mm"' in svg and svg.count("<rect") == 36
    png = (tmp_path / "b.png").read_bytes()
    img = read_image(tmp_path / "b.png")
    ppm = struct.unpack(">IIB", _png_chunks(png)[b"pHYs"][0])[0]
    px = round(0.025 * 300 / 0.0254)  # 295 px per square at 300 dpi
    assert px / ppm == pytest.approx(0.025, rel=1e-4)  # a printed square is 25 mm
    assert img.shape == (7 * px + 2 * px, 10 * px + 2 * px)
    assert img[px + 3, px + 3] == 0 and img[px + 3, 2 * px + 3] == 255  # top-left square black
    assert zlib.decompress(b"".join(_png_chunks(png)[b"IDAT"]))  # well-formed
    board = Checkerboard(9, 6, 0.025)
    det = detect_corners(img, board)
    assert det.found and det.n_found == 54
    assert np.allclose(det.corners[0], [2 * px - 0.5, 2 * px - 0.5], atol=0.05)


def test_undistort_straightens_the_board(tmp_path, capsys):
    cam = default_camera("brown-conrady").replace(width=640, height=480, cx=320.5, cy=239.0, fx=500.0, fy=500.0)
    board = Checkerboard(9, 6, 0.03)
    pose = plan_views(cam, board, 1, np.random.default_rng(4))[0]
    img, _ = render_checkerboard(cam, pose, board)
    src = tmp_path / "in" / "view.png"
    src.parent.mkdir()
    write_png(src, np.clip(img * 255 + 0.5, 0, 255).astype(np.uint8))
    save_camera(tmp_path / "cam.json", cam)
    assert main(["undistort", str(tmp_path / "cam.json"), str(src), "-o", str(tmp_path / "out")]) == 0
    out = read_image(tmp_path / "out" / "view.png")
    new = optimal_pinhole(cam, 0.0)
    det = detect_corners(out, board)
    expected = new.project(pose.apply(board.object_points()))
    assert det.found and np.nanmax(np.abs(det.corners - expected)) < 0.15
    # The output folder is the input folder: refused before anything is written.
    before = src.read_bytes()
    assert main(["undistort", str(tmp_path / "cam.json"), str(src), "-o", str(src.parent)]) == 1
    assert "never overwrites an input" in capsys.readouterr().err and src.read_bytes() == before


@pytest.mark.parametrize("args,expected", [
    # Reference values from published calculators (issue 5).
    (["dof", "--focal-length", "50mm", "--f-number", "2", "--focus", "3m"],
     ["near 2.802 m, far 3.229 m", "hyperfocal distance 41.72 m"]),
    (["dof", "--focal-length", "50mm", "--f-number", "16", "--focus", "1m"],
     ["near 0.8457 m, far 1.223 m", "hyperfocal distance 5.258 m"]),
    (["fov", "--focal-length", "50mm", "--sensor", "36x24"], ["horizontal 39.60 deg"]),
    (["exposure", "--f-number", "16", "--time", "1/125"], ["EV 14.97", "f/8 at 1/500 s"]),
])
def test_lens_calculators(capsys, args, expected):
    assert main(["lens", *args]) == 0
    out = capsys.readouterr().out
    for text in expected:
        assert text in out


def test_bad_arguments_are_reported(tmp_path, capsys):
    assert main(["calibrate", str(tmp_path / "missing.png"), "--board", "9x6", "--square", "25mm"]) == 1
    assert "cannot read" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["board", "--inner", "9by6", "--square", "25mm", "-o", "x.pdf"])
    assert "COLSxROWS" in capsys.readouterr().err
    assert main(["board", "--inner", "9x6", "--square", "25mm", "-o", str(tmp_path / "b.jpg")]) == 1
    assert "expected a name ending in .pdf, .svg or .png" in capsys.readouterr().err


def test_demo_needs_three_views(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path / "d"), "--views", "2"]) == 1
    assert "views: expected at least 3" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()  # refused before anything was written


def test_no_command_prints_help(capsys):
    assert main([]) == 2
    assert "demo" in capsys.readouterr().out


def test_module_entry_point():
    proc = subprocess.run([sys.executable, "-m", "camkit", "--version"], capture_output=True, text=True,
                          check=False, timeout=120)
    assert proc.returncode == 0 and proc.stdout.startswith("camkit ")
