"""Tangential contact operators of friction scenes: ``Bt = Mt^T diag(w) Ut``
with P1 friction multipliers ``Mt`` and the collocation nodes ``C(mu)``; built only for
friction scenes; frictionless operators bitwise as before; scikit-fem = NGSolve on one mesh;
rigid translations; Dirichlet values of the load steps."""

from __future__ import annotations

import os
import subprocess
import sys
import tarfile
import textwrap
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from rbbench.registry import default_registry
from rbbench.scene.loading import load_scene
from rbbench.testing import HERTZ_COARSE

ROOT = Path(__file__).resolve().parents[3]
COARSE = list(HERTZ_COARSE)
COULOMB = ['friction.law="coulomb"', "friction.coefficient=0.2"]
SHEAR = ["load.tangential_displacement=0.002",
         "load.load_steps=[{normal = 1.0}, {normal = 1.0, tangential = 1.0}]"]
#: the last commit before the friction operators: frictionless operators are compared with it
REFERENCE_COMMIT = "0e512e5"


def _disc(overrides, degree=1, backend="skfem", mu=None, needs=frozenset()):
    sc = load_scene("hertz_halfdisks", [*overrides, f"discretization.degree={degree}"])
    b = default_registry().create("backend", backend, scene=sc)
    return b, b.discretize(sc.default_mu if mu is None else mu, needs=needs)


# ---------------------------------------------------------------------------
# frictionless scenes: nothing new, bitwise the same operators
# ---------------------------------------------------------------------------
def test_frictionless_scenes_build_no_tangential_operators():
    _, d = _disc(COARSE)
    c = d.contact
    assert c.Ut is None and c.Mt is None and c.colloc_points is None
    assert d.dirichlet_steps is None
    with pytest.raises(ValueError, match="friction scenes only"):
        c.Bt()
    # asked for explicitly, they are built (as before: Ut), with Mt and C(mu)
    _, d = _disc(COARSE, needs=frozenset({"tangential"}))
    assert d.contact.Ut is not None and d.contact.Bt().shape[0] == d.contact.Mt.shape[1]


_DUMP = textwrap.dedent("""
    import sys
    import numpy as np
    import scipy.sparse as sp
    from rbbench.registry import default_registry
    from rbbench.scene.loading import load_scene
    out = {}
    for name in ("hertz_halfdisks", "membrane_obstacle"):
        sc = load_scene(name)
        out[name + "/fingerprint"] = np.array(sc.fingerprint())
        for backend in sys.argv[2:]:
            b = default_registry().create("backend", backend, scene=sc)
            for i, mu in enumerate((sc.default_mu, sc.bounds[:, 1])):
                d = b.discretize(mu)
                c = d.contact
                arrays = {"B": c.B(), "G": c.G(), "W": c.W(), "Un": c.Un, "gap": c.gap,
                          "A": d.A, "dirichlet_values": d.dirichlet_values}
                for k, v in arrays.items():
                    key = f"{name}/{backend}/{i}/{k}"
                    if sp.issparse(v):
                        v = sp.csr_matrix(v)
                        for part in ("data", "indices", "indptr"):
                            out[f"{key}/{part}"] = getattr(v, part)
                    else:
                        out[key] = np.asarray(v)
    import rbbench, rbbench_plugins
    out["origin"] = np.array([rbbench.__file__, rbbench_plugins.__file__])
    np.savez(sys.argv[1], **out)
""")


def _dump(tmp: Path, label: str, backends: list[str], pythonpath: str | None = None
          ) -> dict[str, np.ndarray]:
    """The arrays of :data:`_DUMP` computed in a subprocess (``pythonpath`` first)."""
    script = tmp / "dump.py"
    script.write_text(_DUMP)
    target = tmp / f"{label}.npz"
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = os.pathsep.join([pythonpath, env.get("PYTHONPATH", "")])
    subprocess.run([sys.executable, str(script), str(target), *backends], check=True,
                   env=env, cwd=tmp, timeout=600)
    with np.load(target) as z:
        return {k: z[k] for k in z.files}


def _reference_tree(tmp: Path) -> str:
    """``rbbench`` and ``plugins`` (as ``rbbench_plugins``) of :data:`REFERENCE_COMMIT`,
    extracted with ``git archive`` (no worktree, no stash), with today's scenes as
    ``rbbench.problems``; the PYTHONPATH to import them."""
    tar = tmp / "ref.tar"
    try:
        with open(tar, "wb") as fh:
            subprocess.run(["git", "-C", str(ROOT), "archive", REFERENCE_COMMIT, "rbbench",
                            "plugins"], stdout=fh, stderr=subprocess.DEVNULL, check=True,
                           timeout=120)
    except (OSError, subprocess.CalledProcessError, subprocess.TimeoutExpired):
        pytest.skip(f"no git history with commit {REFERENCE_COMMIT} to compare with")
    ref = tmp / "ref"
    with tarfile.open(tar) as t:
        t.extractall(ref, filter="data")
    (ref / "plugins").rename(ref / "rbbench_plugins")
    (ref / "rbbench" / "problems").symlink_to(ROOT / "problems", target_is_directory=True)
    return str(ref)


@pytest.mark.slow  # a guard of one past refactoring: checks out and runs an older commit
def test_frictionless_operators_bitwise_as_before(tmp_path):
    """B, G, W, Un, gap, A and the Dirichlet values of both shipped scenes (default mesh,
    mu at the default and the upper bound, each installed backend) and the fingerprints
    are bitwise those of the commit before the friction operators; except the values of
    the scikit-fem half-disk stiffness, which is now combined from reference Lame terms
    (``SkfemBackend._elastic_operator``): those to 1e-12 of the largest, same pattern."""
    backends = ["skfem"]
    try:
        import ngsolve  # noqa: F401
        backends.append("ngsolve")
    except ImportError:
        pass
    ref = _dump(tmp_path, "reference", backends, _reference_tree(tmp_path))
    now = _dump(tmp_path, "now", backends)
    tree = str(tmp_path / "ref")
    assert all(f.startswith(tree) for f in ref.pop("origin"))  # the reference code ran
    assert not any(f.startswith(tree) for f in now.pop("origin"))
    assert ref.keys() == now.keys()
    for k in ref:
        assert ref[k].dtype == now[k].dtype and ref[k].shape == now[k].shape, k
        if k.startswith("hertz_halfdisks/skfem/") and k.endswith("/A/data"):
            assert np.abs(ref[k] - now[k]).max() <= 1e-12 * np.abs(ref[k]).max(), k
            continue
        assert np.array_equal(ref[k], now[k]), k


# ---------------------------------------------------------------------------
# friction scenes: Mt, C(mu), Bt
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("degree", [1, 2])
def test_friction_scene_builds_p1_multipliers_and_collocation_nodes(degree):
    sc_over = COARSE + COULOMB
    b, d = _disc(sc_over, degree, mu=np.array([1.2]))
    c, layout = d.contact, b.contact_layout()
    n_nodes = layout.n_facets + 1
    assert c.Ut is not None and c.Mt.shape == (c.n_quad, n_nodes)
    assert np.allclose(np.asarray(c.Mt.sum(axis=1)).ravel(), 1.0)  # a partition of unity
    # C(mu): the slave chain vertices (a contiguous chain) mapped by the geometry at mu
    slave = layout.slave
    assert np.allclose(slave.b[:-1], slave.a[1:], rtol=0, atol=1e-14)
    want = slave.map(np.array([1.2]), np.vstack([slave.a, slave.b[-1:]]))
    assert c.colloc_points.shape == (n_nodes, 2) and np.array_equal(c.colloc_points, want)
    # P1 hats interpolate their nodes: at a point, Mt reproduces the position linearly
    assert np.allclose(c.Mt @ c.colloc_points, c.points, rtol=0, atol=1e-12)
    # Bt, B_nodal, G_nodal, Wt from their definitions
    W = sp.diags(c.weights)
    assert abs(c.Bt() - c.Mt.T @ W @ c.Ut).max() == 0
    assert abs(c.B_nodal() - c.Mt.T @ W @ c.Un).max() == 0
    assert np.array_equal(c.G_nodal(), c.Mt.T @ (c.weights * c.gap))
    Wt = c.Wt().toarray()
    assert np.allclose(Wt, Wt.T) and np.all(np.linalg.eigvalsh(Wt) > 0)
    # the normal operators of the scene's multiplier space are those of a frictionless scene
    _, d0 = _disc(COARSE, degree, mu=np.array([1.2]))
    for name in ("B", "G", "W"):
        x, y = getattr(c, name)(), getattr(d0.contact, name)()
        assert abs(x - y).max() == 0, name
    assert abs(c.Un - d0.contact.Un).max() == 0 and np.array_equal(c.gap, d0.contact.gap)


def test_p1_scene_multipliers_are_the_friction_multipliers():
    _, d = _disc(COARSE + COULOMB + ['discretization.multiplier="p1"'], 2)
    c = d.contact
    assert abs(c.Mt - c.Mlam).max() == 0
    assert abs(c.B_nodal() - c.B()).max() == 0 and np.array_equal(c.G_nodal(), c.G())


def _translation(layout, n_dofs: int, slave: np.ndarray, master: np.ndarray) -> np.ndarray:
    """A displacement translating the slave facets by ``slave`` and the master by ``master``
    (the jump operators read only these dofs)."""
    u = np.zeros(n_dofs)
    for chain, c in ((layout.slave, slave), (layout.master, master)):
        for k in range(2):
            u[chain.dofs[..., k].ravel()] = c[k]
    return u


@pytest.mark.parametrize("degree", [1, 2])
def test_rigid_translations(degree):
    """A common translation of both bodies has no jump; a translation ``c`` of the slave
    body alone gives ``Ut u = c . t`` and ``Un u = c . n`` at every point, hence
    ``Bt u = Mt^T diag(w) (c . t)`` (``(c . t) * row sums`` where ``t`` is constant),
    with ``t = (-n_y, n_x)``."""
    b, d = _disc(COARSE + COULOMB, degree, mu=np.array([0.8]))
    c, layout = d.contact, b.contact_layout()
    shift = np.array([3e-4, -1e-4])
    u = _translation(layout, d.n_dofs, shift, shift)
    assert np.abs(c.Ut @ u).max() < 1e-16 and np.abs(c.Un @ u).max() < 1e-16
    assert np.abs(c.Bt() @ u).max() < 1e-18
    u = _translation(layout, d.n_dofs, shift, np.zeros(2))
    n = c.normals
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    assert np.allclose(c.Ut @ u, t @ shift, rtol=0, atol=1e-16)
    assert np.allclose(c.Un @ u, n @ shift, rtol=0, atol=1e-16)
    assert np.allclose(c.Bt() @ u, c.Mt.T @ (c.weights * (t @ shift)), rtol=1e-12, atol=0)
    # the bottom of the upper body: n ~ (0, -1), so t ~ +x and a shift along x is tangential
    assert np.all(t[:, 0] > 0.9)
    along = _translation(layout, d.n_dofs, np.array([1e-3, 0.0]), np.zeros(2))
    row_sums = np.asarray((c.Mt.T @ sp.diags(c.weights)).sum(axis=1)).ravel()
    bt = c.Bt() @ along
    assert np.all(bt > 0) and np.all(bt <= 1e-3 * row_sums * (1 + 1e-12))
    # a flat contact (rigid foundation, normal facets exactly (0, -1) at the centre) is
    # where Bt u = (c . t) * row sums holds exactly; here: to the curvature of the zone
    assert np.allclose(bt, 1e-3 * row_sums, rtol=0.1)


def test_load_steps_give_the_dirichlet_values_of_each_step():
    b, d = _disc(COARSE + COULOMB + SHEAR, mu=np.array([1.0]))
    _, d0 = _disc(COARSE, mu=np.array([1.0]))
    assert np.array_equal(d.dirichlet_dofs, d0.dirichlet_dofs)
    x = np.isin(d.dirichlet_dofs, b.upper.basis_hat.nodal_dofs[0])  # upper face, x dofs
    y = np.isin(d.dirichlet_dofs, b.upper.basis_hat.nodal_dofs[1])
    assert x.any() and y.any()
    assert np.all(d.dirichlet_values[x] == 0.002) and np.all(d.dirichlet_values[y] == -0.05)
    assert np.all(d.dirichlet_values[~(x | y)] == 0.0)
    first, second = d.dirichlet_steps
    assert np.array_equal(first, d0.dirichlet_values)  # normal load only
    assert np.array_equal(second, d.dirichlet_values)  # then the shear


# ---------------------------------------------------------------------------
# scikit-fem and NGSolve on one mesh
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("degree", [1, 2])
def test_skfem_and_ngsolve_agree_on_the_same_mesh(degree):
    pytest.importorskip("ngsolve", reason='NGSolve backend not installed')
    from rbbench_plugins.backends.ngsolve.backend import NGSolveBackend
    from support.fields import dof_permutation

    sc = load_scene("hertz_halfdisks", COARSE + COULOMB + SHEAR
                    + [f"discretization.degree={degree}"])
    bs = default_registry().create("backend", "skfem", scene=sc)
    bn = NGSolveBackend(sc, mesh="skfem")
    p = dof_permutation(bs, bn)
    for mu in (sc.bounds[:, 0], sc.default_mu, sc.bounds[:, 1]):
        ds, dn = bs.discretize(mu), bn.discretize(mu)
        cs, cn = ds.contact, dn.contact
        errors = {"Bt": abs(cn.Bt() - cs.Bt()[:, p]).max() / abs(cs.Bt()).max(),
                  "B_nodal": abs(cn.B_nodal() - cs.B_nodal()[:, p]).max()
                  / abs(cs.B_nodal()).max(),
                  "G_nodal": np.abs(cn.G_nodal() - cs.G_nodal()).max()
                  / np.abs(cs.G_nodal()).max(),
                  "Wt": abs(cn.Wt() - cs.Wt()).max() / abs(cs.Wt()).max(),
                  "C": np.abs(cn.colloc_points - cs.colloc_points).max()}
        assert max(errors.values()) < 1e-12, errors
        want = {int(k): [s[i] for s in ds.dirichlet_steps]
                for i, k in enumerate(ds.dirichlet_dofs)}
        got = {int(p[k]): [s[i] for s in dn.dirichlet_steps]
               for i, k in enumerate(dn.dirichlet_dofs)}
        assert got == want
