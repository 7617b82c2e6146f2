"""NGSolve backend: the same operators and solutions as scikit-fem on one identical mesh,
the same Hertz values on its own Netgen meshes, options, the direct-solver hook, the CLI."""

from __future__ import annotations

import contextlib
import dataclasses
import io

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

pytest.importorskip("ngsolve",
                    reason='NGSolve backend not installed: pip install "rbbench[ngsolve]"')

import ngsolve as ngs  # noqa: E402
from rbbench_plugins.backends.ngsolve.backend import NGSolveBackend
from rbbench_plugins.backends.ngsolve.fe import sparse_cholesky
from rbbench_plugins.backends.skfem.meshes import graded_half_disk, unit_square  # noqa: E402
from support.fields import dof_permutation

from rbbench.cli import main  # noqa: E402
from rbbench.hf.condensation.dense import condense
from rbbench.hf.model import solve_hf  # noqa: E402
from rbbench.registry import default_registry  # noqa: E402
from rbbench.scene.loading import load_scene  # noqa: E402
from rbbench.testing import HERTZ_COARSE  # noqa: E402

COARSE = list(HERTZ_COARSE)
RIGID = ["geometry.lower='rigid_flat'"]
#: (scene, overrides): the two-body Hertz case, its rigid-flat variant, the membrane.
SCENES = {"two-body": ("hertz_halfdisks", COARSE),
          "rigid-flat": ("hertz_halfdisks", COARSE + RIGID),
          "membrane": ("membrane_obstacle", [])}


def _scene(key: str, degree: int = 1, extra=()):
    name, overrides = SCENES[key]
    return load_scene(name, overrides + [f"discretization.degree={degree}", *extra])


def _pair(key: str, degree: int = 1, extra=()):
    """(skfem backend, ngsolve backend on the skfem meshes, scene)."""
    sc = _scene(key, degree, extra)
    return (default_registry().create("backend", "skfem", scene=sc),
            NGSolveBackend(sc, mesh="skfem"), sc)


def _mult_permutation(ds, dn, p) -> np.ndarray:
    """Rows of the skfem multipliers in NGSolve order (nodal: one per free dof)."""
    if ds.contact.multiplier != "nodal":
        return np.arange(ds.contact.n_mult)
    fs = np.setdiff1d(np.arange(ds.n_dofs), ds.dirichlet_dofs)
    fn = np.setdiff1d(np.arange(dn.n_dofs), dn.dirichlet_dofs)
    return np.searchsorted(fs, p[fn])


def _rel(a, b) -> float:
    diff = abs(a - b).max()
    return float(diff / abs(b).max())


# ---------------------------------------------------------------------------
# one identical mesh: same operators, same solutions
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("degree", [1, 2])
@pytest.mark.parametrize("key", list(SCENES))
def test_operators_match_skfem_on_the_same_mesh(key, degree):
    bs, bn, sc = _pair(key, degree)
    p = dof_permutation(bs, bn)
    for mu in (sc.default_mu, sc.bounds[:, 1]):
        ds, dn = bs.discretize(mu), bn.discretize(mu)
        r = _mult_permutation(ds, dn, p)
        cs, cn = ds.contact, dn.contact
        errors = {
            "A": _rel(dn.A, ds.A[p][:, p]), "X": _rel(dn.X, ds.X[p][:, p]),
            "B": _rel(cn.B(), cs.B()[r][:, p]), "G": _rel(cn.G(), cs.G()[r]),
            "W": _rel(cn.W(), cs.W()[r][:, r]),
        }
        if np.any(ds.F):
            errors["F"] = _rel(dn.F, ds.F[p])
        assert max(errors.values()) < 1e-10, errors
        assert dn.A.shape == ds.A.shape and cn.n_mult == cs.n_mult
        # the same Dirichlet dofs with the same values
        want = dict(zip(ds.dirichlet_dofs.tolist(), ds.dirichlet_values.tolist(), strict=True))
        got = dict(zip(p[dn.dirichlet_dofs].tolist(), dn.dirichlet_values.tolist(), strict=True))
        assert got == want


@pytest.mark.parametrize("key, degree", [("two-body", 1), ("two-body", 2), ("rigid-flat", 1),
                                         ("membrane", 1)])
def test_hf_solutions_match_skfem_on_the_same_mesh(key, degree):
    bs, bn, sc = _pair(key, degree)
    p = dof_permutation(bs, bn)
    reg = default_registry()
    mu = sc.bounds[:, 0] if key != "membrane" else sc.default_mu
    a, b = (solve_hf(sc, mu, components=(backend, reg.create("formulation", "mixed"),
                                         reg.create("solver", "ssn"))) for backend in (bs, bn))
    assert a.result.converged and b.result.converged
    assert b.problem.factorize is sparse_cholesky  # the NGSolve direct solver was used
    r = _mult_permutation(a.disc, b.disc, p)
    assert _rel(b.result.u, a.result.u[p]) < 1e-8
    assert _rel(b.result.lam, a.result.lam[r]) < 1e-8
    for k in ("contact_force", "max_pressure", "energy"):
        assert abs(b.metrics[k] - a.metrics[k]) <= 1e-8 * abs(a.metrics[k]), k
    assert b.metrics["n_active"] == a.metrics["n_active"]


def test_mesh_from_arrays_equals_the_named_mesh():
    """``mesh=(points, triangles)`` / ``{body: ...}``: the arrays are the mesh, exactly."""
    sc = _scene("membrane")
    m = unit_square(int(sc.data["discretization"]["n_cells"]))
    d_arr = NGSolveBackend(sc, mesh=(m.p.T, m.t.T)).discretize(sc.default_mu)
    d_ref = NGSolveBackend(sc, mesh="skfem").discretize(sc.default_mu)
    assert abs(d_arr.A - d_ref.A).max() == 0 and np.array_equal(d_arr.F, d_ref.F)
    sc = _scene("rigid-flat")
    zone = tuple(np.pi * np.asarray(sc.data["geometry"]["contact_zone"]))
    m = graded_half_disk(zone, 0.04, 0.3, 0.3)
    b = NGSolveBackend(sc, mesh={"upper": (m.p.T, m.t.T)})
    assert b.upper.nv == m.p.shape[1]
    d = b.discretize(1.0)
    assert np.isclose(d.contact.weights.sum(), np.pi / 4, rtol=1e-2)


# ---------------------------------------------------------------------------
# own (Netgen) meshes
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("extra", [[], RIGID, ["discretization.degree=2"]])
def test_hertz_on_own_meshes_matches_skfem(extra):
    """Different meshes, same physics: contact force within 2 %, Hertz errors both small."""
    sc = load_scene("hertz_halfdisks", COARSE + extra)
    a, b = (solve_hf(sc, 1.0, backend=name).metrics for name in ("skfem", "ngsolve"))
    assert abs(b["contact_force"] - a["contact_force"]) <= 0.02 * a["contact_force"]
    assert abs(b["max_pressure"] - a["max_pressure"]) <= 0.03 * a["max_pressure"]
    for m in (a, b):
        assert abs(m["hertz"]["a_rel_error"]) < 0.08 and abs(m["hertz"]["p0_rel_error"]) < 0.08


def test_netgen_mesh_geometry():
    """Arc vertices on the unit circle, flat face at y = 0, contact facets of size ~h_contact."""
    b = NGSolveBackend(_scene("two-body"))
    h = b.h_contact
    for body, sign in ((b.upper, -1.0), (b.lower, 1.0)):
        p = body.points
        assert np.all(sign * p[:, 1] >= 0) and np.all(np.linalg.norm(p, axis=1) <= 1 + 1e-14)
        chain = b.contact_layout().slave if body is b.upper else b.contact_layout().master
        length = np.linalg.norm(chain.b - chain.a, axis=1)
        assert 0.5 * h < length.min() and length.max() < 1.3 * h
        assert np.allclose(np.linalg.norm(chain.a, axis=1), 1.0, atol=1e-14)
    area = sum(ngs.Integrate(1.0, body.mesh) for body in (b.upper, b.lower))
    assert abs(area - np.pi) < 0.01 * np.pi


def test_assembly_happens_on_the_mu_mapped_body():
    """Inside ``mapped`` the NGSolve mesh is the physical body: area R1^2 pi / 2, centre c(mu)."""
    b = NGSolveBackend(_scene("two-body"))
    body, amap = b.upper, b._body_maps()["upper"]
    area0 = ngs.Integrate(1.0, body.mesh)
    for mu in (0.7, 1.3):
        r1, centre = amap.at(np.array([mu]))
        with body.mapped(amap, np.array([mu])):
            area = ngs.Integrate(1.0, body.mesh)
            cy = ngs.Integrate(ngs.y, body.mesh) / area
        assert np.isclose(area, r1**2 * area0, rtol=1e-12)
        assert np.isclose(cy, centre[1] - r1 * 4 / (3 * np.pi), rtol=1e-2)
    assert np.isclose(ngs.Integrate(1.0, body.mesh), area0, rtol=1e-14)  # deformation undone


def test_material_follows_mu():
    """A mu-dependent Young's modulus scales the upper block exactly like scikit-fem's."""
    bs, bn, sc = _pair("rigid-flat", 1, ['material.upper.E="mu.mu"'])
    p = dof_permutation(bs, bn)
    A7, A13 = bn.discretize(0.7).A, bn.discretize(1.3).A
    assert _rel(A13, A7 * (1.3 / 0.7)) < 1e-12
    assert _rel(A13, bs.discretize(1.3).A[p][:, p]) < 1e-10


@pytest.mark.parametrize("degree", [1, 2])
def test_rigid_motions_and_jumps_in_the_lagrange_basis(degree):
    """Lagrange dofs: rigid motions are nodal interpolants, A annihilates them and a
    translation of the slave gives Un u = v . n (P2: through the edge-bubble change of basis)."""
    b = NGSolveBackend(_scene("two-body", degree))
    d = b.discretize(1.0, needs=frozenset({"tangential"}))
    t = b.dof_table()
    v = np.array([0.3, -0.7])
    x = t["x_hat"]
    rot = np.where(t["component"] == 0, -x[:, 1], x[:, 0])
    trans = v[t["component"]]
    scale = abs(d.A).max()
    for mode in (trans, rot):
        assert np.abs(d.A @ mode).max() <= 1e-10 * scale * np.abs(mode).max()
    upper = np.where(t["body"] == 0, trans, 0.0)
    n = d.contact.normals
    assert np.allclose(d.contact.Un @ upper, n @ v, atol=1e-12)
    assert np.allclose(d.contact.Ut @ upper, np.stack([-n[:, 1], n[:, 0]], axis=1) @ v,
                       atol=1e-12)
    assert np.allclose(d.contact.Un @ trans, 0.0, atol=1e-12)
    vd = np.concatenate([body.vertex_dofs for body in d.bodies])
    assert np.array_equal(np.sort(vd.ravel()), np.flatnonzero(t["kind"] == 0))


# ---------------------------------------------------------------------------
# the direct-solver hook
# ---------------------------------------------------------------------------
def test_sparse_cholesky_solves_like_superlu():
    rng = np.random.default_rng(0)
    n = 300
    R = sp.random(n, n, density=0.02, random_state=1)
    A = (R @ R.T + sp.identity(n)).tocsr()
    b1, b2 = rng.standard_normal(n), rng.standard_normal((n, 70))  # 70 > one MultiVector block
    solve = sparse_cholesky(A)
    for rhs in (b1, b2):
        ref = spla.spsolve(A.tocsc(), rhs)
        assert solve(rhs).shape == rhs.shape
        assert np.abs(solve(rhs) - ref).max() <= 1e-10 * np.abs(ref).max()


def test_factorize_hook_reaches_the_condensed_solver():
    b = NGSolveBackend(_scene("membrane"))
    disc = b.discretize(b.scene.default_mu)
    calls = []

    def spy(A):
        calls.append(A.shape)
        return sparse_cholesky(A)

    reg = default_registry()
    prob = reg.create("formulation", "mixed").build(dataclasses.replace(disc, factorize=spy))
    assert prob.factorize is spy
    res = reg.create("solver", "ssn").solve(prob)
    assert calls == [prob.A.shape] and res.converged
    ref = condense(prob.A, prob.F, prob.B, prob.G)  # SuperLU
    hook = condense(prob.A, prob.F, prob.B, prob.G, factorize=sparse_cholesky)
    assert _rel(hook.D, ref.D) < 1e-10 and _rel(hook.u0, ref.u0) < 1e-10
    plain = NGSolveBackend(b.scene, direct_solver="scipy").discretize(b.scene.default_mu)
    assert plain.factorize is None
    assert default_registry().create("backend", "skfem", scene=b.scene).discretize(
        b.scene.default_mu).factorize is None


# ---------------------------------------------------------------------------
# options
# ---------------------------------------------------------------------------
def test_option_errors_name_the_option_and_the_valid_values():
    sc = _scene("rigid-flat")
    with pytest.raises(TypeError, match="unknown options \\['meshh'\\].*'mesh'"):
        NGSolveBackend(sc, meshh="skfem")
    with pytest.raises(ValueError, match="option mesh = 'gmsh'.*'netgen', 'skfem'"):
        NGSolveBackend(sc, mesh="gmsh")
    with pytest.raises(ValueError, match="option direct_solver = 'lu'.*'sparsecholesky'"):
        NGSolveBackend(sc, direct_solver="lu")
    with pytest.raises(ValueError, match="option threads = 0"):
        NGSolveBackend(sc, threads=0)
    m = graded_half_disk((-2.0, -1.0), 0.05, 0.3, 0.3)
    p, t = m.p.T, m.t.T
    two = _scene("two-body")
    with pytest.raises(ValueError, match="option mesh: .*missing \\['lower'\\]"):
        NGSolveBackend(two, mesh={"upper": (p, t)})
    with pytest.raises(ValueError, match="option mesh\\['upper'\\]: boundary vertex"):
        NGSolveBackend(sc, mesh={"upper": (p * 0.9, t)})
    with pytest.raises(ValueError, match="option mesh\\['upper'\\]: boundary vertex"):
        NGSolveBackend(sc, mesh={"upper": (-p, t)})  # the upper half-disk: wrong side
    with pytest.raises(ValueError, match="option mesh\\['upper'\\]: triangles must be"):
        NGSolveBackend(sc, mesh={"upper": (p, t[:, :2])})


def _run_main(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, out.getvalue(), err.getvalue()


def test_cli_solve_with_backend_options(tmp_path):
    sets = [a for s in COARSE for a in ("--set", s)]
    rc, out, err = _run_main(["solve", "hertz_halfdisks", "--backend", "ngsolve", *sets,
                              "--backend-option", "mesh=skfem", "--backend-option",
                              "direct_solver='scipy'", "--no-plot", "--quiet",
                              "--out", str(tmp_path / "a")])
    assert rc == 0, err
    ref = solve_hf(load_scene("hertz_halfdisks", COARSE)).metrics  # skfem, same mesh
    force = float(next(line.split()[1] for line in out.splitlines()
                       if line.strip().startswith("contact_force")))
    assert abs(force - ref["contact_force"]) <= 1e-5 * ref["contact_force"]  # 6 digits printed
    rc, _, err = _run_main(["solve", "hertz_halfdisks", "--backend", "ngsolve", *sets,
                            "--backend-option", "mesh=gmsh", "--no-plot", "--quiet"])
    assert rc == 2 and "option mesh = 'gmsh'" in err and "'netgen', 'skfem'" in err
    rc, _, err = _run_main(["solve", "membrane_obstacle", "--backend-option", "mesh",
                            "--no-plot", "--quiet"])
    assert rc == 2 and "expected KEY=VALUE" in err


def test_rb_pipeline_runs_unchanged_on_ngsolve(tmp_path):
    """The offline / online pipeline sees only sparse operators: same code, other backend."""
    import pickle

    from rbbench.rb.config import make_config
    from rbbench.rb.offline import reduce

    sc = load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    kw = dict(dual="mcpg", stabilizer="pga", N=6, R=6, n_train=9, n_valid=4, n_jobs=1,
              online_repeats=2, exact_max_r=4, cache_dir=str(tmp_path))
    s_ng = reduce(sc, make_config(backend="ngsolve", **kw))
    s_sk = reduce(sc, make_config(backend="skfem", **kw))
    a, b = s_ng.summary(), s_sk.summary()
    assert a["hyper"] == b["hyper"] == "affine"  # the membrane is affine on both backends
    assert a["err_u_max"] < 0.1 and a["beta_off_min"] > 0
    # own meshes (Netgen's unit square is not skfem's grid): comparable accuracy only
    assert 0.2 < a["err_u_max"] / b["err_u_max"] < 5
    assert pickle.loads(pickle.dumps(s_ng.model)).N == s_ng.model.N
