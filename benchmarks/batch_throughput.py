"""Batch jobs on Dask (issue 25, items 2 and 6): throughput, scaling, memory, per-task overhead.

- undistort: ``--images`` 12 MP JPEG files (4000x3000 RGB, quality 90), read -> remap
  (bicubic) -> write PNG (each side's default: zlib level 1, the SUB filter and run-length
  strategy on both, libpng on both): camkit's ``undistort_files`` on a fresh
  local cluster of 2 workers (the job as a user runs it, cluster start included) and of 1
  worker, against a plain Python loop over ``cv2.imread`` + ``cv2.remap`` (INTER_CUBIC, the
  same undistortion map) + ``cv2.imwrite``;
- simulate: ``--views`` rendered views (1280x960 PNG), 1 worker against 2;
- memory: the workers' peak resident memory (``ru_maxrss``, read in each worker after the job)
  undistorting 20 and 2000 small images (640x480);
- overhead: the wall time per task of a job whose tasks do almost nothing (a 64x48 image with
  no board, detected), less the tasks' own time.

Run: ``python -m benchmarks.batch_throughput [--images 200] [--views 1000] [--skip-memory]``.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np


def _write_inputs(folder: Path, n: int, h: int, w: int) -> list[Path]:
    import cv2

    from camkit.io import write_image

    rng = np.random.default_rng(0)
    small = rng.random((h // 50 + 2, w // 50 + 2, 3))
    base = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    yy, xx = np.mgrid[0:h, 0:w]
    board = (((xx // (w // 16)) + (yy // (h // 12))) % 2).astype(np.float64)[..., None]
    img = np.clip((0.5 * base + 0.5 * board) * 255, 0, 255).astype(np.uint8)
    paths = []
    for k in range(n):
        p = folder / f"img_{k:04d}.jpg"
        write_image(p, np.roll(img, 7 * k, axis=1), quality=90)
        paths.append(p)
    return paths


def undistort(n: int) -> dict[str, float]:
    import cv2

    from camkit.lens import BrownConrady
    from camkit.pipeline import undistort_files
    from camkit.resample import optimal_pinhole

    cam = BrownConrady(fx=3500.0, fy=3500.0, cx=1999.5, cy=1499.5, width=4000, height=3000, k1=-0.12, k2=0.03)
    new = optimal_pinhole(cam, 0.0)
    tmp = Path(tempfile.mkdtemp(prefix="camkit-bench-"))
    try:
        (tmp / "in").mkdir()
        paths = _write_inputs(tmp / "in", n, 3000, 4000)
        K = cam.K
        dist = np.array([cam.k1, cam.k2, cam.p1, cam.p2, cam.k3])
        t0 = time.perf_counter()
        mx, my = cv2.initUndistortRectifyMap(K, dist, None, new.K, (4000, 3000), cv2.CV_32FC1)
        (tmp / "cv").mkdir()
        for p in paths:
            img = cv2.imread(str(p), cv2.IMREAD_COLOR)
            out = cv2.remap(img, mx, my, cv2.INTER_CUBIC, borderMode=cv2.BORDER_CONSTANT)
            cv2.imwrite(str(tmp / "cv" / (p.stem + ".png")), out)
        t_cv = time.perf_counter() - t0
        res = {"opencv loop": n / t_cv}
        for workers in (2, 1):
            t0 = time.perf_counter()
            job = undistort_files(paths, cam, tmp / f"ck{workers}", workers=workers)
            dt = time.perf_counter() - t0
            assert job.summary.done == n and not job.summary.failed
            res[f"camkit {workers} workers"] = n / dt
        return res
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def simulate(views: int, one_thread: bool = False) -> dict[str, float]:
    """Views per second on 1 and 2 workers: the default local cluster (numba's threads =
    cores / workers, so one worker already renders on every core), or, with ``one_thread``,
    workers of one numba thread each (a worker per core, as on a cluster's nodes)."""
    from dask.distributed import Client, LocalCluster

    from camkit.pipeline import simulate_files
    from camkit.render import default_camera
    from camkit.target import Checkerboard

    cam = default_camera("brown-conrady")
    board = Checkerboard(inner_cols=9, inner_rows=6, square=0.03)
    tmp = Path(tempfile.mkdtemp(prefix="camkit-bench-"))
    res = {}
    try:
        for workers in (1, 2):
            t0 = time.perf_counter()
            if one_thread:
                with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                  dashboard_address="127.0.0.1:0", host="127.0.0.1",
                                  env={"NUMBA_NUM_THREADS": "1"}) as cluster, \
                        Client(cluster) as client:
                    job = simulate_files(tmp / f"w{workers}", cam, board, views, seed=1, client=client)
            else:
                job = simulate_files(tmp / f"w{workers}", cam, board, views, seed=1, workers=workers)
            res[f"camkit {workers} workers"] = views / (time.perf_counter() - t0)
            assert job.summary.done == views
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return res


def memory(counts: tuple[int, ...] = (20, 2000)) -> dict[int, float]:
    import resource

    from dask.distributed import Client, LocalCluster

    from camkit.lens import BrownConrady
    from camkit.pipeline import undistort_files

    cam = BrownConrady(fx=500.0, fy=500.0, cx=319.5, cy=239.5, width=640, height=480, k1=-0.1)
    out = {}
    tmp = Path(tempfile.mkdtemp(prefix="camkit-bench-"))
    try:
        (tmp / "in").mkdir()
        paths = _write_inputs(tmp / "in", max(counts), 480, 640)
        for n in counts:
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                              host="127.0.0.1") as cluster, Client(cluster) as client:
                before = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
                undistort_files(paths[:n], cam, tmp / f"out{n}", client=client)
                peaks = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
            out[n] = max(peaks.values()) / 1024.0  # kB -> MB (Linux)
            print(f"  {n} inputs: workers' peak RSS {sorted(v / 1024 for v in before.values())} MB before the job, "
                  f"{sorted(v / 1024 for v in peaks.values())} MB after")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def overhead(n: int = 400) -> tuple[float, float]:
    from dask.distributed import Client, LocalCluster

    from camkit.io import write_png
    from camkit.pipeline import detect_files
    from camkit.target import Checkerboard

    tmp = Path(tempfile.mkdtemp(prefix="camkit-bench-"))
    try:
        (tmp / "in").mkdir()
        paths = [write_png(tmp / "in" / f"b{k:04d}.png", np.full((48, 64), 128, np.uint8)) for k in range(n)]
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                          host="127.0.0.1") as cluster, Client(cluster) as client:
            detect_files(paths[:20], Checkerboard(inner_cols=5, inner_rows=4, square=0.03), tmp / "warm",
                         client=client)
            t0 = time.perf_counter()
            job = detect_files(paths, Checkerboard(inner_cols=5, inner_rows=4, square=0.03), tmp / "out",
                               client=client)
            wall = time.perf_counter() - t0
        work = sum(r["seconds"] for r in job.summary.results.values())
        return wall / n * 1e3, (wall - work / 2) / n * 1e3
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=200)
    ap.add_argument("--views", type=int, default=1000)
    ap.add_argument("--skip-memory", action="store_true")
    ap.add_argument("--skip-overhead", action="store_true")
    ap.add_argument("--one-thread", action="store_true",
                    help="simulate on workers of one numba thread each (scaling by workers, one core each)")
    a = ap.parse_args()
    if a.images:
        r = undistort(a.images)
        print(f"undistort {a.images} x 12 MP JPEG -> PNG, images/s: " + ", ".join(f"{k} {v:.3f}" for k, v in r.items()))
        print(f"  camkit 2 workers / OpenCV loop: {r['camkit 2 workers'] / r['opencv loop']:.2f} (asked >= 1.5); "
              f"2 workers / 1 worker: {r['camkit 2 workers'] / r['camkit 1 workers']:.2f} (asked >= 1.7)")
    if a.views:
        s = simulate(a.views, a.one_thread)
        how = "workers of one numba thread" if a.one_thread else "the default local cluster"
        print(f"simulate {a.views} views 1280x960 ({how}), views/s: "
              + ", ".join(f"{k} {v:.3f}" for k, v in s.items()))
        print(f"  2 workers / 1 worker: {s['camkit 2 workers'] / s['camkit 1 workers']:.2f} (asked >= 1.7)")
    if not a.skip_memory:
        m = memory()
        sizes = ", ".join(f"{n} inputs {v:.0f} MB" for n, v in m.items())
        print(f"peak worker RSS, undistorting 640x480 images: {sizes} (difference "
              f"{abs(m[2000] - m[20]) / m[20] * 100:.1f} %, asked < 20 %)")
    if not a.skip_overhead:
        per, over = overhead()
        print(f"per-task time of near-empty tasks: {per:.2f} ms wall a task on 2 workers, of which overhead "
              f"{over:.2f} ms")


if __name__ == "__main__":
    main()
