"""Settings shared by the asv suites: the cases, and how each is loaded and reduced.

Every suite goes through the entry points of the CLI (``rbbench solve``:
:func:`rbbench.hf.model.solve_hf`; ``rbbench reduce``: :func:`rbbench.rb.offline.reduce`
and the stage functions it calls) on small settings, so that ``asv run --quick``
takes a few minutes on two cores.

Cases (the ``scene`` parameter of the suites):

* ``membrane_obstacle``: the scene as shipped (289 dofs, 225 multipliers, 2 parameters);
* ``hertz_coarse``: ``hertz_halfdisks`` with :data:`rbbench.testing.HERTZ_COARSE`
  (the contract suite's coarse mesh: 8888 dofs, 64 multipliers);
* ``hertz_default``: ``hertz_halfdisks`` on its default mesh (36910 dofs; HF solve only);
* ``friction_p1_h04``, ``friction_p1_h02``: ``hertz_friction`` at P1 on two coarse meshes
  (the friction online suite: the wedge model hyper-reduced by its EIM);
* ``sphere_l0``, ``sphere_l1``: ``hertz_sphere`` at mesh levels 0 and 1 (the 3D online
  suite: the contact EIM on triangulated surfaces).

This module holds no benchmark (no ``time_`` / ``track_`` / ``peakmem_`` names).
"""

from __future__ import annotations

import math

from rbbench.scene.loading import Scene, load_scene
from rbbench.testing import HERTZ_COARSE

#: case -> (scene name, overrides as for ``rbbench ... --set``)
CASES: dict[str, tuple[str, tuple[str, ...]]] = {
    "membrane_obstacle": ("membrane_obstacle", ()),
    "hertz_coarse": ("hertz_halfdisks", tuple(HERTZ_COARSE)),
    "hertz_default": ("hertz_halfdisks", ()),
    "friction_p1_h04": ("hertz_friction", ("discretization.degree=1",
                                           "discretization.h_contact=0.04",
                                           "discretization.h_max=0.4")),
    "friction_p1_h02": ("hertz_friction", ("discretization.degree=1",
                                           "discretization.h_contact=0.02",
                                           "discretization.h_max=0.25")),
    "sphere_l0": ("hertz_sphere", ("discretization.level=0",)),
    "sphere_l1": ("hertz_sphere", ("discretization.level=1",)),
}

#: the cases of the reduced-basis suites (small training / validation sets)
RB_CASES = ["membrane_obstacle", "hertz_coarse"]

#: ``rbbench reduce`` options per RB case; everything else is the CLI default
#: (POD, mCPG, PGA, hyper auto: exact-affine on the membrane, EIM on Hertz).
RB_OPTIONS: dict[str, dict] = {
    "membrane_obstacle": {"n_train": 16, "n_valid": 5},  # 4 x 4 training grid
    "hertz_coarse": {"n_train": 11, "n_valid": 5},
    **{case: {"n_train": 5, "n_valid": 2, "N": 8, "R": 4, "S": 4, "k_pga_max": 6,
              "hyper": "eim", "friction_dual": "wedge"}
       for case in ("friction_p1_h04", "friction_p1_h02")},
    **{case: {"n_train": 11, "n_valid": 2, "N": 20, "R": 20, "hyper": "eim"}
       for case in ("sphere_l0", "sphere_l1")},
}

#: the 3D cases of the online suite: hertz_sphere (two hemispheres, the contact EIM on
#: triangulated surfaces) at mesh levels 0 and 1 (5,352 and 31,764 dofs)
SPHERE_CASES = ["sphere_l0", "sphere_l1"]

#: the friction cases of the online suite: hertz_friction, P1, two contact mesh sizes
#: (h_contact 0.04 and 0.02: 65 and 129 contact nodes), the wedge model with its EIM
FRICTION_CASES = ["friction_p1_h04", "friction_p1_h02"]

#: Timeout (s) of one benchmark and of a setup_cache; generous against a loaded machine.
TIMEOUT = 300.0


def scene(case: str) -> Scene:
    """The scene of ``case``, overrides applied (validated as ``rbbench`` does)."""
    name, overrides = CASES[case]
    return load_scene(name, overrides=list(overrides))


def reduce_config(case: str, cache_dir: str | None = None, **changes):
    """The :class:`~rbbench.rb.config.ReduceConfig` of ``case``, resolved for its scene.

    Snapshots in ``cache_dir`` (give a temporary directory whenever snapshots are
    computed) and in this process (``n_jobs = 1``: no process pool inside a benchmark);
    ``changes`` override any field (the tests use tiny sets).
    """
    from rbbench.rb.config import make_config
    from rbbench.rb.offline import prepare_config
    from rbbench.registry import default_registry

    opts = {"n_jobs": 1, "online_repeats": 3, **RB_OPTIONS[case]}
    if cache_dir is not None:
        opts["cache_dir"] = str(cache_dir)
    # resolved as reduce() resolves it (formulation, solver and options from the scene), so
    # the stage suites call the stage functions with the names reduce() would give them
    return prepare_config(scene(case), make_config(**{**opts, **changes}),
                          default_registry())[1]


def reduced_case(case: str, cache_dir: str, **changes) -> dict:
    """Run ``rbbench reduce`` on ``case``; keep what the online suites need (picklable).

    Returns ``{"model": ReducedModel, "mu": default mu, "summary": {...}}`` where
    ``summary`` holds the scalar results of :meth:`ReduceResult.summary`; the model without
    its reconstruction basis (HF size, used by ``reconstruct`` only: the online solves and
    their memory are measured without it).
    """
    from rbbench.rb.offline import reduce

    sc = scene(case)
    res = reduce(sc, reduce_config(case, cache_dir, **changes))
    if res.hyper == "none":
        raise RuntimeError(f"{case}: reduce() built no hyper-reduced model (hyper 'none')")
    res.model.basis = None
    summary = {k: v for k, v in res.summary().items()
               if v is None or isinstance(v, (int, float, str, bool))}
    return {"model": res.model, "mu": sc.default_mu, "summary": summary}


def online_median_s(model, mu, repeats: int, method: str, case: str) -> float:
    """Median (s) of ``repeats`` online solves of ``model`` at ``mu``
    (:func:`rbbench.rb.online.timed_online_solves`, protocol ``ONLINE_PROTOCOL``); raise
    (a failing benchmark) when a solve did not converge."""
    from rbbench.rb.online import timed_online_solves

    run = timed_online_solves(model, [mu], repeats, method=method)
    bad = {s.stop_reason for sols in run.per_mu for s in sols} - {"converged"}
    if bad:
        raise RuntimeError(f"{case}: online solve stopped: {sorted(bad)}")
    return run.summary()["t_online_median_s"]


def finite(value, what: str) -> float:
    """``float(value)``, or raise (a failing benchmark) when it is None or not finite."""
    if value is None or not math.isfinite(float(value)):
        raise ValueError(f"{what} is {value!r}: not a finite number")
    return float(value)


