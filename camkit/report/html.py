"""A calibration report: one self-contained HTML file with its figures embedded."""

from __future__ import annotations

import base64
import html
import io
import os
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from camkit import __version__
from camkit._atomic import write_atomic
from camkit.calib.uncertainty import projection_uncertainty
from camkit.errors import ParameterError
from camkit.lens.base import CameraModel

__all__ = ["write_report"]


def _figure(figsize: tuple[float, float]) -> Any:
    """A matplotlib Figure of its own (the object-oriented API: no pyplot state, no backend
    chosen for the caller's process)."""
    from matplotlib.figure import Figure

    return Figure(figsize=figsize)


def _fig_to_img(fig: Any, alt: str) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    data = base64.b64encode(buf.getvalue()).decode()
    return f'<img class="fig" alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _grid(model: CameraModel, nx: int = 33) -> tuple[np.ndarray, np.ndarray]:
    ny = max(round(nx * model.height / model.width), 2)
    xs = np.linspace(0, model.width - 1, nx)
    ys = np.linspace(0, model.height - 1, ny)
    return np.meshgrid(xs, ys)


def _image_axes(ax: Any, model: CameraModel) -> None:
    ax.set_xlim(-0.5, model.width - 0.5)
    ax.set_ylim(model.height - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")


def _thumb(img: np.ndarray, width: int, full_width: int) -> tuple[np.ndarray, float]:
    """The image shown ``width`` px wide, stretched to [0, 1], and the scale from the full
    image's pixels (``full_width`` wide; ``img`` may already be a thumbnail of it)."""
    from camkit.resample import resize

    s = width / img.shape[1]
    h = max(round(img.shape[0] * s), 1)
    small = resize(img, width=width, height=h, interpolation="area") if s < 1 else img
    small = small.astype(np.float64)
    # Stretch to the image's own range: a 12-bit sensor's data in a 16-bit file would
    # otherwise show nearly black.
    lo, hi = np.percentile(small, [0.5, 99.5])
    small = (small - lo) / max(hi - lo, 1e-12)
    return np.clip(small, 0, 1), small.shape[1] / full_width


def write_report(path: str | os.PathLike, result: Any, *, images: Sequence[Any] | None = None,
                 image_names: Sequence[str] | None = None, truth: CameraModel | None = None,
                 title: str = "Camera calibration", image_info: Sequence[Any] | None = None) -> Path:
    """Write the calibration report: per-view RMS, residuals (scatter and vectors over the
    image), corner coverage, the distortion field, the projection uncertainty, the parameter
    table with one-sigma values (and the true values when ``truth`` is given, as in the
    demo), rejected corners and views with their reasons, and a thumbnail of each view with
    its corners. One self-contained HTML file (PNG figures embedded), written atomically.

    Parameters
    ----------
    result : CalibrationResult
    images : sequence of arrays, optional
        The input images or thumbnails of them (any size with the images' aspect; in input
        order), for the thumbnails. :func:`camkit.pipeline.calibrate_files` passes the
        thumbnails it kept while detecting: no image is decoded twice. None for a file that
        could not be read (its place is labelled so).
    image_names : sequence of str, optional
    truth : CameraModel, optional
    image_info : sequence of ImageInfo or None, optional
        The images' EXIF (camera, lens, focal length, orientation), shown when present.
    """
    from matplotlib import colormaps
    from matplotlib.patches import Rectangle

    from camkit.calib.result import CalibrationResult

    if not isinstance(result, CalibrationResult):
        raise ParameterError(f"result: expected a CalibrationResult, got {type(result).__name__}")
    model = result.model
    n_in = len(result.detections) if result.detections is not None else (
        max((*result.view_indices, *(i for i, _ in result.rejected_views)), default=-1) + 1)
    names = list(image_names) if image_names is not None else [f"view {i}" for i in range(n_in)]
    if len(names) != n_in:
        raise ParameterError(f"image_names: expected {n_in} names, got {len(names)}")
    if images is not None and len(images) != n_in:
        raise ParameterError(f"images: expected {n_in} images (one per input view), got {len(images)}")
    if images is not None:
        for k, img in enumerate(images):
            if img is not None and (not isinstance(img, np.ndarray) or img.ndim not in (2, 3)):
                raise ParameterError(f"images[{k}]: expected an image array (a thumbnail will do) or None (a file "
                                     f"that could not be read), got {type(img).__name__}")
    W, H = model.width, model.height
    vnames = [names[i] for i in result.view_indices]
    figs: list[tuple[str, str, str]] = []

    # Per-view RMS.
    fig = _figure((9, 3.2))
    ax = fig.subplots()
    ax.bar(np.arange(len(vnames)), result.view_rms_px, color="#4477aa")
    ax.axhline(result.rms_px, color="#cc3311", lw=1, label=f"overall RMS {result.rms_px:.3f} px")
    ax.set_xticks(np.arange(len(vnames)), vnames, rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("RMS reprojection error per corner (px)")
    ax.legend(loc="upper right")
    figs.append(("Per-view RMS", _fig_to_img(fig, "per-view RMS bars"),
                 "A view much above the others is worth a look: motion blur, a bent board, a wrong detection."))

    # Residuals: scatter and vectors over the image.
    resid_views = result.residuals  # per used view, (N_i, 2)
    fig = _figure((11, 4.4))
    a1, a2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 1.45]})
    cmap = colormaps["tab20"]
    for k, r in enumerate(resid_views):
        a1.scatter(r[:, 0], r[:, 1], s=4, color=cmap(k % 20), alpha=0.7)
    lim = max(float(np.nanmax(np.abs(np.concatenate(resid_views)))) * 1.1, 1e-3)
    a1.set_xlim(-lim, lim)
    a1.set_ylim(lim, -lim)
    a1.set_aspect("equal")
    a1.axhline(0, color="grey", lw=0.5)
    a1.axvline(0, color="grey", lw=0.5)
    a1.set_xlabel("residual x (px)")
    a1.set_ylabel("residual y (px)")
    a1.set_title(f"std x {result.std_px[0]:.3f} px, y {result.std_px[1]:.3f} px", fontsize=9)
    pts = _observed(result)
    resid = np.concatenate(resid_views)
    ok = np.isfinite(resid).all(axis=1) & np.isfinite(pts).all(axis=1)
    mag = np.hypot(*resid[ok].T)
    scale = 0.04 * W / max(float(np.percentile(mag, 95)) if mag.size else 1.0, 1e-9)
    a2.quiver(pts[ok, 0], pts[ok, 1], resid[ok, 0] * scale, resid[ok, 1] * scale, mag, angles="xy",
              scale_units="xy", scale=1, cmap="viridis", width=0.002)
    _image_axes(a2, model)
    a2.set_title(f"residual vectors, magnified x{scale:.0f}", fontsize=9)
    figs.append(("Residuals", _fig_to_img(fig, "residual scatter and vectors"),
                 "Residuals should look like noise: round, centred, with no pattern over the image. A swirl or a "
                 "radial pattern means the lens model is too simple."))

    # Coverage.
    fig = _figure((6.4, 6.4 * H / W + 0.6))
    ax = fig.subplots()
    nx, ny = 16, max(round(16 * H / W), 1)
    good = pts[np.isfinite(pts).all(axis=1)]
    counts, _, _ = np.histogram2d(good[:, 0], good[:, 1], bins=[nx, ny], range=[[-0.5, W - 0.5], [-0.5, H - 0.5]])
    im = ax.imshow(counts.T, extent=(-0.5, W - 0.5, H - 0.5, -0.5), cmap="Greens", vmin=0,
                   vmax=max(counts.max(), 1))
    empty = np.argwhere(counts.T == 0)
    for cy, cx in empty:
        ax.add_patch(Rectangle((-0.5 + cx * W / nx, -0.5 + cy * H / ny), W / nx, H / ny, fill=False,
                               hatch="///", edgecolor="#cc3311", lw=0))
    ax.scatter(good[:, 0], good[:, 1], s=1, color="k", alpha=0.5)
    _image_axes(ax, model)
    fig.colorbar(im, ax=ax, fraction=0.04, label="corners per cell")
    frac = 1 - len(empty) / (nx * ny)
    figs.append(("Coverage", _fig_to_img(fig, "coverage map of detected corners"),
                 f"{len(good)} corners; {frac:.0%} of the {nx}x{ny} cells hold at least one. Hatched cells have "
                 "no data: the lens model there is extrapolated. Photograph the board in those parts of the image."))

    # Distortion field.
    gx, gy = _grid(model, 25)
    pix = np.stack([gx, gy], axis=-1)
    rays = model.unproject(pix)
    front = rays[..., 2] > np.cos(np.radians(80.0))
    z = np.where(front, rays[..., 2], np.nan)
    ideal = np.stack([model.fx * rays[..., 0] / z + model.cx, model.fy * rays[..., 1] / z + model.cy], -1)
    disp = pix - ideal
    fig = _figure((6.4, 6.4 * H / W + 0.6))
    ax = fig.subplots()
    m = np.hypot(disp[..., 0], disp[..., 1])
    im = ax.imshow(m, extent=(-0.5, W - 0.5, H - 0.5, -0.5), cmap="magma", interpolation="bilinear")
    ax.quiver(ideal[..., 0], ideal[..., 1], disp[..., 0], disp[..., 1], color="w", angles="xy", scale_units="xy",
              scale=1, width=0.002)
    _image_axes(ax, model)
    fig.colorbar(im, ax=ax, fraction=0.04, label="displacement (px)")
    figs.append(("Distortion", _fig_to_img(fig, "distortion field"),
                 f"Where the lens moves each point relative to a pinhole with the same focal lengths and principal "
                 f"point (arrows true length). Largest: {np.nanmax(m):.1f} px."))

    # Projection uncertainty.
    depth = float(np.median([p.t[2] for p in result.poses]))
    gx, gy = _grid(model, 41)
    sig = projection_uncertainty(model, result.covariance, result.free_params, np.stack([gx, gy], -1), depth)
    fig = _figure((6.4, 6.4 * H / W + 0.6))
    ax = fig.subplots()
    top = float(np.nanpercentile(sig, 90))
    im = ax.imshow(sig, extent=(-0.5, W - 0.5, H - 0.5, -0.5), cmap="viridis", interpolation="bilinear",
                   vmin=0, vmax=top)
    cs = ax.contour(gx, gy, sig, levels=np.linspace(0, top, 7)[1:], colors="w", linewidths=0.6)
    ax.clabel(cs, fontsize=7, fmt="%.2f")
    ax.scatter(good[:, 0], good[:, 1], s=0.5, color="w", alpha=0.3)
    _image_axes(ax, model)
    fig.colorbar(im, ax=ax, fraction=0.04, label="1-sigma (px)")
    figs.append(("Projection uncertainty", _fig_to_img(fig, "projection uncertainty map"),
                 f"How far (1 sigma, px) the fitted camera may misplace a point {depth:.2f} m away (the median "
                 "board distance), from the parameters' covariance. It grows where the image has no corners."))

    # Thumbnails.
    thumbs_html = ""
    if images is not None:
        n = len(images)
        cols = 5
        rows = -(-n // cols)
        fig = _figure((cols * 2.4, rows * 2.4 * H / W + 0.3 * rows))
        axes = fig.subplots(rows, cols, squeeze=False)
        pos = {v: k for k, v in enumerate(result.view_indices)}
        bad = {(v, c) for v, c, _ in result.rejected}
        for i in range(rows * cols):
            ax = axes.flat[i]
            ax.axis("off")
            if i >= n:
                continue
            if images[i] is None:
                ax.set_title(names[i] + "  (not read)", fontsize=7, color="#cc3311")
                continue
            small, s = _thumb(images[i], 240, W)
            ax.imshow(small, cmap="grey" if small.ndim == 2 else None, vmin=0, vmax=1)
            c = result.detections[i].corners if result.detections is not None else None
            if c is not None:
                cc = (c + 0.5) * s - 0.5
                ax.plot(cc[:, 0], cc[:, 1], "-", color="#33bb33", lw=0.5)
                ax.scatter(cc[:, 0], cc[:, 1], s=2, color="#33bb33")
                rej = [j for j in range(len(c)) if (i, j) in bad]
                if rej:
                    ax.scatter(cc[rej, 0], cc[rej, 1], s=20, marker="x", color="#cc3311")
            label = names[i] + (f"  {result.view_rms_px[pos[i]]:.2f} px" if i in pos else "  (not used)")
            ax.set_title(label, fontsize=7, color="k" if i in pos else "#cc3311")
        thumbs_html = _fig_to_img(fig, "view thumbnails with detected corners")

    table = param_table(result, truth)
    rej = "".join(f"<li>{html.escape(names[v])}: {html.escape(r)}</li>" for v, r in result.rejected_views)
    rejc = "".join(f"<li>{html.escape(names[v])}, corner {c}: {html.escape(r)}</li>" for v, c, r in result.rejected)
    summary = (f"<p>{model.name} model, {W}x{H} px; {len(result.view_indices)} of {n_in} views used; "
               f"RMS {result.rms_px:.3f} px; residual std {result.std_px[0]:.3f} / {result.std_px[1]:.3f} px "
               f"(x / y); {html.escape(result.message)} after {result.iterations} iterations.</p>")
    from camkit.io.results import camera_info, orientation_note

    exif = camera_info(image_info)
    labels = {"make": "make", "model": "model", "lens": "lens", "focal_length_mm": "focal length (mm)",
              "focal_length_35mm": "35 mm equivalent focal length (mm)"}
    exif_items = "".join(f"<li>{labels[k]}: {html.escape(str(v))}</li>" for k, v in exif.items() if k in labels)
    note = orientation_note(image_info)
    summary += ((f"<p>From the images' EXIF:</p><ul>{exif_items}</ul>" if exif_items else "")
                + (f"<p class='warn'>Note: {html.escape(note)}.</p>" if note else "")
                + "<p>RMS: sqrt(mean over corners of dx&sup2; + dy&sup2;), as OpenCV's calibrateCamera reports it, "
                  "overall and per view; residual std: per axis.</p>")
    body = [f"<h1>{html.escape(title)}</h1>", summary, "<h2>Parameters</h2>", table,
            "<p class=note>Pixel (0, 0) is the centre of the top-left pixel. Sigmas are one standard deviation, "
            "from the covariance of the fit scaled by the residual variance.</p>",
            "<h2>Rejected views</h2>", f"<ul>{rej}</ul>" if rej else "<p>None.</p>",
            "<h2>Rejected corners</h2>",
            (f"<details><summary>{len(result.rejected)} corners left out as outliers (fingers over the board, "
             f"glare, a wrong match)</summary><ul>{rejc}</ul></details>") if rejc else "<p>None.</p>"]
    for head, img_tag, note in figs:
        body += [f"<h2>{head}</h2>", f"<p class=note>{html.escape(note)}</p>", img_tag]
    if thumbs_html:
        body += ["<h2>Views</h2>", "<p class=note>Detected corners in green, rejected corners as red crosses.</p>",
                 thumbs_html]
    return write_atomic(path, page(title, body).encode())


def param_table(result: Any, truth: Any = None) -> str:
    """The camera's parameters as an HTML table: estimate, one-sigma ("held" for a parameter
    held fixed) and, given ``truth`` (a camera model), the true value."""
    model = result.model
    rows_html = []
    for name in model.param_names:
        sd = result.stddev.get(name)
        t = f"<td>{getattr(truth, name):.6g}</td>" if truth is not None and hasattr(truth, name) else (
            "<td></td>" if truth is not None else "")
        sd_txt = f"&plusmn; {sd:.3g}" if sd is not None else "held"
        rows_html.append(f"<tr><td>{name}</td><td>{getattr(model, name):.6g}</td><td>{sd_txt}</td>{t}</tr>")
    truth_head = "<th>true</th>" if truth is not None else ""
    return (f"<table><tr><th>parameter</th><th>estimate</th><th>1 sigma</th>{truth_head}</tr>"
            + "".join(rows_html) + "</table>")


def page(title: str, body: Sequence[str]) -> str:
    """The report's HTML page around ``body`` (HTML fragments), with its style and stamp."""
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>
body {{ font-family: sans-serif; max-width: 1100px; margin: 2em auto; padding: 0 1em; color: #222; }}
table {{ border-collapse: collapse; }} td, th {{ border: 1px solid #ccc; padding: 2px 8px; text-align: right; }}
td:first-child {{ text-align: left; font-family: monospace; }}
img.fig {{ max-width: 100%; display: block; margin: 0.5em 0 1.5em; }}
.note {{ color: #555; font-size: 0.9em; }}
</style></head><body>
{chr(10).join(body)}
<p class=note>camkit {__version__}, {stamp}.</p>
</body></html>
"""


def _observed(result: Any) -> np.ndarray:
    """Observed corner pixels of the used views, stacked; NaN where not seen or rejected."""
    out = []
    for k, i in enumerate(result.view_indices):
        p = np.array(result.image_points[i], dtype=np.float64)
        p[~np.isfinite(result.residuals[k]).all(axis=1)] = np.nan
        out.append(p)
    return np.concatenate(out)
