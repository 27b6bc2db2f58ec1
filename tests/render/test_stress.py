"""The stress corpus of issue 21: views drawn from a seed, with the labellings a detector may
return."""

from __future__ import annotations

import numpy as np
import pytest

from camkit.errors import ParameterError, ShapeError
from camkit.geometry import Pose
from camkit.geometry.rotation import matrix_from_rvec
from camkit.lens import Pinhole
from camkit.render import render_checkerboard
from camkit.render.stress import acceptable_labellings, stress_view
from camkit.target import Checkerboard

CAM = Pinhole(fx=800.0, fy=800.0, cx=319.5, cy=239.5, width=640, height=480)


def _front(board: Checkerboard, back: bool = False) -> np.ndarray:
    R = matrix_from_rvec([0.0, np.pi, 0.0]) if back else np.eye(3)
    centre = board.object_points().mean(axis=0)
    return CAM.project(Pose(R, np.array([0.0, 0.0, 1.0]) - R @ centre).apply(board.object_points()))


def test_labellings_follow_the_colours():
    # 9x6 inner corners: the half-turn swaps the colours, so only the identity is right.
    b = Checkerboard(9, 6, 0.03)
    (only,) = acceptable_labellings(b, _front(b))
    assert np.array_equal(only, np.arange(54))
    # 7x5: the half-turn keeps the colours; both are right.
    b = Checkerboard(7, 5, 0.03)
    got = {tuple(p) for p in acceptable_labellings(b, _front(b))}
    grid = np.arange(35).reshape(5, 7)
    assert got == {tuple(grid.ravel()), tuple(grid[::-1, ::-1].ravel())}
    # Seen from behind (a print with the colours the other way round): the right-handed
    # labellings are the mirrors, and the colours cannot fix which.
    got = {tuple(p) for p in acceptable_labellings(b, _front(b, back=True))}
    assert got == {tuple(grid[:, ::-1].ravel()), tuple(grid[::-1, :].ravel())}


def test_truth_matches_the_renderer_and_seeds_repeat():
    v = stress_view(3, megapixels=(0.1, 0.3))
    w = stress_view(3, megapixels=(0.1, 0.3))
    assert np.array_equal(v.image, w.image) and v.tags == w.tags
    assert v.image.dtype == np.uint8 and v.image.shape[:2] == (v.camera.height, v.camera.width)
    vis = v.corners_px[v.visible]
    assert len(vis) and ((vis >= 0) & (vis <= [v.camera.width - 1, v.camera.height - 1])).all()
    # A clean render of the same board and camera puts the corners where the truth says.
    b = Checkerboard(5, 4, 0.03)
    _, truth = render_checkerboard(CAM, Pose(np.eye(3), [-0.05, -0.04, 0.6]), b)
    assert np.allclose(acceptable_labellings(b, truth.corners_px)[0], np.arange(20))


def test_corpus_spans_what_the_issue_asks():
    views = [stress_view(s, megapixels=(0.1, 0.4)) for s in range(40)]
    lenses = {v.tags["lens"] for v in views}
    assert lenses == {"pinhole", "barrel", "pincushion", "fisheye"}
    assert any(v.jpeg_quality for v in views) and any(v.noise > 0 for v in views)
    assert any(not v.whole for v in views) and any(v.tags.get("occluders") for v in views)
    assert any(v.blur_sigma_px > 1 for v in views) and any(v.motion_px > 0 for v in views)
    assert any(v.tags["inverted_print"] for v in views)
    assert all(1 <= len(v.labellings) <= 4 for v in views)
    # Backlight: the board dimmed beside a near-white window, the board's squares spanning a
    # small part of the image's range.
    lit = [v for v in views if "backlit" in v.tags and "window" in v.tags["backlit"]]
    assert lit
    for v in lit:
        on = v.corners_px[v.visible].round().astype(int)
        grey = v.image.mean(axis=2) if v.image.ndim == 3 else v.image
        top = np.percentile(grey, 99)
        assert top > 150 and np.percentile(grey[on[:, 1], on[:, 0]], 90) < 0.4 * top


def test_obliquity_is_the_angle_to_the_line_of_sight():
    """``obliquity_deg`` against the pose recovered from the truth alone: for a pinhole view the
    homography from the board's plane to normalised image coordinates is [r1 r2 t] up to
    scale, so the board's normal is r1 x r2 and its centre H (centre, 1)."""
    from camkit.target._homography import fit_homographies

    checked = 0
    for seed in range(40):
        v = stress_view(seed, megapixels=(0.1, 0.4))
        if v.tags["lens"] != "pinhole":
            continue
        cam = v.camera
        xy = np.stack([(v.corners_px[:, 0] - cam.cx) / cam.fx, (v.corners_px[:, 1] - cam.cy) / cam.fy], -1)
        obj = v.board.object_points()[:, :2]
        H = fit_homographies(obj[None], xy[None])[0]
        r1, r2 = H[:, 0] / np.linalg.norm(H[:, 0]), H[:, 1] / np.linalg.norm(H[:, 1])
        n = np.cross(r1, r2)
        c = H @ np.append(obj.mean(axis=0), 1.0)
        want = np.degrees(np.arccos(abs(n @ c) / np.linalg.norm(c)))
        assert v.obliquity_deg == pytest.approx(want, abs=0.05), seed
        checked += 1
    assert checked >= 5
    # The tilt is drawn about the camera's axis; off the axis the board is seen more or less
    # obliquely than that, up to edge on (the corpus's found rate counts views up to 70 deg).
    assert 0.0 <= min(v.obliquity_deg for v in (stress_view(s, megapixels=(0.1, 0.4)) for s in range(10))) < 70.0


def test_bad_arguments():
    with pytest.raises(ParameterError, match="seed: expected a non-negative integer"):
        stress_view(-1)
    with pytest.raises(ParameterError, match="low <= high"):
        stress_view(0, megapixels=(2.0, 1.0))
    for bad in (3.0, (1.0,), (1.0, 2.0, 3.0)):
        with pytest.raises(ParameterError, match=r"megapixels: expected \(low, high\)"):
            stress_view(0, megapixels=bad)
    with pytest.raises(ParameterError, match="square_px: expected a positive"):
        stress_view(0, square_px=(0.0, 10.0))
    b = Checkerboard(4, 3, 0.03)
    with pytest.raises(ParameterError, match="board: expected a Checkerboard"):
        acceptable_labellings((4, 3), np.zeros((12, 2)))
    with pytest.raises(ShapeError, match=r"corners_px: expected \(12, 2\)"):
        acceptable_labellings(b, np.zeros((11, 2)))
    with pytest.raises(ShapeError, match="corners_px: expected"):
        acceptable_labellings(b, np.full((12, 2), np.nan))


def test_the_corners_of_a_view_are_rendered_where_its_truth_says():
    # Corpus view 116 (546x307, barrel, squares of 19.5 px, blur 0.9 px, little noise): the
    # corners read on the corpus's render against those read on a 32x supersampled render
    # of the same view (the same noise draw). The corpus's sampling must not move them by a
    # measurable part of the error it is there to measure (issue 21 asks 0.02 px median and
    # 0.1 px 95th); at 4 samples a side it moved them 0.12 px (95th percentile).
    from camkit.target import detect_corners

    def corners(supersample=None):
        v = stress_view(116, megapixels=(0.1, 2.0), **({} if supersample is None else {"supersample": supersample}))
        det = detect_corners(v.image, v.board)
        assert det.found and det.n_found == len(v.corners_px), det.message
        return det.corners

    fine = corners(32)
    moved = np.hypot(*(corners() - fine).T)
    assert np.percentile(moved, 95) < 0.01, np.percentile(moved, 95)
    assert np.percentile(np.hypot(*(corners(4) - fine).T), 95) > 0.05
