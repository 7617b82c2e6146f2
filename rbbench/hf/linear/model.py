"""HF solves of the linear scenes: no contact operator, no multiplier, no VI.

:class:`LinearProblem` is the algebraic problem on the free dofs (homogeneous Dirichlet
eliminated for ``thermal``; every dof free for ``heat``): ``A u = F`` (elliptic), or
implicit Euler ``(M / dt + A) u^k = M / dt u^{k-1} + F``, ``u^0 = u0`` (Benaceur, Drouet,
Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric variational inequalities"
(talk), slide "Simple toy example: heat equation"). :func:`solve_linear` solves it with one
factorisation (the backend's direct solver, else SuperLU); a trajectory is stored as
``(K, n_free)`` rows ``u^1 .. u^K`` and
flattened row by row for the snapshot set, so that the space-time norm
``kron(dt I_K, X)`` (:func:`space_time_norm`) is the discrete ``L2(0, T; X)`` norm.

:class:`LinearHF` is the HF model (``solve(mu)`` checks mu against D, as
:class:`rbbench.hf.model.HFModel`); :func:`linear_snapshots` computes and caches snapshots
with the files and keys of :mod:`rbbench.hf.snapshots.compute`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from rbbench.hf.condensation.dense import factorize
from rbbench.hf.model import HFSolution, hf_vectors
from rbbench.hf.snapshots.cache import (
    Snapshot,
    SnapshotSet,
    cache_path,
    load_snapshot,
    save_snapshot,
)
from rbbench.hf.snapshots.key import snapshot_key
from rbbench.interfaces import Discretization, Factorize, HFVectors, SolveResult
from rbbench.interfaces.problems import _FreeDofs
from rbbench.registry import Registry, default_registry
from rbbench.runtime.threads import one_blas_thread
from rbbench.scene.linear import check_physics
from rbbench.scene.loading import Scene

__all__ = ["NO_CONTACT", "LinearHF", "LinearProblem", "hf_row", "linear_backend",
           "linear_snapshots", "solve_linear", "space_time_norm"]

#: Why the contact columns of a linear scene's row are empty (the row's reason).
NO_CONTACT = ("no contact: n_contact, R, S, err_lam_*, penetration, complementarity, "
              "contact_force and beta_* do not apply (NaN); no contact operator, dual space "
              "or stabiliser built")


@dataclass
class LinearProblem(_FreeDofs):
    """A linear problem on the free dofs (module docstring). ``M``: the mass matrix
    (``None`` when stationary); ``dt``, ``steps``: the implicit Euler grid; ``u0``: the
    initial free values."""

    A: sp.csr_matrix
    F: np.ndarray
    free: np.ndarray
    u_lift: np.ndarray
    X: sp.csr_matrix
    M: sp.csr_matrix | None = None
    dt: float = 0.0
    steps: int = 0
    u0: np.ndarray | None = None
    factorize: Factorize | None = None

    @property
    def parabolic(self) -> bool:
        return self.M is not None


def _restrict(S: sp.spmatrix, free: np.ndarray) -> sp.csr_matrix:
    return sp.csr_matrix(S)[free][:, free].tocsr()


def build_linear(disc: Discretization) -> LinearProblem:
    """The :class:`LinearProblem` of a linear discretization (``contact`` must be None)."""
    if disc.contact is not None:
        raise ValueError("a linear problem has no contact operators (disc.contact is set)")
    n = disc.n_dofs
    free = np.setdiff1d(np.arange(n), np.asarray(disc.dirichlet_dofs, dtype=np.int64))
    u_lift = np.zeros(n)
    u_lift[disc.dirichlet_dofs] = disc.dirichlet_values
    F = np.asarray(disc.F - disc.A @ u_lift)[free]
    prob = LinearProblem(A=_restrict(disc.A, free), F=F, free=free, u_lift=u_lift,
                         X=disc.X, factorize=disc.factorize)
    grid = disc.info.get("time")
    if grid is not None:
        prob.M = _restrict(disc.info["mass"], free)
        prob.steps = int(grid["steps"])
        prob.dt = float(grid["final"]) / prob.steps
        prob.u0 = np.asarray(disc.info["initial"], float)[free]
    return prob


def _factor(problem: LinearProblem, S: sp.csr_matrix):
    """The backend's direct solver, else SuperLU in symmetric mode as the HF contact solvers
    (:func:`rbbench.hf.condensation.dense.factorize`)."""
    if problem.factorize is not None:
        return problem.factorize(S)
    return factorize(S).solve


def solve_linear(problem: LinearProblem) -> np.ndarray:
    """``u`` on the free dofs (elliptic), or the trajectory ``(K, n_free)`` of implicit
    Euler (one factorisation of ``M / dt + A``)."""
    if not problem.parabolic:
        return np.asarray(_factor(problem, problem.A)(problem.F))
    M, dt = problem.M, problem.dt
    solve = _factor(problem, (M / dt + problem.A).tocsr())
    out = np.empty((problem.steps, problem.F.size))
    u = problem.u0
    for k in range(problem.steps):
        u = solve(M @ u / dt + problem.F)
        out[k] = u
    return out


def space_time_norm(X: sp.spmatrix, dt: float, steps: int) -> sp.csr_matrix:
    """``kron(dt I_K, X)``: the discrete ``L2(0, T; X)`` inner product of flattened
    trajectories (rows ``u^1 .. u^K``, the right-endpoint rule of implicit Euler)."""
    return sp.kron(sp.identity(steps) * dt, X, format="csr")


def linear_backend(scene: Scene, name: str, registry: Registry | None = None,
                   **options: Any) -> Any:
    """The backend ``name``'s linear assembler (``capabilities["linear_target"]`` of the
    registered backend: the same backend role, its linear scenes)."""
    import importlib

    from rbbench.registry import NotInstalledError

    check_physics(scene)
    reg = registry or default_registry()
    spec = reg.get("backend", name)
    target = spec.capabilities.get("linear_target")
    if target is None:
        raise ValueError(f"backend {name!r} declares no linear scenes (linear_target)")
    ok, why = reg.availability(spec)
    if not ok:
        raise NotInstalledError(f"backend {name!r}: {why}")
    module, attr = target.split(":", 1)
    return getattr(importlib.import_module(module), attr)(scene, **options)


class LinearHF:
    """The HF model of a linear scene (:class:`rbbench.interfaces.Model`): ``solve(mu)`` an
    :class:`~rbbench.hf.model.HFSolution` whose ``problem`` is a :class:`LinearProblem`,
    ``u`` the global field or the flattened free trajectory, ``lam`` empty."""

    def __init__(self, scene: Scene, backend: str = "skfem", registry: Registry | None = None,
                 backend_options: dict | None = None) -> None:
        self.scene = scene
        self.parameters = scene.parameter_space
        self.backend = linear_backend(scene, backend, registry, **(backend_options or {}))
        self.names = {"backend": backend, "formulation": "linear", "solver": "direct"}

    def problem(self, mu: Any) -> LinearProblem:
        """The :class:`LinearProblem` at mu (checked against D)."""
        return build_linear(self.backend.discretize(self.parameters.check(mu)))

    def solve(self, mu: Any = None) -> HFSolution:
        """Assemble and solve at mu with one BLAS thread (default: the scene default; checked
        against D); ``times``: ``discretize_s``, ``solve_s``, ``total_s`` (s)."""
        mu = self.scene.default_mu if mu is None else self.parameters.check(mu)
        with one_blas_thread():
            t0 = time.perf_counter()
            disc = self.backend.discretize(mu)
            prob = build_linear(disc)
            t1 = time.perf_counter()
            u = solve_linear(prob)
            t2 = time.perf_counter()
        times = {"discretize_s": t1 - t0, "solve_s": t2 - t1, "total_s": t2 - t0}
        result = SolveResult(u=u.ravel() if prob.parabolic else prob.expand(u), lam=np.empty(0),
                             iterations=1, stop_reason="converged", times=times,
                             info={"free": prob.free, "n_dofs": int(prob.u_lift.size),
                                   "parabolic": prob.parabolic})
        return HFSolution(self.scene, np.asarray(mu, float), dict(self.names), disc, prob,
                          result, times)

    def reconstruct(self, solution: HFSolution) -> HFVectors:
        """The free values (a trajectory flattened step by step), as the snapshots store them."""
        return hf_vectors(solution)


def _snapshot(hf: LinearHF, mu: np.ndarray) -> Snapshot:
    sol = hf.solve(mu)
    return Snapshot(mu=np.asarray(mu, float), u=hf.reconstruct(sol).u, lam=np.empty(0),
                    iterations=1, stop_reason=sol.stop_reason, time_s=sol.time_s,
                    free=np.asarray(sol.problem.free, dtype=np.int64),
                    n_dofs=int(sol.problem.u_lift.size))


def linear_snapshots(scene: Scene, mus: np.ndarray, hf: LinearHF, backend: str,
                     cache_dir: str | Path, registry: Registry | None = None) -> SnapshotSet:
    """HF snapshots at every row of ``mus`` (serial; cached under the key of
    :func:`rbbench.hf.snapshots.compute.snapshot_key` with formulation ``"linear"``)."""
    mus = np.asarray(mus, float).reshape(len(mus), len(scene.parameters))
    key = snapshot_key(scene, backend, "linear", "direct", registry=registry)
    snaps, n_new = [], 0
    for mu in mus:
        path = cache_path(cache_dir, key, mu)
        snap = None
        if path.exists():
            try:
                snap = load_snapshot(path)
            except Exception:  # noqa: BLE001 - unreadable: recompute
                snap = None
        if snap is None or not np.array_equal(snap.mu, mu):
            snap, n_new = _snapshot(hf, mu), n_new + 1
            save_snapshot(path, snap)
        snaps.append(snap)
    return SnapshotSet(mus=mus, U=np.column_stack([s.u for s in snaps]),
                       LAM=np.empty((0, len(snaps))), stop_reasons=[s.stop_reason for s in snaps],
                       iterations=np.ones(len(snaps), dtype=int),
                       times=np.array([s.time_s for s in snaps]), n_dofs=snaps[0].n_dofs,
                       free=snaps[0].free, key=key, cache_dir=Path(cache_dir),
                       n_computed=n_new)


def hf_row(scene: Scene, backend: str, repeats: int, registry: Registry | None = None
           ) -> dict[str, Any]:
    """The columns of an HF matrix row (``mode = "hf"``) of a linear scene: ``repeats``
    solves at the default mu (assembly included, meshing not), their median time."""
    hf = LinearHF(scene, backend, registry)
    times, sol = [], None
    for _ in range(max(1, repeats)):
        sol = hf.solve()
        times.append(sol.time_s)
    return {"n_hf_dofs": int(sol.result.info["n_dofs"]), "hf_iterations": 1,
            "t_hf_median_s": float(np.median(times)), "status": "ok", "reason": NO_CONTACT}
