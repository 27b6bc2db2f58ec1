"""Optics and exposure: the thin lens, depth of field, aperture, exposure value, motion blur."""

from camkit.optics.exposure import (
    equivalent_exposure,
    exposure_value,
    motion_blur_px,
    relative_exposure_stops,
)
from camkit.optics.thin_lens import (
    aperture_diameter,
    circle_of_confusion,
    depth_of_field,
    field_of_view_deg,
    focal_length_from_distances,
    hyperfocal_distance,
    image_distance,
    magnification,
    object_distance,
)

__all__ = [
    "aperture_diameter",
    "circle_of_confusion",
    "depth_of_field",
    "equivalent_exposure",
    "exposure_value",
    "field_of_view_deg",
    "focal_length_from_distances",
    "hyperfocal_distance",
    "image_distance",
    "magnification",
    "motion_blur_px",
    "object_distance",
    "relative_exposure_stops",
]
