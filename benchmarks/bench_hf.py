"""asv: the HF solve of ``rbbench solve`` (:func:`rbbench.hf.model.solve_hf`), time and accuracy."""

from rbbench.hf.components import make_components
from rbbench.hf.model import solve_hf

from ._common import CASES, FRICTION_CASES, TIMEOUT, finite, scene

#: the frictionless cases (the two solvers here solve frictionless contact)
HF_CASES = [case for case in CASES if case not in FRICTION_CASES]


class HFSolve:
    """One HF contact solve at the scene's default mu, meshing excluded.

    ``setup`` builds the components once (backend: meshes the reference configuration;
    formulation; solver), so the timed call is what ``rbbench solve`` does after meshing:
    discretise at mu (assemble A, F, X, W, B, G), build the contact problem, solve it,
    compute the summary metrics. Cases: the frictionless ones of :mod:`benchmarks._common`;
    solvers ``ssn`` (primal-dual active set) and ``uzawa``.
    """

    params = (HF_CASES, ["ssn", "uzawa"])
    param_names = ["scene", "solver"]
    timeout = TIMEOUT
    repeat = (1, 5, 10.0)  # at most 5 samples or 10 s per round (hertz_default: ~3 s a solve)

    def setup(self, case, solver):
        self.scene = scene(case)
        self.mu = self.scene.default_mu
        self.components = make_components(self.scene, solver=solver)

    def time_hf_solve(self, case, solver):
        """Wall time (s) of ``solve_hf`` at the default mu: discretise + formulate + solve."""
        sol = solve_hf(self.scene, self.mu, solver=solver, components=self.components)
        if not sol.result.converged:
            raise RuntimeError(f"{case}/{solver}: HF solve did not converge "
                               f"({sol.result.stop_reason})")

    def peakmem_hf_solve(self, case, solver):
        """Peak resident memory (bytes) of the benchmark process around one HF solve.

        asv's measure: the process maximum (interpreter, libraries, the components built
        in ``setup`` and the solve), so the level includes a constant base; its change
        along the history is what matters.
        """
        solve_hf(self.scene, self.mu, solver=solver, components=self.components)


class HertzAccuracy:
    """|relative error| of the HF solution against 2D Hertz theory, default mesh, mu = 1.

    Signed errors are (computed - theory) / theory at the solver's own contact force
    (``rbbench solve`` summary, ``hertz`` block); tracked as absolute values, so lower
    is better. Unit: relative (dimensionless).
    """

    timeout = TIMEOUT

    def setup_cache(self):
        m = solve_hf(scene("hertz_default"), 1.0).metrics["hertz"]
        return {"a": abs(m["a_rel_error"]), "p0": abs(m["p0_rel_error"])}

    setup_cache.timeout = TIMEOUT

    def track_a_rel_error(self, cache):
        """|a_h - a| / a: contact half-width against Hertz (relative, lower is better)."""
        return finite(cache["a"], "Hertz half-width error")

    def track_p0_rel_error(self, cache):
        """|p0_h - p0| / p0: peak pressure against Hertz (relative, lower is better)."""
        return finite(cache["p0"], "Hertz peak-pressure error")

    track_a_rel_error.unit = "relative"
    track_p0_rel_error.unit = "relative"


#: The e_AC table's setting (``rbbench nitsche-table``; README "The e_AC^n table").
_AC_SETTING = ("load.displacement=0.09", "discretization.degree=2",
               "discretization.normals=smooth", "discretization.contact_integration=segmented")


class NitscheAlartCurnier:
    """The relative Alart-Curnier residual e_AC^n of the Nitsche HF solve on two non-matching
    bodies (mu = 0.7), at h = 5 and 2.5 mm as published by Benaceur, Drouet, Ehrlacher, Ern &
    Niakh, "Model order reduction methods: parametric variational inequalities" (talk), slide
    "Relative error on the Alart-Curnier reformulation" (``h_contact = 4 h``,
    coarse far field ``h_max = 0.2``), in the e_AC table's setting (P2, smooth normals,
    segment-to-segment quadrature, theta = 1, gamma0 = 10).

    A fraction, L2(Gamma_c) by the contact quadrature (``summary.json`` ``e_ac``);
    lower is better. The ratio of the two values gives the observed order (about 1;
    Gauss-point-to-segment with facet normals stagnates at 7 %).
    """

    params = (["5", "2.5"],)
    param_names = ["h_mm"]
    timeout = TIMEOUT

    def setup_cache(self):
        from rbbench.scene.loading import load_scene

        out = {}
        for h in self.params[0]:
            sc = load_scene("hertz_halfdisks", [*_AC_SETTING, "discretization.h_max=0.2",
                                                f"discretization.h_contact={4e-3 * float(h)!r}"])
            sol = solve_hf(sc, 0.7, formulation="nitsche")
            if not sol.result.converged:
                raise RuntimeError(f"h = {h} mm: Nitsche solve {sol.result.stop_reason}")
            out[h] = sol.metrics["e_ac"]
        return out

    setup_cache.timeout = TIMEOUT

    def track_e_ac(self, cache, h_mm):
        """e_AC^n at mu = 0.7 (relative, lower is better)."""
        return finite(cache[h_mm], "e_AC")

    track_e_ac.unit = "relative"


class ContactPairing:
    """Wall time (s) of the contact pairing at mu = 0.8 on the default Hertz mesh with
    smooth normals (:func:`rbbench.hf.geometry.operators.pair`): the Gauss rule per slave
    facet, or segment-to-segment pieces (master-vertex rays, a quadratic per facet and
    master vertex)."""

    params = (["gauss", "segmented"],)
    param_names = ["integration"]
    timeout = TIMEOUT

    def setup(self, integration):
        import numpy as np

        from rbbench.registry import default_registry
        from rbbench.scene.loading import load_scene

        sc = load_scene("hertz_halfdisks", ["discretization.normals=smooth",
                                            f"discretization.contact_integration={integration}"])
        self.layout = default_registry().create("backend", "skfem", scene=sc).contact_layout()
        self.mu = np.array([0.8])

    def time_pair(self, integration):
        """Pairing at mu: points, normals, ray casts, gaps (s)."""
        from rbbench.hf.geometry.pairing import pair

        pair(self.layout, self.mu)


class HFFloor:
    """The HF contact solve against its floor: ``hertz_halfdisks`` at mu = 1 on
    the default mesh refined ``level`` times (36910 / 75226 / 159k dofs at levels 0 / 1 / 2),
    per direct solver of the condensation (``linear_solver`` of ``ssn``: the Schur
    complement of the KKT matrix by SuperLU or PARDISO, :mod:`rbbench.hf.condensation.schur`;
    PARDISO skipped when ``pypardiso`` is not installed).

    ``setup_cache`` runs ``rbbench solve``'s solve once per case (:func:`solve_hf`, one
    BLAS thread, the floor timed right after the solve in the same process): the solver's
    time ``times_s.solve_s`` (condensation, contact iterations, recovery of u; no
    assembly), the floor ``floor_s`` (one factorisation + one solve of the same stiffness
    with the same direct solver: SuperLU, or PARDISO's Cholesky,
    :func:`rbbench.hf.model.solve_floor`) and their ratio ``solve_over_floor`` (goal <= 1.5).
    """

    params = (["0", "1", "2"], ["superlu", "pardiso"])
    param_names = ["level", "linear_solver"]
    timeout = TIMEOUT

    def setup_cache(self):
        from rbbench.hf.condensation.pardiso import available
        from rbbench.scene.loading import load_scene

        out = {}
        for level in self.params[0]:
            for ls in self.params[1]:
                if ls == "pardiso" and not available():
                    continue
                sol = solve_hf(load_scene("hertz_halfdisks", [f"discretization.level={level}"]),
                               solver_options={"linear_solver": ls})
                if not sol.result.converged:
                    raise RuntimeError(f"level {level}: HF solve {sol.result.stop_reason}")
                m = sol.metrics
                out[(level, ls)] = {"solve_s": m["times_s"]["solve_s"], "floor_s": m["floor_s"],
                                    "solve_over_floor": m["solve_over_floor"]}
        return out

    setup_cache.timeout = 4 * TIMEOUT

    def setup(self, cache, level, linear_solver):
        if (level, linear_solver) not in cache:
            raise NotImplementedError  # asv: skipped (pypardiso not installed)

    def track_solve_s(self, cache, level, linear_solver):
        """The solver's time of one HF solve (s): times_s.solve_s."""
        return finite(cache[(level, linear_solver)]["solve_s"], "HF solver time")

    def track_floor_s(self, cache, level, linear_solver):
        """One factorisation + one solve of the same stiffness (s), timed after the solve."""
        return finite(cache[(level, linear_solver)]["floor_s"], "floor")

    def track_solve_over_floor(self, cache, level, linear_solver):
        """times_s.solve_s / floor_s (dimensionless, lower is better; goal <= 1.5)."""
        return finite(cache[(level, linear_solver)]["solve_over_floor"], "solve over floor")

    track_solve_s.unit = "s"
    track_floor_s.unit = "s"
    track_solve_over_floor.unit = "ratio"


class SnapshotWorkers:
    """HF snapshots of 8 parameters (mu = 0.7 ... 1.3, ``hertz_halfdisks`` default mesh)
    with 1 and 2 worker processes (:func:`rbbench.hf.snapshots.compute.compute_snapshots`, a
    fresh cache directory per call, so that every solve runs).

    ``setup`` builds this process's components (meshing + inner product) by one snapshot
    at mu = 1: the timed calls reuse them (serial; with 2 jobs two ``fork`` workers
    inherit them), as ``rbbench reduce``'s validation snapshots do after its training
    ones. The time of 2 processes against 1 is the scaling
    of the solves (goal: >= 1.85x).
    """

    params = ([1, 2],)
    param_names = ["n_jobs"]
    timeout = TIMEOUT
    number = 1
    repeat = (1, 3, 120.0)

    def setup(self, n_jobs):
        import tempfile

        import numpy as np

        from rbbench.hf.snapshots.compute import compute_snapshots

        self.scene = scene("hertz_default")
        self.mus = np.linspace(0.7, 1.3, 8)
        with tempfile.TemporaryDirectory() as d:
            compute_snapshots(self.scene, [1.0], cache_dir=d, n_jobs=1, progress=False)

    def time_snapshots(self, n_jobs):
        """Wall time (s) of 8 HF snapshots with n_jobs worker processes."""
        import tempfile

        from rbbench.hf.snapshots.compute import compute_snapshots

        with tempfile.TemporaryDirectory() as d:
            compute_snapshots(self.scene, self.mus, cache_dir=d, n_jobs=n_jobs,
                              progress=False)


class SnapshotWorkersKept(SnapshotWorkers):
    """As :class:`SnapshotWorkers`, but the timed call is the second of a
    :func:`rbbench.runtime.workers.keep_workers` block (``setup`` makes the first, which
    starts the pool): ``rbbench reduce``'s validation snapshots after its training ones.
    With 2 workers the timed call finds workers that already solved (no first-solve page
    faults); with 1 it is the same serial call as :class:`SnapshotWorkers`."""

    def setup(self, n_jobs):
        from rbbench.runtime.workers import keep_workers

        super().setup(n_jobs)
        self.block = keep_workers()
        self.block.__enter__()
        self.time_snapshots(n_jobs)  # the block's first call

    def teardown(self, n_jobs):
        self.block.__exit__(None, None, None)

    def time_snapshots(self, n_jobs):
        """Wall time (s) of 8 HF snapshots, the second call of a kept pool."""
        super().time_snapshots(n_jobs)
