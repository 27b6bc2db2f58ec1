"""Image files in and out, through well-kept libraries: Pillow (JPEG, PNG, BMP, WebP, PGM/PPM),
imagecodecs (libpng: writing PNG, reading 16-bit colour PNG), tifffile (TIFF, every sample
format) and rawpy (camera RAW, the optional extra ``camkit[raw]``).
camkit decodes no standard format itself; what it adds is one shape for what comes back, a pixel
cap checked before any decoding, and one error, :class:`ImageFileError`, naming the file.

What a reader returns, whatever the format (conventions.md, "Images"):

- (H, W) for grey, (H, W, 2) grey and alpha, (H, W, 3) RGB, (H, W, 4) RGBA; rows top to bottom
  as stored, never turned by the EXIF orientation (calibration needs the sensor's pixel grid;
  :func:`read_image_info` reports the orientation so that callers can say so);
- the file's own sample type: uint8, uint16 for 16-bit files, float32 for float TIFF; no
  range rescaling, except that 1-bit images become 0/255 and palettes are looked up.
"""

from __future__ import annotations

import hashlib
import io
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from camkit._atomic import write_atomic
from camkit._repr import summary_repr
from camkit._validate import as_image, as_positive_int
from camkit.errors import ImageFileError, ParameterError, ShapeError
from camkit.io._files import regular_file_size

__all__ = [
    "DEFAULT_MAX_PIXELS",
    "IMAGE_SUFFIXES",
    "PNG_LEVEL",
    "RAW_SUFFIXES",
    "ImageFileError",
    "ImageInfo",
    "RawImage",
    "is_image_name",
    "read_image",
    "read_image_and_info",
    "read_image_info",
    "read_image_sha256",
    "read_raw",
    "write_image",
    "write_png",
]

#: The largest image (width x height, in pixels) the readers decode unless told otherwise:
#: 250 MP, beyond every camera sold today (a 200 MP phone sensor, a 150 MP medium format back),
#: so that a small hostile file cannot make camkit allocate gigabytes.
DEFAULT_MAX_PIXELS = 250_000_000

#: Camera RAW file name endings (any case), read through rawpy (LibRaw).
RAW_SUFFIXES = (".dng", ".cr2", ".cr3", ".crw", ".nef", ".nrw", ".arw", ".srf", ".sr2", ".raf", ".orf",
                ".rw2", ".pef", ".srw", ".rwl", ".3fr", ".iiq", ".erf", ".kdc", ".dcr", ".mrw", ".mos", ".x3f")

#: File name endings (any case) that :func:`read_image` reads. Formats are recognised by their
#: content; the ending only serves to pick image files out of a folder.
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".jpe", ".png", ".tif", ".tiff", ".bmp", ".dib", ".webp", ".pgm", ".ppm",
                  ".pnm", ".pbm", *RAW_SUFFIXES)

# Pillow's format plugins that camkit opens, in the order tried. Naming them keeps every other
# plugin (EPS runs Ghostscript, for one) away from a file that merely claims to be an image.
_PILLOW_FORMATS = ("JPEG", "PNG", "BMP", "WEBP", "PPM")
_TIFF_MAGIC = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")  # classic and BigTIFF
_DNG_VERSION_TAG = 50706


def is_image_name(path: str | os.PathLike) -> bool:
    """True when the file name ends in one of :data:`IMAGE_SUFFIXES`, in any case."""
    return Path(path).suffix.lower() in IMAGE_SUFFIXES


@dataclass(frozen=True, slots=True)
class ImageInfo:
    """What a file says about its image, read without decoding the pixels.

    Attributes
    ----------
    path : Path
    format : str
        "JPEG", "PNG", "TIFF", "BMP", "WEBP", "PPM" or "RAW".
    width, height : int
        The stored pixel grid (for RAW: the visible sensor area).
    orientation : int
        EXIF orientation, 1 (as stored) to 8; 1 when the file has none. camkit always works on
        the stored grid; a viewer that honours another value shows the image turned.
    make, model, lens : str or None
        EXIF Make, Model and LensModel.
    focal_length_mm : float or None
        EXIF FocalLength.
    focal_length_35mm : float or None
        EXIF FocalLengthIn35mmFilm: the focal length giving the same angle of view on a
        36 x 24 mm frame.
    """

    path: Path
    format: str
    width: int
    height: int
    orientation: int = 1
    make: str | None = None
    model: str | None = None
    lens: str | None = None
    focal_length_mm: float | None = None
    focal_length_35mm: float | None = None

    def __repr__(self) -> str:
        return summary_repr(self)

    def exif_dict(self) -> dict[str, Any]:
        """The EXIF fields present, for results files and reports (absent ones left out)."""
        keys = ("make", "model", "lens", "focal_length_mm", "focal_length_35mm")
        out = {k: getattr(self, k) for k in keys if getattr(self, k) is not None}
        if self.orientation != 1:
            out["orientation"] = self.orientation
        return out


@dataclass(frozen=True, slots=True, eq=False)
class RawImage:
    """A camera RAW file's sensor data, as :func:`read_raw` returns it.

    Attributes
    ----------
    mosaic : ndarray, (H, W) uint16
        The visible sensor area, one sample per photosite, as recorded (black level included).
    pattern : str
        The 2x2 colour filter pattern from the top-left photosite: "RGGB", "BGGR", "GRBG" or
        "GBRG", as :func:`camkit.sensor.demosaic` takes it.
    black_level : ndarray, (2, 2) float
        The black level of each photosite of the 2x2 tile (the mosaic's value for no light).
    white_level : float
        The largest value the sensor records (saturation).
    white_balance : ndarray, (3,) float
        The camera's as-shot multipliers for R, G, B, normalised to G = 1 (ones when the file
        has none).
    """

    mosaic: np.ndarray
    pattern: str
    black_level: np.ndarray
    white_level: float
    white_balance: np.ndarray

    def __repr__(self) -> str:
        return summary_repr(self)

    def normalised(self) -> np.ndarray:
        """The mosaic as float32 with the black level subtracted and the white level at 1:
        ``(mosaic - black) / (white - black)``, not clipped."""
        h, w = self.mosaic.shape
        black = np.tile(self.black_level, (h // 2 + 1, w // 2 + 1))[:h, :w]
        scale = np.float32(1.0 / max(self.white_level - float(self.black_level.max()), 1.0))
        return ((self.mosaic.astype(np.float32) - black.astype(np.float32)) * scale).astype(np.float32)


# -- opening ------------------------------------------------------------------------------------


def _as_path(path: Any, name: str = "path") -> Path:
    if not isinstance(path, str | os.PathLike):
        raise ImageFileError(f"{name}: expected a file name (str or path), got {type(path).__name__}")
    return Path(path)


def _read_bytes(p: Path) -> bytes:
    """The whole file, after checking that it is a regular file (a FIFO would block forever)."""
    if regular_file_size(p, ImageFileError, "an image file") == 0:
        raise ImageFileError(f"{p}: the file is empty (0 bytes)")
    try:
        return p.read_bytes()
    except OSError as exc:
        raise ImageFileError(f"{p}: cannot read the file ({exc.strerror or exc})") from None


def _check_pixels(p: Path, width: int, height: int, max_pixels: int) -> None:
    if width <= 0 or height <= 0:
        raise ImageFileError(f"{p}: damaged image file (size {width}x{height})")
    if width * height > max_pixels:
        raise ImageFileError(f"{p}: {width}x{height} is {width * height / 1e6:.0f} MP, over the limit of "
                             f"{max_pixels / 1e6:g} MP (max_pixels); raise max_pixels if the file is genuine")


def _pillow_open(data: bytes, p: Path):
    """Pillow's image object for the file, header parsed and pixels not decoded. Pillow's own
    open() would also apply its global decompression-bomb limit (which camkit's per-call cap
    replaces), so the plugins named in ``_PILLOW_FORMATS`` are asked directly, as open() does."""
    from PIL import BmpImagePlugin, Image, JpegImagePlugin, PngImagePlugin, PpmImagePlugin, WebPImagePlugin  # noqa: F401 - registers the plugins  # noqa: F401

    prefix = data[:16]
    for fmt in _PILLOW_FORMATS:
        entry = Image.OPEN.get(fmt)
        if entry is None:
            continue
        factory, accept = entry
        if accept is not None and accept(prefix) is not True:
            continue
        try:
            return factory(io.BytesIO(data), str(p))
        except Exception as exc:  # every way a third-party parser can fail on a bad header
            raise ImageFileError(f"{p}: damaged {fmt} file ({_why(exc)})") from None
    return None


def _why(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."


def _kind(data: bytes, p: Path) -> str:
    if p.suffix.lower() in RAW_SUFFIXES:
        return "RAW"
    if data[:4] in _TIFF_MAGIC:
        return "TIFF"
    return "PILLOW"


def _exif_fields(exif: Any) -> dict[str, Any]:
    """Orientation, make, model, lens and focal lengths from a Pillow Exif mapping."""

    def text(v: Any) -> str | None:
        if isinstance(v, bytes):
            v = v.decode("utf-8", "replace")
        if isinstance(v, str):
            v = v.strip("\x00 ").strip()
            return v or None
        return None

    def number(v: Any) -> float | None:
        try:
            x = float(v[0] / v[1]) if isinstance(v, tuple) and len(v) == 2 else float(v)
        except (TypeError, ValueError, ZeroDivisionError):
            return None
        return x if np.isfinite(x) and x > 0 else None

    out: dict[str, Any] = {}
    try:
        orient = int(exif.get(0x0112, 1))
    except (TypeError, ValueError):
        orient = 1
    out["orientation"] = orient if 1 <= orient <= 8 else 1
    out["make"], out["model"] = text(exif.get(0x010F)), text(exif.get(0x0110))
    try:
        sub = exif.get_ifd(0x8769)  # the Exif sub-IFD: lens and focal length
    except Exception:  # a damaged sub-IFD leaves these fields empty, never the image unreadable
        sub = {}
    out["lens"] = text(sub.get(0xA434))
    out["focal_length_mm"] = number(sub.get(0x920A))
    out["focal_length_35mm"] = number(sub.get(0xA405))
    return out


def read_image_info(path: str | os.PathLike) -> ImageInfo:
    """Format, stored size, EXIF orientation, camera and lens of an image file, without decoding
    its pixels.

    Raises
    ------
    ImageFileError
        Not an image file camkit reads, or damaged; the message names the file.
    """
    p = _as_path(path)
    data = _read_bytes(p)
    return _info(data, p)


def _info(data: bytes, p: Path) -> ImageInfo:
    kind = _kind(data, p)
    if kind == "RAW":
        with _RawHandle(data, p) as raw:
            s = raw.sizes
            w, h = int(s.width), int(s.height)
        fields = _pillow_exif_best_effort(data, p)
        return ImageInfo(p, "RAW", w, h, **fields)
    if kind == "TIFF":
        page = _tiff_page_shape(data, p)
        fields = _pillow_exif_best_effort(data, p)
        return ImageInfo(p, "TIFF", page[1], page[0], **fields)
    im = _pillow_open(data, p)
    if im is None:
        raise _not_an_image(data, p)
    try:
        fields = _exif_fields(im.getexif())
    except Exception:  # damaged EXIF: the pixels may still be fine
        fields = {}
    return ImageInfo(p, im.format or "?", int(im.size[0]), int(im.size[1]), **fields)


def _pillow_exif_best_effort(data: bytes, p: Path) -> dict[str, Any]:
    """EXIF of TIFF-based files (TIFF, DNG, NEF, CR2, ARW ...) through Pillow's TIFF parser;
    nothing when Pillow cannot parse the container."""
    try:
        from PIL import Image, TiffImagePlugin  # noqa: F401 - registers the plugin

        factory, _ = Image.OPEN["TIFF"]
        im = factory(io.BytesIO(data), str(p))
        return _exif_fields(im.getexif())
    except Exception:  # EXIF is information; a file Pillow cannot parse simply has none here
        return {}


def _not_an_image(data: bytes, p: Path) -> ImageFileError:
    return ImageFileError(f"{p}: not an image file camkit reads (expected JPEG, PNG, TIFF, BMP, WebP, PGM/PPM or "
                          f"camera RAW; the file starts with {data[:8]!r})")


# -- reading ------------------------------------------------------------------------------------


def read_image(path: str | os.PathLike, *, max_pixels: int = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """Read an image file into an array, as stored.

    Formats, recognised by their content: JPEG (baseline and progressive, CMYK converted to RGB),
    PNG (every colour type and bit depth, interlaced too), TIFF (every compression tifffile
    reads; 8/16-bit integer and 32-bit float samples; grey, RGB, palette), BMP, WebP, PGM/PPM;
    camera RAW (by name: :data:`RAW_SUFFIXES`; DNG also by content) is demosaiced by camkit, see
    below. Decoding goes through Pillow, tifffile (TIFF) and rawpy (RAW, ``camkit[raw]``).

    The EXIF orientation is not applied: rows come as stored, the pixel grid the sensor saw
    (:func:`read_image_info` gives the orientation).

    A RAW file gives linear camera RGB, uint16: the black level subtracted, the white level
    scaled to 65535, the camera's as-shot white balance applied, demosaiced with
    :func:`camkit.sensor.demosaic` ("menon"); no colour matrix, no tone curve. For the mosaic
    itself use :func:`read_raw`.

    Parameters
    ----------
    path : str or path
    max_pixels : int
        Width times height above which the file is refused before any decoding
        (:data:`DEFAULT_MAX_PIXELS`, 250 MP).

    Returns
    -------
    ndarray
        (H, W) grey, or (H, W, C) with C = 2 (grey and alpha), 3 (RGB) or 4 (RGBA); uint8,
        uint16 (16-bit files, RAW) or float32 (float TIFF).

    Raises
    ------
    ImageFileError
        The file does not exist, is empty, is not an image of these formats, is damaged or
        truncated, or exceeds ``max_pixels``; the message names the file and the reason.
    """
    p = _as_path(path)
    cap = as_positive_int(max_pixels, "max_pixels")
    return _decode_image(_read_bytes(p), p, cap)


def read_image_sha256(path: str | os.PathLike, *,
                      max_pixels: int = DEFAULT_MAX_PIXELS) -> tuple[np.ndarray, str]:
    """:func:`read_image`, and the SHA-256 (hex) of the bytes it decoded, from one read of the
    file (a batch job's manifest records it; reading the file again to hash it would read
    every input twice). Raises as :func:`read_image`."""
    p = _as_path(path)
    cap = as_positive_int(max_pixels, "max_pixels")
    data = _read_bytes(p)
    return _decode_image(data, p, cap), hashlib.sha256(data).hexdigest()


def read_image_and_info(path: str | os.PathLike, *,
                        max_pixels: int = DEFAULT_MAX_PIXELS) -> tuple[np.ndarray, ImageInfo | None]:
    """:func:`read_image` and :func:`read_image_info` from one read of the file (a calibration
    reads each photo's pixels and its EXIF; a file on a network share is then fetched once).
    The info is None where only the pixels could be made out. Raises as :func:`read_image`."""
    p = _as_path(path)
    cap = as_positive_int(max_pixels, "max_pixels")
    data = _read_bytes(p)
    img = _decode_image(data, p, cap)
    try:
        info = _info(data, p)
    except ImageFileError:
        info = None
    return img, info


def _decode_image(data: bytes, p: Path, cap: int) -> np.ndarray:
    """The pixels of ``data``, the bytes of file ``p`` (named in messages); see :func:`read_image`."""
    kind = _kind(data, p)
    if kind == "RAW":
        return _raw_to_rgb(_read_raw_data(data, p, cap))
    if kind == "TIFF":
        return _read_tiff(data, p, cap)
    im = _pillow_open(data, p)
    if im is None:
        raise _not_an_image(data, p)
    _check_pixels(p, int(im.size[0]), int(im.size[1]), cap)
    try:
        arr = _pillow_pixels(im, data, p)
        if im.format == "PNG":
            # Every chunk's CRC and the closing IEND (Pillow's verify): a PNG cut anywhere, or
            # with a flipped byte, is refused even where the pixels happened to inflate.
            _pillow_open(data, p).verify()
        return arr
    except ImageFileError:
        raise
    except Exception as exc:  # truncated data, corrupt streams: whatever the decoder raised
        raise ImageFileError(f"{p}: damaged {im.format} file ({_why(exc)})") from None


def _pillow_pixels(im: Any, data: bytes, p: Path) -> np.ndarray:
    """Decode a Pillow image into camkit's layout (see the module docstring)."""
    im.load()
    mode = im.mode
    rawmode = ""
    if im.format == "PNG" and mode in ("RGB", "RGBA", "LA"):
        rawmode = _png_rawmode(data)
    if rawmode.endswith(";16B"):
        # Pillow keeps 8 bits of a 16-bit colour PNG; imagecodecs (libpng) keeps all 16.
        import imagecodecs

        out = imagecodecs.png_decode(data)
        return np.ascontiguousarray(out.astype(np.uint16, copy=False))
    if mode == "1":
        return np.asarray(im, dtype=np.uint8) * np.uint8(255)
    if mode == "P" or mode == "PA":
        has_alpha = mode == "PA" or "transparency" in im.info
        im = im.convert("RGBA" if has_alpha else "RGB")
    elif mode in ("CMYK", "YCbCr", "LAB", "HSV", "RGBX", "RGBa"):
        im = im.convert("RGB")
    elif mode == "La":
        im = im.convert("LA")
    elif mode == "I":
        # 16-bit PNG/PGM come as 32-bit integers in some Pillow versions: back to their own type.
        arr = np.asarray(im)
        if arr.size and (arr.min() < 0 or arr.max() > 65535):
            raise ImageFileError(f"{p}: 32-bit integer images are not supported (values outside 0..65535)")
        return np.ascontiguousarray(arr.astype(np.uint16))
    arr = np.asarray(im)
    if arr.dtype.byteorder not in ("=", "|"):
        arr = arr.astype(arr.dtype.newbyteorder("="))
    return np.ascontiguousarray(arr)


def _png_rawmode(data: bytes) -> str:
    """The IHDR's colour type at 16 bits as Pillow names raw modes ("RGB;16B" for 16-bit RGB),
    or "" (the IHDR is the first chunk: W3C PNG specification, 3rd ed., sec. 5.6)."""
    if len(data) >= 26 and data[12:16] == b"IHDR" and data[24] == 16:
        return {2: "RGB;16B", 4: "LA;16B", 6: "RGBA;16B"}.get(data[25], "")
    return ""


def _tiff_page_shape(data: bytes, p: Path) -> tuple[int, int]:
    import tifffile

    try:
        with tifffile.TiffFile(io.BytesIO(data)) as tif:
            page = tif.pages.first
            return int(page.imagelength), int(page.imagewidth)
    except Exception as exc:  # tifffile raises many types on damaged headers
        raise ImageFileError(f"{p}: damaged TIFF file ({_why(exc)})") from None


def _read_tiff(data: bytes, p: Path, cap: int) -> np.ndarray:
    """The first image of a TIFF through tifffile; the photometric interpretation applied
    (white-is-zero inverted, palettes looked up), the samples' own type kept."""
    import tifffile

    try:
        with tifffile.TiffFile(io.BytesIO(data)) as tif:
            page = tif.pages.first
            if _DNG_VERSION_TAG in page.tags:
                return _raw_to_rgb(_read_raw_data(data, p, cap))
            h, w = int(page.imagelength), int(page.imagewidth)
            _check_pixels(p, w, h, cap)
            photometric = int(page.photometric)
            if photometric not in (0, 1, 2, 3):
                raise ImageFileError(f"{p}: TIFF with photometric interpretation {page.photometric.name} is not "
                                     "supported (expected grey, RGB or palette)")
            if page.samplesperpixel > 1 and photometric != 2 and page.samplesperpixel != 2:
                raise ImageFileError(f"{p}: TIFF with {page.samplesperpixel} samples per pixel and photometric "
                                     f"{page.photometric.name} is not supported")
            arr = page.asarray()
            colormap = page.colormap if photometric == 3 else None
    except ImageFileError:
        raise
    except Exception as exc:  # truncated strips, bad codes, unsupported compression
        raise ImageFileError(f"{p}: damaged or unsupported TIFF file ({_why(exc)})") from None
    if arr.ndim == 3 and arr.shape[0] in (2, 3, 4) and arr.shape[0] < arr.shape[2] and arr.shape[1:] == (h, w):
        arr = np.moveaxis(arr, 0, -1)  # planar configuration: samples first
    if arr.shape[:2] != (h, w) or arr.ndim not in (2, 3):
        raise ImageFileError(f"{p}: TIFF of shape {arr.shape} is not a single image of {w}x{h}")
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8) * np.uint8(255)
    if arr.dtype.kind == "f":
        arr = arr.astype(np.float32)
    elif arr.dtype not in (np.uint8, np.uint16):
        raise ImageFileError(f"{p}: TIFF with {arr.dtype} samples is not supported (expected 8- or 16-bit "
                             "unsigned integers or floats)")
    if photometric == 0:  # white is zero
        arr = (np.iinfo(arr.dtype).max - arr) if arr.dtype.kind == "u" else (1.0 - arr).astype(np.float32)
    elif photometric == 3:
        if colormap is None or arr.ndim != 2:
            raise ImageFileError(f"{p}: damaged TIFF (palette image without a colour map)")
        lut = np.asarray(colormap, dtype=np.uint16).T  # (n, 3), 16-bit entries (TIFF 6.0, sec. 5)
        if int(arr.max(initial=0)) >= len(lut):
            raise ImageFileError(f"{p}: damaged TIFF (palette index out of range)")
        arr = lut[arr]
        if page.bitspersample <= 8:
            arr = (arr >> 8).astype(np.uint8)
    arr = arr.astype(arr.dtype.newbyteorder("="), copy=False)
    return np.ascontiguousarray(arr)


# -- camera RAW ---------------------------------------------------------------------------------


def _rawpy_module():
    try:
        import rawpy
    except ImportError:
        raise ImageFileError("reading camera RAW files needs rawpy: pip install 'camkit[raw]'") from None
    return rawpy


class _RawHandle:
    def __init__(self, data: bytes, p: Path) -> None:
        rawpy = _rawpy_module()
        self.raw = rawpy.RawPy()
        try:
            self.raw.open_buffer(io.BytesIO(data))
        except Exception as exc:  # LibRaw's errors: unsupported or damaged file
            self.raw.close()
            raise ImageFileError(f"{p}: not a camera RAW file LibRaw reads ({_why(exc)})") from None

    def __enter__(self):
        return self.raw

    def __exit__(self, *exc) -> None:
        self.raw.close()


def read_raw(path: str | os.PathLike, *, max_pixels: int = DEFAULT_MAX_PIXELS) -> RawImage:
    """The sensor's mosaic of a camera RAW file (DNG, CR2, CR3, NEF, ARW, RAF, ORF, RW2, ...),
    through rawpy (LibRaw), with what :func:`camkit.sensor.demosaic` needs to apply.

    Needs the optional extra: ``pip install 'camkit[raw]'``.

    Examples
    --------
    >>> raw = read_raw("IMG_0001.CR2")                              # doctest: +SKIP
    >>> rgb = demosaic(raw.normalised(), raw.pattern)               # doctest: +SKIP

    Returns
    -------
    RawImage
        The visible area's mosaic (uint16), its 2x2 pattern, black and white levels and the
        as-shot white balance.

    Raises
    ------
    ImageFileError
        rawpy is not installed, the file is not a RAW file LibRaw reads or is damaged, the
        sensor is not a 2x2 Bayer mosaic (Fujifilm X-Trans, Foveon, four-colour filters), or
        it exceeds ``max_pixels``.
    """
    p = _as_path(path)
    cap = as_positive_int(max_pixels, "max_pixels")
    return _read_raw_data(_read_bytes(p), p, cap)


def _read_raw_data(data: bytes, p: Path, cap: int) -> RawImage:
    with _RawHandle(data, p) as raw:
        s = raw.sizes
        _check_pixels(p, int(s.width), int(s.height), cap)
        try:
            raw.unpack()
            mosaic = np.array(raw.raw_image_visible, dtype=np.uint16)
            pattern_idx = np.asarray(raw.raw_pattern)
            desc = raw.color_desc.decode("ascii", "replace")
            black = np.asarray(raw.black_level_per_channel, dtype=np.float64)
            white = float(raw.white_level)
            wb = np.asarray(raw.camera_whitebalance, dtype=np.float64)
        except ImageFileError:
            raise
        except Exception as exc:  # LibRaw's decoding errors
            raise ImageFileError(f"{p}: damaged camera RAW file ({_why(exc)})") from None
    if pattern_idx is None or pattern_idx.shape != (2, 2) or mosaic.ndim != 2:
        shape = None if pattern_idx is None else pattern_idx.shape
        raise ImageFileError(f"{p}: the sensor is not a 2x2 Bayer mosaic (colour pattern {shape}); camkit "
                             "demosaics Bayer sensors only (not X-Trans or Foveon)")
    pattern = "".join(desc[int(k)] if 0 <= int(k) < len(desc) else "?" for k in pattern_idx.ravel())
    if pattern not in ("RGGB", "BGGR", "GRBG", "GBRG"):
        raise ImageFileError(f"{p}: colour filter pattern {pattern!r} (colours {desc!r}) is not an RGB Bayer "
                             "pattern camkit demosaics")
    black2 = np.array([black[int(k)] if int(k) < len(black) else 0.0 for k in pattern_idx.ravel()]).reshape(2, 2)
    rgb_wb = np.ones(3)
    if wb.size >= 3 and np.isfinite(wb[:3]).all() and wb[1] > 0 and (wb[:3] > 0).all():
        rgb_wb = wb[:3] / wb[1]
    if not white > 0:
        white = float(np.iinfo(np.uint16).max)
    return RawImage(mosaic=mosaic, pattern=pattern, black_level=black2, white_level=white, white_balance=rgb_wb)


def _raw_to_rgb(raw: RawImage) -> np.ndarray:
    from camkit.sensor.cfa import cfa_masks
    from camkit.sensor.demosaic import demosaic

    x = raw.normalised()
    masks = cfa_masks(*x.shape, raw.pattern)
    gains = (masks * raw.white_balance[None, None, :].astype(np.float32)).sum(axis=2, dtype=np.float32)
    x = np.clip(x * gains, 0.0, 1.0)
    m16 = np.floor(x * np.float32(65535.0) + np.float32(0.5)).astype(np.uint16)
    return demosaic(m16, raw.pattern, "menon")


# -- writing ------------------------------------------------------------------------------------

#: The default zlib level of PNG writing: 1, OpenCV's ``IMWRITE_PNG_COMPRESSION`` default
#: ("best speed"): much faster than level 6 (Pillow's default) for a slightly larger file
#: (benchmarks/notes.md, issue 20, has the figures).
PNG_LEVEL = 1


def write_image(path: str | os.PathLike, image: np.ndarray, *, quality: int = 95,
                png_level: int = PNG_LEVEL) -> Path:
    """Write an image; the format follows the name's ending (any case).

    - ``.png``: uint8 or uint16; grey, grey+alpha, RGB or RGBA (libpng through imagecodecs;
      at level 1 with OpenCV's default filter and strategy); ``png_level`` is zlib's
      compression level 0-9 (lossless at every level: higher is smaller and slower);
    - ``.tif``/``.tiff``: uint8, uint16 or float32, any channel count up to 4 (tifffile, Deflate);
    - ``.jpg``/``.jpeg``: uint8 grey or RGB, ``quality`` 1-100 (Pillow; lossy).

    The file is written to a temporary name in the same folder and renamed into place, so a
    reader never sees half a file and an existing file is replaced only by a complete one
    (an interrupt leaves the old file or none). Returns the path.
    """
    p = Path(path)
    img = as_image(image, "image", max_channels=4)
    kind = p.suffix.lower()
    if kind == ".png":
        data = _encode_png(img, png_level)
    elif kind in (".tif", ".tiff"):
        data = _encode_tiff(img)
    elif kind in (".jpg", ".jpeg"):
        q = as_positive_int(quality, "quality")
        if q > 100:
            raise ParameterError(f"quality: expected 1..100, got {q}")
        data = _encode_jpeg(img, q)
    else:
        raise ParameterError(f"path: expected a name ending in .png, .tif, .tiff, .jpg or .jpeg, got {p.name!r}")
    return write_atomic(p, data)


def write_png(path: str | os.PathLike, image: np.ndarray, *, png_level: int = PNG_LEVEL) -> Path:
    """Write a uint8 or uint16 image, (H, W) grey, (H, W, 2) grey+alpha, (H, W, 3) RGB or
    (H, W, 4) RGBA, as PNG, atomically, with zlib level ``png_level`` 0-9 (see
    :func:`write_image`). Returns the path."""
    p = Path(path)
    return write_atomic(p, _encode_png(as_image(image, "image", max_channels=4), png_level))


def _encode_png(img: np.ndarray, level: int) -> bytes:
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or not 0 <= level <= 9:
        raise ParameterError(f"png_level: expected an integer 0..9 (zlib's compression level), got {level!r}")
    if img.dtype not in (np.uint8, np.uint16):
        raise ShapeError(f"image: expected uint8 or uint16 for PNG, got {img.dtype}")
    import imagecodecs

    img = np.ascontiguousarray(img)
    # libpng through imagecodecs (Pillow keeps only 8 bits of 16-bit colour, and is slower).
    # At level 1 (the default) the fast settings OpenCV's imwrite uses by default: the SUB
    # filter and zlib's run-length strategy (imagecodecs.png_encode's documentation): faster
    # and smaller than Pillow's encoder (benchmarks/notes.md has the figures).
    fast = {"strategy": 3, "filter": 16} if int(level) == 1 else {}
    return bytes(imagecodecs.png_encode(img, level=int(level), **fast))


def _encode_tiff(img: np.ndarray) -> bytes:
    import tifffile

    if img.dtype not in (np.uint8, np.uint16, np.float32):
        raise ShapeError(f"image: expected uint8, uint16 or float32 for TIFF, got {img.dtype}")
    buf = io.BytesIO()
    photometric = "rgb" if img.ndim == 3 and img.shape[2] in (3, 4) else "minisblack"
    extra = ["unassalpha"] if img.ndim == 3 and img.shape[2] in (2, 4) else None
    tifffile.imwrite(buf, np.ascontiguousarray(img), photometric=photometric, compression="zlib",
                     extrasamples=extra)
    return buf.getvalue()


def _encode_jpeg(img: np.ndarray, quality: int) -> bytes:
    from PIL import Image

    if img.dtype != np.uint8 or (img.ndim == 3 and img.shape[2] != 3):
        raise ShapeError(f"image: expected uint8 grey (H, W) or RGB (H, W, 3) for JPEG, got {img.dtype} "
                         f"{img.shape}")
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(img)).save(buf, format="JPEG", quality=quality)
    return buf.getvalue()
