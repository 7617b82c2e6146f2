"""asv: the reduced-basis-driven shape optimisation of ``shape_coulomb`` on a small body mesh.

:func:`rbbench.optim.rb_driver.optimize_rb` (the trust region of reduced models behind
``rbbench optimize shape_coulomb --driver rb --strategy none``) from the scene's initial
design on :data:`SHAPE_CASES`: model B with its 81 contact nodes (the design) and a body
of ``geometry.ny`` element rows (10: 1,782 dofs; the shipped 40: 6,642 dofs), and one
reduced evaluation (state + subgradient) at the initial design with the interior space
of the HF factors there. One BLAS thread (the study ``rbbench studies shape-side-by-side``
measures the HF-driven run beside it).

Side by side, the cost of each part of the two drivers on several body meshes (medians of
wall and thread CPU time over ``--repeats``, one BLAS thread, in one process)::

    python -m benchmarks.bench_shape_optimisation --ny 40 160 640 --repeats 3
"""

import argparse
import copy
import json
import sys
import time
from statistics import median

import numpy as np

from rbbench.optim.rb_driver import RBOptions, optimize_rb
from rbbench.optim.shape_adjoint import evaluate
from rbbench.optim.shape_reduced import (
    ReducedModel,
    hf_snapshots,
    interior_space,
    state_vector,
)
from rbbench.optim.shape_scene import load_shape_scene
from rbbench.runtime.threads import one_blas_thread

from ._common import TIMEOUT

#: body meshes of the suite: ``geometry.ny`` (element rows), the contact nodes kept
SHAPE_CASES = ["ny10", "ny40"]


def shape_scene(case: str):
    """The ``shape_coulomb`` scene of ``case`` (``ny<rows>``)."""
    return load_shape_scene("shape_coulomb", {"geometry.ny": int(case.removeprefix("ny"))})


class ShapeRBDriver:
    """The RB-driven optimisation from the initial design (``RBOptions()`` defaults: the
    HF state and adjoint added to the basis at each new centre); the HF solves it needs
    and its ``J`` relative to the uniform-pressure bound are tracked beside the time."""

    params = (SHAPE_CASES,)
    param_names = ["mesh"]
    timeout = TIMEOUT
    number = 1
    repeat = (1, 3, 60.0)

    def setup(self, mesh):
        self.sc = shape_scene(mesh)
        self.alpha0 = self.sc.initial_design()
        self._result = None

    def _run(self):
        with one_blas_thread():
            return optimize_rb(self.sc, self.alpha0, RBOptions())

    def _tracked(self):
        """The run the ``track_`` benchmarks read (one run per setup)."""
        if self._result is None:
            self._result = self._run()
        return self._result

    def time_rb_driven_optimisation(self, mesh):
        """Wall time (s) of one RB-driven run (HF centres, reduced bundle runs, updates)."""
        self._run()

    def track_hf_solves(self, mesh):
        """HF state solves of the RB-driven run (the start included)."""
        return float(self._tracked().hf_solves)

    track_hf_solves.unit = "solves"

    def track_J_over_bound(self, mesh):
        """HF-verified J at the RB optimum over the uniform-pressure bound (>= 1)."""
        return float(self._tracked().J_hf / self.sc.uniform_pressure_bound())

    track_J_over_bound.unit = "ratio"


class ShapeReducedEvaluation:
    """One reduced evaluation (state by the semismooth Newton on the reduced Schur
    complement, objective, subgradient) at the initial design, warm-started from the HF
    state there, with the interior space of the HF factors at that design (N = 162)."""

    params = (SHAPE_CASES,)
    param_names = ["mesh"]
    timeout = TIMEOUT

    def setup(self, mesh):
        sc = shape_scene(mesh)
        self.alpha = sc.initial_design()
        with one_blas_thread():
            ev = evaluate(sc, self.alpha)
            self.model = ReducedModel(sc)
            self.model.enrich(interior_space(sc, ev.state))
        self.y0 = state_vector(ev.state)

    def time_reduced_evaluation(self, mesh):
        """Wall time (s) of one reduced state + subgradient evaluation, one BLAS thread."""
        with one_blas_thread():
            self.model.evaluate(self.alpha, y0=self.y0)


def _timed(fun, *args, **kwargs):
    """``(result, wall s, thread CPU s)`` of ``fun(*args, **kwargs)``."""
    w, c = time.perf_counter(), time.thread_time()
    out = fun(*args, **kwargs)
    return out, time.perf_counter() - w, time.thread_time() - c


def _update(sc, model, state):
    """The RB driver's incremental update at a new centre (HF state and adjoint added)."""
    return model.enrich(hf_snapshots(sc, state))


def _rebuild(sc, model, state):
    """The former update: the basis replaced by the interior space of the centre."""
    return model.enrich(interior_space(sc, state), reset=True)


def part_costs(ny: int, repeats: int) -> dict:
    """Medians (wall, CPU) of the parts of one optimisation step on the body mesh ``ny``:
    the HF evaluation (state + subgradient), the interior space (HF factors), the reduced
    model's projection of it, one reduced evaluation near the centre, the incremental
    update at a new centre (adjoint, extension, two new columns) and the rebuild
    (interior space + projection)."""
    sc = shape_scene(f"ny{ny}")
    a0 = sc.initial_design()
    a1 = a0 + 0.002 * np.random.default_rng(0).standard_normal(a0.size) * (a0 > 0.01)
    rows: dict[str, list] = {}

    def add(name, fun, *args, **kwargs):
        out, w, c = _timed(fun, *args, **kwargs)
        rows.setdefault(name, []).append((w, c))
        return out

    with one_blas_thread():
        for _ in range(repeats):
            ev = add("HF evaluation", evaluate, sc, a0)
            vs = add("interior space", interior_space, sc, ev.state)
            model = ReducedModel(sc)
            add("projection of the interior space", model.enrich, vs)
            y0 = state_vector(ev.state)
            model.evaluate(a1, y0=y0, reconstruct=False)           # warm-up
            for _ in range(5):
                add("reduced evaluation", model.evaluate, a1, y0=y0, reconstruct=False)
            other = copy.deepcopy(model)
            add("incremental update (state + adjoint)", _update, sc, other, ev.state)
            add("rebuild (interior space + projection)", _rebuild, sc, ReducedModel(sc),
                ev.state)
    return {"ny": ny, "dofs": 2 * sc.grid.n_nodes, "N": model.N,
            "parts": {k: {"wall_s": median(w for w, _ in v), "cpu_s": median(c for _, c in v),
                          "samples": len(v)} for k, v in rows.items()}}


def main(argv: list[str] | None = None) -> int:
    """Print the table of :func:`part_costs` per mesh (and JSON with ``--json``)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ny", type=int, nargs="+", default=[40, 160, 640])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    out = []
    for ny in args.ny:
        r = part_costs(ny, args.repeats)
        out.append(r)
        print(f"ny {r['ny']} ({r['dofs']} dofs, N = {r['N']}), medians, one BLAS thread")
        for name, v in r["parts"].items():
            print(f"  {name:<40} wall {v['wall_s']:8.3f} s  CPU {v['cpu_s']:8.3f} s  "
                  f"({v['samples']} samples)", flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
