"""The image-formation simulator: planar targets seen through any camera model."""

from camkit.render.target import RenderTruth, render_checkerboard

__all__ = ["RenderTruth", "render_checkerboard"]
