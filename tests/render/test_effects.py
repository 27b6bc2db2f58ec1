"""Physical effects in the simulator: each one does what its physics says, the noisy
pipeline is reproducible from the seed, and bad combinations are refused."""

from __future__ import annotations

import numpy as np
import pytest

from camkit.errors import ParameterError
from camkit.geometry import Pose
from camkit.lens import BrownConrady, LateralChromaticAberration
from camkit.optics import circle_of_confusion
from camkit.render import Defocus, Effects, Exposure, Motion, render_checkerboard, render_view
from camkit.sensor import EMVA1288Sensor
from camkit.target import Checkerboard

CAM = BrownConrady(fx=500.0, fy=500.0, cx=319.5, cy=239.5, width=640, height=480, k1=-0.15)
BOARD = Checkerboard(7, 5, 0.04)
POSE = Pose.from_ypr(np.radians([10, -8, 3]), [-0.12, -0.08, 0.7])


def _edge_sharpness(img):
    g = np.abs(np.diff(img, axis=1))
    return float(np.percentile(g, 99.9))


def test_motion_blur_zero_velocity_is_static_and_motion_blurs():
    static, truth = render_checkerboard(CAM, POSE, BOARD)
    still, truth_m = render_view(CAM, POSE, BOARD, Effects(motion=Motion(exposure_time=0.02, samples=5)))
    assert np.allclose(still, static, atol=1e-12)
    moving, truth_m = render_view(CAM, POSE, BOARD, Effects(motion=Motion(
        linear_velocity=(0.5, 0.0, 0.0), exposure_time=0.02, samples=9)))
    # 0.5 m/s for 20 ms at 0.7 m through f = 500 px: a streak of about 7 px along x.
    assert _edge_sharpness(moving) < 0.5 * _edge_sharpness(static)
    assert np.allclose(truth_m.corners_px, truth.corners_px)  # truth is mid-exposure


def test_defocus_follows_the_circle_of_confusion():
    focused = Defocus(focal_length=0.004, f_number=1.4, focus_distance=0.7, pixel_pitch=8e-6)
    static, _ = render_checkerboard(CAM, Pose(np.eye(3), [-0.12, -0.08, 0.7]), BOARD)
    sharp, _ = render_view(CAM, Pose(np.eye(3), [-0.12, -0.08, 0.7]), BOARD, Effects(defocus=focused))
    assert np.allclose(sharp, static)  # the board lies in the focus plane: blur < 0.5 px
    near = Defocus(focal_length=0.004, f_number=1.4, focus_distance=0.2, pixel_pitch=8e-6)
    blurred, _ = render_view(CAM, Pose(np.eye(3), [-0.12, -0.08, 0.7]), BOARD, Effects(defocus=near))
    assert _edge_sharpness(blurred) < 0.5 * _edge_sharpness(static)
    d = near.blur_diameter_px(np.array([0.7]))[0]
    assert d == pytest.approx(circle_of_confusion(0.004, 1.4, 0.2, 0.7) / 8e-6)


def test_chromatic_aberration_separates_the_channels():
    tca = LateralChromaticAberration(vr=1.004, vb=0.996)
    img, _ = render_view(CAM, POSE, BOARD, Effects(chromatic=tca))
    assert img.shape == (480, 640, 3)
    assert np.abs(img[..., 0] - img[..., 1]).max() > 0.1  # fringes at the edges
    grey, _ = render_view(CAM, POSE, BOARD, Effects(colour=True))
    assert np.array_equal(grey[..., 0], grey[..., 2])


def test_full_sensor_pipeline_is_reproducible_from_the_seed():
    fx = Effects(exposure=Exposure(photons_at_white=8000.0, exposure_time=0.01), sensor=EMVA1288Sensor(),
                 cfa="RGGB", demosaic="malvar")
    a, _ = render_view(CAM, POSE, BOARD, fx, rng=np.random.default_rng(7))
    b, _ = render_view(CAM, POSE, BOARD, fx, rng=np.random.default_rng(7))
    c, _ = render_view(CAM, POSE, BOARD, fx, rng=np.random.default_rng(8))
    assert a.dtype == np.uint16 and a.shape == (480, 640, 3)
    assert a.tobytes() == b.tobytes() and a.tobytes() != c.tobytes()
    raw, _ = render_view(CAM, POSE, BOARD, Effects(exposure=fx.exposure, sensor=fx.sensor, cfa="GBRG",
                                                   demosaic=None), rng=np.random.default_rng(7))
    assert raw.shape == (480, 640) and raw.dtype == np.uint16
    # Exposure scales light: white paper collects photons_at_white * eta * K DN above black.
    white = EMVA1288Sensor()
    grey, _ = render_view(CAM, POSE, BOARD, Effects(exposure=fx.exposure, sensor=white),
                              rng=np.random.default_rng(1))
    margin = grey[5:40, 5:40]  # background, reflectance 0.5
    assert margin.mean() == pytest.approx(white.black_level_dn + white.system_gain * white.quantum_efficiency
                                          * 8000 * 0.5 + white.dark_current_e_per_s * 0.01 * white.system_gain,
                                          abs=1.0)


def test_bad_combinations():
    with pytest.raises(ParameterError, match="sensor: needs exposure"):
        Effects(sensor=EMVA1288Sensor())
    with pytest.raises(ParameterError, match=r"rng: expected a numpy\.random\.Generator"):
        render_view(CAM, POSE, BOARD, Effects(exposure=Exposure(photons_at_white=1e3, exposure_time=0.01),
                                              sensor=EMVA1288Sensor()))
    with pytest.raises(ParameterError, match="cfa: expected one of"):
        Effects(cfa="RGBG")
    with pytest.raises(ParameterError, match="samples: expected an odd number"):
        Motion(samples=4)
    with pytest.raises(ParameterError, match="focus_distance: expected more than the focal length"):
        Defocus(focal_length=0.05, f_number=2.0, focus_distance=0.01, pixel_pitch=5e-6)
    with pytest.raises(ParameterError, match="effects: expected an Effects"):
        render_view(CAM, POSE, BOARD, {"motion": None})
