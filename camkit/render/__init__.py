"""The image-formation simulator: planar targets seen through any camera model."""

from camkit.render.effects import Defocus, Effects, Exposure, Motion, render_view
from camkit.render.target import RenderTruth, render_checkerboard

__all__ = ["Defocus", "Effects", "Exposure", "Motion", "RenderTruth", "render_checkerboard", "render_view"]
