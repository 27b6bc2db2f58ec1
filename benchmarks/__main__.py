"""Run every benchmark: ``python -m benchmarks [-k SUBSTRING] [--no-write]``.

Prints a markdown table (camkit's median, the peer's median, the ratio, all measured in this
run) and writes it to benchmarks/RESULTS.md with the date and the command.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import importlib
import os
import platform
import sys
from pathlib import Path

import numba

from benchmarks.harness import markdown_table, run_case

MODULES = [
    "bench_geometry", "bench_lens", "bench_resample", "bench_sensor", "bench_render", "bench_detect", "bench_charuco",
    "bench_calib", "bench_stereo",
]
RESULTS = Path(__file__).with_name("RESULTS.md")
NOTES = Path(__file__).with_name("notes.md")  # appended to RESULTS.md: what a table alone cannot say


def main() -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks")
    parser.add_argument("-k", default="", help="run only cases whose operation contains this text")
    parser.add_argument("--no-write", action="store_true", help="do not rewrite RESULTS.md")
    args = parser.parse_args()

    rows = []
    extra = []
    for mod_name in MODULES:
        mod = importlib.import_module(f"benchmarks.{mod_name}")
        if hasattr(mod, "extra_tables") and not args.k:
            extra.append(mod.extra_tables())
        for case in mod.cases():
            if args.k and args.k.lower() not in case.operation.lower():
                continue
            row = run_case(case)
            print(f"  {case.operation} [{case.size}]: camkit {row.camkit_s * 1e3:.2f} ms, "
                  f"{case.peer_name} {row.peer_s * 1e3:.2f} ms, ratio {row.ratio:.3f}",
                  file=sys.stderr, flush=True)
            rows.append(row)
    table = markdown_table(rows) + "".join("\n" + t for t in extra)
    print(table)
    if not args.no_write and not args.k:
        now = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
        machine = f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
        threads = (f"numba's {numba.threading_layer()!r} threading layer with "
                   f"OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY', '(unset)')}")
        RESULTS.write_text(
            "# Benchmark results\n\n"
            f"Measured {now} on {machine} with `python -m benchmarks`,\n"
            f"{threads} (docs/conventions.md, \"Threads\").\n"
            "Each time is the median of several repeats after warm-up calls (numba compilation\n"
            "excluded). camkit and the peer are timed alternately, call beside call, and the ratio\n"
            "is the median of those pairs' ratios: on this shared, noisy machine the ratio is what\n"
            "counts, and it still moves between runs (see the notes below the tables).\n\n" + table
            + (("\n" + NOTES.read_text()) if NOTES.exists() else "")
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
