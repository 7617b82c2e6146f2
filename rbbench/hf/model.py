"""One HF solve: scene -> backend -> formulation -> solver -> metrics.

:func:`solve_hf` is the entry point shared by ``rbbench solve``, the tests and
the benchmarks. :func:`contact_metrics` turns a solution into the labelled
numbers of ``summary.json``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rbbench._compat import deprecated_names
from rbbench.hf.components import (
    default_solver,
    discretize_for,
    friction_at,
    make_components,
    warm_up,
)
from rbbench.hf.condensation.dense import factorize
from rbbench.hf.geometry.checks import flag
from rbbench.hf.metrics import contact_metrics
from rbbench.hf.metrics3d import contact_metrics_3d, is_3d
from rbbench.interfaces import (
    ContactProblem,
    Discretization,
    FrictionProblem,
    HFVectors,
    NitscheProblem,
    SolveResult,
)
from rbbench.registry import Registry, default_registry
from rbbench.runtime.threads import one_blas_thread
from rbbench.scene.friction import friction_of
from rbbench.scene.loading import Scene


@dataclass
class HFSolution:
    """One HF solve: the scene, the components by name, the operators, the algebraic problem,
    the solver's result, the times (s) and the labelled numbers of ``summary.json``.

    Its common fields (:class:`rbbench.interfaces.Solution`: ``mu``, ``u``, ``lam``,
    ``iterations``, ``stop_reason``, ``time_s``) are the result's: ``u`` on all dofs,
    ``time_s`` the solve's total (``times["total_s"]``).
    """

    scene: Scene
    mu: np.ndarray
    components: dict[str, str]
    disc: Discretization
    problem: ContactProblem | NitscheProblem | FrictionProblem
    result: SolveResult
    times: dict[str, float]
    metrics: dict[str, Any] = field(default_factory=dict)

    @property
    def u(self) -> np.ndarray:
        return self.result.u

    @property
    def lam(self) -> np.ndarray:
        return self.result.lam

    @property
    def iterations(self) -> int:
        return int(self.result.iterations)

    @property
    def stop_reason(self) -> str:
        return self.result.stop_reason

    @property
    def time_s(self) -> float:
        return float(self.times["total_s"])

    @property
    def converged(self) -> bool:
        return self.result.converged


def hf_vectors(sol: HFSolution) -> HFVectors:
    """The HF vectors of a solve in the snapshot space: ``u`` on the free dofs (a trajectory
    flattened as solved), the multipliers, and ``lam_t`` for a friction solve."""
    res, prob = sol.result, sol.problem
    u = np.asarray(res.u, dtype=float)
    if not res.info.get("parabolic", False):
        u = u[prob.free]
    lam_t = res.info.get("lam_t")
    return HFVectors(u=u, lam=np.asarray(res.lam, dtype=float),
                     lam_t=None if lam_t is None else np.asarray(lam_t, dtype=float))


def _noop(stage: str) -> None:
    return None


def build_problem(backend: Any, formulation: Any, scene: Scene, mu: Any) -> Any:
    """The HF problem at ``mu``: discretise and formulate, with the scene's friction law
    (:func:`~rbbench.hf.components.friction_at`)."""
    disc = discretize_for(backend, formulation, mu)
    friction = friction_at(scene, mu)
    return formulation.build(disc) if friction is None else formulation.build(disc, friction)


class ProblemCache:
    """``mu -> HF problem``, built once per mu (backend discretize + formulation build; with
    a ``scene``, its friction law at mu: :func:`build_problem`).

    Also gives the V inner product on the free dofs, ``X_free`` (parameter-independent).
    """

    def __init__(self, backend: Any, formulation: Any, scene: Scene | None = None):
        self.backend, self.formulation, self.scene = backend, formulation, scene
        self._problems: dict[bytes, Any] = {}

    def __call__(self, mu: Any) -> Any:
        key = np.asarray(mu, float).tobytes()
        if key not in self._problems:
            if self.scene is None:
                self._problems[key] = self.formulation.build(
                    discretize_for(self.backend, self.formulation, mu))
            else:
                self._problems[key] = build_problem(self.backend, self.formulation,
                                                    self.scene, mu)
        return self._problems[key]

    def X_free(self, mu: Any) -> Any:
        """``X`` restricted to the free dofs of the problem at ``mu``."""
        p = self(mu)
        return p.X[p.free][:, p.free].tocsr()


class ProblemSource:
    """``mu -> HF problem``, assembled afresh at each call (no cache): the online stage of a
    reduced model without hyper-reduction.

    Picklable as a recipe: the scene, the component names and options; the built backend and
    formulation (``components``, e.g. the offline stage's, so that nothing is meshed again)
    are dropped when pickled and built again at the next call.
    """

    def __init__(self, scene: Scene, backend: str = "skfem", formulation: str = "mixed",
                 component_options: dict | None = None, registry: Registry | None = None,
                 components: tuple[Any, Any] | None = None) -> None:
        self.scene, self.backend, self.formulation = scene, backend, formulation
        self.component_options = component_options or {}
        self.registry, self.components = registry, components

    def __call__(self, mu: Any) -> Any:
        if self.components is None:
            b, f, _ = make_components(self.scene, self.backend, self.formulation,
                                      registry=self.registry,
                                      component_options=self.component_options)
            warm_up(b)
            self.components = (b, f)
        return build_problem(*self.components, self.scene, mu)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["components"] = None
        if state["registry"] is default_registry():
            state["registry"] = None  # the receiving process discovers its own
        return state


class HFModel:
    """The HF model of a scene and a choice of components (the model interface it shares
    with the reduced models, as pyMOR's ``Model.solve(mu)``).

    ``solve(mu)`` parses mu and checks it against the scene's domain D
    (:attr:`parameters`, a :class:`~rbbench.scene.parameters.ParameterSpace`), then
    discretises, formulates and solves. The components (mesh included) are built at the
    first solve and reused.
    """

    def __init__(self, scene: Scene, backend: str = "skfem", formulation: str = "mixed",
                 solver: str | None = None, registry: Registry | None = None,
                 solver_options: dict | None = None, components: Any = None) -> None:
        self.scene = scene
        self.parameters = scene.parameter_space
        self.names = {"backend": backend, "formulation": formulation,
                      "solver": default_solver(formulation, registry, friction_of(scene).law)
                      if solver is None else solver}
        self.registry, self.solver_options = registry, solver_options
        self.components = components

    def reconstruct(self, solution: HFSolution) -> HFVectors:
        """The solution's vectors in the snapshot space (:func:`hf_vectors`)."""
        return hf_vectors(solution)

    def __getstate__(self) -> dict:
        """Pickle the recipe (scene, names, options), not the built components: they are
        built again at the next solve."""
        state = dict(self.__dict__)
        state["components"] = None
        return state

    def solve(self, mu: Any = None, progress: Callable[[str], None] = _noop,
              floor: bool = False) -> HFSolution:
        """Solve at ``mu`` (default: the scene default); a
        :class:`~rbbench.scene.parameters.SceneError` names a parameter outside D.

        The solve runs with one BLAS thread (:func:`rbbench.runtime.threads.one_blas_thread`,
        recorded in ``metrics["blas_threads"]``). ``floor``: also time one factorisation +
        one solve of the same stiffness right after it (:func:`solve_floor`: ``floor_s``,
        ``solve_over_floor``).
        """
        mu = self.scene.default_mu if mu is None else self.parameters.check(mu)
        with one_blas_thread() as threads:
            sol = self._solve(mu, progress)
            if floor:
                progress("timing the floor: one factorisation + one solve of A")
                sol.metrics.update(floor_metrics(sol))
        sol.metrics["blas_threads"] = threads
        return sol

    def _solve(self, mu: np.ndarray, progress: Callable[[str], None]) -> HFSolution:
        """Mesh and build the mu-independent operators (first call, ``Backend.warm_up``),
        discretise, formulate, solve, metrics, flag."""
        scene, names = self.scene, self.names
        t0 = time.perf_counter()
        if self.components is None:
            progress("meshing the reference configuration")
            self.components = make_components(scene, names["backend"], names["formulation"],
                                              names["solver"], self.registry,
                                              self.solver_options)
            warm_up(self.components[0])  # mu-independent operators: setup, not discretisation
        b, f, s = self.components
        t1 = time.perf_counter()
        progress("assembling operators")
        disc = discretize_for(b, f, mu)
        t2 = time.perf_counter()
        friction = friction_at(scene, mu)
        problem = f.build(disc) if friction is None else f.build(disc, friction=friction)
        n_contact = (2 * problem.n_nodes if isinstance(problem, FrictionProblem)
                     else disc.contact.n_mult)
        progress(f"solving ({disc.n_dofs} dofs, {n_contact} contact unknowns)")
        t3 = time.perf_counter()
        result = s.solve(problem)
        t4 = time.perf_counter()
        times = {"setup_s": t1 - t0, "discretize_s": t2 - t1, "formulate_s": t3 - t2,
                 "solve_s": t4 - t3, "total_s": t4 - t0}
        sol = HFSolution(scene, mu, dict(names), disc, problem, result, times)
        sol.metrics = contact_metrics_3d(sol) if is_3d(disc) else contact_metrics(sol)
        flag(sol)  # zero force on an overlapping solution: stop_reason "flagged"
        return sol


def solve_floor(problem: Any, linear_solver: str | None = None) -> dict[str, Any]:
    """Time one factorisation + one solve ``A x = F`` of the problem's stiffness on the free
    dofs with the direct solver the HF solve used: PARDISO when ``linear_solver`` is
    ``"pardiso"`` (the solve's condensation ran on it), else ``problem.factorize`` (the
    backend's), else SuperLU (:func:`rbbench.hf.condensation.dense.factorize`): the floor of a
    contact solve.

    Returns ``factor_s``, ``solve_s`` and their sum ``floor_s`` (s) and ``solver``.
    """
    t0 = time.perf_counter()
    if linear_solver == "pardiso":
        from rbbench.hf.condensation.pardiso import factorized

        solve, name = factorized(problem.A), "PARDISO (rbbench.hf.condensation.pardiso.factorized)"
    elif problem.factorize is not None:
        solve, name = problem.factorize(problem.A), "backend factorize"
    else:
        solve = factorize(problem.A).solve
        name = "SuperLU (rbbench.hf.condensation.dense.factorize)"
    t1 = time.perf_counter()
    x = solve(np.asarray(problem.F, dtype=float))
    t2 = time.perf_counter()
    if not np.all(np.isfinite(x)):
        raise FloatingPointError("floor: the solve of A x = F gave a non-finite x")
    return {"floor_s": t2 - t0, "factor_s": t1 - t0, "solve_s": t2 - t1, "solver": name}


def default_floor(problem: Any) -> dict[str, Any]:
    """:func:`solve_floor` with the direct solver a default HF contact solve picks
    (``linear_solver = "auto"`` of :func:`rbbench.hf.condensation.schur.condense_problem`): the
    backend's ``factorize`` when it gives one, else PARDISO when ``pypardiso`` is installed,
    else SuperLU. Used where the solve itself is not at hand (a reduction's validation, whose
    HF snapshots were solved, maybe cached, with the default)."""
    from rbbench.hf.condensation.pardiso import available

    pardiso = problem.factorize is None and available()
    return solve_floor(problem, "pardiso" if pardiso else None)


def floor_metrics(sol: HFSolution) -> dict[str, Any]:
    """``floor_s``, ``solve_over_floor`` (solver time ``times["solve_s"]`` / ``floor_s``)
    and the ``floor`` block of :func:`solve_floor` with the solve's own linear solver
    (``condensation_linear_solver`` of its info), timed now (see :data:`DEFINITIONS`)."""
    fl = solve_floor(sol.problem, sol.result.info.get("condensation_linear_solver"))
    return {"floor_s": fl["floor_s"], "solve_over_floor": sol.times["solve_s"] / fl["floor_s"],
            "floor": fl}


def solve_hf(scene: Scene, mu: Any = None, backend: str = "skfem", formulation: str = "mixed",
             solver: str | None = None, registry: Registry | None = None,
             solver_options: dict | None = None,
             progress: Callable[[str], None] = _noop, components=None,
             floor: bool = True) -> HFSolution:
    """Solve the HF contact problem of ``scene`` at ``mu`` (default: the scene default):
    :meth:`HFModel.solve`, one BLAS thread.

    ``solver = None``: the formulation's declared solver (``ssn`` for mixed, ``newton``
    for Nitsche). ``floor`` (default, as ``rbbench solve``): also time one factorisation +
    one solve of the stiffness (``metrics["floor_s"]``, ``["solve_over_floor"]``); pass
    ``False`` where only the solution counts (snapshots).
    """
    return HFModel(scene, backend, formulation, solver, registry, solver_options,
                   components).solve(mu, progress, floor=floor)


__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)
