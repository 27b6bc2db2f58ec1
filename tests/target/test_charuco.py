"""ChArUco boards: OpenCV's layout and numbering, the printed sheet read by OpenCV, detection on
renders (partial boards, a second board, fisheye) and on OpenCV's tutorial photos."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from camkit.errors import ParameterError
from camkit.geometry import Pose
from camkit.io import read_image
from camkit.lens import BrownConrady, KannalaBrandt
from camkit.render import render_target
from camkit.target import Charuco
from camkit.target._markers import TypicalSigma, find_markers, refine_quads, x_corner_shades
from camkit.target.base import Sheet
from camkit.target.charuco import _BOARD_Z, _colours_on_circle, _dark_squares, _lattice_reads, _square_signs
from camkit.target.checkerboard import _to_grey


def _cv_board(b: Charuco):
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, b.dictionary))
    board = cv2.aruco.CharucoBoard((b.squares_x, b.squares_y), b.square, b.marker, d)
    board.setLegacyPattern(b.legacy)
    return board


@pytest.mark.parametrize("size", [(5, 7), (4, 4), (6, 5), (3, 3), (5, 6), (11, 8)])
@pytest.mark.parametrize("legacy", [False, True])
def test_layout_and_ids_are_opencvs(size, legacy):
    b = Charuco(*size, 0.03, 0.022, "DICT_5X5_100", legacy=legacy)
    ref = _cv_board(b)
    np.testing.assert_allclose(b.object_points(), ref.getChessboardCorners(), atol=1e-7)  # float32 there
    assert b.n_points == len(b.object_points()) == len(ref.getChessboardCorners())
    np.testing.assert_allclose(b.marker_corners(), np.array(ref.getObjPoints()), atol=1e-7)
    np.testing.assert_array_equal(np.arange(b.n_markers), np.ravel(ref.getIds()))


def test_opencv_reads_the_printed_sheet():
    """The sheet at 4 px/mm, given to OpenCV's CharucoDetector: every marker with its id, every
    corner with its id where camkit's object points put it."""
    b = Charuco(5, 7, 0.04, 0.02, "DICT_6X6_250")
    sheet = b.sheet()
    img = sheet.raster(4000.0)
    corners, ids, _, mids = cv2.aruco.CharucoDetector(_cv_board(b)).detectBoard(img)
    assert sorted(np.ravel(mids)) == list(range(b.n_markers))
    truth = (b.object_points()[:, :2] - sheet.extent[:2]) * 4000.0 - 0.5
    np.testing.assert_array_equal(np.sort(np.ravel(ids)), np.arange(b.n_points))
    # OpenCV's corner refinement on a hard-edged raster: within 0.1 px.
    np.testing.assert_allclose(corners.reshape(-1, 2), truth[np.ravel(ids)], atol=0.1)


def _view(board, camera, rvec, centre_at=None, distance=1.9):
    pts = board.object_points()
    c = 0.5 * (pts.min(axis=0) + pts.max(axis=0)) if centre_at is None else np.asarray(centre_at, float)
    R = Pose.from_rvec(rvec, [0.0, 0.0, 0.0]).R
    t = np.array([0.0, 0.0, distance * np.ptp(pts[:, 0]) * camera.fx / camera.width]) - R @ c
    return Pose(R, t)


CAM = BrownConrady(fx=600.0, fy=600.0, cx=319.5, cy=239.5, k1=-0.1, k2=0.02, width=640, height=480)


def test_a_board_half_out_of_the_frame_gives_every_corner_it_shows_beside_markers():
    b = Charuco(11, 8, 0.03, 0.022, "DICT_5X5_100")
    pose = _view(b, CAM, [0.3, -0.2, 0.1], centre_at=[0.05, 0.05, 0.0], distance=1.2)
    img, truth = render_target(CAM, pose, b)
    det = b.detect(img)
    assert det.found, det.message
    assert 0 < truth.visible.sum() < b.n_points  # a partial view
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert err.max() < 0.1, err.max()  # every returned id right, and placed at its saddle point
    # Every corner well inside the image (its four squares seen) is found.
    px = truth.corners_px
    inner = truth.visible & (px[:, 0] > 30) & (px[:, 0] < 610) & (px[:, 1] > 30) & (px[:, 1] < 450)
    assert set(np.flatnonzero(inner)) <= set(det.ids.tolist())


def test_a_second_board_in_view_is_another_boards():
    """Two boards, different dictionaries, side by side: each detector returns its own corners."""
    a = Charuco(5, 7, 0.03, 0.02, "DICT_5X5_100")
    b = Charuco(5, 7, 0.03, 0.02, "DICT_4X4_50")
    pa = _view(a, CAM, [0.2, 0.3, 0.0], centre_at=[0.17, 0.1, 0.0], distance=5.0)
    pb = Pose(pa.R, pa.t + pa.R @ [0.22, 0.0, 0.0])  # beside a, sheets not overlapping
    img_b, truth_b = render_target(CAM, pb, b)
    img, truth_a = render_target(CAM, pa, a, background=img_b)
    for board, truth in ((a, truth_a), (b, truth_b)):
        det = board.detect(img)
        assert det.found, det.message
        err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
        assert err.max() < 0.1 and det.n_found >= 0.9 * truth.visible.sum()


def test_fisheye_view():
    cam = KannalaBrandt(fx=300.0, fy=300.0, cx=319.5, cy=239.5, k1=0.02, k2=-0.005, width=640, height=480)
    b = Charuco(7, 5, 0.04, 0.03, "DICT_4X4_50")
    img, truth = render_target(cam, _view(b, cam, [0.4, 0.3, 0.2], distance=1.2), b)
    det = b.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    # Edges curve across the saddle window under a fisheye: the quadratic fit is biased by up
    # to ~0.15 px there (a wrong id would be a square, tens of px, away).
    assert det.n_found >= 0.8 * truth.visible.sum(), det.message
    assert err.max() < 0.2 and np.median(err) < 0.05, (err.max(), np.median(err))


class _Unread(Charuco):
    """A ChArUco board whose right half's markers are printed white: no code to read there."""

    __slots__ = ()

    def sheet(self) -> Sheet:
        s = Charuco.sheet(self)
        square = s.black[:, 2] - s.black[:, 0] >= 0.999 * self.square
        keep = square | (s.black[:, 0] < 0.5 * self.squares_x * self.square)
        return Sheet(s.extent, s.black[keep], s.label)


def test_corners_past_the_markers_read_are_found_with_their_labels():
    """Markers too small or blurred to read leave their squares: the corners there are reached
    from those read, square by square. Half the board without codes: every corner found, each
    within 0.05 px of its truth (without the growth, 20 of the 40)."""
    b = _Unread(9, 6, 0.03, 0.021, "DICT_4X4_50")
    img, truth = render_target(CAM, _view(b, CAM, [0.3, -0.4, 0.1], distance=1.5), b)
    assert truth.visible.all()
    det = b.detect(img)
    assert det.n_found == b.n_points, det.message
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert err.max() < 0.05, err.max()


def test_a_board_one_corner_wide_is_found():
    """A 2x8 board has a single column of seven corners: every step handles it, step 6 (the
    point of symmetry of corners still missing, whose neighbourhood maps and spacing take the
    lattice's width) included, run here for the last corner cut off by the image's edge;
    every corner returned within 0.1 px."""
    b = Charuco(2, 8, 0.04, 0.03, "DICT_4X4_50")
    pts = b.object_points()
    R = Pose.from_rvec([0.2, -0.1, 0.3], [0.0, 0.0, 0.0]).R
    img, truth = render_target(CAM, Pose(R, np.array([0.0, 0.0, 0.5]) - R @ pts.mean(axis=0)), b)
    y = truth.corners_px[:, 1]
    assert np.all(np.diff(y) > 0)
    cut = int(0.5 * (y[-1] + y[-2]))  # the last corner's row and below cut off
    det = b.detect(img[:cut])
    assert det.found and det.n_found == 6 and 6 not in det.ids, det.message
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert err.max() < 0.1, err


def test_a_grown_corner_needs_its_black_squares_where_the_lattice_puts_them():
    """The growth's colour test, on a render with the true corners and steps: at a corner under
    its own label both black squares are dark; under the next corner's label along its row
    (the same junction, the other colouring), or at a marker's centre, they are not."""
    b = Charuco(7, 5, 0.03, 0.022, "DICT_4X4_50")
    img, truth = render_target(CAM, _view(b, CAM, [0.3, -0.2, 0.1]), b)
    g = _to_grey(img)
    T = truth.corners_px
    nx = b.squares_x - 1
    ids = np.array([c for c in range(nx + 1, b.n_points - nx - 1) if 0 < c % nx < nx - 1])
    u = (T[ids + 1] - T[ids - 1]) / 2
    v = (T[ids + nx] - T[ids - nx]) / 2
    rho = np.full(len(ids), 1.5)
    x, mid = x_corner_shades(g, T[ids], rho)
    assert x.all()
    assert _dark_squares(b, g, ids, T[ids], u, v, mid).all()
    assert not _dark_squares(b, g, ids + 1, T[ids], u, v, mid).any()
    centres = T[ids] + 0.5 * (u + v)  # the centre of square (cx, cy): a marker where it holds one
    marker = (ids // nx + ids % nx) % 2 == 1  # cx + cy odd: square (cx, cy) holds a marker
    assert marker.any() and not _dark_squares(b, g, ids[marker], centres[marker], u[marker], v[marker],
                                              mid[marker]).any()


def test_a_crossing_of_white_margins_beside_a_marker_is_not_the_corner():
    """Corpus view 13 (benchmarks/charuco_corpus.py: squares of 28 px, margins of 3.5 px,
    blurred): the markers' homography put corner 54 2.9 px off, and the saddle fit carried it
    to where the white margins around the marker beside it cross, 4.2 px from the corner,
    with four alternating sectors on the X-test's circle. On that circle the crossing is dark
    towards the marker (a white square of the corner's) and light towards a black square; the
    corner's colour test now sees it. Every corner of the view within 0.2 px of its truth."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(13)
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 80 and err.max() < 0.2, (det.n_found, err.max())
    # The colour test itself at the crossing (where the previous code put the corner), with the
    # lattice's steps there: refused; at the corner: kept.
    g = _to_grey(img)
    T = truth.corners_px
    nx = board.squares_x - 1
    u, v = T[54] - T[53], (T[54 + nx] - T[54 - nx]) / 2
    at = np.stack([T[54], T[54] + [-1.94, -3.77]])
    rho = np.full(2, 2.1)
    x, mid = x_corner_shades(g, at, rho)
    assert x.all()  # both pass the X-test
    ok = _colours_on_circle(board, g, np.array([54, 54]), at, np.stack([u, u]), np.stack([v, v]), mid, rho)
    assert ok.tolist() == [True, False]



def test_a_fit_is_judged_against_fits_with_its_own_window():
    """Corpus view 234 (noise and JPEG; squares of 25-29 px): the corners beside markers were
    fitted with 2 px windows, those grown past them with 3 px, whose sigmas run twice as high
    (a quadratic follows the smoothed junction less far out), so a cap of twice the median
    passed grown corners by a hair (45 of 49), and refused them all once two poor fits beside
    markers were refused (11). Each fit is now judged against the corners beside markers with
    a window within a pixel of its own, refitted with it: all 49, each within 0.1 px of its
    truth. Only those: view 815 (squares of 75-100 px) refitted every corner with a 9 px window,
    whose poorer fits on the smaller squares excused a corner 1.24 px off."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(234)
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found == board.n_points and err.max() < 0.1, (det.n_found, err.max())
    seen = det.ids
    typical = TypicalSigma(_to_grey(img), truth.corners_px[seen], np.zeros(len(seen)), np.full(len(seen), 2),
                           lambda r: 1.5)
    assert typical.at(3) > 1.5 * typical.at(2)
    board, _, _, _, img, truth, _ = view(815)
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 50 and err.max() < 1.0, (det.n_found, err.max())



def test_the_fit_keeps_clear_of_the_markers_in_the_acute_sectors():
    """Corpus view 100 (noise-free, fisheye, a sheared board of 50 px squares, markers read at
    half resolution): the corners whose markers lie in the acute sectors have them 5-10 px
    away, and the 3 px smoothing with 2-10 px windows reached their borders: those corners
    were 0.087 px off (median; the others 0.012), and 21 of 80 were dropped as poor fits. The
    window and smoothing now stay clear of the corner's markers: both kinds of corner within
    0.03 px (median), and more found."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, noisy = view(100)
    assert not noisy
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    kind = _square_signs(board, det.ids)
    assert det.n_found >= 63 and err.max() < 0.5, (det.n_found, err.max())
    for k in (1, -1):
        assert (kind == k).sum() >= 25 and np.median(err[kind == k]) < 0.03, (k, np.median(err[kind == k]))



def test_the_growths_coarse_search_keeps_clear_of_the_markers():
    """Corpus view 55 (fisheye, noise and JPEG, squares of 17 px, markers at 77 % of the square:
    margins of 2 px): the growth's coarse search (a window of a fifth of a square) saw the
    markers beside each corner and drifted 1-5 px off corners predicted within 0.3 px, and the
    growth stopped at 44 of the 77 corners in view. The coarse window now keeps clear of the
    markers as the fine fit's does (where none fits, the fit starts from the prediction)."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(55)
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 50 and err.max() < 0.5, (det.n_found, err.max())


def test_markers_too_small_to_read_one_by_one_are_read_as_a_board():
    """Corpus view 5 (squares of 20 px, 5x5 markers at 2.2 px a cell, blurred, noise and JPEG):
    no marker reads by itself, and OpenCV's CharucoDetector finds no corner. Read as a board
    (its chessboard lattice, each square sampled at the code's cells, every placement of the
    lattice on the board scored), every corner is found within 0.1 px. The same image as a
    board it is not (the other legacy setting, whose markers sit on the other squares; a
    dictionary of 5x5 codes as well; the board turned) gives no placement near the bar and
    no corner."""
    from benchmarks.charuco_corpus import opencv_corners, view

    board, _, _, _, img, truth, _ = view(5)
    assert len(opencv_corners(board, img)[0]) == 0
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found == board.n_points and err.max() < 0.1, (det.n_found, err.max())
    g = _to_grey(img)
    assert max(z for z, *_ in _lattice_reads(board, g)) > 2 * _BOARD_Z
    sx, sy, s, m = board.squares_x, board.squares_y, board.square, board.marker
    for other in (Charuco(sx, sy, s, m, board.dictionary, legacy=not board.legacy),
                  Charuco(sx, sy, s, m, "DICT_ARUCO_ORIGINAL", legacy=board.legacy),
                  Charuco(sy, sx, s, m, board.dictionary, legacy=board.legacy)):
        assert max(z for z, *_ in _lattice_reads(other, g)) < 0.5 * _BOARD_Z
        assert other.detect(img).n_found == 0


def test_corners_beside_markers_their_markers_predict_beyond_the_fine_window_are_searched_for():
    """Corpus view 1521 (a fisheye, squares of 190-270 px, markers 50 px from the corners):
    the markers predict corners 4 and 5 4.8 and 5.8 px off, beyond the fine fit's window of
    5 px, and growth's parallelogram 21 and 38 px off; OpenCV finds corner 5. Searched for
    with a window and smoothing that keep clear of the markers (step 7), both are found
    within 0.03 px of the truth, as every other corner returned."""
    from benchmarks.charuco_corpus import opencv_corners, view

    board, _, _, _, img, truth, _ = view(1521)
    assert 5 in opencv_corners(board, img)[0]
    det = board.detect(img)
    assert {4, 5} <= set(det.ids.tolist())
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert err[np.isin(det.ids, [4, 5])].max() < 0.03 and err.max() < 0.3, err.round(3)


def test_opencv_tutorial_photos(shared_data):
    """OpenCV's ChArUco tutorial photos against OpenCV 5's CharucoDetector (the README of the
    folder: 4.7-4.12 are 0.5 px off): every corner id OpenCV finds, found, and the positions
    within 0.4 px of OpenCV's (both detectors' own scatter on 640x480 JPEG; median 0.2)."""
    folder = shared_data / "charuco_opencv_tutorial"
    ref = json.loads((folder / "reference.json").read_text())
    board = Charuco(5, 7, 0.04, 0.02, "DICT_6X6_250")
    errs = []
    for entry in ref["detections"]:
        det = board.detect(read_image(folder / "images" / entry["file"]))
        ids = np.ravel(entry["charuco_ids"])
        assert set(ids.tolist()) <= set(det.ids.tolist()), entry["file"]
        errs.append(np.hypot(*(det.corners[ids] - np.reshape(entry["charuco_corners"], (-1, 2))).T))
    e = np.concatenate(errs)
    # Issue 23 asks 0.3 px: 0.303 (0.349 before step 8 read the light across each corner).
    assert e.max() < 0.31 and np.median(e) < 0.12, (e.max(), np.median(e))


def test_tutorial_photos_half_in_a_shadow_keep_their_corners(shared_data):
    """The tutorial photos with their right half dimmed to a fifth past a soft edge (the
    "shadow" of ``benchmarks.detect_altered``): every id OpenCV 5 finds on the photos as they
    are is found, within 0.4 px of OpenCV's corner there, and no corner's sigma understates its
    distance threefold. Before step 8 the corners along the shadow's edge moved up to 1.14 px
    with sigmas of 0.06-0.14 px."""
    from benchmarks.detect_altered import ALTERATIONS

    folder = shared_data / "charuco_opencv_tutorial"
    ref = json.loads((folder / "reference.json").read_text())
    board = Charuco(5, 7, 0.04, 0.02, "DICT_6X6_250")
    errs, z = [], []
    for entry in ref["detections"]:
        ids = np.ravel(entry["charuco_ids"])
        img, pts = ALTERATIONS["shadow"](read_image(folder / "images" / entry["file"]),
                                         np.reshape(entry["charuco_corners"], (-1, 2)).astype(np.float64))
        det = board.detect(img)
        assert set(ids.tolist()) <= set(det.ids.tolist()), entry["file"]
        e = np.hypot(*(det.corners[ids] - pts).T)
        errs.append(e)
        z.append(e / (np.sqrt(2.0) * det.sigma_px[ids]))
    e, z = np.concatenate(errs), np.concatenate(z)
    assert e.max() < 0.4 and np.median(e) < 0.12, (e.max(), np.median(e))
    assert z.max() < 3.0, z.max()


@pytest.mark.parametrize("width,depth,angle", [(8.0, 0.25, 0.0), (15.0, 0.2, 2.0), (4.0, 0.3, 0.7)])
def test_a_shadows_edge_across_a_rendered_board_leaves_its_corners_in_place(width, depth, angle):
    """A rendered board under a shadow's edge (on the sheet, then blurred by 1 px): the light
    read across each corner (step 8) leaves every corner within 0.03 px of the truth (before:
    0.089 and 0.078 px with edges 8 and 15 px soft). A sharp edge (4 px) a square's fraction
    from a corner, beyond what its fit sees, moves nothing: a reading over whole squares moved
    one 0.25 px."""
    from scipy.ndimage import gaussian_filter

    b = Charuco(5, 7, 0.04, 0.02, "DICT_6X6_250")
    rvec = {0.0: [0.3, -0.2, 0.1], 2.0: [-0.4, 0.1, 0.2], 0.7: [0.2, 0.3, -0.4]}[angle]
    img, truth = render_target(CAM, _view(b, CAM, rvec, distance=1.3), b)
    yy, xx = np.mgrid[0:CAM.height, 0:CAM.width]
    c = truth.corners_px[truth.visible].mean(axis=0)
    t = np.clip(((xx - c[0]) * np.cos(angle) + (yy - c[1]) * np.sin(angle)) / width, -50, 50)
    light = depth + (1.0 - depth) / (1.0 + np.exp(t))
    u8 = np.clip(gaussian_filter(img * light, 1.0) * 255 + 0.5, 0, 255).astype(np.uint8)
    det = b.detect(u8)
    assert det.n_found >= 11, det.message
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert err.max() < 0.03, err.round(3)


def test_the_light_divided_out_of_a_junction_gives_its_saddle_back():
    """:func:`_light_refit` on a junction (rendered 8x over, blurred 1.2 px) under light that
    grows 2 % a pixel and a glare's slope of 0.002 a pixel: the plain saddle fit is 0.3-0.5 px
    off, the refit with that light within 0.005 px (a first-order shift of the saddle by the
    gradient finds 70 % of the move)."""
    from scipy.ndimage import gaussian_filter

    from camkit.target._markers import refine_patches
    from camkit.target.charuco import _light_refit

    n, ss = 80, 8
    c0 = np.array([40.3, 39.7])
    yy, xx = (np.mgrid[0:n * ss, 0:n * ss] + 0.5) / ss - 0.5
    u = (xx - c0[0]) * np.cos(0.35) + (yy - c0[1]) * np.sin(0.35)
    v = -(xx - c0[0]) * np.sin(0.35) + (yy - c0[1]) * np.cos(0.35)
    pattern = gaussian_filter(np.where(u * v > 0, 0.85, 0.12).reshape(n, ss, n, ss).mean(axis=(1, 3)), 1.2)
    gy, gx = np.mgrid[0:n, 0:n] - c0[::-1, None, None]
    m, a = np.array([0.02, -0.006]), np.array([0.0, 0.002])
    img = pattern * (1.0 + m[0] * gx + m[1] * gy) + a[0] * gx + a[1] * gy
    q, _ = refine_patches(img, c0[None] + 0.2, 5, 1.5)
    assert np.hypot(*(q[0] - c0)) > 0.3
    # The light as seen from the plain fit's place.
    at = 1.0 + m @ (q[0] - c0)
    theta = np.concatenate([m / at, a])[None]
    back, _ = _light_refit(img, q, np.array([5]), 1.5, theta)
    assert np.hypot(*(back[0] - c0)) < 0.005, back[0] - c0


def test_the_light_read_across_a_corner_is_the_weighted_least_squares_fit_and_its_chi_square():
    """Step 8's reading (kernel ``light_fit``) against NumPy's weighted least squares on the
    same pairs: the light's four numbers and their covariance (grown by the residuals'
    chi-square per degree of freedom where over 1), and ``seen``, the reading's chi-square
    against no light: the quadratic form theta^T C^-1 theta (the fifty-second session's NumPy
    code summed theta_i^2 times the rows of C^-1 instead, and corrected the light of corners
    whose reading was within its noise). Places along one line leave the fit rank-deficient."""
    from camkit._kernels.markers import light_fit

    rng = np.random.default_rng(5)
    K, P, n_box, noise = 40, 10, 25, 0.01
    d = rng.normal(0.0, 3.0, (K, P, 2))
    d[-1] = np.outer(rng.normal(0.0, 3.0, P), [0.6, 0.8])  # one direction only: no fit
    truth = rng.normal(0.0, 0.01, (K, 4))
    truth[:10] = 0.0  # no light: seen is a chi-square of 4 degrees of freedom
    M = rng.uniform(0.1, 0.9, (K, P))
    D = M * (d * truth[:, None, :2]).sum(axis=2) + (d * truth[:, None, 2:]).sum(axis=2)
    D += rng.normal(0.0, noise, (K, P)) * rng.uniform(0.5, 2.0, (K, 1))
    v0 = rng.uniform(0.0, 2.0, (K, P)) * noise ** 2
    v1 = rng.uniform(0.0, 2.0, (K, P)) * noise ** 2
    theta, cov, seen = np.empty((K, 4)), np.empty((K, 4, 4)), np.empty(K)
    fits, full = np.empty(K, dtype=bool), np.empty(K, dtype=bool)
    light_fit(M + D, M - D, v0, v1, d, noise, n_box, 0.1, theta, cov, seen, fits, full)
    assert not full[-1] and full[:-1].all()
    for k in range(K - 1):
        var = (np.fmax(noise ** 2, v0[k]) + np.fmax(noise ** 2, v1[k])) / (4.0 * n_box)
        A = np.concatenate([M[k, :, None] * d[k], d[k]], axis=1)
        sw = 1.0 / np.sqrt(var)
        th, *_ = np.linalg.lstsq(A * sw[:, None], D[k] * sw, rcond=None)
        res = D[k] - A @ th
        chi = (res ** 2 / var).sum() / (P - 4)
        C = np.linalg.inv((A / var[:, None]).T @ A) * max(chi, 1.0)
        np.testing.assert_allclose(theta[k], th, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(cov[k], C, rtol=1e-9, atol=1e-18)
        np.testing.assert_allclose(seen[k], th @ np.linalg.solve(C, th), rtol=1e-9)
        Ms = np.sort(M[k])
        bar = 3.0 * np.sqrt(var.mean()) + 0.1 * 0.5 * (Ms[5:].mean() - Ms[:5].mean())
        assert fits[k] == (np.sqrt((res ** 2).sum() / (P - 4)) <= bar)
    # Without light, seen is about chi-square(4); with it, far beyond.
    assert np.median(seen[:10]) < 8.0 and np.median(seen[10:-1]) > 50.0, (seen[:10], seen[10:-1])


@pytest.mark.parametrize("kwargs,match", [
    ({"dictionary": "DICT_5X5_101"}, "dictionary: expected one of"),
    ({"marker": 0.03}, r"marker: expected a marker smaller than its square \(0.03 m\), got 0.03 m"),
    ({"squares_x": 20, "squares_y": 20, "dictionary": "DICT_4X4_50"}, "dictionary: a 20x20 board needs 200 markers"),
    ({"squares_x": 1}, "squares_x, squares_y: expected at least 2x2"),
    ({"legacy": "yes"}, "legacy: expected True or False"),
])
def test_bad_input_is_named(kwargs, match):
    args = {"squares_x": 5, "squares_y": 7, "square": 0.03, "marker": 0.02, "dictionary": "DICT_5X5_100", **kwargs}
    with pytest.raises(ParameterError, match=match):
        Charuco(**args)


def test_nothing_but_another_dictionary_is_not_found_with_a_reason():
    other = Charuco(5, 7, 0.03, 0.02, "DICT_4X4_50")
    img, _ = render_target(CAM, _view(other, CAM, [0.2, 0.1, 0.0]), other)
    det = Charuco(5, 7, 0.03, 0.02, "DICT_5X5_100").detect(img)
    assert not det.found and "no marker of the board" in det.message


def test_detect_refuses_what_is_not_an_image_and_finds_nothing_in_tiny_or_blank_ones():
    from camkit.errors import ShapeError

    b = Charuco.example()
    with pytest.raises(ShapeError, match="image: expected shape"):
        b.detect(np.zeros(3))
    with pytest.raises(ShapeError, match="image: expected dtype"):
        b.detect(np.zeros((10, 10), bool))
    with pytest.raises(ShapeError, match="image: expected finite values"):
        b.detect(np.full((40, 40), np.nan))
    for img in (np.zeros((1, 1), np.uint8), np.zeros((5, 7))):
        det = b.detect(img)
        assert not det.found and det.message.startswith("not found")


def test_render_target_names_a_bad_target():
    with pytest.raises(ParameterError, match="board: expected a camkit target"):
        render_target(CAM, Pose.identity(), (5, 7))


def test_marker_quads_are_refined_to_their_sides_edges():
    """Corpus view 137 (6x6 markers of 15-20 px, 2 px a cell, blurred): the dark regions of the
    threshold are a pixel narrower than the markers, and their extreme pixels lay 1.3 px off the
    markers' corners (median, 1.9 at the 90th percentile), so the markers' homographies put the
    chessboard corners beside them 2-3 px off. The quads are now refined to where the lines of
    their sides' edges meet: the markers found and the truth's quads shrunk by a pixel both come
    back within 0.7 px (median 0.5)."""
    from benchmarks.charuco_corpus import view

    board, camera, _, pose, img, _, _ = view(137)
    g = _to_grey(img)
    truth = camera.project(pose.apply(board.marker_corners().reshape(-1, 3))).reshape(-1, 4, 2)
    found, factor, _ = find_markers(g, board.aruco)
    assert factor == 1 and len(found) >= 3
    err = np.concatenate([np.hypot(*(q[0] - truth[m]).T) for m, q in found.items()])
    assert np.median(err) < 0.6 and err.max() < 1.0, (np.median(err), err.max())
    n = board.aruco.marker_size + 2
    inside = np.isfinite(truth).all(axis=(1, 2)) & (truth >= 5).all(axis=(1, 2)) & (
        truth[..., 0] < img.shape[1] - 5).all(axis=1) & (truth[..., 1] < img.shape[0] - 5).all(axis=1)
    t = truth[inside]
    centre = t.mean(axis=1, keepdims=True)
    shrunk = t - (t - centre) / np.hypot(*(t - centre).transpose(2, 0, 1))[..., None] * 1.0
    before = np.hypot(*(shrunk - t).transpose(2, 0, 1))
    after = np.hypot(*(refine_quads(g, shrunk, n) - t).transpose(2, 0, 1))
    assert np.median(before) == pytest.approx(1.0) and np.median(after) < 0.6 and np.percentile(after, 90) < 0.8, (
        np.median(after), np.percentile(after, 90))
    # A one-channel 8-bit image is read lazily (RawGrey): refined on a square around each quad.
    lazy = refine_quads(_to_grey(img, lazy=True), shrunk, n)
    after_lazy = np.hypot(*(lazy - t).transpose(2, 0, 1))
    assert np.median(after_lazy) < 0.6 and np.percentile(after_lazy, 90) < 0.8


def test_a_side_edge_found_on_the_next_side_does_not_tilt_the_quad():
    """Corpus view 1301 (a 5 x 4 legacy board at 73 degrees at a fisheye's rim): near marker 0's
    obtuse corner the search across its left side, 0.8 of a cell either way, reached the top
    side's edge; that one place, 8.8 px off the side, tilted the side's line, and the refined
    quad lay 2.9 and 5.2 px off at two corners. The chessboard corner beside it, which
    OpenCV's CharucoDetector returns 0.03 px from the truth, was then predicted 10 px off and
    not found. The line is now fitted again without the places off it: every corner of the
    quad within 0.6 px, and corner 0 found within 0.05 px. (The corpus test of AprilGrid view
    1550 holds the other side: where the lines fitted again put a corner over a cell from the
    quad, the first lines' corners are taken, as before.)"""
    from benchmarks.charuco_corpus import view

    board, camera, _, pose, img, truth, _ = view(1301)
    g = _to_grey(img)
    true_quad = camera.project(pose.apply(board.marker_corners()[0]))
    found, _, _ = find_markers(g, board.aruco)
    err = np.hypot(*(found[0][0] - true_quad).T)
    assert err.max() < 0.6, err
    det = board.detect(img)
    assert 0 in det.ids
    assert np.hypot(*(det.corners[0] - truth.corners_px[0])) < 0.05


def test_the_board_read_assembles_its_lattice_beside_sharp_markers():
    """Corpus view 137 (clean, squares of 28-32 px, markers at 62 % of the square): two markers
    confirmed, and the board read found no lattice: the checkerboard's seed test takes each
    square's shade three tenths of a square from the edge, inside the markers here. It now also
    takes it inside the white margin: every corner, within 0.1 px. Where the markers blur to
    grey (view 116, squares of 20 px), the checkerboard's offset still reads the board."""
    from benchmarks.charuco_corpus import view

    for seed in (137, 116):
        board, _, _, _, img, truth, _ = view(seed)
        det = board.detect(img)
        err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
        assert det.n_found >= 20 and err.max() < 0.1, (seed, det.n_found, err.max())
    assert det.n_found == board.n_points


def test_two_markers_place_their_corner_at_their_near_corners_midpoint():
    """Corpus view 220 (clean, a strong fisheye, squares of 60-120 px): the homography of the two
    markers touching a corner put it 3.4 px off (median, 10 at most), outside the fit's reach,
    and 35 of the 65 corners in view were found. The two markers' corners nearest it lie either
    side of it on a diagonal, and it is their midpoint to second order: 0.75 px (1.9 at most)."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(220)
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 45 and err.max() < 0.5, (det.n_found, err.max())


def test_each_kind_of_corner_is_judged_against_its_own_kind():
    """Corpus view 55 (fisheye, noise and JPEG, squares of 18 px, sheared): the corners of one
    chirality have their markers in the acute sectors and fit with sigmas of 0.10-0.11 px, twice
    the other kind's 0.04-0.05, though both lie within 0.05 px of the truth; judged against the
    median of all they were dropped as poor fits (53 found). Each kind is now judged against its
    own (a corner's sigma still twice its kind's goes). Judged on its residuals too (a fit of
    less contrast), corner 27, predicted 6.8 px off by one marker's blurred quad, passed on a
    saddle of the white margin beside it; only grown corners, which pass the black-square
    test as well, are judged on their residuals."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(55)
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 60 and err.max() < 0.5, (det.n_found, err.max())


def test_a_board_with_few_markers_confirmed_is_read_as_a_board_too():
    """Corpus view 428 (squares of 25 px, noise and JPEG): four markers confirmed, in two pairs at
    the board's two ends, and the corners beside them did not link up (8 of 36). With fewer than
    six confirmed the board is read as a whole too: every corner, within 0.1 px."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(428)
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found == board.n_points and err.max() < 0.1, (det.n_found, err.max())


def test_a_grown_corners_squares_are_checked_along_its_measured_steps():
    """Corpus view 28 (clean, a strong fisheye): past the last corners found, the lattice's
    extrapolated steps run long towards the rim (55 px where the neighbour lies 41 px away),
    and the black-square test's points half a step out landed in the next square: corners within
    0.04 px of the truth were refused (55 found). The test now takes its steps from the corner's
    found neighbours where they agree with the prediction (58)."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(28)
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 58 and err.max() < 0.5, (det.n_found, err.max())


def test_refine_quads_returns_quads_it_cannot_refine_as_they_came():
    """A quad that is not finite, or that has collapsed to a point or a line, has no edges to
    find: it comes back unchanged, without an error from the kernel."""
    g = np.full((40, 40), 0.5)
    g[10:30, 10:30] = 0.1
    good = np.array([[10.5, 9.5], [29.5, 10.5], [28.5, 29.5], [9.5, 28.5]])
    bad = np.stack([np.full((4, 2), np.nan), np.full((4, 2), 20.0),
                    np.array([[5.0, 5.0], [15.0, 5.0], [25.0, 5.0], [35.0, 5.0]])])
    out = refine_quads(g, np.concatenate([good[None], bad]), 6)
    np.testing.assert_array_equal(out[1:], bad)
    true = np.array([[9.5, 9.5], [29.5, 9.5], [29.5, 29.5], [9.5, 29.5]])
    assert np.abs(out[0] - true).max() < 0.2 < np.abs(good - true).max()
    assert refine_quads(g, np.zeros((0, 4, 2)), 6).shape == (0, 4, 2)


def test_a_low_contrast_corner_that_fits_as_well_is_kept_on_its_residuals():
    """Corpus view 210 (barrel lens, noise; the board's far side foreshortened, its white
    margins thin under the blur): the corners there are X-junctions of less contrast, whose
    saddle fits place them less surely though they fit as well; their sigmas ran 2.1-3.4 times
    the typical and the corners were refused (0.04-0.17 px from the truth; 28 found). They are
    now judged on their fits' residuals where their sigma is over (41 found, all within a
    pixel)."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(210)
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 38 and err.max() < 1.0, (det.n_found, err.max())
    assert det.sigma.max() <= 0.25


def test_a_shallow_saddle_beside_markers_is_judged_by_the_noise_not_the_misfit():
    """Corpus view 89 (noise-free, pincushion lens, a legacy board of 15-20 px squares with
    markers of 0.74 of the square): corners 8 and 19 lie where the board is sheared, their
    windows 2 px to keep clear of the markers. The quadratic's misfit there (residuals as
    typical as the board's) made their fits' sigmas 0.57-0.89 px with the corners 0.05-0.15 px
    from the truth, and they were refused, though OpenCV returns them. Past the typical sigma,
    the quarter-pixel bound now holds the sigma the image's noise gives the fit
    (``noise_sigma``): both found, within 0.2 px."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(89)
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert 8 in err and 19 in err, sorted(err)
    assert max(err[8], err[19]) < 0.2 and max(err.values()) < 1.0, err


def test_corners_the_saddle_fit_cannot_place_are_placed_at_their_point_of_symmetry():
    """Corpus view 98 (noise, a legacy board seen sheared, squares of about 30 px): the saddle
    fits of corners 16 and 28, their windows 2 px to keep clear of the markers, came 0.16 and
    0.53 px from the truth with sigmas of 0.74 and 0.79 px, and were refused (OpenCV returns
    them 0.45 and 0.56 px off). Read out to the markers' borders, where the board is still
    point-symmetric about them (step 6), both lie within 0.05 px; every corner within a pixel."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(98)
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert 16 in err and 28 in err, sorted(err)
    assert max(err[16], err[28]) < 0.05 and max(err.values()) < 1.0, err
    assert max(det.sigma_px[16], det.sigma_px[28]) <= 0.1


def test_a_missing_corner_is_judged_by_the_asymmetry_of_the_boards_found_corners():
    """Step 6 kept a symmetric point only where its residuals implied at most twice the
    image's noise plus 0.02 of the board's range. Through a fisheye, or a JPEG whose noise
    reads a quarter of a level, even the found corners' samples are 0.03-0.05 from
    symmetric. So corpus view 76's corners 6 and 15 (noise-free, residuals 0.036 and 0.047)
    and view 155's corner 8 (JPEG, 0.049) were refused, though they lay within 0.025 px of the
    truth. OpenCV returns them. They are now judged against the median of the board's found
    corners placed the same way."""
    from benchmarks.charuco_corpus import view

    for seed, ids in ((76, (6, 15)), (155, (8,))):
        board, _, _, _, img, truth, _ = view(seed)
        det = board.detect(img)
        err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
        assert set(ids) <= set(err), (seed, sorted(err))
        assert max(err[i] for i in ids) < 0.05 and max(err.values()) < 1.0, (seed, err)


def test_a_sheared_corner_is_tested_on_a_circle_clear_of_its_markers():
    """Corpus view 257 (pincushion, squares of about 58 px seen sheared, margins of 7 px):
    the X-test's circle, 0.6 of the margin (4.2 px), crossed the borders of the markers in
    the acute sectors, 4 px from corner 1. It met four dark sectors and refused the corner,
    though the saddle fit placed it 0.003 px from the truth. Where the margin's circle
    fails, a circle clear of the markers is tried."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(257)
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert 1 in err and err[1] < 0.05, sorted(err)
    assert max(err.values()) < 1.0


def test_a_corner_is_fitted_only_where_its_window_lies_inside_the_image():
    """Corpus view 901 (noise, squares of 90 px): corner 25 lies 3 px from the image's right
    edge, predicted within 0.02 px; its 5 px window ran past the edge, where the smoothing
    repeats the last column, and the fit moved it 1.9 px. Its residuals passed (the sigma had
    refused it). A fit whose window and bicubic support leave the image is now dropped, as the
    AprilGrid's are."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(901)
    det = board.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 40 and err.max() < 1.0, (det.n_found, err.max())


def test_a_marker_whose_quad_lies_a_pixel_off_is_read_again_at_its_sides_edges():
    """Corpus view 878 (fisheye, noise; the board's last column of markers seen at 63-69
    degrees, 12-18 px across): the quads of markers 16 and 23 were their dark regions'
    extreme pixels, a pixel off the markers' corners, and at two pixels a cell read as no
    code; the corners beside them (20, 31, 43), which OpenCV returns, were missed. A quad that
    reads as nothing but has a marker's border is read again with its corners where its
    sides' edges meet; the markers' neighbours' homography, which puts a marker at the
    board's edge a cell off through a fisheye, is refined the same way."""
    from benchmarks.charuco_corpus import view

    board, camera, _, pose, img, truth, _ = view(878)
    found, factor, _ = find_markers(_to_grey(img, lazy=True), board.aruco)
    assert factor == 1 and {16, 23} <= set(found), sorted(found)
    true_q = camera.project(pose.apply(board.marker_corners().reshape(-1, 3))).reshape(-1, 4, 2)
    assert max(np.hypot(*(found[m][0] - true_q[m]).T).max() for m in (16, 23)) < 1.0
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert {20, 31, 43} <= set(err) and max(err[i] for i in (20, 31, 43)) < 0.05, err
    assert max(err.values()) < 1.0


def test_markers_of_cells_under_two_pixels_are_read_on_the_full_image():
    """Corpus view 883 (barrel lens, noise, markers of about 13 px: cells of 1.6 px): no quad
    was looked for under two pixels a cell, and the board read as a whole found no lattice, so
    the board was not found; OpenCV reads eight markers and returns corner 33. On the full
    image quads are now looked for down to 1.25 px a cell, read where their border is a
    marker's. An image of noise, whose sigma makes such cells unreadable, is not searched so
    (656 quads against 33 on 640x480) and has no marker."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(883)
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert det.n_found >= 50 and 33 in err and err[33] < 0.05, (det.n_found, sorted(err))
    assert max(err.values()) < 1.0
    noise = np.random.default_rng(0).integers(0, 256, (480, 640), dtype=np.uint8)
    assert find_markers(_to_grey(noise, lazy=True), board.aruco)[0] == {}


def test_markers_seen_nearly_edge_on_are_found_as_quads_of_their_regions_hulls():
    """Corpus view 383 (barrel lens, noise, 83 degrees from square on): markers 3 and 7 are
    slivers (marker 7: sides of 163 and 134 px, ends of 16 and 29 px), whose two farthest
    pixels are the ends of one long side, so the region's quad from its extreme pixels covered
    a fraction of it and no marker was read (OpenCV reads both and returns corner 6). Such a
    region's quad is now the largest on its convex hull's corners."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(383)
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert 6 in err and err[6] < 0.1 and max(err.values()) < 1.0, err


def test_a_corner_between_thin_white_squares_is_fitted_again_at_the_full_smoothing():
    """Corpus view 595 (fisheye, noise-free, 73 degrees from square on): corners 40 and 51 lie
    between white squares 2-3 px thick, their markers that near, so their fits' smoothing was
    lessened to 1 px; there the two light lines crossing have no saddle near the prediction
    (none, or one 7 px off), and nothing later found them (OpenCV returns both, 0.85 and
    1.12 px from the truth). Fitted again at the full smoothing, both are within 0.12 px."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(595)
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert 40 in err and 51 in err and err[40] < 0.2 and err[51] < 0.2, err
    assert max(err.values()) < 1.0, err


def test_a_corner_growth_missed_is_placed_from_the_homography_of_the_corners_around():
    """Corpus view 598 (pinhole, noise, legacy board, 76 degrees from square on): corner 12's
    marker 7 is not read, and growth's parallelogram of three neighbours put it 4 px off,
    between light lines crossing 6-8 px apart, where the fit took the next crossing (OpenCV
    returns it, 0.04 px from the truth). The homography of the nine found around puts it
    0.02 px off."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(598)
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert 12 in err and err[12] < 0.1 and max(err.values()) < 1.0, err


def test_a_corner_with_few_neighbours_is_mapped_through_its_markers_corners():
    """Step 6 places a missing corner at its point of symmetry on its neighbours' local map,
    which needs four of them. At the board's edge, or beside two unread markers, a corner has
    one to three: corpus view 98's corners 4, 5 and 11 (pinhole, noise, 68 degrees; their
    saddle fits refused at sigmas of 0.74-0.79 px), view 970's corner 6 and view 1075's
    corner 0. OpenCV returns them all. Their map is now fitted to their neighbours and the
    corners of their confirmed markers."""
    from benchmarks.charuco_corpus import view

    for seed, ids in ((98, (4, 5, 11)), (970, (6,)), (1075, (0,))):
        board, _, _, _, img, truth, _ = view(seed)
        det = board.detect(img)
        err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
        assert set(ids) <= set(err), (seed, sorted(err))
        assert max(err[i] for i in ids) < 0.1 and max(err.values()) < 1.0, (seed, err)
        assert max(det.sigma_px[list(ids)]) <= 0.1


def test_a_corner_seen_at_75_degrees_is_tested_on_a_circle_on_the_board():
    """Seen 74-79 degrees from square on, a board's squares meet at angles of about 20 degrees:
    an image circle inside the white margins has one sample or none in the acute sectors, and
    one as wide as the margin crosses into the markers there (eight changes of shade, not
    four). Corpus views 89 (corner 51), 491 (7) and 842 (36) were refused so, though placed
    within 0.2 px; OpenCV returns them. The X-test now falls back to a circle on the board (an
    ellipse in the image, through the corner's steps), which gives each square a quarter of
    its samples. On such a board a diagonal neighbour lies nearer than a side's length (view
    975: 14 px against 41), so step 6 keeps a corner half the way to its nearest neighbour
    apart from the others, not half a side (corner 41 there)."""
    from benchmarks.charuco_corpus import view

    for seed, ids in ((89, (51,)), (491, (7,)), (842, (36,)), (975, (41,))):
        board, _, _, _, img, truth, _ = view(seed)
        det = board.detect(img)
        err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
        assert set(ids) <= set(err), (seed, sorted(err))
        assert max(err[i] for i in ids) < 0.15 and max(err.values()) < 1.0, (seed, err)


def test_a_marker_its_neighbours_put_pixels_off_is_looked_for_around_that_place():
    """Corpus view 100 (fisheye, 3.7 MP, 75 degrees at the board's edge): markers 0, 5 and 11
    gave no quad on the coarser level the others were read on, and their neighbours'
    homography put them 2-9.5 px off, more than a cell: neither the predicted quad nor its
    refinement read, and corners 0 and 10, which OpenCV returns, were missed. Such a marker is
    now looked for on the full image in a square around its prediction."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(100)
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert {0, 10} <= set(err) and max(err[0], err[10]) < 0.05, sorted(err)
    assert max(err.values()) < 1.0


def test_a_corner_dropped_for_its_sigma_by_the_image_edge_is_grown_from_its_own_fit():
    """Corpus view 1164 (barrel lens, noise-free, legacy board): corner 36, 25 px from the
    image's right edge, fits 0.03 px from the truth beside its marker, but its sigma is 2.04
    times the typical one (the white squares are wedges the quadratic does not follow) and it
    is dropped before growth. Growth predicts it 6 px off (a parallelogram extrapolated at the
    board's corner through the lens) and too near the edge for its coarse search, so it was
    never found (OpenCV returns it, 0.05 px from the truth). Grown from its own fit, it passes
    growth's tests by its residuals (1.44 times the typical ones)."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(1164)
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert 36 in err and err[36] < 0.1 and max(err.values()) < 1.0, err


def test_a_symmetric_point_whose_search_fails_from_its_map_is_sought_from_its_saddle():
    """Corpus view 1150 (fisheye, noise, 70 degrees from square on): corner 1's saddle fits end
    0.6 px off with a sigma of 0.23 px and are refused; its neighbours' map puts it 2.3 px off,
    and the point-symmetry's search from there fails across the slivers (OpenCV returns it,
    0.35 px off). Sought again from the saddle, the symmetric point is within 0.1 px."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(1150)
    det = board.detect(img)
    err = dict(zip(det.ids.tolist(), np.hypot(*(det.pixels - truth.corners_px[det.ids]).T), strict=True))
    assert 1 in err and err[1] < 0.1 and max(err.values()) < 1.0, err


def test_a_board_given_the_wrong_legacy_setting_or_turned_is_refused_and_named():
    """OpenCV 4.6 changed the layout of boards with an even number of rows (``legacy``): read
    with the wrong setting, every marker but the rows' ends sits one square along, so most of
    them confirm each other and every corner would be labelled a square off. Where the other
    setting confirms more markers, the board is not found and the message names the setting
    the markers fit; a board given with its squares counted the other way round (8x11 for
    11x8) confirms none, and the message names the size they fit. The right settings find it."""
    from camkit.render import default_camera, plan_views

    cam = default_camera("brown-conrady")
    for legacy in (True, False):
        real = Charuco(11, 8, 0.03, 0.022, "DICT_5X5_100", legacy=legacy)
        img, truth = render_target(cam, plan_views(cam, real, 1, np.random.default_rng(1))[0], real)
        det = real.detect(img)
        assert det.found and det.n_found == 70 and np.nanmax(np.abs(det.corners - truth.corners_px)) < 0.1
        wrong = Charuco(11, 8, 0.03, 0.022, "DICT_5X5_100", legacy=not legacy).detect(img)
        layout = "before 4.6 (legacy=True)" if legacy else "since 4.6 (legacy=False)"
        assert not wrong.found and wrong.message.startswith(
            f"not found: the markers read fit OpenCV's layout {layout} better than the board's (44 confirmed "
            "against 40): its labels would be a square off"), wrong.message
        turned = Charuco(8, 11, 0.03, 0.022, "DICT_5X5_100", legacy=legacy).detect(img)
        assert not turned.found and turned.message.endswith(
            "; the markers read fit a 11x8-square board (the squares counted the other way round)"), turned.message


def test_corners_dropped_by_the_light_are_not_counted_in_the_message():
    """Rendered corpus view 145 under a shadow's edge (``charuco_corpus --shadow``): step 8
    drops a corner its light leaves in doubt (1.3 px off), and the message counts the corners
    returned (it counted them before step 8: 48 for 47)."""
    from benchmarks.charuco_corpus import view

    board, _, _, _, img, truth, _ = view(145, True)
    det = board.detect(img)
    assert det.message.startswith(f"found {det.n_found} of {board.n_points} "), (det.message, det.n_found)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert err.max() < 1.0, err.max()


def test_two_markers_on_one_quad_are_not_both_confirmed():
    """A quad read as one code and, with a bit corrected, as another: where two such
    misreadings lie alike (markers 2 and 18 read also as 0 and 16, four squares off), they fit
    one homography together and confirmed each other. One place holds one marker: the one
    fewer pairs confirm goes, and the votes are counted again without it."""
    from camkit.target._homography import apply_homographies
    from camkit.target._markers import confirm_markers
    from camkit.target.charuco import _layout

    board = Charuco(16, 4, 0.03, 0.0125, "DICT_ARUCO_ORIGINAL")
    ms, obj, _ = _layout(board)
    H = np.array([[2200.0, 300.0, 80.0], [-150.0, 2100.0, 40.0], [0.4, 0.2, 1.0]])
    quads = apply_homographies(np.broadcast_to(H, (len(obj), 3, 3)), obj)
    unread = {0, 1, 8, 9, 16, 17, 24, 25}  # every marker within two places of 0 and 16
    found = {m: [quads[m]] for m in range(len(obj)) if m not in unread}
    ok, _, _ = confirm_markers(found, obj, ms, board.square / board.marker, 1)
    assert sorted(ok) == sorted(found)
    found[0], found[16] = [quads[2] + 0.3], [quads[18] - 0.2]  # the same quads, found again
    ok, homs, _ = confirm_markers(found, obj, ms, board.square / board.marker, 1)
    assert 0 not in ok and 16 not in ok
    assert sorted(ok) == sorted(set(found) - {0, 16}) and set(homs) == set(ok)


@pytest.mark.parametrize("seed", [434, 116, 410, 616, 618])
def test_boards_drawn_wider_than_the_corpus_give_no_corner_off_its_place(seed):
    """Views of ``benchmarks.wide_boards`` that returned corners more than a pixel from their
    truth: 434 (ARUCO_ORIGINAL markers of 41 % of the square, two read twice: five corners
    100-125 px off), 116 and 410 (markers of 85 % and 90 % of the square through a fisheye:
    a grown corner's fit from its prediction, 2 px off, stopped on a saddle of the thin
    margins 2.8 and 3.5 px from the corner, where the fits about it found the corner, fitting
    better), 616 (markers of 80 %, squares of 14 px through a fisheye, margins of 1.1 px
    across: a fit 1.6 px off, even from the truth, its sigma 11 times the typical, kept on its
    residuals; beside margins under 1.35 px the sigma must pass), 618 (markers of 89 %, margins
    under a pixel, nearly edge-on through a fisheye: the fit from a prediction 0.5 px off was
    refused, a saddle 3 px off fitting better beside it, and a later round's prediction led into
    that saddle; a corner with two saddles in reach is not tried again)."""
    from benchmarks.wide_boards import charuco_view

    board, _, _, _, img, truth, _ = charuco_view(seed)
    det = board.detect(img)
    assert det.found
    d = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert (d <= 1.0).all(), (seed, det.ids[d > 1.0], d[d > 1.0])
    assert len(det.ids) >= 0.9 * {434: 44, 116: 154, 410: 28, 616: 53, 618: 38}[seed]


def test_a_corners_white_margin_across_is_measured_from_its_steps():
    """The margin across is (square - marker) / (2 square) of the parallelogram of a square's
    steps, its height over its longer side; the steps measured from found neighbours, else the
    markers' (``u``, ``v`` at ``cand``), else NaN."""
    from camkit.target.charuco import _margins

    board = Charuco(6, 5, 0.03, 0.027, "DICT_4X4_50")  # margins of a twentieth of the square
    nx, ny = 5, 4
    gx, gy = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float))
    none = (np.zeros(0, dtype=int), np.zeros((0, 2)), np.zeros((0, 2)))
    # Square on, squares of 28 px: 1.4 px across. Sheared, steps of 40 and 28 px at 45 degrees:
    # the parallelogram is 20 px high, 1.0 px across; steps of 60 and 42 px, 30 px high: 1.5.
    for u, v, want in (((28.0, 0.0), (0.0, 28.0), 1.4), ((40.0, 0.0), (20.0, 20.0), 1.0),
                       ((60.0, 0.0), (30.0, 30.0), 1.5), ((0.0, -50.0), (30.0, 10.0), 1.5)):
        out = 100.0 + gx.reshape(-1, 1) * np.array(u) + gy.reshape(-1, 1) * np.array(v)
        np.testing.assert_allclose(_margins(board, out, *none), want, rtol=1e-12)
        out[[2, 7]] = np.nan  # one neighbour either way is enough; a corner not found has none
        m = _margins(board, out, *none)
        assert np.isnan(m[[2, 7]]).all()
        np.testing.assert_allclose(np.delete(m, [2, 7]), want, rtol=1e-12)
    # A lone corner: its markers' steps where given, else NaN.
    out = np.full((nx * ny, 2), np.nan)
    out[7] = (50.0, 50.0)
    assert np.isnan(_margins(board, out, *none)).all()
    m = _margins(board, out, np.array([7]), np.array([[20.0, 0.0]]), np.array([[0.0, 20.0]]))
    assert m[7] == pytest.approx(1.0) and np.isnan(np.delete(m, 7)).all()



def test_a_corners_clearance_is_the_nearest_point_of_its_two_markers_sides():
    """``_clearance`` (kernel ``marker_clearance``) against its definition in NumPy: each of the
    two markers' four corners through the corner's steps, each side's nearest point to the
    corner (clamped to the side), the least distance; inf where a step is NaN. Bit for bit,
    on boards of both layouts and markers of any size, sheared and collapsed steps."""
    from camkit.target.charuco import _clearance, _layout

    def numpy_clearance(board, cand, u, v):
        nx = board.squares_x - 1
        sign = np.where(_layout(board)[2][cand // nx + 1, cand % nx + 1], -1.0, 1.0)
        lo = (board.square - board.marker) / (2 * board.square)
        hi = 1.0 - lo
        mk = np.array([[lo, lo], [hi, lo], [hi, hi], [lo, hi]])
        a = np.array([1.0, -1.0])[None, :, None] * mk[None, None, :, 0]
        b = np.array([-1.0, 1.0])[None, :, None] * sign[:, None, None] * mk[None, None, :, 1]
        p0 = a[..., None] * u[:, None, None] + b[..., None] * v[:, None, None]  # (K, 2 markers, 4, 2)
        d = np.roll(p0, -1, axis=2) - p0
        t = np.clip(-(p0 * d).sum(axis=-1) / np.maximum((d * d).sum(axis=-1), 1e-12), 0.0, 1.0)
        near = p0 + t[..., None] * d
        return np.nan_to_num(np.hypot(near[..., 0], near[..., 1]).min(axis=(1, 2)), nan=np.inf)

    rng = np.random.default_rng(8)
    for trial in range(60):
        board = Charuco(int(rng.integers(3, 10)), int(rng.integers(3, 10)), 0.04, float(rng.uniform(0.01, 0.039)),
                        "DICT_6X6_250", legacy=bool(trial % 2))
        cand = rng.integers(0, board.n_points, 30)
        u, v = rng.normal(0.0, 40.0, (30, 2)), rng.normal(0.0, 40.0, (30, 2))
        if trial % 3 == 0:
            v[::2] = u[::2] * 0.5  # a collapsed parallelogram
        u[::7] = np.nan
        got = _clearance(board, cand, u, v)
        np.testing.assert_array_equal(got, numpy_clearance(board, cand, u, v))
        assert np.isinf(got[::7]).all() and np.isfinite(np.delete(got, np.arange(0, 30, 7))).all()
    # Square on, squares of 40 px, markers of 0.6 of the square: margins of 8 px, the markers in
    # the diagonal squares, their nearest corners 8 px along either way from the corner.
    board = Charuco(5, 7, 0.04, 0.024, "DICT_6X6_250")
    assert _clearance(board, np.array([0, 1]), np.array([[40.0, 0.0]] * 2),
                      np.array([[0.0, 40.0]] * 2)) == pytest.approx([8.0 * np.sqrt(2.0)] * 2)


def test_the_lights_verdicts_and_response_are_those_of_their_numpy_definition():
    """light_jacobian and light_verdicts (the end of step 8) against the NumPy they replace,
    bit for bit: the inverse Hessian times each number's change, scaled by the refit's move
    over the first-order one (1 to 2 times, 1 where unknown); a move beyond its noise taken
    where the light fits and the move is small, else added to the sigma, the corner dropped
    past the bar."""
    from camkit._kernels import markers as mk

    rng = np.random.default_rng(21)
    K = 400
    quad = rng.normal(0.0, 1.0, (K, 3))
    lin = rng.normal(0.0, 1.0, (K, 4, 2))
    theta = rng.normal(0.0, 0.01, (K, 4))
    pts = rng.uniform(0.0, 100.0, (K, 2))
    q = pts + rng.normal(0.0, 0.05, (K, 2))
    q[::9] = np.nan
    quad[5] = 0.0  # no Hessian: no first-order move
    a2, b2, c2 = quad.T
    with np.errstate(divide="ignore", invalid="ignore"):
        det = 4 * a2 * c2 - b2 * b2
        h00, h01, h11 = (2 * c2 / det)[:, None], (-b2 / det)[:, None], (2 * a2 / det)[:, None]
        J = np.stack([h00 * lin[:, :, 0] + h01 * lin[:, :, 1], h01 * lin[:, :, 0] + h11 * lin[:, :, 1]], axis=1)
        first = np.einsum("kia,ka->ki", J, theta)
        gain = np.clip(np.hypot(*(q - pts).T) / np.hypot(*first.T), 1.0, 2.0)
    want = J * np.where(np.isfinite(gain), gain, 1.0)[:, None, None]
    got = np.empty((K, 2, 4))
    with np.errstate(divide="ignore", invalid="ignore"):
        mk.light_jacobian(quad, lin, theta, q, pts, got)
    np.testing.assert_array_equal(got, want)
    assert (gain[np.isfinite(gain)] > 1).any() and (gain[np.isfinite(gain)] == 1).any()

    N = K + 10
    idx = rng.permutation(N)[:K]
    c = rng.uniform(0.0, 100.0, (K, 2))
    shift = rng.normal(0.0, 1.0, (K, 2)) * rng.uniform(0.01, 0.4, (K, 1))
    shift[::11] = np.nan
    cov = rng.normal(0.0, 1.0, (K, 4, 4))
    cov = cov @ cov.transpose(0, 2, 1) * rng.uniform(0.0001, 0.01, (K, 1, 1))
    scov = want @ cov @ want.transpose(0, 2, 1)
    fits = rng.random(K) < 0.5
    win = rng.integers(2, 6, K)
    sig0 = rng.uniform(0.01, 0.2, N)
    out0 = rng.uniform(0.0, 100.0, (N, 2))
    out, sig = out0.copy(), sig0.copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        mk.light_verdicts(idx, c, shift, scov, fits, win, 0.25, 16.0, 0.25, out, sig)
    wo, ws = out0.copy(), sig0.copy()
    svar = 0.5 * (scov[:, 0, 0] + scov[:, 1, 1])
    size = np.hypot(*shift.T)
    small = np.isfinite(size) & (size <= 0.25 * win) & np.isfinite(svar)
    with np.errstate(invalid="ignore", divide="ignore"):
        sdet = scov[:, 0, 0] * scov[:, 1, 1] - scov[:, 0, 1] ** 2
        chi2 = (scov[:, 1, 1] * shift[:, 0] ** 2 - 2 * scov[:, 0, 1] * shift[:, 0] * shift[:, 1]
                + scov[:, 0, 0] * shift[:, 1] ** 2) / sdet
    moves = ~(chi2 <= 16.0)
    use = fits & small & moves
    wo[idx[use]] = c[use] + shift[use]
    ws[idx[use]] = np.sqrt(ws[idx[use]] ** 2 + svar[use])
    doubt = moves & ~use
    grown = np.sqrt(ws[idx] ** 2 + size ** 2)
    lost = doubt & ~(grown <= 0.25)
    grow = doubt & ~lost
    ws[idx[grow]] = grown[grow]
    wo[idx[lost]] = np.nan
    ws[idx[lost]] = np.nan
    np.testing.assert_array_equal(out, wo)
    np.testing.assert_array_equal(sig, ws)
    assert use.sum() > 20 and grow.sum() > 5 and lost.sum() > 5 and (~moves).sum() > 20


def test_step_4s_predictions_are_those_of_their_numpy_definition():
    """charuco_predictions against the NumPy it replaced, bit for bit, on boards of both
    layouts seen through a perspective with noisy marker corners: each corner's place and
    steps through its touching markers' homographies, averaged; where two or more touch it,
    the homography of their corners, and where two, the midpoint of their nearest corners."""
    from camkit._kernels import markers as mk
    from camkit.target._homography import apply_homographies, fit_homographies
    from camkit.target.charuco import _STEP_OFFSETS, _layout

    def numpy_predictions(board, conf, homs, side, img):
        ms, obj, _ = _layout(board)
        N, sx, s = board.n_points, board.squares_x, board.square
        offsets = _STEP_OFFSETS * s
        pred_sum, pred_n, size = np.zeros((N, 5, 2)), np.zeros(N), np.zeros(N)
        mine = ms[conf][:, None, :] + np.array([[0, 0], [1, 0], [0, 1], [1, 1]])
        mi, ci = np.nonzero((mine >= 1).all(axis=2) & (mine[..., 0] <= sx - 1) & (mine[..., 1] <= board.squares_y - 1))
        at = mine[mi, ci]
        cid = (at[:, 1] - 1) * (sx - 1) + (at[:, 0] - 1)
        np.add.at(pred_sum, cid, apply_homographies(homs[mi], (at * s)[:, None, :] + offsets))
        np.add.at(pred_n, cid, 1)
        np.maximum.at(size, cid, side[mi])
        cand = np.flatnonzero(pred_n > 0)
        five = pred_sum[cand] / pred_n[cand, None, None]
        cxy = np.stack([cand % (sx - 1) + 1, cand // (sx - 1) + 1], axis=-1)
        sq = ms[conf]
        touch = ((sq[None, :, 0] >= cxy[:, None, 0] - 1) & (sq[None, :, 0] <= cxy[:, None, 0])
                 & (sq[None, :, 1] >= cxy[:, None, 1] - 1) & (sq[None, :, 1] <= cxy[:, None, 1]))
        count = touch.sum(axis=1)
        for c in np.unique(count[count >= 2]):
            rows = np.flatnonzero(count == c)
            k2 = np.nonzero(touch[rows])[1].reshape(len(rows), c)
            Hn = fit_homographies(obj[conf[k2]].reshape(len(rows), 4 * c, 2), img[k2].reshape(len(rows), 4 * c, 2))
            q = apply_homographies(Hn, cxy[rows, None] * s + offsets)
            good = np.isfinite(q).all(axis=(1, 2))
            five[rows[good]] = q[good]
            if c == 2:
                own = obj[conf[k2]]
                k = np.argmin(np.hypot(*(own - (cxy[rows, None, None] * s)).transpose(3, 0, 1, 2)), axis=2)
                near = np.take_along_axis(img[k2], k[:, :, None, None], axis=2)[:, :, 0]
                mid = near.mean(axis=1)
                ok = good & np.isfinite(mid).all(axis=1)
                five[rows[ok]] += (mid[ok] - five[rows[ok], 0])[:, None]
        return cand, five, size

    rng = np.random.default_rng(4)
    n_mid = 0
    for t in range(40):
        board = Charuco(int(rng.integers(3, 12)), int(rng.integers(3, 10)), 0.03, 0.02, "DICT_6X6_250",
                        legacy=bool(t % 3 == 0))
        ms, obj, _ = _layout(board)
        H = np.array([[9000.0, rng.normal(0, 500), 100.0], [rng.normal(0, 500), 9000.0, 80.0],
                      [rng.normal(0, 3), rng.normal(0, 3), 1.0]])
        img = apply_homographies(np.broadcast_to(H, (len(obj), 3, 3)).copy(), obj)
        img = img + rng.normal(0.0, 0.5, img.shape)
        conf = np.sort(rng.permutation(len(obj))[:rng.integers(1, len(obj) + 1)])
        homs = fit_homographies(obj[conf], img[conf])
        side = rng.uniform(10.0, 40.0, len(conf))
        cand, five, size = numpy_predictions(board, conf, homs, side, img[conf])
        got, got_size, touched = np.empty((board.n_points, 5, 2)), np.empty(board.n_points), np.empty(board.n_points)
        mk.charuco_predictions(np.ascontiguousarray(ms[conf], dtype=np.int64), homs, side, np.ascontiguousarray(obj[conf]),
                               np.ascontiguousarray(img[conf]), board.squares_x, board.squares_y, board.square,
                               _STEP_OFFSETS * board.square, got, got_size, touched)
        np.testing.assert_array_equal(np.flatnonzero(touched > 0), cand)
        np.testing.assert_array_equal(got[cand], five)
        np.testing.assert_array_equal(got_size, size)
        assert np.isnan(np.delete(got, cand, axis=0)).all()
        n_mid += int((touched == 2).sum())
    assert n_mid > 50


def test_the_circles_colours_are_those_of_their_numpy_definition():
    """_colours_on_circle (kernel circle_colours) against the NumPy it replaced, bit for bit:
    dark along the bisectors of the black squares' sectors and light along the white ones',
    at the circle's radius (or on the board's circle, rho in squares), on a float image and a
    RawGrey, sheared steps and both chiralities."""
    from camkit.target.checkerboard import RawGrey, _sample

    def numpy_colours(board, grey, cand, q, u, v, mid, rho, on_board):
        sign = _square_signs(board, cand)[:, None]
        un = u / np.maximum(np.hypot(*u.T), 1e-12)[:, None]
        vn = v / np.maximum(np.hypot(*v.T), 1e-12)[:, None]
        diag = np.stack([un + sign * vn, -(un + sign * vn), un - sign * vn, -(un - sign * vn)], axis=1)
        diag *= (rho[:, None] / np.maximum(np.hypot(*diag.transpose(2, 0, 1)), 1e-12))[..., None]
        b = np.flatnonzero(on_board)
        ub, vb, sb = u[b], v[b], sign[b]
        diag[b] = np.stack([ub + sb * vb, -(ub + sb * vb), ub - sb * vb, -(ub - sb * vb)], axis=1) * (
            rho[b, None, None] / np.sqrt(2.0))
        on = _sample(grey, q[:, None, 0] + diag[..., 0], q[:, None, 1] + diag[..., 1], "bilinear")
        return (on[:, :2].max(axis=1) < mid) & (on[:, 2:].min(axis=1) > mid)

    rng = np.random.default_rng(6)
    board = Charuco(7, 6, 0.03, 0.02, "DICT_6X6_250")
    img = rng.random((80, 90))
    n_true = 0
    for grey in (img, RawGrey((img * 255).astype(np.uint8), 1 / 255, 0.0)):
        for _ in range(20):
            K = 50
            cand = rng.integers(0, board.n_points, K)
            q = rng.uniform(5.0, 75.0, (K, 2))
            u, v = rng.normal(0.0, 10.0, (K, 2)), rng.normal(0.0, 10.0, (K, 2))
            mid, rho = rng.uniform(0.2, 0.8, K), rng.uniform(1.5, 6.0, K)
            on_board = rng.random(K) < 0.3
            got = _colours_on_circle(board, grey, cand, q, u, v, mid, rho, on_board)
            np.testing.assert_array_equal(got, numpy_colours(board, grey, cand, q, u, v, mid, rho, on_board))
            n_true += int(got.sum())
    assert n_true > 30

def test_thin_margins_seen_square_on_keep_their_corners():
    """Markers of 90 % of the square, squares of 20 px seen square on: margins of a pixel, under
    the 1.35 px below which a fit's sigma must pass without its residuals' help, and every corner
    still found, in place: the rule drops poor fits, not thin margins."""
    b = Charuco(8, 6, 0.03, 0.027, "DICT_4X4_50")
    cam = BrownConrady(fx=600.0, fy=600.0, cx=319.5, cy=239.5, width=640, height=480)
    img, truth = render_target(cam, _view(b, cam, [0.0, 0.0, 0.05], distance=5.3), b)
    step = np.hypot(*(truth.corners_px[1] - truth.corners_px[0]))
    assert 19 < step < 21 and 0.05 * step < 1.35
    det = b.detect(img)
    assert det.n_found == b.n_points, det.message
    assert np.hypot(*(det.pixels - truth.corners_px[det.ids]).T).max() < 0.15
