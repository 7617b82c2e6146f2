"""The wedge dual model (rbbench.rb.friction.wedge.model): De Saxce's fixed point against the HF
Coulomb solvers (a different algorithm), the cone at every node on raw values, the optimality
conditions of the reduced problem from D and q."""

from __future__ import annotations

import numpy as np
import pytest

from rbbench.hf.algebra.friction import condense_friction
from rbbench.hf.solvers import friction as fs
from rbbench.rb.friction.wedge.model import (
    WedgeBasis,
    desaxce_coulomb,
    identity_wedge,
    wedge_condensed,
    wedge_snapshots,
)
from rbbench.testing.contract_solver import random_friction_problem


def _dense(seed: int, m: int = 6) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((2 * m, 2 * m))
    return M @ M.T + 1.2 * m * np.eye(2 * m), rng.standard_normal(2 * m)


def _from_problem(seed: int) -> tuple[np.ndarray, np.ndarray]:
    p = random_friction_problem(seed, n=30, m=8)
    s = p.steps[-1]
    c = condense_friction(p.A, s.F, p.Bn, p.Bt, s.Gn)
    return 0.5 * (c.D + c.D.T), c.q


@pytest.mark.parametrize("F", [0.2, 1.0])
def test_identity_wedge_equals_coulomb_direct(F):
    """The full nodal wedge (V+ = V- = I): De Saxce's fixed point on bound-constrained QPs
    gives coulomb_direct's solution (active set / Lemke on the wedge LCP), with open, stick
    and slip nodes; it contracts by about F / 2 per iteration (measured)."""
    states, rates = set(), []
    for k in range(8):
        D, q = _dense(k) if k % 2 else _from_problem(k)
        m = q.size // 2
        ref = fs.coulomb_direct(D, q, F)
        assert ref.stop_reason == "converged"
        states.update(ref.states)
        b = identity_wedge(np.full(m, F))
        res = desaxce_coulomb(wedge_condensed(D, q, b), tol=1e-13)
        assert res.stop_reason == "converged"
        x = np.concatenate([b.Ln @ res.c, b.Lt @ res.c])
        assert np.abs(x - ref.x).max() <= 1e-9 * np.abs(ref.x).max()
        rates.append(res.rate)
    assert {"open", "stick", "slip"} <= states
    assert max(rates) < (0.15 if F < 0.5 else 0.85)


def test_reduced_wedge_cone_at_every_node_and_kkt():
    """Random non-negative generators (fewer than the nodes): raw reduced multipliers satisfy
    |lam_t| <= F lam_n at EVERY node, and c solves the associated cone QP with the gap
    modified by F |w_t| (KKT from D, q: c >= 0, grad >= 0, c . grad = 0)."""
    active = 0
    for seed in (5, 6, 8, 9):
        rng = np.random.default_rng(seed)
        D, q = _from_problem(seed)
        m = q.size // 2
        F = rng.uniform(0.1, 0.4, m)
        b = WedgeBasis(rng.uniform(0, 1, (m, 3)), rng.uniform(0, 1, (m, 2)), F)
        res = desaxce_coulomb(wedge_condensed(D, q, b))
        assert res.stop_reason == "converged" and res.c.size == 5
        ln, lt = b.Ln @ res.c, b.Lt @ res.c
        assert ln.min() >= 0.0 and np.all(np.abs(lt) <= F * ln * (1 + 1e-14))
        w = q + D @ np.concatenate([ln, lt])  # HF w at the reduced multipliers
        grad = b.generators.T @ np.concatenate([w[:m] + F * np.abs(w[m:]), w[m:]])
        gs = np.abs(b.generators.T @ q).max()
        assert res.c.min() >= 0.0 and grad.min() >= -1e-8 * gs
        assert abs(res.c @ grad) <= 1e-8 * gs * np.abs(res.c).max()
        active += int(np.abs(lt).max() > 1e-6 * np.abs(q).max() / np.abs(D).max())
    assert active >= 3


def test_wedge_snapshots_reconstruct_and_refuse_outside_the_cone():
    rng = np.random.default_rng(0)
    F = np.full(5, 0.3)
    ln = rng.uniform(0, 1, (5, 4))
    lt = F[:, None] * ln * rng.uniform(-1, 1, (5, 4))
    WP, WM, info = wedge_snapshots(ln, lt, F)
    assert WP.min() >= 0 and WM.min() >= 0 and info["clipped"] == 0
    b = WedgeBasis(WP, WM, F)
    c = np.concatenate([np.eye(4), np.eye(4)])  # c+ = c- = e_j: snapshot j
    assert np.allclose(b.Ln @ c, ln) and np.allclose(b.Lt @ c, lt)
    assert np.allclose(b.P, b.Ln.T * F[None, :])
    lt[0, 0] = 0.5 * ln[0, 0]
    with pytest.raises(ValueError, match="outside the Coulomb cone"):
        wedge_snapshots(ln, lt, F)


def test_friction_dual_choice_and_table():
    """The dual model is an option (default: auto; 'seed', the deprecated alias);
    unknown names refused; the comparison table puts summaries side by side."""
    from rbbench.rb.friction.options import FrictionOptions
    from rbbench.rb.friction.wedge.stage import comparison_table

    assert FrictionOptions().friction_dual == "auto"
    assert FrictionOptions(friction_dual="wedge").friction_dual == "wedge"
    with pytest.warns(DeprecationWarning, match="'seed' is now 'collocation'"):
        assert FrictionOptions(friction_dual="seed").friction_dual == "collocation"
    with pytest.raises(ValueError, match="valid: auto, collocation, wedge"):
        FrictionOptions(friction_dual="box")
    table = comparison_table({"collocation": {"R": 20, "S": 20, "err_u_max": 0.015},
                              "wedge": {"R": 20, "S": 20, "err_u_max": 2.4e-4}})
    assert "| dual unknowns (R + S) | 40 | 40 |" in table
    assert "| err_u max | 1.50e-02 | 2.40e-04 |" in table


@pytest.mark.parametrize("law, hyper, integration, expected", [
    ("coulomb", "auto", "gauss", ("wedge", "eim")),
    ("coulomb", "none", "gauss", ("wedge", "none")),
    ("coulomb", "auto", "segmented", ("wedge", "none")),  # moving points: no EIM
    ("tresca", "auto", "gauss", ("collocation", "auto")),
])
def test_auto_picks_the_model_for_the_law(law, hyper, integration, expected):
    """friction_dual = auto: the wedge model (and its EIM with hyper auto, when the contact
    points are fixed) on Coulomb scenes, the collocation model on Tresca scenes."""
    from types import SimpleNamespace

    from rbbench.rb.config import ReduceConfig
    from rbbench.rb.friction.offline import resolve_auto
    from rbbench.rb.friction.options import FrictionOptions

    scene = SimpleNamespace(path="s.toml", data={
        "friction": {"law": law},
        "discretization": {"contact_integration": integration},
        "geometry": {"kind": "halfdisks", "lower": "half_disk"}})
    cfg = resolve_auto(scene, ReduceConfig(hyper=hyper, options=FrictionOptions()))
    assert (cfg.options.friction_dual, cfg.hyper) == expected
    explicit = ReduceConfig(hyper=hyper, options=FrictionOptions(friction_dual="collocation"))
    assert resolve_auto(scene, explicit) is explicit
