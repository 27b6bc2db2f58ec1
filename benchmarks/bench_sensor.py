"""Demosaicing: quality (colour PSNR) and speed vs OpenCV and colour-demosaicing.

Quality: the colour photographs bundled with scikit-image that load without a download
(astronaut, chelsea, coffee, rocket), mosaiced RGGB, 10-pixel border excluded, PSNR over
all three channels, averaged over the images. Speed: a 12 MP (4000x3000) mosaic.
"""

from __future__ import annotations

import warnings

import cv2
import numpy as np

from benchmarks.harness import Case, median_time
from camkit.sensor import demosaic, mosaic

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    _opts = np.get_printoptions()
    import colour_demosaicing as cd  # importing 'colour' changes NumPy's print options

    np.set_printoptions(**_opts)

IMAGES = ("astronaut", "chelsea", "coffee", "rocket")


def _photos() -> list[np.ndarray]:
    import skimage.data

    return [getattr(skimage.data, name)() for name in IMAGES]


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    a = a[10:-10, 10:-10].astype(np.float64)
    b = b[10:-10, 10:-10].astype(np.float64)
    return float(10 * np.log10(1.0 / np.mean((a - b) ** 2)))


def _check_opencv_pattern() -> None:
    """OpenCV names Bayer codes after the second row's first two colours: an RGGB mosaic is
    COLOR_BayerBG2RGB. Check on a flat colour that the code decodes our RGGB correctly."""
    rgb = np.zeros((8, 8, 3), np.uint8)
    rgb[...] = (200, 100, 50)
    out = cv2.cvtColor(mosaic(rgb, "RGGB"), cv2.COLOR_BayerBG2RGB)
    assert np.abs(out[2:-2, 2:-2].astype(int) - rgb[2:-2, 2:-2]).max() <= 1, "wrong Bayer code"


def extra_tables() -> str:
    _check_opencv_pattern()
    rows = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for img in _photos():
            f = img.astype(np.float64) / 255.0
            raw = mosaic(f, "RGGB")
            raw8 = mosaic(img, "RGGB")
            results = {
                "camkit bilinear": demosaic(raw, "RGGB", "bilinear"),
                "OpenCV Bayer (cvtColor BayerBG2RGB)": cv2.cvtColor(raw8, cv2.COLOR_BayerBG2RGB) / 255.0,
                "camkit malvar": demosaic(raw, "RGGB", "malvar"),
                "colour-demosaicing Malvar2004": cd.demosaicing_CFA_Bayer_Malvar2004(raw, "RGGB"),
                "camkit menon": demosaic(raw, "RGGB", "menon"),
                "colour-demosaicing Menon2007": cd.demosaicing_CFA_Bayer_Menon2007(raw, "RGGB"),
                "OpenCV VNG (BayerBG2RGB_VNG)": cv2.cvtColor(raw8, cv2.COLOR_BayerBG2RGB_VNG) / 255.0,
            }
            for name, out in results.items():
                rows.setdefault(name, []).append(_psnr(out, f))
    lines = ["| demosaicing | mean colour PSNR (dB) | " + " | ".join(IMAGES) + " |",
             "|---|---|" + "---|" * len(IMAGES)]
    for name, vals in rows.items():
        lines.append(f"| {name} | {np.mean(vals):.3f} | " + " | ".join(f"{v:.2f}" for v in vals) + " |")
    # Time per megapixel at 12 MP for every method, same run.
    rng = np.random.default_rng(0)
    raw12 = cv2.GaussianBlur(rng.integers(0, 256, (3000, 4000), dtype=np.uint8), (0, 0), 1.5)
    rawf = raw12.astype(np.float64) / 255.0
    timers = {
        "camkit bilinear": lambda: demosaic(raw12, "RGGB", "bilinear"),
        "OpenCV Bayer (cvtColor BayerBG2RGB)": lambda: cv2.cvtColor(raw12, cv2.COLOR_BayerBG2RGB),
        "camkit malvar": lambda: demosaic(raw12, "RGGB", "malvar"),
        "colour-demosaicing Malvar2004": lambda: cd.demosaicing_CFA_Bayer_Malvar2004(rawf, "RGGB"),
        "camkit menon": lambda: demosaic(raw12, "RGGB", "menon"),
        "colour-demosaicing Menon2007": lambda: cd.demosaicing_CFA_Bayer_Menon2007(rawf, "RGGB"),
        "OpenCV VNG (BayerBG2RGB_VNG)": lambda: cv2.cvtColor(raw12, cv2.COLOR_BayerBG2RGB_VNG),
    }
    lines += ["", "| demosaicing, 12 MP uint8 (colour-demosaicing: float64) | ms per megapixel |",
              "|---|---|"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, fn in timers.items():
            slow = name.startswith("colour")
            t = median_time(fn, repeats=3 if slow else 7, warmup=1 if slow else 2)
            lines.append(f"| {name} | {t * 1e3 / 12.0:.2f} |")
    return "\n".join(lines) + "\n"


def cases() -> list[Case]:
    rng = np.random.default_rng(0)
    raw12 = cv2.GaussianBlur(rng.integers(0, 256, (3000, 4000), dtype=np.uint8), (0, 0), 1.5)
    rawf = raw12.astype(np.float64) / 255.0

    def malvar_cd():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return cd.demosaicing_CFA_Bayer_Malvar2004(rawf, "RGGB")

    return [
        # ~7 ms a call: 25 pairs (0.4 s), as for the halving; with 7, slow spells on the shared
        # machine gave 3.3 to 22.8 ms for camkit between runs of the same code.
        Case("demosaic bilinear", "12 MP RGGB u8", lambda: demosaic(raw12, "RGGB", "bilinear"),
             "cv2.cvtColor BayerBG2RGB", lambda: cv2.cvtColor(raw12, cv2.COLOR_BayerBG2RGB), target=2.0,
             repeats=25),
        Case("demosaic malvar", "12 MP RGGB", lambda: demosaic(raw12, "RGGB", "malvar"),
             "colour-demosaicing Malvar2004 (float64)", malvar_cd, target=0.05, repeats=3, warmup=1),
        Case("demosaic menon", "12 MP RGGB u8", lambda: demosaic(raw12, "RGGB", "menon"),
             "cv2.cvtColor BayerBG2RGB_VNG", lambda: cv2.cvtColor(raw12, cv2.COLOR_BayerBG2RGB_VNG),
             target=1.0),
    ]
