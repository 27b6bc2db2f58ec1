"""The coded targets' shared pieces: the batched homographies against OpenCV, and the grey
image the detectors start from against NumPy."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from camkit.target._homography import apply_homographies, fit_homographies
from camkit.target._markers import distort, undistort
from camkit.target.checkerboard import _to_grey


def _sets(rng, K, P):
    src = rng.uniform(-50, 150, (K, P, 2))
    H = np.eye(3) + rng.normal(0, 0.2, (K, 3, 3))
    H[:, 2, :2] *= 0.005
    return src, apply_homographies(H, src)


def test_homographies_are_exact_on_exact_points_and_opencvs_on_four():
    rng = np.random.default_rng(3)
    for P in (4, 9, 16):
        src, dst = _sets(rng, 50, P)
        H = fit_homographies(src, dst)
        np.testing.assert_allclose(apply_homographies(H, src), dst, atol=1e-8)
    src, dst = _sets(rng, 20, 4)
    H = fit_homographies(src, dst)
    grid = np.stack(np.meshgrid(np.linspace(-50, 150, 5), np.linspace(-50, 150, 5)), -1).reshape(-1, 2)
    for k in range(20):  # four points fix the homography: OpenCV's is the same map
        ref = cv2.getPerspectiveTransform(src[k].astype(np.float32), dst[k].astype(np.float32))
        np.testing.assert_allclose(apply_homographies(H[k:k + 1], grid[None])[0],
                                   apply_homographies(ref[None], grid[None])[0], atol=1e-3)  # float32 there


def test_homographies_of_noisy_points_fit_them_as_well_as_opencvs_least_squares():
    rng = np.random.default_rng(4)
    src, dst = _sets(rng, 30, 12)
    noisy = dst + rng.normal(0, 0.5, dst.shape)
    ours = np.hypot(*(apply_homographies(fit_homographies(src, noisy), src) - noisy).transpose(2, 0, 1))
    for k in range(30):
        ref, _ = cv2.findHomography(src[k], noisy[k], 0)
        theirs = np.hypot(*(apply_homographies(ref[None], src[k][None])[0] - noisy[k]).T)
        # The algebraic fit in normalised frames against OpenCV's, refined on the geometric
        # error: within 3.3 % over 200 such sets (as the SVD form of the DLT).
        assert np.sqrt(np.mean(ours[k] ** 2)) <= 1.05 * np.sqrt(np.mean(theirs ** 2))


def test_degenerate_point_sets_give_nan():
    src = np.array([[[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]],  # one point
                    [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]])  # one line
    dst = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]] * 2)
    assert np.isnan(fit_homographies(src, dst)).all()


def test_grey_is_the_channel_mean_stretched_by_its_percentiles():
    """uint8 (one and three channels, the percentiles from a histogram) and float images: the
    mean of R, G and B, its 1st percentile at 0 and 99th at 1, as NumPy computes them."""
    rng = np.random.default_rng(5)
    for img in (rng.integers(0, 256, (480, 640), dtype=np.uint8), rng.integers(0, 256, (300, 401, 3), np.uint8),
                rng.integers(0, 256, (300, 401, 4), np.uint8), rng.uniform(0, 1, (200, 300)),
                rng.integers(0, 256, (1200, 1700), dtype=np.uint8)):
        f = img.astype(np.float64) / (255.0 if img.dtype == np.uint8 else 1.0)
        g = f if f.ndim == 2 else f[..., :3].mean(axis=2)
        step = max(1, int(np.sqrt(g.size / 250_000)))
        lo, hi = np.percentile(g[::step, ::step], [1, 99])
        np.testing.assert_allclose(_to_grey(img), (g - lo) / (hi - lo), atol=1e-12)


def test_the_greys_histogram_counts_every_channel_sum_as_bincount_does():
    """channel_sum_histogram (four histograms in turn, the one-channel rows four pixels at a
    time) against np.bincount of the channel sums: one channel, RGB and RGBA, every 1st to 3rd
    row and column, widths that leave 0-3 pixels over."""
    from camkit._kernels.detect import channel_sum_histogram

    rng = np.random.default_rng(12)
    for shape in ((7, 9, 1), (20, 31, 1), (5, 4, 1), (13, 10, 3), (9, 7, 4)):
        img = rng.integers(0, 256, shape, dtype=np.uint8)
        img[:, : shape[1] // 2] = 200  # a flat area: runs of one value
        n = 3 if shape[2] >= 3 else 1
        for step in (1, 2, 3):
            hist = np.zeros(255 * n + 1, dtype=np.int64)
            channel_sum_histogram(img, step, hist)
            sums = img[::step, ::step, :n].astype(np.int64).sum(axis=2).ravel()
            np.testing.assert_array_equal(hist, np.bincount(sums, minlength=255 * n + 1))


def test_box_shades_are_numpys_means_and_spreads_of_the_sampled_boxes_bit_for_bit():
    """Step 8's boxes (kernel box_shades) against sampling them (checkerboard._sample) and
    NumPy's mean and var(ddof=1), bit for bit, on a float image and on a uint8 one through its
    stretch; a box reaching off the image clears its corner's ``inside``."""
    from camkit._kernels.markers import box_shades
    from camkit.target.charuco import _BOX_X, _BOX_Y
    from camkit.target.checkerboard import RawGrey, _sample, _stretched

    rng = np.random.default_rng(13)
    raw = rng.integers(0, 256, (60, 80), dtype=np.uint8)
    for img in (rng.random((60, 80)), RawGrey(raw, 1 / 200, -0.1)):
        px = rng.uniform(-2, 82, (30, 10, 2))
        px[..., 1] *= 60 / 80
        half = rng.uniform(0.5, 6, 30)
        v = _sample(img, px[..., :1] + half[:, None, None] * _BOX_X, px[..., 1:] + half[:, None, None] * _BOX_Y,
                    "bilinear")
        lo, hi = px - half[:, None, None], px + half[:, None, None]
        want_in = (lo >= 0).all(axis=(1, 2)) & (hi[..., 0] <= 79).all(axis=1) & (hi[..., 1] <= 59).all(axis=1)
        mean, var, inside = np.empty((30, 10)), np.empty((30, 10)), np.ones(30, dtype=bool)
        box_shades(*_stretched(img), px, half, _BOX_X, _BOX_Y, mean, var, inside)
        np.testing.assert_array_equal(mean, v.mean(axis=2))
        np.testing.assert_array_equal(var, v.var(axis=2, ddof=1))
        np.testing.assert_array_equal(inside, want_in)
        assert 0 < want_in.sum() < 30


def test_a_forked_child_starts_its_own_thread_pool():
    """The marker quads are labelled on a thread pool; a child forked after the parent used it
    has none of its threads, and starts its own pool: on the parent's, a task waits for an
    idle thread that is not there."""
    import multiprocessing
    import time

    from camkit.target import _markers

    assert _markers._pool().submit(abs, -1).result() == 1  # the parent's pool has an idle thread
    time.sleep(0.1)
    with multiprocessing.get_context("fork").Pool(1) as pool:
        assert pool.apply_async(_pool_in_child).get(timeout=60) == 3


def _pool_in_child() -> int:
    from camkit.target import _markers

    return _markers._pool().submit(abs, -3).result(timeout=10)


def _quad_by_pixels(ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """The region's quad pixel by pixel in raster order: farthest from the centroid (a), from
    a (b), and from the line ab on either side (e, f), the first where several tie."""
    order = np.lexsort((xs, ys))
    x, y = xs[order].astype(float), ys[order].astype(float)
    a = np.argmax((x - x.mean()) ** 2 + (y - y.mean()) ** 2)
    b = np.argmax((x - x[a]) ** 2 + (y - y[a]) ** 2)
    side = (x[b] - x[a]) * (y - y[a]) - (y[b] - y[a]) * (x - x[a])
    e, f = np.argmax(side), np.argmin(side)
    return np.array([[x[a], y[a]], [x[e], y[e]], [x[b], y[b]], [x[f], y[f]]])


def _shoelace(q: np.ndarray) -> float:
    return 0.5 * float(np.sum(q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1]))


def _hull_quad_by_brute_force(ys: np.ndarray, xs: np.ndarray) -> tuple[float, np.ndarray]:
    """The largest area of a quadrilateral on the corners of the pixels' convex hull (every
    four of them, scipy's hull), and those corners."""
    from itertools import combinations

    from scipy.spatial import ConvexHull

    pts = np.c_[xs, ys].astype(float)
    v = pts[ConvexHull(pts).vertices]  # in order round the hull
    return max((abs(_shoelace(v[list(c)])) for c in combinations(range(len(v)), 4)), default=0.0), v


def test_region_quads_from_runs_are_those_of_the_pixels():
    """Regions against scipy.ndimage.label (4-connected; area and box) and each quad against
    the pixel-by-pixel search, on random masks (the kernel looks at the runs' ends only);
    where that quad covers under 0.6 of the region or the region's box is too thin or empty
    for it, the hull's quad against the largest on scipy's hull (every four corners), kept
    exactly where the region fills 0.35 of it and it covers 0.6 of the region."""
    from scipy import ndimage

    from camkit._kernels.markers import region_quads

    rng = np.random.default_rng(6)
    n_hull = 0
    for trial in range(60):
        H, W = rng.integers(5, 90, 2)
        m = rng.random((H, W)) < rng.uniform(0.2, 0.8)
        if trial % 2:
            m = ndimage.binary_opening(m)
        lab, n = ndimage.label(m)
        stats, quads = region_quads(m, 3, H * W, 2)
        assert len(stats) == n
        for k, box in enumerate(ndimage.find_objects(lab)):  # scipy numbers regions in raster order too
            ys, xs = np.nonzero(lab == k + 1)
            area = len(ys)
            assert abs(stats[k, 0]) == area
            assert tuple(stats[k, 1:5]) == (box[1].start, box[0].start, box[1].stop - 1, box[0].stop - 1)
            w, h = box[1].stop - box[1].start, box[0].stop - box[0].start
            if area < 3 or min(w, h) < 2:
                assert stats[k, 0] < 0
                continue
            q = _quad_by_pixels(ys, xs)
            side = [(q[2, 0] - q[0, 0]) * (p[1] - q[0, 1]) - (q[2, 1] - q[0, 1]) * (p[0] - q[0, 0]) for p in q[[1, 3]]]
            if (max(w, h) <= 8 * min(w, h) and 5 * area >= w * h and side[0] > 0 > side[1]
                    and abs(_shoelace(q)) >= 0.6 * area):
                assert stats[k, 5] == 0 and stats[k, 0] > 0
                np.testing.assert_array_equal(quads[k], q)
                continue
            if len(np.unique(np.c_[xs, ys] @ [1.0, 1e-3])) < 4 or np.linalg.matrix_rank(np.c_[xs - xs[0], ys - ys[0]]) < 2:
                continue  # collinear or too few pixels for a hull of four corners
            best, hull = _hull_quad_by_brute_force(ys, xs)
            keep = area >= 0.35 * best and best >= 0.6 * area
            assert (stats[k, 0] > 0) == keep and stats[k, 5] == int(keep), (trial, k, area, best)
            if keep:
                n_hull += 1
                assert abs(abs(_shoelace(quads[k])) - best) < 1e-9
                assert all(np.any(np.all(hull == c, axis=1)) for c in quads[k])  # on the hull's corners
    assert n_hull >= 20


def test_mask_quads_are_the_regions_quads_that_hold_their_region():
    """The quads a mask gives (kernel mask_quads) against the regions' own (region_quads),
    filtered in NumPy: a region with a quad that spans 0.6 of its area, its box at most 8
    times longer than wide unless the quad is its hull's; turned clockwise where it ran the
    other way (positive shoelace area, y down), in the regions' order."""
    from scipy import ndimage

    from camkit._kernels.markers import mask_quads, region_quads

    rng = np.random.default_rng(8)
    kept = turned = 0
    for trial in range(40):
        H, W = rng.integers(20, 120, 2)
        m = rng.random((H, W)) < rng.uniform(0.2, 0.7)
        if trial % 2:
            m = ndimage.binary_opening(m)
        stats, quads = region_quads(m, 4, H * W // 4, 2)
        x, y = quads[..., 0], quads[..., 1]
        area2 = (x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1)
        w, h = stats[:, 3] - stats[:, 1] + 1, stats[:, 4] - stats[:, 2] + 1
        ok = ((stats[:, 0] > 0) & ((stats[:, 5] == 1) | (np.maximum(w, h) <= 8 * np.minimum(w, h)))
              & (np.abs(area2) / 2 >= 0.6 * stats[:, 0]))
        want = np.where((area2 > 0)[:, None, None], quads, quads[:, ::-1])[ok]
        got = mask_quads(m, 4, H * W // 4, 2)
        np.testing.assert_array_equal(got, want)
        kept += len(got)
        turned += int((area2[ok] <= 0).sum())
    assert kept >= 200 and turned >= 20


def test_a_saddles_residuals_follow_the_noise_and_its_sigma_the_contrast_too():
    """The saddle fit's residuals (``refine_patches(..., residuals=True)``) measure how well a
    quadratic describes the window, not how sharply the junction's contrast fixes its saddle:
    the same X-junction (one the window's quadratic describes, so that the residuals are the
    noise's) at a third of the contrast under the same noise leaves residuals as large
    (within 25 %) while its sigma grows about threefold. A low-contrast
    corner that fits as well as the others is kept on its residuals (TypicalSigma.passes with
    ``res``) where its sigma alone would call it poor, and not past the sigma cap."""
    from camkit.target._markers import MAX_LOW_CONTRAST_SIGMA, TypicalSigma, refine_patches

    rng = np.random.default_rng(5)
    yy, xx = np.mgrid[0:60, 0:60].astype(float)
    centres = rng.uniform(24, 36, (40, 2))
    res, sig = {}, {}
    for contrast in (0.6, 0.2):
        r_all, s_all = [], []
        for c in centres:
            g = 0.5 + 0.5 * contrast * np.tanh((xx - c[0]) * (yy - c[1]) / 12.0)
            g = g + rng.normal(0, 0.02, g.shape)
            q, s, rr = refine_patches(g, c[None] + 0.3, 2, 1.0, residuals=True)
            assert np.hypot(*(q[0] - c)) < 1.0
            r_all.append(rr[0])
            s_all.append(s[0])
        res[contrast], sig[contrast] = np.median(r_all), np.median(s_all)
    assert 0.8 < res[0.2] / res[0.6] < 1.25, res
    assert sig[0.2] / sig[0.6] > 2.2, sig
    # The typical fit: the high-contrast corners (window 2, smoothing 1).
    g = 0.5 + 0.3 * np.tanh((xx - 30.2) * (yy - 29.7) / 12.0) + rng.normal(0, 0.02, xx.shape)
    pts = np.array([[30.2, 29.7]])
    typ = TypicalSigma(g, pts, np.array([sig[0.6]]), np.array([2]), lambda r: 1.0)
    low = np.array([sig[0.2]])
    one = np.array([2])
    assert not typ.passes(low, one, 2.0)
    assert typ.passes(low, one, 2.0, res=np.array([res[0.2]]))
    assert not typ.passes(low, one, 2.0, res=np.array([3 * res[0.6]]))  # residuals as poor
    assert not typ.passes(np.array([MAX_LOW_CONTRAST_SIGMA * 1.01]), one, 2.0, res=np.array([res[0.2]]))


def test_the_noise_sigma_is_the_scatter_white_noise_gives_the_saddle_fit():
    """``noise_sigma`` turns a fit's own sigma into the one white noise of a known level gives
    it (through the smoothing's correlation): over 300 noisy copies of one junction its median
    is the fitted saddles' scatter (RMS per axis) within 20 %, for two windows and smoothings.
    On a noise-free, sharp junction whose lines meet at 35 degrees, the quadratic's misfit
    makes the fit's own sigma over three times its error, and the sigma the image's rounding
    gives is under a tenth of it (beside ChArUco markers the misfit is larger still:
    test_charuco's view 89)."""
    from scipy.ndimage import gaussian_filter

    from camkit.target._markers import image_noise, noise_sigma, refine_patches

    rng = np.random.default_rng(11)
    yy, xx = np.mgrid[0:60, 0:60].astype(float)
    c = np.array([30.3, 29.6])
    clean = 0.5 + 0.3 * np.tanh((xx - c[0]) * (yy - c[1]) / 12.0)
    for r, sm in ((2, 1.0), (3, 1.5)):
        q, s, res = [], [], []
        for _ in range(300):
            qq, ss, rr = refine_patches(clean + rng.normal(0, 0.02, clean.shape), c[None], r, sm, residuals=True)
            q.append(qq[0]), s.append(ss[0]), res.append(rr[0])
        q, s, res = np.array(q), np.array(s), np.array(res)
        scatter = np.sqrt(0.5 * ((q - q.mean(axis=0)) ** 2).sum(axis=1).mean())
        predicted = float(np.median(noise_sigma(s, res, r, sm, 0.02)))
        assert 0.8 < predicted / scatter < 1.2, (r, sm, predicted, scatter)
    # A sharp junction, lines at 35 degrees, rendered 8x supersampled and rounded to 8 bits.
    ss = 8
    y8, x8 = (np.mgrid[0:60 * ss, 0:60 * ss] + 0.5) / ss - 0.5
    a1, a2 = np.radians(20.0), np.radians(55.0)
    side = np.sign((x8 - c[0]) * np.sin(a1) - (y8 - c[1]) * np.cos(a1)) * np.sign(
        (x8 - c[0]) * np.sin(a2) - (y8 - c[1]) * np.cos(a2))
    g = gaussian_filter((0.5 + 0.4 * side).reshape(60, ss, 60, ss).mean(axis=(1, 3)), 0.7)
    g = np.round(g * 255) / 255
    qq, s, rr = refine_patches(g, c[None] + 0.2, 2, 1.0, residuals=True)
    err = float(np.hypot(*(qq[0] - c)))
    assert s[0] > 3 * err, (s[0], err)
    held = noise_sigma(s, rr, 2, 1.0, image_noise(g))
    assert held[0] < 0.1 * s[0], (held, s)


def test_the_division_model_undoes_itself_and_is_fitzgibbons():
    """:func:`undistort` is Fitzgibbon's one-parameter division model (CVPR 2001, eq. 3:
    undistorted = distorted / (1 + lambda r^2)) about the image's middle, r in half diagonals;
    :func:`distort` is its inverse, for barrel and pincushion strengths."""
    shape = (480, 640)  # half diagonal 400 px, middle (319.5, 239.5)
    p = np.array([[319.5 + 200.0, 239.5], [319.5, 239.5], [0.0, 0.0], [639.0, 479.0]])
    # A point half a half-diagonal out: r = 0.5, so bend -1 puts it at 0.5 / 0.75 = 2/3.
    np.testing.assert_allclose(undistort(p[:1], -1.0, shape), [[319.5 + 400.0 * 2.0 / 3.0, 239.5]])
    np.testing.assert_allclose(undistort(p, 0.0, shape), p)
    for bend in (-0.9, -0.3, 0.4, 0.9):
        np.testing.assert_allclose(distort(undistort(p, bend, shape), bend, shape), p, atol=1e-9)
    # Past either model's reach (|bend| r^2 >= 1, where it folds back): NaN, not a wrong pixel.
    for bend in (-2.5, 2.0):
        assert np.isnan(undistort(p[2:], bend, shape)).all()
        np.testing.assert_allclose(distort(undistort(p[:2], bend, shape), bend, shape), p[:2], atol=1e-9)
    assert np.isnan(distort(np.array([[319.5 + 4000.0, 239.5]]), 0.5, shape)).all()


def test_the_cells_are_read_in_one_kernel_as_sampled_one_by_one():
    """read_cells (projection, bilinear samples, the cells' means, the margin's median) against
    the same reading in NumPy: each point through its homography, sampled by _sample, the
    means and median taken by NumPy; on a float image and on a RawGrey (its stretch applied
    per sample), quads at random and one whose homography sends points to infinity (NaN)."""
    from camkit._kernels import markers as mk
    from camkit.target._markers import RawGrey
    from camkit.target.checkerboard import _sample

    rng = np.random.default_rng(3)
    raw = rng.integers(0, 256, (120, 160), dtype=np.uint8)
    n, m = 8, 9
    g, o = np.mgrid[0:n, 0:n]
    mid = np.array([0.3, 0.5, 0.7])
    ov, ou = np.meshgrid(mid, mid, indexing="ij")
    cells = np.stack([(o[:, :, None] + ou.ravel()).ravel(), (g[:, :, None] + ov.ravel()).ravel()], axis=-1)
    pts = np.concatenate([cells, [[n / 2, -0.5], [n + 0.5, n / 2], [n / 2, n + 0.5], [-0.5, n / 2]]])
    unit = np.array([[0.0, 0.0], [n, 0.0], [n, n], [0.0, n]])
    quads = unit * rng.uniform(2, 6, (30, 1, 1)) + rng.uniform(-10, 150, (30, 1, 2)) + rng.normal(0, 2, (30, 4, 2))
    Hs = fit_homographies(np.broadcast_to(unit, quads.shape), quads)
    Hs[0] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, -4.0]]  # x = 4 (two margin points) to infinity
    for img, a, b in ((raw.astype(np.float64) / 255.0, 1.0, 0.0), (raw, 0.7 / 255.0, -0.1)):
        cell, white = np.empty((len(Hs), n * n)), np.empty(len(Hs))
        mk.read_cells(img, a, b, Hs, pts, n * n, m, cell, white)
        p = (Hs @ np.c_[pts, np.ones(len(pts))].T).transpose(0, 2, 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            px = p[:, :, :2] / p[:, :, 2:]
        ok = np.isfinite(px).all(axis=(1, 2))
        grey = RawGrey(img, a, b) if img.dtype == np.uint8 else img
        vals = _sample(grey, px[ok, :, 0], px[ok, :, 1], "bilinear")
        np.testing.assert_allclose(cell[ok], vals[:, :n * n * m].reshape(-1, n * n, m).mean(axis=2), rtol=0,
                                   atol=1e-12)
        np.testing.assert_allclose(white[ok], np.median(vals[:, n * n * m:], axis=1), rtol=0, atol=1e-12)
        assert not ok[0] and np.isnan(white[0])  # a margin's point at infinity: no median


def test_the_marker_pyramid_makes_only_the_levels_read_and_each_as_halving_does():
    """find_markers' pyramid: a 12 MP image's coarsest level (two halvings) made in one pass
    without the half level, bit for bit as _half twice (uint8 through its stretch, and float),
    on odd sizes too; the half level made only when asked for, from the full image."""
    from camkit.target._markers import MARKER_LEVEL_SIDE, RawGrey, _Pyramid
    from camkit.target.checkerboard import _half

    rng = np.random.default_rng(4)
    for shape in ((3000, 4000), (3001, 4003), (6001, 8002)):
        raw = rng.integers(0, 256, shape, dtype=np.uint8)
        for full in (RawGrey(raw, 1.3 / 255.0, -0.2), raw / 255.0):
            pyr = _Pyramid(full)
            side, levels = max(shape), 1
            while side > MARKER_LEVEL_SIDE:
                side //= 2
                levels += 1
            assert len(pyr) == levels
            coarse = pyr.level(len(pyr) - 1)
            assert 1 not in pyr._levels  # the half level was not made
            ref = full
            for _ in range(len(pyr) - 1):
                ref = _half(ref)
            np.testing.assert_array_equal(coarse, ref)
            np.testing.assert_array_equal(pyr.level(1), _half(full))


def test_quads_found_on_threads_side_by_side_are_those_found_one_by_one():
    """find_quads keeps its integral image and masks between calls, per thread: detections run
    on threads side by side (as Dask's threaded scheduler runs them) find the same quads as
    one by one, images of different sizes interleaved (a buffer kept from a larger image
    serves a smaller one), the opened masks of an AprilGrid too."""
    from concurrent.futures import ThreadPoolExecutor

    from camkit.target._markers import find_quads

    rng = np.random.default_rng(8)
    imgs = []
    for shape in ((240, 320), (480, 640), (200, 260), (480, 640)):
        img = np.full(shape, 0.9)
        for _ in range(12):  # dark squares of 16-40 px
            s = int(rng.integers(16, 40))
            y, x = int(rng.integers(0, shape[0] - s)), int(rng.integers(0, shape[1] - s))
            img[y:y + s, x:x + s] = 0.1
        imgs.append(img + rng.normal(0, 0.02, shape))
    jobs = [(img, opening) for img in imgs for opening in (False, True)] * 3
    alone = [find_quads(img, 10, opening=opening) for img, opening in jobs]
    assert all(len(q) >= 5 for q in alone)
    with ThreadPoolExecutor(4) as ex:
        together = list(ex.map(lambda j: find_quads(j[0], 10, opening=j[1]), jobs))
    for a, b in zip(alone, together, strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_masks_are_shared_out_between_the_callers_thread_and_the_pools():
    """find_quads makes and labels its masks side by side (_side_by_side): the results come
    back in the calls' order, and a call that waits for another to start is not left alone
    (a second thread takes the rest)."""
    import threading

    from camkit.target import _markers as mk

    started = threading.Event()
    who: dict[int, int] = {}

    def fn(i: int) -> np.ndarray:
        who[i] = threading.get_ident()
        if i == 0:
            assert started.wait(timeout=30), "no second thread took a call"
        else:
            started.set()
        return np.full(3, i)

    out = mk._side_by_side(fn, 5)
    assert [int(o[0]) for o in out] == list(range(5))
    assert len(set(who.values())) >= 2

    # A call that fails: its error comes back, after every call has ended.
    ended: list[int] = []

    def bad(i: int) -> np.ndarray:
        if i == 2:
            raise ValueError("call 2")
        ended.append(i)
        return np.zeros(1)

    with pytest.raises(ValueError, match="call 2"):
        mk._side_by_side(bad, 6)
    assert sorted(ended) == [0, 1, 3, 4, 5]

    # In two stages: then(i, fn(i)) in the calls' order; every first stage taken before any
    # second, a second stage that waits for its first on another thread; an error in either
    # stage comes back.
    log: list[tuple[str, int]] = []
    took_rest = threading.Event()

    def first(i: int) -> int:
        log.append(("first", i))
        if i == 2:
            took_rest.set()
        if i == 0:  # (the other thread takes the other first stages, then waits for this one)
            assert took_rest.wait(timeout=30), "no second thread took a first stage"
        return 10 * i

    def second(i: int, f: int) -> np.ndarray:
        log.append(("then", i))
        return np.full(2, f + i)

    out = mk._side_by_side(first, 3, then=second)
    assert [int(o[0]) for o in out] == [0, 11, 22]
    assert {e for e in log[:3]} == {("first", 0), ("first", 1), ("first", 2)}
    assert sorted(log[3:]) == [("then", 0), ("then", 1), ("then", 2)]
    for where in ("first", "then"):
        def fail_first(i: int, where: str = where) -> int:
            if where == "first" and i == 1:
                raise ValueError("stage first")
            return i

        def fail_then(i: int, f: int, where: str = where) -> np.ndarray:
            if where == "then" and i == 2:
                raise ValueError("stage then")
            return np.zeros(1)

        with pytest.raises(ValueError, match=f"stage {where}"):
            mk._side_by_side(fail_first, 4, then=fail_then)


def test_the_detection_kernels_serial_twins_give_the_parallel_ones_results_bit_for_bit():
    """Saddle fits, patch blurs, homographies and cell readings run serially where their work is
    small (a parallel loop's wake-up costs more): the serial twin of each kernel gives what the
    parallel one gives, bit for bit, and the dispatcher picks serial for a few points and
    parallel for many."""
    from camkit._kernels import detect as dk
    from camkit._kernels import markers as mk
    from camkit.target.checkerboard import _saddle_design

    rng = np.random.default_rng(6)
    img = rng.random((200, 260))
    r, iters = 4, 6
    pinv, cvar = _saddle_design(r)
    pts = rng.uniform(20, 180, (40, 2))
    outs = []
    for kern in (dk._saddle_fit_serial, dk._saddle_fit_parallel):
        q, sg, rs = np.empty((40, 2)), np.empty(40), np.empty(40)
        kern(img, pts, r, iters, pinv, cvar, q, sg, rs)
        outs.append((q, sg, rs))
    origin = rng.integers(-5, 190, (12, 2))
    tile = np.stack([np.arange(12) * 21, np.zeros(12, np.int64)], axis=1)
    for kern in (dk._blur_patches_serial, dk._blur_patches_parallel):
        mosaic = np.zeros((21, 21 * 12))
        kern(img, origin, tile, 21, 2.0, mosaic)
        outs.append((mosaic,))
    src = rng.random((30, 6, 2)) * 50
    for kern in (mk._fit_homographies_serial, mk._fit_homographies_parallel):
        h = np.empty((30, 3, 3))
        kern(src, src @ [[1.1, 0.1], [-0.05, 0.9]] + 7.0, h)
        outs.append((h,))
    Hs = np.tile(np.eye(3), (25, 1, 1))
    Hs[:, :2, 2] = rng.uniform(10, 150, (25, 2))
    cells_at = rng.random((68, 2)) * 8
    for kern in (mk._read_cells_serial, mk._read_cells_parallel):
        cell, white = np.empty((25, 64)), np.empty(25)
        kern(img, 1.0, 0.0, Hs, cells_at, 64, 1, cell, white)
        outs.append((cell, white))
    for serial, parallel in zip(outs[::2], outs[1::2], strict=True):
        for a, b in zip(serial, parallel, strict=True):
            np.testing.assert_array_equal(a, b)
    # The dispatch: few points serial, many parallel.
    calls = []
    orig = dk._saddle_fit_serial, dk._saddle_fit_parallel
    try:
        dk._saddle_fit_serial = lambda *a: calls.append("serial")
        dk._saddle_fit_parallel = lambda *a: calls.append("parallel")
        for n in (3, 3000):
            p = np.zeros((n, 2))
            dk.saddle_fit(img, p, r, iters, pinv, cvar, p.copy(), np.empty(n), np.empty(n))
    finally:
        dk._saddle_fit_serial, dk._saddle_fit_parallel = orig
    assert calls == ["serial", "parallel"]


def test_the_dark_mask_is_the_pixels_under_their_windows_clipped_mean():
    """dark_mask (and the integral image, bit for bit its row recurrence) against its definition
    in NumPy: each pixel against the mean of g over its (2r+1)^2 window clipped at the image's
    borders, less c; windows inside a row (the kernel's vectorised loop) and clipped ones, radii
    from 1 to wider than the image."""
    from camkit._kernels import markers as mk

    rng = np.random.default_rng(9)
    for H, W in ((37, 53), (60, 8)):
        g = rng.random((H, W))
        ii = np.empty((H + 1, W + 1))
        mk.integral(g, ii)
        np.testing.assert_allclose(ii[1:, 1:], g.cumsum(0).cumsum(1), rtol=1e-12)
        # Bit for bit the one-row recurrence (the kernel runs four rows side by side).
        want = np.zeros((H + 1, W + 1))
        for y in range(H):
            want[y + 1, 1:] = want[y, 1:] + np.cumsum(g[y])  # (cumsum adds in order, as the kernel)
        np.testing.assert_array_equal(ii, want)
        ys, xs = np.mgrid[0:H, 0:W]
        for r in (1, 3, 10, 70):
            y0, y1 = np.maximum(ys - r, 0), np.minimum(ys + r + 1, H)
            x0, x1 = np.maximum(xs - r, 0), np.minimum(xs + r + 1, W)
            mean = np.array([[g[a:b, c:d].mean() for a, b, c, d in zip(*row, strict=True)]
                             for row in zip(y0, y1, x0, x1, strict=True)])
            out = np.empty((H, W), dtype=bool)
            mk.dark_mask(g, ii, r, 0.05, out)
            sure = np.abs(g - (mean - 0.05)) > 1e-9  # (a tie's side is the rounding's)
            np.testing.assert_array_equal(out[sure], (g < mean - 0.05)[sure])


def test_a_masks_runs_are_its_rows_changes_and_their_quads_the_masks():
    """mask_runs against the runs NumPy finds from each row's changes (rows that start or end
    set, rows wholly set or clear, one column, noise's many short runs), and runs_quads on
    them against mask_quads on the mask."""
    from camkit._kernels import markers as mk

    rng = np.random.default_rng(12)
    n_runs = 0
    for H, W, p in ((83, 97, 0.5), (40, 1, 0.5), (30, 64, 0.9), (60, 50, 0.2)):
        m = rng.random((H, W)) < p
        m[3] = True
        m[4] = False
        d = np.diff(np.pad(m, ((0, 0), (1, 1))).astype(np.int8), axis=1)
        ys, starts = np.nonzero(d == 1)
        _, ends = np.nonzero(d == -1)
        n, ry, r0, r1 = mk.mask_runs(m)
        assert n == len(ry) == len(starts)
        np.testing.assert_array_equal(ry, ys)
        np.testing.assert_array_equal(r0, starts)
        np.testing.assert_array_equal(r1, ends - 1)
        np.testing.assert_array_equal(mk.runs_quads(ry, r0, r1, 4, H * W // 4, 2), mk.mask_quads(m, 4, H * W // 4, 2))
        n_runs += n
    assert n_runs > 2000


def test_the_cells_verdicts_are_their_medians_and_thresholds():
    """cell_verdicts and rim_verdicts against their definition in NumPy: the border's median is
    black (NaN where a cell is), the threshold halfway to the margin; a marker's border 0.85
    dark and 0.15 darker than the margin, the code's bits above the threshold; rimmed where
    the border is 0.6 dark, ``rim_contrast`` darker, and a code cell lit. Cells near their
    threshold, borders of one and two cells, rows not read (``ok`` False) and NaN margins."""
    from camkit._kernels import markers as mk

    rng = np.random.default_rng(31)
    for n, border in ((7, 1), (10, 2)):
        K = 400
        inner = np.zeros((n, n), dtype=bool)
        inner[border:-border, border:-border] = True
        cell = rng.uniform(0.6, 1.0, (K, n, n))
        dark_rim = rng.random((K, n, n)) < rng.uniform(0.5, 1.0, (K, 1, 1))
        cell[dark_rim & ~inner] = rng.uniform(0.0, 0.4, int((dark_rim & ~inner).sum()))
        cell[: K // 4, inner] = 0.05  # black squares: no code cell lit
        white = rng.uniform(0.3, 1.0, K)
        white[::37] = np.nan
        cell[5, 0, 0] = np.nan
        ok = rng.random(K) > 0.1
        rim = cell[:, ~inner]
        black = np.median(rim, axis=1)
        t = 0.5 * (white + black)
        with np.errstate(invalid="ignore"):
            dark = np.mean(rim < t[:, None], axis=1)
            contrast = ok & np.isfinite(white) & (white - black > 0.15)
            want_good = contrast & (dark >= 0.85)
            want_rimmed = contrast & (white - black > 0.3) & (dark >= 0.6) & (cell[:, inner] > t[:, None]).any(axis=1)
            want_bits = (cell[:, inner] > t[:, None]).astype(np.uint8)
        good, rimmed = np.empty(K, dtype=bool), np.empty(K, dtype=bool)
        bits = np.empty((K, (n - 2 * border) ** 2), dtype=np.uint8)
        mk.cell_verdicts(cell.reshape(K, n * n), white, ok, n, border, 0.3, 0.6, good, rimmed, bits)
        np.testing.assert_array_equal(good, want_good)
        np.testing.assert_array_equal(rimmed, want_rimmed)
        np.testing.assert_array_equal(bits[good], want_bits[good])
        assert 50 < good.sum() < K - 50 and 50 < rimmed.sum() and not good[5]
        vals = np.ascontiguousarray(rim)
        out = np.empty(K, dtype=bool)
        mk.rim_verdicts(vals, white, ok, 0.2, 0.6, out)
        with np.errstate(invalid="ignore"):
            np.testing.assert_array_equal(out, ok & (white - black > 0.2) & (dark >= 0.6))
        assert 50 < out.sum() < K - 50


def test_the_grey_and_its_integral_made_in_one_pass_are_those_made_apart():
    """grey_integral (the stretched grey of an 8-bit image and its integral image in one pass)
    gives grey_mean's grey and integral's integral bit for bit, on heights that are and are
    not a multiple of its four rows; and a RawGrey's dense grey asked for with its integral
    (made in that pass, or from the grey made before) is the same."""
    from camkit._kernels import detect as dk
    from camkit._kernels import markers as mk
    from camkit.target.checkerboard import _to_grey

    rng = np.random.default_rng(14)
    for H, W in ((37, 53), (40, 8), (3, 90), (1, 1)):
        raw = rng.integers(0, 256, (H, W), dtype=np.uint8)
        lo, inv = 13.7 / 255.0, 255.0 / 211.3
        want_g, want_ii = np.empty((H, W)), np.empty((H + 1, W + 1))
        dk.grey_mean(raw[:, :, None], 1.0, lo, inv, want_g)
        mk.integral(want_g, want_ii)
        g, ii = np.full((H, W), np.nan), np.full((H + 1, W + 1), np.nan)
        mk.grey_integral(raw, lo, inv, g, ii)
        np.testing.assert_array_equal(g, want_g)
        np.testing.assert_array_equal(ii, want_ii)
    raw = rng.integers(20, 230, (61, 75), dtype=np.uint8)
    ii1, ii2 = np.empty((62, 76)), np.empty((62, 76))
    g1 = _to_grey(raw, lazy=True).dense(integral=ii1).copy()  # in one pass
    lazy = _to_grey(raw, lazy=True)
    g2 = lazy.dense().copy()
    lazy.dense(integral=ii2)  # from the grey made before
    np.testing.assert_array_equal(g1, g2)
    np.testing.assert_array_equal(ii1, ii2)
    np.testing.assert_allclose(g1, _to_grey(raw), rtol=0, atol=1e-12)  # (the eager grey: its own rounding)


def test_the_buffers_kept_per_thread_stay_under_their_bound():
    """find_quads' work arrays (and a detection's dense grey) are kept per thread up to
    SCRATCH_MAX_BYTES in all: asked for more (a 12 MP image read at full resolution), they are
    made afresh and not kept; each name is its own memory."""
    import threading

    from camkit import _alloc as al

    def kept() -> int:
        return sum(b.size for b in getattr(al._SCRATCH, "bufs", {}).values())

    def work(out: list) -> None:
        a = al.scratch("integral", (481, 641), np.float64)
        b = al.scratch("mask0", (480, 640), np.bool_)
        a[:] = 1.0
        b[:] = False
        assert a.shape == (481, 641) and b.shape == (480, 640) and (a == 1.0).all()  # no overlap
        big = [al.scratch(f"mask{i}", (3000, 4000), np.bool_) for i in range(1, 4)]
        ii = al.scratch("integral", (3001, 4001), np.float64)
        assert all(m.shape == (3000, 4000) for m in big) and ii.shape == (3001, 4001)
        out.append(kept())

    sizes: list = []
    t = threading.Thread(target=work, args=(sizes,))  # a fresh thread: its own, empty buffers
    t.start()
    t.join()
    assert 0 < sizes[0] <= al.SCRATCH_MAX_BYTES


def test_the_x_junction_kernels_judge_the_shades_as_numpy_does():
    """x_corner_shades and x_shades (kernels x_junctions, x_verdicts) against their definition in
    NumPy, bit for bit: 32 bilinear shades on the circle (a RawGrey stretched after sampling),
    four crossings of their mean, a contrast over 0.15, opposite shades alike within a quarter
    of it, and the middle of the darkest and brightest; a NaN shade is no junction."""
    from camkit.target._markers import x_corner_shades, x_shades
    from camkit.target.checkerboard import RawGrey, _sample

    def numpy_shades(v):
        sign = v > v.mean(axis=1, keepdims=True)
        changes = (sign != np.roll(sign, 1, axis=1)).sum(axis=1)
        lo, hi = v.min(axis=1), v.max(axis=1)
        sym = np.abs(v - np.roll(v, 16, axis=1)).mean(axis=1) / np.maximum(hi - lo, 1e-12)
        return (changes == 4) & (hi - lo > 0.15) & (sym < 0.25), 0.5 * (lo + hi)

    rng = np.random.default_rng(12)
    yy, xx = np.mgrid[0:60, 0:70]
    n_x = 0
    for _ in range(20):
        cx, cy, ang = rng.uniform(10, 60), rng.uniform(10, 50), rng.uniform(0, np.pi)
        u, w = np.cos(ang) * (xx - cx) + np.sin(ang) * (yy - cy), -np.sin(ang) * (xx - cx) + np.cos(ang) * (yy - cy)
        img = ((u > 0) ^ (w > 0)) * rng.uniform(0.2, 1.0) + rng.normal(0.0, rng.uniform(0.0, 0.2), xx.shape)
        for g in (img, RawGrey(np.clip(img * 200 + 20, 0, 255).astype(np.uint8), 1 / 200, -0.1)):
            pts = np.stack([rng.uniform(-5, 75, 40), rng.uniform(-5, 65, 40)], axis=1)
            pts[:5] = cx, cy
            rho = rng.uniform(1.5, 8.0, 40)
            ang32 = np.arange(32) * 2 * np.pi / 32
            want = numpy_shades(_sample(g, pts[:, :1] + rho[:, None] * np.cos(ang32),
                                        pts[:, 1:] + rho[:, None] * np.sin(ang32), "bilinear"))
            got = x_corner_shades(g, pts, rho)
            np.testing.assert_array_equal(got[0], want[0])
            np.testing.assert_array_equal(got[1], want[1])
            n_x += int(got[0].sum())
    assert n_x > 100  # junctions judged as such, not only refusals
    v = rng.normal(size=(50, 32))
    v[3, 5] = np.nan
    got, want = x_shades(v), numpy_shades(v)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert not got[0][3] and np.isnan(got[1][3])


def test_the_pairs_votes_are_those_of_each_pairs_homography_misfit():
    """_pair_votes (kernel pair_votes) against its definition in NumPy: each pair of markers
    within two places of each other fitted by one homography through their eight corners
    (fit_homographies), the pair fitting where its worst miss is under 2 px times the level's
    factor or 0.15 of the smaller pitch; a misplaced marker and a collapsed one (no
    homography: inf) among them."""
    from camkit.target import Charuco
    from camkit.target._homography import apply_homographies, fit_homographies
    from camkit.target._markers import _pair_votes
    from camkit.target.charuco import _layout

    def numpy_votes(found, obj, grid, ids, pitch, factor):
        agree, disagree = np.zeros(len(ids), dtype=np.int64), np.zeros(len(ids), dtype=np.int64)
        g = grid[ids]
        a, j = np.nonzero(np.triu(np.abs(g[:, None] - g[None]).max(axis=2) <= 2, k=1))
        src = np.concatenate([obj[ids][a], obj[ids][j]], axis=1)
        img = np.stack([found[m][0] for m in ids])
        dst = np.concatenate([img[a], img[j]], axis=1)
        with np.errstate(invalid="ignore"):
            miss = np.hypot(*(apply_homographies(fit_homographies(src, dst), src) - dst).transpose(2, 0, 1)).max(axis=1)
        worst = np.where(np.isfinite(miss), miss, np.inf)
        p = np.array([pitch[m] for m in ids])
        fits = worst < np.maximum(2.0 * factor, 0.15 * np.minimum(p[a], p[j]))
        for both in (a, j):
            np.add.at(agree, both[fits], 1)
            np.add.at(disagree, both[~fits], 1)
        return agree, disagree

    rng = np.random.default_rng(3)
    totals = np.zeros(2, dtype=np.int64)
    for t in range(60):
        board = Charuco(int(rng.integers(3, 12)), int(rng.integers(3, 10)), 0.04, 0.03, "DICT_6X6_250")
        grid, obj, _ = _layout(board)
        H = np.array([[800.0, rng.normal(0, 50), 100.0], [rng.normal(0, 50), 800.0, 80.0],
                      [rng.normal(0, 2), rng.normal(0, 2), 1.0]])
        img = apply_homographies(np.broadcast_to(H, (len(obj), 3, 3)).copy(), obj)
        img += rng.normal(0.0, rng.uniform(0.1, 3.0), img.shape)
        ids = [int(m) for m in rng.permutation(len(obj))[:rng.integers(2, len(obj) + 1)]]
        found = {m: [img[m]] for m in ids}
        if t % 5 == 0 and len(ids) > 2:
            found[ids[1]] = [img[ids[0]]]  # a marker read in another's place
        if t % 7 == 0:
            found[ids[0]] = [np.full((4, 2), 5.0)]  # a quad of one point
        pitch = {m: float(rng.uniform(5.0, 40.0)) for m in ids}
        factor = int(rng.integers(1, 3))
        got = _pair_votes(found, obj, grid, ids, pitch, factor)
        want = numpy_votes(found, obj, grid, ids, pitch, factor)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
        totals += [want[0].sum(), want[1].sum()]
    assert (totals > 500).all()  # pairs that fit and pairs that do not
