"""Nitsche against mixed: HF energies and reduced errors (``rbbench nitsche-compare``).

As in Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Comparison with the mixed formulation (1/2), (2/2)".
"""

from __future__ import annotations

from rbbench.hf.model import solve_hf
from rbbench.scene.loading import load_scene
from rbbench.studies.formatting import markdown_table

__all__ = ["comparison_markdown", "formulation_comparison"]


def formulation_comparison(scene: str = "hertz_halfdisks", overrides=(), n_train: int = 61,
                           n_valid: int = 10, N: int = 20, Rs=(10, 30, 40),
                           cache_dir: str = ".rbbench_cache", progress=print) -> dict:
    """Benaceur et al., slides "Comparison with the mixed formulation (1/2), (2/2)".

    1. HF energies ``J(mu; u(mu)) = 1/2 a(u, u) - f(u)`` of the mixed (LAC + ssn) and
       Nitsche (newton) solutions over ``D_train``.
    2. Reduced errors (max over the validation set) of the mixed model (mCPG cone of
       size ``R``: no dual tolerance, so ``R`` generators unless the training set has
       fewer; PGA; hyper auto) for each ``R`` in ``Rs``, and of the Nitsche model
       (same ``N``; no dual space), u in the X norm and the multiplier / pressure in
       L2(Gamma_c) (mixed: the W norm of ``lam``).
    """
    from rbbench.rb.config import make_config
    from rbbench.rb.offline import reduce
    from rbbench.scene.sampling import parameter_set

    sc = load_scene(scene, list(overrides))
    mus = parameter_set(sc, "train", n_train)
    energies = []
    for mu in mus:
        m = solve_hf(sc, mu, floor=False)
        n = solve_hf(sc, mu, formulation="nitsche", floor=False)
        energies.append({"mu": float(mu[0]), "J_mixed": m.metrics["energy"],
                         "J_nitsche": n.metrics["energy"],
                         "rel_diff": (n.metrics["energy"] - m.metrics["energy"])
                         / abs(m.metrics["energy"])})
        progress(f"HF energies at mu = {float(mu[0]):.4g}")
    reduced = []
    common = dict(N=N, n_train=n_train, n_valid=n_valid, cache_dir=cache_dir)
    for R in Rs:
        s = reduce(sc, make_config(R=R, tol_dual=0.0, **common)).summary()
        reduced.append({"formulation": "mixed", "N": s["N"], "R": s["R"], "K": s["K_pga"],
                        "err_u_max": s["err_u_max"], "err_lam_max": s["err_lam_max"],
                        "t_online_s": s["t_online_median_s"]})
        progress(f"mixed reduction, R = {R}: err_u_max = {s['err_u_max']:.3e}")
    s = reduce(sc, make_config(formulation="nitsche", **common)).summary()
    reduced.append({"formulation": "nitsche", "N": s["N"], "R": None, "K": 0,
                    "err_u_max": s["err_u_max"], "err_lam_max": s["err_lam_max"],
                    "t_online_s": s["t_online_median_s"]})
    return {"energies": energies, "reduced": reduced}


def comparison_markdown(res: dict) -> str:
    """The two tables of :func:`formulation_comparison`."""
    energies = markdown_table(("mu (m)", "J mixed (J/m)", "J Nitsche (J/m)", "rel. diff"), (
        (f"{r['mu']:.4g}", f"{r['J_mixed']:.6g}", f"{r['J_nitsche']:.6g}",
         f"{100 * r['rel_diff']:+.4f} %") for r in res["energies"]))
    reduced = markdown_table(
        ("formulation", "N", "R", "K (PGA)", "err u max", "err lam / pressure max",
         "online (ms)"),
        ((r["formulation"], r["N"], "" if r["R"] is None else r["R"], r["K"],
          f"{r['err_u_max']:.3e}", f"{r['err_lam_max']:.3e}", f"{1e3 * r['t_online_s']:.3f}")
         for r in res["reduced"]))
    return energies + "\n\n" + reduced
