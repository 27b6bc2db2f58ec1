"""Entry point of the ``camkit`` command."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from camkit import __version__
from camkit.errors import CamkitError, EstimationError, ParameterError

__all__ = ["main"]


def _console():
    from rich.console import Console

    return Console(highlight=False)


class _Progress:
    """A rich progress bar per pipeline stage (render, detect, undistort...)."""

    LABELS: ClassVar[dict[str, str]] = {"render": "rendering views", "detect": "detecting corners",
                                        "calibrate": "calibrating", "report": "writing the report",
                                        "undistort": "undistorting", "rectify": "rectifying pairs"}

    def __init__(self, console) -> None:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        self.progress = Progress(TextColumn("{task.description:<20}"), BarColumn(), MofNCompleteColumn(),
                                 TimeElapsedColumn(), console=console, transient=False)
        self.tasks: dict[str, int] = {}

    def __enter__(self):
        self.progress.__enter__()
        return self

    def __exit__(self, *exc):
        return self.progress.__exit__(*exc)

    def __call__(self, stage: str, done: int, total: int) -> None:
        if stage not in self.LABELS:
            return
        if stage not in self.tasks:
            self.tasks[stage] = self.progress.add_task(self.LABELS[stage], total=total)
        self.progress.update(self.tasks[stage], completed=done)


def _param_table(result, truth=None, title="Camera"):
    from rich.table import Table

    table = Table(title=title, title_justify="left")
    table.add_column("parameter")
    table.add_column("estimate", justify="right")
    table.add_column("1 sigma", justify="right")
    if truth is not None:
        table.add_column("true", justify="right")
        table.add_column("error / sigma", justify="right")
    for name in result.model.param_names:
        if name not in result.stddev:
            continue
        v, sd = getattr(result.model, name), result.stddev[name]
        row = [name, f"{v:.6g}", f"{sd:.2g}"]
        if truth is not None:
            t = getattr(truth, name)
            row += [f"{t:.6g}", f"{(v - t) / sd:+.1f}" if sd > 0 else ""]
        table.add_row(*row)
    return table


def _view_table(job):
    from rich.table import Table

    r = job.result
    pos = {v: k for k, v in enumerate(r.view_indices)}
    reasons = dict(r.rejected_views)
    table = Table(title="Views", title_justify="left")
    for col, just in (("image", "left"), ("corners", "right"), ("RMS px", "right"), ("camera yaw/pitch/roll deg",
                                                                                     "right")):
        table.add_column(col, justify=just)
    ypr = r.view_ypr_deg()
    for i, name in enumerate(job.image_names):
        det = r.detections[i] if r.detections is not None else None
        n = str(det.n_found) if det is not None else ""
        if i in pos:
            k = pos[i]
            table.add_row(name, n, f"{r.view_rms_px[k]:.3f}", "{:+.1f} / {:+.1f} / {:+.1f}".format(*ypr[k]))
        else:
            table.add_row(name, n, "[red]not used[/red]", reasons.get(i, "board not found"))
    return table


def _detection_table(names, detections):
    from rich.table import Table

    table = Table(title="Boards", title_justify="left")
    for col, just in (("image", "left"), ("board", "left"), ("corners", "right"), ("detector", "left")):
        table.add_column(col, justify=just)
    for name, det in zip(names, detections, strict=True):
        table.add_row(name, "found" if det.found else "[red]not found[/red]", str(det.n_found), det.message)
    return table


def _summary(console, job) -> None:
    r = job.result
    if r.detections is not None:
        console.print(f"board found in {sum(d.found for d in r.detections)} of {len(r.detections)} images")
    console.print(f"{len(r.view_indices)} of {len(job.image_names)} views used; RMS {r.rms_px:.3f} px per corner "
                  f"(as OpenCV's); residual std {r.std_px[0]:.3f} / {r.std_px[1]:.3f} px (x / y); "
                  f"{len(r.rejected)} corners rejected as outliers; {r.message}")


def _cmd_demo(args: argparse.Namespace) -> int:
    import time

    from camkit.demo import DEMO_BOARD, run_demo

    console = _console()
    t0 = time.perf_counter()
    console.print(f"camkit demo: {args.views} simulated views of a {DEMO_BOARD.inner_cols}x{DEMO_BOARD.inner_rows} "
                  f"board (30 mm squares) through a 1280x960 camera with barrel distortion, defocus, sensor noise "
                  "and a Bayer mosaic; then calibration as `camkit calibrate` does it")
    console.print("The first run compiles camkit's kernels once (about 10 s more on 2 cores); "
                  "later runs load them from numba's cache.")
    with _Progress(console) as progress:
        r = run_demo(args.output, views=args.views, seed=args.seed, progress=progress)
    job = r.job
    console.print(_view_table(job))
    console.print(_param_table(job.result, r.truth, title="Estimated and true parameters"))
    _summary(console, job)
    console.print(f"images:  {r.image_dir}")
    console.print(f"camera:  {job.camera_file}")
    console.print(f"results: {job.results_file}")
    console.print(f"[bold]report:  {job.report_file}[/bold]  (open it in a browser)")
    console.print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from camkit.calib import held_parameters
    from camkit.io.results import orientation_note
    from camkit.pipeline import calibrate_files, collect_images, prepare_outputs

    console = _console()
    board = _target_of(args)
    fix, free = tuple(args.fix or ()), tuple(args.free or ())
    held_parameters(args.model, fix, free)  # a misspelt name fails here, before any work
    inputs = collect_images(args.images)
    prepare_outputs({"-o": args.output, "--json": args.json, "--report": args.report}, inputs.paths)
    console.print(f"camkit calibrate: {len(inputs.paths)} images, {_describe(board)}, model {args.model}")
    for path, why in inputs.skipped:
        console.print(f"skipped {path}: {why}")
    try:
        with _Progress(console) as progress:
            job = calibrate_files(inputs.paths, board, model=args.model, fix=fix, free=free,
                                  camera_file=args.output, results_file=args.json, report_file=args.report,
                                  progress=progress)
    except EstimationError as exc:
        if exc.detections is not None:  # which images gave a board, and why the others did not
            console.print(_detection_table([p.name for p in inputs.paths], exc.detections))
        raise
    console.print(_view_table(job))
    console.print(_param_table(job.result))
    _summary(console, job)
    note = orientation_note(job.image_info)
    if note:
        console.print(f"[yellow]note: {note}[/yellow]")
    for label, path in (("camera", job.camera_file), ("results", job.results_file), ("report", job.report_file)):
        if path is not None:
            console.print(f"{label + ':':<9}{path}")
    return 0


def _cmd_calibrate_rig(args: argparse.Namespace) -> int:
    from rich.table import Table

    from camkit.calib import held_parameters
    from camkit.pipeline import calibrate_rig_files, collect_images, pair_images, prepare_outputs

    console = _console()
    board = _target_of(args)
    fix, free = tuple(args.fix or ()), tuple(args.free or ())
    held = held_parameters(args.model, fix, free)
    if args.kalibr and args.model == "brown-conrady" and "k3" not in held:
        raise ParameterError("--kalibr: Kalibr's radtan model holds k1, k2, p1, p2 only; add --fix k3 so the "
                             "cameras can be written to a camchain")
    cams: dict[str, list] = {}
    for name, pattern in args.camera:
        if name in cams:
            raise ParameterError(f"--camera: the name {name!r} is given twice")
        cams[name] = collect_images([pattern]).paths
    if len(cams) < 2:
        raise ParameterError("--camera: a rig needs two or more cameras (--camera NAME IMAGES, once per camera)")
    if args.opencv and len(cams) != 2:
        raise ParameterError(f"--opencv: OpenCV's stereo file holds two cameras; the rig has {len(cams)}")
    every = [p for v in cams.values() for p in v]
    prepare_outputs({"-o": args.output, "--opencv": args.opencv, "--kalibr": args.kalibr, "--report": args.report},
                    every)
    instants, paths = pair_images(cams, args.pair_by)
    table = Table(title="Pairing" + (f" (by {args.pair_by!r})" if args.pair_by else " (by sorted order)"),
                  title_justify="left")
    table.add_column("instant")
    for name in cams:
        table.add_column(name)
    for k, key in enumerate(instants):
        table.add_row(key, *[(row[k].name if row[k] is not None else "-") for row in paths])
    console.print(table)
    console.print(f"camkit calibrate-rig: {len(cams)} cameras, {len(instants)} instants, {_describe(board)}, "
                  f"model {args.model}")
    with _Progress(console) as progress:
        job = calibrate_rig_files(cams, board, pair_by=args.pair_by, models=args.model, fix=fix, free=free,
                                  rig_file=args.output, opencv_file=args.opencv, kalibr_file=args.kalibr,
                                  report_file=args.report, progress=progress)
    r = job.result
    res = Table(title="Rig", title_justify="left")
    for col in ("camera", "boards used", "RMS px", "baseline mm", "rotation sigma deg (x y z)",
                "translation sigma mm (x y z)"):
        res.add_column(col, justify="left" if col == "camera" else "right")
    for k, name in enumerate(r.names):
        ref = k == r.reference
        res.add_row(name, str(len(r.cameras[k].view_indices)), f"{r.camera_rms_px[k]:.3f}",
                    "reference" if ref else f"{r.baseline_m[k] * 1000:.2f} +- {r.baseline_sigma_m[k] * 1000:.2f}",
                    "" if ref else " ".join(f"{v:.4f}" for v in r.rotation_sigma_deg[k]),
                    "" if ref else " ".join(f"{v * 1000:.3f}" for v in r.translation_sigma_m[k]))
    console.print(res)
    for k, name in enumerate(r.names):
        console.print(_param_table(r.cameras[k], title=f"Camera {name}"))
    console.print(f"RMS {r.rms_px:.3f} px per corner over every camera; {len(r.rejected)} corners rejected as "
                  f"outliers; {r.message}")
    for c, k, reason in job.left_out:
        console.print(f"[red]camera {r.names[c]}, instant {job.instants[k]}[/red]: {reason}")
    for path in job.written:
        console.print(f"wrote {path}")
    return 0


def _cmd_rectify(args: argparse.Namespace) -> int:
    from camkit.io.rig_files import read_rig
    from camkit.pipeline import collect_images, rectify_files

    console = _console()
    rig = read_rig(args.rig)
    left = collect_images([args.left]).paths
    right = collect_images([args.right]).paths
    cams = tuple(args.cameras) if args.cameras else (0, 1)
    with _Progress(console) as progress:
        job = rectify_files(rig, left, right, args.output, cameras=cams, mode=args.mode,
                            interpolation=args.interpolation, progress=progress, output_option="-o",
                            scheduler=args.scheduler, workers=args.workers, resume=args.resume)
    r = job.rectification
    console.print(f"wrote {len(job.written)} rectified pairs to {job.out_dir} and {job.stereo_file}; the rectified "
                  f"cameras: f={r.left.fx:.2f} cx={r.left.cx:.2f} cy={r.left.cy:.2f} ({r.left.width}x"
                  f"{r.left.height}), baseline {abs(float(r.baseline[1 if r.vertical else 0])) * 1000:.2f} mm; valid "
                  f"rectangles (x, y, w, h) {r.valid_left} and {r.valid_right}")
    return _batch_summary(console, job.summary)


def _mode(text: str) -> str | float:
    if text in ("valid", "full"):
        return text
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected valid, full or a number in [0, 1], got {text!r}") from None
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"expected valid, full or a number in [0, 1], got {text!r}")
    return v


def _describe(board) -> str:
    from camkit.target import AprilGrid, Charuco, Checkerboard

    if isinstance(board, AprilGrid):
        return (f"AprilGrid {board.tags_x}x{board.tags_y} {board.family} tags of {board.tag_size * 1000:g} mm, "
                f"spacing {board.tag_spacing:g}")
    if isinstance(board, Checkerboard):
        return (f"board {board.inner_cols}x{board.inner_rows} inner corners, {board.square * 1000:g} mm "
                "squares")
    if isinstance(board, Charuco):
        return (f"ChArUco board {board.squares_x}x{board.squares_y} squares of {board.square * 1000:g} mm, "
                f"{board.marker * 1000:g} mm markers, {board.dictionary}{' (legacy)' if board.legacy else ''}")
    return f"{board.name} target"


def _cmd_board(args: argparse.Namespace) -> int:
    from camkit.pipeline import prepare_outputs
    from camkit.target import AprilGrid, Charuco, Checkerboard
    from camkit.target.sheet import board_layout, parse_paper, write_board

    if args.target == "aprilgrid":
        missing = [f for f, v in (("--tags", args.tags), ("--tag-size", args.tag_size),
                                  ("--tag-spacing", args.tag_spacing)) if v is None]
        if missing:
            raise ParameterError(f"{', '.join(missing)}: an AprilGrid needs --tags, --tag-size and --tag-spacing")
        board = AprilGrid(*args.tags, args.tag_size, args.tag_spacing, args.family)
    elif args.target == "charuco":
        missing = [f for f, v in (("--squares", args.squares), ("--square", args.square), ("--marker", args.marker))
                   if v is None]
        if missing:
            raise ParameterError(f"{', '.join(missing)}: a ChArUco board needs --squares, --square and --marker")
        board = Charuco(*args.squares, args.square, args.marker, args.dictionary, legacy=args.legacy)
    else:
        if args.inner is None or args.square is None:
            raise ParameterError("--inner, --square: a checkerboard needs both (inner corners, e.g. --inner 9x6)")
        board = Checkerboard(*args.inner, args.square, margin=args.margin)
    paper = parse_paper(args.paper) if args.paper else None
    layout = board_layout(board, paper)  # a board that does not fit is refused here
    prepare_outputs({"-o": args.output})
    path = write_board(args.output, board, paper=paper, dpi=args.dpi)
    what = (f"{args.inner[0]}x{args.inner[1]} inner corners ({args.inner[0] + 1}x{args.inner[1] + 1} squares of "
            f"{args.square * 1000:g} mm)" if args.target == "checkerboard" else _describe(board))
    print(f"wrote {path}: {what}, page {layout.page_w_mm:g} x {layout.page_h_mm:g} mm. "
          "Print at 100 % (actual size) and measure a square.")
    return 0


def _cmd_undistort(args: argparse.Namespace) -> int:
    from camkit.io import read_camera
    from camkit.pipeline import collect_images, undistort_files

    console = _console()
    model = read_camera(args.camera)
    images = collect_images(args.images).paths
    with _Progress(console) as progress:
        job = undistort_files(images, model, args.output, alpha=args.alpha, interpolation=args.interpolation,
                              progress=progress, output_option="-o", scheduler=args.scheduler, workers=args.workers,
                              resume=args.resume)
    new = job.new_model
    console.print(f"wrote {len(job.written)} images to {job.out_dir}; the undistorted camera is a pinhole with "
                  f"fx={new.fx:.2f} fy={new.fy:.2f} cx={new.cx:.2f} cy={new.cy:.2f} ({new.width}x{new.height})")
    return _batch_summary(console, job.summary)


def _cmd_detect(args: argparse.Namespace) -> int:
    from camkit.pipeline import collect_images, detect_files

    console = _console()
    board = _target_of(args)
    inputs = collect_images(args.images)
    console.print(f"camkit detect: {len(inputs.paths)} images, {_describe(board)}")
    with _Progress(console) as progress:
        job = detect_files(inputs.paths, board, args.output, scheduler=args.scheduler, workers=args.workers,
                           resume=args.resume, progress=progress, output_option="-o")
    found = sum(1 for r in job.summary.results.values() if r.get("found"))
    console.print(f"the target was found in {found} of {len(inputs.paths)} images; one JSON file an image in "
                  f"{job.out_dir}")
    return _batch_summary(console, job.summary)


def _batch_summary(console, summary) -> int:
    """Print a batch job's summary and its failed inputs; exit status 1 where any failed."""
    console.print(summary.line() + f"; manifest {summary.manifest}")
    for name, why in summary.failed:
        console.print(f"[red]failed[/red] {name}: {why}")
    return 1 if summary.failed else 0


def _batch_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--workers", type=int, help="worker processes of the local Dask cluster (default: one per core)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on this dask.distributed scheduler, e.g. tcp://host:8786 (default: "
                        "$DASK_SCHEDULER_ADDRESS, else a local cluster)")
    p.add_argument("--resume", action="store_true",
                   help="skip inputs the output folder's manifest records as done (same input bytes, outputs present)")


def _cmd_lens(args: argparse.Namespace) -> int:
    from camkit import optics

    f = args.focal_length
    if args.lens_command == "dof":
        near, far = optics.depth_of_field(f, args.f_number, args.focus, args.coc)
        hyper = optics.hyperfocal_distance(f, args.f_number, args.coc)
        far_txt = "infinity" if not np.isfinite(far) else f"{far:.4g} m"
        print(f"{f * 1000:g} mm at f/{args.f_number:g} focused at {args.focus:g} m, circle of confusion "
              f"{args.coc * 1000:g} mm:")
        print(f"  near {near:.4g} m, far {far_txt}, depth of field "
              f"{'infinite' if not np.isfinite(far) else f'{far - near:.4g} m'}")
        print(f"  hyperfocal distance {hyper:.4g} m")
    elif args.lens_command == "fov":
        w, h = args.sensor
        d = float(np.hypot(w, h))
        fov = [optics.field_of_view_deg(x, f) for x in (w, h, d)]
        print(f"{f * 1000:g} mm on a {w * 1000:g} x {h * 1000:g} mm sensor: horizontal {fov[0]:.2f} deg, "
              f"vertical {fov[1]:.2f} deg, diagonal {fov[2]:.2f} deg (full angles, 2 atan(d / 2f))")
    else:
        ev = optics.exposure_value(args.f_number, args.time, args.iso)
        print(f"f/{args.f_number:g}, {_fmt_time(args.time)}, ISO {args.iso:g}: EV {ev:.2f}")
        print("  the same exposure:")
        for stops in (-2, -1, 1, 2):
            n = args.f_number * 2 ** (stops / 2)
            t = float(optics.equivalent_exposure(args.f_number, args.time, new_f_number=n))
            print(f"    f/{n:.3g} at {_fmt_time(t)}")
    return 0


def _fmt_time(t: float) -> str:
    return f"1/{1 / t:.4g} s" if t < 1 else f"{t:g} s"


def _board_size(text: str) -> tuple[int, int]:
    try:
        cols, rows = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected inner corners as COLSxROWS (e.g. 9x6), got {text!r}") from None
    return cols, rows


#: Units a length may carry on the command line, in metres.
_UNITS = (("mm", 1e-3), ("cm", 1e-2), ("in", 0.0254), ("m", 1.0))


def _target_spec(text: str):
    """A target on the command line: ``checkerboard:9x6,25mm`` (inner corners, square),
    ``charuco:11x8,30mm,22mm,DICT_5X5_100[,legacy]`` (squares, square, marker, dictionary) or
    ``aprilgrid:6x6,88mm,0.3[,tag36h11]`` (tags, tag size, spacing as Kalibr's tagSpacing, family)."""
    from camkit.target import AprilGrid, Charuco, Checkerboard

    kind, _, rest = text.partition(":")
    parts = [p.strip() for p in rest.split(",")] if rest else []
    try:
        if kind == "checkerboard" and len(parts) == 2:
            return Checkerboard(*_board_size(parts[0]), _length_m(parts[1]))
        if kind == "charuco" and len(parts) in (4, 5) and (len(parts) == 4 or parts[4] == "legacy"):
            return Charuco(*_board_size(parts[0]), _length_m(parts[1]), _length_m(parts[2]), parts[3],
                           legacy=len(parts) == 5)
        if kind == "aprilgrid" and len(parts) in (3, 4):
            return AprilGrid(*_board_size(parts[0]), _length_m(parts[1]), _ratio(parts[2]), *parts[3:])
    except CamkitError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    raise argparse.ArgumentTypeError(
        f"expected checkerboard:COLSxROWS,SQUARE (inner corners, e.g. checkerboard:9x6,25mm) or "
        f"charuco:COLSxROWS,SQUARE,MARKER,DICTIONARY[,legacy] (squares, e.g. charuco:11x8,30mm,22mm,DICT_5X5_100) "
        f"or aprilgrid:COLSxROWS,TAGSIZE,SPACING[,FAMILY] (tags, e.g. aprilgrid:6x6,88mm,0.3,tag36h11), got {text!r}")


def _ratio(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number (the gap between tags over the tag's size, e.g. 0.3), "
                                         f"got {text!r}") from None


def _target_of(args: argparse.Namespace, board_flag: str = "--board"):
    """The target of a command: ``--target``, or a checkerboard from ``--board``/``--square``."""
    from camkit.target import Checkerboard

    if args.target is not None:
        if args.board is not None:
            raise ParameterError(f"--target, {board_flag}: give the target one way, not both")
        return args.target
    if args.board is None or args.square is None:
        raise ParameterError(f"{board_flag}, --square: a checkerboard needs both (or give --target)")
    return Checkerboard(*args.board, args.square)


def _length_m(text: str) -> float:
    """A length with its unit: '30mm', '3cm', '0.03m' or '1.5in' (returned in metres). A bare
    number is refused: '30' could be 30 mm or 30 m."""
    t = text.strip().lower().replace(" ", "")
    for unit, scale in _UNITS:
        if t.endswith(unit):
            t, factor = t[: -len(unit)], scale
            break
    else:
        try:
            bare = float(t)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a length with a unit (mm, cm, m or in) such as 30mm, "
                                             f"got {text!r}") from None
        guess = f"{bare:g}mm" if bare >= 1 else f"{bare:g}m"
        raise argparse.ArgumentTypeError(f"a length needs a unit (mm, cm, m or in): did you mean {guess}? "
                                         f"got {text!r}")
    try:
        value = float(t) * factor
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a length with a unit (mm, cm, m or in) such as 30mm, "
                                         f"got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a positive length, got {text!r}")
    return value


def _sensor_size(text: str) -> tuple[float, float]:
    try:
        w, h = (float(v) / 1000.0 for v in text.lower().removesuffix("mm").split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a sensor size WxH in mm (e.g. 36x24), got {text!r}") from None
    if not (w > 0 and h > 0):
        raise argparse.ArgumentTypeError(f"expected a positive sensor size, got {text!r}")
    return w, h


def _seconds(text: str) -> float:
    try:
        num, _, den = text.strip().removesuffix("s").partition("/")
        value = float(num) / (float(den) if den else 1.0)
    except (ValueError, ZeroDivisionError):
        raise argparse.ArgumentTypeError(f"expected a time such as 1/125 or 0.008, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a positive time, got {text!r}")
    return value


def _cmd_simulate(args: argparse.Namespace) -> int:
    from camkit.lens import LateralChromaticAberration
    from camkit.render import Defocus, Effects, Exposure, Motion, default_camera
    from camkit.sensor import EMVA1288Sensor
    from camkit.target import Checkerboard

    camera = default_camera(args.model)
    board = args.target if args.target is not None else Checkerboard(*args.board, args.square)
    exposure_time = 0.01
    effects = Effects(
        chromatic=LateralChromaticAberration(vr=1.0006, vb=0.9994) if args.chromatic else None,
        defocus=Defocus(focal_length=0.0048, f_number=args.f_number, focus_distance=args.defocus,
                        pixel_pitch=0.0048 / camera.fx) if args.defocus else None,
        motion=Motion(linear_velocity=(args.motion, 0.0, 0.0), exposure_time=exposure_time)
        if args.motion else None,
        exposure=Exposure(photons_at_white=20000.0, exposure_time=exposure_time) if args.noise else None,
        sensor=EMVA1288Sensor() if args.noise else None,
        cfa=args.bayer,
        demosaic=None if args.demosaic == "raw" else args.demosaic,
    )
    console = _console()
    console.print(f"camkit simulate: {args.views} views of the {_describe(board)} through the built-in "
                  f"{camera.name} camera, seed {args.seed}")
    from camkit.pipeline import simulate_files

    with _Progress(console) as progress:
        job = simulate_files(args.output, camera, board, args.views, seed=args.seed, effects=effects,
                             bit_depth=args.bit_depth, fmt=args.format, quality=args.quality,
                             shard_size=args.shard_size, scheduler=args.scheduler, workers=args.workers,
                             resume=args.resume, progress=progress)
    where = (f"{job.shards} shards of {args.shard_size or 1000} views (dataset.json, and truth.jsonl in each shard)"
             if job.shards > 1 or args.shard_size else "truth.json")
    console.print(f"wrote {job.summary.done + job.summary.skipped} images and {where} to {job.out_dir}")
    return _batch_summary(console, job.summary)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="camkit", description="The whole camera in one library.")
    parser.add_argument("--version", action="version", version=f"camkit {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = sub.add_parser("demo", help="simulate a camera, calibrate it and write a report (the whole pipeline)")
    demo.add_argument("-o", "--output", default="camkit-demo", help="output folder (default ./camkit-demo)")
    demo.add_argument("--views", type=int, default=15, help="number of simulated views (default 15)")
    demo.add_argument("--seed", type=int, default=0, help="random seed of the simulation (default 0)")
    demo.set_defaults(func=_cmd_demo)

    cal = sub.add_parser("calibrate", help="calibrate a camera from photos of a checkerboard")
    cal.add_argument("images", nargs="+", metavar="IMAGES",
                     help="image files, folders or glob patterns (JPEG, PNG, TIFF, BMP, WebP, PGM/PPM, camera RAW)")
    cal.add_argument("--board", type=_board_size, help="a checkerboard's inner corners COLSxROWS, e.g. 9x6")
    cal.add_argument("--square", type=_length_m, help="the checkerboard's square side, e.g. 25mm")
    cal.add_argument("--target", type=_target_spec, metavar="SPEC",
                     help="another target instead of --board/--square: charuco:COLSxROWS,SQUARE,MARKER,DICTIONARY"
                          "[,legacy] (squares; e.g. charuco:11x8,30mm,22mm,DICT_5X5_100) or "
                          "aprilgrid:COLSxROWS,TAGSIZE,SPACING[,FAMILY] (tags; e.g. aprilgrid:6x6,88mm,0.3)")
    cal.add_argument("--model", default="brown-conrady", choices=_model_names(),
                     help="lens model (kannala-brandt for fisheye lenses)")
    cal.add_argument("--fix", action="append", metavar="NAME",
                     help="hold this parameter or group at its start value, besides the model's defaults "
                          "(repeatable; e.g. --fix k3 --fix tangential)")
    cal.add_argument("--free", action="append", metavar="NAME",
                     help="estimate a parameter the model holds by default (repeatable; e.g. --free skew)")
    cal.add_argument("-o", "--output", default="camera.json", help="camera file to write (default camera.json)")
    cal.add_argument("--json", metavar="RESULTS", help="also write the results (residuals, sigmas, views) here")
    cal.add_argument("--report", metavar="HTML", help="also write an HTML report here")
    cal.set_defaults(func=_cmd_calibrate)

    rig = sub.add_parser("calibrate-rig", help="calibrate a stereo pair or camera rig from photos taken at the same "
                                               "instants")
    rig.add_argument("--camera", nargs=2, action="append", required=True, metavar=("NAME", "IMAGES"),
                     help="a camera's name and its images (a folder or a quoted glob pattern); once per camera")
    rig.add_argument("--pair-by", metavar="REGEX",
                     help="pair the images by the part of their names this matches (its first group if any), e.g. "
                          "'(\\d+)'; default: by sorted order")
    rig.add_argument("--board", type=_board_size, help="a checkerboard's inner corners COLSxROWS, e.g. 9x6")
    rig.add_argument("--square", type=_length_m, help="the checkerboard's square side, e.g. 25mm")
    rig.add_argument("--target", type=_target_spec, metavar="SPEC", help="another target, as for calibrate")
    rig.add_argument("--model", default="brown-conrady", choices=_model_names(), help="lens model of every camera")
    rig.add_argument("--fix", action="append", metavar="NAME", help="as for calibrate")
    rig.add_argument("--free", action="append", metavar="NAME", help="as for calibrate")
    rig.add_argument("-o", "--output", default="rig.json", help="rig file to write (default rig.json)")
    rig.add_argument("--opencv", metavar="YAML", help="also write OpenCV's stereo file (two cameras)")
    rig.add_argument("--kalibr", metavar="YAML", help="also write a Kalibr camchain")
    rig.add_argument("--report", metavar="HTML", help="also write an HTML report (the rig from above, a rectified "
                                                      "pair, every camera)")
    rig.set_defaults(func=_cmd_calibrate_rig)

    rect = sub.add_parser("rectify", help="rectify stereo pairs with a rig file")
    rect.add_argument("rig", metavar="RIG", help="a rig file: camkit rig JSON, OpenCV stereo YAML or Kalibr camchain")
    rect.add_argument("left", metavar="LEFT", help="the left images (a file, folder or quoted glob)")
    rect.add_argument("right", metavar="RIGHT", help="the right images, paired with the left ones by sorted order")
    rect.add_argument("--cameras", nargs=2, metavar=("LEFT_NAME", "RIGHT_NAME"),
                      help="which cameras of the rig (default its first two)")
    rect.add_argument("--mode", type=_mode, default="valid",
                      help="valid (no black borders, default), full (every source pixel kept) or a number in [0, 1]")
    rect.add_argument("--interpolation", default="bilinear", choices=("nearest", "bilinear", "bicubic", "lanczos3"))
    rect.add_argument("-o", "--output", required=True, help="output folder (inputs are never overwritten)")
    _batch_options(rect)
    rect.set_defaults(func=_cmd_rectify)

    brd = sub.add_parser("board", help="write a printable checkerboard, ChArUco board or AprilGrid (pdf, svg or "
                                       "png) at exact scale")
    brd.add_argument("--target", default="checkerboard", choices=("checkerboard", "charuco", "aprilgrid"),
                     help="the kind of board (default checkerboard)")
    brd.add_argument("--inner", type=_board_size, help="checkerboard: inner corners COLSxROWS, e.g. 9x6")
    brd.add_argument("--squares", type=_board_size, help="ChArUco: squares COLSxROWS, e.g. 11x8")
    brd.add_argument("--square", type=_length_m, help="square side, e.g. 25mm")
    brd.add_argument("--marker", type=_length_m, help="ChArUco: marker side, e.g. 22mm")
    brd.add_argument("--dictionary", default="DICT_5X5_100", help="ChArUco: marker dictionary (default DICT_5X5_100)")
    brd.add_argument("--legacy", action="store_true", help="ChArUco: OpenCV's pattern before 4.6")
    brd.add_argument("--tags", type=_board_size, help="AprilGrid: tags COLSxROWS, e.g. 6x6")
    brd.add_argument("--tag-size", type=_length_m, help="AprilGrid: a tag's side, e.g. 88mm")
    brd.add_argument("--tag-spacing", type=_ratio,
                     help="AprilGrid: the gap between tags over the tag's side (Kalibr's tagSpacing), e.g. 0.3")
    brd.add_argument("--family", default="tag36h11", help="AprilGrid: tag family (default tag36h11)")
    brd.add_argument("--margin", type=_length_m, help="white margin (default one square)")
    brd.add_argument("--dpi", type=int, default=300, help="pixels per inch for .png (default 300)")
    brd.add_argument("--paper", help="centre the board on A4, A3, letter or WxHmm paper (default: the board's own "
                                     "sheet)")
    brd.add_argument("-o", "--output", required=True, help="board.pdf, board.svg or board.png")
    brd.set_defaults(func=_cmd_board)

    und = sub.add_parser("undistort", help="remove lens distortion from images")
    und.add_argument("camera", metavar="CAMERA",
                     help="a camera file: camkit JSON, OpenCV/ROS YAML, Kalibr camchain or COLMAP cameras.txt")
    und.add_argument("images", nargs="+", metavar="IMAGES")
    und.add_argument("-o", "--output", required=True, help="output folder (inputs are never overwritten)")
    und.add_argument("--alpha", type=float, default=0.0,
                     help="0: crop to valid pixels (default); 1: keep every source pixel")
    und.add_argument("--interpolation", default="bicubic", choices=("nearest", "bilinear", "bicubic", "lanczos3"))
    _batch_options(und)
    und.set_defaults(func=_cmd_undistort)

    det = sub.add_parser("detect", help="detect a target in images and write the detections as JSON (one file an "
                                        "image), for your own solver")
    det.add_argument("images", nargs="+", metavar="IMAGES", help="image files, folders or glob patterns")
    det.add_argument("--board", type=_board_size, help="a checkerboard's inner corners COLSxROWS, e.g. 9x6")
    det.add_argument("--square", type=_length_m, help="the checkerboard's square side, e.g. 25mm")
    det.add_argument("--target", type=_target_spec, metavar="SPEC", help="another target, as for calibrate")
    det.add_argument("-o", "--output", required=True, help="output folder (one <image stem>.json an image)")
    _batch_options(det)
    det.set_defaults(func=_cmd_detect)

    lens = sub.add_parser("lens", help="lens calculators: depth of field, field of view, exposure")
    lsub = lens.add_subparsers(dest="lens_command", metavar="CALCULATOR", required=True)
    dof = lsub.add_parser("dof", help="depth of field and hyperfocal distance")
    dof.add_argument("--focal-length", type=_length_m, required=True, help="e.g. 50mm")
    dof.add_argument("--f-number", type=float, required=True, help="e.g. 2.8")
    dof.add_argument("--focus", type=_length_m, required=True, help="focus distance, e.g. 3m")
    dof.add_argument("--coc", type=_length_m, default=0.00003, help="circle of confusion (default 0.03mm)")
    fov = lsub.add_parser("fov", help="field of view")
    fov.add_argument("--focal-length", type=_length_m, required=True, help="e.g. 50mm")
    fov.add_argument("--sensor", type=_sensor_size, default=(0.036, 0.024), help="WxH in mm (default 36x24)")
    exp = lsub.add_parser("exposure", help="exposure value and equivalent exposures")
    exp.add_argument("--f-number", type=float, required=True)
    exp.add_argument("--time", type=_seconds, required=True, help="exposure time, e.g. 1/125 or 0.008")
    exp.add_argument("--iso", type=float, default=100.0)
    exp.set_defaults(focal_length=None)
    lens.set_defaults(func=_cmd_lens)

    sim = sub.add_parser("simulate", help="render a calibration dataset with exact ground truth")
    sim.add_argument("--views", type=int, default=15, help="number of views (default 15)")
    sim.add_argument("--board", type=_board_size, default=(9, 6), help="inner corners COLSxROWS (default 9x6)")
    sim.add_argument("--square", type=_length_m, default=0.03, help="square side, e.g. 30mm (default 0.03 m)")
    sim.add_argument("--target", type=_target_spec, metavar="SPEC",
                     help="another target instead of --board/--square, e.g. charuco:11x8,30mm,22mm,DICT_5X5_100 or "
                          "aprilgrid:6x6,88mm,0.3")
    sim.add_argument("--model", default="brown-conrady", choices=_model_names())
    sim.add_argument("--bit-depth", type=int, default=8, choices=(8, 16),
                     help="bits per sample of the files: 8 (default) or 16 (the sensor's full range, white at 65535)")
    sim.add_argument("--seed", type=int, default=0, help="random seed: the same seed gives the same files")
    sim.add_argument("-o", "--output", required=True, help="output folder")
    sim.add_argument("--noise", action="store_true", help="expose and read out through an EMVA 1288 sensor")
    sim.add_argument("--bayer", choices=("RGGB", "BGGR", "GRBG", "GBRG"), help="colour filter mosaic")
    sim.add_argument("--demosaic", default="menon", choices=("bilinear", "malvar", "menon", "raw"),
                     help="demosaicing method with --bayer, or 'raw' for the mosaic itself")
    sim.add_argument("--defocus", type=_length_m, metavar="FOCUS_DISTANCE",
                     help="focus the 4.8 mm lens at this distance (thin-lens blur elsewhere)")
    sim.add_argument("--f-number", type=float, default=2.0, help="aperture for --defocus (default 2.0)")
    sim.add_argument("--motion", type=float, metavar="M_PER_S", help="camera speed along x during a 10 ms exposure")
    sim.add_argument("--chromatic", action="store_true", help="lateral chromatic aberration")
    sim.add_argument("--format", default="png", choices=("png", "jpeg"), help="image files (default png)")
    sim.add_argument("--quality", type=int, default=95, help="JPEG quality 1-100 (default 95)")
    sim.add_argument("--shard-size", type=int, metavar="N",
                     help="write the dataset in shards of N views (a folder and a truth.jsonl each; default: one "
                          "folder up to 1000 views, shards of 1000 beyond)")
    _batch_options(sim)
    sim.set_defaults(func=_cmd_simulate)

    exp_ = sub.add_parser("export", help="write a camera file in another format")
    exp_.add_argument("camera", metavar="CAMERA",
                      help="a camera file: camkit JSON, OpenCV/ROS YAML, Kalibr camchain or COLMAP cameras.txt")
    exp_.add_argument("--to", required=True, choices=_export_formats(), help="the format to write")
    exp_.add_argument("-o", "--output", help="file to write (default: print to the terminal)")
    exp_.set_defaults(func=_cmd_export)
    return parser


def _model_names() -> tuple[str, ...]:
    from camkit.lens.base import MODELS

    return tuple(sorted(MODELS))


def _export_formats() -> tuple[str, ...]:
    from camkit.io.camera_files import EXPORT_FORMATS

    return EXPORT_FORMATS


def _cmd_export(args: argparse.Namespace) -> int:
    import tempfile
    from pathlib import Path

    from camkit.io.camera_files import export_camera, read_camera
    from camkit.pipeline import prepare_outputs

    model = read_camera(args.camera)
    if args.output:
        prepare_outputs({"-o": args.output}, [Path(args.camera)])
        path = export_camera(model, args.output, args.to)
        print(f"wrote {path}: {model.name} camera {model.width}x{model.height} as {args.to}")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        path = export_camera(model, Path(tmp) / "camera", args.to)
        sys.stdout.write(path.read_text())
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args))
    except CamkitError as exc:
        print(f"camkit {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:  # a disk full, a folder that vanished, a permission taken away mid-run
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"camkit {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        # Files are written to a temporary name and renamed when complete: nothing half-written
        # is left behind.
        print(f"camkit {args.command}: interrupted; no partial file was written", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug: one line, and the traceback only on request
        if os.environ.get("CAMKIT_DEBUG"):
            raise
        print(f"camkit {args.command}: internal error: {type(exc).__name__}: {exc} (please report it; set "
              "CAMKIT_DEBUG=1 for the traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
