"""File formats: images (the camera files arrive with calibration)."""

from camkit.io.images import write_png

__all__ = ["write_png"]
