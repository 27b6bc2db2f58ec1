"""Kalibr's AprilGrid: its layout and numbering, the printed tags, OpenCV reading the sheet, and
detection on renders (tilted, partial, fisheye, JPEG)."""

from __future__ import annotations

import io

import cv2
import numpy as np
import pytest
from PIL import Image

from camkit.errors import ParameterError
from camkit.geometry import Pose
from camkit.lens import BrownConrady, KannalaBrandt
from camkit.render import render_target
from camkit.target import AprilGrid
from camkit.target.base import Sheet


def _kalibr_points(tag_rows: int, tag_cols: int, size: float, spacing: float) -> np.ndarray:
    """Kalibr's GridCalibrationTargetAprilgrid::createGridPoints, restated: point (r, c) of the
    2 rows x 2 cols grid, row by row."""
    rows, cols = 2 * tag_rows, 2 * tag_cols
    out = np.zeros((rows * cols, 3))
    for r in range(rows):
        for c in range(cols):
            out[r * cols + c] = [(c // 2) * (1 + spacing) * size + (c % 2) * size,
                                 (r // 2) * (1 + spacing) * size + (r % 2) * size, 0.0]
    return out


@pytest.mark.parametrize("size", [(6, 6), (4, 3), (2, 5), (7, 1)])
def test_layout_and_ids_are_kalibrs(size):
    """Object points as Kalibr's createGridPoints; tag t's corners as its computeObservation
    numbers them (baseId = (t / tagCols) 2 cols + (t % tagCols) 2; corners baseId, +1,
    +cols+1, +cols for the tag's bottom-left, bottom-right, top-right, top-left)."""
    tx, ty = size
    g = AprilGrid(tx, ty, 0.05, 0.25)
    np.testing.assert_allclose(g.object_points(), _kalibr_points(ty, tx, 0.05, 0.25), atol=1e-15)
    cols = 2 * tx
    pts = g.object_points()
    for t in range(g.n_tags):
        base = (t // tx) * cols * 2 + (t % tx) * 2
        bl, br, tr, tl = base, base + 1, base + cols + 1, base + cols
        ids = g.tag_point_ids()[t]
        assert set(ids) == {bl, br, tr, tl}
        # The ids sit where tag_corners puts the tag's corners.
        np.testing.assert_allclose(pts[ids, :2], g.tag_corners()[t], atol=1e-15)
        x0, y0 = pts[bl, :2]
        np.testing.assert_allclose(pts[tr, :2], [x0 + 0.05, y0 + 0.05], atol=1e-15)


#: The first two codes of each family as Kalibr's createTargetPDF.py lists them (the AprilTags
#: C++ library's tagCodes, M. Kaess): published numbers, the oracle of the tag drawing.
KALIBR_CODES = {"tag36h11": (36, [0xD5D628584, 0xD97F18B49]), "tag25h9": (25, [0x155CBF1, 0x1E4D1B6]),
                "tag16h5": (16, [0x231B, 0x2EA5])}


@pytest.mark.parametrize("family", sorted(KALIBR_CODES))
def test_tags_are_drawn_as_kalibr_prints_them(family):
    """Kalibr's rule (createTargetPDF.generateAprilTag): bit n i + j of the code, black where
    it is 0, the matrix turned by np.rot90(., 2), row i from the top of the page, a black
    border two bits wide. camkit's printed page (raster, y up) shows the same cells."""
    nbits, codes = KALIBR_CODES[family]
    n = int(np.sqrt(nbits))
    cells = n + 4
    g = AprilGrid(2, 1, cells * 0.001, 0.5, family)  # one cell = 1 mm
    sheet = g.sheet()
    img = sheet.raster(10000.0)  # 10 px a cell
    u_min, _, _, v_max = sheet.extent
    for t, code in enumerate(codes):
        black = np.array([[not code & (1 << (n * i + j)) for j in range(n)] for i in range(n)])
        want = np.ones((cells, cells), dtype=bool)
        want[2:-2, 2:-2] = np.rot90(black, 2)
        u0, v0 = g.tag_corners()[t].min(axis=0)
        top = v_max - (v0 + g.tag_size)  # the tag's top edge, down the page from its top
        r0 = round(top * 10000.0)
        c0 = round((u0 - u_min) * 10000.0)
        got = img[r0 + 5:r0 + cells * 10:10, c0 + 5:c0 + cells * 10:10] == 0
        np.testing.assert_array_equal(got, want)


def test_opencv_reads_the_printed_sheet():
    """The page at 4 px/mm given to OpenCV's ArUco detector (DICT_APRILTAG_36h11, a border two
    bits wide): every tag with its id, its corners where camkit's tag_corners put them."""
    g = AprilGrid(4, 3, 0.03, 0.3)
    sheet = g.sheet()
    img = sheet.raster(4000.0)
    params = cv2.aruco.DetectorParameters()
    params.markerBorderBits = 2
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11), params)
    corners, ids, _ = det.detectMarkers(img)
    assert sorted(np.ravel(ids)) == list(range(g.n_tags))
    u_min, _, _, v_max = sheet.extent
    for c, i in zip(corners, np.ravel(ids), strict=True):
        obj = g.tag_corners()[i]
        page = np.stack([(obj[:, 0] - u_min) * 4000.0 - 0.5, (v_max - obj[:, 1]) * 4000.0 - 0.5], axis=-1)
        np.testing.assert_allclose(c.reshape(4, 2), page, atol=0.3)


CAM = BrownConrady(fx=600.0, fy=600.0, cx=319.5, cy=239.5, k1=-0.1, k2=0.02, width=640, height=480)


def _view(grid: AprilGrid, camera, rvec, shift=(0.0, 0.0), distance=1.6) -> Pose:
    """The printed face towards the camera (the grid's z points at it), turned by rvec."""
    pts = grid.object_points()
    c = 0.5 * (pts.min(axis=0) + pts.max(axis=0)) + [*shift, 0.0]
    R = Pose.from_rvec(rvec, [0.0, 0.0, 0.0]).R @ np.diag([1.0, -1.0, -1.0])
    t = np.array([0.0, 0.0, distance * np.ptp(pts[:, 0]) * camera.fx / camera.width]) - R @ c
    return Pose(R, t)


def _check(det, truth, grid, min_fraction):
    """Every corner returned within 0.3 px of its id's truth (a corner at another junction is
    a corner square off), and at least ``min_fraction`` of the corners of the tags seen whole
    (a tag cut by the image's edge is not read: its corners carry no id)."""
    assert det.found, det.message
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert err.max() < 0.3, (err.max(), det.ids[np.argmax(err)])
    ids = grid.tag_point_ids()
    whole = ids[truth.visible[ids].all(axis=1)].ravel()
    assert np.isin(whole, det.ids).sum() >= min_fraction * len(whole), (np.isin(whole, det.ids).sum(), len(whole))
    return err


@pytest.mark.parametrize("rvec", [(0.3, -0.2, 0.1), (-0.6, 0.4, 2.0), (0.9, 0.1, -0.7)])
def test_tilted_views(rvec):
    g = AprilGrid.example()
    img, truth = render_target(CAM, _view(g, CAM, rvec), g)
    err = _check(g.detect(img), truth, g, 0.98)
    assert np.median(err) < 0.03


class _Blotted(AprilGrid):
    """An AprilGrid whose right half's tags are printed solid black: no code to read there."""

    __slots__ = ()

    def sheet(self) -> Sheet:
        s = AprilGrid.sheet(self)
        o = self.tag_places() * self.pitch
        right = o[self.tag_places()[:, 0] >= self.tags_x / 2]
        r = s.black
        inside = ((r[:, None, 0] >= right[None, :, 0] - 1e-9) & (r[:, None, 2] <= right[None, :, 0] + self.tag_size + 1e-9)
                  & (r[:, None, 1] >= right[None, :, 1] - 1e-9)
                  & (r[:, None, 3] <= right[None, :, 1] + self.tag_size + 1e-9)).any(axis=1)
        solid = np.c_[right, right + self.tag_size]
        return Sheet(s.extent, np.concatenate([r[~inside], solid]), s.label, v_up=True)


def test_points_of_tags_not_read_are_grown_from_those_found():
    """Tags that cannot be read (here printed solid) still have X-junctions at their corners:
    reached from the tags read, every point is found at its truth (without the growth, half)."""
    g = _Blotted(6, 4, 0.03, 0.3)
    img, truth = render_target(CAM, _view(g, CAM, (0.3, -0.2, 0.1)), g)
    assert truth.visible.all()
    det = g.detect(img)
    assert det.n_found == g.n_points, det.message
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert err.max() < 0.05, err.max()


def test_a_grid_half_out_of_the_frame_gives_the_corners_it_shows():
    g = AprilGrid(6, 5, 0.04, 0.3)
    img, truth = render_target(CAM, _view(g, CAM, (0.2, 0.3, 0.1), shift=(0.14, 0.05), distance=1.1), g)
    assert 0.3 * g.n_points < truth.visible.sum() < 0.8 * g.n_points
    det = g.detect(img)
    _check(det, truth, g, 0.95)
    assert not np.isfinite(det.corners[~truth.visible]).any()


def test_fisheye_and_jpeg():
    cam = KannalaBrandt(fx=330.0, fy=330.0, cx=319.5, cy=239.5, k1=0.02, k2=-0.01, k3=0.0, k4=0.0, width=640,
                        height=480)
    g = AprilGrid(5, 4, 0.04, 0.3)
    img, truth = render_target(cam, _view(g, cam, (0.3, -0.5, 0.2), shift=(0.03, 0.0), distance=1.3), g)
    buf = io.BytesIO()
    Image.fromarray(np.clip(img * 255 + 0.5, 0, 255).astype(np.uint8)).save(buf, "JPEG", quality=75)
    jpeg = np.asarray(Image.open(io.BytesIO(buf.getvalue())))
    # A tag at the rim reads wrong through its four corners' homography (the lens bends its
    # cells): its corners go rather than risk a label (59 of 64 found).
    _check(g.detect(jpeg), truth, g, 0.9)


def test_the_grid_seen_from_behind_is_not_read():
    """A mirrored print (the grid seen through the paper) holds no code of the family's:
    nothing is returned rather than mirrored labels."""
    g = AprilGrid.example()
    R = Pose.from_rvec((0.2, -0.1, 0.1), [0.0, 0.0, 0.0]).R  # z away from the camera: the back
    pts = g.object_points()
    t = np.array([0.0, 0.0, 1.6 * np.ptp(pts[:, 0]) * CAM.fx / CAM.width]) - R @ pts.mean(axis=0)
    img, _ = render_target(CAM, Pose(R, t), g)
    det = g.detect(img)
    assert not det.found and det.message.startswith("not found")


def test_bad_input():
    with pytest.raises(ParameterError, match="family"):
        AprilGrid(6, 6, 0.088, 0.3, "tag99h9")
    with pytest.raises(ParameterError, match="family"):
        AprilGrid(6, 6, 0.088, 0.3, ["tag36h11"])
    with pytest.raises(ParameterError, match="tag_spacing"):
        AprilGrid(6, 6, 0.088, float("nan"))
    with pytest.raises(ParameterError, match="tags_x"):
        AprilGrid(6.5, 6, 0.088, 0.3)
    with pytest.raises(ParameterError, match="tag_spacing"):
        AprilGrid(6, 6, 0.088, 1.5)
    with pytest.raises(ParameterError, match="tag_spacing"):
        AprilGrid(6, 6, 0.088, 0.0)
    with pytest.raises(ParameterError, match="family: a 6x6 grid needs 36 tags"):
        AprilGrid(6, 6, 0.088, 0.3, "tag16h5")
    with pytest.raises(ParameterError, match="tags_x, tags_y"):
        AprilGrid(1, 1, 0.088, 0.3)
    with pytest.raises(ParameterError, match="tag_size"):
        AprilGrid(6, 6, -0.088, 0.3)


def test_corpus_sample_never_a_wrong_id():
    """Issue 23 item 3 on a sample of the rendered corpus (benchmarks/aprilgrid_corpus.py runs
    500 views): views 0-11 (fisheye, barrel, pincushion and pinhole lenses, tilts to 70 degrees,
    blur, noise, JPEG, partial grids). No returned corner more than 1 px from its id's truth;
    at least 92 % of the eligible corners (tags wholly in view, 2 px a cell) found (measured
    97.2 %; 88.5 % before each fit was judged against fits with its own window); noise-free
    median error under 0.02 px (measured 0.0045)."""
    from benchmarks.aprilgrid_corpus import eligible, view

    found = total = 0
    clean = []
    for seed in range(12):
        v = view(seed)
        if v is None:
            continue
        grid, camera, _, pose, img, truth, noisy = v
        det = grid.detect(img)
        err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
        assert not (err > 1.0).any(), (seed, det.ids[err > 1.0], err[err > 1.0])
        el = np.flatnonzero(eligible(grid, camera, pose, truth))
        found += int(np.isin(el, det.ids).sum())
        total += len(el)
        if not noisy:
            clean.extend(err.tolist())
    assert found >= 0.92 * total, (found, total)
    assert np.median(clean) < 0.02


def test_the_corpus_does_not_count_a_grid_seen_from_behind():
    """The renderer draws a sheet's marks from either side; seen from behind, a tag is
    mirrored and holds no code. The corpora's eligibility measures the angle against the
    printed face (benchmarks.charuco_corpus.obliquity), so a grid turned away counts for
    nothing, at any angle (AprilGrid corpus views 183, 1221 and 1995 held 103 such corners,
    counted as missed; with an unsigned angle the turned grid below counts every corner).
    Both kinds of sheet: the AprilGrid's z points at the camera that sees its print,
    ChArUco's away from it."""
    from benchmarks.aprilgrid_corpus import eligible
    from benchmarks.charuco_corpus import eligible as charuco_eligible
    from camkit.geometry.rotation import matrix_from_rvec
    from camkit.lens import Pinhole
    from camkit.target import Charuco

    cam = Pinhole(fx=800.0, fy=800.0, cx=319.5, cy=239.5, width=640, height=480)
    flip = matrix_from_rvec([0.0, np.pi, 0.0])
    for target, faces in ((AprilGrid(4, 3, 0.03, 0.3), flip), (Charuco(5, 4, 0.03, 0.022), np.eye(3))):
        centre = target.object_points().mean(axis=0)
        for R, seen in ((faces, True), (faces @ flip, False)):
            pose = Pose(R, np.array([0.0, 0.0, 0.5]) - R @ centre)
            truth = type("T", (), {"corners_px": cam.project(pose.apply(target.object_points()))})
            el = eligible if isinstance(target, AprilGrid) else charuco_eligible
            for any_angle in (False, True):
                ok = el(target, cam, pose, truth, any_angle=any_angle)
                assert ok.all() if seen else not ok.any(), (type(target).__name__, seen, any_angle, ok.mean())


def test_sheared_corner_squares_and_corners_at_the_image_edge():
    """Two corpus views that returned corners 1.0-1.33 px off their truth. View 455: a grid
    seen obliquely, its corner squares sheared to about 5 px across while their sides stay
    long; the window and smoothing followed the tag's shortest side (median error 0.49 px).
    They now follow how narrow it is (measured: median 0.11, max 0.39 px). View 562: a corner
    three rows from the image's bottom edge, its window reaching past it."""
    from benchmarks.aprilgrid_corpus import view

    for seed, max_err, max_median in ((455, 0.6, 0.2), (562, 0.3, 0.1)):
        grid, _, _, _, img, truth, _ = view(seed)
        det = grid.detect(img)
        err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
        assert err.max() < max_err and np.median(err) < max_median, (seed, err.max(), np.median(err))


def test_tags_are_not_read_again_from_refined_quads():
    """The ChArUco detector reads a quad with a marker's border again with its corners refined
    to its sides' edges. An AprilGrid's tag joins its corner squares' dark regions where
    blurred (it is read as such a swollen quad instead), and read after refining, corpus view
    43's tags gave corner 92 1.4 px off: the AprilGrid does not take that path."""
    from benchmarks.aprilgrid_corpus import view

    grid, _, _, _, img, truth, _ = view(43)
    det = grid.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 30 and err.max() < 1.0, (det.n_found, err.max())


def test_a_fisheyes_tags_keep_the_corners_their_quads_found():
    """Corpus view 133 (fisheye, noise, tags of 75-120 px): every tag was read, its quad's
    corners within 2 px, but each corner more than a third of a corner square from where one
    homography through the tags around it put it was taken from that homography, 5-18 px off
    through the lens: 79 of 168 corners found. A corner is now taken from the other tags'
    corners only where their local map puts it inwards along the tag's diagonal by about a
    corner square (a joined corner square's far corner), or where the tags around fit one
    homography."""
    from benchmarks.aprilgrid_corpus import view

    grid, _, _, _, img, truth, _ = view(133)
    det = grid.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 150 and err.max() < 1.0, (det.n_found, err.max())


def test_the_corners_of_a_fisheyes_large_middle_tags_are_checked_at_their_own_scale():
    """Corpus view 89 (fisheye, tags of 70-210 px): the last check held every corner to 6 % of
    the grid's median tag (6.3 px); the middle tags, twice that size, miss a quadratic map of
    their neighbours by up to 9 px through the lens, and 10 of their corners that OpenCV
    returns within 0.1 px went. The tolerance now follows the corner's own tag where larger."""
    from benchmarks.aprilgrid_corpus import opencv_corners, view

    grid, _, _, _, img, truth, _ = view(89)
    det = grid.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    ids, _ = opencv_corners(grid, img)
    assert set(ids.tolist()) <= set(det.ids.tolist()) and err.max() < 1.0, (sorted(set(ids) - set(det.ids)), err.max())


def test_a_fisheyes_bent_tags_are_read_through_a_lens():
    """Corpus view 28 (fisheye, noise, tags of 20-250 px): the lens bows the tags' sides, and
    the homography through a tag's four corners puts its middle cells 0.6-1.7 cells off, so 5
    of its 42 tags were read and 16 of its 168 corners found. A quad that reads as no code is
    now read through Fitzgibbon's division model at a few strengths (every tag's cells lie
    within 0.07 of a cell of that model's at -1.5, measured on the render's truth), and the
    tags are confirmed and recovered through the strength that confirms the most."""
    from benchmarks.aprilgrid_corpus import view
    from camkit.target._markers import find_markers

    grid, _, _, _, img, truth, _ = view(28)
    found, _, _ = find_markers(img.astype(np.float64) / 255.0, grid.aruco, 2, corner_squares=grid.tag_spacing)
    assert len(set(found) & set(range(grid.n_tags))) >= 25, sorted(found)
    det = grid.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 115 and err.max() < 1.0, (det.n_found, err.max())


def test_tags_chained_to_their_corner_squares_are_cut_apart_at_the_junctions():
    """Corpus view 186 (barrel lens, 3 x 5 tags of 24 px seen aslant, blurred): the junctions
    along one axis have light sectors so thin that their middle is darker than any threshold
    between black and white, so each tag joined its corner squares into a chain and 2 of 15
    tags were read (not found: none confirmed). The dark masks are now cut along the light
    sectors of every X-junction: all 15 read, all 60 corners found."""
    from benchmarks.aprilgrid_corpus import view

    grid, _, _, _, img, truth, _ = view(186)
    det = grid.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 56 and err.max() < 0.5, (det.message, err.max())


def _check_corpus_view(seed: int, max_err: float, max_missed: int) -> None:
    """AprilGrid corpus view ``seed`` (benchmarks/aprilgrid_corpus.py): every corner returned
    within ``max_err`` px of its id's truth, and at most ``max_missed`` of the eligible corners
    (tags wholly in view, 2 px a cell, within 70 degrees) missed."""
    from benchmarks.aprilgrid_corpus import eligible, view

    grid, camera, _, pose, img, truth, _ = view(seed)
    det = grid.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    el = np.flatnonzero(eligible(grid, camera, pose, truth))
    assert err.max() < max_err, (det.message, err.max())
    assert np.isin(el, det.ids).sum() >= len(el) - max_missed, (len(el), np.isin(el, det.ids).sum())


def test_a_small_blurred_tag_read_again_through_its_exact_corners_is_read_at_its_cells_middles():
    """Corpus view 228 (barrel lens, 6 x 6 tags of 23-24 px, 2.35 px a cell, blurred): seven
    tags whose corners were all fitted within 0.05 px of the truth read as no code through
    them (7-9 of their 36 bits wrong: the points 0.2 of a cell either side of a cell's middle
    take in the blur of the cells beside it), and the reading again took their 28 corners.
    Read at their cells' middles alone, four of them read as their own code."""
    _check_corpus_view(228, max_err=0.5, max_missed=12)


def test_a_tag_read_again_takes_its_missing_corners_from_the_other_tags_not_its_quad():
    """Corpus view 975 (fisheye, 8 x 4 tags of 21-38 px, noise): tags with a corner not
    fitted were read again through their quad's corner there, which the lens and joined
    corner squares put pixels off, and read as no code: the reading again took their found
    corners (22 of the 91 eligible corners missed). Such a tag is now read once more with
    its missing corners where the other tags' found corners put them (13 missed, none more
    than 0.36 px off)."""
    _check_corpus_view(975, max_err=0.5, max_missed=15)


def test_small_blurred_tags_are_read_in_the_quads_of_their_junctions():
    """Corpus view 1117 (pinhole, 7 x 6 tags of 20-26 px, blurred, 160 eligible corners): the
    threshold joins each tag with its corner squares, its quads lie 8-46 px off, one tag read
    and nothing was found. The tags' corners are sharp X-junctions: quads of junctions with a
    tag's border read 14 tags, and the grid grows from them."""
    _check_corpus_view(1117, max_err=0.3, max_missed=20)


def test_every_tag_of_a_small_blurred_grid_is_a_quad_of_junctions():
    """:func:`junction_quads` on corpus view 1117: each of the 40 tags' four corners is a quad
    of it, within 0.3 px (saddle points), in the image's clockwise order; the quads are few
    beside the pairs of junctions (a few per tag)."""
    from benchmarks.aprilgrid_corpus import view
    from camkit.target._markers import junction_quads
    from camkit.target.checkerboard import _to_grey

    grid, _, _, _, img, truth, _ = view(1117)
    q = junction_quads(_to_grey(img, lazy=True).dense())
    tags = truth.corners_px[grid.tag_point_ids()]  # (40, 4, 2), the code's order: clockwise here
    # Each tag against every quad in each of its four turns: the largest corner distance.
    d = np.stack([np.hypot(*(np.roll(q, k, axis=1)[:, None] - tags[None]).transpose(3, 0, 1, 2)).max(axis=2)
                  for k in range(4)]).min(axis=0)  # (quads, tags)
    assert (d.min(axis=0) < 0.3).all(), np.sort(d.min(axis=0))[-5:]
    assert len(q) <= 4 * len(tags), len(q)
    e1, e2 = q[:, 1] - q[:, 0], q[:, 3] - q[:, 0]
    assert (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] > 0).all()


def test_noise_read_through_its_junctions_is_not_a_grid():
    """An image of blurred noise has saddles everywhere and no tag: the junction reading
    (taken where fewer than four tags are confirmed) makes its quads and reads them, and
    the grid is not found, with the reason."""
    from scipy import ndimage

    from camkit.target._markers import junction_quads

    noise = ndimage.gaussian_filter(np.random.default_rng(3).normal(size=(240, 320)), 1.5)
    img = np.clip(0.5 + 2.0 * noise, 0.0, 1.0)
    assert len(junction_quads(img)) > 0  # the junction reading has quads to read
    det = AprilGrid.example().detect(img)
    assert not det.found and det.n_found == 0 and det.message.startswith("not found"), det.message


def test_a_tags_exact_corners_are_not_taken_from_a_neighbour_read_with_its_corner_square():
    """Corpus view 1063 (pinhole, 5 x 7 tags of 40 px seen aslant, noise): nine tags were read
    with a corner square joined at some corners (their quads 4-9 px off there). Where one
    such tag was the only one beside a tag read exactly, the homography through both put the
    exact tag's corners 16-54 px away, and they were taken from it though they lay nowhere a
    joined corner square puts a corner (tags 4, 5 and 14); the corners fitted there then
    turned those tags' cells, and the reading again took 33 of the 140 corners. A corner is
    now taken from the tags beside it only where it has a joined corner square's signature,
    whichever map predicted it."""
    _check_corpus_view(1063, max_err=0.5, max_missed=8)


def test_corners_tried_again_from_their_neighbours_are_held_to_the_grown_corners_sigma_test():
    """Corpus view 872 (fisheye, tags of 20-29 px, corner squares of 4-6 px): corner 26's fit
    at its tag's corner failed, and the fit from its neighbours' prediction (3.9 px off) took
    the saddle a blur makes between a corner square's two junctions, 3.2 px from the truth,
    with a sigma of 0.13 px. Whether it survives depends on which neighbours the last check
    sees: the change to the joined-corner signature above let it through. Such corners are
    now held to the test of the points grown past the tags (sigma at most 1.5 times the
    typical one): on 150 views of the corpus, 19 of the 20 fits that took such a saddle had
    sigmas of 0.14-0.9 px, and 123 of the 126 right ones under 0.12 px."""
    from benchmarks.aprilgrid_corpus import view

    grid, _, _, _, img, truth, _ = view(872)
    det = grid.detect(img)
    err = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert det.n_found >= 150 and err.max() < 1.0, (det.n_found, err.max())


def test_a_small_tag_through_a_strong_lens_is_read_again_as_it_was_first_read():
    """Corpus view 1307 (fisheye, tags of 20-28 px): tags 14 and 22 read first through a lens
    of some strength (the reading's fallback), then not again through their corners, all
    within 0.17 px of the truth, at the view's strength: their eight eligible corners went.
    A tag that reads as no code is now read again through the strengths the first reading
    tries."""
    _check_corpus_view(1307, max_err=0.5, max_missed=0)


def test_a_corner_by_the_images_edge_is_fitted_with_a_window_that_fits():
    """Corpus view 1298 (barrel): a tag's corner 6 px from the image's edge, where the window
    of 5 px and its support did not fit inside the image, and the fit, 0.02 px from the
    truth, went. The window now shrinks to fit."""
    _check_corpus_view(1298, max_err=0.5, max_missed=0)


def test_a_corner_off_the_whole_grids_lens_model_goes_though_its_neighbours_let_it_through():
    """Corpus view 1550 (pinhole, 8 x 7 tags of 37-48 px, corner squares of 8 px, blur): corner
    98's fit from its tag's quad took the saddle a blur makes beside the junction, 2.7 px off,
    and the tag still read. At the grid's edge the last check's map of its neighbours missed
    it by 2.80 px, within the 6 % of a tag (2.86 px) a lens may bend the grid there. The model
    of the lens fitted on the whole grid misses it by 2.6 px and the right corners by at most
    0.7 px: it goes. The starting code returned it."""
    _check_corpus_view(1550, max_err=1.0, max_missed=36)


def test_the_lens_veto_takes_a_moved_corner_and_nothing_where_the_model_cannot_follow():
    """:func:`_lens_veto` on an AprilGrid's corners through a barrel lens: a corner moved by
    2 px (within the local check's tolerance for its tags of 45 px, 2.7 px) goes, and only
    it; with the corners bent by a ripple no lens model follows (2 px, the board not flat),
    the spread of the fit's misses is large and nothing goes."""
    from camkit.target.checkerboard import _lens_veto

    grid = AprilGrid(6, 5, 0.03, 0.3)
    pts = grid.object_points()
    pose = Pose.from_rvec([0.3, -0.25, 0.05], [0.0, 0.0, 0.0])
    pose = Pose(pose.R, np.array([0.0, 0.0, 0.45]) - pose.R @ pts.mean(axis=0))
    q = CAM.project(pose.apply(pts))
    g = pts[:, :2] / grid.pitch
    keep = np.ones(len(q), dtype=bool)
    assert _lens_veto(g, q, keep, (480, 640), 1.5, 6.0, 1.5).all()
    moved = q.copy()
    moved[37] += 2.0 * np.array([0.8, -0.6])
    assert np.array_equal(_lens_veto(g, moved, keep, (480, 640), 1.5, 6.0, 1.5), np.arange(len(q)) != 37)
    rippled = q + 2.0 * np.sin(q[:, ::-1] / 25.0)
    assert _lens_veto(g, rippled, keep, (480, 640), 1.5, 6.0, 1.5).all()


def test_corners_at_a_fisheyes_rim_the_local_check_cannot_follow_are_put_back_by_a_lens_model():
    """Corpus view 1304 (fisheye, 8 x 4 tags of 22-90 px): the last check's quadratic map,
    fitted on one side of the corners at the grid's edge, missed right corners (0.00-0.05 px
    from the truth) by 8-12 px against tolerances of 4-6 px, and 10 of the 88 eligible
    corners went. A global model of the lens (the checkerboard's rescue: a homography and
    radial distortion about a free centre, trusted where it predicts the outer corners it
    was not fitted on) puts back those it predicts within half a pixel."""
    _check_corpus_view(1304, max_err=0.5, max_missed=2)


def test_quads_read_in_chunks_read_as_all_at_once(monkeypatch):
    """Each quad's reading is its own: read a few at a time (as a cluttered image's hundred
    thousand quads are, to bound the samples held at once), the codes, turns and rims are
    those of one reading of all of them (the tags' own quads, quads a few pixels off them,
    one that is not finite), straight, through a lens and with the corners placed in the
    tag's cells."""
    from camkit.target import _markers

    g = AprilGrid.example()
    img, truth = render_target(CAM, _view(g, CAM, (0.3, -0.2, 0.1)), g)
    tags = truth.corners_px[g.tag_point_ids()]  # (T, 4, 2)
    T = len(tags)
    quads = np.concatenate([tags, tags, tags + np.random.default_rng(3).normal(0, 3, tags.shape),
                            np.full((1, 4, 2), np.nan)])
    n = g.aruco.marker_size + 4
    unit = np.array([[0.0, 0.0], [n, 0.0], [n, n], [0.0, n]])
    # The second copy of each tag with its corners placed a quarter turn round: it reads turned.
    src = np.concatenate([np.broadcast_to(unit, tags.shape), np.broadcast_to(np.roll(unit, 1, axis=0), tags.shape),
                          np.broadcast_to(unit, (T + 1, 4, 2))])
    for kw in ({}, {"bend": -0.5}, {"src": src}):
        whole = _markers.read_markers_rims(img, quads, g.aruco, 2, **kw)
        monkeypatch.setattr(_markers, "_READ_CHUNK", 7)
        parts = _markers.read_markers_rims(img, quads, g.aruco, 2, **kw)
        monkeypatch.setattr(_markers, "_READ_CHUNK", 4096)
        for a, b in zip(whole, parts, strict=True):
            np.testing.assert_array_equal(a, b)
        # Not a comparison of empty readings: the tags' own quads read as their ids.
        np.testing.assert_array_equal(parts[0][:T], np.arange(T))
        assert parts[0][-1] == -1
    assert (parts[1][T:2 * T] != parts[1][:T]).all()  # placed a quarter turn round: turned


def test_a_grid_given_with_its_tags_counted_the_other_way_round_is_named():
    """A 6x4 grid given as 4x6: no tag is where that layout puts it, nothing is labelled, and
    the message names the layout the tags read fit."""
    from camkit.render import default_camera, plan_views, render_target

    cam = default_camera("brown-conrady")
    real = AprilGrid(6, 4, 0.05, 0.3)
    img, _ = render_target(cam, plan_views(cam, real, 1, np.random.default_rng(0))[0], real)
    assert real.detect(img).n_found == 96
    det = AprilGrid(4, 6, 0.05, 0.3).detect(img)
    assert not det.found and det.message.endswith(
        "(tag36h11); the tags read fit a 6x4-tag grid (the tags counted the other way round)"), det.message


def test_small_corner_squares_seen_aslant_give_their_corners_in_place():
    """View 32 of ``benchmarks.wide_boards`` (tag16h5, spacing 0.23, 64 degrees from square on:
    corner squares 4.7 px across). The fit's smoothing of 1.5 px pulled the saddles 0.6 px off
    (one 1.04 px); kept inside the junction's width it leaves them in place, and where a
    quad's corner predicts a junction 2 px off, a saddle on the corner square's far side,
    fitting worse than the corner's, is not taken for it. Before: 34 of 72 corners, one
    1.04 px off."""
    from benchmarks.wide_boards import aprilgrid_view

    grid, _, _, _, img, truth, _ = aprilgrid_view(32)
    det = grid.detect(img)
    d = np.hypot(*(det.pixels - truth.corners_px[det.ids]).T)
    assert (d <= 1.0).all(), (det.ids[d > 1.0], d[d > 1.0])
    assert len(det.ids) >= 50 and np.median(d) < 0.4  # (0.60 before; 0.31 after: the floor of 1 px)
