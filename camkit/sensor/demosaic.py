"""Demosaicing: a full-colour image from a Bayer sensor's raw mosaic."""

from __future__ import annotations

import numpy as np

from camkit._alloc import new_image
from camkit._kernels import demosaic as demosaic_kernels
from camkit._kernels import menon as menon_kernels
from camkit._validate import as_image, check_choice
from camkit.errors import ShapeError
from camkit.sensor.cfa import pattern_code

__all__ = ["DEMOSAIC_METHODS", "demosaic"]

#: "bilinear": each missing colour is the mean of its nearest samples.
#: "malvar": Malvar, He and Cutler's gradient-corrected linear filters.
#: "menon": Menon, Andriani and Calvagno's directional filtering with a posteriori decision,
#: with its refinement step.
DEMOSAIC_METHODS = ("bilinear", "malvar", "menon")


def demosaic(raw: np.ndarray, pattern: str = "RGGB", method: str = "menon") -> np.ndarray:
    """Reconstruct RGB from a Bayer mosaic.

    Methods (:data:`DEMOSAIC_METHODS`):

    - ``"bilinear"``: the mean of the 2 or 4 nearest samples of each missing colour.
    - ``"malvar"``: H. S. Malvar, L.-W. He and R. Cutler, "High-quality linear interpolation
      for demosaicing of Bayer-patterned color images", ICASSP 2004,
      doi:10.1109/ICASSP.2004.1326587 — bilinear corrected by the Laplacian of the sampled
      colour (5x5 filters).
    - ``"menon"`` (default): D. Menon, S. Andriani and G. Calvagno, "Demosaicing with
      directional filtering and a posteriori decision", IEEE TIP 16(1), 2007,
      doi:10.1109/TIP.2006.884928 — green interpolated horizontally and vertically, the
      direction whose colour differences vary less chosen per pixel, red and blue from colour
      differences along it, then the paper's refinement step.

    Borders are mirrored without repeating the edge pixel, which keeps the Bayer phase.
    Sampled values are returned unchanged: ``mosaic(demosaic(raw), pattern) == raw``.

    Parameters
    ----------
    raw : ndarray, (H, W), uint8, uint16, float32 or float64; H, W >= 2
    pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}
    method : {"bilinear", "malvar", "menon"}

    Returns
    -------
    ndarray, (H, W, 3), the dtype of ``raw``
        Integer outputs are rounded and clipped to the dtype's range; float outputs are not
        clipped (interpolation can overshoot slightly at edges).
    """
    img = as_image(raw, "raw")
    if img.ndim != 2:
        raise ShapeError(f"raw: expected a single-channel mosaic (H, W), got shape {img.shape}")
    if img.shape[0] < 2 or img.shape[1] < 2:
        raise ShapeError(f"raw: expected at least 2x2 pixels (one Bayer tile), got {img.shape}")
    code = pattern_code(pattern)
    method = check_choice(method, DEMOSAIC_METHODS, "method")
    is_int = img.dtype.kind == "u"
    hi = float(np.iinfo(img.dtype).max) if is_int else 0.0
    H, W = img.shape
    out = new_image((H, W, 3), img.dtype)  # pages touched in NumPy, not by the parallel kernel
    src = np.ascontiguousarray(img)
    if method == "bilinear":
        if is_int:
            demosaic_kernels.bilinear_int(src, code, out)
        else:
            demosaic_kernels.bilinear(src, code, is_int, hi, out)
        return out
    if method == "malvar":
        if is_int and W >= 4:
            demosaic_kernels.malvar_int(src, code, int(hi), out)
        else:
            demosaic_kernels.malvar(src, code, is_int, hi, out)
        return out
    # Menon: one streaming pass over ring buffers; float32 arithmetic, float64 for float64 input.
    consts = np.array([0.5, 0.25, 3.0], dtype=np.float64 if img.dtype == np.float64 else np.float32)
    menon_kernels.menon(src, code, consts, is_int, hi, out)
    return out
