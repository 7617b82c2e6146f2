"""asv: the offline stages of ``rbbench reduce`` (:func:`rbbench.rb.offline.reduce`).

Each stage is timed alone, on the inputs ``reduce()`` gives it and through the same
registered plugins (``primal`` / ``dual`` / ``stabilizer`` roles of the default
registry), with the options of :data:`benchmarks._common.RB_OPTIONS` and otherwise the
CLI defaults. The training snapshots (and, for EIM, the bases) are computed once by
``setup_cache``; the HF operators at the training parameters are assembled in ``setup``
(not timed).
"""

import tempfile
from dataclasses import replace

import numpy as np

from rbbench.hf.components import make_components
from rbbench.hf.geometry.operators import contact_operators
from rbbench.hf.model import ProblemCache
from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.compressors import make_stabilizer, pga_delta
from rbbench.rb.hyper.contact_eim import contact_eim
from rbbench.rb.offline import eim_training_set, primal_basis
from rbbench.registry import default_registry
from rbbench.scene.sampling import parameter_set

from ._common import RB_CASES, TIMEOUT, reduce_config, scene

#: the dual compressors compared (``pod`` and ``nnmf`` are left out: not cone-greedy)
DUALS = ["cpg", "mcpg", "eng"]


def _training(case: str, cache_dir: str | None = None):
    cfg = reduce_config(case, cache_dir)
    sc = scene(case)
    return sc, cfg, parameter_set(sc, "train", cfg.n_train)


def _snapshots(sc, cfg, mus):
    return compute_snapshots(sc, mus, backend=cfg.backend, formulation=cfg.formulation,
                             solver=cfg.solver, cache_dir=cfg.cache_dir, n_jobs=cfg.n_jobs,
                             progress=False)


def offline_inputs():
    """setup_cache: training snapshots of each RB case, plus Z_off, Vg for EIM.

    Bases as ``reduce()`` builds them (POD, mCPG, PGA with the default delta).
    """
    out = {}
    with tempfile.TemporaryDirectory(prefix="rbbench-asv-") as d:
        for case in RB_CASES:
            snaps = _snapshots(*_training(case, d))
            out[case] = {"mus": snaps.mus, "U": snaps.U, "LAM": snaps.LAM}
    # bases for the EIM benchmark (hertz_coarse only: the membrane is exactly affine)
    st = _Stage()
    st.setup(out, "hertz_coarse")
    Z, Vg = st.bases()
    problems = [st.problem_at(mu) for mu in st.data["mus"]]
    Z_off = st.stabilise(make_stabilizer(st.registry, st.opts), Z, Vg, problems)
    st.data.update(Vg=Vg, Z_off=Z_off)
    return out


offline_inputs.timeout = TIMEOUT


class _Stage:
    """Common setup: the scene, the registry, X and W_ref (as in ``reduce()``); the
    training inputs from :func:`offline_inputs` (``setup_cache``)."""

    timeout = TIMEOUT
    setup_cache = staticmethod(offline_inputs)

    def setup(self, data, case):
        self.data = data[case]
        self.cfg = reduce_config(case)
        self.opts = self.cfg.options  # the mixed formulation's options (dual, PGA, EIM)
        self.scene = scene(case)
        self.registry = default_registry()
        b, f, _ = make_components(self.scene, self.cfg.backend, self.cfg.formulation,
                                  self.cfg.solver, registry=self.registry)
        self.backend = b
        self.problem_at = ProblemCache(b, f)
        self.X = self.problem_at.X_free(self.scene.default_mu)
        self.x_solve = inf.make_solver(self.X)
        self.W_ref = self.problem_at(self.scene.default_mu).W

    def bases(self):
        """``Z`` (primal plugin) and ``Vg`` (dual plugin) as ``reduce()`` builds them."""
        cfg, opts, reg = self.cfg, self.opts, self.registry
        Z = primal_basis(reg, cfg, self.data["U"], self.X).Z
        Vg = reg.create("dual", opts.dual)(self.data["LAM"], self.W_ref, tol=opts.tol_dual,
                                           r_max=opts.R).generators
        return Z, Vg

    def stabilise(self, stabilizer, Z, Vg, problems):
        """The stabiliser stage of ``reduce()``: default delta (Benaceur et al.'s), offline()."""
        delta = pga_delta(self.opts, problems, self.x_solve, Vg)
        return stabilizer.offline(Z, Vg, self.X, self.x_solve, (p.B for p in problems),
                                  delta)[0]


class Snapshots:
    """HF snapshots of the training set, as ``reduce()`` computes them (stage 1).

    :func:`rbbench.hf.snapshots.compute.compute_snapshots` into a fresh empty cache directory (so
    every solve runs and its file is written), in this process (``n_jobs = 1``);
    includes building the components (meshing) once. Training sets: 16 (membrane,
    4 x 4 grid) and 11 (coarse Hertz) parameters. Unit: seconds.
    """

    params = (RB_CASES,)
    param_names = ["scene"]
    timeout = TIMEOUT
    repeat = (1, 5, 10.0)

    def setup(self, case):
        self.scene, self.cfg, self.mus = _training(case)

    def time_snapshots(self, case):
        """Wall time (s) of the training snapshots (fresh cache, serial)."""
        with tempfile.TemporaryDirectory(prefix="rbbench-asv-") as d:
            _snapshots(self.scene, replace(self.cfg, cache_dir=d), self.mus)


class PrimalPOD(_Stage):
    """Primal POD of the training displacements in the X inner product (stage 2).

    The registered ``primal`` plugin ``pod`` (:func:`rbbench.rb.algorithms.pod.pod`) with the CLI
    default tolerance 1e-4. Unit: seconds.
    """

    params = (RB_CASES,)
    param_names = ["scene"]

    def setup(self, data, case):
        super().setup(data, case)
        self.primal = self.registry.create("primal", "pod")

    def time_primal_pod(self, data, case):
        """Wall time (s) of the POD (X-weighted snapshot correlation + eigenproblem)."""
        cfg = self.cfg
        self.primal(self.data["U"], self.X, tol=None if cfg.N else cfg.tol_pod, n=cfg.N)


class DualCompressor(_Stage):
    """Dual cone from the training multipliers (stage 3), for cpg / mcpg / eng.

    The registered ``dual`` plugin called as in ``reduce()``:
    ``(LAM, W(mu_default), tol=1e-3, r_max=R)``. Unit: seconds.
    """

    params = (RB_CASES, DUALS)
    param_names = ["scene", "dual"]

    def setup(self, data, case, dual):
        super().setup(data, case)
        self.dual = self.registry.create("dual", dual)

    def time_dual_compressor(self, data, case, dual):
        """Wall time (s) of the greedy cone construction (all generators)."""
        self.dual(self.data["LAM"], self.W_ref, tol=self.opts.tol_dual, r_max=self.opts.R)


class PGA(_Stage):
    """Stabiliser stage of ``reduce()`` with the default ``pga`` plugin (stage 4).

    Timed: the default tolerance (the rule of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model
    order reduction methods: parametric variational inequalities" (talk), slide "Projected
    Greedy Algorithm (PGA)": ``pga_default_delta`` over every fifth training mu) and the
    plugin's ``offline``: the supremizers ``X^-1 B(mu)^T Vg`` at
    every training mu and the greedy :func:`rbbench.rb.algorithms.pga.pga`. Not timed (setup): the
    HF operators at the training mus, the factorisation of X, the POD and mCPG bases.
    Unit: seconds.
    """

    params = (RB_CASES,)
    param_names = ["scene"]

    def setup(self, data, case):
        super().setup(data, case)
        self.problems = [self.problem_at(mu) for mu in self.data["mus"]]
        self.Z, self.Vg = self.bases()
        self.stabilizer = make_stabilizer(self.registry, self.opts)

    def time_pga(self, data, case):
        """Wall time (s) of default delta + supremizers + PGA greedy."""
        self.stabilise(self.stabilizer, self.Z, self.Vg, self.problems)


class EIM(_Stage):
    """Contact EIM of ``B(mu) Z_off`` and ``G(mu)`` on coarse Hertz (hyper ``eim``).

    The EIM training set is the one of ``reduce()``: the training mus plus a uniform
    grid of ``4 (n_train - 1) + 1`` points of D. Two parts, timed apart:
    ``time_eim_operators``, the contact operators ``B(mu)``, ``G(mu)`` on that set
    (:func:`rbbench.hf.geometry.operators.contact_operators`, no HF solve);
    ``time_eim_build``, the greedy EIMs and the magic-row evaluator
    (:func:`rbbench.rb.hyper.contact_eim.contact_eim`, tolerance 1e-4). Unit: seconds.
    """

    def setup(self, data):
        super().setup(data, "hertz_coarse")
        self.layout = self.backend.contact_layout()
        mus = self.data["mus"]
        self.mus_eim = eim_training_set(self.scene, self.opts, mus)
        self.free = self.problem_at(mus[0]).free
        self.B_eim, G = self._operators()
        self.G_eim = np.stack(G, axis=1)

    def _operators(self):
        B, G = [], []
        for mu in self.mus_eim:
            c = contact_operators(self.layout, mu)
            B.append(c.B()[:, self.free])
            G.append(c.G())
        return B, G

    def time_eim_operators(self, data):
        """Wall time (s) of B(mu), G(mu) at every EIM training parameter."""
        self._operators()

    def time_eim_build(self, data):
        """Wall time (s) of the contact EIM construction (greedy EIMs + row evaluator)."""
        contact_eim(self.layout, self.B_eim, self.G_eim, self.data["Z_off"], self.data["Vg"],
                    self.free, self.mus_eim, tol=self.opts.tol_eim, m_max=self.opts.m_eim)
