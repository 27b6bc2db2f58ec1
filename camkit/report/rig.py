"""The rig calibration report: every camera, the rig seen from above, and a rectified pair with
rows drawn through it. One self-contained HTML file, as the camera report."""

from __future__ import annotations

import html
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from camkit._atomic import write_atomic
from camkit.errors import ParameterError
from camkit.report.html import _fig_to_img, _figure, _thumb, page, param_table

__all__ = ["write_rig_report"]


def write_rig_report(path: str | os.PathLike, result: Any, *, pair: Sequence[np.ndarray] | None = None,
                     pair_cameras: tuple[int | str, int | str] = (0, 1), instant_names: Sequence[str] | None = None,
                     title: str = "Rig calibration") -> Path:
    """Write the rig report: a summary, the rig's geometry (each camera's pose, baseline and
    their one-sigma), the rig seen from above (cameras, their viewing directions, where the
    target was), the RMS per instant and camera, each camera's parameters with one-sigma,
    and, given ``pair`` (one image of each of ``pair_cameras`` taken at the same instant), that
    pair rectified side by side with rows drawn through it. Written atomically.

    Parameters
    ----------
    result : RigResult
    pair : (left image, right image), optional
    pair_cameras : the two cameras of ``pair`` (names or indices)
    instant_names : names of the instants (the image stems), optional
    """
    from camkit.calib.rig import RigResult
    from camkit.resample import remap
    from camkit.stereo import rectify, rectify_maps

    if not isinstance(result, RigResult):
        raise ParameterError(f"result: expected a RigResult, got {type(result).__name__}")
    r = result
    n_t = len(r.instant_rms_px)
    inames = list(instant_names) if instant_names is not None else [str(k) for k in range(n_t)]
    if len(inames) != n_t:
        raise ParameterError(f"instant_names: expected {n_t} names, got {len(inames)}")
    body = [f"<h1>{html.escape(title)}</h1>",
            f"<p>{len(r.names)} cameras ({', '.join(html.escape(n) for n in r.names)}), {n_t} instants; RMS "
            f"{r.rms_px:.3f} px per corner over every camera; {len(r.rejected)} corners rejected as outliers; "
            f"{html.escape(r.message)}.</p>"]
    rows = []
    for k, name in enumerate(r.names):
        p = r.cam_from_rig[k]
        ref = k == r.reference
        rows.append(
            f"<tr><td>{html.escape(name)}</td><td>{len(r.cameras[k].view_indices)}</td><td>{r.camera_rms_px[k]:.3f}</td>"
            + ("<td>reference</td><td></td><td></td><td></td>" if ref else
               f"<td>{r.baseline_m[k] * 1000:.3f} &plusmn; {r.baseline_sigma_m[k] * 1000:.3f}</td>"
               f"<td>{' '.join(f'{v:+.5f}' for v in np.degrees(p.rvec))}</td>"
               f"<td>{' '.join(f'{v:.4f}' for v in r.rotation_sigma_deg[k])}</td>"
               f"<td>{' '.join(f'{v * 1000:+.3f}' for v in p.t)} (&plusmn; "
               f"{' '.join(f'{v * 1000:.3f}' for v in r.translation_sigma_m[k])})</td>") + "</tr>")
    body += ["<h2>The rig</h2>",
             "<table><tr><th>camera</th><th>instants used</th><th>RMS px</th><th>baseline mm</th>"
             "<th>rotation vector deg (cam_from_rig)</th><th>rotation 1 sigma deg</th><th>t mm (1 sigma)</th></tr>"
             + "".join(rows) + "</table>",
             "<p class=note>cam_from_rig maps points in the rig's frame (the reference camera's) into each camera's. "
             "Sigmas are one standard deviation from the joint fit's covariance scaled by the residual variance.</p>"]

    # The rig from above: x (right) against z (forward) in the rig's frame.
    fig = _figure((6.4, 5.0))
    ax = fig.subplots()
    centres = np.array([p.inverse().t for p in r.cam_from_rig])
    axes = np.array([p.R[2] for p in r.cam_from_rig])  # each camera's z axis in the rig frame
    span = max(float(np.ptp(centres[:, [0, 2]], axis=0).max()), 0.05)
    for k, name in enumerate(r.names):
        ax.plot(centres[k, 0], centres[k, 2], "o", color=f"C{k}")
        ax.annotate("", xy=(centres[k, 0] + 0.6 * span * axes[k, 0], centres[k, 2] + 0.6 * span * axes[k, 2]),
                    xytext=(centres[k, 0], centres[k, 2]), arrowprops={"arrowstyle": "->", "color": f"C{k}"})
        ax.text(centres[k, 0], centres[k, 2] - 0.12 * span, name, color=f"C{k}", ha="center", va="top")
    targets = np.array([p.t for p in r.rig_from_target if p is not None])
    if len(targets):
        ax.scatter(targets[:, 0], targets[:, 2], s=8, color="grey", label="target origin per instant")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x in the rig frame (m)")
    ax.set_ylabel("z, forward (m)")
    body += ["<h2>The rig from above</h2>",
             "<p class=note>Camera centres and viewing directions (arrows), and where the target was.</p>",
             _fig_to_img(fig, "the rig seen from above")]

    # RMS per instant and camera.
    fig = _figure((9, 3.2))
    ax = fig.subplots()
    width = 0.8 / len(r.names)
    for k, name in enumerate(r.names):
        v = np.full(n_t, np.nan)
        for t, vr in zip(r.cameras[k].view_indices, r.cameras[k].view_rms_px, strict=True):
            v[t] = vr
        ax.bar(np.arange(n_t) + (k - (len(r.names) - 1) / 2) * width, v, width, label=name, color=f"C{k}")
    ax.set_xticks(np.arange(n_t), inames, rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("RMS per corner (px)")
    ax.legend(fontsize=8)
    body += ["<h2>RMS per instant</h2>",
             "<p class=note>An instant much above the others (one camera or all) is worth a look: motion between "
             "the cameras' exposures, blur, a wrong detection.</p>", _fig_to_img(fig, "RMS per instant and camera")]

    if pair is not None:
        if len(pair) != 2 or not all(isinstance(im, np.ndarray) and im.ndim in (2, 3) for im in pair):
            raise ParameterError("pair: expected two image arrays (one image of each camera at the same instant)")
        a, b = r.index(pair_cameras[0]), r.index(pair_cameras[1])
        rect = rectify(r.models[a], r.models[b], r.relative_pose(a, b))
        maps = rectify_maps(rect)
        shown = []
        for im, m, model in zip(pair, maps, (r.models[a], r.models[b]), strict=True):
            if im.shape[:2] != (model.height, model.width):
                raise ParameterError(f"pair: expected images of {model.width}x{model.height}, got "
                                     f"{im.shape[1]}x{im.shape[0]}")
            small, _ = _thumb(remap(im.astype(np.float32), m), 520, model.width)
            shown.append(small)
        fig = _figure((11, 11 * shown[0].shape[0] / (2 * shown[0].shape[1]) + 0.4))
        axs = fig.subplots(1, 2)
        for ax, im, name in zip(axs, shown, (r.names[a], r.names[b]), strict=True):
            ax.imshow(im, cmap="gray" if im.ndim == 2 else None, vmin=0, vmax=1)
            for y in np.linspace(0, im.shape[0] - 1, 13)[1:-1]:
                ax.axhline(y, color="#cc3311", lw=0.6)
            ax.set_title(f"{name}, rectified", fontsize=9)
            ax.set_axis_off()
        body += ["<h2>A rectified pair</h2>",
                 "<p class=note>The same rows of the two rectified images see the same points: a feature on a red "
                 "line in one image lies on that line in the other.</p>", _fig_to_img(fig, "a rectified pair")]

    for k, name in enumerate(r.names):
        body += [f"<h2>Camera {html.escape(name)} ({r.models[k].name}, {r.models[k].width}x{r.models[k].height})</h2>",
                 param_table(r.cameras[k])]
    return write_atomic(path, page(title, body).encode())
