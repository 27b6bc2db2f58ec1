"""Calibration targets: the Target contract, its registry, the checkerboard, ChArUco and AprilGrid, and
printable sheets."""

from camkit.target.aprilgrid import APRILTAG_FAMILIES, AprilGrid
from camkit.target.aruco import DICTIONARY_NAMES, ArucoDictionary, get_dictionary
from camkit.target.base import TARGETS, Detection, Sheet, Target, get_target, register_target
from camkit.target.charuco import Charuco
from camkit.target.checkerboard import Checkerboard, detect_corners
from camkit.target.sheet import PAPER_SIZES_MM, BoardLayout, board_layout, parse_paper, write_board

__all__ = [
    "APRILTAG_FAMILIES",
    "DICTIONARY_NAMES",
    "PAPER_SIZES_MM",
    "TARGETS",
    "AprilGrid",
    "ArucoDictionary",
    "BoardLayout",
    "Charuco",
    "Checkerboard",
    "Detection",
    "Sheet",
    "Target",
    "board_layout",
    "detect_corners",
    "get_dictionary",
    "get_target",
    "parse_paper",
    "register_target",
    "write_board",
]
