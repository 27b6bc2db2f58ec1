"""Hard views for checkerboard detectors, with exact truth: the stress corpus of issue 21.

:func:`stress_view` draws one view from a seed: a camera of 0.1-24 MP (pinhole, Brown-Conrady
barrel or pincushion, Kannala-Brandt fisheye), a board of 3-12 by 3-10 inner corners (either
parity, printed either way round: a colour-inverted print is a board seen from behind; a white
margin of 0.1-1.5 squares round the squares), a pose
tilted up to 70 degrees with squares of 10-250 px, sometimes partly outside the frame; motion
blur and Gaussian blur, vignetting and uneven light, backlight (the board in shade beside a bright
window), clutter behind the board (smooth texture,
tiles, text, a second board of another size), finger-like occluders over it, sensor noise and
JPEG compression (quality 40-95, through Pillow). Everything is drawn from
``numpy.random.default_rng(seed)`` (the margin and the backlight from streams of their own,
``default_rng([seed, 7])`` and ``default_rng([seed, 21])``), so a seed names a view.

The truth says which corners can be seen (inside the frame, not under an occluder) and which
labellings of the board are right: a detector sees the printed face, so its labels are
right-handed in the image, and the colours of the squares fix the rest except where the board
is symmetric in colour (then every labelling that keeps the colours is right).
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camkit._repr import summary_repr
from camkit._validate import as_points, as_positive_float
from camkit.errors import ParameterError, ShapeError
from camkit.geometry import Pose
from camkit.geometry.rotation import matrix_from_rvec
from camkit.lens.base import CameraModel
from camkit.target import Checkerboard

__all__ = ["StressView", "acceptable_labellings", "stress_view"]


@dataclass(frozen=True, slots=True, eq=False)
class StressView:
    """One view of the stress corpus.

    Attributes
    ----------
    image : ndarray, uint8, (H, W) or (H, W, 3)
    board : Checkerboard
    camera : CameraModel
    corners_px : ndarray, (N, 2)
        Every inner corner's true position (the pose at the middle of the exposure), in the
        order of ``board.object_points()`` (NaN where not projectable).
    visible : ndarray, (N,) bool
        Inside the frame and not under an occluder (nor within half a square of one).
    labellings : tuple of ndarray
        Index permutations ``p`` such that returning ``corners_px[p]`` is right: ``p[k]`` is
        the true corner that label ``k`` may carry.
    square_px : float
        The median distance between neighbouring corners in the image.
    blur_sigma_px : float
        Gaussian blur applied (0 for none), besides motion.
    motion_px : float
        Length of the motion blur at the board's centre (0 for none).
    noise : float
        Standard deviation of the added noise (reflectance units).
    jpeg_quality : int or None
    tags : dict
        What was drawn (lens, occluders, distractors, inverted print, partial view, ...).
    obliquity_deg : float
        The angle between the board's normal and the line of sight to the board's centre
        (0: seen square on; 90: edge on). The pose's tilt is drawn about the camera's axis, so a
        board placed off the axis of a wide lens is seen more obliquely than its tilt.
    """

    image: np.ndarray
    board: Checkerboard
    camera: CameraModel
    corners_px: np.ndarray
    visible: np.ndarray
    labellings: tuple[np.ndarray, ...]
    square_px: float
    blur_sigma_px: float
    motion_px: float
    noise: float
    jpeg_quality: int | None
    tags: dict[str, Any] = field(default_factory=dict)
    obliquity_deg: float = 0.0

    def __repr__(self) -> str:
        return summary_repr(self)

    @property
    def whole(self) -> bool:
        """Every corner of the board can be seen."""
        return bool(self.visible.all())


def _lattice_ops(rows: int, cols: int) -> list[Any]:
    ops = [lambda a: a, lambda a: a[::-1, ::-1], lambda a: a[:, ::-1], lambda a: a[::-1, :]]
    if rows == cols:
        ops += [lambda a, f=f: f(a).T for f in ops]
    return ops


def acceptable_labellings(board: Checkerboard, corners_px: np.ndarray) -> tuple[np.ndarray, ...]:
    """The labellings of a view that a detector may return (see the module's text): the board
    symmetries whose labels are right-handed in the image and keep square (0, 0)'s colour black
    as :class:`Checkerboard` defines it; where none does (a colour-inverted print of a board
    whose colours no turn restores), the right-handed ones that keep the colours consistent."""
    if not isinstance(board, Checkerboard):
        raise ParameterError(f"board: expected a Checkerboard, got {type(board).__name__}")
    cols, rows = board.inner_cols, board.inner_rows
    pts = as_points(corners_px, 2, "corners_px", nan_rows=True)
    if pts.shape != (cols * rows, 2) or not np.isfinite(pts).all(axis=1).any():
        raise ShapeError(f"corners_px: expected ({cols * rows}, 2) positions of the board's corners, some finite, "
                         f"got shape {pts.shape}")
    grid = np.arange(cols * rows).reshape(rows, cols)
    a, b = np.meshgrid(np.arange(-1, cols), np.arange(-1, rows))
    black = (a + b) % 2 == 0  # squares (b + 1, a + 1), as the renderer colours them
    right, keep = [], []
    for op in _lattice_ops(rows, cols):
        perm = op(grid)
        P = pts[perm]
        ex = np.nanmean(np.diff(P, axis=1).reshape(-1, 2), axis=0)
        ey = np.nanmean(np.diff(P, axis=0).reshape(-1, 2), axis=0)
        if ex[0] * ey[1] - ex[1] * ey[0] <= 0:
            continue
        right.append(perm.ravel())
        if op(black)[0, 0]:
            keep.append(perm.ravel())
    return tuple(keep if keep else right)


def _camera(rng: np.random.Generator, megapixels: tuple[float, float]) -> tuple[CameraModel, str]:
    from camkit.lens import BrownConrady, KannalaBrandt, Pinhole

    mp = float(np.exp(rng.uniform(np.log(megapixels[0]), np.log(megapixels[1]))))
    aspect = float(rng.choice([4 / 3, 3 / 2, 16 / 9, 1.0]))
    W = max(round(float(np.sqrt(mp * 1e6 * aspect))), 32)
    H = max(round(W / aspect), 32)
    cx, cy = (W - 1) / 2 + rng.normal(0, 0.01 * W), (H - 1) / 2 + rng.normal(0, 0.01 * H)
    kind = str(rng.choice(["pinhole", "barrel", "pincushion", "fisheye"], p=[0.2, 0.4, 0.15, 0.25]))
    if kind == "fisheye":
        theta = rng.uniform(0.9, 1.5)  # half the horizontal field of view, radians
        f = (W / 2) / theta
        return KannalaBrandt(fx=f, fy=f, cx=cx, cy=cy, width=W, height=H, k1=rng.uniform(-0.02, 0.03),
                             k2=rng.uniform(-0.005, 0.005)), kind
    fov = np.radians(rng.uniform(40, 95))
    f = (W / 2) / np.tan(fov / 2)
    if kind == "pinhole":
        return Pinhole(fx=f, fy=f, cx=cx, cy=cy, width=W, height=H), kind
    # Distortion sized by the field: at the frame's corner the radial factor stays in 0.7-1.25.
    r2 = ((W / 2) ** 2 + (H / 2) ** 2) / f ** 2
    if kind == "barrel":
        k1 = -rng.uniform(0.05, 0.3) / r2
        k2 = rng.uniform(0.0, 0.5) * k1 * k1
    else:
        k1 = rng.uniform(0.03, 0.2) / r2
        k2 = 0.0
    return BrownConrady(fx=f, fy=f, cx=cx, cy=cy, width=W, height=H, k1=k1, k2=k2,
                        p1=rng.normal(0, 2e-4), p2=rng.normal(0, 2e-4)), kind


def _pose(rng: np.random.Generator, camera: CameraModel, board: Checkerboard, square_px: float,
          partial: bool, back: bool, max_tilt: float = 70.0, centred: bool = False,
          square: float | None = None) -> Pose | None:
    """A pose with squares of about ``square_px`` at the board's centre; every corner inside
    the frame unless ``partial`` (then some are outside); seen from behind if ``back``.
    ``square``: the length that spans ``square_px`` (default the board's square)."""
    pts = board.object_points()
    centre = pts.mean(axis=0)
    W, H = camera.width, camera.height
    for _ in range(60):
        tilt = np.radians(rng.uniform(0, max_tilt))
        phi = rng.uniform(0, 2 * np.pi)
        R = matrix_from_rvec([0.0, 0.0, rng.uniform(-np.pi, np.pi)]) @ matrix_from_rvec(
            tilt * np.array([np.cos(phi), np.sin(phi), 0.0]))
        if back:
            R = R @ matrix_from_rvec([0.0, np.pi, 0.0])
        lo, hi = (0.5, 0.5) if centred else (0.2, 0.8)
        px = np.array([rng.uniform(lo, hi) * (W - 1), rng.uniform(lo, hi) * (H - 1)])
        ray = camera.unproject(px)
        if not np.isfinite(ray).all() or ray[2] <= 0.3:
            continue
        ray = ray / np.linalg.norm(ray)
        f = float(np.sqrt(camera.fx * camera.fy))
        dist = f * (board.square if square is None else square) / square_px
        t = ray * dist - R @ centre
        pose = Pose(R, t)
        cam = pose.apply(pts)
        if (cam[:, 2] <= 0.05 * dist).any():
            continue
        c = camera.project(cam)
        if not np.isfinite(c).all():
            continue
        inside = (c[:, 0] >= 0) & (c[:, 0] <= W - 1) & (c[:, 1] >= 0) & (c[:, 1] <= H - 1)
        if partial:
            if 0.3 <= inside.mean() < 0.95:
                return pose
        else:
            m = 0.01 * min(W, H) + 2
            if ((c[:, 0] > m) & (c[:, 0] < W - 1 - m) & (c[:, 1] > m) & (c[:, 1] < H - 1 - m)).all():
                return pose
    return None


def _blur(img: np.ndarray, sigma: float) -> np.ndarray:
    from camkit._kernels import detect as detect_kernels

    out = np.empty_like(img)
    detect_kernels.gaussian_blur(np.ascontiguousarray(img), float(sigma), out)
    return out


def _smooth_noise(rng: np.random.Generator, H: int, W: int, cells: int) -> np.ndarray:
    """A smooth random field in [0, 1] (bilinear upsampling of a coarse random grid)."""
    from camkit.resample import resize

    g = rng.random((max(cells * H // max(W, H), 2), max(cells * W // max(W, H), 2)))
    return np.clip(resize(g, width=W, height=H, interpolation="bilinear"), 0.0, 1.0)


def _background(rng: np.random.Generator, camera: CameraModel, tags: dict[str, Any]) -> np.ndarray:
    H, W = camera.height, camera.width
    bg = 0.25 + 0.5 * _smooth_noise(rng, H, W, int(rng.integers(2, 12)))
    if rng.random() < 0.2:  # tiles: a grid of dark joints
        step = rng.uniform(0.03, 0.12) * min(W, H)
        yy, xx = np.mgrid[0:H, 0:W]
        ang = rng.uniform(0, np.pi / 2)
        u = xx * np.cos(ang) + yy * np.sin(ang)
        v = -xx * np.sin(ang) + yy * np.cos(ang)
        joint = (np.mod(u, step) < 0.06 * step) | (np.mod(v, step) < 0.06 * step)
        bg = np.where(joint, 0.15, bg)
        tags["tiles"] = True
    if rng.random() < 0.2:  # text
        from PIL import Image, ImageDraw, ImageFont

        im = Image.fromarray((bg * 255).astype(np.uint8))
        draw = ImageDraw.Draw(im)
        size = int(np.clip(rng.uniform(0.02, 0.06) * min(W, H), 8, 200))
        try:
            font = ImageFont.load_default(size=size)
        except TypeError:  # Pillow < 10.1
            font = ImageFont.load_default()
        words = ["calibration", "CAMERA 01", "f/2.8 1/60", "ISO 800", "chessboard 9x6", "#####", "XXXXXX"]
        for _ in range(int(rng.integers(2, 8))):
            draw.text((float(rng.uniform(0, W * 0.8)), float(rng.uniform(0, H * 0.9))),
                      str(rng.choice(words)), fill=int(rng.integers(0, 60)), font=font)
        bg = np.asarray(im, dtype=np.float64) / 255.0
        tags["text"] = True
    return bg


def _segment_distance(x: np.ndarray, y: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of the points (x, y) from the segment a-b (pixels)."""
    ab = b - a
    t = np.clip(((x - a[0]) * ab[0] + (y - a[1]) * ab[1]) / (ab @ ab), 0, 1)
    return np.hypot(x - a[0] - t * ab[0], y - a[1] - t * ab[1])


def _capsule(shape: tuple[int, int], start: np.ndarray, tip: np.ndarray, width: float) -> np.ndarray:
    """Coverage (H, W) in [0, 1] of a finger-like capsule of ``width`` pixels whose axis runs
    from ``start`` to ``tip`` (x, y pixel centres), its edge anti-aliased over one pixel: the
    occluder the stress corpus draws (:func:`_occluders`), and a test places by hand. Only
    the box around the capsule is computed (the rest is 0): a 24 MP view has up to three."""
    a, b = np.asarray(start, float), np.asarray(tip, float)
    reach = width / 2 + 1.5
    x0, y0 = (int(max(np.floor(min(a[k], b[k]) - reach), 0)) for k in (0, 1))
    x1, y1 = (int(min(np.ceil(max(a[k], b[k]) + reach) + 1, shape[1 - k])) for k in (0, 1))
    out = np.zeros(shape[:2])
    if x1 > x0 and y1 > y0:
        yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
        out[y0:y1, x0:x1] = np.clip(width / 2 - _segment_distance(xx, yy, a, b) + 0.5, 0, 1)
    return out


def _occluders(rng: np.random.Generator, corners: np.ndarray, square_px: float, H: int, W: int,
               tags: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """Finger-like capsules reaching over the board from outside it: (alpha (H, W), hidden
    corners (N,) bool)."""
    alpha = np.zeros((H, W))
    hidden = np.zeros(len(corners), dtype=bool)
    ok = np.isfinite(corners).all(axis=1)
    if not ok.any():
        return alpha, hidden
    c = corners[ok]
    lo, hi = c.min(axis=0), c.max(axis=0)
    mid = 0.5 * (lo + hi)
    n = int(rng.integers(1, 4))
    for _ in range(n):
        # A point on the board's outline, and a direction inwards.
        t = rng.uniform(0, 1)
        side = int(rng.integers(0, 4))
        p0 = np.array([lo[0] + t * (hi[0] - lo[0]) if side < 2 else (lo[0] if side == 2 else hi[0]),
                       (lo[1] if side == 0 else hi[1]) if side < 2 else lo[1] + t * (hi[1] - lo[1])])
        d = mid - p0
        d /= max(np.linalg.norm(d), 1e-9)
        length = rng.uniform(1.0, 3.0) * square_px
        width = rng.uniform(0.5, 1.2) * square_px
        a, b = p0 - d * 2 * square_px, p0 + d * length
        alpha = np.maximum(alpha, _capsule((H, W), a, b, width))
        hidden |= _segment_distance(corners[:, 0], corners[:, 1], a, b) < width / 2 + 0.5 * square_px
    tags["occluders"] = n
    return alpha, hidden


def stress_view(seed: int, *, megapixels: tuple[float, float] = (0.1, 24.0),
                square_px: tuple[float, float] = (10.0, 250.0), supersample: int = 16) -> StressView:
    """Draw view number ``seed`` of the stress corpus (see the module's text).

    ``megapixels`` and ``square_px`` bound the image size and the squares' size (a small
    image holds only small squares: the upper bound shrinks until the board fits).
    ``supersample``: samples per pixel side where a pixel crosses an edge
    (:func:`~camkit.render.render_checkerboard`). Each edge pixel's shade is then right to
    about 1/supersample^2 of the contrast, and a corner read from a few such pixels moves by
    as much: at 4 (16 samples), the corners a detector read on the same view moved by up to
    0.15 px from those on a 32x render (views 116 and 384 at up to 2 MP: 95th percentile
    0.12-0.14 px), as much as the error the corpus is there to measure; at 16, by at most
    0.005 px (benchmarks/notes.md, thirty-third session)."""
    from camkit.render.effects import Effects, Motion, render_view

    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError(f"seed: expected a non-negative integer, got {seed!r}")
    bounds = []
    for value, name in ((megapixels, "megapixels"), (square_px, "square_px")):
        if not isinstance(value, (tuple, list)) or len(value) != 2:
            raise ParameterError(f"{name}: expected (low, high), got {value!r}")
        bounds.append([as_positive_float(v, name) for v in value])
    (lo_mp, hi_mp), (lo_sq, hi_sq) = bounds
    if lo_mp > hi_mp or lo_sq > hi_sq:
        raise ParameterError(f"megapixels, square_px: expected (low, high) with low <= high, got {megapixels}, "
                             f"{square_px}")
    rng = np.random.default_rng(seed)
    tags: dict[str, Any] = {}
    camera, lens = _camera(rng, (lo_mp, hi_mp))
    tags["lens"] = lens
    cols, rows = int(rng.integers(3, 13)), int(rng.integers(3, 11))
    # The sheet's white margin, 0.1-1.5 squares (a print trimmed close, or not): from a stream
    # of its own, so that every other draw of the seed stays as it was before it varied.
    margin = float(np.random.default_rng([seed, 7]).uniform(0.1, 1.5))
    board = Checkerboard(cols, rows, 0.03, margin=0.03 * margin)
    partial = bool(rng.random() < 0.15)
    back = bool(rng.random() < 0.25)  # a colour-inverted print (or the same board from behind)
    tags.update(partial=partial, inverted_print=back, board=f"{cols}x{rows}", margin=round(margin, 2))
    W, H = camera.width, camera.height
    fit = 0.8 * min(W, H) / (max(cols, rows) + 1)
    hi = max(min(hi_sq, fit * (2.0 if partial else 1.0)), lo_sq)
    sq = float(np.exp(rng.uniform(np.log(lo_sq), np.log(hi))))
    pose = _pose(rng, camera, board, sq, partial, back)
    for _ in range(6):  # smaller squares until a pose fits (a strong fisheye squeezes the edges)
        if pose is not None:
            break
        sq = max(lo_sq, 0.7 * sq)
        pose = _pose(rng, camera, board, sq, partial, back)
    if pose is None:  # the board facing the camera at the image centre always fits
        sq = min(sq, fit)
        pose = _pose(rng, camera, board, sq, False, back, max_tilt=0.0, centred=True)
        partial = False
        if pose is None:
            raise ParameterError(f"seed {seed}: no pose fits a {cols}x{rows} board with {sq:.1f} px squares "
                                 f"in {W}x{H}; give a smaller square_px")
    bg = _background(rng, camera, tags)
    if rng.random() < 0.2:  # a second board of another size behind or beside
        other = Checkerboard(int(rng.integers(3, 13)), int(rng.integers(3, 11)), 0.03)
        if (other.inner_cols, other.inner_rows) != (cols, rows):
            p2 = _pose(rng, camera, other, float(rng.uniform(lo_sq, max(lo_sq, fit))), True, False)
            if p2 is not None:
                from camkit.render.target import render_checkerboard

                bg, _ = render_checkerboard(camera, p2, other, supersample=supersample, background=bg)
                tags["second_board"] = f"{other.inner_cols}x{other.inner_rows}"
    motion = None
    motion_px = 0.0
    if rng.random() < 0.2:
        length = rng.uniform(1.0, 8.0)  # pixels
        f = float(np.sqrt(camera.fx * camera.fy))
        w = rng.normal(size=3)
        w[2] *= 0.2
        w *= (length / f) / 0.01 / np.linalg.norm(w[:2])
        motion = Motion(angular_velocity=w, exposure_time=0.01, samples=int(2 * np.ceil(length) + 1))
        motion_px = length
    img, truth = render_view(camera, pose, board, Effects(motion=motion), supersample=supersample,
                             rng=rng) if motion else _static(camera, pose, board, supersample, bg)
    if motion:
        # Motion renders over a grey background; put the clutter where the board is not.
        on = np.isfinite(truth.depth)
        img = np.where(on, img, bg)
    corners = truth.corners_px
    grid = corners.reshape(rows, cols, 2)
    steps = np.concatenate([np.hypot(*np.diff(grid, axis=1).reshape(-1, 2).T),
                            np.hypot(*np.diff(grid, axis=0).reshape(-1, 2).T)])
    square = float(np.nanmedian(steps))
    visible = truth.visible.copy()
    if rng.random() < 0.25:
        alpha, hidden = _occluders(rng, corners, square, H, W, tags)
        skin = rng.uniform(0.35, 0.75) * (0.85 + 0.15 * _smooth_noise(rng, H, W, 6))
        img = img * (1 - alpha) + skin * alpha
        visible &= ~hidden
    blur = float(rng.choice([0.0, rng.uniform(0.3, 1.0), rng.uniform(1.0, 3.0)], p=[0.4, 0.35, 0.25]))
    if blur > 0:
        img = _blur(img, blur)
    # Light: vignetting and a gradient across the frame, then a contrast and level.
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    r2 = ((xx - W / 2) ** 2 + (yy - H / 2) ** 2) / ((W / 2) ** 2 + (H / 2) ** 2)
    gain = (1 - rng.uniform(0, 0.6) * r2) * (1 + rng.uniform(-0.4, 0.4) * (xx / W - 0.5)
                                              + rng.uniform(-0.4, 0.4) * (yy / H - 0.5))
    img = img * gain * rng.uniform(0.4, 1.1) + rng.uniform(0.0, 0.1)
    img = _backlight(np.random.default_rng([seed, 21]), img, corners, tags)
    noise = float(rng.choice([0.0, rng.uniform(0.003, 0.03)], p=[0.3, 0.7]))
    colour = bool(rng.random() < 0.3)
    if colour:
        img = img[:, :, None] * rng.uniform(0.7, 1.0, 3)
    if noise > 0:
        img = img + rng.normal(0, noise, img.shape)
    out = np.clip(np.round(img * 255), 0, 255).astype(np.uint8)
    quality = None
    if rng.random() < 0.5:
        from PIL import Image

        quality = int(rng.integers(40, 96))
        buf = io.BytesIO()
        Image.fromarray(out).save(buf, format="JPEG", quality=quality)
        buf.seek(0)
        out = np.asarray(Image.open(buf).convert("RGB" if colour else "L"))
    centre = pose.apply(board.object_points().mean(axis=0))
    normal = pose.R[:, 2]
    obliquity = float(np.degrees(np.arccos(min(1.0, abs(float(normal @ centre)) / float(np.linalg.norm(centre))))))
    return StressView(out, board, camera, corners, visible, acceptable_labellings(board, corners), square,
                      blur, motion_px, noise, quality, tags, obliquity)


def _backlight(rng: np.random.Generator, img: np.ndarray, corners: np.ndarray, tags: dict[str, Any]) -> np.ndarray:
    """One view in ten: the board in shade beside a bright window. The whole view is dimmed to
    10-30 % and a band along the image side with the most room beside the board (up to a
    tenth of the image from it) is near white, so the image's range is the window's and the
    board spans a tenth to a third of it. Drawn from a stream of its own, so the other views
    of the corpus are as they were."""
    if rng.random() >= 0.1:
        return img
    H, W = img.shape[:2]
    c = corners[np.isfinite(corners).all(axis=1)]
    dim = float(rng.uniform(0.1, 0.3))
    out = img * dim
    room = {"left": c[:, 0].min() - 0.1 * W, "right": W - 1 - c[:, 0].max() - 0.1 * W,
            "top": c[:, 1].min() - 0.1 * H, "bottom": H - 1 - c[:, 1].max() - 0.1 * H}
    side = max(room, key=room.get)
    if room[side] >= 0.05 * min(W, H):
        n = int(room[side])
        light = float(rng.uniform(0.85, 1.0))
        band = {"left": np.s_[:, :n], "right": np.s_[:, W - n:], "top": np.s_[:n, :], "bottom": np.s_[H - n:, :]}
        out[band[side]] = light
        tags["backlit"] = f"{dim:.2f}, window {side}"
    else:
        tags["backlit"] = f"{dim:.2f}"
    return out


def _static(camera: CameraModel, pose: Pose, board: Checkerboard, supersample: int,
            bg: np.ndarray) -> tuple[np.ndarray, Any]:
    from camkit.render.target import render_checkerboard

    return render_checkerboard(camera, pose, board, supersample=supersample, background=bg)
