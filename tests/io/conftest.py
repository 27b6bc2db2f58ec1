"""Fixtures of the io tests (no __init__.py here: a package named "io" would shadow the standard library)."""

from __future__ import annotations

import pytest


def write_dng(path, mosaic, cfa=(0, 1, 1, 2), black=64, white=4095, neutral=(0.5, 1.0, 0.8)):
    """A minimal DNG (Adobe DNG 1.4 spec: CFARepeatPatternDim, CFAPattern, DNGVersion,
    UniqueCameraModel, BlackLevel, WhiteLevel, ColorMatrix1, AsShotNeutral) written with
    tifffile's tag support; CFA codes 0 = red, 1 = green, 2 = blue (TIFF/EP)."""
    import tifffile

    tags = [(33421, "H", 2, (2, 2), True), (33422, "B", 4, tuple(cfa), True), (50706, "B", 4, (1, 4, 0, 0), True),
            (50708, "s", 0, "camkit test camera", True), (50714, "H", 1, (black,), True),
            (50717, "H", 1, (white,), True), (50721, "d", 9, (1, 0, 0, 0, 1, 0, 0, 0, 1), True),
            (50728, "d", 3, tuple(neutral), True), (271, "s", 0, "CamkitMake", True),
            (272, "s", 0, "RawModel", True)]
    tifffile.imwrite(path, mosaic, photometric=32803, extratags=tags)


@pytest.fixture
def dng_writer():
    """:func:`write_dng`, for the RAW tests."""
    return write_dng
