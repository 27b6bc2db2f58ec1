"""EMVA 1288 sensor: mean and variance of simulated frames against the model, photon
transfer recovers the system gain within 1 %, saturation and clipping, SNR curve."""

from __future__ import annotations

import numpy as np
import pytest

from camkit.errors import EstimationError, ParameterError
from camkit.sensor import EMVA1288Sensor, photon_transfer, photons_from_irradiance

CAM = EMVA1288Sensor(quantum_efficiency=0.55, system_gain=0.31, dark_noise_e=4.0,
                     dark_current_e_per_s=50.0, full_well_e=11000.0, bit_depth=12, black_level_dn=80.0)


def test_mean_and_variance_follow_the_model():
    rng = np.random.default_rng(1)
    t = 0.02
    mu_p = 3000.0
    raw = CAM.simulate(np.full((400, 400), mu_p), exposure_time=t, rng=rng).astype(np.float64)
    K, eta = CAM.system_gain, CAM.quantum_efficiency
    mean = CAM.black_level_dn + K * (eta * mu_p + CAM.dark_current_e_per_s * t)
    var = K**2 * (CAM.dark_noise_e**2 + CAM.dark_current_e_per_s * t + eta * mu_p) + 1 / 12
    # 160 000 samples: the mean is known to ~0.05 DN, the variance to ~0.4 % (3 sigma).
    assert raw.mean() == pytest.approx(mean, abs=0.1)
    assert raw.var() == pytest.approx(var, rel=0.01)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_photon_transfer_recovers_the_gain(seed):
    rng = np.random.default_rng(seed)
    t = 0.01
    sat = CAM.saturation_photons(t)
    levels = np.linspace(0.05, 0.95, 12) * sat
    flats = [(CAM.simulate(np.full((300, 300), p), exposure_time=t, rng=rng),
              CAM.simulate(np.full((300, 300), p), exposure_time=t, rng=rng)) for p in levels]
    dark = (CAM.simulate(np.zeros((300, 300)), exposure_time=t, rng=rng),
            CAM.simulate(np.zeros((300, 300)), exposure_time=t, rng=rng))
    pt = photon_transfer(flats, dark, max_dn=CAM.max_dn)
    assert pt.system_gain == pytest.approx(CAM.system_gain, rel=0.01)
    assert pt.used.sum() >= 6


def test_saturation_and_adc_clipping():
    rng = np.random.default_rng(3)
    raw = CAM.simulate(np.full((50, 50), 1e7), exposure_time=0.01, rng=rng)
    # The full well (11000 e * 0.31 = 3410 DN, + 80 black) saturates before the 12-bit ADC
    # (4095): the output stays within read noise (5 sigma = 20 e) of the full-well level.
    full = CAM.black_level_dn + CAM.system_gain * CAM.full_well_e
    assert abs(raw.mean() - full) < 0.1
    assert raw.max() <= full + CAM.system_gain * 5 * CAM.dark_noise_e + 1
    tiny_gain = EMVA1288Sensor(system_gain=2.0, full_well_e=1e6, bit_depth=10)
    assert tiny_gain.simulate(np.full((5, 5), 1e6), exposure_time=0.01, rng=rng).max() == 1023
    # No clipping before the ADC: a dark frame keeps its noise around the black level.
    dark = CAM.simulate(np.zeros((300, 300)), exposure_time=1e-3, rng=rng).astype(float)
    expected_var = CAM.system_gain**2 * (CAM.dark_noise_e**2 + CAM.dark_current_e_per_s * 1e-3) + 1 / 12
    assert dark.var() == pytest.approx(expected_var, rel=0.03)


def test_snr_and_dynamic_range():
    t = 0.01
    p_min = CAM.absolute_sensitivity_threshold(t)
    assert CAM.snr(p_min, t) == pytest.approx(1.0, rel=1e-9)  # the definition of the threshold
    big = CAM.saturation_photons(t)
    # Shot-noise limit near saturation: SNR ~ sqrt(eta mu_p).
    assert CAM.snr(big, t) == pytest.approx(np.sqrt(CAM.quantum_efficiency * big), rel=0.01)
    assert CAM.dynamic_range(t) == pytest.approx(big / p_min)
    assert CAM.saturation_capacity_e(t) == pytest.approx(CAM.full_well_e - CAM.dark_current_e_per_s * t)


def test_irradiance_to_photons():
    # mu_p = E A t lambda / (h c), with exact SI constants.
    assert photons_from_irradiance(0.01, 0.01, 25e-12, 550e-9) == pytest.approx(
        0.01 * 25e-12 * 0.01 * 550e-9 / (6.62607015e-34 * 299792458.0), rel=1e-12)


def test_bad_input():
    with pytest.raises(ParameterError, match="quantum_efficiency: expected a value in"):
        EMVA1288Sensor(quantum_efficiency=1.5)
    with pytest.raises(ParameterError, match=r"bit_depth: expected 1\.\.16"):
        EMVA1288Sensor(bit_depth=20)
    with pytest.raises(ParameterError, match=r"rng: expected a numpy\.random\.Generator"):
        CAM.simulate(np.ones((2, 2)), exposure_time=0.01, rng=42)
    with pytest.raises(ParameterError, match="photons: expected finite values >= 0"):
        CAM.simulate(np.array([[-1.0]]), exposure_time=0.01, rng=np.random.default_rng())
    with pytest.raises(EstimationError, match="at least two exposure levels"):
        photon_transfer([(np.zeros((4, 4)), np.zeros((4, 4)))], (np.zeros((4, 4)), np.zeros((4, 4))))
