"""File formats: images and camera files."""

from camkit.io.camera_files import (
    CAMERA_FORMAT_VERSION,
    load_camera,
    read_opencv_yaml,
    save_camera,
    write_colmap_cameras,
    write_opencv_yaml,
)
from camkit.io.images import IMAGE_SUFFIXES, ImageFileError, read_image, write_png

__all__ = [
    "CAMERA_FORMAT_VERSION",
    "IMAGE_SUFFIXES",
    "ImageFileError",
    "load_camera",
    "read_image",
    "read_opencv_yaml",
    "save_camera",
    "write_colmap_cameras",
    "write_opencv_yaml",
    "write_png",
]
