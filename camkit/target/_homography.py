"""Plane-to-image homographies of many small point sets at once, for the targets' detectors
(the normalised DLT of Hartley and Zisserman, *Multiple View Geometry*, alg. 4.2, batched).
The calibration's own :func:`camkit.calib.find_homography` refines one set by maximum
likelihood; these are the detectors' quick fits."""

from __future__ import annotations

import numpy as np


def fit_homographies(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Least-squares homographies (normalised DLT, Hartley and Zisserman alg. 4.2) of K point
    sets, ``src`` (K, P, 2) to ``dst`` (K, P, 2), P >= 4, all at once: (K, 3, 3), NaN where a
    set is degenerate (its points coincide). Exact for four points in general position."""
    def normalise(p):
        c = p.mean(axis=1)
        d = np.sqrt(((p - c[:, None]) ** 2).sum(axis=2)).mean(axis=1)
        k = np.sqrt(2.0) / np.where(d > 1e-12, d, np.nan)
        T = np.zeros((len(p), 3, 3))
        T[:, 0, 0] = T[:, 1, 1] = k
        T[:, 0, 2], T[:, 1, 2], T[:, 2, 2] = -k * c[:, 0], -k * c[:, 1], 1.0
        return np.nan_to_num((p - c[:, None]) * k[:, None, None]), T

    a, Ts = normalise(src)
    b, Td = normalise(dst)
    K, P = a.shape[:2]
    A = np.zeros((K, 2 * P, 9))
    A[:, 0::2, 0:2], A[:, 0::2, 2] = a, 1.0
    A[:, 0::2, 6:8], A[:, 0::2, 8] = -b[:, :, :1] * a, -b[:, :, 0]
    A[:, 1::2, 3:5], A[:, 1::2, 5] = a, 1.0
    A[:, 1::2, 6:8], A[:, 1::2, 8] = -b[:, :, 1:2] * a, -b[:, :, 1]
    h = np.linalg.svd(A)[2][:, -1].reshape(K, 3, 3)
    ok = np.isfinite(Td).all(axis=(1, 2)) & np.isfinite(Ts).all(axis=(1, 2))
    H = np.full((K, 3, 3), np.nan)
    H[ok] = np.linalg.solve(Td[ok], h[ok] @ Ts[ok])
    return H


def fit_homography(src: np.ndarray, dst: np.ndarray) -> np.ndarray | None:
    """:func:`fit_homographies` of one point set, (P, 2) to (P, 2); None where degenerate."""
    H = fit_homographies(src[None], dst[None])[0]
    return H if np.isfinite(H).all() else None


def homography_misfit(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """For each of K point sets, ``src`` (K, P, 2) to ``dst`` (K, P, 2): the largest distance
    (in ``dst``'s units) by which the least-squares homography misses a point; inf where none
    is fitted."""
    miss = np.hypot(*(apply_homographies(fit_homographies(src, dst), src) - dst).transpose(2, 0, 1)).max(axis=1)
    return np.where(np.isfinite(miss), miss, np.inf)


def apply_homographies(H: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Each point set ``p`` (K, P, 2) mapped by its homography ``H`` (K, 3, 3); NaN where a
    point maps to infinity (or ``H`` is NaN)."""
    q = np.einsum("kij,kpj->kpi", H, np.concatenate([p, np.ones(p.shape[:2] + (1,))], axis=2))
    with np.errstate(divide="ignore", invalid="ignore"):
        return q[:, :, :2] / q[:, :, 2:]


def apply_homography(H: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``p`` (N, 2) mapped by ``H`` (3, 3)."""
    return apply_homographies(H[None], p[None])[0]
