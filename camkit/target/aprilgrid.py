"""Kalibr's AprilGrid (a grid of AprilTags with a black square at every tag corner) and its
detector.

Layout, object points and ids are Kalibr's (``GridCalibrationTargetAprilgrid`` and its
``createTargetPDF.py``, ethz-asl/kalibr; the facts, not the code, carried over):

- the board frame's origin is the first tag's outer corner, x along the tag columns, y along
  the tag rows *up* the printed face (tag 0 at the bottom left of the page), so z points at a
  camera that sees the printed face (:attr:`~camkit.target.Sheet.v_up`);
- tag ``t`` is in column ``t % tags_x`` and row ``t // tags_x``, its outer corner at
  ``(1 + tag_spacing) * tag_size`` times that; ``tag_spacing`` is the gap between tags over
  ``tag_size`` (Kalibr's ``tagSpacing``);
- a tag is ``tag_size`` across: the code's ``n x n`` bits inside a black border two bits wide
  (Kalibr prints ``borderBits = 2``), drawn turned by a half-turn from OpenCV's drawing of the
  same code (``np.rot90(code, 2)`` in Kalibr's script; checked in tests/target/test_aprilgrid.py);
- a black square of side ``tag_spacing * tag_size`` sits diagonally off each tag corner, so
  every tag corner is an X-junction (Kalibr's ``symmCorners``);
- the points are the tags' corners, ``2 tags_y`` rows of ``2 tags_x``, numbered row by row
  from the bottom: point ``(c, r)`` at ``((c // 2) (1 + spacing) + c % 2, (r // 2) (1 +
  spacing) + r % 2) * tag_size``; tag ``t``'s corners are points ``b, b + 1, b + 2 tags_x + 1,
  b + 2 tags_x`` with ``b = 4 tags_x (t // tags_x) + 2 (t % tags_x)``.

The codes are OpenCV's AprilTag dictionaries (:mod:`camkit.target.aruco`; AprilRobotics's
families).

Detection reads the tags with the marker machinery ChArUco uses (:mod:`camkit.target._markers`):

1. dark quads of an adaptive threshold, opened by a 3 x 3 cross (a tag touches its corner
   squares at a point) and cut along the light sectors of every X-junction (seen aslant and
   blurred, a junction's light sectors are thin wedges whose middle is dark, and tags join
   their corner squares into chains there); a quad that reads as no code is read again as a
   tag with corner squares joined at some of its corners (a blurred junction joins them),
   then through a lens (Fitzgibbon's division model about the image's middle, at a few
   strengths: through a fisheye a tag's sides bow and the homography of its corners misses
   its middle cells); where fewer than four tags are confirmed (step 2), the quads whose
   corners are X-junctions and whose border is a tag's are read too (small blurred tags
   join their corner squares in every threshold, but their corners stay sharp saddles), and
   the grid is found from both readings where that finds more corners;
2. the cells read against the family with its error correction, ids checked against the grid
   and confirmed by a neighbour (one homography through both tags' corners, undistorted by
   the weakest strength under which the most tags are confirmed; the neighbours'
   homographies that follow, and the reading of tags through them, use it too);
3. a confirmed tag's corner that the other tags' corners put a third of a corner square or
   more away is taken from them, where that is a joined corner square's signature (the
   corner outwards along the tag's diagonal by about a square, on a local map of the corners
   around or, where the tags around fit one homography, on that); tags not read are read
   where their neighbours put them;
4. each corner at its saddle point (camkit's sub-pixel estimator; the X-junction's circle
   and the fit's reach scaled by the tag's shortest side, the window and its smoothing by
   how narrow the tag is, its area over its longer sides: a tilted tag's border and corner
   squares are narrow across the tilt, and a sheared one is narrower than its shortest side;
   the smoothing less where the window and 2.5 of its sigmas would reach past the junction's
   narrow width, to 1 px; near the image's edge the window shrinks to fit inside it), with
   its sigma; a fit that does not converge, whose window does not fit inside the image,
   moves more than 0.45 of a corner square (the next junction is a square away), is not an
   X-junction, or beside which the fits started a window's radius about its prediction find
   a saddle that fits better (a smaller sigma) within that reach and over a pixel from it (a
   small corner square's far side is a saddle too), is dropped, and tried again from the
   corners found around it (held to the grown points' sigma test below: no code vouches for
   such a corner); then the points of tags not read (too small, blurred, or bent by a lens
   past reading through their four corners) are reached from those found, junction by
   junction (completing a rectangle of three found points, else continuing a row or column),
   each kept within a quarter of a corner square of its prediction, nearer it than its
   neighbours' places, on no other point, and with a sigma at most 1.5 times the typical one
   for its window (the median of the tags' corners' fits, or where higher, of those with a
   window within a pixel of it refitted with it: a fit's sigma grows with its window); a
   corner whose sigma is over twice that is dropped;
5. each tag is read again through its corners as found (one that reads as no code, through
   the lens strengths the first reading tries, then at its cells' middles alone): a tag
   that no longer reads as itself (a corner at another junction or in a corner square turns
   its cells) loses its corners;
6. every corner is checked against a quadratic map of its neighbours within 1.6 pitches (6 %
   of its tag, or of the grid's median tag where larger; a fisheye's bend over that reach is
   under 4.5 %), worst first; a corner so dropped is put back where a global model of the
   lens (a homography and radial distortion about a free centre, fitted on the corners that
   passed and trusted only where it predicts the outer ones it was not fitted on) predicts it
   within the same tolerance and half a pixel: at the grid's edge through a strong lens the
   quadratic on one side of a corner cannot follow the bend;
7. the same model, fitted on all the corners kept, takes out any it misses by more than
   1.5 px and six times the spread of its misses, the worst first: a fit on a blur's saddle
   beside the junction at the grid's edge can pass the local check, whose tolerance allows
   for a lens's bend there, but not a model of the whole grid.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Self

import numpy as np

from camkit._validate import as_positive_float, as_positive_int
from camkit.errors import ParameterError
from camkit.target._markers import (
    BENDS,
    TypicalSigma,
    _read_bent,
    _rims,
    add_marker,
    apart_from_found,
    better_saddle_near,
    confirm_markers,
    consistent_points,
    drop_poor_fits,
    find_markers,
    fit_inside,
    image_noise,
    is_x_corner,
    junction_quads,
    lattice_rounds,
    narrowest_side,
    narrowest_width,
    neighbour_quads,
    predict_points,
    quad_area,
    read_markers,
    recover_markers,
    refine_patches,
    unconfirmed_reason,
)
from camkit.target.aruco import ArucoDictionary, get_dictionary
from camkit.target.base import Detection, Sheet, Target, register_target
from camkit.target.checkerboard import _lens_rescue, _lens_veto, _to_grey

__all__ = ["APRILTAG_FAMILIES", "AprilGrid"]

#: Kalibr's tag families that OpenCV's dictionaries hold: family name -> dictionary name.
APRILTAG_FAMILIES: dict[str, str] = {
    "tag36h11": "DICT_APRILTAG_36h11",
    "tag25h9": "DICT_APRILTAG_25h9",
    "tag16h5": "DICT_APRILTAG_16h5",
}

#: Bits of black border around a tag's code on Kalibr's printed grid.
BORDER_BITS = 2


@register_target
@dataclass(frozen=True, slots=True)
class AprilGrid(Target):
    """Kalibr's AprilGrid: ``tags_x x tags_y`` AprilTags of side ``tag_size`` metres, apart by
    ``tag_spacing * tag_size`` (see the module docstring for the layout, Kalibr's).

    Examples
    --------
    >>> grid = AprilGrid(6, 6, 0.088, 0.3)
    >>> grid.object_points().shape
    (144, 3)
    >>> grid.object_points()[2]    # tag 1's first corner
    array([0.1144, 0.    , 0.    ])
    """

    tags_x: int
    tags_y: int
    tag_size: float
    tag_spacing: float
    family: str = "tag36h11"

    name = "aprilgrid"

    def __post_init__(self) -> None:
        tx = as_positive_int(self.tags_x, "tags_x")
        ty = as_positive_int(self.tags_y, "tags_y")
        if tx * ty < 2:
            raise ParameterError(f"tags_x, tags_y: expected at least two tags (a tag is confirmed by a neighbour), "
                                 f"got {tx}x{ty}")
        size = as_positive_float(self.tag_size, "tag_size")
        spacing = as_positive_float(self.tag_spacing, "tag_spacing")
        if spacing > 1.0:
            raise ParameterError(f"tag_spacing: expected the gap between tags over the tag's size, in (0, 1] as "
                                 f"Kalibr's tagSpacing, got {spacing:g}")
        if not isinstance(self.family, str) or self.family not in APRILTAG_FAMILIES:
            raise ParameterError(f"family: expected one of {', '.join(APRILTAG_FAMILIES)}, got {self.family!r}")
        for name, v in (("tags_x", tx), ("tags_y", ty), ("tag_size", size), ("tag_spacing", spacing)):
            object.__setattr__(self, name, v)
        if tx * ty > len(self.aruco):
            raise ParameterError(f"family: a {tx}x{ty} grid needs {tx * ty} tags, more than the {len(self.aruco)} "
                                 f"of {self.family}; choose a larger family or a smaller grid")

    # -- layout ------------------------------------------------------------------------------
    @property
    def aruco(self) -> ArucoDictionary:
        return get_dictionary(APRILTAG_FAMILIES[self.family])

    @property
    def n_tags(self) -> int:
        return self.tags_x * self.tags_y

    @property
    def pitch(self) -> float:
        """Distance between neighbouring tags' first corners, metres."""
        return (1.0 + self.tag_spacing) * self.tag_size

    def tag_places(self) -> np.ndarray:
        """``(column, row)`` of each tag, (T, 2), in id order."""
        t = np.arange(self.n_tags)
        return np.stack([t % self.tags_x, t // self.tags_x], axis=-1)

    def tag_corners(self) -> np.ndarray:
        """Each tag's corners in the board frame, (T, 4, 2), in the code's order (top-left,
        top-right, bottom-right, bottom-left of the tag as OpenCV draws the code; on Kalibr's
        page, turned by a half-turn: bottom-right, bottom-left, top-left, top-right)."""
        o = self.tag_places() * self.pitch
        s = self.tag_size
        off = np.array([[s, 0.0], [0.0, 0.0], [0.0, s], [s, s]])
        return o[:, None, :] + off[None]

    def tag_point_ids(self) -> np.ndarray:
        """The point ids of each tag's corners, (T, 4), in the order of :meth:`tag_corners`."""
        cols = 2 * self.tags_x
        t = np.arange(self.n_tags)
        b = (t // self.tags_x) * 2 * cols + (t % self.tags_x) * 2
        return np.stack([b + 1, b, b + cols, b + cols + 1], axis=-1)

    def object_points(self) -> np.ndarray:
        """The tags' corners, (4 tags_x tags_y, 3), row by row from the bottom (Kalibr's order)."""
        r, c = np.mgrid[0:2 * self.tags_y, 0:2 * self.tags_x]
        x = (c // 2) * self.pitch + (c % 2) * self.tag_size
        y = (r // 2) * self.pitch + (r % 2) * self.tag_size
        return np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=-1).astype(np.float64)

    def size_note(self) -> str:
        return (f"grid ({self.tags_x}x{self.tags_y} tags of {self.tag_size * 1000:g} mm, spacing {self.tag_spacing:g}, "
                f"{self.family})")

    def sheet(self) -> Sheet:
        """The tags (border and black bits) and the corner squares, on white; a margin of one
        corner square beyond the corner squares. The page shows y up (:attr:`Sheet.v_up`)."""
        s, b = self.tag_size, self.tag_spacing * self.tag_size
        d = self.aruco
        n = d.marker_size + 2 * BORDER_BITS
        cell = s / n
        rects = []
        origins = self.tag_places() * self.pitch
        for t in range(self.n_tags):  # one tag at a time: its black cells as rectangles
            full = np.zeros((n, n), dtype=np.uint8)
            full[BORDER_BITS:-BORDER_BITS, BORDER_BITS:-BORDER_BITS] = d.codes[t]
            r, c = np.nonzero(full == 0)
            # OpenCV's cell (r, c) of the code lies, on Kalibr's page, turned by a half-turn:
            # columns run towards -x, rows towards +y.
            u0, v0 = origins[t]
            rects.append(np.stack([u0 + (n - 1 - c) * cell, v0 + r * cell, u0 + (n - c) * cell,
                                   v0 + (r + 1) * cell], axis=-1))
        # The corner squares, one per place between and around the tags.
        i, j = np.mgrid[0:self.tags_x + 1, 0:self.tags_y + 1]
        bu = (i * self.pitch - b).ravel()
        bv = (j * self.pitch - b).ravel()
        rects.append(np.stack([bu, bv, bu + b, bv + b], axis=-1))
        W = self.tags_x * self.pitch - b
        H = self.tags_y * self.pitch - b
        label = (f"AprilGrid {self.tags_x}x{self.tags_y} {self.family} tags of {s * 1000:g} mm, spacing "
                 f"{self.tag_spacing:g} ({b * 1000:g} mm). Print at 100 % (actual size).")
        return Sheet((-2 * b, -2 * b, W + 2 * b, H + 2 * b), np.concatenate(rects), label, v_up=True)

    @classmethod
    def example(cls) -> Self:
        """Kalibr's documented example grid: 6 x 6 tags of 88 mm, spacing 0.3, tag36h11."""
        return cls(6, 6, 0.088, 0.3, "tag36h11")

    def detect(self, image: np.ndarray) -> Detection:
        """The tags' corners in ``image`` (see the module docstring)."""
        return _detect(self, image)


def _detect(grid: AprilGrid, image: np.ndarray) -> Detection:
    full = _to_grey(image, lazy=True)
    noise = image_noise(full)
    found, factor, level = find_markers(full, grid.aruco, BORDER_BITS, corner_squares=grid.tag_spacing, noise=noise)
    confirmed, bend = _confirmed(grid, found, factor, full.shape)
    det = _from_tags(grid, full, found, factor, confirmed, bend)
    if len(confirmed) >= _JUNCTIONS_BELOW:
        return det
    # Too few tags read from the threshold's quads: the tags bounded by X-junctions read as
    # well, and the grid found from both where that finds more corners (each passes the same
    # checks). Not the one result from both: a tag confirmed is held to the reading again,
    # where its corners grown from the others are not (corpus view 228: two tags that the
    # junctions let be confirmed read as no code through their exact corners, 8 corners).
    more = {m: list(q) for m, q in found.items()}
    _add_junction_tags(grid, more, level, factor, noise)
    if len(more) == len(found):  # no tag read that the threshold's quads did not read
        return det
    confirmed, bend = _confirmed(grid, more, factor, full.shape)
    det2 = _from_tags(grid, full, more, factor, confirmed, bend)
    return det2 if det2.n_found > det.n_found else det


def _from_tags(grid: AprilGrid, full: np.ndarray, found: dict[int, list[np.ndarray]], factor: int,
               confirmed: list[int], bend: float) -> Detection:
    """The grid's corners from the tags read (``found``, as
    :func:`~camkit.target._markers.find_markers` gives them) and those of them ``confirmed``
    under the lens strength ``bend``."""
    N = grid.n_points
    obj = grid.tag_corners()
    places = grid.tag_places()
    if not confirmed:
        return Detection.not_found(N, f"not found: {unconfirmed_reason(found, grid.n_tags, 'tag', 'grid')} "
                                      f"({grid.family}){_turned(grid, found, factor, full.shape)}")
    quads = {m: found[m][0] for m in confirmed}
    quads = _unjoined(grid, quads, factor, bend, full.shape)
    # Tags not read (a quad not found, or merged beyond reading) where their neighbours put them.
    quads = recover_markers(full, grid.aruco, BORDER_BITS, obj, places, quads, bend)
    tags = sorted(quads)
    ids = grid.tag_point_ids()[tags].ravel()
    pred = np.concatenate([quads[m] for m in tags])
    # The tag's narrowest side in pixels (a tilted tag is narrow across its tilt, and so are
    # its border and corner squares): the scale of the X-junction's circle and the reach of
    # the fit. Seen obliquely a tag is sheared, narrower than its shortest side: how narrow
    # (its area over its longer sides) scales the window and its smoothing.
    tag_quads = np.stack([quads[m] for m in tags])
    tag_px = np.repeat(narrowest_side(tag_quads), 4)
    narrow_px = np.repeat(narrowest_width(tag_quads), 4)
    out = np.full((N, 2), np.nan)
    sig = np.full(N, np.nan)
    win_of = np.zeros(N, dtype=np.int64)
    sm_of = np.zeros(N)  # each found corner's window and smoothing
    win = _refine(grid, full, ids, pred, tag_px, narrow_px, factor, out, sig, win_of, sm_of)
    side_of, narrow_of = np.zeros(N), np.zeros(N)
    side_of[ids] = tag_px
    narrow_of[ids] = narrow_px
    # Corners whose quad put them too far off to converge: again, from the corners found
    # around them (a quadratic map of the grid within a pitch).
    obj2 = grid.object_points()[:, :2]
    retried = np.zeros(N, dtype=bool)
    res_retried = np.full(N, np.nan)  # their fits' residuals (TypicalSigma.passes)
    for _ in range(2):
        seen = np.isfinite(out).all(axis=1)
        again = ids[~seen[ids]]
        if not len(again) or not seen.any():
            break
        p2 = predict_points(obj2[seen], out[seen], obj2[again], grid.pitch)
        ok = np.isfinite(p2).all(axis=1)
        if not ok.any():
            break
        _refine(grid, full, again[ok], p2[ok], side_of[again[ok]], narrow_of[again[ok]], factor, out, sig, win_of,
                sm_of, res_retried)
        retried |= np.isfinite(out).all(axis=1) & ~seen
    # A fit's sigma is judged against the tags' corners refitted with its own window.
    typical = TypicalSigma(full, out, sig, win_of, lambda r: _smoothing(r, factor), sm_of)
    # The corners retried are held to the grown corners' test (no code vouches for them: the
    # fit at their tag's corner failed): where the fit took a blur's saddle beside the
    # junction, its sigma was 0.14-0.9 px (19 of 20 such fits), and under 0.12 px for 123 of
    # the 126 at the junction (AprilGrid corpus, 150 views of 0-299).
    r = np.flatnonzero(retried)
    if len(r):
        poor = r[~_unvouched_fit_passes(typical, sig[r], win_of[r], sm_of[r], res_retried[r])]
        out[poor] = np.nan
        sig[poor] = np.nan
    # Corners of tags not read (too small, blurred, or bent by the lens past reading through
    # their four corners), reached from the corners found, junction by junction.
    res_of = np.full(N, np.nan)  # the grown points' fits' residuals (TypicalSigma.passes)
    _grow(grid, full, out, sig, factor, win_of, sm_of, res_of, typical)
    drop_poor_fits(out, sig, typical, win_of, sm_of, res=res_of)
    # Each tag read again through its corners as found (the quad's where one is missing): a
    # corner at another junction, or in a corner square, turns the tag's cells and border
    # away from its code; such a tag's corners go.
    tid = grid.tag_point_ids()[tags]  # (T, 4)
    at = np.where(np.isfinite(out[tid]).all(axis=2)[:, :, None], out[tid], np.stack([quads[m] for m in tags]))
    got = np.isfinite(out[tid]).all(axis=2).any(axis=1)
    if got.any():
        t_arr = np.asarray(tags)
        k = np.flatnonzero(got)
        codes, turns = _read_again(grid, full, at[k], bend)
        # A tag not read as itself with a corner not found is read once more with that corner
        # where the other tags' found corners put it (a local map of the grid within a pitch,
        # :func:`~camkit.target._markers.predict_points`), not its quad's: through a fisheye
        # or a strong barrel the quad's corner lies 1-7 px off where a corner square was joined
        # to the tag or its sides bow, and turns the tag's cells away from its code. Only the
        # corners not found are so placed, and from other tags' corners alone: a wrong fit of
        # one of the tag's own corners moves none of them, so the reading still tests it (a
        # corner completing the parallelogram of the tag's own three let a corner fitted 5 px
        # off read as its tag; corpus view 861, twenty-first session). On the AprilGrid
        # corpus's 1500 views: 45 right corners kept, on 14 views (10 through a fisheye), none
        # wrong.
        bad = np.flatnonzero((codes != t_arr[k]) | (turns != 0))
        if len(bad):
            q, moved = _from_other_tags(grid, obj2, out, tid[k[bad]], at[k[bad]])
            if moved.any():
                c2, t2 = _read_again(grid, full, q[moved], bend)
                codes[bad[moved]], turns[bad[moved]] = c2, t2
        drop = tid[k[(codes != t_arr[k]) | (turns != 0)]].ravel()
        out[drop] = np.nan
        sig[drop] = np.nan
    # Every corner against its neighbours (the other corners within 1.6 pitches): one at the
    # wrong X-junction (a tag's neighbour's corner, a corner square away) misses by that
    # square, one fitted on a blurred or cut junction by a fraction of it. The tolerance, 6 %
    # of a tag (its own where larger than the grid's median: a tag of 200 px in the middle of
    # a fisheye's view, twice the median, missed by up to 9 px, corpus view 89; 0.4 of its
    # own corner square at most, 0.6 px at the level read at least), holds the bend of a
    # fisheye over a pitch and a half (true corners miss by up to 4.5 % of a tag).
    seen = np.flatnonzero(np.isfinite(out).all(axis=1))
    own, overall = _tag_px(grid, out)
    own = own[seen]
    tol = np.maximum(0.6 * factor, np.minimum(0.06 * np.maximum(own, overall), 0.4 * grid.tag_spacing * own))
    ok = consistent_points(obj2[seen], out[seen], 1.6 * grid.pitch, tol)
    # A quadratic map on one side of a corner at the grid's edge cannot follow a strong lens
    # there (through a fisheye, right corners missed it by 5-34 px, 68 of the 180 eligible
    # corners missed on corpus views 1250-1399, none of them wrong): a global model of the
    # lens, trusted where it predicts the outer corners it was not fitted on, puts back those
    # it predicts within the same tolerance and :data:`_RESCUE_BACK_PX` (the checkerboard's
    # rescue).
    ok = _lens_rescue(obj2[seen] / grid.pitch, out[seen], ok, tol, full.shape, _RESCUE_SPAN, _RESCUE_BACK_PX)
    # A corner the local check let through, but off a model of the lens fitted on all the
    # grid's corners (:data:`_VETO_PX`).
    ok = _lens_veto(obj2[seen] / grid.pitch, out[seen], ok, full.shape, _VETO_PX, _VETO_SPREAD, _RESCUE_SPAN)
    out[seen[~ok]] = np.nan
    sig[seen[~ok]] = np.nan
    n_found = int(np.isfinite(out).all(axis=1).sum())
    if n_found == 0:
        return Detection.not_found(N, f"not found: {len(tags)} tags confirmed, but none of their corners "
                                      "passes the saddle-point fit")
    window = int(np.median(win)) if len(win) else 0
    return Detection(True, out, sig, window,
                     f"found {n_found} of {N} corners from {len(tags)} tags (window {window} px)")


#: Where fewer tags than this are confirmed from the threshold's quads, tags bounded by
#: X-junctions (:func:`~camkit.target._markers.junction_quads`) are read as well.
_JUNCTIONS_BELOW = 4


def _turned(grid: AprilGrid, found: dict[int, list[np.ndarray]], factor: int, shape: tuple[int, ...]) -> str:
    """Where tags were read but none is where ``grid``'s layout puts it, and they fit the grid
    with its tags counted the other way round (a user's commonest mistake with the grid's
    size): a clause saying so; else ""."""
    if grid.tags_x == grid.tags_y or not any(m < grid.n_tags and len(c) == 1 for m, c in found.items()):
        return ""
    turned = replace(grid, tags_x=grid.tags_y, tags_y=grid.tags_x)
    if len(_confirmed(turned, found, factor, shape)[0]) < 2:
        return ""
    return f"; the tags read fit a {turned.tags_x}x{turned.tags_y}-tag grid (the tags counted the other way round)"


def _confirmed(grid: AprilGrid, found: dict[int, list[np.ndarray]], factor: int,
               shape: tuple[int, ...]) -> tuple[list[int], float]:
    """The tags of ``found`` confirmed by their neighbours, and the lens: the strength
    (:func:`~camkit.target._markers.undistort`) under which the most are confirmed, the weakest
    of those (a fisheye's tags off one homography by more than the test allows, two by two)."""
    obj, places = grid.tag_corners(), grid.tag_places()
    confirmed: list[int] = []
    bend = 0.0
    for b in (0.0, *BENDS):
        c, _, _ = confirm_markers(found, obj, places, 1.0 + grid.tag_spacing, factor, b, shape)
        if len(c) > len(confirmed):
            confirmed, bend = c, b
    return confirmed, bend


def _add_junction_tags(grid: AprilGrid, found: dict[int, list[np.ndarray]], level: np.ndarray, factor: int,
                       noise: float) -> None:
    """Adds to ``found`` the tags read in the quads of X-junctions of ``level`` (the finest
    pyramid level read, ``factor`` times coarser than the image, whose noise is ``noise``)
    that have a tag's border (as :func:`~camkit.target._markers.find_markers` tests it), read
    as :func:`_read_again` reads (through the lens strengths, then at the cells' middles).
    On AprilGrid corpus views 926 and 1117 (tags of 20-26 px, blurred), where the threshold's
    quads read 3 and 1 tags, 15 and 14 tags read so, every one within a pixel of its place."""
    q = junction_quads(level)
    if not len(q):
        return
    n_cells = grid.aruco.marker_size + 2 * BORDER_BITS
    contrast = max(0.15, 3.0 * noise / factor)
    q = q[_rims(level, q, n_cells, BORDER_BITS, contrast)]
    if not len(q):
        return
    codes, turns = _read_again(grid, level, q, 0.0)
    for quad, code, k in zip(q, codes, turns, strict=True):
        if code >= 0:
            add_marker(found, int(code), (quad[(np.arange(4) - k) % 4] + 0.5) * factor - 0.5)


def _read_again(grid: AprilGrid, full: np.ndarray, quads: np.ndarray, bend: float) -> tuple[np.ndarray, np.ndarray]:
    """``(codes, turns)`` of the tags at ``quads`` (K, 4, 2; the code's corner order), read as
    the reading again reads them: through the view's lens strength ``bend``; one that reads
    as no code through the lens strengths the first reading tries (:func:`_read_bent`), as
    it was first read: tags of 20-28 px through a fisheye or a strong barrel read through
    their exact corners at some strengths and not at the view's (corpus views 1307, 1313,
    1337, 1396: 20 right corners dropped); one that still reads as no code at its cells'
    middles alone: at 2-3 px a cell, blurred, the points 0.2 of a cell either side of the
    middle take in the blur of the cells beside it (AprilGrid corpus views 5, 55 and 228: 13
    tags of 23-29 px, every corner within 0.08 px of the truth, read with 6-9 of their 36 bits
    wrong through their corners, 3-9 at the middles alone, and 6 of them as their own
    code)."""
    codes, turns = read_markers(full, quads, grid.aruco, BORDER_BITS, bend=bend)
    codes, turns, _ = _read_bent(full, quads, codes, turns, grid.aruco, BORDER_BITS)
    fail = np.flatnonzero(codes < 0)
    if len(fail):
        codes[fail], turns[fail] = read_markers(full, quads[fail], grid.aruco, BORDER_BITS, bend=bend,
                                                middles=(0.5,))
    return codes, turns


def _from_other_tags(grid: AprilGrid, obj2: np.ndarray, out: np.ndarray, tid: np.ndarray,
                     at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tags ``tid`` (P, 4 point ids) at ``at`` (P, 4, 2) with each corner not found in
    ``out`` put where the found corners of the other tags put it
    (:func:`~camkit.target._markers.predict_points` on the grid's points ``obj2`` (N, 2), none
    of the tag's own); and which tags had a corner so placed (none where all four are found;
    where too few found corners are around one, ``at``'s stays)."""
    seen = np.flatnonzero(np.isfinite(out).all(axis=1))
    flat = tid.ravel()
    others = ~(seen[None, :, None] == tid[:, None, :]).any(axis=2)  # (P, S): not the tag's own
    usable = np.repeat(others, 4, axis=0)  # (4P, S), a row per corner
    pred = predict_points(obj2[seen], out[seen], obj2[flat], grid.pitch, usable=usable).reshape(-1, 4, 2)
    place = ~np.isfinite(out[tid]).all(axis=2) & np.isfinite(pred).all(axis=2)
    q = at.copy()
    q[place] = pred[place]
    return q, place.any(axis=1)


def _unjoined(grid: AprilGrid, quads: dict[int, np.ndarray], factor: int, bend: float = 0.0,
              shape: tuple[int, ...] = (0, 0)) -> dict[int, np.ndarray]:
    """The confirmed tags' quads (id -> (4, 2) image corners) with each corner that the other
    tags' corners put a third of a corner square or more away (2 px at the level read at
    least) taken from them: a tag's dark region joined to a corner square puts that corner
    at the square's far side. The prediction is a local map of the other tags' corners
    around the corner (:func:`~camkit.target._markers.predict_points`' quadratic within one
    pitch or 1.6, affine on four to seven), first on all of them, then without the corners
    so judged off; taken only where the corner lies outwards of it, along the tag's
    diagonal, by half to twice a corner square (at most half a square across). Where the
    tags beside it fit one homography (missing their corners by at most half the tolerance;
    a single tag beside it fits one exactly, so there it is used as before) or too few
    corners are around for that map, the prediction is that homography
    (:func:`~camkit.target._markers.neighbour_quads`), held to the same signature. That
    homography alone was used before: through a fisheye it put corners 5-18 px off and
    replaced corners found within 2 px (AprilGrid corpus view 133: 79 of 168 corners
    lost). Taken wherever it was that far off, it replaced exact corners by 16-54 px where
    the one tag beside them had been read with a corner square joined (corpus view 1063:
    tags 4, 5 and 14, then 33 of 140 corners lost to the reading again)."""
    tags = np.array(sorted(quads), dtype=np.int64)
    if len(tags) < 2:
        return quads
    obj = grid.tag_corners()[tags].reshape(-1, 2)
    tq = np.stack([quads[m] for m in tags])  # (T, 4, 2)
    pts = tq.reshape(-1, 2)
    owner = np.repeat(np.arange(len(tags)), 4)
    b = np.repeat(grid.tag_spacing * np.sqrt(np.abs(quad_area(tq))), 4)
    tol = np.maximum(2.0 * factor, b / 3.0)
    # Outwards: from the tag's centre through the corner (a joined corner square lies on
    # that diagonal, beyond the corner).
    u = pts - np.repeat(tq.mean(axis=1), 4, axis=0)
    u /= np.maximum(np.hypot(*u.T), 1e-12)[:, None]
    other = owner[:, None] != owner[None, :]  # (k, j): j on another tag than k
    # The homography of the tags beside it, where it fits them (or too few corners are
    # around for a local map).
    miss: dict[int, float] = {}
    nbr = neighbour_quads(grid.tag_corners(), grid.tag_places(), quads, miss, bend, shape)
    fallback = np.concatenate([nbr.get(int(m), np.full((4, 2), np.nan)) for m in tags])
    fits = np.repeat([miss.get(int(m), np.inf) <= 0.5 * t for m, t in zip(tags, tol[::4], strict=True)], 4)
    off = np.zeros(len(obj), dtype=bool)
    for _ in range(2):
        pred = predict_points(obj, pts, obj, grid.pitch, usable=other & ~off[None, :])
        local = np.isfinite(pred).all(axis=1) & ~fits
        pred[~local] = fallback[~local]
        d = pts - pred
        along = np.einsum("ij,ij->i", d, u)
        across = np.abs(d[:, 0] * u[:, 1] - d[:, 1] * u[:, 0])
        with np.errstate(invalid="ignore"):
            off = (np.hypot(*d.T) > tol) & (along >= 0.5 * b) & (along <= 2.0 * b) & (across <= 0.5 * b)  # signature
    moved = off.reshape(-1, 4).any(axis=1)
    new = np.where(off[:, None], pred, pts).reshape(-1, 4, 2)
    return {**quads, **{int(m): new[i] for i, m in enumerate(tags) if moved[i]}}


def _refine(grid: AprilGrid, full: np.ndarray, ids: np.ndarray, pred: np.ndarray, tag_px: np.ndarray,
            narrow_px: np.ndarray, factor: int, out: np.ndarray, sig: np.ndarray, win_of: np.ndarray,
            sm_of: np.ndarray, res_of: np.ndarray | None = None, reach: float = 0.45) -> np.ndarray:
    """The corners ``ids`` at their saddle points from ``pred``, written into ``out``, ``sig``,
    ``win_of`` (the window), ``sm_of`` (its smoothing: :func:`_smoothing`, less where the
    window and 2.5 smoothing sigmas would reach past the junction's narrow width, to 1 px in
    quarter pixels) and ``res_of`` (the fit's residuals, where given) where the fit
    converges within ``reach`` of a corner square of the prediction (the nearest other
    junction is a corner square away) and the point is an X-junction on a circle inside its
    clean radius (the tag's border and the corner square, the smaller). Returns the windows
    used."""
    n_cells = grid.aruco.marker_size + 2 * BORDER_BITS
    clean = min(BORDER_BITS / n_cells, grid.tag_spacing) * tag_px
    H, W = full.shape
    inside = (pred[:, 0] >= 2) & (pred[:, 0] <= W - 3) & (pred[:, 1] >= 2) & (pred[:, 1] <= H - 3)
    ids, pred, tag_px, clean = ids[inside], pred[inside], tag_px[inside], clean[inside]
    narrow = min(BORDER_BITS / n_cells, grid.tag_spacing) * narrow_px[inside]
    win = np.clip(np.round(narrow / 2.5), 2, 5 * factor).astype(int)
    # Near the image's edge the window shrinks to stay inside it with its support
    # (:func:`fit_inside`), half a pixel to spare for the fit's move, to 2 px at least: at
    # the full window, right fits 0.02-0.05 px from the truth were dropped there (corpus
    # views 1250, 1298).
    edge = np.minimum.reduce([pred[:, 0], W - 1 - pred[:, 0], pred[:, 1], H - 1 - pred[:, 1]])
    win = np.maximum(np.minimum(win, np.floor(edge - 0.5).astype(int) - 2), 2)
    # The smoothing follows the window, and keeps with it inside the junction's narrow width (a
    # corner square seen obliquely: more smoothing pulls the saddle towards the tag; tag16h5
    # tags of 20-30 px, spacing 0.23, 64 degrees from square on: corner squares 4.7 px across,
    # saddles 0.6 px off at 1.5 px, wide-board probe view 32).
    full_sm = np.array([_smoothing(int(r), factor) for r in win])
    smooth = np.clip(np.floor((narrow - win) / 2.5 * 4) / 4, 1.0, full_sm)
    for r, sm in sorted(set(zip(win.tolist(), smooth.tolist(), strict=True))):  # one fit per window and smoothing
        k = (win == r) & (smooth == sm)
        q, sg, res = refine_patches(full, pred[k], int(r), sm, residuals=True)
        moved = np.hypot(*(q - pred[k]).T)
        far = np.maximum(1.5 * factor, reach * grid.tag_spacing * tag_px[k])
        ok = np.isfinite(moved) & np.isfinite(sg) & (moved <= far)
        ok &= fit_inside(q, int(r), full.shape)
        ok[ok] = is_x_corner(full, q[ok], np.maximum(0.6 * clean[k][ok], 1.5))
        # A corner square's far side is a saddle too, a few pixels off: a prediction 2 px off
        # the junction (a quad's corner seen 64 degrees from square on) can lie in its basin.
        # The fits from a window's radius about the prediction must find none that fits
        # better within the reach (wide-board probe view 32: saddles 2.9-3.1 px off, sigma
        # 0.044-0.050 px, the corners' 0.023-0.025).
        ok[ok] = ~better_saddle_near(full, pred[k][ok], q[ok], sg[ok], int(r), sm, far[ok])
        out[ids[k][ok]] = q[ok]
        sig[ids[k][ok]] = sg[ok]
        win_of[ids[k][ok]] = r
        sm_of[ids[k][ok]] = sm
        if res_of is not None:
            res_of[ids[k][ok]] = res[ok]
    return win


def _smoothing(r: int, factor: int) -> float:
    """The smoothing of a saddle fit with window ``r`` (pixels; ``factor``: the markers' level)."""
    return float(np.clip(r / 1.5, 1.5, 1.5 * factor))


def _tag_px(grid: AprilGrid, out: np.ndarray) -> tuple[np.ndarray, float]:
    """Tags' sides in pixels: each point's tag's (N,), the median of its tag's sides whose two
    corners are found, or where it has none, the grid's; and the grid's, the median over all
    the tags' such sides (0 where none is). A fisheye's tags differ twofold and more in size
    across the image."""
    ids = grid.tag_point_ids()
    have = np.isfinite(out[ids]).all(axis=2)  # (T, 4)
    sides = np.full((len(ids), 4), np.nan)
    for j, (a, b) in enumerate(((0, 1), (1, 2), (2, 3), (3, 0))):
        both = have[:, a] & have[:, b]
        sides[both, j] = np.hypot(*(out[ids[both, a]] - out[ids[both, b]]).T)
    seen = np.isfinite(sides)
    overall = float(np.median(sides[seen])) if seen.any() else 0.0
    own = np.full(len(ids), overall)
    any_side = seen.any(axis=1)
    own[any_side] = np.nanmedian(sides[any_side], axis=1)
    per_point = np.full(len(out), overall)
    per_point[ids] = own[:, None]
    return per_point, overall


#: The span (pitches, both ways) of the corners that pass the last check below which no lens
#: model is fitted to put back those it dropped: two tags' corners.
_RESCUE_SPAN = 1.5
#: How near (px) the lens model must put a corner the last check dropped to put it back: the
#: right corners it put back at the check's tolerance (3-9 px) lay 0.06 px from it (median; 90 %
#: within 0.31 px; AprilGrid corpus, 111 corners of views 0-924), so a corner within half a
#: pixel of it is within a pixel of its junction; at that tolerance it also put back two
#: corners 1.95 and 2.57 px off (views 917 and 843), which this leaves out.
_RESCUE_BACK_PX = 0.5
#: How far (px) a corner may miss the lens model fitted on all the grid's corners
#: (:func:`~camkit.target.checkerboard._lens_veto`), and how many times the fit's robust spread.
#: The local check's tolerance allows for a lens bending the grid between a corner and its
#: neighbours, 6 % of a tag: a fit on a blur's saddle beside the junction, 2.7 px off in a tag
#: of 37 px, missed its neighbours' map by 2.80 px and passed it (corpus view 1550, corner 98,
#: through a pinhole lens). The whole grid's model missed it by 2.61 px, and the right corners
#: (within 1 px of their junction) by at most 0.90 px (AprilGrid corpus: the 68 650 corners
#: the check kept on 690 views of 0-299, 800-924, 1250-1399 and 1550-1699; it misses them by
#: about their own error, so closely does it follow the corpus's lenses). On real
#: checkerboard photos (``real_boards``), OpenCV's corners missed it by up to 2.9 px through
#: a car camera's lens, where the spread of the misses was 0.6-1.1 px, and by up to 3.8 px
#: through a fisheye (spread 1.2 px): six spreads leave those alone.
_VETO_PX = 1.5
_VETO_SPREAD = 6.0
#: How far (in corner squares) a point grown past the tags read may move from its prediction.
_GROWN_REACH = 0.25
#: A grown point whose sigma is over the typical one but whose residuals are not (a junction
#: of less contrast) is kept only where its sigma is at most this (px): labelled by its
#: neighbours alone, it must lie well within a pixel of its junction (as ChArUco's step 6).
#: A blurred junction of corner squares of 5 px fitted so, sigma 0.23 px, lay 1.4 px off
#: (corpus view 43, corner 92).
_MAX_GROWN_LOW_CONTRAST_SIGMA = 0.1


def _unvouched_fit_passes(typical: TypicalSigma, sig: np.ndarray, win: np.ndarray, sm: np.ndarray,
                          res: np.ndarray) -> np.ndarray:
    """Which saddle fits that no tag's code vouches for (points grown past the tags, corners
    tried again from their neighbours) are kept: sigma ``sig`` at most 1.5 times
    ``typical``'s for the window ``win`` and smoothing ``sm``, or residuals ``res`` at most that times the typical
    ones with a sigma of at most :data:`_MAX_GROWN_LOW_CONTRAST_SIGMA`
    (:meth:`~camkit.target._markers.TypicalSigma.passes`)."""
    return typical.passes(sig, win, 1.5, sm, res=res, cap=_MAX_GROWN_LOW_CONTRAST_SIGMA)


def _grow(grid: AprilGrid, full: np.ndarray, out: np.ndarray, sig: np.ndarray, factor: int,
          win_of: np.ndarray, sm_of: np.ndarray, res_of: np.ndarray, typical: TypicalSigma) -> None:
    """Add the grid's points next to found ones (``out``, NaN where not found), round by round:
    each predicted from the points found beside it on the grid (:func:`extend_lattice`), fitted
    and tested as :func:`_refine` does, and kept where it ends twice as near its own predicted
    place as its neighbours' along the grid's rows and columns, within :data:`_GROWN_REACH` of a
    corner square of it (0.45 for a tag's own corners), on no other found point, and with a
    fit's sigma at most 1.5 times ``typical``'s for its window (no code vouches for it), or its
    residuals (recorded in ``res_of``) at most that times the typical ones with a sigma of at
    most :data:`_MAX_GROWN_LOW_CONTRAST_SIGMA` (a junction of less contrast:
    :meth:`TypicalSigma.passes`). A point is tried again only once more of its neighbours are
    found. The check of every point against its neighbours that follows
    (:func:`consistent_points`) covers these too."""
    nx, ny = 2 * grid.tags_x, 2 * grid.tags_y
    T = grid.tag_size
    idx_x, idx_y = np.arange(-3, nx + 3), np.arange(-3, ny + 3)
    xs = (idx_x // 2) * grid.pitch + (idx_x % 2) * T  # the padded lattice's board places
    ys = (idx_y // 2) * grid.pitch + (idx_y % 2) * T
    for cand, pred, u, v, others in lattice_rounds(out, nx, ny, xs, ys):
        tag_px = np.fmin(np.hypot(*u.T), np.hypot(*v.T)) * T
        # The lattice cell's narrowest width (its area over its longer side), as a tag's.
        narrow_px = np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]) / np.fmax(np.hypot(*u.T), np.hypot(*v.T)) * T
        ok = np.isfinite(pred).all(axis=1) & np.isfinite(tag_px) & np.isfinite(narrow_px) & (tag_px >= 8)
        if not ok.any():
            continue
        cand, pred, tag_px, narrow_px, others = cand[ok], pred[ok], tag_px[ok], narrow_px[ok], others[ok]
        tmp, tsig, twin = np.full_like(out, np.nan), np.full_like(sig, np.nan), np.zeros_like(win_of)
        tres, tsm = np.full_like(sig, np.nan), np.zeros_like(sig)
        _refine(grid, full, cand, pred, tag_px, narrow_px, factor, tmp, tsig, twin, tsm, tres, _GROWN_REACH)
        q = tmp[cand]
        got = np.isfinite(q).all(axis=1)
        own = np.hypot(*(q - pred).T)
        theirs = np.hypot(*(q[:, None] - others).transpose(2, 0, 1)).min(axis=1)
        got &= 2.0 * own < theirs
        got[got] = apart_from_found(q[got], out[np.isfinite(out).all(axis=1)],
                                    np.maximum(1.5 * factor, 0.25 * grid.tag_spacing * tag_px[got]))
        got[got] = _unvouched_fit_passes(typical, tsig[cand[got]], twin[cand[got]], tsm[cand[got]], tres[cand[got]])
        out[cand[got]] = q[got]
        sig[cand[got]] = tsig[cand[got]]
        win_of[cand[got]] = twin[cand[got]]
        sm_of[cand[got]] = tsm[cand[got]]
        res_of[cand[got]] = tres[cand[got]]
