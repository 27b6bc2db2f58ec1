"""Plane-to-image homographies of many small point sets at once, for the targets' detectors
(the normalised DLT of Hartley and Zisserman, *Multiple View Geometry*, alg. 4.2, batched).
The calibration's own :func:`camkit.calib.find_homography` refines one set by maximum
likelihood; these are the detectors' quick fits."""

from __future__ import annotations

import numpy as np

from camkit._kernels import markers as markers_kernels


def fit_homographies(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Least-squares homographies of K point sets, ``src`` (K, P, 2) to ``dst`` (K, P, 2),
    P >= 4, all at once: (K, 3, 3), NaN where a set is degenerate (its points coincide, or lie
    on a line). The normalised DLT (Hartley and Zisserman alg. 4.2), h33 = 1 in the normalised
    frames (:func:`camkit._kernels.markers.fit_homographies`). Exact for four points in
    general position."""
    src = np.ascontiguousarray(src, dtype=np.float64)
    dst = np.ascontiguousarray(dst, dtype=np.float64)
    out = np.empty((src.shape[0], 3, 3))
    markers_kernels.fit_homographies(src, dst, out)
    return out


def fit_homography(src: np.ndarray, dst: np.ndarray) -> np.ndarray | None:
    """:func:`fit_homographies` of one point set, (P, 2) to (P, 2); None where degenerate."""
    H = fit_homographies(src[None], dst[None])[0]
    return H if np.isfinite(H).all() else None


def apply_homographies(H: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Each point set ``p`` (K, P, 2) mapped by its homography ``H`` (K, 3, 3); NaN where a
    point maps to infinity (or ``H`` is NaN)."""
    q = np.einsum("kij,kpj->kpi", H, np.concatenate([p, np.ones(p.shape[:2] + (1,))], axis=2))
    with np.errstate(divide="ignore", invalid="ignore"):
        return q[:, :, :2] / q[:, :, 2:]


def apply_homography(H: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``p`` (N, 2) mapped by ``H`` (3, 3)."""
    return apply_homographies(H[None], p[None])[0]
