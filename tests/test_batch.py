"""Batch jobs on a real dask.distributed LocalCluster (issue 25): outputs, the manifest,
failing inputs, resume, and a worker process killed mid-run."""

from __future__ import annotations

import json
import os
import signal
import threading

import numpy as np
import pytest

from camkit.io import read_image, write_png
from camkit.lens import BrownConrady
from camkit.pipeline import undistort_files

distributed = pytest.importorskip("distributed")

CAM = BrownConrady(fx=200.0, fy=200.0, cx=159.5, cy=119.5, width=320, height=240, k1=-0.15)


@pytest.fixture(scope="module")
def client():
    """Two worker processes on the loopback interface, one task thread each (numba on one
    thread: two cores in CI)."""
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                           host="127.0.0.1", env={"NUMBA_NUM_THREADS": "1"})
    c = Client(cluster, timeout=60)
    yield c
    c.close()
    cluster.close()


@pytest.fixture()
def images(tmp_path):
    rng = np.random.default_rng(0)
    folder = tmp_path / "in"
    folder.mkdir()
    paths = []
    for k in range(12):
        paths.append(write_png(folder / f"img{k:02d}.png", rng.integers(0, 256, (240, 320), dtype=np.uint8)))
    return paths


def test_outputs_manifest_and_a_corrupt_input(client, images, tmp_path):
    bad = images[0].parent / "corrupt.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 50)
    out = tmp_path / "out"
    job = undistort_files([*images, bad], CAM, out, client=client, timeout=120)
    s = job.summary
    assert s.done == 12 and s.skipped == 0 and [f for f, _ in s.failed] == [str(bad)]
    assert "corrupt.png" in s.failed[0][1] or "not" in s.failed[0][1]
    assert sorted(p.name for p in out.glob("*.png")) == [f"img{k:02d}.png" for k in range(12)]
    # The same pixels as the single-process path.
    from camkit.resample import undistort_image

    ref = undistort_image(read_image(images[3]), CAM, job.new_model, interpolation="bicubic")
    assert np.array_equal(read_image(out / "img03.png"), ref)
    recs = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]
    assert len(recs) == 13 and {r["status"] for r in recs} == {"done", "failed"}
    assert all(len(r["input_sha256"]) == 64 for r in recs)


def test_resume_skips_what_is_complete(client, images, tmp_path):
    out = tmp_path / "out"
    undistort_files(images, CAM, out, client=client, timeout=120)
    again = undistort_files(images, CAM, out, client=client, resume=True, timeout=120).summary
    assert again.done == 0 and again.skipped == 12
    # A changed input and a deleted output are done again; the rest is skipped.
    write_png(images[1], np.zeros((240, 320), np.uint8))
    (out / "img05.png").unlink()
    third = undistort_files(images, CAM, out, client=client, resume=True, timeout=120).summary
    assert third.done == 2 and third.skipped == 10
    assert read_image(out / "img01.png").max() == 0


def test_resume_redoes_a_pair_whose_right_image_changed(client, images, tmp_path):
    """A stereo pair is one item of two files: the manifest holds both files' hashes (read
    once each, from the bytes the task decoded), and a change to the right one alone redoes
    the pair on resume."""
    from camkit.batch import file_sha256
    from camkit.calib.rig import CameraRig
    from camkit.geometry import Pose
    from camkit.pipeline import rectify_files

    rig = CameraRig(("left", "right"), (CAM, CAM), (Pose.identity(), Pose.from_rvec([0.0, 0.0, 0.0],
                                                                                     [-0.1, 0.0, 0.0])))
    left, right = images[:3], images[3:6]
    out = tmp_path / "out"
    rectify_files(rig, left, right, out, client=client, timeout=120)
    recs = {r["key"]: r for r in map(json.loads, (out / "manifest.jsonl").read_text().splitlines())}
    first = recs[f"{left[0].name}|{right[0].name}"]
    assert first["inputs"] == [str(left[0]), str(right[0])] and first["input"] == str(left[0])
    assert first["inputs_sha256"] == [file_sha256(left[0]), file_sha256(right[0])]
    write_png(right[1], np.zeros((240, 320), np.uint8))
    again = rectify_files(rig, left, right, out, client=client, resume=True, timeout=120).summary
    assert again.done == 1 and again.skipped == 2
    assert read_image(out / "right" / f"{right[1].stem}.png").max() == 0


def test_a_worker_killed_mid_run_does_not_stop_the_job(client, tmp_path):
    """One worker process is killed (SIGKILL) after the first image is done: its tasks run
    again on the other worker or the restarted one; every output exists exactly once and no
    temporary file is left."""
    rng = np.random.default_rng(1)
    folder = tmp_path / "in"
    folder.mkdir()
    big = BrownConrady(fx=800.0, fy=800.0, cx=639.5, cy=479.5, width=1280, height=960, k1=-0.15)
    paths = [write_png(folder / f"v{k:02d}.png", rng.integers(0, 256, (960, 1280, 3), dtype=np.uint8))
             for k in range(24)]
    out = tmp_path / "out"
    out.mkdir()
    # A temporary file as a killed writer leaves one: cleaned up at the end.
    (out / ".v03.png.abandoned").write_bytes(b"half")
    pids = client.run(os.getpid)
    killed = []

    def progress(stage, done, total):
        if done == 1 and not killed:
            victim = sorted(pids.values())[0]
            killed.append(victim)
            threading.Thread(target=os.kill, args=(victim, signal.SIGKILL)).start()

    job = undistort_files(paths, big, out, client=client, progress=progress, interpolation="bilinear", timeout=180)
    assert killed
    assert job.summary.done == 24 and not job.summary.failed
    names = sorted(p.name for p in out.iterdir())
    assert names == ["manifest.jsonl"] + [f"v{k:02d}.png" for k in range(24)]
    recs = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]
    assert sorted(r["key"] for r in recs) == sorted(p.name for p in paths)
    client.wait_for_workers(2, timeout=60)


def test_detect_files_writes_what_the_detector_finds(client, shared_data, tmp_path):
    from camkit.pipeline import detect_files
    from camkit.target import Checkerboard

    board = Checkerboard(inner_cols=6, inner_rows=4, square=0.03)
    paths = sorted((shared_data / "real_boards" / "boofcv_sony" / "images").glob("*.jpg"))[:4]
    job = detect_files(paths, board, tmp_path / "det", client=client, timeout=120)
    assert job.summary.done == 4 and len(job.written) == 4
    for p in paths:
        doc = json.loads((tmp_path / "det" / (p.stem + ".json")).read_text())
        det = board.detect(read_image(p))
        assert doc["format"] == "camkit-detection" and doc["found"] == det.found and doc["image"] == p.name
        assert doc["ids"] == det.ids.tolist() and doc["board_seen"] is None
        np.testing.assert_allclose(doc["corners_px"], det.pixels, atol=1e-6)
    # The board miscounted (squares for inner corners): not found, and the whole board seen is said.
    job = detect_files(paths[:1], Checkerboard(inner_cols=7, inner_rows=5, square=0.03), tmp_path / "det75",
                       client=client, timeout=120)
    doc = json.loads((tmp_path / "det75" / (paths[0].stem + ".json")).read_text())
    assert not doc["found"] and doc["board_seen"] == [6, 4]


def test_simulated_shards_are_the_same_bytes_on_one_or_two_workers(client, tmp_path):
    from dask.distributed import Client, LocalCluster

    from camkit.pipeline import iter_dataset, simulate_files
    from camkit.render import default_camera
    from camkit.target import Checkerboard

    cam = default_camera("brown-conrady")
    board = Checkerboard(inner_cols=5, inner_rows=4, square=0.04)
    two = simulate_files(tmp_path / "two", cam, board, 5, seed=7, fmt="jpeg", shard_size=2, client=client)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                      host="127.0.0.1") as cluster, Client(cluster) as one_client:
        one = simulate_files(tmp_path / "one", cam, board, 5, seed=7, fmt="jpeg", shard_size=2, client=one_client)
    assert two.shards == one.shards == 3
    files = sorted(p.relative_to(tmp_path / "two") for p in (tmp_path / "two").rglob("*")
                   if p.is_file() and p.name != "manifest.jsonl")
    assert len([f for f in files if f.suffix == ".jpg"]) == 5
    for f in files:
        assert (tmp_path / "two" / f).read_bytes() == (tmp_path / "one" / f).read_bytes(), f
    views = list(iter_dataset(tmp_path / "two"))
    assert [p.name for p, _ in views] == [f"view_{k:06d}.jpg" for k in range(5)]
    # The truth is the image's: the detector finds the board where the truth says.
    p, rec = views[0]
    det = board.detect(read_image(p))
    if det.found:
        truth = np.array(rec["corners_px"], dtype=float)
        assert np.nanmedian(np.hypot(*(det.corners - truth).T)) < 0.3


def test_cli_detect_and_sharded_simulate(tmp_path, capsys):
    """`camkit simulate --shard-size` then `camkit detect` on the shards, each on its own local
    cluster (the command line's default), with --workers 2."""
    from camkit.cli.main import main

    assert main(["simulate", "--views", "4", "--seed", "2", "--shard-size", "2", "--format", "jpeg",
                 "--board", "6x5", "--square", "30mm", "-o", str(tmp_path / "sim"), "--workers", "2"]) == 0
    assert (tmp_path / "sim" / "dataset.json").is_file()
    assert sorted(p.name for p in (tmp_path / "sim").glob("shard_*")) == ["shard_0000", "shard_0001"]
    assert main(["detect", str(tmp_path / "sim" / "shard_*" / "*.jpg"), "--board", "6x5", "--square", "30mm",
                 "-o", str(tmp_path / "det"), "--workers", "2"]) == 0
    out = capsys.readouterr().out
    assert "4 done, 0 skipped, 0 failed" in out
    docs = [json.loads(p.read_text()) for p in sorted((tmp_path / "det").glob("view_*.json"))]
    assert len(docs) == 4 and sum(d["found"] for d in docs) >= 3
    # Again with --resume: nothing to do.
    assert main(["detect", str(tmp_path / "sim" / "shard_*" / "*.jpg"), "--board", "6x5", "--square", "30mm",
                 "-o", str(tmp_path / "det"), "--workers", "1", "--resume"]) == 0
    assert "0 done, 4 skipped" in capsys.readouterr().out


def test_a_job_past_its_timeout_stops_with_what_it_did(client, images, tmp_path):
    from camkit.errors import EstimationError

    with pytest.raises(EstimationError, match=r"timeout: the undistort job ran past 0.001 s with \d+ of 12"):
        undistort_files(images, CAM, tmp_path / "out", client=client, timeout=0.001)
    # What it did is kept; resume finishes the rest.
    rest = undistort_files(images, CAM, tmp_path / "out", client=client, resume=True, timeout=120).summary
    assert rest.done + rest.skipped == 12


def test_an_existing_cluster_by_address_and_by_variable(client, images, tmp_path, capsys, monkeypatch):
    """--scheduler tcp://... and DASK_SCHEDULER_ADDRESS: the job runs on that cluster's two
    workers (no local cluster is started)."""
    from camkit.cli.main import main

    address = client.scheduler.address
    save = tmp_path / "cam.json"
    from camkit.io import save_camera

    save_camera(save, CAM)
    assert main(["undistort", str(save), str(images[0].parent), "-o", str(tmp_path / "a"), "--scheduler",
                 address]) == 0
    assert "12 done, 0 skipped, 0 failed" in capsys.readouterr().out
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", address)
    assert main(["undistort", str(save), str(images[0].parent), "-o", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "12 done" in out and "on 2 workers" in out
    import dask

    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:9")
    with dask.config.set({"distributed.comm.timeouts.connect": "2s"}):
        assert main(["undistort", str(save), str(images[0].parent), "-o", str(tmp_path / "c")]) != 0
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in capsys.readouterr().err


def test_bad_input_is_refused_before_any_work(tmp_path):
    """No cluster is started for these: each is refused naming the argument."""
    from pathlib import Path

    from camkit.batch import connect, run_batch
    from camkit.errors import ParameterError
    from camkit.pipeline import detect_files, iter_dataset, pair_images, simulate_files
    from camkit.target import Checkerboard

    board = Checkerboard(inner_cols=5, inner_rows=4, square=0.03)
    with pytest.raises(ParameterError, match="unique string key"):
        run_batch(lambda a, b: {}, [{"key": "a"}, {"key": "a"}], None, tmp_path / "x")
    with pytest.raises(ParameterError, match="workers"):
        connect(workers=0)
    with pytest.raises(ParameterError, match="client"):
        connect(client="x")
    with pytest.raises(ParameterError, match="expected tcp://HOST:PORT"):
        connect(scheduler="tcp://127.0.0.1:notaport")
    for kwargs, what in (({"fmt": "gif"}, "fmt"), ({"fmt": "jpeg", "bit_depth": 16}, "bit_depth"),
                         ({"shard_size": 0}, "shard_size"), ({"fmt": "jpeg", "quality": 0}, "quality"),
                         ({"quality": 101}, "quality"), ({"quality": 9.5}, "quality")):
        with pytest.raises(ParameterError, match=what):
            simulate_files(tmp_path / "s", CAM, board, 2, seed=1, **kwargs)
    with pytest.raises(ParameterError, match="views"):
        simulate_files(tmp_path / "s", CAM, board, 0, seed=1)
    with pytest.raises(ParameterError, match="target"):
        detect_files([], "board", tmp_path / "d")
    with pytest.raises(ParameterError, match="not a valid regular expression"):
        pair_images({"a": [Path("x1.png")], "b": [Path("y1.png")]}, "(")
    with pytest.raises(ParameterError, match=r"does not match the file name y\.png"):
        pair_images({"a": [Path("x1.png")], "b": [Path("y.png")]}, r"(\d+)")
    with pytest.raises(ParameterError, match="different numbers of images"):
        pair_images({"a": [Path("x1.png")], "b": []})
    with pytest.raises(ParameterError, match="holds no simulated dataset"):
        list(iter_dataset(tmp_path / "nothing"))
