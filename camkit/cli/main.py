"""Entry point of the ``camkit`` command."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np

from camkit import __version__
from camkit.errors import CamkitError

__all__ = ["main"]


def _cmd_demo(args: argparse.Namespace) -> int:
    from camkit.demo import run_demo

    r = run_demo()
    cam = r.camera
    fov = cam.fov_deg()
    print("camkit demo: a 9x6 checkerboard (30 mm squares) seen by a 6 mm lens on a 3.45 um sensor")
    print(f"  camera   {cam.width}x{cam.height} px, fx={cam.fx:.2f} fy={cam.fy:.2f} "
          f"cx={cam.cx:.2f} cy={cam.cy:.2f}")
    print(f"  view     {fov.horizontal_deg:.2f} x {fov.vertical_deg:.2f} deg "
          f"(diagonal {fov.diagonal_deg:.2f} deg)")
    ypr = np.degrees(r.cam_from_board.inverse().ypr())
    print(f"  pose     board origin at z = {r.cam_from_board.t[2]:.3f} m; camera yaw/pitch/roll "
          f"{ypr[0]:.2f}/{ypr[1]:.2f}/{ypr[2]:.2f} deg relative to the board")
    lo, hi = r.pixels.min(axis=0), r.pixels.max(axis=0)
    print(f"  pixels   {len(r.pixels)} corners projected, x in [{lo[0]:.1f}, {hi[0]:.1f}], "
          f"y in [{lo[1]:.1f}, {hi[1]:.1f}]")
    print(f"  checks   project/unproject round trip {r.round_trip_error_px:.2e} px; "
          f"P = K[R|t] decomposition {r.decomposition_error:.2e}")
    return 0


def _board_size(text: str) -> tuple[int, int]:
    try:
        cols, rows = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected inner corners as COLSxROWS (e.g. 9x6), got {text!r}") from None
    return cols, rows


def _length_m(text: str) -> float:
    """'30mm', '3cm', '0.03m' or '0.03' (metres)."""
    t = text.strip().lower()
    for unit, scale in (("mm", 1e-3), ("cm", 1e-2), ("m", 1.0)):
        if t.endswith(unit):
            t, factor = t[: -len(unit)], scale
            break
    else:
        factor = 1.0
    try:
        value = float(t) * factor
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a length such as 30mm or 0.03, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a positive length, got {text!r}")
    return value


def _cmd_simulate(args: argparse.Namespace) -> int:
    from camkit.calib import Checkerboard
    from camkit.lens import LateralChromaticAberration
    from camkit.render import Defocus, Effects, Exposure, Motion, default_camera, simulate_dataset
    from camkit.sensor import EMVA1288Sensor

    camera = default_camera(args.model)
    board = Checkerboard(*args.board, args.square)
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
    print(f"camkit simulate: {args.views} views of a {args.board[0]}x{args.board[1]} board "
          f"({args.square * 1000:g} mm squares) through the built-in {camera.name} camera, seed {args.seed}")

    def progress(done: int, total: int) -> None:
        print(f"\r  rendering {done}/{total}", end="" if done < total else "\n", flush=True)

    out = simulate_dataset(args.output, camera, board, args.views, seed=args.seed, effects=effects,
                           progress=progress)
    print(f"  wrote {args.views} images and truth.json to {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="camkit", description="The whole camera in one library.")
    parser.add_argument("--version", action="version", version=f"camkit {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = sub.add_parser("demo", help="run the built-in demonstration on a simulated camera")
    demo.set_defaults(func=_cmd_demo)

    sim = sub.add_parser("simulate", help="render a calibration dataset with exact ground truth")
    sim.add_argument("--views", type=int, default=15, help="number of views (default 15)")
    sim.add_argument("--board", type=_board_size, default=(9, 6), help="inner corners COLSxROWS (default 9x6)")
    sim.add_argument("--square", type=_length_m, default=0.03, help="square side, e.g. 30mm (default 0.03 m)")
    sim.add_argument("--model", default="brown-conrady", choices=("pinhole", "brown-conrady", "kannala-brandt"))
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
    sim.set_defaults(func=_cmd_simulate)
    return parser


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


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
