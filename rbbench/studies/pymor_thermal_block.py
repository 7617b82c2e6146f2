"""rbbench and pyMOR side by side on pyMOR's thermal block (``rbbench studies
pymor-thermal-block``).

The problem of :func:`pymor.analyticalproblems.thermalblock.thermal_block_problem`:
``-div(kappa grad u) = 1`` on the unit square, ``u = 0`` on the boundary, ``kappa = mu_i``
on block ``i`` of a ``b x b`` grid, ``mu_i in [0.1, 1]`` (rbbench: the scene
``thermal_block``, the same numbering of the blocks). Both tools get the same mesh size,
the largest element diameter ``sqrt(2) / n`` (rbbench: ``n x n`` squares cut into 2 P1
triangles, 4225 dofs at n = 64; pyMOR's ``TriaGrid`` at ``diameter = sqrt(2) / n``:
``ceil(n / sqrt(2))`` squares per side cut into 4 around their centre, 4325 dofs), the same
``N``, the same training and validation parameters (the
scene's sampling), POD in the H1_0 seminorm of the training snapshots, the Galerkin
reduced model with the residual error bound ``||r||_X' / min_i mu_i`` (pyMOR:
``CoerciveRBReductor`` with ``ExpressionParameterFunctional('min(diffusion)')``).

Rows: offline time (training snapshots + POD + reduced model), online median (one reduced
solve, one BLAS thread, validation mus x repeats; pyMOR gets parsed ``Mu`` objects,
rbbench raw arrays it checks itself), max relative error in the H1_0 seminorm over the
validation set (each tool against its own HF solution), the bound's effectivity, the HF
solve median. pyMOR is an optional extra (``pip install pymor``): without it its column is
``not_installed`` with the install hint.
"""

from __future__ import annotations

import math
import tempfile
import time
from typing import Any

import numpy as np

from rbbench._compat import deprecated_names
from rbbench.studies.formatting import markdown_table

__all__ = ["INSTALL_HINT", "pymor_column", "rbbench_column",
           "side_by_side", "side_by_side_markdown"]

INSTALL_HINT = "pyMOR is not installed: pip install pymor (the optional extra 'pymor')"


def thermal_block_scene(n_cells: int, blocks: int) -> Any:
    """The ``thermal_block`` scene with ``n_cells`` squares per side and ``blocks x
    blocks`` blocks (parameters ``mu_1 .. mu_{b^2}`` declared by overrides)."""
    from rbbench.scene.loading import load_scene

    extra = [f"parameters.mu_{i}.range=[0.1, 1.0]" for i in range(5, blocks * blocks + 1)]
    return load_scene("thermal_block", [f"discretization.n_cells={n_cells}",
                                        f"geometry.blocks=[{blocks}, {blocks}]", *extra])


def rbbench_column(scene: Any, N: int, n_train: int, n_valid: int, repeats: int,
                   backend: str = "skfem") -> dict[str, Any]:
    """rbbench's figures: :func:`rbbench.rb.linear.offline.reduce_linear` with a fresh
    snapshot cache (the training snapshots are solved, not read)."""
    from rbbench.rb.config import make_config
    from rbbench.rb.linear.offline import reduce_linear

    with tempfile.TemporaryDirectory() as cache:
        cfg = make_config(formulation="linear", primal="pod", dual="", stabilizer="", N=N,
                           n_train=n_train, n_valid=n_valid, cache_dir=cache,
                           online_repeats=repeats, backend=backend)
        s = reduce_linear(scene, cfg).summary()
    return {"status": "ok", "n_hf_dofs": s["n_hf_dofs"], "N": s["N"],
            "t_offline_s": s["t_offline_hf_s"], "t_online_median_s": s["t_online_median_s"],
            "err_u_max": s["err_u_max"], "effectivity_min": s["effectivity_min"],
            "effectivity_max": s["effectivity_max"], "t_hf_median_s": s["t_hf_median_s"]}


def _pymor_model(n_cells: int, blocks: int) -> tuple[Any, Any]:
    """pyMOR's thermal block FOM on ``n_cells`` x ``n_cells`` squares (TriaGrid)."""
    from pymor.analyticalproblems.thermalblock import thermal_block_problem
    from pymor.core.logger import set_log_levels
    from pymor.discretizers.builtin import discretize_stationary_cg

    set_log_levels({"pymor": "WARN"})
    problem = thermal_block_problem((blocks, blocks), (0.1, 1.0))
    # the largest element diameter of rbbench's mesh, sqrt(2) / n: TriaGrid takes
    # ceil(n / sqrt(2)) squares per side, each cut in 4 (about as many dofs as rbbench)
    fom, _ = discretize_stationary_cg(problem, diameter=math.sqrt(2) / n_cells)
    return problem, fom


def _pymor_online(rom: Any, reductor: Any, fom: Any, mus: list, repeats: int
                  ) -> dict[str, list[float]]:
    """Timed reduced solves (one BLAS thread), errors and effectivities per mu."""
    from threadpoolctl import threadpool_limits

    out: dict[str, list[float]] = {"t_on": [], "t_hf": [], "err": [], "eff": []}
    norm = fom.h1_0_semi_norm
    for mu in mus:
        t0 = time.perf_counter()
        u = fom.solve(mu)
        out["t_hf"].append(time.perf_counter() - t0)
        with threadpool_limits(1):
            for _ in range(repeats):
                t0 = time.perf_counter()
                u_n = rom.solve(mu)
                out["t_on"].append(time.perf_counter() - t0)
        err = float(norm(u - reductor.reconstruct(u_n))[0])
        out["err"].append(err / float(norm(u)[0]))
        out["eff"].append(float(np.asarray(rom.estimate_error(mu)).ravel()[0]) / err)
    return out


def pymor_column(n_cells: int, blocks: int, N: int, mus_train: np.ndarray,
                 mus_valid: np.ndarray, repeats: int) -> dict[str, Any]:
    """pyMOR's figures on the same sets (``not_installed`` without pyMOR)."""
    try:
        import pymor
        from pymor.algorithms.pod import pod
        from pymor.parameters.functionals import ExpressionParameterFunctional
        from pymor.reductors.coercive import CoerciveRBReductor
    except ImportError:
        return {"status": "not_installed", "reason": INSTALL_HINT}
    _, fom = _pymor_model(n_cells, blocks)
    parse = fom.parameters.parse
    train = [parse({"diffusion": list(m)}) for m in mus_train]
    valid = [parse({"diffusion": list(m)}) for m in mus_valid]
    product = fom.h1_0_semi_product
    t0 = time.perf_counter()
    U = fom.solution_space.empty()
    for mu in train:
        U.append(fom.solve(mu))
    basis, _ = pod(U, modes=N, product=product)
    reductor = CoerciveRBReductor(fom, RB=basis, product=product, coercivity_estimator=(
        ExpressionParameterFunctional("min(diffusion)", fom.parameters)))
    rom = reductor.reduce()
    t_off = time.perf_counter() - t0
    if getattr(rom, "cache_region", None) not in (None, "none"):
        rom.disable_caching()  # time solves, not cache hits
    on = _pymor_online(rom, reductor, fom, valid, repeats)
    return {"status": "ok", "version": pymor.__version__, "n_hf_dofs": fom.solution_space.dim,
            "N": len(basis), "t_offline_s": t_off,
            "t_online_median_s": float(np.median(on["t_on"])),
            "err_u_max": max(on["err"]), "effectivity_min": min(on["eff"]),
            "effectivity_max": max(on["eff"]), "t_hf_median_s": float(np.median(on["t_hf"]))}


def side_by_side(n_cells: int = 64, blocks: int = 2, N: int = 10, n_train: int = 100,
                 n_valid: int = 20, repeats: int = 20, backend: str = "skfem",
                 progress=print) -> dict[str, Any]:
    """Both columns in one run, on the scene's training / validation parameters, with the
    ratios rbbench / pyMOR of the max error and of the online median."""
    from rbbench.scene.sampling import parameter_set

    scene = thermal_block_scene(n_cells, blocks)
    mus_train = parameter_set(scene, "train", n_train)
    mus_valid = parameter_set(scene, "valid", n_valid)
    progress(f"rbbench ({backend}): {n_train} training, {n_valid} validation, N = {N}")
    ours = rbbench_column(scene, N, n_train, n_valid, repeats, backend)
    progress("pyMOR: the same sets")
    theirs = pymor_column(n_cells, blocks, N, mus_train, mus_valid, repeats)
    ratios = {}
    if theirs["status"] == "ok":
        ratios = {"err_u_max": ours["err_u_max"] / theirs["err_u_max"],
                  "t_online_median_s": ours["t_online_median_s"]
                  / theirs["t_online_median_s"]}
    return {"setup": {"n_cells": n_cells, "blocks": blocks, "N": N, "n_train": n_train,
                      "n_valid": n_valid, "repeats": repeats, "backend": backend},
            "rbbench": ours, "pymor": theirs, "ratio_rbbench_over_pymor": ratios}


_ROWS = (("n_hf_dofs", "HF dofs", "{:d}"), ("N", "N (built)", "{:d}"),
         ("t_offline_s", "offline: training snapshots + POD + reduced model (s)", "{:.3g}"),
         ("t_online_median_s", "online median, one reduced solve (s)", "{:.3g}"),
         ("err_u_max", "max relative error, H1_0 seminorm", "{:.3e}"),
         ("effectivity_min", "estimator effectivity, min", "{:.3g}"),
         ("effectivity_max", "estimator effectivity, max", "{:.3g}"),
         ("t_hf_median_s", "HF solve median (s)", "{:.3g}"))


def side_by_side_markdown(res: dict[str, Any]) -> str:
    """The study as a Markdown table, one column per tool, plus the ratios."""
    ours, theirs = res["rbbench"], res["pymor"]

    def cell(col: dict, key: str, fmt: str) -> str:
        if col["status"] != "ok":
            return col["status"]
        return fmt.format(col[key])

    rows = [(label, cell(ours, k, f), cell(theirs, k, f)) for k, label, f in _ROWS]
    su = res["setup"]
    head = ("quantity", f"rbbench ({su['backend']})",
            f"pyMOR {theirs.get('version', '')}".strip())
    text = markdown_table(head, rows)
    r = res["ratio_rbbench_over_pymor"]
    if r:
        text += (f"\n\nrbbench / pyMOR: max error {r['err_u_max']:.3g}, online median "
                 f"{r['t_online_median_s']:.3g}")
    else:
        text += f"\n\npyMOR column: {theirs.get('reason', theirs['status'])}"
    return (f"Thermal block {su['blocks']} x {su['blocks']}, {su['n_cells']} x "
            f"{su['n_cells']} squares, N = {su['N']}, {su['n_train']} training / "
            f"{su['n_valid']} validation parameters, {su['repeats']} online repeats\n\n"
            + text)


__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)
