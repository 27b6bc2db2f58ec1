"""The sensor: colour filter arrays, demosaicing and the EMVA 1288 noise model."""

from camkit.sensor.cfa import PATTERNS, cfa_masks, mosaic, pattern_code, three_layer
from camkit.sensor.demosaic import DEMOSAIC_METHODS, demosaic
from camkit.sensor.noise import EMVA1288Sensor, PhotonTransfer, photon_transfer, photons_from_irradiance

__all__ = [
    "DEMOSAIC_METHODS",
    "PATTERNS",
    "EMVA1288Sensor",
    "PhotonTransfer",
    "cfa_masks",
    "demosaic",
    "mosaic",
    "pattern_code",
    "photon_transfer",
    "photons_from_irradiance",
    "three_layer",
]
