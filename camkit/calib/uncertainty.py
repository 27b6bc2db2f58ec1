"""How well a calibration knows where the camera images a point."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from camkit._validate import as_matrix, as_points, as_positive_float
from camkit.errors import ParameterError
from camkit.lens.base import CameraModel

__all__ = ["projection_uncertainty"]


def projection_uncertainty(model: CameraModel, covariance: np.ndarray, free_params: Sequence[str], pixels: Any,
                           depth_m: float) -> np.ndarray:
    """One-sigma uncertainty (pixels, along the worst direction) of where a point is imaged,
    from the covariance of the fitted parameters.

    The point is the one seen at each pixel at ``depth_m`` in front of the camera; its pixel
    moves with the parameters as ``J = d pixel / d params`` (the lens model's analytic
    Jacobian), so its covariance is ``J C J^T`` and the returned value the square root of that
    2x2 matrix's larger eigenvalue. This is the uncertainty of the intrinsics alone, with the
    point fixed in the camera frame (the covariance is the intrinsics' marginal, poses
    eliminated), in the spirit of mrcal's projection uncertainty (D. Kogan, mrcal
    documentation, "Projection uncertainty").
    """
    if not isinstance(model, CameraModel):
        raise ParameterError(f"model: expected a camkit camera model, got {type(model).__name__}")
    names = tuple(free_params)
    unknown = [n for n in names if n not in model.param_names]
    if unknown:
        raise ParameterError(f"free_params: {unknown} are not parameters of {model.name!r}")
    cov = as_matrix(covariance, (len(names), len(names)), "covariance")
    depth = as_positive_float(depth_m, "depth_m")
    px = as_points(pixels, 2, "pixels")
    idx = [model.param_names.index(n) for n in names]
    X = model.unproject_depth(px, np.full(px.shape[:-1], depth))
    _, _, dk = model.project_with_jacobian(X)
    J = dk[..., idx]
    C = np.einsum("...ai,ij,...bj->...ab", J, cov, J)
    tr, det = C[..., 0, 0] + C[..., 1, 1], C[..., 0, 0] * C[..., 1, 1] - C[..., 0, 1] ** 2
    lam = tr / 2 + np.sqrt(np.maximum(tr * tr / 4 - det, 0.0))
    return np.sqrt(np.maximum(lam, 0.0))
