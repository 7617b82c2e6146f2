"""Does ``beta_dec`` vanish over the reduced cone, and does PGA restore it? (measured)

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "Decorrelated model reduction": with ``V_N = POD(u)``
and ``W_R^+ = mCPG(lam)`` chosen independently, nothing guarantees

    beta_dec(mu) = inf_{eta in W_R^+} sup_{v in V_N} b(mu; v, eta) / (||v||_V ||eta||_W) > 0,

and slides "Projected Greedy Algorithm (PGA)" / "(1/2)" / "(2/2)" build
``V_off = V_N + S_R^red`` offline so that ``beta_off > 0`` on the training set.
:func:`beta_dec_study` measures both, for fixed generators (``R``) and ``N = 1, 2, ...``:

* ``span``: :func:`rbbench.rb.algorithms.infsup.infsup_span` over ``span(Vg)``, exact, a LOWER bound
of
  the cone value; it is 0 whenever ``N < R`` (``Z^T B^T Vg`` then has a null space);
* ``cone``: :func:`rbbench.rb.algorithms.infsup.infsup_cone`, exact (face enumeration) for
  ``R <= exact_max_r`` (kind ``"cone-exact"``), else a multistart UPPER estimate
  (``"cone-upper"``);
* ``zero``: :func:`rbbench.rb.algorithms.infsup.beta_zero_test`, the EXACT LP test of ``beta = 0``
on the
  cone (``exists alpha >= 0, sum 1, Z^T B^T Vg alpha = 0``), independent of the kind.

The same three numbers are computed for ``V_off = [V_N, S_PGA]``
(:func:`rbbench.rb.algorithms.pga.pga` on the supremizers of the training parameters, tolerance
``delta``), and ``beta_on`` (whole V against the reduced cone: the online-supremizer value) for
scale.

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

from rbbench.hf.components import make_components
from rbbench.hf.model import ProblemCache
from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.algorithms.pga import pga, supremizers
from rbbench.rb.compressors import pga_default_delta
from rbbench.registry import default_registry
from rbbench.scene.loading import Scene, load_scene
from rbbench.scene.sampling import parameter_set
from rbbench.studies.formatting import markdown_table

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
        (:func:`rbbench.rb.algorithms.infsup.boundedness_constant`), the scale of all the constants.
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
        cells = ([f"{r[c]:.3e}" if isinstance(r[c], float) else str(r[c]) for c in COLUMNS]
                 for r in self.rows)
        return markdown_table(COLUMNS, cells)


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
        Passed to :func:`rbbench.rb.algorithms.infsup.infsup_cone` (exact face enumeration up to
        ``exact_max_r`` generators, ~0.7 s per call at R = 16).
    cache_dir, n_jobs, backend, formulation, solver
        HF snapshot computation (:func:`rbbench.hf.snapshots.compute.compute_snapshots`).
    progress : callable, optional
        Receives one line per stage.

    Returns
    -------
    BetaDecStudy
    """
    t0 = time.perf_counter()
    if isinstance(scene, str):
        scene = load_scene(scene)
    opts = _Options(dual, [int(R)] if np.isscalar(R) else [int(r) for r in R],
                    None if N_list is None else list(N_list), n_train, n_valid, list(sets),
                    primal, delta_pga, exact_max_r, n_starts, cache_dir, n_jobs, backend,
                    formulation, solver)
    run = _Run(scene, opts, progress or (lambda _msg: None), t0)
    run.prepare()
    for R_req in opts.R_list:
        Vg, Ns, Z_dec, Z_off = run.offline(R_req)
        for s in opts.sets:
            run.constants(R_req, s, Vg, Ns, Z_dec, Z_off)
    return run.result()


@dataclass(frozen=True)
class _Options:
    """The arguments of :func:`beta_dec_study` (``R_list``: the requested ``R``)."""

    dual: str
    R_list: list[int]
    N_list: list[int] | None
    n_train: int | None
    n_valid: int | None
    sets: list[str]
    primal: str
    delta_pga: float | None
    exact_max_r: int
    n_starts: int
    cache_dir: str | Path
    n_jobs: int | None
    backend: str
    formulation: str
    solver: str


@dataclass
class _Run:
    """A :func:`beta_dec_study` in progress: the HF operators it reuses and its results."""

    scene: Scene
    opts: _Options
    say: Callable[[str], None]
    t0: float
    timings: dict[str, float] = field(default_factory=dict)
    rows: list[dict[str, Any]] = field(default_factory=list)
    per_mu: dict[tuple[int, str], dict[str, Any]] = field(default_factory=dict)
    pga: dict[tuple[int, int], dict[str, Any]] = field(default_factory=dict)
    R_actual: dict[int, int] = field(default_factory=dict)
    #: B X^-1 B^T = H H^T per mu: m solves per mu, reused per R
    H_cache: dict[bytes, np.ndarray] = field(default_factory=dict)
    # set by prepare(): registry, parameter sets, training snapshots, HF problems per mu,
    # X and its solver, N -> primal basis, the snapshots' rank, B(mu) on the training set
    reg: Any = field(init=False)
    mus: dict[str, np.ndarray] = field(init=False)
    train: Any = field(init=False)
    problem_at: ProblemCache = field(init=False)
    X: Any = field(init=False)
    x_solve: Any = field(init=False)
    basis: Callable[[int], np.ndarray] = field(init=False)
    rank: int = field(init=False)
    train_B: list[Any] = field(init=False)

    def prepare(self) -> None:
        """Parameter sets, training snapshots, the HF problems and the primal bases."""
        o, scene = self.opts, self.scene
        self.reg = default_registry()
        self.mus = {"train": parameter_set(scene, "train", o.n_train),
                    "valid": parameter_set(scene, "valid", o.n_valid)}
        for s in o.sets:
            if s not in self.mus:
                raise ValueError(f"unknown parameter set {s!r}: 'train' or 'valid'")
        self.say(f"HF snapshots: {len(self.mus['train'])} training parameters")
        self.train = compute_snapshots(scene, self.mus["train"], backend=o.backend,
                                       formulation=o.formulation, solver=o.solver,
                                       cache_dir=Path(o.cache_dir), n_jobs=o.n_jobs,
                                       progress=False)
        self.timings["snapshots_s"] = time.perf_counter() - self.t0
        b, f, _ = make_components(scene, o.backend, o.formulation, o.solver)
        self.problem_at = ProblemCache(b, f)
        self.X = self.problem_at.X_free(scene.default_mu)
        self.x_solve = inf.make_solver(self.X)
        t1 = time.perf_counter()
        n_max = max(max(o.N_list) if o.N_list is not None else r for r in o.R_list)
        self.basis, self.rank = _primal_bases(self.reg, o.primal, self.train.U, self.X, n_max)
        self.timings["primal_s"] = time.perf_counter() - t1
        self.train_B = [self.problem_at(mu).B for mu in self.mus["train"]]

    def H_at(self, mu: np.ndarray) -> np.ndarray:
        """The supremizer operator ``H`` at ``mu`` (cached)."""
        key = np.asarray(mu, float).tobytes()
        if key not in self.H_cache:
            self.H_cache[key] = inf.supremizer_operator(self.problem_at(mu).B, self.x_solve)
        return self.H_cache[key]

    def offline(self, R_req: int) -> tuple[np.ndarray, list[int], dict[int, np.ndarray],
                                           dict[int, np.ndarray]]:
        """The cone generators ``Vg`` for ``R_req``, the primal sizes ``Ns``, and per ``N``
        the bases of ``V_N`` and of ``V_off = [V_N, S_PGA]``."""
        o = self.opts
        t1 = time.perf_counter()
        self.say(f"dual compressor {o.dual}, R = {R_req}")
        Vg = self.reg.create("dual", o.dual)(
            self.train.LAM, self.problem_at(self.scene.default_mu).W, tol=0.0,
            r_max=R_req).generators
        self.R_actual[R_req] = int(Vg.shape[1])
        Ns = [N for N in (o.N_list if o.N_list is not None else range(1, R_req + 1))
              if 1 <= N <= self.rank]
        T_list = [supremizers(B, self.x_solve, Vg) for B in self.train_B]
        delta = self._pga_delta(Vg)
        self.say(f"PGA for N in {Ns[0]}..{Ns[-1]} (delta = {delta:.3g})")
        Z_dec: dict[int, np.ndarray] = {}  # once per N (a non-nested primal recompresses)
        Z_off: dict[int, np.ndarray] = {}
        for N in Ns:
            Z = Z_dec[N] = self.basis(N)
            res = pga(T_list, Z, self.X, delta)
            Z_off[N] = np.hstack([Z, res.basis])
            self.pga[(R_req, N)] = {"delta": delta, "stop": res.stop_reason, "K": res.dim,
                                    "sigma_max": res.sigma_max.tolist()}
        self.timings[f"offline_R{R_req}_s"] = time.perf_counter() - t1
        return Vg, Ns, Z_dec, Z_off

    def _pga_delta(self, Vg: np.ndarray) -> float:
        """``delta_pga``, or the default on every fifth training parameter."""
        if self.opts.delta_pga is not None:
            return float(self.opts.delta_pga)
        probe = self.mus["train"][:: max(1, len(self.mus["train"]) // 5)]
        return pga_default_delta([self.problem_at(mu).B for mu in probe],
                                 [self.problem_at(mu).W for mu in probe], self.x_solve, Vg)

    def constants(self, R_req: int, s: str, Vg: np.ndarray, Ns: list[int],
                  Z_dec: dict[int, np.ndarray], Z_off: dict[int, np.ndarray]) -> None:
        """The constants on parameter set ``s``: per-mu values and one row per ``N``."""
        t1 = time.perf_counter()
        Rg, mus = self.R_actual[R_req], self.mus[s]
        self.say(f"inf-sup constants, R = {Rg}, {s} set ({len(mus)} parameters)")
        shape = (len(Ns), len(mus))
        d = {k: np.zeros(shape) for k in ("dec_span", "dec_cone", "off_span", "off_cone")}
        d.update(dec_zero=np.zeros(shape, bool), off_zero=np.zeros(shape, bool))
        d.update({k: np.zeros(len(mus)) for k in ("on_span", "on_cone", "c")})
        kinds: dict[str, set[str]] = {"dec": set(), "off": set(), "on": set()}
        for j, mu in enumerate(mus):
            self._values_at(mu, j, Vg, Ns, Z_dec, Z_off, d, kinds)
        d["mus"] = mus
        self.per_mu[(R_req, s)] = d
        self.rows += [_table_row(d, kinds, i, N, Rg, s, self.pga[(R_req, N)]["K"])
                      for i, N in enumerate(Ns)]
        self.timings[f"infsup_R{R_req}_{s}_s"] = time.perf_counter() - t1

    def _values_at(self, mu: np.ndarray, j: int, Vg: np.ndarray, Ns: list[int],
                   Z_dec: dict[int, np.ndarray], Z_off: dict[int, np.ndarray],
                   d: dict[str, np.ndarray], kinds: dict[str, set[str]]) -> None:
        """Column ``j`` of the per-mu values: ``beta_on``, ``c``, then ``beta_dec`` and
        ``beta_off`` for every ``N``."""
        o = self.opts
        p = self.problem_at(mu)
        BtV = np.asarray(p.B.T @ Vg)
        C_on = inf.cone_coupling(self.H_at(mu), Vg)
        S_on, M_on = C_on.T @ C_on, Vg.T @ (p.W @ Vg)
        v, k, sp_, _ = _cone(S_on, M_on, C_on, o.exact_max_r, o.n_starts)
        d["on_cone"][j], d["on_span"][j] = v, sp_
        d["c"][j] = inf.boundedness_constant(S_on, M_on)
        kinds["on"].add(k)
        for i, N in enumerate(Ns):
            for tag, Y in (("dec", Z_dec[N]), ("off", Z_off[N])):
                S, M = inf.quotient_matrices(p.B, self.X, Vg, p.W, Z=Y)
                v, k, sp_, zero = _cone(S, M, Y.T @ BtV, o.exact_max_r, o.n_starts)
                d[f"{tag}_cone"][i, j], d[f"{tag}_span"][i, j] = v, sp_
                d[f"{tag}_zero"][i, j] = zero
                kinds[tag].add(k)

    def result(self) -> BetaDecStudy:
        """The study, with the total time and the run's configuration."""
        o = self.opts
        self.timings["total_s"] = time.perf_counter() - self.t0
        config = {"dual": o.dual, "primal": o.primal, "R": o.R_list, "R_actual": self.R_actual,
                  "N_list": o.N_list, "sets": o.sets,
                  "n_train": len(self.mus["train"]), "n_valid": len(self.mus["valid"]),
                  "delta_pga": o.delta_pga, "exact_max_r": o.exact_max_r,
                  "n_starts": o.n_starts, "overrides": list(self.scene.overrides),
                  "primal_rank": self.rank}
        return BetaDecStudy(scene=self.scene.name, dual=o.dual, rows=self.rows,
                            per_mu=self.per_mu, pga=self.pga, config=config,
                            timings=self.timings)


def _primal_bases(reg: Any, primal: str, U: np.ndarray, X: Any,
                  n_max: int) -> tuple[Callable[[int], np.ndarray], int]:
    """``N -> Z`` (the primal basis of size ``N``; a nested compressor runs once and is
    truncated) and the rank of the snapshots."""
    spec = reg.get("primal", primal)
    compress = reg.create("primal", primal)
    if spec.capabilities.get("nested"):
        Z_all = compress(U, X, n=n_max).Z

        def basis(N: int) -> np.ndarray:
            return Z_all[:, :N]
    else:
        def basis(N: int) -> np.ndarray:
            return compress(U, X, n=N).Z
    return basis, compress(U, X).N


def _table_row(d: dict[str, np.ndarray], kinds: dict[str, set[str]], i: int, N: int, Rg: int,
               s: str, K: int) -> dict[str, Any]:
    """The row (keys :data:`COLUMNS`) of primal size ``N`` (index ``i``) on set ``s``."""
    return {
        "R": Rg, "N": N, "set": s, "n_mu": len(d["mus"]),
        "dec_span_min": float(d["dec_span"][i].min()),
        "dec_cone_min": float(d["dec_cone"][i].min()),
        "dec_kind": "/".join(sorted(kinds["dec"])),
        "dec_zero_count": int(d["dec_zero"][i].sum()),
        "K_pga": K,
        "off_span_min": float(d["off_span"][i].min()),
        "off_cone_min": float(d["off_cone"][i].min()),
        "off_kind": "/".join(sorted(kinds["off"])),
        "off_zero_count": int(d["off_zero"][i].sum()),
        "on_span_min": float(d["on_span"].min()),
        "on_cone_min": float(d["on_cone"].min()),
    }


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
