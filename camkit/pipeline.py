"""The calibration job shared by ``camkit calibrate`` and ``camkit demo``: images in; camera
file, results file and report out. The place where paths become arrays."""

from __future__ import annotations

import glob
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from camkit._repr import summary_repr
from camkit.calib.calibrate import CalibrationResult, calibrate_detections
from camkit.errors import ImageFileError, ParameterError, ShapeError
from camkit.lens.base import CameraModel
from camkit.target import Detection, Target

#: Width of the thumbnails kept for the report (pixels).
THUMBNAIL_WIDTH = 240

__all__ = ["DETECTION_FORMAT_VERSION", "CalibrationJob", "DetectJob", "InputImages", "RectifyJob", "RigJob",
           "SimulateJob", "UndistortJob", "calibrate_files", "calibrate_rig_files", "collect_images", "detect_files",
           "iter_dataset", "pair_images", "prepare_outputs", "rectify_files", "simulate_files", "undistort_files"]


@dataclass(frozen=True, slots=True)
class InputImages:
    """Image files gathered from the command line's arguments.

    Attributes
    ----------
    paths : list of Path
        The image files, in the order given (a folder's or a glob's files sorted by name).
    skipped : list of (Path, str)
        Files found in a folder that are not images (by suffix), with the reason.
    """

    paths: list[Path]
    skipped: list[tuple[Path, str]] = field(default_factory=list)

    def __repr__(self) -> str:
        return summary_repr(self)


def collect_images(inputs: Sequence[str | os.PathLike]) -> InputImages:
    """Image files from files, folders and glob patterns.

    - a folder: its files whose name ends in one of :data:`camkit.io.IMAGE_SUFFIXES`, in any
      case (``IMG_0001.JPG``), sorted by name; its other files are listed as skipped; not
      recursive;
    - a pattern with ``*``, ``?`` or ``[`` that is not an existing file: the files it matches
      (sorted; ``**`` matches any depth of folders), the same suffix rule;
    - a file: taken as given (its content decides its format).

    Raises ParameterError when an input does not exist or nothing is found (naming a folder's
    folders, where it has no images but has folders).
    """
    from camkit.io.images import is_image_name

    paths: list[Path] = []
    skipped: list[tuple[Path, str]] = []
    for item in inputs:
        text = os.fspath(item)
        p = Path(text)
        if p.is_dir():
            found = sorted((q for q in p.iterdir() if q.is_file()), key=lambda q: q.name)
            for q in found:
                if is_image_name(q):
                    paths.append(q)
                elif not q.name.startswith("."):
                    skipped.append((q, "not an image file name"))
            if not any(is_image_name(q) for q in found):
                subs = sorted(q.name for q in p.iterdir() if q.is_dir() and not q.name.startswith("."))
                hint = (f"; folders are not searched inside, and it has {len(subs)} folder{'s' * (len(subs) > 1)}: "
                        + ", ".join(subs[:5]) + (", ..." if len(subs) > 5 else "")
                        + f" (name one, or a pattern such as '{p / '**' / '*.jpg'}')") if subs else ""
                raise ParameterError(f"IMAGES: the folder {p} holds no image files (JPEG, PNG, TIFF, BMP, WebP, "
                                     f"PGM/PPM or camera RAW){hint}")
        elif p.exists():
            paths.append(p)
        elif any(ch in text for ch in "*?["):
            matches = sorted(Path(m) for m in glob.glob(text, recursive=True))
            files = [m for m in matches if m.is_file()]
            if not files:
                raise ParameterError(f"IMAGES: the pattern {text!r} matches no files")
            for q in files:
                (paths.append(q) if is_image_name(q) else skipped.append((q, "not an image file name")))
        else:
            raise ParameterError(f"IMAGES: {text} does not exist")
    if not paths:
        raise ParameterError("IMAGES: no image files among the inputs")
    return InputImages(paths, skipped)


def prepare_outputs(outputs: dict[str, str | os.PathLike | None], inputs: Sequence[Path] = ()) -> dict[str, Path]:
    """Check and create the folders of the files a job will write, before any work starts.

    ``outputs`` maps an option name (for messages, e.g. ``"-o"``) to a file path or None.
    Missing parent folders are created; an output that is an existing folder, one of the
    inputs, or whose folder cannot be created or written is refused with a ParameterError
    naming the option. Returns the paths given (None dropped).
    """
    ins = {p.resolve() for p in inputs}
    out: dict[str, Path] = {}
    for name, target in outputs.items():
        if target is None:
            continue
        t = Path(target)
        if t.resolve() in ins:
            raise ParameterError(f"{name}: {t} is one of the input images; camkit never overwrites an input")
        if t.is_dir():
            raise ParameterError(f"{name}: {t} is a folder; expected a file name")
        parent = t.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except FileExistsError:
            raise ParameterError(f"{name}: cannot create the folder {parent}: a file is in the way") from None
        except OSError as exc:
            raise ParameterError(f"{name}: cannot create the folder {parent} ({exc.strerror or exc})") from None
        if not os.access(parent, os.W_OK | os.X_OK):
            raise ParameterError(f"{name}: cannot write in the folder {parent} (permission denied)")
        out[name] = t
    return out


@dataclass(frozen=True, slots=True)
class CalibrationJob:
    result: CalibrationResult
    image_names: list[str]
    camera_file: Path | None
    results_file: Path | None
    report_file: Path | None
    image_info: list = field(default_factory=list)

    def __repr__(self) -> str:
        return summary_repr(self)


def calibrate_files(paths: Sequence[str | os.PathLike], board: Target, *, model: str = "brown-conrady",
                    fix: tuple[str, ...] | None = None, free: tuple[str, ...] | None = None,
                    camera_file: str | os.PathLike | None = None, results_file: str | os.PathLike | None = None,
                    report_file: str | os.PathLike | None = None, truth: CameraModel | None = None,
                    title: str = "Camera calibration",
                    progress: Callable[[str, int, int], None] | None = None) -> CalibrationJob:
    """Detect, calibrate and write what was asked for (each file atomically).

    Output folders are created (or refused) before any image is read. ``progress(stage, done,
    total)`` is called during detection (stage ``"detect"``), then with 0 and 1 of 1 around the
    solve (``"calibrate"``) and the report (``"report"``). No output may be one of the inputs.
    The images' EXIF (camera, lens, focal length, orientation) goes into the results file and
    the report.

    Images are left out, with the reason in ``result.rejected_views``, where a file cannot be
    read (damaged, or not an image) or where its size is not the one most images share (see
    :func:`_common_size`); where no image can be read, a ParameterError.

    Each file is read once and decoded once: the target is detected in it and, when a report is asked for,
    a thumbnail (:data:`THUMBNAIL_WIDTH` px wide) is kept for it; only one full image is in memory at
    a time."""
    from camkit.io.camera_files import save_camera
    from camkit.io.images import read_image_and_info
    from camkit.io.results import write_results
    from camkit.report import write_report
    from camkit.resample import resize

    if not isinstance(board, Target):
        raise ParameterError(f"board: expected a camkit target (e.g. a Checkerboard), got {type(board).__name__}")

    files = [Path(p) for p in paths]
    outs = prepare_outputs({"camera_file": camera_file, "results_file": results_file, "report_file": report_file},
                           files)
    names = [f.name if len({g.name for g in files}) == len(files) else str(f) for f in files]
    detections, thumbs, sizes, unread, info = [], [], {}, {}, []
    n_points = len(board.object_points())
    for k, f in enumerate(files):
        try:
            img, image_info = read_image_and_info(f)
        except ImageFileError as exc:  # a damaged file among many: left out, with why
            unread[k] = f"left out: {exc}"
            detections.append(Detection.not_found(n_points, unread[k]))
            thumbs.append(None)
            info.append(None)
            if progress is not None:
                progress("detect", k + 1, len(files))
            continue
        info.append(image_info)
        sizes[k] = tuple(img.shape[:2])
        detections.append(board.detect(img))
        if "report_file" in outs:
            w = min(THUMBNAIL_WIDTH, img.shape[1])
            thumbs.append(resize(img, width=w, height=max(round(img.shape[0] * w / img.shape[1]), 1),
                                 interpolation="area") if w < img.shape[1] else img)
        del img
        if progress is not None:
            progress("detect", k + 1, len(files))
    if progress is not None:
        progress("calibrate", 0, 1)  # the solve starts when detection ends
    if not files:
        raise ParameterError("paths: no images given")
    if not sizes:
        raise _none_read("paths", f"the {len(files)} images", unread[0])
    size, odd = _common_size(sizes)
    # Images of another size go to the solve as boards not found; the result keeps what the
    # detector found in them, with the reason they were left out (and so for damaged files).
    used = [Detection.not_found(len(d.corners), odd[k]) if k in odd else d for k, d in enumerate(detections)]
    result = calibrate_detections(used, board, width=size[1], height=size[0], model=model, fix=fix, free=free)
    left_out = {**odd, **unread}
    if left_out:
        result = replace(result, rejected_views=[(i, left_out.get(i, r)) for i, r in result.rejected_views],
                         detections=detections)
    if progress is not None:
        progress("calibrate", 1, 1)
    cam_path = res_path = rep_path = None
    if "camera_file" in outs:
        cam_path = save_camera(outs["camera_file"], result.model, rms_px=result.rms_px,
                               stddev=dict(result.stddev))
    if "results_file" in outs:
        res_path = write_results(outs["results_file"], result, names, image_info=info)
    if "report_file" in outs:
        if progress is not None:
            progress("report", 0, 1)
        rep_path = write_report(outs["report_file"], result, images=thumbs, image_names=names, truth=truth,
                                title=title, image_info=info)
        if progress is not None:
            progress("report", 1, 1)
    return CalibrationJob(result, names, cam_path, res_path, rep_path, info)


def _common_size(sizes: dict[int, tuple[int, ...]]) -> tuple[tuple[int, int], dict[int, str]]:
    """The (H, W) that most of the images of one calibration share (``sizes``: each image read,
    by its index), and for each image of another size (by index) why it is left out: one
    calibration is for one camera mode, and an image of another size (a crop, a resized copy,
    another camera) does not fit its model. Where no size is shared by more than half of the
    images, which one is the camera's is not clear: a ShapeError lists the sizes."""
    from collections import Counter

    counts = Counter((int(h), int(w)) for h, w, *_ in sizes.values())
    (size, n), = counts.most_common(1)
    if len(counts) > 1 and 2 * n <= len(sizes):
        listed = ", ".join(f"{w}x{h} ({c} image{'s' if c > 1 else ''})" for (h, w), c in counts.most_common())
        turned = len(counts) == 2 and (size[1], size[0]) in counts
        raise ShapeError(f"images: expected one size for all images (one calibration is for one camera mode), got "
                         f"{listed}; " + (_TURNED if turned else "calibrate each camera mode on its own"))
    odd = {k: f"left out: {w}x{h}, where the other {n} images are {size[1]}x{size[0]} " + (
              f"({_TURNED})" if (h, w) == (size[1], size[0]) else "(one calibration is for one camera mode)")
           for k, (h, w, *_) in sizes.items() if (h, w) != size}
    return size, odd


# Images of one camera whose sizes are each other's turned a quarter: copies that an exporter
# turned upright by their EXIF orientation (a phone held upright). camkit reads every image's
# rows as the sensor stored them, so the camera's own files have one size.
_TURNED = ("the same size turned a quarter: copies turned upright by their orientation tag, where camkit reads "
           "rows as the sensor stored them; use the camera's original files")


def _none_read(what: str, images: str, first: str) -> ParameterError:
    """The error where none of ``images`` ("the 5 images") could be read; ``first`` the first
    one's reason (as left out)."""
    return ParameterError(f"{what}: none of {images} could be read; the first: {first.removeprefix('left out: ')}")


@dataclass(frozen=True, slots=True)
class UndistortJob:
    """What :func:`undistort_files` wrote: the PNG files (in input order; those of failed
    inputs missing), their folder, the pinhole camera they were taken with, and the batch's
    summary (done, skipped, failed with reasons, images per second)."""

    written: list[Path]
    out_dir: Path
    new_model: CameraModel
    summary: Any = None

    def __repr__(self) -> str:
        return summary_repr(self)


def _one_output_each(paths: Sequence[str | os.PathLike], out_dir: str | os.PathLike, suffix: str, what: str,
                     output_option: str) -> tuple[list[Path], Path, list[Path]]:
    """The inputs, the output folder (created) and each input's output ``<stem><suffix>`` in
    it, checked before any work: the folder is not a file, no two inputs share a stem, no
    output is an input."""
    images = [Path(p) for p in paths]
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ParameterError(f"{output_option}: {out} is a file; expected a folder for {what}")
    inputs = {p.resolve() for p in images}
    targets = [out / (p.stem + suffix) for p in images]
    if len({t.resolve() for t in targets}) != len(targets):
        raise ParameterError("IMAGES: two inputs have the same name; their outputs would overwrite each other")
    for t in targets:
        if t.resolve() in inputs:
            raise ParameterError(f"{output_option}: {t} is one of the input images; camkit never overwrites an input")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ParameterError(f"{output_option}: cannot create the folder {out} ({exc.strerror or exc})") from None
    return images, out, targets


#: Per worker process: maps built from a recipe scattered to it, by the recipe's token (a
#: worker builds each map once, not once a task).
_WORKER_MAPS: dict[str, Any] = {}


def _worker_map(ctx: dict[str, Any]) -> Any:
    token = ctx["token"]
    if token not in _WORKER_MAPS:
        _WORKER_MAPS.clear()  # one job's maps at a time
        _WORKER_MAPS[token] = ctx["build"](*ctx["args"])
    return _WORKER_MAPS[token]


def _undistort_one(item: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    """One batch task: read an image, check its size, remap it, write the PNG atomically."""
    from camkit.io import read_image_sha256, write_png
    from camkit.resample import remap

    model = ctx["model"]
    img, sha = read_image_sha256(item["input"])
    if img.shape[1] != model.width or img.shape[0] != model.height:
        raise ParameterError(f"{item['input']}: expected {model.width}x{model.height} (the camera's size), got "
                             f"{img.shape[1]}x{img.shape[0]}")
    write_png(Path(ctx["out_dir"]) / item["outputs"][0],
              remap(img, _worker_map(ctx), interpolation=ctx["interpolation"]))
    return {"outputs": item["outputs"], "input_sha256": sha}


def _undistort_map(model: CameraModel, new: CameraModel) -> Any:
    from camkit.resample import reproject_map

    return reproject_map(model, new)


def undistort_files(paths: Sequence[str | os.PathLike], model: CameraModel, out_dir: str | os.PathLike, *,
                    alpha: float = 0.0, interpolation: str = "bicubic",
                    progress: Callable[[str, int, int], None] | None = None,
                    output_option: str = "out_dir", client: Any = None, scheduler: str | None = None,
                    workers: int | None = None, resume: bool = False, timeout: float | None = None) -> UndistortJob:
    """Undistort image files into ``out_dir`` as PNG (same stem), seen through the pinhole
    :func:`camkit.resample.optimal_pinhole` (``alpha``: 0 keeps only valid pixels, 1 keeps
    every source pixel) of ``model``: a batch job on Dask (:func:`camkit.batch.run_batch`;
    ``client``, ``scheduler``, ``workers`` say where, ``resume`` skips inputs already done,
    ``timeout`` bounds the job's seconds).

    Everything is checked before the first file is written: the folder is created (or
    refused), no two inputs share a stem, no output is one of the inputs. Each file is written
    atomically; an image whose size is not the camera's fails with its name (the others
    complete; ``job.summary.failed`` lists it). ``progress(stage, done, total)`` is called
    after each image (stage ``"undistort"``); ``output_option`` names the output in messages
    (the command line's ``-o``).
    """
    import uuid

    from camkit.batch import run_batch
    from camkit.resample import optimal_pinhole

    if not isinstance(model, CameraModel):
        raise ParameterError(f"model: expected a camkit camera model, got {type(model).__name__}")
    from camkit.resample.kernels import interpolation_code

    interpolation_code(interpolation)  # a misspelt name fails here, before any work
    new = optimal_pinhole(model, alpha)
    images, out, targets = _one_output_each(paths, out_dir, ".png", "the undistorted images", output_option)
    items = [{"key": p.name, "input": str(p), "outputs": [t.name]} for p, t in zip(images, targets, strict=True)]
    ctx = {"model": model, "out_dir": str(out), "interpolation": interpolation, "token": uuid.uuid4().hex,
           "build": _undistort_map, "args": (model, new)}
    summary = run_batch(_undistort_one, items, ctx, out, client=client, scheduler=scheduler, workers=workers,
                        resume=resume, progress=progress, stage="undistort", timeout=timeout)
    return UndistortJob([t for t in targets if t.is_file()], out, new, summary)


def _natural(key: str) -> tuple:
    return (0, int(key), key) if key.isdigit() else (1, 0, key)


def pair_images(cameras: dict[str, Sequence[Path]],
                pair_by: str | None = None) -> tuple[list[str], list[list[Path | None]]]:
    """Pair the cameras' image files instant by instant.

    Without ``pair_by``, by sorted order: the k-th file of every camera is instant k (every
    camera must have as many files). With ``pair_by`` (a regular expression), by the part of
    each file name it matches (its first group if it has one: ``r"(\\d+)"`` pairs
    ``left_012.png`` with ``right_012.png``); a camera without a file for an instant has None
    there. Returns the instants' names and, per camera, its file at each instant.
    """
    import re

    names = list(cameras)
    if pair_by is None:
        counts = {n: len(cameras[n]) for n in names}
        if len(set(counts.values())) != 1:
            raise ParameterError(f"--camera: the cameras have different numbers of images ({counts}); pairing by "
                                 "sorted order needs as many for each (or pair by name with --pair-by)")
        n = counts[names[0]]
        return [str(k) for k in range(n)], [list(cameras[c]) for c in names]
    try:
        rx = re.compile(pair_by)
    except re.error as exc:
        raise ParameterError(f"--pair-by: not a valid regular expression ({exc})") from None
    keyed: list[dict[str, Path]] = []
    for c in names:
        table: dict[str, Path] = {}
        for p in cameras[c]:
            m = rx.search(p.name)
            if m is None:
                raise ParameterError(f"--pair-by: {pair_by!r} does not match the file name {p.name} (camera {c})")
            key = m.group(1) if m.groups() else m.group(0)
            if key in table:
                raise ParameterError(f"--pair-by: camera {c} has two files for instant {key!r}: {table[key].name} "
                                     f"and {p.name}")
            table[key] = p
        keyed.append(table)
    keys = sorted(set().union(*keyed), key=_natural)
    return keys, [[t.get(k) for k in keys] for t in keyed]


@dataclass(frozen=True, slots=True)
class RigJob:
    """What :func:`calibrate_rig_files` did: the result, the instants' names, each camera's
    file per instant (None where it had none) and the files written."""

    result: Any
    instants: list[str]
    paths: list[list[Path | None]]
    rig_file: Path | None
    written: list[Path] = field(default_factory=list)
    #: (camera, instant, reason) of each file left out: damaged, or not the size most of its
    #: camera's images share (as :func:`calibrate_files` leaves them out).
    left_out: list[tuple[int, int, str]] = field(default_factory=list)

    def __repr__(self) -> str:
        return summary_repr(self)


def calibrate_rig_files(cameras: dict[str, Sequence[str | os.PathLike]], target: Target, *,
                        pair_by: str | None = None, models: Any = "brown-conrady", fix: tuple[str, ...] | None = None,
                        free: tuple[str, ...] | None = None, rig_file: str | os.PathLike | None = None,
                        opencv_file: str | os.PathLike | None = None, kalibr_file: str | os.PathLike | None = None,
                        report_file: str | os.PathLike | None = None,
                        progress: Callable[[str, int, int], None] | None = None) -> RigJob:
    """Calibrate a camera rig from each camera's image files (``{name: files}``, paired by
    :func:`pair_images`): each image read and the target detected in it, then
    :func:`camkit.calib.calibrate_rig`; the rig written as camkit JSON (``rig_file``), OpenCV
    stereo YAML (``opencv_file``, two cameras) and a Kalibr camchain (``kalibr_file``), each
    atomically, and the report (``report_file``: the first instant both the first two cameras
    saw is shown rectified; those two images are kept from the detection pass, nothing is
    decoded twice). A file that cannot be read, or whose size is not the one most of its
    camera's images share, is left out of that instant (``RigJob.left_out``, with the reason,
    also in that camera's ``rejected_views``), as :func:`calibrate_files` leaves it out."""
    from camkit.calib.rig import calibrate_rig
    from camkit.io import read_image
    from camkit.io.rig_files import save_rig, write_kalibr_camchain, write_opencv_stereo_yaml

    if not isinstance(cameras, dict) or len(cameras) < 2:
        raise ParameterError("--camera: expected two or more cameras, each with its images")
    files = {c: [Path(p) for p in v] for c, v in cameras.items()}
    instants, paths = pair_images(files, pair_by)
    names = list(files)
    total = sum(p is not None for row in paths for p in row)
    views, sizes = [], []
    done = 0
    shown = next((k for k in range(len(instants)) if paths[0][k] is not None and paths[1][k] is not None), None)
    pair: list = []
    left_out: list[tuple[int, int, str]] = []
    for ci, (c, row) in enumerate(zip(names, paths, strict=True)):
        dets: list[Any] = []
        read_sizes: dict[int, tuple[int, ...]] = {}
        for k, p in enumerate(row):
            if p is None:
                dets.append(None)
                continue
            done += 1
            try:
                img = read_image(p)
            except ImageFileError as exc:  # a damaged file: this camera did not see this instant
                left_out.append((ci, k, f"left out: {exc}"))
                dets.append(None)
            else:
                if report_file is not None and k == shown and len(pair) < 2:
                    pair.append(img)
                read_sizes[k] = tuple(img.shape[:2])
                dets.append(target.detect(img))
            if progress is not None:
                progress("detect", done, total)
        if not any(p is not None for p in row):
            raise ParameterError(f"--camera {c}: no image of this camera is paired with another camera's")
        if not read_sizes:
            raise _none_read(f"--camera {c}", f"this camera's {sum(p is not None for p in row)} images",
                             next(r for cc, _, r in left_out if cc == ci))
        try:
            size, odd = _common_size(read_sizes)
        except ShapeError as exc:
            raise ShapeError(f"--camera {c}: {str(exc).removeprefix('images: ')}") from None
        for k, reason in odd.items():
            dets[k] = None
            left_out.append((ci, k, reason))
        views.append(dets)
        sizes.append((size[1], size[0]))
    if any(k == shown for _, k, _ in left_out):
        pair = []  # the instant shown rectified lost an image: no pair in the report
    result = calibrate_rig(views, target, sizes=sizes, models=models, names=names, fix=fix, free=free)
    if left_out:
        why = {(c, k): r for c, k, r in left_out}
        result = replace(result, cameras=tuple(
            replace(cam, rejected_views=[(t, why.get((c, t), r)) for t, r in cam.rejected_views])
            for c, cam in enumerate(result.cameras)))
    written = []
    if rig_file is not None:
        written.append(save_rig(rig_file, result))
    if opencv_file is not None:
        written.append(write_opencv_stereo_yaml(opencv_file, result))
    if kalibr_file is not None:
        written.append(write_kalibr_camchain(kalibr_file, result))
    if report_file is not None:
        from camkit.report import write_rig_report

        stems = []
        for k in range(len(instants)):
            first = next(row[k] for row in paths if row[k] is not None)
            stems.append(instants[k] if pair_by is not None else first.stem)
        written.append(write_rig_report(report_file, result, pair=pair if len(pair) == 2 else None,
                                        instant_names=stems))
    return RigJob(result, instants, paths, Path(rig_file) if rig_file is not None else None, written,
                  sorted(left_out))


@dataclass(frozen=True, slots=True)
class RectifyJob:
    """What :func:`rectify_files` wrote: the rectified pairs (left, right; those of failed
    pairs missing), the folder, the rectification, its OpenCV stereo file, and the batch's
    summary."""

    written: list[tuple[Path, Path]]
    out_dir: Path
    rectification: Any
    stereo_file: Path
    summary: Any = None

    def __repr__(self) -> str:
        return summary_repr(self)


def _rectify_maps(rect: Any) -> Any:
    from camkit.stereo import rectify_maps

    return rectify_maps(rect)


def _rectify_one(item: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    """One batch task: read a stereo pair, check the sizes, remap both, write both PNGs."""
    from camkit.io import read_image_sha256, write_png
    from camkit.resample import remap

    maps = _worker_map(ctx)
    rect = ctx["args"][0]
    digests = []
    for src, dst, model, m in zip(item["inputs"], item["outputs"], (rect.left_model, rect.right_model), maps,
                                  strict=True):
        img, sha = read_image_sha256(src)
        digests.append(sha)
        if img.shape[1] != model.width or img.shape[0] != model.height:
            raise ParameterError(f"{src}: expected {model.width}x{model.height} (the camera's size), got "
                                 f"{img.shape[1]}x{img.shape[0]}")
        write_png(Path(ctx["out_dir"]) / dst, remap(img, m, interpolation=ctx["interpolation"]))
    return {"outputs": item["outputs"], "inputs_sha256": digests}


def rectify_files(rig: Any, left: Sequence[str | os.PathLike], right: Sequence[str | os.PathLike],
                  out_dir: str | os.PathLike, *, cameras: tuple[str | int, str | int] = (0, 1),
                  mode: str | float = "valid", interpolation: str = "bilinear",
                  progress: Callable[[str, int, int], None] | None = None,
                  output_option: str = "out_dir", client: Any = None, scheduler: str | None = None,
                  workers: int | None = None, resume: bool = False, timeout: float | None = None) -> RectifyJob:
    """Rectify stereo pairs (the k-th left file with the k-th right one) of cameras
    ``cameras`` of ``rig`` (a CameraRig or RigResult) into ``out_dir/<left name>/`` and
    ``out_dir/<right name>/`` as PNG (same stems), with ``out_dir/stereo.yml`` (OpenCV's
    M1 ... Q). A batch job on Dask (:func:`camkit.batch.run_batch`, one task a pair; each
    worker builds the maps once). Everything is checked before the first file is written;
    each file is written atomically; a pair whose image is not its camera's size fails with
    its name while the others complete."""
    import uuid

    from camkit.batch import run_batch
    from camkit.calib.rig import CameraRig, RigResult
    from camkit.io.rig_files import write_opencv_stereo_yaml
    from camkit.resample.kernels import interpolation_code
    from camkit.stereo import rectify

    r = rig.rig if isinstance(rig, RigResult) else rig
    if not isinstance(r, CameraRig):
        raise ParameterError(f"rig: expected a CameraRig or RigResult, got {type(rig).__name__}")
    a, b = r.index(cameras[0]), r.index(cameras[1])
    ls, rs = [Path(p) for p in left], [Path(p) for p in right]
    if len(ls) != len(rs):
        raise ParameterError(f"LEFT, RIGHT: expected as many right images as left ones, got {len(ls)} and {len(rs)}")
    interpolation_code(interpolation)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ParameterError(f"{output_option}: {out} is a file; expected a folder for the rectified images")
    names = [(f"{r.names[a]}/{p.stem}.png", f"{r.names[b]}/{q.stem}.png") for p, q in zip(ls, rs, strict=True)]
    flat = [out / n for pair in names for n in pair]
    if len({t.resolve() for t in flat}) != len(flat):
        raise ParameterError("LEFT, RIGHT: two inputs of one camera have the same name; their outputs would "
                             "overwrite each other")
    inputs = {p.resolve() for p in (*ls, *rs)}
    for t in flat:
        if t.resolve() in inputs:
            raise ParameterError(f"{output_option}: {t} is one of the input images; camkit never overwrites an input")
    rect = rectify(r.models[a], r.models[b], r.relative_pose(a, b), mode=mode)
    try:
        for d in (out / r.names[a], out / r.names[b]):
            d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ParameterError(f"{output_option}: cannot create the folder {out} ({exc.strerror or exc})") from None
    sub = CameraRig((r.names[a], r.names[b]), (r.models[a], r.models[b]), (r.cam_from_rig[a], r.cam_from_rig[b]))
    stereo_file = write_opencv_stereo_yaml(out / "stereo.yml", sub, mode=mode)
    items = [{"key": f"{p.name}|{q.name}", "inputs": [str(p), str(q)], "outputs": list(n)}
             for p, q, n in zip(ls, rs, names, strict=True)]
    ctx = {"out_dir": str(out), "interpolation": interpolation, "token": uuid.uuid4().hex, "build": _rectify_maps,
           "args": (rect,)}
    summary = run_batch(_rectify_one, items, ctx, out, client=client, scheduler=scheduler, workers=workers,
                        resume=resume, progress=progress, stage="rectify", timeout=timeout)
    written = [(out / n[0], out / n[1]) for n in names if (out / n[0]).is_file() and (out / n[1]).is_file()]
    return RectifyJob(written, out, rect, stereo_file, summary)


#: Version of the detection files (``camkit detect``).
DETECTION_FORMAT_VERSION = 1


def _detect_one(item: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    """One batch task: read an image, detect the target, write its detection as JSON."""
    import json as _json

    import numpy as np

    from camkit._atomic import write_atomic
    from camkit.io import read_image_sha256

    img, sha = read_image_sha256(item["input"])
    det = ctx["target"].detect(img)
    ids = det.ids
    doc = {"format": "camkit-detection", "version": DETECTION_FORMAT_VERSION, "image": Path(item["input"]).name,
           "width": int(img.shape[1]), "height": int(img.shape[0]), "target": ctx["target_dict"],
           "pixel_origin": "centre of the top-left pixel is (0, 0)", "found": bool(det.found),
           "message": det.message, "window_px": int(det.window_px), "ids": [int(i) for i in ids],
           "corners_px": np.round(det.corners[ids], 6).tolist(),
           "sigma_px": [None if not np.isfinite(s) else round(float(s), 6) for s in det.sigma_px[ids]],
           "board_seen": list(det.board_seen) if det.board_seen is not None else None}
    write_atomic(Path(ctx["out_dir"]) / item["outputs"][0], (_json.dumps(doc) + "\n").encode())
    return {"outputs": item["outputs"], "found": bool(det.found), "n_found": len(ids), "message": det.message,
            "input_sha256": sha}


@dataclass(frozen=True, slots=True)
class DetectJob:
    """What :func:`detect_files` wrote: one JSON file an image (``<stem>.json``) in
    ``out_dir``, and the batch's summary."""

    written: list[Path]
    out_dir: Path
    summary: Any

    def __repr__(self) -> str:
        return summary_repr(self)


def detect_files(paths: Sequence[str | os.PathLike], target: Target, out_dir: str | os.PathLike, *,
                 client: Any = None, scheduler: str | None = None, workers: int | None = None,
                 resume: bool = False, progress: Callable[[str, int, int], None] | None = None,
                 output_option: str = "out_dir", timeout: float | None = None) -> DetectJob:
    """Detect ``target`` in every image and write each detection as JSON (``<stem>.json``:
    the image's name and size, the target, found, the detector's message, and the points seen
    with their ids, pixels and sigma; docs/file_formats.md) for users with their own solver.
    A batch job on Dask (:func:`camkit.batch.run_batch`): the target is sent to the workers
    once; each image is read inside its task; outputs are atomic; ``resume`` skips images
    already done."""
    from camkit.batch import run_batch

    if not isinstance(target, Target):
        raise ParameterError(f"target: expected a camkit target (e.g. a Checkerboard), got {type(target).__name__}")
    images, out, targets = _one_output_each(paths, out_dir, ".json", "the detections", output_option)
    items = [{"key": p.name, "input": str(p), "outputs": [t.name]} for p, t in zip(images, targets, strict=True)]
    ctx = {"target": target, "target_dict": target.to_dict(), "out_dir": str(out)}
    summary = run_batch(_detect_one, items, ctx, out, client=client, scheduler=scheduler, workers=workers,
                        resume=resume, progress=progress, stage="detect", timeout=timeout)
    return DetectJob([t for t in targets if t.is_file()], out, summary)


def _simulate_one(item: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    """One batch task: plan, render and write view ``item["index"]`` with its own random state
    (from the seed and the index: the same bytes whatever the number of workers)."""
    import numpy as np

    from camkit.io import write_image
    from camkit.render.dataset import plan_views, to_file_image, view_record
    from camkit.render.effects import render_view

    k = item["index"]
    rng = np.random.default_rng([ctx["seed"], k])
    pose = plan_views(ctx["camera"], ctx["board"], 1, rng)[0]
    img, truth = render_view(ctx["camera"], pose, ctx["board"], ctx["effects"], rng=rng)
    name = item["outputs"][0]
    write_image(Path(ctx["out_dir"]) / name, to_file_image(img, ctx["scale"], ctx["bit_depth"]),
                quality=ctx["quality"])
    return {"outputs": item["outputs"], "truth": view_record(Path(name).name, pose, truth)}


@dataclass(frozen=True, slots=True)
class SimulateJob:
    """What :func:`simulate_files` wrote: the dataset's folder, its truth files (``truth.json``
    for one folder; ``dataset.json`` and a ``truth.jsonl`` a shard), and the batch's summary."""

    out_dir: Path
    truth_files: list[Path]
    shards: int
    summary: Any

    def __repr__(self) -> str:
        return summary_repr(self)


def simulate_files(out_dir: str | os.PathLike, camera: CameraModel, board: Target, views: int, *, seed: int,
                   effects: Any = None, bit_depth: int = 8, fmt: str = "png", quality: int = 95,
                   shard_size: int | None = None, client: Any = None, scheduler: str | None = None,
                   workers: int | None = None, resume: bool = False,
                   progress: Callable[[str, int, int], None] | None = None,
                   timeout: float | None = None) -> SimulateJob:
    """Render ``views`` views of ``board`` through ``camera`` as a batch job on Dask, each view
    one task with its own random state (``numpy.random.default_rng([seed, index])``: its pose
    is planned alone, :func:`camkit.render.plan_views` with one view, and its noise drawn from
    it), so the same seed gives the same bytes whatever the number of workers.

    Without ``shard_size`` (and for 1 000 views or fewer), one folder: ``view_000.png`` ...
    and ``truth.json`` (the layout :func:`camkit.render.simulate_dataset` writes). With
    ``shard_size`` (1 000 by default beyond 1 000 views): ``shard_0000/`` ... each with its
    images and ``truth.jsonl`` (one view's truth a line), and ``dataset.json`` (the camera, the
    target, the seed and the shards), so a dataset of any size is written and read back in
    pieces (:func:`iter_dataset`). ``fmt``: "png" or "jpeg" (``quality`` 1-100)."""
    import json as _json

    from camkit._atomic import write_atomic
    from camkit._validate import as_positive_int
    from camkit.batch import run_batch
    from camkit.render.dataset import dataset_header, file_scale

    n = as_positive_int(views, "views")
    if fmt not in ("png", "jpeg"):
        raise ParameterError(f"fmt: expected 'png' or 'jpeg', got {fmt!r}")
    if bit_depth not in (8, 16) or (fmt == "jpeg" and bit_depth != 8):
        raise ParameterError(f"bit_depth: expected 8 or 16 (8 for JPEG), got {bit_depth!r}")
    if isinstance(quality, bool) or not isinstance(quality, int) or not 1 <= quality <= 100:
        raise ParameterError(f"quality: expected an integer 1..100, got {quality!r}")
    if shard_size is None and n > 1000:
        shard_size = 1000
    size = None if shard_size is None else as_positive_int(shard_size, "shard_size")
    ext = "png" if fmt == "png" else "jpg"
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ParameterError(f"out_dir: cannot create the folder {out} ({exc.strerror or exc})") from None

    def name(k: int) -> str:
        # One folder: simulate_dataset's names; shards: six digits, any size sorts by name.
        return f"view_{k:03d}.{ext}" if size is None else f"shard_{k // size:04d}/view_{k:06d}.{ext}"

    shards = 1 if size is None else (n + size - 1) // size
    for s in range(shards if size is not None else 0):
        (out / f"shard_{s:04d}").mkdir(exist_ok=True)
    scale, sensor_bits = file_scale(effects, bit_depth)
    items = [{"key": f"view_{k:06d}", "input": None, "index": k, "outputs": [name(k)]} for k in range(n)]
    ctx = {"camera": camera, "board": board, "effects": effects, "seed": int(seed), "scale": scale,
           "bit_depth": bit_depth, "quality": int(quality), "out_dir": str(out)}
    summary = run_batch(_simulate_one, items, ctx, out, client=client, scheduler=scheduler, workers=workers,
                        resume=resume, progress=progress, stage="render", timeout=timeout)
    header = dataset_header(camera, board, int(seed), bit_depth, sensor_bits, scale, version=1 if size is None
                            else 2)
    truth = {k: summary.results[f"view_{k:06d}"].get("truth") for k in range(n)
             if summary.results.get(f"view_{k:06d}", {}).get("status") == "done"}
    written = []
    if size is None:
        doc = {**header, "views": [truth[k] for k in range(n) if k in truth]}
        written.append(write_atomic(out / "truth.json", _json.dumps(doc, indent=1).encode()))
    else:
        for s in range(shards):
            lines = "".join(_json.dumps(truth[k]) + "\n" for k in range(s * size, min((s + 1) * size, n)) if k in truth)
            written.append(write_atomic(out / f"shard_{s:04d}" / "truth.jsonl", lines.encode()))
        doc = {**header, "views": n, "shard_size": size, "shards": [f"shard_{s:04d}" for s in range(shards)]}
        written.insert(0, write_atomic(out / "dataset.json", _json.dumps(doc, indent=1).encode()))
    return SimulateJob(out, written, shards, summary)


def iter_dataset(folder: str | os.PathLike):
    """The views of a simulated dataset, shard by shard (never all in memory): yields
    ``(image path, truth record)``; a one-folder dataset (``truth.json``) or a sharded one
    (``dataset.json``). The header (camera, target, seed) is in the folder's JSON file."""
    import json as _json

    root = Path(folder)
    if (root / "dataset.json").is_file():
        head = _json.loads((root / "dataset.json").read_text())
        for shard in head.get("shards", []):
            with open(root / shard / "truth.jsonl", encoding="utf-8") as f:
                for line in f:
                    rec = _json.loads(line)
                    yield root / shard / rec["image"], rec
    elif (root / "truth.json").is_file():
        for rec in _json.loads((root / "truth.json").read_text())["views"]:
            yield root / rec["image"], rec
    else:
        raise ParameterError(f"folder: {root} holds no simulated dataset (dataset.json or truth.json)")
