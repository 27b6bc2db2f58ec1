"""Batch jobs on Dask: each input one task, locally or on a dask.distributed cluster.

``camkit undistort``, ``camkit rectify``, ``camkit detect`` and ``camkit simulate`` run their
images through :func:`run_batch`:

- **Where**: a ``dask.distributed.Client`` given by the caller; else the scheduler at
  ``scheduler`` (or the ``DASK_SCHEDULER_ADDRESS`` variable); else a local cluster of worker
  processes sized to the machine (``workers`` processes, one task thread each, and numba's
  threads per worker set so that workers x threads = cores).
- **Streaming**: inputs are read inside the tasks; what every task needs (the camera, a map's
  recipe, the target) is scattered to the workers once and cached there; at most a few tasks
  per worker are in flight, so memory stays bounded whatever the number of inputs.
- **Nothing lost, nothing twice**: every output is written atomically (a temporary file, then a
  rename); a task whose worker dies is run again elsewhere (Dask's own retry) and rewrites the
  same files; temporary files a killed worker left are removed at the end. A failing input
  (a corrupt file) is reported by name and the others complete. A manifest (JSON lines in the
  output folder) records every input with the SHA-256 of its bytes and its outputs; with
  ``resume`` an input whose record says done, with the same hash and every output present, is
  skipped.

Nothing here schedules work itself: Dask does (M. Rocklin, "Dask: parallel computation with
blocked algorithms and task scheduling", SciPy 2015).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from camkit._atomic import write_atomic
from camkit._repr import summary_repr
from camkit.errors import EstimationError, ParameterError

__all__ = ["BatchSummary", "connect", "file_sha256", "run_batch"]

#: The manifest's name in a job's output folder.
MANIFEST = "manifest.jsonl"


@dataclass(frozen=True, slots=True)
class BatchSummary:
    """What a batch job did.

    Attributes
    ----------
    done, skipped : int
        Inputs processed now, and inputs skipped as already complete (``resume``).
    failed : list of (input, error)
    seconds : float
    results : dict
        Per input key, what its task returned (outputs, and the task's own record).
    manifest : Path
    workers : int
        Workers of the cluster the job ran on.
    """

    done: int
    skipped: int
    failed: list[tuple[str, str]]
    seconds: float
    results: dict[str, dict[str, Any]] = field(default_factory=dict)
    manifest: Path | None = None
    workers: int = 0

    def __repr__(self) -> str:
        return summary_repr(self)

    @property
    def per_second(self) -> float:
        """Inputs processed per second (skipped ones not counted)."""
        return (self.done + len(self.failed)) / self.seconds if self.seconds > 0 else float("nan")

    def line(self) -> str:
        """One line for a person: done, skipped, failed, images per second."""
        return (f"{self.done} done, {self.skipped} skipped, {len(self.failed)} failed in {self.seconds:.1f} s "
                f"({self.per_second:.2f} images/s on {self.workers} workers)")


def file_sha256(path: str | os.PathLike) -> str:
    """The SHA-256 of a file's bytes, hex."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def connect(client: Any = None, *, scheduler: str | None = None, workers: int | None = None) -> tuple[Any, list]:
    """A Dask client, and what was opened for it and is the caller's to close when the job
    ends (``for x in opened: x.close()``): nothing for the caller's client, the client for a
    scheduler's address, the client and the local cluster otherwise.

    ``client``: used as it is. ``scheduler`` (or ``DASK_SCHEDULER_ADDRESS``): a
    dask.distributed scheduler's address, ``tcp://host:port``. Else a local cluster of
    ``workers`` processes (the machine's cores by default), one thread each for tasks, numba
    limited to ``cores // workers`` threads per worker, on the loopback interface only."""
    from dask.distributed import Client, LocalCluster

    if client is not None:
        if not isinstance(client, Client):
            raise ParameterError(f"client: expected a dask.distributed.Client, got {type(client).__name__}")
        return client, []
    address = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")
    if address:
        _reachable(address)
        try:
            # Dask's connect timeout (distributed.comm.timeouts.connect, 30 s by default).
            c = Client(address)
            return c, [c]
        except OSError as exc:
            raise ParameterError(f"scheduler: cannot reach the Dask scheduler at {address} ({exc})") from None
    cores = os.cpu_count() or 1
    n = cores if workers is None else workers
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ParameterError(f"workers: expected a positive number of worker processes, got {workers!r}")
    threads = str(max(cores // n, 1))
    # Loopback only; the scheduler's HTTP endpoint on a free port (a fixed one clashes with any
    # other cluster on the machine); Dask's own log lines only for errors. numba's threads are
    # set in each task (_call, from _TASK_THREADS), not by NUMBA_NUM_THREADS: Dask sets a
    # worker's environment after the process starts, and a worker spawned from the `camkit`
    # script imports camkit (and numba, which reads the variable once) before that; numba then
    # refused to compile once its threads had started ("Cannot set NUMBA_NUM_THREADS to a
    # different value once the threads have been launched"), and every image failed.
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                           host="127.0.0.1", silence_logs=logging.ERROR,
                           env={_TASK_THREADS: threads, "OMP_NUM_THREADS": threads})
    c = Client(cluster)
    return c, [c, cluster]


#: The worker's environment variable that holds how many of numba's threads each task uses
#: (the local cluster's cores // workers; see :func:`connect`).
_TASK_THREADS = "CAMKIT_TASK_THREADS"


def _reachable(address: str) -> None:
    """For a ``tcp://host:port`` address, a plain connection first: a scheduler that is not
    there is reported at once, without a Dask client left retrying in the background."""
    import socket

    import dask

    if not address.startswith("tcp://"):
        return
    host, _, port = address[len("tcp://"):].rpartition(":")
    try:
        p = int(port)
    except ValueError:
        raise ParameterError(f"scheduler: expected tcp://HOST:PORT, got {address!r}") from None
    seconds = dask.utils.parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"), default="s")
    try:
        socket.create_connection((host.strip("[]"), p), timeout=seconds).close()
    except OSError as exc:
        raise ParameterError(f"scheduler: cannot reach the Dask scheduler at {address} "
                             f"({exc.strerror or exc})") from None


def _read_manifest(path: Path) -> dict[str, dict[str, Any]]:
    """The manifest's records by key; lines that are not complete JSON (a job killed while
    appending) are ignored."""
    out: dict[str, dict[str, Any]] = {}
    if not path.is_file():
        return out
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(rec, dict) and isinstance(rec.get("key"), str):
            out[rec["key"]] = rec
    return out


def _inputs(item: dict[str, Any]) -> list[str]:
    """An item's input files: ``inputs`` (several, e.g. a stereo pair), else ``input``."""
    if item.get("inputs"):
        return [str(p) for p in item["inputs"]]
    return [] if item.get("input") is None else [str(item["input"])]


def _digests(rec: dict[str, Any]) -> list[str] | None:
    """The input hashes a record holds: ``inputs_sha256`` (several inputs) or ``input_sha256``."""
    if "inputs_sha256" in rec:
        return list(rec["inputs_sha256"])
    return [rec["input_sha256"]] if "input_sha256" in rec else None


def _complete(rec: dict[str, Any] | None, item: dict[str, Any], out_dir: Path) -> bool:
    if rec is None or rec.get("status") != "done":
        return False
    paths = _inputs(item)
    if paths and _digests(rec) != [file_sha256(p) for p in paths]:
        return False
    return all((out_dir / o).is_file() for o in rec.get("outputs", []))


def _call(func: Callable[..., dict[str, Any]], item: dict[str, Any], context: Any) -> dict[str, Any]:
    """Run one task on a worker: the task's record, or the failure with its reason. The inputs'
    hashes are the task's own where it gives them (hashed from the bytes it decoded, one read
    of each file), else read here."""
    t0 = time.perf_counter()
    threads = os.environ.get(_TASK_THREADS)
    if threads:  # a local cluster's worker: numba's threads for this task's thread (thread-local)
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    try:
        rec = dict(func(item, context))
        rec.setdefault("status", "done")
    except Exception as exc:  # one input's failure, whatever it is, is that input's: recorded, not fatal
        rec = {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
    rec["key"] = item["key"]
    rec["seconds"] = time.perf_counter() - t0
    paths = _inputs(item)
    if paths:
        rec["input"] = paths[0]
        try:
            digests = _digests(rec) or [file_sha256(p) for p in paths]
        except OSError as exc:
            rec.update(status="failed", error=f"{type(exc).__name__}: {exc}")
        else:
            rec.pop("input_sha256", None)
            rec.pop("inputs_sha256", None)
            if len(paths) == 1:
                rec["input_sha256"] = digests[0]
            else:
                rec.update(inputs=paths, inputs_sha256=digests)
    return rec


def _remove_temporaries(out_dir: Path, outputs: Sequence[str]) -> None:
    """Temporary files (``.<name>.<random>``, camkit's atomic writes) a killed worker left
    beside the outputs: each folder is listed once, whatever the number of outputs in it."""
    by_dir: dict[Path, set[str]] = {}
    for o in outputs:
        p = out_dir / o
        by_dir.setdefault(p.parent, set()).add(p.name)
    for folder, names in by_dir.items():
        if not folder.is_dir():
            continue
        with os.scandir(folder) as entries:
            for e in entries:
                # mkstemp's random suffix has no dot: what lies before the last dot is the name.
                if e.name.startswith(".") and e.name[1:].rpartition(".")[0] in names and e.is_file():
                    Path(e.path).unlink(missing_ok=True)


def _until(ac: Any, stage: str, timeout: float | None, count: Callable[[], tuple[int, int]]) -> Any:
    """The completed futures of ``ac``; its timeout (the whole job's) as an EstimationError
    saying how far the job got."""
    it = iter(ac)
    while True:
        try:
            yield next(it)
        except StopIteration:
            return
        except TimeoutError:
            done, total = count()
            raise EstimationError(f"timeout: the {stage} job ran past {timeout:g} s with {done} of {total} inputs "
                                  "done; their outputs are kept (run again with resume to go on)") from None


def run_batch(func: Callable[[dict[str, Any], Any], dict[str, Any]], items: Sequence[dict[str, Any]], context: Any,
              out_dir: str | os.PathLike, *, client: Any = None, scheduler: str | None = None,
              workers: int | None = None, resume: bool = False,
              progress: Callable[[str, int, int], None] | None = None, stage: str = "batch",
              in_flight_per_worker: int = 2, timeout: float | None = None) -> BatchSummary:
    """Run ``func(item, context)`` for every item on Dask, one task an item.

    Parameters
    ----------
    func : callable
        A module-level function (workers import it): reads its input, writes its outputs into
        ``out_dir`` atomically, returns a JSON-ready record with ``outputs`` (names relative to
        ``out_dir``) and, where it read its inputs through
        :func:`camkit.io.read_image_sha256`, their ``input_sha256`` (``inputs_sha256`` for
        several), so that no input is read twice. Any exception marks the item failed, with its type and message (a
        100 000-image job does not stop for one bad input).
    items : list of dict
        Each with a unique ``key`` (str) and ``input`` (a path, or None for generated items) or
        ``inputs`` (several paths, e.g. a stereo pair: a change to any one redoes the item on
        ``resume``), and whatever ``func`` needs; ``outputs`` (names relative to ``out_dir``) lets ``resume``
        and the clean-up know them before the task runs.
    context : object
        What every task needs; sent to every worker once (``Client.scatter`` with broadcast),
        not with each task.
    out_dir : folder of the outputs and the manifest
    client, scheduler, workers : where to run (:func:`connect`)
    resume : skip items the manifest records as done with the same input and present outputs
    progress : ``progress(stage, done, total)`` after each item
    in_flight_per_worker : tasks submitted ahead per worker (bounds memory)
    timeout : seconds the whole job may take (None: no limit); past it the job stops with an
        EstimationError saying how many inputs were done (their outputs and manifest records
        are kept; ``resume`` goes on from there)

    Returns
    -------
    BatchSummary
    """
    from dask.distributed import as_completed

    out = Path(out_dir)
    keys = [it.get("key") for it in items]
    if len(set(keys)) != len(keys) or not all(isinstance(k, str) for k in keys):
        raise ParameterError("items: expected a unique string key per item")
    out.mkdir(parents=True, exist_ok=True)
    manifest = out / MANIFEST
    previous = _read_manifest(manifest) if resume else {}
    todo = [it for it in items if not (resume and _complete(previous.get(it["key"]), it, out))]
    skipped = len(items) - len(todo)
    records: dict[str, dict[str, Any]] = {k: previous[k] for k in keys if k in previous and resume}
    t0 = time.perf_counter()
    if not todo:  # everything complete already: no cluster to start
        return BatchSummary(done=0, skipped=skipped, failed=[], seconds=time.perf_counter() - t0, results=records,
                            manifest=manifest, workers=0)
    cl, opened = connect(client, scheduler=scheduler, workers=workers)
    n_workers = 0
    try:
        n_workers = max(len(cl.scheduler_info().get("workers", {})), 1)
        # Sent once to every worker. In a list: Client.scatter sends a dict's values under the
        # dict's own keys ("model", "out_dir"...), which the next job would reuse while this
        # one's are being released (its tasks then fail with "lost dependencies").
        ctx = cl.scatter([context], broadcast=True, hash=False)[0]
        limit = max(in_flight_per_worker * n_workers, 1)
        job = uuid.uuid4().hex[:12]  # task keys unique to this job: never an earlier job's task
        submitted = []

        def submit(it: dict[str, Any]) -> Any:
            fut = cl.submit(_call, func, it, ctx, key=f"camkit-{stage}-{job}-{it['key']}", pure=False)
            submitted.append(fut)
            return fut

        pending = iter(todo)
        ac = as_completed(timeout=timeout)
        for it in pending:
            ac.add(submit(it))
            if ac.count() >= limit:
                break
        tally = {"done": 0}
        try:
            with open(manifest, "a", encoding="utf-8") as log:
                for fut in _until(ac, stage, timeout, lambda: (tally["done"], len(todo))):
                    rec = fut.result()
                    fut.release()
                    records[rec["key"]] = rec
                    log.write(json.dumps(rec) + "\n")
                    log.flush()
                    tally["done"] += 1
                    if progress is not None:
                        progress(stage, tally["done"] + skipped, len(items))
                    nxt = next(pending, None)
                    if nxt is not None:
                        ac.add(submit(nxt))
        except BaseException:
            # A timeout or an interrupt: the tasks still queued or running are cancelled; what
            # finished is in the manifest for resume.
            cl.cancel([f for f in submitted if not f.done()])
            raise
    finally:
        for x in opened:
            x.close()
    _remove_temporaries(out, [o for it in items for o in it.get("outputs", [])]
                        + [o for r in records.values() for o in r.get("outputs", [])])
    # The manifest, rewritten whole and atomically: one record per input, this run's or the
    # one it skipped on.
    write_atomic(manifest, "".join(json.dumps(records[k]) + "\n" for k in keys if k in records).encode())
    failed = [(str(records[k].get("input", k)), records[k].get("error", "")) for k in keys
              if k in records and records[k].get("status") == "failed"]
    done = sum(1 for it in todo if records.get(it["key"], {}).get("status") == "done")
    return BatchSummary(done=done, skipped=skipped, failed=failed, seconds=time.perf_counter() - t0,
                        results=records, manifest=manifest, workers=n_workers)
