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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="camkit", description="The whole camera in one library.")
    parser.add_argument("--version", action="version", version=f"camkit {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = sub.add_parser("demo", help="run the built-in demonstration on a simulated camera")
    demo.set_defaults(func=_cmd_demo)
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
