"""One sparse Levenberg-Marquardt solver for every least-squares problem in camkit.

A problem has named parameter blocks of two kinds: one **global** block that every observation
may depend on (a camera's free intrinsics; a homography's eight entries; a single pose), and
any number of **local** blocks of one size, each observation depending on at most one of them
(a pose per view). The normal equations then have an arrow shape, and each step eliminates the
local blocks by the Schur complement of their block-diagonal part, as bundle adjustment does
(B. Triggs, P. McLauchlan, R. Hartley and A. Fitzgibbon, "Bundle adjustment - a modern
synthesis", 1999, sec. 6.1): a global system of the global block's size, then each local block
alone. The inverse of the undamped complement is the global block's covariance (unit noise).

A problem supplies its residuals and Jacobians at a state (:class:`Linearization`) and moves a
state by a step (``retract``: rotations are updated multiplicatively, so the state is not a flat
vector); the solver owns damping, robust weights, convergence and the report. Calibration,
PnP and homography refinement are problems for it; a camera rig is another. (The checkerboard
detector, a layer below, fits its lattice's lens model of twelve parameters with a small dense
kernel of its own, :func:`camkit._kernels.lattice.lens_fit`.)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from camkit._kernels import calib as calib_kernels
from camkit._validate import as_positive_float, as_positive_int, check_choice
from camkit.errors import EstimationError, ParameterError

__all__ = ["LMOptions", "Linearization", "Problem", "RefineReport", "robust_weights", "solve"]


@dataclass(frozen=True, slots=True, eq=False)
class Linearization:
    """Residuals and Jacobians at one state.

    Attributes
    ----------
    residuals : ndarray, (N, K)
        One row per observation (K = 2 for a pixel).
    J_global : ndarray, (N, K, G)
        d residual / d global block.
    J_local : ndarray, (N, K, L)
        d residual / d the observation's local block (L = 0 where the problem has none).
    group : ndarray, (N,) int64
        The local block each observation depends on.
    """

    residuals: np.ndarray
    J_global: np.ndarray
    J_local: np.ndarray
    group: np.ndarray


class Problem(Protocol):
    """What :func:`solve` needs of a problem."""

    #: Names of the global block's parameters, in order (the covariance's rows).
    global_names: tuple[str, ...]
    #: Name of the local blocks' kind (``"pose"``) and their size (0: none).
    local_name: str
    local_size: int
    #: How many local blocks there are.
    n_groups: int

    def linearize(self, state: Any) -> Linearization:
        """Residuals and Jacobians at ``state``; raises ParameterError where the state is not
        a valid one (a trial step left the model's valid region)."""

    def retract(self, state: Any, d_global: np.ndarray, d_local: np.ndarray) -> Any:
        """``state`` moved by a step: ``d_global`` (G,), ``d_local`` (n_groups, L)."""


@dataclass(frozen=True, slots=True)
class LMOptions:
    """How :func:`solve` runs.

    Attributes
    ----------
    max_iterations : int
        Iterations before stopping without convergence (the report says so).
    tolerance : float
        Converged when an accepted step lowers the cost by less than this fraction.
    robust_loss : None, "huber" or "cauchy"
        Reweights each observation by its residual norm over ``robust_scale``.
    robust_scale : float
    damping : float
        The first step's damping, relative to the normal matrix's diagonal.
    covariance : bool
        Compute the global block's covariance at the solution (unit noise, unweighted).
    """

    max_iterations: int = 200
    tolerance: float = 1e-10
    robust_loss: str | None = None
    robust_scale: float = 1.0
    damping: float = 1e-6
    covariance: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "max_iterations", as_positive_int(self.max_iterations, "max_iterations"))
        for name in ("tolerance", "robust_scale", "damping"):
            object.__setattr__(self, name, as_positive_float(getattr(self, name), name))
        if self.robust_loss is not None:
            check_choice(self.robust_loss, ("huber", "cauchy"), "robust_loss")
        if not isinstance(self.covariance, bool):
            raise ParameterError(f"covariance: expected True or False, got {self.covariance!r}")


@dataclass(frozen=True, slots=True, eq=False)
class RefineReport:
    """What :func:`solve` found.

    Attributes
    ----------
    state : object
        The final state (the problem's own type).
    converged : bool
    iterations : int
    cost : float
        Final sum of (robustly weighted) squared residuals.
    message : str
        Why it stopped.
    residuals : ndarray, (N, K)
        At the final state.
    covariance : ndarray, (G, G)
        Of the global block, unit noise (multiply by the residual variance); NaN where not
        computed or singular.
    global_names : tuple of str
    n_params : int
        Global plus every local parameter.
    """

    state: Any
    converged: bool
    iterations: int
    cost: float
    message: str
    residuals: np.ndarray
    covariance: np.ndarray
    global_names: tuple[str, ...]
    n_params: int


def robust_weights(r: np.ndarray, loss: str | None, scale: float) -> np.ndarray:
    """Per-observation weights of the iteratively reweighted least squares for ``loss`` on the
    residual norm: Huber ``min(1, s/|r|)``, Cauchy ``1 / (1 + |r|^2/s^2)``, none 1."""
    if loss is None:
        return np.ones(len(r))
    n = np.linalg.norm(r, axis=1) / scale
    if loss == "huber":
        return np.where(n <= 1, 1.0, 1.0 / np.maximum(n, 1e-300))
    if loss == "cauchy":
        return 1.0 / (1.0 + n * n)
    raise ParameterError(f"robust_loss: expected None, 'huber' or 'cauchy', got {loss!r}")


_KERNELS: dict[int, Any] = {}


def _blocks(lin: Linearization, w: np.ndarray, n_groups: int):
    L = lin.J_local.shape[2]
    if L not in _KERNELS:  # one compiled kernel per local block size (numba caches it on disk)
        _KERNELS[L] = calib_kernels.make_normal_blocks(L)
    return _KERNELS[L](np.ascontiguousarray(lin.J_global, dtype=np.float64),
                                       np.ascontiguousarray(lin.J_local, dtype=np.float64),
                                       np.ascontiguousarray(lin.residuals, dtype=np.float64),
                                       np.ascontiguousarray(w, dtype=np.float64),
                                       np.ascontiguousarray(lin.group, dtype=np.int64), max(n_groups, 1))


def _cost(lin: Linearization, w: np.ndarray) -> float:
    r = lin.residuals
    return float((w[:, None] * r * r).sum())


def solve(problem: Problem, state: Any, options: LMOptions | None = None) -> RefineReport:
    """Minimise ``sum_n w_n |r_n|^2`` over the problem's blocks from ``state``.

    Each iteration forms the blocks of the normal equations (one numba pass), damps their
    diagonals by ``mu`` (Marquardt's scaling), eliminates the local blocks (Schur complement)
    and solves for the global step, then each local step. A step that lowers the cost is
    taken and ``mu`` divided by 10; one that does not (or leaves the valid region) is retried
    with ``mu`` times 4, up to 30 times; when none helps, the solver has converged. It stops
    when the relative decrease falls under ``options.tolerance`` or the step under 1e-12.

    Raises
    ------
    EstimationError
        The start itself has no finite cost.
    """
    opt = LMOptions() if options is None else options
    G, L, B = len(problem.global_names), problem.local_size, problem.n_groups
    lin = problem.linearize(state)
    w = robust_weights(lin.residuals, opt.robust_loss, opt.robust_scale)
    cost = _cost(lin, w)
    if not np.isfinite(cost):
        raise EstimationError("start: the starting point projects points outside the model's valid region; check "
                              "the object points' units and the image points' order")
    mu = opt.damping
    converged, message, it = False, "", 0
    eye_l = np.eye(L)
    for it in range(1, opt.max_iterations + 1):  # noqa: B007 - the count is reported after the loop
        U, W, V, gg, gl = _blocks(lin, w, B)
        dU = np.where(np.diag(U) > 0, np.diag(U), 1.0)
        dV = np.where(np.diagonal(V, axis1=1, axis2=2) > 0, np.diagonal(V, axis1=1, axis2=2), 1.0)
        improved = False
        for _ in range(30):
            try:
                Vinv = np.linalg.inv(V + mu * dV[:, :, None] * eye_l) if L else np.zeros((max(B, 1), 0, 0))
                S = U + mu * np.diag(dU) - np.einsum("vik,vkl,vjl->ij", W, Vinv, W)
                dg = np.linalg.solve(S, -gg + np.einsum("vik,vkl,vl->i", W, Vinv, gl)) if G else np.zeros(0)
            except np.linalg.LinAlgError:
                mu *= 10
                continue
            dl = np.einsum("vkl,vl->vk", Vinv, -gl - np.einsum("vik,i->vk", W, dg))[:B] if L else np.zeros((B, 0))
            try:
                trial = problem.retract(state, dg, dl)
                lin_new = problem.linearize(trial)
            except ParameterError:
                mu *= 10
                continue
            w_new = robust_weights(lin_new.residuals, opt.robust_loss, opt.robust_scale)
            cost_new = _cost(lin_new, w_new)
            if np.isfinite(cost_new) and cost_new < cost:
                rel = (cost - cost_new) / max(cost, 1e-300)
                state, lin, w, cost = trial, lin_new, w_new, cost_new
                mu = max(mu / 10, 1e-15)
                improved = True
                step = max(np.abs(dg).max(initial=0.0), np.abs(dl).max(initial=0.0))
                if rel < opt.tolerance or step < 1e-12:
                    converged, message = True, f"converged: relative cost decrease {rel:.1e} < {opt.tolerance:.0e}"
                break
            mu *= 4
        if not improved:
            converged = True
            message = "converged: no step reduces the cost further"
            break
        if converged:
            break
    else:
        message = f"stopped after {opt.max_iterations} iterations without converging"
    cov = np.full((G, G), np.nan)
    if opt.covariance and G:
        U, W, V, _, _ = _blocks(lin, np.ones(len(lin.residuals)), B)
        try:
            Vinv = np.linalg.inv(V) if L else np.zeros((max(B, 1), 0, 0))
            cov = np.linalg.inv(U - np.einsum("vik,vkl,vjl->ij", W, Vinv, W))
        except np.linalg.LinAlgError:
            pass
    return RefineReport(state=state, converged=converged, iterations=it, cost=cost, message=message,
                        residuals=lin.residuals, covariance=cov, global_names=tuple(problem.global_names),
                        n_params=G + L * B)
