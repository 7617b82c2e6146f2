"""Does ``beta_dec`` vanish over the reduced cone, and does PGA restore it? (measured)

Seed 000, slide "Decorrelated model reduction": with ``V_N = POD(u)`` and
``W_R^+ = mCPG(lam)`` chosen independently, nothing guarantees

    beta_dec(mu) = inf_{eta in W_R^+} sup_{v in V_N} b(mu; v, eta) / (||v||_V ||eta||_W) > 0,

and slides "Projected Greedy Algorithm (PGA)" / "(1/2)" / "(2/2)" build
``V_off = V_N + S_R^red`` offline so that ``beta_off > 0`` on the training set.
:func:`beta_dec_study` measures both, for fixed generators (``R``) and ``N = 1, 2, ...``:

* ``span``: :func:`rbbench.rb.infsup.infsup_span` over ``span(Vg)``, exact, a LOWER bound of
  the cone value; it is 0 whenever ``N < R`` (``Z^T B^T Vg`` then has a null space);
* ``cone``: :func:`rbbench.rb.infsup.infsup_cone`, exact (face enumeration) for
  ``R <= exact_max_r`` (kind ``"cone-exact"``), else a multistart UPPER estimate
  (``"cone-upper"``);
* ``zero``: :func:`rbbench.rb.infsup.beta_zero_test`, the EXACT LP test of ``beta = 0`` on the
  cone (``exists alpha >= 0, sum 1, Z^T B^T Vg alpha = 0``), independent of the kind.

The same three numbers are computed for ``V_off = [V_N, S_PGA]`` (:func:`rbbench.rb.pga.pga`
on the supremizers of the training parameters, tolerance ``delta``), and ``beta_on`` (whole
V against the reduced cone: the online-supremizer value) for scale.

Run from the shell (prints the table)::

    python -m rbbench.studies.beta_dec hertz_halfdisks --R 10 15 20
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rbbench.hf.model import ProblemCache, make_components
from rbbench.hf.snapshots import compute_snapshots
from rbbench.rb import infsup as inf
from rbbench.rb.compressors import pga_default_delta
from rbbench.rb.pga import pga, supremizers
from rbbench.registry import default_registry
from rbbench.scene.loading import Scene, load_scene
from rbbench.scene.sampling import parameter_set

__all__ = ["BetaDecStudy", "beta_dec_study", "main"]

#: Columns of :meth:`BetaDecStudy.table` (one row per R, N and parameter set).
COLUMNS = ("R", "N", "set", "n_mu", "dec_span_min", "dec_cone_min", "dec_kind",
           "dec_zero_count", "K_pga", "off_span_min", "off_cone_min", "off_kind",
           "off_zero_count", "on_span_min", "on_cone_min")


@dataclass
class BetaDecStudy:
    """Result of :func:`beta_dec_study`.

    Attributes
    ----------
    rows : list of dict
        One per ``(R, N, set)``, keys :data:`COLUMNS`: minima over the parameter set of the
        span and cone values of ``beta_dec`` and ``beta_off``, the kinds of the cone values,
        how many parameters the exact LP test finds ``beta = 0`` for, ``K_pga = dim S_PGA``
        and the minima of ``beta_on`` (span lower bound and cone value, same kind rules).
    per_mu : dict
        ``per_mu[(R, set)]`` holds ``mus`` and, per quantity (``dec_span``, ``dec_cone``,
        ``dec_zero``, ``off_span``, ``off_cone``, ``off_zero``: arrays ``(n_N, n_mu)``;
        ``on_span``, ``on_cone``, ``c``: ``(n_mu,)``), the values for every parameter;
        ``c`` is the continuity constant of ``b`` on ``V x span(Vg)``
        (:func:`rbbench.rb.infsup.boundedness_constant`), the scale of all the constants.
    pga : dict
        ``pga[(R, N)]``: ``delta``, ``stop`` reason, ``K`` and the ``sigma_max`` history.
    config : dict
        The arguments of the run; ``R_actual[R]`` the number of generators obtained.
    timings : dict
        Seconds per stage.
    """

    scene: str
    dual: str
    rows: list[dict[str, Any]]
    per_mu: dict[tuple[int, str], dict[str, Any]]
    pga: dict[tuple[int, int], dict[str, Any]]
    config: dict[str, Any] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)

    def table(self) -> str:
        """The rows as a Markdown table (``%.3e`` floats)."""
        head = "| " + " | ".join(COLUMNS) + " |"
        sep = "|" + "---|" * len(COLUMNS)
        lines = [head, sep]
        for r in self.rows:
            cells = [f"{r[c]:.3e}" if isinstance(r[c], float) else str(r[c]) for c in COLUMNS]
            lines.append("| " + " | ".join(cells) + " |")
        return "\n".join(lines)


def _cone(S: np.ndarray, M: np.ndarray, C: np.ndarray, exact_max_r: int,
          n_starts: int) -> tuple[float, str, float, bool]:
    r = inf.infsup_cone(S, M, C=C, exact_max_r=exact_max_r, n_starts=n_starts)
    return r.value, r.kind, r.span, r.is_zero


def beta_dec_study(scene: Scene | str, dual: str = "mcpg", R: int | Sequence[int] = 10,
                   N_list: Sequence[int] | None = None, n_train: int | None = None,
                   n_valid: int | None = None, sets: Sequence[str] = ("train", "valid"),
                   primal: str = "pod", delta_pga: float | None = None,
                   exact_max_r: int = 12, n_starts: int = 32,
                   cache_dir: str | Path = ".rbbench_cache", n_jobs: int | None = None,
                   backend: str = "skfem", formulation: str = "mixed", solver: str = "ssn",
                   progress: Callable[[str], None] | None = None) -> BetaDecStudy:
    """``beta_dec`` and ``beta_off`` over the reduced cone for ``N = 1..`` at fixed ``R``.

    Parameters
    ----------
    scene : Scene or str
        A scene (or its name, loaded without overrides).
    dual : str
        Registered dual compressor (``rbbench plugins``); run with ``tol = 0`` and
        ``r_max = R``, so ``R`` generators unless the snapshots are exhausted earlier.
    R : int or sequence of int
        Numbers of cone generators studied.
    N_list : sequence of int, optional
        Primal sizes; default ``1..R`` for each ``R`` (sizes above the snapshot rank are
        dropped).
    n_train, n_valid : int, optional
        Sizes of the parameter sets (scene defaults otherwise). HF snapshots are solved for
        the training set only; the validation set needs ``B(mu)``, ``W(mu)``.
    sets : sequence of {"train", "valid"}
        Parameter sets on which the constants are evaluated.
    primal : str
        Registered primal compressor; nested ones (``capabilities["nested"]``) are run
        once and truncated.
    delta_pga : float, optional
        PGA tolerance; default :func:`rbbench.rb.compressors.pga_default_delta` with its
        defaults (half the smallest ratio) on every fifth training parameter (the probes of
        ``rbbench reduce``, which takes the largest ratio), computed per ``R``.
    exact_max_r, n_starts : int
        Passed to :func:`rbbench.rb.infsup.infsup_cone` (exact face enumeration up to
        ``exact_max_r`` generators, ~0.7 s per call at R = 16).
    cache_dir, n_jobs, backend, formulation, solver
        HF snapshot computation (:func:`rbbench.hf.snapshots.compute_snapshots`).
    progress : callable, optional
        Receives one line per stage.

    Returns
    -------
    BetaDecStudy
    """
    say = progress or (lambda _msg: None)
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    if isinstance(scene, str):
        scene = load_scene(scene)
    R_list = [int(R)] if np.isscalar(R) else [int(r) for r in R]
    reg = default_registry()
    mus = {"train": parameter_set(scene, "train", n_train),
           "valid": parameter_set(scene, "valid", n_valid)}
    for s in sets:
        if s not in mus:
            raise ValueError(f"unknown parameter set {s!r}: 'train' or 'valid'")
    say(f"HF snapshots: {len(mus['train'])} training parameters")
    train = compute_snapshots(scene, mus["train"], backend=backend, formulation=formulation,
                              solver=solver, cache_dir=Path(cache_dir), n_jobs=n_jobs,
                              progress=False)
    timings["snapshots_s"] = time.perf_counter() - t0

    b, f, _ = make_components(scene, backend, formulation, solver)
    problem_at = ProblemCache(b, f)
    X = problem_at.X_free(scene.default_mu)
    x_solve = inf.make_solver(X)

    t1 = time.perf_counter()
    n_max = max(max(N_list) if N_list is not None else r for r in R_list)
    primal_spec = reg.get("primal", primal)
    compress = reg.create("primal", primal)
    if primal_spec.capabilities.get("nested"):
        Z_all = compress(train.U, X, n=n_max).Z

        def basis(N: int) -> np.ndarray:
            return Z_all[:, :N]
    else:
        def basis(N: int) -> np.ndarray:
            return compress(train.U, X, n=N).Z
    rank = compress(train.U, X).N
    timings["primal_s"] = time.perf_counter() - t1

    H_cache: dict[bytes, np.ndarray] = {}  # B X^-1 B^T = H H^T: m solves per mu, reused per R

    def H_at(mu: np.ndarray) -> np.ndarray:
        key = np.asarray(mu, float).tobytes()
        if key not in H_cache:
            H_cache[key] = inf.supremizer_operator(problem_at(mu).B, x_solve)
        return H_cache[key]

    rows: list[dict[str, Any]] = []
    per_mu: dict[tuple[int, str], dict[str, Any]] = {}
    pga_info: dict[tuple[int, int], dict[str, Any]] = {}
    R_actual: dict[int, int] = {}
    train_B = [problem_at(mu).B for mu in mus["train"]]
    for R_req in R_list:
        t1 = time.perf_counter()
        say(f"dual compressor {dual}, R = {R_req}")
        Vg = reg.create("dual", dual)(train.LAM, problem_at(scene.default_mu).W, tol=0.0,
                                      r_max=R_req).generators
        Rg = int(Vg.shape[1])
        R_actual[R_req] = Rg
        Ns = [N for N in (N_list if N_list is not None else range(1, R_req + 1))
              if 1 <= N <= rank]
        T_list = [supremizers(B, x_solve, Vg) for B in train_B]
        if delta_pga is None:
            probe = mus["train"][:: max(1, len(mus["train"]) // 5)]
            delta = pga_default_delta([problem_at(mu).B for mu in probe],
                                      [problem_at(mu).W for mu in probe], x_solve, Vg)
        else:
            delta = float(delta_pga)
        say(f"PGA for N in {Ns[0]}..{Ns[-1]} (delta = {delta:.3g})")
        Z_dec: dict[int, np.ndarray] = {}  # once per N (a non-nested primal recompresses)
        Z_off: dict[int, np.ndarray] = {}
        for N in Ns:
            Z = Z_dec[N] = basis(N)
            res = pga(T_list, Z, X, delta)
            Z_off[N] = np.hstack([Z, res.basis])
            pga_info[(R_req, N)] = {"delta": delta, "stop": res.stop_reason, "K": res.dim,
                                    "sigma_max": res.sigma_max.tolist()}
        timings[f"offline_R{R_req}_s"] = time.perf_counter() - t1

        for s in sets:
            t1 = time.perf_counter()
            say(f"inf-sup constants, R = {Rg}, {s} set ({len(mus[s])} parameters)")
            shape = (len(Ns), len(mus[s]))
            d = {k: np.zeros(shape) for k in ("dec_span", "dec_cone", "off_span", "off_cone")}
            d.update(dec_zero=np.zeros(shape, bool), off_zero=np.zeros(shape, bool))
            d.update({k: np.zeros(len(mus[s])) for k in ("on_span", "on_cone", "c")})
            kinds: dict[str, set[str]] = {"dec": set(), "off": set(), "on": set()}
            for j, mu in enumerate(mus[s]):
                p = problem_at(mu)
                BtV = np.asarray(p.B.T @ Vg)
                C_on = inf.cone_coupling(H_at(mu), Vg)
                S_on, M_on = C_on.T @ C_on, Vg.T @ (p.W @ Vg)
                v, k, sp_, _ = _cone(S_on, M_on, C_on, exact_max_r, n_starts)
                d["on_cone"][j], d["on_span"][j] = v, sp_
                d["c"][j] = inf.boundedness_constant(S_on, M_on)
                kinds["on"].add(k)
                for i, N in enumerate(Ns):
                    for tag, Y in (("dec", Z_dec[N]), ("off", Z_off[N])):
                        S, M = inf.quotient_matrices(p.B, X, Vg, p.W, Z=Y)
                        v, k, sp_, zero = _cone(S, M, Y.T @ BtV, exact_max_r, n_starts)
                        d[f"{tag}_cone"][i, j], d[f"{tag}_span"][i, j] = v, sp_
                        d[f"{tag}_zero"][i, j] = zero
                        kinds[tag].add(k)
            d["mus"] = mus[s]
            per_mu[(R_req, s)] = d
            for i, N in enumerate(Ns):
                rows.append({
                    "R": Rg, "N": N, "set": s, "n_mu": len(mus[s]),
                    "dec_span_min": float(d["dec_span"][i].min()),
                    "dec_cone_min": float(d["dec_cone"][i].min()),
                    "dec_kind": "/".join(sorted(kinds["dec"])),
                    "dec_zero_count": int(d["dec_zero"][i].sum()),
                    "K_pga": pga_info[(R_req, N)]["K"],
                    "off_span_min": float(d["off_span"][i].min()),
                    "off_cone_min": float(d["off_cone"][i].min()),
                    "off_kind": "/".join(sorted(kinds["off"])),
                    "off_zero_count": int(d["off_zero"][i].sum()),
                    "on_span_min": float(d["on_span"].min()),
                    "on_cone_min": float(d["on_cone"].min()),
                })
            timings[f"infsup_R{R_req}_{s}_s"] = time.perf_counter() - t1
    timings["total_s"] = time.perf_counter() - t0
    config = {"dual": dual, "primal": primal, "R": R_list, "R_actual": R_actual,
              "N_list": None if N_list is None else list(N_list), "sets": list(sets),
              "n_train": len(mus["train"]), "n_valid": len(mus["valid"]),
              "delta_pga": delta_pga, "exact_max_r": exact_max_r, "n_starts": n_starts,
              "overrides": list(scene.overrides), "primal_rank": rank}
    return BetaDecStudy(scene=scene.name, dual=dual, rows=rows, per_mu=per_mu, pga=pga_info,
                        config=config, timings=timings)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m rbbench.studies.beta_dec SCENE [--R ...] [--set k=v ...]``: print the table."""
    ap = argparse.ArgumentParser(prog="python -m rbbench.studies.beta_dec",
                                 description=beta_dec_study.__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("--set", dest="overrides", action="append", default=[],
                    metavar="SECTION.KEY=VALUE", help="scene override (repeatable)")
    ap.add_argument("--dual", default="mcpg")
    ap.add_argument("--R", type=int, nargs="+", default=[10])
    ap.add_argument("--N", type=int, nargs="+", default=None, help="default 1..R")
    ap.add_argument("--n-train", type=int, default=None)
    ap.add_argument("--n-valid", type=int, default=None)
    ap.add_argument("--sets", nargs="+", default=["train", "valid"])
    ap.add_argument("--delta", type=float, default=None)
    ap.add_argument("--exact-max-r", type=int, default=12)
    ap.add_argument("--cache-dir", default=".rbbench_cache")
    ap.add_argument("--jobs", type=int, default=None)
    args = ap.parse_args(argv)
    study = beta_dec_study(load_scene(args.scene, args.overrides), dual=args.dual, R=args.R,
                           N_list=args.N, n_train=args.n_train, n_valid=args.n_valid,
                           sets=args.sets, delta_pga=args.delta, exact_max_r=args.exact_max_r,
                           cache_dir=args.cache_dir, n_jobs=args.jobs,
                           progress=lambda m: print(f"# {m}", flush=True))
    print(f"# scene {study.scene}, dual {study.dual}, config {study.config}")
    for (R, N), info in sorted(study.pga.items()):
        print(f"# PGA R={R} N={N}: K={info['K']} stop={info['stop']} delta={info['delta']:.3g}")
    print(study.table())
    print(f"# timings {({k: round(v, 1) for k, v in study.timings.items()})}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
