"""Optics: the issue's reference values (from published depth-of-field and exposure
calculators), thin-lens round trips, and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from camkit.errors import ParameterError
from camkit.optics import (
    aperture_diameter,
    circle_of_confusion,
    depth_of_field,
    equivalent_exposure,
    exposure_value,
    field_of_view_deg,
    focal_length_from_distances,
    hyperfocal_distance,
    image_distance,
    magnification,
    motion_blur_px,
    object_distance,
    relative_exposure_stops,
)

C = 0.03e-3  # the full-frame circle of confusion of the reference calculators


@pytest.mark.parametrize(
    ("f_number", "focus", "H", "near", "far"),
    [(2.0, 3.0, 41.72, 2.802, 3.229), (16.0, 1.0, 5.258, 0.846, 1.223)],
)
def test_reference_depth_of_field(f_number, focus, H, near, far):
    # 50 mm lens; values as the published calculators round them.
    assert hyperfocal_distance(0.050, f_number, C) == pytest.approx(H, abs=0.005)
    n, f = depth_of_field(0.050, f_number, focus, C)
    assert n == pytest.approx(near, abs=5e-4) and f == pytest.approx(far, abs=5e-4)


def test_dof_limits_have_the_coc_as_blur():
    # Definition check: objects at the near and far limits blur to exactly c.
    n, f = depth_of_field(0.050, 2.0, 3.0, C)
    assert circle_of_confusion(0.050, 2.0, 3.0, n) == pytest.approx(C, rel=1e-12)
    assert circle_of_confusion(0.050, 2.0, 3.0, f) == pytest.approx(C, rel=1e-12)


def test_far_limit_infinite_at_and_beyond_hyperfocal():
    H = hyperfocal_distance(0.050, 8.0, C)
    assert depth_of_field(0.050, 8.0, H, C)[1] == np.inf
    assert depth_of_field(0.050, 8.0, 2 * H, C)[1] == np.inf
    assert depth_of_field(0.050, 8.0, H, C)[0] == pytest.approx(H / 2, rel=1e-3)


def test_fov_and_exposure_reference_values():
    assert field_of_view_deg(0.036, 0.050) == pytest.approx(39.60, abs=0.005)
    assert exposure_value(16.0, 1 / 125) == pytest.approx(14.97, abs=0.005)
    assert exposure_value(16.0, 1 / 125, iso=400) == pytest.approx(14.97 - 2, abs=0.005)
    assert aperture_diameter(0.050, 2.0) == pytest.approx(0.025)


@given(st.floats(0.004, 0.6), st.floats(1.001, 1000.0))
def test_thin_lens_round_trips(f, ratio):
    d0 = f * ratio
    d1 = image_distance(f, d0)
    assert 1 / d0 + 1 / d1 == pytest.approx(1 / f, rel=1e-9)
    assert object_distance(f, d1) == pytest.approx(d0, rel=1e-9)
    assert focal_length_from_distances(d0, d1) == pytest.approx(f, rel=1e-9)
    assert magnification(f, d0) == pytest.approx(-d1 / d0, rel=1e-9)


@given(st.floats(1.0, 22.0), st.floats(1e-4, 10.0), st.floats(0.5, 32.0))
def test_equivalent_exposures_keep_the_light(N, t, N2):
    t2 = equivalent_exposure(N, t, new_f_number=N2)
    assert exposure_value(N, t) == pytest.approx(exposure_value(N2, t2), abs=1e-9)
    assert relative_exposure_stops(N, t, N2, t2) == pytest.approx(0.0, abs=1e-9)
    assert equivalent_exposure(N, t, new_exposure_time=t2) == pytest.approx(N2, rel=1e-9)


def test_one_stop():
    assert relative_exposure_stops(8.0, 1 / 250, 8.0, 1 / 125) == pytest.approx(1.0)
    assert relative_exposure_stops(8.0, 1 / 250, 5.6, 1 / 250) == pytest.approx(2 * np.log2(8 / 5.6))


def test_motion_blur_and_arrays():
    assert motion_blur_px([[3.0, 4.0], [6.0, 8.0]], 0.1).tolist() == pytest.approx([0.5, 1.0])
    assert np.allclose(field_of_view_deg(np.array([0.036, 0.024]), 0.050), [39.5978, 26.9915], atol=1e-4)


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda: image_distance(0.05, 0.04), "object_distance: expected distances beyond the focal length"),
        (lambda: image_distance(-0.05, 1.0), "focal_length: expected finite values > 0"),
        (lambda: hyperfocal_distance(0.05, 0.0, C), "f_number: expected finite values > 0"),
        (lambda: depth_of_field(0.05, 2.0, np.nan, C), "focus_distance: expected finite values > 0"),
        (lambda: exposure_value(2.0, 0.0), "exposure_time: expected finite values > 0"),
        (lambda: equivalent_exposure(2.0, 0.1), "exactly one of"),
        (lambda: equivalent_exposure(2.0, 0.1, new_f_number=2, new_exposure_time=1), "exactly one of"),
        (lambda: motion_blur_px(np.inf, 0.1), "image_velocity_px_per_s: expected finite"),
    ],
)
def test_bad_input(call, needle):
    with pytest.raises(ParameterError) as info:
        call()
    assert needle in str(info.value)
