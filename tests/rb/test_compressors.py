"""Primal / dual compressors and stabilisers as registered plugins (rbbench.rb.compressors).

The wrappers reproduce the library functions exactly, the registry lists them, and the
role contracts of :mod:`rbbench.testing` reject deliberately broken components.
(Every registered component passing its contract is ``tests/testing/test_contract.py``.)
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rbbench.cli import main
from rbbench.rb import compressors as comp
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.algorithms.cones import DUAL_COMPRESSORS
from rbbench.rb.algorithms.cones.baselines import pod_dual
from rbbench.rb.algorithms.pga import pga, supremizers, x_orthonormalize
from rbbench.rb.algorithms.pod import pod, weak_greedy
from rbbench.registry import ComponentSpec, Registry, default_registry
from rbbench.testing import (
    ContractViolation,
    check_dual,
    check_primal,
    check_spec,
    check_stabilizer,
    dual_test_data,
    primal_test_data,
    stabilizer_test_data,
)

pytestmark = pytest.mark.timeout(60)

PRIMAL_CAPS = {"tol": "energy", "nested": True}
CONE_CAPS = {"cone": True, "nested": True}
PGA_CAPS = {"online_hf": False, "inf_sup": "training set"}
SUP_CAPS = {"online_hf": True, "inf_sup": "every mu"}


# ---------------------------------------------------------------------------
# registration
# ---------------------------------------------------------------------------
EXPECTED = {
    "primal": {"pod": comp.PODPrimal, "greedy": comp.GreedyPrimal},
    "dual": {"pod": comp.PODLam, "cpg": comp.CPG, "mcpg": comp.MCPG, "eng": comp.ENG,
             "nnmf": comp.NNMF},
    "stabilizer": {"none": comp.NoStabilizer, "supremizer": comp.SupremizerStabilizer,
                   "pga": comp.PGAStabilizer},
}


@pytest.mark.parametrize("role", sorted(EXPECTED))
def test_registered_targets(role):
    reg = default_registry()
    assert reg.names(role) == sorted(EXPECTED[role])
    for name, cls in EXPECTED[role].items():
        assert reg.load(role, name) is cls
        assert check_spec(reg, reg.get(role, name)) is cls


def test_spec_check_requires_the_role_method():
    reg = Registry()
    for role, target, method in (("primal", "rbbench.rb.compressors:PrimalBasis", "__call__"),
                                 ("dual", "rbbench.rb.algorithms.cones:WMetric", "__call__"),
                                 ("stabilizer", "rbbench.rb.compressors:PODPrimal", "offline")):
        reg.add(ComponentSpec(name="x", role=role, target=target, description="d"))
        with pytest.raises(ContractViolation, match=f"no {method}\\(\\) method"):
            check_spec(reg, reg.get(role, "x"))


def test_dual_names_are_the_cli_names_and_capabilities_tell_cones():
    reg = default_registry()
    assert set(reg.names("dual")) == set(DUAL_COMPRESSORS)
    for name in DUAL_COMPRESSORS:
        assert reg.load("dual", name).name == name
        assert reg.get("dual", name).capabilities["cone"] is (name != "pod")
    assert reg.get("stabilizer", "supremizer").capabilities["online_hf"] is True
    assert reg.get("stabilizer", "pga").capabilities["online_hf"] is False


def test_protocols_are_satisfied():
    assert isinstance(comp.PODPrimal(), comp.PrimalCompressor)
    assert isinstance(comp.GreedyPrimal(), comp.PrimalCompressor)
    for cls in EXPECTED["stabilizer"].values():
        assert isinstance(cls(), comp.Stabilizer)


def test_rbbench_plugins_lists_them(capsys):
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    for role, names in EXPECTED.items():
        for name in names:
            assert any(line.split()[:1] == [role] and name in line for line in
                       out.splitlines()), (role, name)


# ---------------------------------------------------------------------------
# the wrappers change nothing
# ---------------------------------------------------------------------------
def test_primal_wrappers_reproduce_pod_and_greedy():
    U, X, _ = primal_test_data(1)
    a, b = comp.PODPrimal()(U, X, tol=1e-2), pod(U, X, tol=1e-2)
    assert np.array_equal(a.Z, b.Z) and a.history["singular_values"] == b.s.tolist()
    g, w = comp.GreedyPrimal()(U, X, n=4), weak_greedy(U, X, tol=1e-8, n_max=4)
    assert np.array_equal(g.Z, w.Z) and g.history["picks"] == w.picks
    assert g.history["indicator"] == "true error"

    def residual_indicator(Z, p):  # a weak greedy: a different indicator is used as given
        return float(np.linalg.norm(U[:, p] - Z @ (Z.T @ (X @ U[:, p]))))

    h = comp.GreedyPrimal(indicator=residual_indicator)(U, X, n=3)
    assert h.N == 3 and h.history["indicator"] == "custom"


@pytest.mark.parametrize("name", sorted(DUAL_COMPRESSORS))
def test_dual_wrappers_reproduce_the_functions(name):
    T, W = dual_test_data(2)
    a = EXPECTED["dual"][name]()(T, W, tol=0.05, r_max=8)
    b = DUAL_COMPRESSORS[name](T, W, tol=0.05, r_max=8)
    assert np.array_equal(a.generators, b.generators) and a.e_proj == b.e_proj
    assert a.name == name


def test_dual_options_are_forwarded():
    T, W = dual_test_data(3)
    assert comp.NNMF(r=3)(T, W).R == 3
    assert comp.ENG(sweeps=2)(T, W, tol=0.1).info["sweeps"] == 2
    with pytest.raises(TypeError, match="unexpected options"):
        comp.CPG(bogus=1)(T, W)


def test_stabilizers_reproduce_pga_and_supremizers():
    d = stabilizer_test_data(1)
    Z, Vg, X, xs = d["Z"], d["Vg"], d["X"], d["x_solve"]
    Z_off, hist = comp.PGAStabilizer().offline(Z, Vg, X, xs, d["B_train"], 0.2)
    ref = pga([supremizers(B, xs, Vg) for B in d["B_train"]], Z, X, 0.2)
    assert np.array_equal(Z_off, np.hstack([Z, ref.basis]))
    assert hist["sigma_max"] == ref.sigma_max.tolist() and hist["K"] == ref.dim
    assert comp.PGAStabilizer().online_basis(Z_off, Vg, X, xs, d["B_new"]) is Z_off
    sup = comp.SupremizerStabilizer()
    assert sup.offline(Z, Vg, X, xs, d["B_train"])[0] is not None
    Y = sup.online_basis(Z, Vg, X, xs, d["B_new"])
    assert np.array_equal(Y, x_orthonormalize(np.hstack([Z, supremizers(d["B_new"], xs, Vg)]),
                                              X)[0])
    with pytest.raises(ValueError, match="delta"):
        comp.PGAStabilizer().offline(Z, Vg, X, xs, d["B_train"], None)


def test_pga_max_dim_is_honoured():
    d = stabilizer_test_data(2)
    Z_off, hist = comp.PGAStabilizer(max_dim=2).offline(
        d["Z"], d["Vg"], d["X"], d["x_solve"], d["B_train"], 0.0)
    assert Z_off.shape[1] == d["Z"].shape[1] + 2 and hist["pga_stop"] == "max_dim"


def test_pga_default_delta_is_the_pipeline_rule():
    d = stabilizer_test_data(3)
    Ws = [d["W"]] * len(d["B_train"])
    got = comp.pga_default_delta(d["B_train"], Ws, d["x_solve"], d["Vg"])
    want = []
    for B in d["B_train"]:
        S, M = inf.quotient_matrices(B, d["x_solve"], d["Vg"], d["W"])
        want.append(inf.infsup_span(S, M) / inf.boundedness_constant(S, M))
    assert got == pytest.approx(0.5 * min(want), rel=1e-10) and 0 < got < 0.5
    with pytest.raises(ValueError, match="no parameters"):
        comp.pga_default_delta([], [], d["x_solve"], d["Vg"])


# ---------------------------------------------------------------------------
# the primal contract rejects broken compressors
# ---------------------------------------------------------------------------
class _Euclidean(comp.PODPrimal):
    """POD in the Euclidean product: Z^T Z = I, not Z^T X Z = I."""

    def __call__(self, U, X, *, tol=None, n=None):
        return super().__call__(U, None, tol=tol, n=n)


class _IgnoresN(comp.PODPrimal):
    def __call__(self, U, X, *, tol=None, n=None):
        return super().__call__(U, X, tol=tol)


class _IgnoresTol(comp.PODPrimal):
    def __call__(self, U, X, *, tol=None, n=None):
        return super().__call__(U, X, n=n)


class _Random(comp.PODPrimal):
    """Right size and X-orthonormal, but not built from the snapshots."""

    def __call__(self, U, X, *, tol=None, n=None):
        N = super().__call__(U, X, tol=tol, n=n).N
        Z, _ = x_orthonormalize(np.random.default_rng(0).standard_normal((U.shape[0], N)), X)
        return comp.PrimalBasis(Z=Z, name="random")


class _ArrayHistory(comp.PODPrimal):
    def __call__(self, U, X, *, tol=None, n=None):
        res = super().__call__(U, X, tol=tol, n=n)
        return dataclasses.replace(res, history={"s": np.ones(2)})


class _Mutates(comp.PODPrimal):
    def __call__(self, U, X, *, tol=None, n=None):
        U -= U.mean()  # in place: the caller's snapshots change
        return super().__call__(U, X, tol=tol, n=n)


class _ReturnsArray(comp.PODPrimal):
    def __call__(self, U, X, *, tol=None, n=None):
        return super().__call__(U, X, tol=tol, n=n).Z


@pytest.mark.parametrize("factory, caps, match", [
    (_Euclidean, PRIMAL_CAPS, "not X-orthonormal"),
    (_IgnoresN, PRIMAL_CAPS, "requested n = 1"),
    (_IgnoresTol, PRIMAL_CAPS, "not the first size"),
    (_Random, PRIMAL_CAPS, "leaves the span of the snapshots"),
    (_ArrayHistory, PRIMAL_CAPS, "JSON"),
    (_Mutates, PRIMAL_CAPS, "input was modified"),
    (_ReturnsArray, PRIMAL_CAPS, "not a PrimalBasis"),
    (comp.PODPrimal, {"nested": True}, "declare what tol bounds"),
    (comp.PODPrimal, {"tol": "energy"}, "'nested'"),
    (lambda: pod, PRIMAL_CAPS, "not a PrimalBasis"),  # the bare function: wrong protocol
    (pod, PRIMAL_CAPS, "factory\\(\\) raised"),  # a function target is not a factory
])
def test_primal_contract_rejects(factory, caps, match):
    with pytest.raises(ContractViolation, match=match):
        check_primal(factory, caps)


# ---------------------------------------------------------------------------
# the dual contract rejects broken compressors
# ---------------------------------------------------------------------------
class _PODClaimsCone(comp.DualCompressor):
    name = "pod"

    def __call__(self, LAM, W, *, tol=1e-3, r_max=None):
        return dataclasses.replace(pod_dual(LAM, W, tol=tol, r_max=r_max), is_cone=True)


def _cpg_patched(**changes):
    class Patched(comp.CPG):
        def __call__(self, LAM, W, *, tol=1e-3, r_max=None):
            b = super().__call__(LAM, W, tol=tol, r_max=r_max)
            return dataclasses.replace(b, **{k: f(b) for k, f in changes.items()})

    return Patched


class _IgnoresRmax(comp.CPG):
    def __call__(self, LAM, W, *, tol=1e-3, r_max=None):
        return super().__call__(LAM, W, tol=tol, r_max=None if r_max is None else r_max + 2)


class _IgnoresDualTol(comp.CPG):
    def __call__(self, LAM, W, *, tol=1e-3, r_max=None):
        return super().__call__(LAM, W, tol=0.0, r_max=r_max)


class _MutatesLam(comp.CPG):
    def __call__(self, LAM, W, *, tol=1e-3, r_max=None):
        LAM *= 2.0
        return super().__call__(LAM, W, tol=tol, r_max=r_max)


@pytest.mark.parametrize("factory, caps, match", [
    (_MutatesLam, CONE_CAPS, "input was modified"),
    (_PODClaimsCone, CONE_CAPS, "negative entry"),
    (_cpg_patched(e_proj=lambda b: [0.5 * e for e in b.e_proj]), CONE_CAPS, "does not match"),
    (_cpg_patched(e_proj=lambda b: [0.0] + b.e_proj[1:]), CONE_CAPS, "e_proj increases"),
    (_cpg_patched(e_orth=lambda b: b.e_orth[:-1]), CONE_CAPS, "one entry per generator"),
    (_cpg_patched(generators=lambda b: 2.0 * b.generators), CONE_CAPS, "unit W-norm"),
    (_IgnoresRmax, CONE_CAPS, "R = 8 > r_max = 6"),
    (_IgnoresDualTol, CONE_CAPS, "not the first size"),
    (comp.CPG, {"cone": False, "nested": True}, "is_cone = True"),
    (comp.PODLam, {"cone": True, "nested": True}, "is_cone = False"),
    (comp.CPG, {"nested": True}, "'cone'"),
])
def test_dual_contract_rejects(factory, caps, match):
    with pytest.raises(ContractViolation, match=match):
        check_dual(factory, caps)


# ---------------------------------------------------------------------------
# the stabiliser contract rejects broken stabilisers
# ---------------------------------------------------------------------------
class _DropsZ(comp.PGAStabilizer):
    def offline(self, Z, Vg, X, x_solve, B_train, delta=None):
        Z_off, hist = super().offline(Z, Vg, X, x_solve, B_train, delta)
        return Z_off[:, Z.shape[1]:], hist


class _RawSupremizers(comp.PGAStabilizer):
    """Appends the supremizers of the first parameter without orthonormalising them."""

    def offline(self, Z, Vg, X, x_solve, B_train, delta=None):
        return np.hstack([Z, supremizers(list(B_train)[0], x_solve, Vg)]), {}


class _ForgetsOnline(comp.SupremizerStabilizer):
    def online_basis(self, Z_off, Vg, X, x_solve, B):
        return Z_off


class _OnlineGrows(comp.NoStabilizer):
    """Says the space is parameter-independent, then enriches it online."""

    def online_basis(self, Z_off, Vg, X, x_solve, B):
        return comp.SupremizerStabilizer().online_basis(Z_off, Vg, X, x_solve, B)


class _ArrayHistoryPGA(comp.PGAStabilizer):
    def offline(self, Z, Vg, X, x_solve, B_train, delta=None):
        Z_off, hist = super().offline(Z, Vg, X, x_solve, B_train, delta)
        return Z_off, {**hist, "sigma_max": np.asarray(hist["sigma_max"])}


@pytest.mark.parametrize("factory, caps, match", [
    (_DropsZ, PGA_CAPS, "does not contain"),
    (_RawSupremizers, PGA_CAPS, "not X-orthonormal"),
    (comp.NoStabilizer, PGA_CAPS, "declares 'training set'"),  # beta_dec = 0 here
    (lambda: comp.PGAStabilizer(max_dim=1), PGA_CAPS, "declares 'training set'"),
    (_ForgetsOnline, SUP_CAPS, "declares 'every mu'"),
    (comp.PGAStabilizer, {"online_hf": False, "inf_sup": "every mu"}, "declares 'every mu'"),
    (comp.SupremizerStabilizer, {"online_hf": False, "inf_sup": "every mu"}, "online = True"),
    (_OnlineGrows, {"online_hf": False, "inf_sup": "not guaranteed"}, "online = False, but"),
    (_ArrayHistoryPGA, PGA_CAPS, "JSON"),
    (comp.PGAStabilizer, {"online_hf": False}, "inf_sup"),
])
def test_stabilizer_contract_rejects(factory, caps, match):
    with pytest.raises(ContractViolation, match=match):
        check_stabilizer(factory, caps)


def test_the_contract_data_needs_a_stabiliser():
    """N < R: beta_dec = 0 on span(Vg) at every training matrix, beta_on > 0."""
    d = stabilizer_test_data()
    for B in d["B_train"]:
        S, M = inf.quotient_matrices(B, d["X"], d["Vg"], d["W"], Z=d["Z"])
        assert inf.infsup_span(S, M) < 1e-6
        S, M = inf.quotient_matrices(B, d["x_solve"], d["Vg"], d["W"])
        assert inf.infsup_span(S, M) > 1.0


# ---------------------------------------------------------------------------
# a dual compressor from another package: a subclass, no internal table
# ---------------------------------------------------------------------------
class _NormOrderCone(comp.DualCompressor):
    """The snapshots in decreasing W-norm, normalised: a cone no table of rbbench names."""

    name = "outside-norm-order"

    def compress(self, LAM, W, *, tol=1e-3, r_max=None, **options):
        from rbbench.rb.algorithms.cones import as_metric, cone_projection
        from rbbench.rb.algorithms.cones.greedy import DualBasis

        M = as_metric(W)
        norms = M.norm(LAM)
        V, e_proj, e_orth = np.zeros((LAM.shape[0], 0)), [], []
        for q in np.argsort(-norms):
            if (e_proj and e_proj[-1] <= tol) or len(e_proj) == (r_max or LAM.shape[1]):
                break
            v = LAM[:, q] / norms[q]
            if V.shape[1] and cone_projection(v, V, W)[2] <= 1e-12:
                continue  # already in the cone
            e_orth.append(1.0 if not V.shape[1] else cone_projection(v, V, W)[2])
            V = np.column_stack([V, v])
            e_proj.append(float(np.max(cone_projection(LAM, V, W)[2]) / norms.max()))
        return DualBasis(V, self.name, True, [], e_proj, e_orth, dict(options))


def test_a_dual_compressor_subclass_from_outside_needs_no_table():
    assert _NormOrderCone.name not in DUAL_COMPRESSORS
    T, W = dual_test_data(4)
    basis = _NormOrderCone(seed=7)(T, W, tol=0.2)
    assert basis.name == "outside-norm-order" and basis.info == {"seed": 7}
    # e_proj recomputed here by the contract (NNLS on the cone), nested, tolerance honoured
    check_dual(_NormOrderCone, CONE_CAPS, name="outside-norm-order")


def test_a_dual_compressor_without_compress_says_what_to_implement():
    class Empty(comp.DualCompressor):
        name = "empty"

    T, W = dual_test_data(0)
    with pytest.raises(NotImplementedError, match=r"Empty \(empty\): implement compress"):
        Empty()(T, W)
