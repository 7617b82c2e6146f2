"""Every iterative HF contact solver has an iteration cap and says why it stopped: given
``max_iter`` iterations on a problem that needs more, it returns after at most that many
with a stop reason of :data:`rbbench.interfaces.STOP_REASONS` (``max_iterations`` when the
cap was what stopped it), never a hang; uncapped, the same call converges (so the cap, not
the problem, stopped it)."""

from __future__ import annotations

import numpy as np
import pytest

from rbbench.hf.algebra.friction import uzawa_friction
from rbbench.hf.solvers import friction as fs
from rbbench.hf.solvers import lcp
from rbbench.interfaces import STOP_REASONS

pytestmark = pytest.mark.timeout(120)


def _problem(m: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A Delassus-like SPD ``D`` (2m x 2m, condition about 1e3) and a load ``q`` that closes
    about half of the ``m`` contacts and shears them."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((2 * m, 2 * m)))
    D = Q @ np.diag(np.geomspace(1.0, 1e3, 2 * m)) @ Q.T
    q = np.concatenate([rng.uniform(-1.0, 0.5, m), rng.uniform(-1.0, 1.0, m)])
    return D, q


def _friction_calls(D, q):
    F = 0.5
    return {
        "uzawa_friction": lambda k: uzawa_friction(D, q, F=F, max_iter=k),
        "pdas_tresca": lambda k: fs.pdas_tresca(D, q, 0.3, max_iter=k, fallback=False),
        "coulomb_direct": lambda k: fs.coulomb_direct(D, q, F, max_iter=k, fallback=False),
        "coulomb_fixed_point": lambda k: fs.coulomb_fixed_point(D, q, F, max_iter=k),
        "coulomb_model_b": lambda k: fs.coulomb_model_b(D, q, max_iter=k),
        "model_b_newton": lambda k: fs.model_b_newton(D, q, max_iter=k, fallback=False),
    }


@pytest.mark.parametrize("name", list(_friction_calls(*_problem(2))))
def test_friction_solvers_stop_at_their_cap(name):
    D, q = _problem(30)
    call = _friction_calls(D, q)[name]
    full = call(200_000)
    assert full.stop_reason == "converged", (name, full.stop_reason)
    if full.iterations <= 1:
        pytest.skip(f"{name} converges in one iteration here: no cap to test")
    capped = call(1)
    assert capped.iterations <= 1
    assert capped.stop_reason in STOP_REASONS and capped.stop_reason != "converged"


@pytest.mark.parametrize("name", ["pdas", "uzawa"])
def test_lcp_solvers_stop_at_their_cap(name):
    D, q = _problem(30)
    D, q = D[:30, :30], q[:30]
    solve = getattr(lcp, name)
    _, it_full, why_full, *_ = solve(D, q, max_iter=200_000)
    assert why_full == "converged" and it_full > 1
    _, it, why, *_ = solve(D, q, max_iter=1)
    assert it <= 1 and why == "max_iterations"
