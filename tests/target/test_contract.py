"""The contract every registered target keeps (docs/extending.md): render its example with the
simulator, detect it, and recover the truth; print its sheet; refuse bad input in words.

A second, test-only target (a checkerboard that the renderer knows only by its sheet) runs the
same contract through the generic sheet path, so the seam is exercised beyond the one target
with a fast path of its own."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from camkit.errors import CamkitError
from camkit.geometry import Pose
from camkit.lens import BrownConrady
from camkit.render import render_target
from camkit.target import TARGETS, Checkerboard, Detection, Sheet, Target, get_target, register_target, write_board


@dataclass(frozen=True, slots=True)
class SheetOnlyBoard(Target):
    """A checkerboard the renderer has no fast path for: it is drawn from its sheet."""

    board: Checkerboard

    name = "test-sheet-only-board"

    def object_points(self) -> np.ndarray:
        return self.board.object_points()

    def detect(self, image: np.ndarray) -> Detection:
        return self.board.detect(image)

    def sheet(self) -> Sheet:
        return self.board.sheet()

    @classmethod
    def example(cls) -> SheetOnlyBoard:
        return cls(Checkerboard(7, 5, 0.03))


@pytest.fixture(params=[*sorted(TARGETS), SheetOnlyBoard.name])
def target_cls(request):
    if request.param == SheetOnlyBoard.name:
        register_target(SheetOnlyBoard)
        yield SheetOnlyBoard
        del TARGETS[SheetOnlyBoard.name]
    else:
        yield get_target(request.param)


def _camera() -> BrownConrady:
    # A mildly barrel-distorted 640x480 camera, the target filling about half the frame.
    return BrownConrady(fx=600.0, fy=600.0, cx=319.5, cy=239.5, k1=-0.1, k2=0.02, width=640, height=480)


def test_registry_names_each_class_once(target_cls):
    assert get_target(target_cls.name) is target_cls
    with pytest.raises(CamkitError, match="name: expected one of"):
        get_target("no-such-target")


def test_render_detect_recover_the_truth(target_cls):
    """Every point the detector returns carries the right id and lies within 0.1 px of the
    truth (median under 0.03 px: a noise-free render, the sub-pixel fit's own bias), and at
    least 90 % of the visible points are found at a 25 degree tilt."""
    target = target_cls.example()
    pts = target.object_points()
    assert pts.ndim == 2 and pts.shape[1] == 3 and np.isfinite(pts).all()
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    span = float(np.ptp(pts[:, 0]))
    camera = _camera()
    R = Pose.from_rvec([np.deg2rad(25.0), np.deg2rad(-10.0), 0.05], [0.0, 0.0, 0.0]).R
    if target.sheet().v_up:  # the printed face towards the camera: z points at it
        R = R @ np.diag([1.0, -1.0, -1.0])
    t = np.array([0.0, 0.0, 1.9 * span * camera.fx / camera.width]) - R @ centre
    img, truth = render_target(camera, Pose(R, t), target)
    det = target.detect(img)
    assert isinstance(det, Detection) and det.found, det.message
    assert det.corners.shape == (len(pts), 2) and det.sigma_px.shape == (len(pts),)
    assert np.array_equal(det.ids, np.flatnonzero(np.isfinite(det.corners).all(axis=1)))
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert err.max() < 0.1 and np.median(err) < 0.03, (err.max(), np.median(err))
    assert det.n_found >= 0.9 * truth.visible.sum()
    assert np.isfinite(det.sigma).all() and (det.sigma > 0).all()


@pytest.mark.parametrize("image,message", [
    (np.full((60, 80), np.nan), "image: expected finite values"),
    (np.full((60, 80), np.inf, dtype=np.float32), "image: expected finite values"),
    (np.zeros((0, 80)), "image: expected a non-empty image"),
    (np.zeros((60, 80), dtype=bool), "image: expected dtype"),
    (np.zeros(80), "image: expected shape"),
    ([[0.0, 1.0]], "image: expected a NumPy array"),
])
def test_bad_images_are_refused_naming_the_image(target_cls, image, message):
    with pytest.raises(CamkitError, match=message):
        target_cls.example().detect(image)


def test_nothing_in_view_is_not_found_with_a_reason(target_cls):
    target = target_cls.example()
    det = target.detect(np.full((240, 320), 0.5))
    assert not det.found and det.n_found == 0 and det.message.startswith("not found")


def test_sheet_prints_and_holds_the_points(target_cls, tmp_path):
    """The sheet's marks lie on the paper, and its extent holds every point; it prints."""
    target = target_cls.example()
    sheet = target.sheet()
    u0, v0, u1, v1 = sheet.extent
    b = sheet.black
    assert b.shape[1] == 4 and (b[:, 0] < b[:, 2]).all() and (b[:, 1] < b[:, 3]).all()
    assert (b[:, 0] >= u0).all() and (b[:, 2] <= u1).all() and (b[:, 1] >= v0).all() and (b[:, 3] <= v1).all()
    pts = target.object_points()
    assert (pts[:, 0] > u0).all() and (pts[:, 0] < u1).all() and (pts[:, 1] > v0).all() and (pts[:, 1] < v1).all()
    assert sheet.label
    out = write_board(tmp_path / "t.png", target, dpi=72)
    assert out.stat().st_size > 0


def test_a_name_is_registered_once():
    @dataclass(frozen=True, slots=True)
    class Impostor(SheetOnlyBoard):
        name = "checkerboard"

    with pytest.raises(CamkitError, match="already registered"):
        register_target(Impostor)
    assert TARGETS["checkerboard"] is Checkerboard
