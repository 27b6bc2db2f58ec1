"""The one sparse Levenberg-Marquardt (camkit.calib.refine) against dense linear algebra."""

from __future__ import annotations

import numpy as np
import pytest

from camkit.calib.refine import Linearization, LMOptions, robust_weights, solve
from camkit.errors import EstimationError, ParameterError


class _LinearArrow:
    """r = A_g x_g + A_l[group] x_l[group] - b: an arrow-shaped linear problem (3 global
    parameters, 5 local blocks of 2), whose least-squares solution and covariance numpy's dense
    algebra gives exactly."""

    global_names = ("a", "b", "c")
    local_name = "block"
    local_size = 2
    n_groups = 5

    def __init__(self, seed: int) -> None:
        rng = np.random.default_rng(seed)
        self.group = np.repeat(np.arange(self.n_groups), 8)
        n = len(self.group)
        self.Jg = rng.normal(size=(n, 2, 3))
        self.Jl = rng.normal(size=(n, 2, 2))
        self.b = rng.normal(size=(n, 2))

    def dense(self) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.group)
        A = np.zeros((2 * n, 3 + 2 * self.n_groups))
        A[:, :3] = self.Jg.reshape(2 * n, 3)
        for k in range(n):
            g = self.group[k]
            A[2 * k:2 * k + 2, 3 + 2 * g:5 + 2 * g] = self.Jl[k]
        return A, self.b.ravel()

    def linearize(self, state):
        xg, xl = state
        r = np.einsum("nki,i->nk", self.Jg, xg) + np.einsum("nkl,nl->nk", self.Jl, xl[self.group]) - self.b
        return Linearization(r, self.Jg, self.Jl, self.group)

    def retract(self, state, d_global, d_local):
        return state[0] + d_global, state[1] + d_local


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_schur_steps_reach_the_dense_least_squares_solution_and_covariance(seed):
    p = _LinearArrow(seed)
    report = solve(p, (np.zeros(3), np.zeros((5, 2))))
    A, b = p.dense()
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    assert report.converged, report.message
    # A linear problem: LM with a tiny damping lands on the solution to rounding (1e-9 of 1).
    np.testing.assert_allclose(report.state[0], x[:3], atol=1e-9)
    np.testing.assert_allclose(report.state[1].ravel(), x[3:], atol=1e-9)
    # The covariance of the global block is that block of (A^T A)^-1 (unit noise).
    np.testing.assert_allclose(report.covariance, np.linalg.inv(A.T @ A)[:3, :3], rtol=1e-9)
    assert report.n_params == 3 + 10 and report.global_names == ("a", "b", "c")
    np.testing.assert_allclose(report.cost, float(np.sum((A @ x - b) ** 2)), rtol=1e-9)


def test_a_problem_without_local_blocks():
    p = _LinearArrow(3)
    p.local_size, p.Jl = 0, np.zeros((len(p.group), 2, 0))
    report = solve(p, (np.zeros(3), np.zeros((5, 0))))
    x = np.linalg.lstsq(p.Jg.reshape(-1, 3), p.b.ravel(), rcond=None)[0]
    np.testing.assert_allclose(report.state[0], x, atol=1e-9)


def test_iteration_limit_is_reported_not_hidden():
    class Rosenbrock:
        """r = (1 - x, 10 (y - x^2)): a curved valley; one iteration cannot reach (1, 1)."""

        global_names = ("x", "y")
        local_name, local_size, n_groups = "", 0, 1

        def linearize(self, s):
            x, y = s
            r = np.array([[1 - x, 10 * (y - x * x)]])
            J = np.array([[[-1.0, 0.0], [-20 * x, 10.0]]])
            return Linearization(r, J, np.zeros((1, 2, 0)), np.zeros(1, dtype=np.int64))

        def retract(self, s, dg, dl):
            return s + dg

    one = solve(Rosenbrock(), np.array([-1.2, 1.0]), LMOptions(max_iterations=1))
    assert not one.converged and one.message == "stopped after 1 iterations without converging"
    full = solve(Rosenbrock(), np.array([-1.2, 1.0]))
    assert full.converged
    np.testing.assert_allclose(full.state, [1.0, 1.0], atol=1e-6)


def test_robust_weights():
    r = np.array([[0.5, 0.0], [3.0, 4.0]])
    np.testing.assert_allclose(robust_weights(r, "huber", 1.0), [1.0, 0.2])  # 1 inside the scale, s/|r| outside
    np.testing.assert_allclose(robust_weights(r, "cauchy", 1.0), [1 / 1.25, 1 / 26])
    np.testing.assert_allclose(robust_weights(r, None, 1.0), [1.0, 1.0])
    with pytest.raises(ParameterError, match="robust_loss: expected None, 'huber' or 'cauchy'"):
        robust_weights(r, "l1", 1.0)


def test_a_start_with_no_finite_cost_is_refused_in_words():
    p = _LinearArrow(0)
    p.b[0, 0] = np.nan
    with pytest.raises(EstimationError, match="start: the starting point"):
        solve(p, (np.zeros(3), np.zeros((5, 2))))


@pytest.mark.parametrize("kwargs,match", [
    ({"max_iterations": 0}, "max_iterations"), ({"tolerance": -1.0}, "tolerance"), ({"damping": float("nan")}, "damping"),
    ({"robust_loss": "l1"}, "robust_loss: expected one of"), ({"robust_scale": 0.0}, "robust_scale"),
    ({"covariance": "yes"}, "covariance: expected True or False"),
])
def test_options_are_checked(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        LMOptions(**kwargs)
