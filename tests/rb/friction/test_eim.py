"""Friction hyper-reduction and stabilisation: the P1 row evaluator
against the HF tangential operators, the friction EIM (exact on its training set, at its
magic entries, HF-size independent), the combined inf-sup of ``b^n + b^tau`` (mixed cone
against brute force, reduced with the full dual space = HF), PGA on the combined form."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from scipy.optimize import minimize

from rbbench.hf.components import make_components
from rbbench.hf.geometry.operators import contact_operators
from rbbench.hf.model import build_problem
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.algorithms.eim import deim, eim_error, eim_error_curve
from rbbench.rb.algorithms.pga import riesz_lower_bound, x_orthonormalize
from rbbench.rb.friction.eim import (
    friction_eim,
    friction_layout,
    friction_operators,
    friction_training_operators,
    reduced_eim_errors,
)
from rbbench.rb.friction.infsup import (
    combined_b,
    combined_generators,
    combined_pga,
    combined_supremizers,
    combined_w,
    hf_constants,
    mixed_cone_infsup,
    mixed_zero_test,
    reduced_constants,
)
from rbbench.rb.hyper.contact_eim import build_row_evaluator, tangent
from rbbench.scene.loading import load_scene

COARSE = ["discretization.degree=1", "discretization.h_contact=0.02",
          "discretization.h_max=0.25"]
#: coarser still, for the inf-sup tests (2m HF solves): n_free = 4090, m = 65 nodes
TINY = ["discretization.degree=1", "discretization.h_contact=0.04", "discretization.h_max=0.4"]
_CACHE: dict = {}


def _setup(overrides: tuple[str, ...] = tuple(COARSE)) -> dict:
    """P1 hertz_friction: components, four problems on D, X on the free dofs."""
    if overrides not in _CACHE:
        sc = load_scene("hertz_friction", list(overrides))
        b, f, _ = make_components(sc, "skfem", "mixed", "friction-ssn")
        mus = np.linspace(0.7, 1.3, 4)[:, None]
        probs = [build_problem(b, f, sc, mu) for mu in mus]
        p = probs[0]
        X = p.X[p.free][:, p.free].tocsr()
        _CACHE[overrides] = dict(sc=sc, b=b, f=f, mus=mus, probs=probs, X=X,
                                 xs=inf.make_solver(X))
    return _CACHE[overrides]


def _random_basis(n: int, N: int, seed: int) -> np.ndarray:
    """An orthonormal random primal basis (enough for exactness tests, not for
    generalisation: its columns are not smooth)."""
    return np.linalg.qr(np.random.default_rng(seed).standard_normal((n, N)))[0]


# ---------------------------------------------------------------------------
# the P1 row evaluator and the friction EIM
# ---------------------------------------------------------------------------
def test_p1_row_evaluator_reproduces_bn_bt_gn_rows():
    """Normal and tangential rows on the friction (P1) multipliers, from the restricted
    layout, equal the rows of the full HF operators (another code path: the full pairing)."""
    s = _setup()
    layout = s["b"].contact_layout()
    rng = np.random.default_rng(1)
    m = s["probs"][0].Bn.shape[0]
    rows = np.sort(rng.choice(m, 6, replace=False))
    ev = build_row_evaluator(friction_layout(layout), rows, np.linspace(0.7, 1.3, 13)[:, None])
    for mu in [0.7, 1.3, *rng.uniform(0.7, 1.3, 2)]:
        c = contact_operators(layout, np.array([mu]), tangential=True)
        for tangential, full in ((False, c.B_nodal()), (True, c.Bt())):
            Br, Gr = ev(mu, tangential=tangential)
            assert abs(full[ev.rows]).sum() == pytest.approx(np.abs(Br).sum(), rel=1e-12)
            np.testing.assert_allclose(Br, full[ev.rows][:, ev.local_dofs].toarray(),
                                       atol=1e-14 * abs(full).max())
            np.testing.assert_allclose(Gr, c.G_nodal()[ev.rows],
                                       atol=1e-14 * np.abs(c.G_nodal()).max())
            Z = rng.standard_normal((ev.n_local, 3))
            e_row, e_col = np.divmod(np.arange(ev.rows.size * 3), 3)
            p = ev.pairing(mu)
            d = tangent(p.nrm) if tangential else p.nrm
            vals = ev.jump_entries(p, d, Z, *ev.support(e_row), e_col)
            np.testing.assert_allclose(vals, (Br @ Z).ravel(), atol=1e-13 * np.abs(Br @ Z).max())


def test_friction_eim_exact_on_training_and_at_magic_entries():
    """tol = 1e-12: the training arrays are reproduced to rounding; off training, the
    online magic entries equal those of the HF ``Bn(mu) Z``, ``Bt(mu) Z``; the online
    evaluator touches a few local dofs only; picklable."""
    s = _setup()
    layout, free = s["b"].contact_layout(), s["probs"][0].free
    mus = np.linspace(0.7, 1.3, 9)[:, None]
    Bn, Bt, G = friction_training_operators(layout, mus, free)
    rng = np.random.default_rng(2)
    Z = _random_basis(free.size, 4, 3)
    Vn, Vt = np.abs(rng.standard_normal((G.shape[0], 3))), rng.standard_normal((G.shape[0], 2))
    fe = friction_eim(layout, Bn, Bt, G, Z, Vn, Vt, free, mus, tol=1e-12)
    for j, mu in enumerate(mus):
        exact = (Vn.T @ (Bn[j] @ Z), Vn.T @ G[:, j], Vt.T @ (Bt[j] @ Z))
        for a, e in zip(fe(mu), exact, strict=True):
            np.testing.assert_allclose(a, e, atol=1e-10 * np.abs(e).max())
    mu = np.array([0.93])
    c = contact_operators(layout, mu, tangential=True)
    ev, p = fe.evaluator, fe.evaluator.pairing(mu)
    for part, full, d in ((fe.normal, c.B_nodal(), p.nrm), (fe.tangential, c.Bt(), tangent(p.nrm))):
        C = full[:, free] @ Z
        got = ev.jump_entries(p, d, fe.Z_loc, *part.support, part.col)
        np.testing.assert_allclose(got, C[ev.rows[part.pos], part.col],
                                   atol=1e-13 * np.abs(C).max())
    assert fe.info["n_local_dofs"] < 0.2 * free.size
    again = pickle.loads(pickle.dumps(fe))
    for a, e in zip(again(mu), fe(mu), strict=True):
        np.testing.assert_array_equal(a, e)


def test_eim_error_curve_matches_truncated_eims():
    """The nested validation curve at size k equals eim_error of the EIM stopped at k."""
    x = np.linspace(0.0, 1.0, 120)
    mus = np.random.default_rng(0).uniform(0.0, 1.0, 25)
    S = np.array([np.exp(-(x - m) ** 2 / 0.05) for m in mus]).T
    res = deim(S[:, :18], tol=1e-10)
    curve = eim_error_curve(res, S[:, 18:])
    for k in (1, 3, res.m):
        assert curve["ratio"][k - 1] == pytest.approx(eim_error(deim(S[:, :18], m_max=k),
                                                                S[:, 18:]), rel=1e-8, abs=1e-14)
    np.testing.assert_allclose(eim_error_curve(res, S[:, :18])["ratio"], res.errors,
                               atol=1e-14)
    assert np.all(curve["max_rel"] >= curve["ratio"] - 1e-15)


def test_friction_operators_give_the_projected_arrays():
    """Smooth primal basis (responses to contact loads): the validation errors of the reduced
    arrays fall as the EIM training set densifies (13 -> 49 points), below 1e-3 at 49;
    FrictionOperators: A_N, F_N exact (affine), the rest from the EIM, gt = 0."""
    s = _setup()
    layout, probs = s["b"].contact_layout(), s["probs"]
    free = probs[0].free
    Zraw = np.column_stack([s["xs"](p.Bn.T @ np.ones(p.Bn.shape[0])) for p in probs[:3]])
    Z = np.linalg.qr(Zraw)[0]
    Vn = np.abs(probs[0].Bn @ Z[:, :2]) + 1e-3
    Vt = probs[0].Bt @ Z[:, :2]
    mv = np.array([[0.81], [1.17]])
    valid = friction_training_operators(layout, mv, free)
    errs = []
    for P in (13, 49):  # the pairing kinks C(mu): the error falls as D_train densifies
        mus = np.linspace(0.7, 1.3, P)[:, None]
        fe = friction_eim(layout, *friction_training_operators(layout, mus, free), Z, Vn, Vt,
                          free, mus, tol=1e-10)
        errs.append(reduced_eim_errors(fe, mv, *valid, Z, Vn, Vt))
    assert all(errs[1][k] < errs[0][k] / 5 for k in ("e_eim_BnN", "e_eim_BtN")), errs
    assert max(errs[1].values()) < 1e-3, errs
    cache = {}

    def problem_at(mu):
        key = float(np.asarray(mu).ravel()[0])
        if key not in cache:
            cache[key] = build_problem(s["b"], s["f"], s["sc"], np.atleast_1d(mu))
        return cache[key]

    ops = friction_operators(problem_at, s["sc"].bounds, fe, Z)
    p, mu = probs[1], s["mus"][1]
    arr = ops(mu)
    np.testing.assert_allclose(arr.A, Z.T @ (p.A @ Z), rtol=1e-10, atol=1e-10 * abs(p.A).max())
    np.testing.assert_allclose(arr.F, Z.T @ p.F, atol=1e-9 * np.abs(Z.T @ p.F).max())
    exact = Vt.T @ (p.Bt @ Z)
    assert np.abs(arr.Bt - exact).max() <= errs[1]["e_eim_BtN"] * 10 * np.abs(exact).max()
    assert np.array_equal(arr.law_values, p.coefficient) and not arr.gt.any()


# ---------------------------------------------------------------------------
# inf-sup of the combined form
# ---------------------------------------------------------------------------
def _pencil(seed: int, R: int = 4, S: int = 2, k: int = 5):
    rng = np.random.default_rng(seed)
    C = rng.standard_normal((k, R + S))
    G = rng.standard_normal((R + S, R + S))
    return C, C.T @ C, G @ G.T + 0.5 * np.eye(R + S)


@pytest.mark.parametrize("seed", range(4))
def test_mixed_cone_infsup_against_brute_force(seed):
    """Exact face enumeration (normal part signed, tangential free) against 40 bounded
    local minimisations and 20k feasible samples: never above them, attained at its argmin, and
    the span value is a lower bound (here 0: rank C = 5 < 6, while the cone value is not)."""
    C, S, M = _pencil(seed)
    r = mixed_cone_infsup(S, M, 4, C=C)
    y = r.argmin
    assert r.kind == "cone-exact" and y[:4].min() >= 0
    assert np.sqrt(y @ S @ y / (y @ M @ y)) == pytest.approx(r.value, rel=1e-9)
    rng = np.random.default_rng(10 + seed)
    Y = rng.standard_normal((20000, 6))
    Y[:, :4] = np.abs(Y[:, :4]) * (rng.random((20000, 4)) < 0.6)
    q = np.einsum("ci,ij,cj->c", Y, S, Y) / np.einsum("ci,ij,cj->c", Y, M, Y)
    best = np.sqrt(q.min())
    def quotient(v):
        q = v @ S @ v / (v @ M @ v)
        return q, 2.0 * (S @ v - q * (M @ v)) / (v @ M @ v)

    for y0 in rng.standard_normal((40, 6)):
        y0[:4] = np.abs(y0[:4])
        res = minimize(quotient, y0, jac=True, method="L-BFGS-B",
                       bounds=[(0, None)] * 4 + [(None, None)] * 2)
        if np.linalg.norm(res.x) > 1e-6:
            best = min(best, np.sqrt(res.fun))
    assert r.value <= best * (1 + 1e-9)
    assert r.value >= best * (1 - 1e-5)
    assert r.span <= r.value + 1e-12 and not r.is_zero
    upper = mixed_cone_infsup(S, M, 4, C=C, exact_max_r=0)
    assert upper.kind == "cone-upper" and upper.value >= r.value * (1 - 1e-9)


def test_mixed_cone_reduces_to_the_cone_and_the_span():
    """No tangential part: infsup_cone; no normal part: the span value."""
    C, S, M = _pencil(3, R=5, S=0, k=6)
    a, b = mixed_cone_infsup(S, M, 5, C=C), inf.infsup_cone(S, M, C=C)
    assert a.value == pytest.approx(b.value, rel=1e-10)
    C, S, M = _pencil(3, R=0, S=4)
    assert mixed_cone_infsup(S, M, 0, C=C).value == pytest.approx(inf.infsup_span(S, M),
                                                                   rel=1e-10)


def test_mixed_zero_test():
    """beta = 0 iff some (c >= 0, theta) != 0 is annihilated: a constructed null vector is
    found, flipping the sign of its normal generator removes it, a dependent tangential
    column is detected."""
    rng = np.random.default_rng(5)
    Ct, Cn = rng.standard_normal((6, 2)), rng.standard_normal((6, 3))
    a, th = np.array([1.0, 2.0, 0.5]), rng.standard_normal(2)
    Cn[:, 2] = -(Cn[:, :2] @ a[:2] + Ct @ th) / a[2]
    C = np.column_stack([Cn, Ct])
    assert np.linalg.norm(C @ np.r_[a, th]) < 1e-12 and mixed_zero_test(C, 3)
    C[:, 2] *= -1.0
    assert not mixed_zero_test(C, 3)
    assert mixed_zero_test(np.column_stack([Cn, Ct, Ct[:, :1]]), 3)


def test_reduced_constants_with_the_full_dual_space_equal_the_hf_ones():
    """Brute force on a tiny mesh: the reduced constants with Vn = Vt = I and the
    primal space spanned by the X-orthonormalised supremizers (the projection path, not the
    X^{-1} path of hf_constants) equal beta_HF and c_HF; beta_HF > 0, not zero by the LP."""
    s = _setup(tuple(TINY))
    p, X, xs = s["probs"][0], s["X"], s["xs"]
    hf = hf_constants(p.Bn, p.Bt, p.W, xs)
    m = p.Bn.shape[0]
    eye = np.eye(m)
    Q, _ = x_orthonormalize(combined_supremizers(p.Bn, p.Bt, xs, eye, eye), X)
    red = reduced_constants(p.Bn, p.Bt, p.W, X, eye, eye, Z=Q, c_hf=hf.c, cone=False)
    assert red.span == pytest.approx(hf.span, rel=1e-6)
    assert red.c == pytest.approx(hf.c, rel=1e-9)
    assert hf.span > 0 and not hf.is_zero and not red.is_zero
    assert red.span_rel == pytest.approx(hf.value_rel, rel=1e-6) and 0 < hf.value_rel < 1
    # the combined form on the combined dual basis: the same operator as its pieces
    Vn, Vt = eye[:, :3], eye[:, 3:5]
    np.testing.assert_array_equal(combined_b(p.Bn, p.Bt).toarray()[:m], p.Bn.toarray())
    assert combined_generators(Vn, Vt).shape == (2 * m, 5)
    assert combined_w(p.W).shape == (2 * m, 2 * m)


def test_pga_on_the_combined_form_reaches_delta_and_stabilises():
    """PGA on the combined supremizers reaches its tolerance (sigma_max non-increasing);
    then at every training mu the raw span lower bound of beta_off over V_N + S > 0, not
    zero by the LP, and >= sqrt(1 - sigma^2) beta_on (Riesz bound, from raw values)."""
    s = _setup(tuple(TINY))
    probs, X, xs = s["probs"], s["X"], s["xs"]
    p0 = probs[0]
    m = p0.Bn.shape[0]
    # R = S = 3 smooth nodal fields: normal ones non-negative
    t = np.linspace(0.0, 1.0, m)
    Vn = np.column_stack([np.exp(-((t - c) / 0.2) ** 2) for c in (0.3, 0.5, 0.7)])
    Vt = np.column_stack([np.sin((k + 1) * np.pi * t) for k in range(3)])
    Z = _random_basis(p0.free.size, 3, 4)
    ratios = []
    for p in probs:
        T = combined_supremizers(p.Bn, p.Bt, xs, Vn, Vt)
        Sm = T.T @ (combined_b(p.Bn, p.Bt).T @ combined_generators(Vn, Vt))
        Mm = inf._gram(combined_w(p.W), combined_generators(Vn, Vt))
        ratios.append(inf.infsup_span(Sm, Mm) / inf.boundedness_constant(Sm, Mm))
    # the rule of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
    # parametric variational inequalities" (talk): the sup over training, as pga_delta computes it
    delta = max(ratios)
    res = combined_pga(probs, Z, X, xs, Vn, Vt, delta)
    assert res.stop_reason in ("tolerance", "exhausted") and res.sigma_max[-1] <= delta
    assert np.all(np.diff(res.sigma_max) <= 1e-12)
    Z_off = np.hstack([Z, res.basis])
    for j, p in enumerate(probs):
        off = reduced_constants(p.Bn, p.Bt, p.W, X, Vn, Vt, Z=Z_off, exact_max_r=3)
        # beta_on: V_N + S_R(mu) holds every supremizer of the reduced dual set
        T = combined_supremizers(p.Bn, p.Bt, xs, Vn, Vt)
        on = reduced_constants(p.Bn, p.Bt, p.W, X, Vn, Vt, Z=np.hstack([Z, T]), cone=False)
        assert off.span > 0 and not off.is_zero and off.kind == "cone-exact"
        assert off.value >= off.span * (1 - 1e-12)
        assert off.span >= riesz_lower_bound(on.span, res.sigma[j]) * (1 - 1e-8)
