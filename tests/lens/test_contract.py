"""The contract every registered camera model keeps (ARCHITECTURE.md section 3).

Each model in camkit.lens.MODELS is held to it twice: with its own ``example()`` (what the CLI
and the demo use) and with a richer instance below that sets every parameter; a model
registered without one fails test_every_model_has_an_example, so the contract cannot be
skipped by omission.
"""

from __future__ import annotations

import numpy as np
import pytest

from camkit.errors import CamkitError, ParameterError, ShapeError
from camkit.lens import MODELS, BrownConrady, KannalaBrandt, Pinhole, get_model

EXAMPLES = {
    "pinhole": Pinhole(fx=812.5, fy=809.0, cx=331.2, cy=244.7, skew=0.3, width=640, height=480),
    "brown-conrady": BrownConrady(
        fx=812.5, fy=809.0, cx=331.2, cy=244.7, skew=0.3, width=640, height=480,
        k1=-0.28, k2=0.11, k3=-0.02, p1=8e-4, p2=-5e-4, k4=0.05, k5=0.01, k6=0.002,
        s1=1e-3, s2=-2e-4, s3=5e-4, s4=1e-4,
    ),
    "kannala-brandt": KannalaBrandt(
        fx=285.0, fy=286.5, cx=641.0, cy=481.5, skew=0.2, width=1280, height=960,
        k1=-0.012, k2=0.035, k3=-0.014, k4=0.002,
    ),
}
NAMES = sorted(EXAMPLES)


def test_every_model_has_an_example():
    assert set(EXAMPLES) == set(MODELS)


@pytest.fixture(params=[(n, kind) for n in NAMES for kind in ("rich", "example")], ids=lambda p: f"{p[0]}-{p[1]}")
def model(request):
    name, kind = request.param
    return EXAMPLES[name] if kind == "rich" else get_model(name).example()


def _pixel_grid(m, n=41):
    u = np.linspace(-0.5, m.width - 0.5, n)
    v = np.linspace(-0.5, m.height - 0.5, n)
    return np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)


def test_registry_entry(model):
    assert get_model(model.name) is type(model)
    assert model.param_names[:5] == ("fx", "fy", "cx", "cy", "skew")
    for group, members in model.param_groups.items():
        assert set(members) <= set(model.param_names), group
    assert {"focal", "principal_point", "skew", "distortion"} <= set(model.param_groups)


def test_params_round_trip(model):
    again = type(model).from_params(model.params(), width=model.width, height=model.height)
    assert again == model
    assert model.params().shape == (len(model.param_names),)


@pytest.mark.parametrize("depth", [0.5, 1.0, 2.0])
def test_round_trip_over_the_image(model, depth):
    px = _pixel_grid(model)
    rays = model.unproject(px)
    valid = np.isfinite(rays).all(axis=-1)
    # The typical instances are invertible over their whole image, corners included.
    assert valid.all()
    assert np.allclose(np.linalg.norm(rays, axis=-1), 1.0, atol=1e-15 * 8)
    # The promise: <= 1e-9 px wherever the model is invertible.
    assert np.abs(model.project(rays * depth) - px).max() <= 1e-9
    pts = model.unproject_depth(px, depth)
    ok = rays[:, 2] > 0  # a fisheye's rays beyond 90 degrees have no point at positive depth
    assert np.allclose(pts[ok, 2], depth, rtol=1e-14)
    assert np.abs(model.project(pts[ok]) - px[ok]).max() <= 1e-9
    assert np.isnan(pts[~ok]).all()


def test_project_then_unproject_gives_the_ray(model):
    rng = np.random.default_rng(42)
    px = rng.uniform([0, 0], [model.width - 1, model.height - 1], size=(500, 2))
    X = model.unproject(px) * rng.uniform(0.3, 30, size=(500, 1))
    back = model.unproject(model.project(X))
    cosang = np.sum(back * X, axis=-1) / np.linalg.norm(X, axis=-1)
    assert np.all(cosang > 1 - 1e-14)


def test_jacobians_match_central_differences(model):
    rng = np.random.default_rng(7)
    px = rng.uniform([20, 20], [model.width - 20, model.height - 20], size=(25, 2))
    X = model.unproject(px) * rng.uniform(0.5, 3, size=(25, 1))
    uv, dp, dk = model.project_with_jacobian(X)
    assert np.allclose(uv, model.project(X), atol=1e-12)
    h = 1e-6  # central differences: truncation O(h^2) and rounding O(eps/h) both ~1e-10 relative
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        num = (model.project(X + e) - model.project(X - e)) / (2 * h)
        assert np.allclose(dp[..., j], num, rtol=1e-6, atol=1e-5), j
    p0 = model.params()
    cls = type(model)
    for j, name in enumerate(model.param_names):
        step = h * max(1.0, abs(p0[j]))
        e = np.zeros_like(p0)
        e[j] = step
        plus = cls.from_params(p0 + e, width=model.width, height=model.height).project(X)
        minus = cls.from_params(p0 - e, width=model.width, height=model.height).project(X)
        num = (plus - minus) / (2 * step)
        assert np.allclose(dk[..., j], num, rtol=1e-6, atol=1e-5), name


def test_broadcasting(model):
    rng = np.random.default_rng(3)
    px = rng.uniform([0, 0], [model.width - 1, model.height - 1], size=(2, 3, 4, 2))
    rays = model.unproject(px)
    assert rays.shape == (2, 3, 4, 3)
    assert np.array_equal(rays.reshape(-1, 3), model.unproject(px.reshape(-1, 2)))
    uv, dp, dk = model.project_with_jacobian(rays)
    assert uv.shape == (2, 3, 4, 2) and dp.shape == (2, 3, 4, 2, 3)
    assert dk.shape == (2, 3, 4, 2, len(model.param_names))
    assert model.project(rays[0, 0, 0]).shape == (2,)
    assert model.project(np.zeros((0, 3))).shape == (0, 2)


def test_float32_input(model):
    rng = np.random.default_rng(5)
    px = rng.uniform([0, 0], [model.width - 1, model.height - 1], size=(100, 2))
    X = (model.unproject(px) * 2).astype(np.float32)
    out = model.project(X)
    assert out.dtype == np.float64
    assert np.array_equal(out, model.project(X.astype(np.float64)))


def test_nan_rows_pass_through_as_nan(model):
    out = model.project(np.array([[np.nan] * 3, [0.0, 0.0, 1.0]]))
    assert np.isnan(out[0]).all() and np.isfinite(out[1]).all()
    assert np.isnan(model.unproject([[np.nan, np.nan]])).all()
    with pytest.raises(ParameterError, match="points_cam: expected finite"):
        model.project([[np.nan, 0.0, 1.0]])


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ({"fx": -800.0}, "fx: expected a positive number"),
        ({"fy": 0.0}, "fy: expected a positive number"),
        ({"cx": np.nan}, "cx: expected a finite real number"),
        ({"skew": np.inf}, "skew: expected a finite real number"),
        ({"width": -1}, "width: expected a positive integer"),
    ],
)
def test_bad_parameters_are_rejected(model, change, needle):
    with pytest.raises(ParameterError) as info:
        model.replace(**change)
    assert needle in str(info.value)


def test_bad_distortion_parameter_is_rejected(model):
    dist = model.param_groups["distortion"]
    if not dist:
        pytest.skip("pinhole has no distortion parameters")
    with pytest.raises(ParameterError, match=f"{dist[0]}: expected a finite real number"):
        model.replace(**{dist[0]: float("nan")})


def test_bad_arrays(model):
    with pytest.raises(ShapeError, match=r"points_cam: expected shape \(\.\.\., 3\), got \(17, 2\)"):
        model.project(np.zeros((17, 2)))
    with pytest.raises(ShapeError, match="pixels: expected shape"):
        model.unproject(np.zeros((4, 3)))
    with pytest.raises(CamkitError, match="params: expected shape"):
        type(model).from_params(np.zeros(3), width=10, height=10)


def test_model_knowledge_lives_on_the_model(model):
    """example(), initial_guess(), to_dict(), start_projection(), linear_start_terms and
    default_fixed: what calibration, the CLI and the demo ask a model, answered by the model."""
    cls = type(model)
    ex = cls.example()
    assert type(ex) is cls and ex.width > 0 and ex.height > 0
    d = model.to_dict()
    assert d["type"] == model.name and d["width"] == model.width
    assert cls.from_params([d[n] for n in model.param_names], width=d["width"], height=d["height"]) == model
    guess = cls.initial_guess(model.K, width=model.width, height=model.height)
    np.testing.assert_array_equal(guess.K, model.K)
    dist = [n for n in model.param_groups["distortion"]]
    assert all(getattr(guess, n) == 0.0 for n in dist)  # neutral distortion for every model here
    assert cls.start_projection() in ("perspective", "equidistant")
    assert set(cls.linear_start_terms) <= set(dist) and set(cls.default_fixed) <= set(model.param_names)


def test_for_points_projects_the_same_and_leaves_the_model_alone(model):
    """The solver's trial model (valid region searched only as far as its points) projects
    those points exactly as the model does, and the model keeps its own region."""
    px = _pixel_grid(model, 15)
    rays = model.unproject(px)
    pts = rays[np.isfinite(rays).all(axis=1)] * 2.0
    before = model.project(pts)
    trial = model.for_points(pts)
    np.testing.assert_array_equal(trial.project(pts), before)
    np.testing.assert_array_equal(model.project(pts), before)
    assert trial == model


def test_fused_map_agrees_with_projecting_the_rays(model):
    """map_from_rays (the fast path of resampling maps) against project() of the same rays."""
    from camkit.resample import reproject_map

    dst = Pinhole(fx=0.8 * model.fx, fy=0.8 * model.fy, cx=model.cx, cy=model.cy, width=model.width // 4,
                  height=model.height // 4)
    M = np.linalg.inv(dst.K)
    out = np.empty((dst.height, dst.width, 2))
    assert model.map_from_rays(M, out)  # every model here has a fused kernel
    v, u = np.mgrid[0:dst.height, 0:dst.width]
    rays = np.stack([u, v, np.ones_like(u)], axis=-1) @ M.T
    ref = model.project(rays.astype(np.float64))
    ok = np.isfinite(ref).all(axis=-1)
    np.testing.assert_allclose(out[ok], ref[ok], atol=1e-6)  # float64 throughout: rounding only
    assert np.array_equal(np.isfinite(out).all(axis=-1), ok)
    np.testing.assert_allclose(reproject_map(model, dst, dtype=np.float64)[ok], ref[ok], atol=1e-6)


def test_fused_map_and_trial_model_refuse_bad_arguments(model):
    with pytest.raises(ShapeError, match=r"M: expected shape \(3, 3\)"):
        model.map_from_rays(np.eye(2), np.empty((4, 4, 2)))
    with pytest.raises(ShapeError, match="out: expected a writeable C-contiguous float32 or float64 array"):
        model.map_from_rays(np.eye(3), np.empty((4, 4, 2), dtype=np.int32))
    with pytest.raises(ShapeError, match="out: expected"):
        model.map_from_rays(np.eye(3), np.empty((4, 4, 3)))
    with pytest.raises(ShapeError, match="points_cam"):
        model.for_points(np.zeros((5, 2)))
    with pytest.raises(ShapeError, match=r"K: expected shape \(3, 3\)"):
        type(model).initial_guess(np.eye(2), width=640, height=480)
