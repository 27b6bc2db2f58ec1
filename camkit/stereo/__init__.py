"""Stereo pairs: rectification, rectified maps, triangulation with covariance.

Calibrate the pair (or a larger rig) with :func:`camkit.calib.calibrate_rig`."""

from camkit.stereo.rectify import StereoRectification, rectify, rectify_maps
from camkit.stereo.triangulate import Triangulation, epipolar_error, triangulate

__all__ = ["StereoRectification", "Triangulation", "epipolar_error", "rectify", "rectify_maps", "triangulate"]
