"""Built-in rbbench plugins, registered through the ``rbbench`` entry point.

Declarations only: nothing heavy is imported here. Each target module is imported when a run
uses it. "Benaceur et al." in the descriptions: Benaceur, Drouet, Ehrlacher, Ern & Niakh,
"Model order reduction methods: parametric variational inequalities" (talk).
"""

from rbbench.hookspecs import hookimpl
from rbbench.registry import ComponentSpec

_ALL_PHYSICS = ("elasticity", "poisson")
#: The linear scenes: assembled by each backend's ``linear_target``, no contact.
_LINEAR_PHYSICS = ("thermal", "heat")
_COMP = "rbbench.rb.compressors"

#: Dual compressors: (name, class, is a cone, nested in R, modules, description).
_DUALS = (
    ("pod", "PODLam", False, True, (),
     "POD of the multipliers: a linear span, NOT a cone (baseline: positivity lost)"),
    ("cpg", "CPG", True, True, (),
     "Cone Projected Greedy: normalised selected snapshots (Benaceur et al., CPG algorithm)"),
    ("mcpg", "MCPG", True, True, ("daqp",),
     "modified CPG: generators peeled of the previous cone by a QP (Benaceur et al., mCPG)"),
    ("eng", "ENG", True, True, ("daqp",),
     "Enlarged Nonnegative Greedy (our design): mCPG peeling of every generator"),
    ("nnmf", "NNMF", True, False, (),
     "non-negative matrix factorisation (HALS) baseline, refitted per rank"),
)

#: Hyper-reducers: (name, class, formulations, description).
_HYPERS = (
    ("affine", "ExactAffine", ("mixed",),
     "exact affine decomposition of the reduced operators, verified by probing"),
    ("eim", "ContactRowEIM", ("mixed", "nitsche"),
     "EIM of the contact rows B(mu) Z, G(mu) (mixed); DEIM of the point terms (Nitsche)"),
    ("ecsw", "ECSW", ("nitsche",),
     "empirical cubature at the contact points, sparse NNLS weights (Nitsche default)"),
    ("deim", "DEIM", ("nitsche",), "DEIM of the Nitsche contact point contributions"),
    ("none", "NoHyper", ("mixed", "nitsche"),
     "plain: HF operators at mu projected online (online cost grows with the HF size)"),
)


@hookimpl
def rbbench_register(registry):
    for declare in (_backends, _formulations, _solvers, _executors, _compressors, _hypers,
                    _stabilizers):
        declare(registry.add)


def _backends(add):
    """Declare the built-in HF backends."""
    add(ComponentSpec(
        name="skfem", role="backend",
        target="rbbench_plugins.backends.skfem.backend:SkfemBackend",
        modules=("skfem",),
        capabilities={"physics": _ALL_PHYSICS, "degree": (1, 2),
                      "multiplier": ("lac", "p0", "p1", "nodal"),
                      "friction": ("none", "tresca", "coulomb"),
                      "linear_physics": _LINEAR_PHYSICS,
                      "linear_target": "rbbench_plugins.backends.skfem.linear:SkfemLinearBackend",
                      "geometry": ("halfdisks", "hemispheres", "unit_square")},
        description="scikit-fem: graded triangle meshes, P1/P2, GPTS contact pairing; 3D "
                    "hemispheres (tetrahedra, frictionless mixed or Nitsche); linear scenes "
                    "(thermal, heat): unit square, no contact",
    ))
    add(ComponentSpec(
        name="ngsolve", role="backend",
        target="rbbench_plugins.backends.ngsolve.backend:NGSolveBackend",
        extras=("ngsolve",), modules=("ngsolve",),
        capabilities={"physics": _ALL_PHYSICS, "degree": (1, 2),
                      "multiplier": ("lac", "p0", "p1", "nodal"),
                      "friction": ("none", "tresca", "coulomb"),
                      "linear_physics": _LINEAR_PHYSICS,
                      "linear_target":
                          "rbbench_plugins.backends.ngsolve.linear:NGSolveLinearBackend",
                      "geometry": ("halfdisks", "hemispheres", "unit_square")},
        description="NGSolve: Netgen meshes (or arrays), P1/P2, sparse Cholesky, "
                    "GPTS contact pairing; 3D hemispheres (P1/P2, frictionless mixed or "
                    "Nitsche); linear scenes (P1, the scikit-fem mesh)",
    ))


def _formulations(add):
    """Declare the built-in formulations."""
    add(ComponentSpec(
        name="mixed", role="formulation",
        target="rbbench_plugins.formulations.mixed:MixedFormulation",
        capabilities={"physics": _ALL_PHYSICS, "friction": ("none", "tresca", "coulomb"),
                      "solvers": ("ssn", "uzawa", "friction-ssn", "friction-uzawa",
                                  "petsc-vi", "petsc-tao")},
        description="Lagrange multipliers: A u + B^T lam = F, 0 <= lam _|_ G - B u >= 0; "
                    "friction: P1 nodal (lam_n, lam_t), Tresca box / Coulomb wedge",
    ))
    add(ComponentSpec(
        name="linear", role="formulation",
        target="rbbench_plugins.formulations.linear:LinearFormulation",
        capabilities={"physics": _LINEAR_PHYSICS, "roles": ("backend", "primal", "hyper")},
        description="linear elliptic / parabolic (implicit Euler), no constraint: no contact "
                    "operator, dual or stabiliser; POD / POD-greedy, exact affine, "
                    "residual error bound",
    ))
    add(ComponentSpec(
        name="nitsche", role="formulation",
        target="rbbench_plugins.formulations.nitsche:NitscheFormulation",
        capabilities={"physics": ("elasticity",), "solvers": ("newton",),
                      "needs": ("stress",), "friction": ("none", "tresca", "coulomb"),
                      "roles": ("backend", "solver", "primal", "hyper")},
        description="Nitsche (Alart-Curnier, theta = 1 / 0 / -1, gamma = gamma0 E / h): "
                    "unconstrained, from the contact evaluation matrices Un, Snn; friction: "
                    "Chouly-Hild-Renard [sigma_nt - gamma u_t]_S with Ut, Snt",
    ))


def _solvers(add):
    """Declare the built-in algebraic VI solvers."""
    add(ComponentSpec(
        name="newton", role="solver",
        target="rbbench_plugins.solvers.newton:NewtonSolver",
        capabilities={"formulations": ("nitsche",), "friction": ("none", "tresca", "coulomb")},
        description="generalised Newton (Heaviside tangent) with a line search, for Nitsche; "
                    "friction (Tresca, Coulomb, model B) over the load steps",
    ))
    add(ComponentSpec(
        name="ssn", role="solver",
        target="rbbench_plugins.solvers.condensed:SemismoothNewtonSolver",
        capabilities={"formulations": ("mixed",)},
        description="primal-dual active set (semismooth Newton) on the condensed contact LCP",
    ))
    add(ComponentSpec(
        name="uzawa", role="solver",
        target="rbbench_plugins.solvers.condensed:UzawaSolver",
        capabilities={"formulations": ("mixed",)},
        description="Uzawa projected dual iteration (Benaceur et al.'s baseline), condensed",
    ))
    add(ComponentSpec(
        name="friction-ssn", role="solver",
        target="rbbench_plugins.solvers.friction:FrictionSSNSolver",
        capabilities={"formulations": ("mixed",), "friction": ("none", "tresca", "coulomb")},
        description="friction by active set on the condensed nodal problem: Tresca PDAS, "
                    "Coulomb direct on the wedge (method='fixed_point': Benaceur et al.'s "
                    "fixed point on Tresca), model B fixed point on the coefficient; load steps",
    ))
    add(ComponentSpec(
        name="friction-uzawa", role="solver",
        target="rbbench_plugins.solvers.friction:FrictionUzawaSolver",
        capabilities={"formulations": ("mixed",), "friction": ("none", "tresca", "coulomb")},
        description="Benaceur et al.'s Uzawa for friction (normal then tangential projection), "
                    "condensed, over the load steps (baseline)",
    ))
    add(ComponentSpec(
        name="petsc-vi", role="solver",
        target="rbbench_plugins.solvers.petsc:PetscVISolver",
        extras=("petsc",), modules=("petsc4py",),
        capabilities={"formulations": ("mixed",), "friction": ("none", "tresca", "coulomb")},
        description="PETSc SNES VI (vinewtonrsls, reduced-space active set) on the "
                    "sparse KKT system as a mixed complementarity problem; friction: Tresca "
                    "box QP by SNES VI, Coulomb / model B by the fixed point on it",
    ))
    add(ComponentSpec(
        name="petsc-tao", role="solver",
        target="rbbench_plugins.solvers.petsc:PetscTaoSolver",
        extras=("petsc",), modules=("petsc4py",),
        capabilities={"formulations": ("mixed",), "friction": ("none", "tresca", "coulomb")},
        description="PETSc TAO bound-constrained QP (tron) on the condensed dual problem; "
                    "friction: Tresca box QP by TAO tron, Coulomb / model B by the fixed "
                    "point on it",
    ))


def _executors(add):
    """Declare the built-in executors: where the cases of a run matrix run."""
    # executors: where the cases of a run matrix run
    add(ComponentSpec(
        name="serial", role="executor", target="rbbench_plugins.executors:SerialExecutor",
        capabilities={"isolation": False, "timeout": "sigalrm"},
        description="one case after the other in this process (debugging)",
    ))
    add(ComponentSpec(
        name="processes", role="executor", target="rbbench_plugins.executors:ProcessExecutor",
        capabilities={"isolation": True, "timeout": "kill"},
        description="local processes, one per case, jobs at a time",
    ))
    add(ComponentSpec(
        name="dask", role="executor", target="rbbench_plugins.executors:DaskExecutor",
        extras=("dask",), modules=("dask", "distributed"),
        capabilities={"isolation": True, "timeout": "kill"},
        description="Dask distributed: a LocalCluster, or a scheduler address for a cluster",
    ))


def _compressors(add):
    """Declare the built-in primal and dual compressors."""
    # primal compressors: V_N from displacement snapshots
    add(ComponentSpec(
        name="pod", role="primal", target=f"{_COMP}:PODPrimal",
        capabilities={"tol": "energy", "nested": True},
        description="POD in the X inner product, energy tolerance (Benaceur et al., Method 1)",
    ))
    add(ComponentSpec(
        name="greedy", role="primal", target=f"{_COMP}:GreedyPrimal",
        capabilities={"tol": "max", "nested": True},
        description="ideal greedy on the training snapshots (true projection error), "
                    "max tolerance (Benaceur et al., Method 2)",
    ))
    # dual compressors: W_R+ from multiplier snapshots
    for name, cls, cone, nested, modules, text in _DUALS:
        add(ComponentSpec(
            name=name, role="dual", target=f"{_COMP}:{cls}", modules=modules,
            capabilities={"cone": cone, "nested": nested}, description=text,
        ))


def _hypers(add):
    """Declare the built-in hyper-reducers."""
    # hyper-reducers: HF-size independent online stage (declarations; the formulation's
    # offline steps carry them out)
    for name, cls, forms, text in _HYPERS:
        add(ComponentSpec(
            name=name, role="hyper", target=f"rbbench.rb.hyper.reducers:{cls}",
            capabilities={"formulations": forms}, description=text,
        ))


def _stabilizers(add):
    """Declare the built-in stabilisers."""
    # stabilisers: inf-sup stable primal space over the reduced cone
    add(ComponentSpec(
        name="none", role="stabilizer", target=f"{_COMP}:NoStabilizer",
        capabilities={"online_hf": False, "inf_sup": "not guaranteed"},
        description="decorrelated V_N x W_R+: beta_dec may vanish",
    ))
    add(ComponentSpec(
        name="supremizer", role="stabilizer", target=f"{_COMP}:SupremizerStabilizer",
        capabilities={"online_hf": True, "inf_sup": "every mu"},
        description="online supremizers V_N + S_R(mu): needs the HF B(mu) online",
    ))
    add(ComponentSpec(
        name="pga", role="stabilizer", target=f"{_COMP}:PGAStabilizer",
        capabilities={"online_hf": False, "inf_sup": "training set"},
        description="Projected Greedy Algorithm: V_N + S_R^red built offline (Benaceur et al.)",
    ))
