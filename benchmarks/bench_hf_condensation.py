"""asv and a side-by-side run: the condensation of the HF contact solve against its floor.

``hertz_halfdisks`` at mu = 1 on the default mesh refined ``level``
times; the contact problem is built once per level (assembly excluded) and each timed call
is one ``ssn`` solve (condensation, PDAS, recovery of u) with one BLAS thread:

* ``columns``: today's dense ``A^{-1} B^T`` (:func:`rbbench.hf.condensation.dense.condense`),
SuperLU;
* ``superlu`` / ``pardiso``: ``D`` as the Schur complement of the KKT matrix
  (:func:`rbbench.hf.condensation.schur.condense_schur`);
* the floor: one SuperLU factorisation + one solve of the same stiffness
  (:func:`rbbench.hf.model.solve_floor`).

Side by side (medians of wall and thread CPU time over interleaved repeats, ratios to the floor of
the same run, the difference of u to the columns path on raw values, the memory of one
solve in a fresh process)::

    python -m benchmarks.bench_hf_condensation --levels 0 1 2 --repeats 5 --memory 1
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

import numpy as np

from ._common import TIMEOUT, finite

#: the timed variants: name -> ssn solver options
VARIANTS: dict[str, dict] = {
    "columns": {"condensation": "columns", "linear_solver": "superlu"},
    "superlu": {"condensation": "schur", "linear_solver": "superlu"},
    "pardiso": {"condensation": "schur", "linear_solver": "pardiso"},
}


def contact_problem(level: int):
    """The frictionless mixed contact problem of ``hertz_halfdisks`` at ``level``, mu = 1."""
    from rbbench.hf.components import discretize_for, make_components
    from rbbench.scene.loading import load_scene

    sc = load_scene("hertz_halfdisks", [f"discretization.level={level}"])
    b, f, _ = make_components(sc)
    return f.build(discretize_for(b, f, sc.default_mu))


def _variants() -> list[str]:
    from rbbench.hf.condensation.pardiso import available

    return [v for v in VARIANTS if v != "pardiso" or available()]


def _timed(f):
    """``(wall s, CPU s of this thread, f())`` with one BLAS thread (the CPU time is less
    sensitive to other processes on a shared machine)."""
    from rbbench.runtime.threads import one_blas_thread

    with one_blas_thread():
        t0, c0 = time.perf_counter(), time.thread_time()
        out = f()
        return time.perf_counter() - t0, time.thread_time() - c0, out


def measure_variant(problem, name: str):
    """``(wall s, CPU s, SolveResult)`` of one ``ssn`` solve with the options of ``name``."""
    from rbbench.registry import default_registry

    solver = default_registry().create("solver", "ssn", **VARIANTS[name])
    return _timed(lambda: solver.solve(problem))


def measure_floor(problem, linear_solver: str | None = None) -> tuple[float, float, None]:
    """One factorisation + one solve of the stiffness, SuperLU (default) or ``"pardiso"``
    (:func:`rbbench.hf.model.solve_floor`, as ``rbbench solve``'s ``floor_s``)."""
    from rbbench.hf.model import solve_floor

    w, c, _ = _timed(lambda: solve_floor(problem, linear_solver))
    return w, c, None


def side_by_side(level: int, repeats: int, columns_repeats: int) -> dict:
    """Medians (wall and CPU) of the floors and of every variant, interleaved; u of every
    variant against ``columns`` (raw values, relative to max |u|)."""
    problem = contact_problem(level)
    names = _variants()
    runs = {"floor": measure_floor,
            **({"floor_pardiso": lambda p: measure_floor(p, "pardiso")}
               if "pardiso" in names else {}),
            **{k: (lambda p, k=k: measure_variant(p, k)) for k in names}}
    wall: dict[str, list[float]] = {k: [] for k in runs}
    cpu: dict[str, list[float]] = {k: [] for k in runs}
    u: dict[str, np.ndarray] = {}
    for r in range(repeats):
        for name, run in runs.items():
            if name == "columns" and r >= columns_repeats:
                continue
            w, c, res = run(problem)
            if res is not None:
                if not res.converged:
                    raise RuntimeError(f"level {level} {name}: {res.stop_reason}")
                u[name] = res.u
            wall[name].append(w)
            cpu[name].append(c)
    med = {k: float(np.median(v)) for k, v in wall.items()}
    med_cpu = {k: float(np.median(v)) for k, v in cpu.items()}
    scale = float(np.abs(u["columns"]).max())
    return {"level": level, "n_dofs": int(problem.A.shape[0]),
            "n_mult": int(problem.B.shape[0]), "median_s": med, "median_cpu_s": med_cpu,
            "over_floor": {k: med[k] / med["floor"] for k in names},
            "cpu_over_floor": {k: med_cpu[k] / med_cpu["floor"] for k in names},
            "u_rel_diff": {k: float(np.abs(u[k] - u["columns"]).max() / scale) for k in names},
            "samples": {k: len(v) for k, v in wall.items()}}


#: run in a fresh process: the peak RSS of one solve above the RSS before it (Linux: the
#: peak is reset through /proc/self/clear_refs, so the assembly's peak does not hide it)
_MEMORY_CODE = """
import gc, json, resource, sys
from benchmarks.bench_hf_condensation import contact_problem, measure_variant
def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) / 1024
p = contact_problem({level}); gc.collect()
peak_all = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
open("/proc/self/clear_refs", "w").write("5")
before = status("VmRSS:")
measure_variant(p, {name!r})
print(json.dumps([peak_all, before, status("VmHWM:")]))
"""


def peak_memory(level: int, name: str) -> dict:
    """Memory (MB) of one solve with ``name`` in a fresh process: ``rss_before`` (the
    problem built), ``solve_peak`` (peak RSS during the solve), ``solve_increment`` (their
    difference) and ``process_peak_before`` (the peak of meshing and assembly)."""
    out = subprocess.run([sys.executable, "-c", _MEMORY_CODE.format(level=level, name=name)],
                         capture_output=True, text=True, check=True)
    peak_all, before, peak = json.loads(out.stdout.strip().splitlines()[-1])
    return {"process_peak_before_mb": peak_all, "rss_before_mb": before,
            "solve_peak_mb": peak, "solve_increment_mb": peak - before}


def main(argv: list[str] | None = None) -> int:
    """Print the side-by-side table (and JSON with ``--json``)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--columns-repeats", type=int, default=3)
    ap.add_argument("--memory", type=int, nargs="*", default=[], help="levels to measure")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    rows = []
    for level in args.levels:
        row = side_by_side(level, args.repeats, args.columns_repeats)
        if level in args.memory:
            row["memory"] = {k: peak_memory(level, k) for k in _variants()}
        rows.append(row)
        print(json.dumps(row), flush=True)
    print("| level | dofs | mult | floor SuperLU (s) | floor PARDISO (s) | " + " | ".join(
        f"{k} (s) / floor (CPU ratio)" for k in _variants()) + " |")
    for r in rows:
        cells = " | ".join(f"{r['median_s'][k]:.3f} / {r['over_floor'][k]:.2f}x "
                           f"({r['cpu_over_floor'][k]:.2f}x)" for k in _variants())
        fp = r["median_s"].get("floor_pardiso", float("nan"))
        print(f"| {r['level']} | {r['n_dofs']} | {r['n_mult']} | {r['median_s']['floor']:.3f}"
              f" | {fp:.3f} | {cells} |")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0


class HFCondensation:
    """The ``ssn`` solve of ``hertz_halfdisks`` per level and condensation against the floor
    timed in the same process (``setup_cache``, medians of 3): ``track_over_floor`` is the
    solve's median over the floor's (goal <= 1.5), ``time_solve`` the solve itself.
    ``columns`` (today's dense ``A^{-1} B^T``) is left out at level 2 (~30x the floor)."""

    params = (["0", "1", "2"], ["superlu", "pardiso", "columns"])
    param_names = ["level", "condensation"]
    timeout = 2 * TIMEOUT
    number = 1
    repeat = (1, 3, 60.0)

    def setup_cache(self):
        out = {}
        for level in self.params[0]:
            problem = contact_problem(int(level))
            for name in _variants():
                if name == "columns" and level == "2":
                    continue
                t = [measure_variant(problem, name)[0] for _ in range(3)]
                f = [measure_floor(problem)[0] for _ in range(3)]
                out[(level, name)] = float(np.median(t) / np.median(f))
        return out

    setup_cache.timeout = 4 * TIMEOUT

    def setup(self, cache, level, condensation):
        if (level, condensation) not in cache:
            raise NotImplementedError  # asv: skipped (no PARDISO, or columns at level 2)
        self.problem = contact_problem(int(level))

    def time_solve(self, cache, level, condensation):
        """One ``ssn`` solve (s): condensation, PDAS, u; assembly excluded."""
        measure_variant(self.problem, condensation)

    def track_over_floor(self, cache, level, condensation):
        """Median solve / median floor (one factorisation + one solve), same process."""
        return finite(cache[(level, condensation)], "solve over floor")

    track_over_floor.unit = "ratio"


if __name__ == "__main__":
    sys.exit(main())
