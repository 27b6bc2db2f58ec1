"""The sensor: colour filter arrays, demosaicing and the EMVA 1288 noise model."""

from camkit.sensor.cfa import PATTERNS, cfa_masks, mosaic, pattern_code, three_layer
from camkit.sensor.demosaic import DEMOSAIC_METHODS, demosaic

__all__ = ["DEMOSAIC_METHODS", "PATTERNS", "cfa_masks", "demosaic", "mosaic", "pattern_code", "three_layer"]
