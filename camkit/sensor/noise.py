"""An EMVA 1288 camera: from photons to digital numbers, with the standard's noise model.

The linear model of the EMVA Standard 1288 (release 4.0, European Machine Vision
Association, 2021): a pixel converts ``mu_p`` photons to ``eta mu_p`` electrons (quantum
efficiency ``eta``), with Poisson shot noise; dark current adds ``mu_I t`` electrons, also
Poisson; readout adds Gaussian dark noise of ``sigma_d`` electrons; the system gain ``K``
(DN per electron) scales the charge, an offset (black level) is added, and the ADC rounds
to integers and clips to ``[0, 2^bits - 1]``. The well holds at most ``full_well_e``
electrons. Nothing else clips: negative noise excursions survive until the ADC.

Mean and variance (EMVA 1288 eqs. 2 and 5, with quantisation noise ``1/12 DN^2``)::

    mu_y      = mu_y.dark + K eta mu_p
    sigma_y^2 = K^2 (sigma_d^2 + mu_I t + eta mu_p) + 1/12
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from camkit._validate import as_finite_float, as_positive_float, as_positive_int, as_real_array
from camkit.errors import EstimationError, ParameterError, ShapeError

__all__ = ["EMVA1288Sensor", "PhotonTransfer", "photon_transfer", "photons_from_irradiance"]

_H = 6.62607015e-34  # Planck constant, J s (exact, SI 2019)
_C = 299792458.0  # speed of light, m/s (exact)


def photons_from_irradiance(irradiance: Any, exposure_time: float, pixel_area: float,
                            wavelength: float) -> Any:
    """Mean photons per pixel: ``mu_p = E A t lambda / (h c)`` (EMVA 1288 eq. 1).

    Parameters
    ----------
    irradiance : array_like, W/m^2 on the sensor
    exposure_time : float, s
    pixel_area : float, m^2
    wavelength : float, m

    >>> round(photons_from_irradiance(0.01, 0.01, (5e-6) ** 2, 550e-9))
    6922
    """
    E = as_real_array(irradiance, "irradiance")
    if not np.isfinite(E).all() or (E < 0).any():
        raise ParameterError("irradiance: expected finite values >= 0")
    t = as_positive_float(exposure_time, "exposure_time")
    A = as_positive_float(pixel_area, "pixel_area")
    lam = as_positive_float(wavelength, "wavelength")
    out = E * A * t * lam / (_H * _C)
    return float(out) if out.ndim == 0 else out


@dataclass(frozen=True, slots=True, kw_only=True)
class EMVA1288Sensor:
    """A linear camera in the EMVA 1288 model (see the module docstring).

    Parameters
    ----------
    quantum_efficiency : float in (0, 1]
        ``eta``, electrons per photon.
    system_gain : float > 0
        ``K``, DN per electron.
    dark_noise_e : float >= 0
        ``sigma_d``, temporal dark (read) noise in electrons rms.
    dark_current_e_per_s : float >= 0
        ``mu_I``, electrons per second (thermal).
    full_well_e : float > 0
        Electrons a pixel can hold.
    bit_depth : int in 1..16
    black_level_dn : float >= 0
        Offset added before the ADC (so dark noise is not clipped at 0).

    Examples
    --------
    >>> import numpy as np
    >>> cam = EMVA1288Sensor(quantum_efficiency=0.6, system_gain=0.25, dark_noise_e=3.0)
    >>> raw = cam.simulate(np.full((100, 100), 5000.0), exposure_time=0.01, rng=np.random.default_rng(0))
    >>> raw.dtype, round(float(raw.mean()) - cam.black_level_dn)
    (dtype('uint16'), 750)
    """

    quantum_efficiency: float = 0.6
    system_gain: float = 0.25
    dark_noise_e: float = 3.0
    dark_current_e_per_s: float = 10.0
    full_well_e: float = 12000.0
    bit_depth: int = 12
    black_level_dn: float = 64.0

    def __post_init__(self) -> None:
        eta = as_positive_float(self.quantum_efficiency, "quantum_efficiency")
        if eta > 1:
            raise ParameterError(f"quantum_efficiency: expected a value in (0, 1], got {eta}")
        for name in ("dark_noise_e", "dark_current_e_per_s", "black_level_dn"):
            v = as_finite_float(getattr(self, name), name)
            if v < 0:
                raise ParameterError(f"{name}: expected a value >= 0, got {v}")
            object.__setattr__(self, name, v)
        object.__setattr__(self, "quantum_efficiency", eta)
        object.__setattr__(self, "system_gain", as_positive_float(self.system_gain, "system_gain"))
        object.__setattr__(self, "full_well_e", as_positive_float(self.full_well_e, "full_well_e"))
        bits = as_positive_int(self.bit_depth, "bit_depth")
        if bits > 16:
            raise ParameterError(f"bit_depth: expected 1..16, got {bits}")
        object.__setattr__(self, "bit_depth", bits)

    @property
    def max_dn(self) -> int:
        """The ADC's largest output, ``2^bits - 1``."""
        return (1 << self.bit_depth) - 1

    def simulate(self, photons: Any, *, exposure_time: float, rng: np.random.Generator) -> np.ndarray:
        """Raw digital numbers (uint16) for mean photon counts per pixel.

        Parameters
        ----------
        photons : array_like, mean photons per pixel during the exposure (>= 0)
        exposure_time : float, s (sets the dark current's charge)
        rng : numpy.random.Generator
        """
        mu_p = as_real_array(photons, "photons")
        if not np.isfinite(mu_p).all() or (mu_p < 0).any():
            raise ParameterError("photons: expected finite values >= 0")
        t = as_positive_float(exposure_time, "exposure_time")
        if not isinstance(rng, np.random.Generator):
            raise ParameterError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
        electrons = rng.poisson(self.quantum_efficiency * mu_p + self.dark_current_e_per_s * t)
        electrons = np.minimum(electrons, self.full_well_e)
        charge = electrons + rng.normal(0.0, self.dark_noise_e, size=np.shape(electrons))
        dn = np.floor(self.system_gain * charge + self.black_level_dn + 0.5)
        return np.clip(dn, 0, self.max_dn).astype(np.uint16)

    def saturation_photons(self, exposure_time: float) -> float:
        """Mean photons per pixel at which the output saturates (the full well, or the ADC's top,
        whichever comes first)."""
        t = as_positive_float(exposure_time, "exposure_time")
        e_adc = (self.max_dn - self.black_level_dn) / self.system_gain
        e_sat = min(self.full_well_e, e_adc) - self.dark_current_e_per_s * t
        return max(e_sat, 0.0) / self.quantum_efficiency

    def saturation_capacity_e(self, exposure_time: float) -> float:
        """``mu_e.sat = eta mu_p.sat`` in electrons (EMVA 1288 sec. 6.5)."""
        return self.quantum_efficiency * self.saturation_photons(exposure_time)

    def temporal_dark_noise_e(self, exposure_time: float) -> float:
        """Dark noise including dark-current shot noise and quantisation, in electrons."""
        t = as_positive_float(exposure_time, "exposure_time")
        return math.sqrt(self.dark_noise_e**2 + self.dark_current_e_per_s * t
                         + 1.0 / (12.0 * self.system_gain**2))

    def snr(self, photons: Any, exposure_time: float) -> Any:
        """Signal-to-noise ratio ``eta mu_p / sqrt(sigma_dark^2 + eta mu_p)`` (electrons; EMVA
        1288 eq. 13), the SNR curve of the standard; 0 beyond saturation is not modelled."""
        mu_p = as_real_array(photons, "photons")
        if not np.isfinite(mu_p).all() or (mu_p < 0).any():
            raise ParameterError("photons: expected finite values >= 0")
        s = self.quantum_efficiency * mu_p
        out = s / np.sqrt(self.temporal_dark_noise_e(exposure_time) ** 2 + s)
        return float(out) if out.ndim == 0 else out

    def absolute_sensitivity_threshold(self, exposure_time: float) -> float:
        """Photons at which SNR = 1: ``(sqrt(sigma^2 + 1/4) + 1/2) / eta`` (EMVA 1288 eq. 17)."""
        sd = self.temporal_dark_noise_e(exposure_time)
        return (math.sqrt(sd * sd + 0.25) + 0.5) / self.quantum_efficiency

    def dynamic_range(self, exposure_time: float) -> float:
        """``mu_p.sat / mu_p.min`` (ratio; in dB: 20 log10)."""
        return self.saturation_photons(exposure_time) / self.absolute_sensitivity_threshold(exposure_time)


@dataclass(frozen=True, slots=True)
class PhotonTransfer:
    """The result of :func:`photon_transfer`: the fitted system gain and the points used."""

    system_gain: float
    dark_variance_dn2: float
    means_dn: np.ndarray
    variances_dn2: np.ndarray
    used: np.ndarray


def photon_transfer(flat_pairs: Any, dark_pair: Any, *, max_fraction: float = 0.7,
                    max_dn: float | None = None) -> PhotonTransfer:
    """Estimate the system gain ``K`` by the photon transfer method (EMVA 1288 sec. 6.3).

    For each pair of flat fields taken at the same exposure, the mean above dark is
    ``mu = (mean(a) + mean(b)) / 2 - mu_dark`` and the temporal variance is
    ``var(a - b) / 2 - sigma_dark^2`` (differencing the pair removes fixed-pattern noise).
    ``K`` is the slope of variance against mean, fitted by least squares over the points up to
    ``max_fraction`` of the largest mean (the standard's 0-70 % range).

    Parameters
    ----------
    flat_pairs : sequence of (frame, frame), each (H, W)
        At least two exposure levels.
    dark_pair : (frame, frame)
    max_fraction : float in (0, 1]
    max_dn : float, optional
        Exclude points whose mean comes within 1 % of this (saturating).
    """
    try:
        pairs = [(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)) for a, b in flat_pairs]
        da, db = (np.asarray(x, dtype=np.float64) for x in dark_pair)
    except (TypeError, ValueError):
        raise ShapeError("flat_pairs, dark_pair: expected pairs of equally shaped frames") from None
    if len(pairs) < 2:
        raise EstimationError("flat_pairs: need at least two exposure levels to fit a slope; "
                              "take flat fields at several exposure times")
    for a, b in [*pairs, (da, db)]:
        if a.shape != b.shape or a.ndim != 2:
            raise ShapeError(f"flat_pairs: expected pairs of equal 2-D frames, got {a.shape} and {b.shape}")
    frac = as_positive_float(max_fraction, "max_fraction")
    mu_dark = 0.5 * (da.mean() + db.mean())
    var_dark = 0.5 * np.var(da - db)
    mu = np.array([0.5 * (a.mean() + b.mean()) - mu_dark for a, b in pairs])
    var = np.array([0.5 * np.var(a - b) - var_dark for a, b in pairs])
    used = mu <= frac * mu.max()
    if max_dn is not None:
        raw_mean = mu + mu_dark
        used &= raw_mean < 0.99 * float(max_dn)
    if used.sum() < 2:
        raise EstimationError("flat_pairs: fewer than two unsaturated exposure levels in the fit range")
    A = np.stack([mu[used], np.ones(used.sum())], axis=-1)
    slope, _ = np.linalg.lstsq(A, var[used], rcond=None)[0]
    return PhotonTransfer(float(slope), float(var_dark), mu, var, used)
