"""The report's numbers: projection uncertainty against Monte Carlo sampling of the
parameters; the results file's format; bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from camkit.calib import calibrate
from camkit.errors import CamkitError, ParameterError
from camkit.io.results import results_to_dict, write_results
from camkit.render import default_camera, plan_views
from camkit.report import projection_uncertainty, write_report
from camkit.target import Checkerboard

BOARD = Checkerboard(9, 6, 0.03)
CAM = default_camera("brown-conrady")


@pytest.fixture(scope="module")
def result():
    rng = np.random.default_rng(21)
    poses = plan_views(CAM, BOARD, 10, rng)
    obj = BOARD.object_points()
    imgs = [CAM.project(p.apply(obj)) + rng.normal(0, 0.2, (len(obj), 2)) for p in poses]
    imgs[3][:50] = np.nan  # a view with 4 corners left, on one line: left out
    imgs[7][np.r_[0:20, 22:54]] = np.nan  # 2 corners
    imgs[8][np.setdiff1d(np.arange(54), [10, 11, 12, 20, 30])] = np.nan  # 5 corners, not on one line
    imgs[5][:] = np.nan  # a view with none: left out
    return calibrate([obj] * 10, imgs, width=CAM.width, height=CAM.height)


def test_projection_uncertainty_matches_sampling(result):
    m, cov, names = result.model, result.covariance, result.free_params
    pix = np.array([[640.0, 480.0], [50.0, 40.0], [1200.0, 900.0]])
    sig = projection_uncertainty(m, cov, names, pix, 0.5)
    X = m.unproject_depth(pix, np.full(3, 0.5))
    rng = np.random.default_rng(0)
    samples = rng.multivariate_normal(m.params()[[m.param_names.index(n) for n in names]], cov, 4000)
    idx = [m.param_names.index(n) for n in names]
    out = []
    for s in samples:
        p = m.params().copy()
        p[idx] = s
        out.append(type(m).from_params(p, width=m.width, height=m.height).project(X))
    out = np.array(out)
    # Largest principal standard deviation of the sampled pixels, per point.
    worst = [np.sqrt(np.linalg.eigvalsh(np.cov(out[:, k].T)).max()) for k in range(3)]
    assert np.allclose(sig, worst, rtol=0.08), (sig, worst)
    assert sig[1] > sig[0]  # the image corner, far from most corners, is less certain


def test_results_file_format(result, tmp_path):
    doc = results_to_dict(result, [f"v{i}.png" for i in range(10)])
    assert [v["image"] for v in doc["views"]] == [f"v{i}.png" for i in range(10)]
    assert doc["views"][5] == {"image": "v5.png", "found": False, "n_corners": 0, "rms_px": None,
                               "reason": "only 0 corners (4 needed)"}
    assert doc["views"][3]["reason"] == "the 4 corners seen lie on one line" and not doc["views"][3]["found"]
    assert doc["views"][8]["n_corners"] == 5 and doc["views"][8]["found"]
    assert doc["std_px"] == [pytest.approx(v) for v in result.std_px]
    path = write_results(tmp_path / "r.json", result)
    back = json.loads(path.read_text())  # strict JSON: no NaN
    assert back["views"][0]["image"] == "view 0" and back["stddev"]["fx"] == pytest.approx(result.stddev["fx"])
    with pytest.raises(ParameterError, match="image_names: expected 10 names"):
        results_to_dict(result, ["a"])
    with pytest.raises(ParameterError, match="result: expected a CalibrationResult"):
        results_to_dict({"rms_px": 1.0})


def test_report_without_images_and_bad_input(result, tmp_path):
    path = write_report(tmp_path / "r.html", result, truth=CAM)
    html = path.read_text()
    assert html.count("data:image/png;base64,") == 5  # no thumbnails without images
    assert "only 0 corners" in html and "<th>true</th>" in html
    with pytest.raises(ParameterError, match="images: expected 10 images"):
        write_report(tmp_path / "x.html", result, images=[np.zeros((4, 4))])
    with pytest.raises(ParameterError, match="result: expected a CalibrationResult"):
        write_report(tmp_path / "x.html", "result")
    assert not (tmp_path / "x.html").exists()


@pytest.mark.parametrize("kwargs,match", [
    ({"model": "camera"}, "model: expected a camkit camera model"),
    ({"free_params": ("fx", "zz")}, r"free_params: \['zz'\] are not parameters"),
    ({"covariance": np.eye(3)}, r"covariance: expected shape \(2, 2\)"),
    ({"depth_m": 0.0}, "depth_m"),
    ({"pixels": [[1.0, 2.0, 3.0]]}, r"pixels: expected shape \(\.\.\., 2\)"),
])
def test_projection_uncertainty_bad_input(kwargs, match):
    args = {"model": CAM, "covariance": np.eye(2), "free_params": ("fx", "fy"), "pixels": [[10.0, 20.0]],
            "depth_m": 1.0} | kwargs
    with pytest.raises(CamkitError, match=match):
        projection_uncertainty(**args)
