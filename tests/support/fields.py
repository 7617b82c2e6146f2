"""Test helpers on discrete fields shared by several test files: an affine displacement field
and the dof permutation between the scikit-fem and NGSolve backends on one mesh."""

from __future__ import annotations

import numpy as np


def affine_field(b, d, mu, G):
    """u = G x (physical coordinates) on the upper body, all Lagrange dofs."""
    u = np.zeros(d.n_dofs)
    body = b.upper
    scale, shift = b._body_maps()["upper"].at(np.atleast_1d(mu))
    x = scale * body.basis_hat.doflocs + shift[:, None]
    for comp in range(2):
        dofs = [body.basis_hat.nodal_dofs[comp]]
        if body.degree == 2:
            dofs.append(body.basis_hat.facet_dofs[comp])
        dd = np.concatenate(dofs)
        u[dd + body.offset] = (G @ x[:, dd])[comp]
    return u


def skfem_dof_table(b) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(body, component, reference location) of every skfem dof (basis internals)."""
    if b.kind == "unit_square":
        bases = [b.basis]
    else:
        bases = [body.basis_hat for body in (b.upper, b.lower) if body is not None]
    body, comp, loc = [], [], []
    for i, basis in enumerate(bases):
        c = np.zeros(basis.N, dtype=int)
        if b.kind != "unit_square":
            for k in range(2):
                c[basis.nodal_dofs[k]] = k
                if basis.facet_dofs.size:
                    c[basis.facet_dofs[k]] = k
        body.append(np.full(basis.N, i))
        comp.append(c)
        loc.append(basis.doflocs.T)
    return np.concatenate(body), np.concatenate(comp), np.vstack(loc)


def dof_permutation(bs, bn) -> np.ndarray:
    """``p`` with NGSolve dof ``j`` = skfem dof ``p[j]`` (same body, component, node)."""
    sb, sc, sl = skfem_dof_table(bs)
    t = bn.dof_table()

    def order(body, comp, loc):
        r = np.round(loc, 10)
        return np.lexsort((r[:, 1], r[:, 0], comp, body))

    o_s, o_n = order(sb, sc, sl), order(t["body"], t["component"], t["x_hat"])
    assert np.array_equal(sb[o_s], t["body"][o_n]) and np.array_equal(sc[o_s], t["component"][o_n])
    assert np.allclose(sl[o_s], t["x_hat"][o_n], rtol=0, atol=1e-12)
    p = np.empty(sb.size, dtype=int)
    p[o_n] = o_s
    return p
