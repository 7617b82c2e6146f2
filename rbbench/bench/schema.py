"""The results table: every column of a run-matrix row, defined once.

One row per case x repetition (``rbbench run``). Every column says what it
holds (unit, and for errors: relative, which norm, max or mean over which
set); :func:`column_definitions` is written beside every results table in
``manifest.json``, and ``rbbench report`` / ``rbbench compare`` read only
the columns declared here.

"Published" values and "Benaceur et al." refer to Benaceur, Drouet, Ehrlacher, Ern & Niakh,
"Model order reduction methods: parametric variational inequalities" (talk).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from rbbench.runtime.timing import ONLINE_PROTOCOL_DEFINITION

__all__ = ["COLUMNS", "STATUSES", "Column", "case_record_problem", "column_definitions",
           "empty_row", "names", "normalise_row"]

#: Status of a row. ``ok``: the case ran and its numbers are valid; ``skip``: pruned
#: (incompatible components, from declared capabilities, nothing imported);
#: ``error``: an exception (reason + traceback); ``timeout``: killed at the per-case
#: limit; ``diverged``: a solve did not converge or produced NaN; ``not_installed``:
#: a component's extra is missing (reason = the install hint).
STATUSES = ("ok", "skip", "error", "timeout", "diverged", "not_installed")


@dataclass(frozen=True)
class Column:
    """One results column: name, type (``str``, ``int``, ``float``, ``bool``), group,
    unit and meaning."""

    name: str
    dtype: str
    group: str
    unit: str
    doc: str


def _c(name: str, dtype: str, group: str, unit: str, doc: str) -> Column:
    return Column(name, dtype, group, unit, doc)


_VALID = "over the validation set"
_ERR_U = "relative error ||u - u_N||_X / ||u||_X (X: the scene's V inner product, free dofs)"
_ERR_L = "relative error ||lam - lam_R||_W / ||lam||_W (W: multiplier Gram matrix at mu)"
_ERR_T = ("friction: relative error ||lam_t - lam_t,R||_W / ||lam_t||_W of the tangential "
          "multiplier (W: L2(Gamma_c(mu)) Gram matrix of the nodal P1 multipliers)")
_BETA = ("inf-sup constant, min over the validation set (dimensional, X = the V inner "
         "product); its kind column says, at the minimising mu, span lower bound, exact cone "
         "value or cone upper estimate")

COLUMNS: tuple[Column, ...] = (
    # identity
    _c("run_id", "str", "identity", "", "name of the run (its output directory)"),
    _c("case_id", "str", "identity", "", "hash of everything that determines the case's "
       "numbers (scene content and overrides, components and their parameters, sizes, seed); "
       "the repetitions of a case share it"),
    _c("repetition", "int", "identity", "", "repetition index, 0-based"),
    _c("seed", "int", "identity", "", "seed of the random parameter sets"),
    # components
    _c("mode", "str", "identity", "", "rb: a reduction validated online; hf: HF solves only"),
    _c("scene", "str", "components", "", "scene name (name@variant: the scene under that "
       "variant's overrides)"),
    _c("scene_overrides", "str", "components", "", "scene --set overrides, JSON"),
    _c("backend", "str", "components", "", "HF backend"),
    _c("formulation", "str", "components", "", "formulation"),
    _c("solver", "str", "components", "", "HF VI solver"),
    _c("primal", "str", "components", "", "primal compressor"),
    _c("dual", "str", "components", "", "dual compressor"),
    _c("stabilizer", "str", "components", "", "stabiliser"),
    _c("hyper", "str", "components", "", "hyper-reducer asked for (auto picks)"),
    _c("hyper_used", "str", "components", "", "hyper-reducer actually used (affine / eim / "
       "none)"),
    _c("friction_dual", "str", "components", "", "friction scenes, mode rb: the reduced "
       "friction dual model (collocation: normal cone of lam_n + POD space X_S of lam_t + GCNS "
       "collocation, as in Benaceur et al.'s talk; wedge: cones of F lam_n +- lam_t, Coulomb at "
       "every HF node); empty for frictionless scenes; a skip row: the value asked"),
    _c("executor", "str", "components", "", "executor that ran the case"),
    _c("params", "str", "components", "", "component parameters of the case, JSON"),
    # status
    _c("status", "str", "status", "", "one of " + ", ".join(STATUSES)),
    _c("reason", "str", "status", "", "why the status is not ok (or a note)"),
    _c("traceback", "str", "status", "", "traceback of an error"),
    # sizes
    _c("n_hf_dofs", "int", "sizes", "", "HF displacement dofs"),
    _c("n_contact", "int", "sizes", "", "HF contact unknowns (multipliers)"),
    _c("n_train", "int", "sizes", "", "training parameters (HF snapshots)"),
    _c("n_valid", "int", "sizes", "", "validation parameters"),
    _c("N_req", "int", "sizes", "", "primal size asked for (matrix value)"),
    _c("R_req", "int", "sizes", "", "dual size asked for (matrix value)"),
    _c("N", "int", "sizes", "", "primal RB size obtained"),
    _c("R", "int", "sizes", "", "dual size obtained (cone generators)"),
    _c("S", "int", "sizes", "", "stabiliser size: PGA vectors K (0 for none; R per mu for "
       "online supremizers)"),
    _c("M_eim", "int", "sizes", "", "EIM magic rows evaluated online (hyper eim)"),
    _c("S_tau", "int", "sizes", "", "friction scenes, mode rb: tangential dual size "
       "(collocation model: dim X_S, POD modes of lam_t; wedge model: R-, generators V- of the "
       "cone of F lam_n - lam_t, R being those of F lam_n + lam_t); result.json's S"),
    _c("S_q", "int", "sizes", "", "friction, collocation model: collocation nodes of the "
       "kept GCNS set C(q) (published: 40); 0 for the wedge model (no collocation)"),
    _c("gcns_iterations", "int", "sizes", "", "friction, collocation model: q of the kept "
       "GCNS set (published: 20); 0 for the wedge model"),
    _c("dim_v_off", "int", "sizes", "", "friction scenes, mode rb: N + K, the primal space "
       "after PGA on the combined form b^n + b^tau (published: 70)"),
    # HF solve (mode hf; contact force also for reference in rb mode: not filled)
    _c("dim", "int", "sizes", "", "space dimension of the scene (2, or 3 for the hemispheres)"),
    _c("contact_force", "float", "accuracy", "N/m (2D), N (3D)", "mode hf: total normal "
       "contact force at the scene's default mu (rbbench.hf.model contact_force): 2D per unit "
       "thickness (N/m), 3D of the whole bodies when symmetry planes cut the mesh (N)"),
    _c("max_pressure", "float", "accuracy", "Pa", "mode hf: largest multiplier value, the "
       "peak of the discrete contact pressure"),
    _c("contact_half_width", "float", "accuracy", "m", "mode hf, 2D: half the horizontal "
       "extent of the supports of the active multipliers (quantised to whole supports)"),
    _c("contact_half_width_gap", "float", "accuracy", "m", "mode hf, 2D: half the horizontal "
       "extent of the set where the pointwise gap is closed (edges interpolated)"),
    _c("contact_radius", "float", "accuracy", "m", "mode hf, 3D: largest radial extent "
       "sqrt(x^2 + y^2) of the supports of the active multipliers (quantised to whole "
       "supports)"),
    _c("contact_radius_gap", "float", "accuracy", "m", "mode hf, 3D: radius of the disc of the "
       "projected area where the pointwise gap is closed, whole body"),
    _c("hertz_a_rel_error", "float", "accuracy", "1", "mode hf, Hertz scenes: signed relative "
       "error (computed - theory) / theory of the contact extent (2D contact_half_width, 3D "
       "contact_radius) against Hertz (2D, or 3D a = (3 P R* / (4 E*))^(1/3)) at the "
       "solver's own contact_force"),
    _c("hertz_a_gap_rel_error", "float", "accuracy", "1", "mode hf, Hertz scenes: as "
       "hertz_a_rel_error, of contact_half_width_gap (2D) or contact_radius_gap (3D)"),
    _c("hertz_p0_rel_error", "float", "accuracy", "1", "mode hf, Hertz scenes: signed "
       "relative error of max_pressure against the Hertz peak pressure p0 (3D: 3 P / (2 pi "
       "a^2)) at the solver's own contact_force"),
    _c("hf_iterations", "int", "accuracy", "", "mode hf: iterations of the HF VI solver"),
    _c("hf_final_residual", "float", "accuracy", "1", "mode hf: the solver's final relative "
       "residual (its stopping measure; summary.json final_residual)"),
    _c("tangential_force", "float", "accuracy", "N/m", "mode hf, friction scenes: total "
       "tangential force per unit thickness (sum of lam_t times the friction node weights)"),
    _c("n_stick", "int", "accuracy", "", "mode hf, friction scenes: stick collocation nodes"),
    _c("n_slip", "int", "accuracy", "", "mode hf, friction scenes: slip collocation nodes"),
    _c("friction_residual", "float", "accuracy", "1", "mode hf, friction scenes: max of the "
       "relative stick and slip residuals of the HF solution (rbbench.hf.model)"),
    # accuracy
    _c("err_u_max", "float", "accuracy", "1", _ERR_U + ", max " + _VALID),
    _c("err_u_mean", "float", "accuracy", "1", _ERR_U + ", mean " + _VALID),
    _c("err_lam_max", "float", "accuracy", "1", _ERR_L + ", max " + _VALID),
    _c("err_lam_mean", "float", "accuracy", "1", _ERR_L + ", mean " + _VALID),
    _c("lam_best_max", "float", "accuracy", "1", "||lam - Pi lam||_W / ||lam||_W, Pi the "
       "W-projection onto the reduced cone (span for a non-cone dual): the floor of "
       "err_lam on this dual space, max " + _VALID),
    _c("penetration_max", "float", "accuracy", "m", "largest mean penetration over one HF "
       "multiplier's support of the reconstructed u_N, max " + _VALID),
    _c("complementarity_max", "float", "accuracy", "1", "|lam_R . (G - B u_N)| / "
       "(||lam_R|| ||G||) at the HF rows, max " + _VALID),
    _c("energy_err_max", "float", "accuracy", "1", "|J(u_N) - J(u)| / |J(u)|, max " + _VALID),
    # a posteriori error bound (linear scenes, rbbench.rb.linear.model)
    _c("err_est_max", "float", "accuracy", "1", "linear scenes: the residual-based error "
       "bound (coercivity lower bound by min-theta) divided by ||u||, in err_u's norm, max "
       + _VALID),
    _c("effectivity_min", "float", "accuracy", "1", "error bound / true error in the bound's "
       "norm (linear scenes: err_est; mixed contact scenes: Delta_u / ||u - u_N||_X), min "
       + _VALID + " (>= 1: the bound held)"),
    _c("effectivity_median", "float", "accuracy", "1", "mixed contact scenes: Delta_u / "
       "||u - u_N||_X, median " + _VALID),
    _c("effectivity_max", "float", "accuracy", "1", "error bound / true error, max " + _VALID),
    _c("err_bound_u_max", "float", "accuracy", "1", "mixed contact scenes: the certified bound "
       "Delta_u of ||u - u_N||_X (Haasdonk, Salomon & Wohlmuth 2012; rbbench.rb.algorithms."
       "bounds) divided by ||u||_X as err_u, max " + _VALID),
    _c("certified", "str", "accuracy", "", "mixed contact scenes: 'rigorous' (online bound), "
       "'rigorous (HF-evaluated)' (the same theorem with the HF operators: no online bound "
       "for this model) or 'none'"),
    # accuracy of the reduced friction models (mode rb, friction scenes)
    _c("err_lam_t_max", "float", "accuracy", "1", _ERR_T + ", max " + _VALID),
    _c("err_lam_t_mean", "float", "accuracy", "1", _ERR_T + ", mean " + _VALID),
    _c("lam_t_best_max", "float", "accuracy", "1", "friction: ||lam_t - Pi lam_t||_W / "
       "||lam_t||_W, Pi the W-projection onto the tangential space (collocation model: X_S; wedge "
       "model: span(Lt), the tangential parts (V+ c+ - V- c-) / 2 of the wedge generators): "
       "the floor of err_lam_t, max " + _VALID),
    _c("friction_residual_max", "float", "accuracy", "1", "friction: max over ALL HF nodes "
       "of [|lam_t| - F lam_n]_+ (Tresca: [|lam_t| - s]_+) of the reconstructed reduced "
       "multipliers, relative to the largest reconstructed lam_n (Tresca: s), max " + _VALID),
    _c("friction_law_residual_max", "float", "accuracy", "1", "friction: max over ALL HF "
       "contact nodes of the friction law residual of the reconstruction (u_N, lam_n, lam_t): "
       "max(min(|v|, |lam_t - s sign(v)|), |lam_t| - s, -lam_n, 0), slips v over the HF "
       "solution's max |v|, forces over its max lam_n, s = F lam_n (Tresca: the threshold); "
       "0 iff every node sticks or slips against the bound, max " + _VALID),
    _c("slip_law_residual_max", "float", "accuracy", "1", "friction: max over the HF nodes "
       "where the reconstruction slips (|v| > 1e-3 of the HF solution's max |v|) of "
       "|lam_t - s sign(v)| over the HF solution's max lam_n (a slipping node off the bound "
       "that opposes its slip), max " + _VALID),
    _c("online_iterations_max", "int", "accuracy", "", "friction: iterations of the online "
       "fixed point (collocation: Tresca QPs; wedge: De Saxce), max " + _VALID),
    # stability
    _c("beta_hf_min", "float", "stability", "", _BETA + "; whole V against the HF cone"),
    _c("beta_hf_kind", "str", "stability", "", "kind of beta_hf_min"),
    _c("beta_dec_min", "float", "stability", "", _BETA + "; V_N against the reduced cone"),
    _c("beta_dec_kind", "str", "stability", "", "kind of beta_dec_min"),
    _c("beta_dec_zero_any", "bool", "stability", "", "exact LP test: beta_dec = 0 at some "
       "validation mu"),
    _c("beta_on_min", "float", "stability", "", _BETA + "; V_N + S_R(mu) (online "
       "supremizers)"),
    _c("beta_on_kind", "str", "stability", "", "kind of beta_on_min"),
    _c("beta_off_min", "float", "stability", "", _BETA + "; V_N + S_PGA (offline)"),
    _c("beta_off_kind", "str", "stability", "", "kind of beta_off_min"),
    *(_c(f"beta_{b}_rel_min", "float", "stability", "1", "mode rb: beta_" + b
         + " divided by c_HF(mu), the continuity constant of the same form on V x W "
         "(friction scenes: the combined form b^n + b^tau); dimensionless, Benaceur et al.'s "
         "beta / c ratio; " + what + "; min " + _VALID + " (the per-mu values are of the "
         "kinds of beta_" + b + "_min; empty where the reduction computes no c_HF)")
      for b, what in (("hf", "whole V against the HF cone (friction: R^m_+ x R^m, span lower "
                             "bound; only up to 2m = 400 multiplier rows)"),
                      ("dec", "V_N (friction: whole V) against the reduced dual set"),
                      ("on", "V_N + S_R(mu), the online supremizer space, against the reduced "
                             "cone (frictionless)"),
                      ("off", "span Z_off, the online primal space, against the reduced "
                              "dual set"))),
    _c("delta_pga", "float", "stability", "1", "friction scenes, mode rb: PGA tolerance, "
       "Benaceur et al.'s rule sup_mu beta / c_HF of the combined form over every fifth training "
       "mu (a span lower bound; published: 0.072); empty without PGA"),
    # timings
    _c("t_snapshots_s", "float", "timings", "s", "HF snapshots (wall; 0 when all came from "
       "the cache)"),
    _c("t_primal_s", "float", "timings", "s", "primal compression"),
    _c("t_dual_s", "float", "timings", "s", "dual compression"),
    _c("t_stabilizer_s", "float", "timings", "s", "stabilisation (PGA)"),
    _c("t_hyper_s", "float", "timings", "s", "hyper-reduction (affine probe / EIM)"),
    _c("t_offline_s", "float", "timings", "s", "wall time of the offline stage as it ran: "
       "the snapshot phase as it happened (training and validation snapshots; cache reads "
       "when cached, else HF solves), then the primal, dual, stabiliser and hyper-reduction "
       "steps; without the HF time of cached snapshots (see t_offline_hf_s)"),
    _c("t_snapshots_hf_s", "float", "timings", "s", "HF time of the training snapshots: sum "
       "of each snapshot's stored solve time (measured when it was computed, read from the "
       "cache when cached; a serial sum)"),
    _c("t_offline_hf_s", "float", "timings", "s", "offline cost with the real HF snapshot "
       "time: t_offline_s - t_snapshots_s + t_snapshots_hf_s (training snapshots at their "
       "serial HF time, no validation snapshots)"),
    _c("n_snapshots_cached", "int", "timings", "", "training + validation snapshots the case "
       "read from the snapshot cache"),
    _c("t_online_median_s", "float", "timings", "s", "one online solve (reduced arrays + "
       "reduced saddle-point solve), median over validation mus x repeats under the protocol "
       "online_protocol; with hyper_used "
       "= none (e.g. online supremizers) it includes the HF assembly at mu, the supremizers "
       "and the projection (t_online_hf_assembly_s): such a model is not HF-size "
       "independent"),
    _c("t_online_hf_assembly_s", "float", "timings", "s", "hyper_used = none only: median "
       "time of the HF part of the online step (assembly at mu, online supremizers, "
       "projection), included in t_online_median_s"),
    _c("t_bound_median_s", "float", "timings", "s", "certified = 'rigorous': one online "
       "evaluation of the error bound, median over validation mus x repeats, timed "
       "interleaved with reduced solves (solve, bound, solve, bound ...) under "
       "online_protocol"),
    _c("t_online_iqr_s", "float", "timings", "s", "inter-quartile range of the online time"),
    _c("online_protocol", "str", "timings", "", "the protocol of t_online_median_s and "
       "t_online_iqr_s: " + ONLINE_PROTOCOL_DEFINITION),
    _c("online_path", "str", "timings", "", "the online path of the timed solves: compiled "
       "(numba kernels) or python ('/'-joined when both ran)"),
    _c("online_method", "str", "timings", "", "the online method of the timed solves (auto "
       "resolved: nnls or daqp for the mixed model; empty for a model that names none)"),
    _c("t_hf_median_s", "float", "timings", "s", "one HF solve, median over all snapshots"),
    _c("floor_s", "float", "timings", "s", "the HF floor, one factorisation + one solve of "
       "the HF stiffness A(mu) x = F(mu) (one BLAS thread): mode hf, at the scene's default mu "
       "with the solver's direct solver, timed after the last repeat; mode rb, median over "
       "the validation set, timed at each validation mu with the direct solver of a default "
       "HF solve (empty for parabolic scenes)"),
    _c("solve_over_floor", "float", "timings", "1", "mode hf: the last repeat's solver time "
       "(times_s.solve_s, without assembly) / floor_s"),
    _c("speedup", "float", "timings", "1", "mode rb: speed-up against the timed HF solve, "
       "t_hf_median_s / t_online_median_s"),
    _c("speedup_floor", "float", "timings", "1", "mode rb: speed-up against the HF floor, "
       "floor_s / t_online_median_s (what the reduced model gains over one factorisation + "
       "one solve; speedup / speedup_floor = t_hf_median_s / floor_s, the HF solve's "
       "overhead)"),
    _c("t_case_s", "float", "timings", "s", "wall time of the whole case"),
    # memory
    _c("peak_rss_mb", "float", "memory", "MiB", "peak resident memory of the process that "
       "ran the case (its own process for the processes / dask executors; for serial, the "
       "run's peak so far)"),
    # provenance
    _c("rbbench_version", "str", "provenance", "", "rbbench version"),
    _c("git_sha", "str", "provenance", "", "git commit of the rbbench source ('' if none)"),
    _c("versions", "str", "provenance", "", "versions of the numerical libraries, JSON"),
    _c("machine", "str", "provenance", "", "host name, CPU and core count"),
    _c("threads", "str", "provenance", "", "BLAS / OpenMP thread settings, JSON"),
    _c("started_at", "str", "provenance", "", "UTC start time, ISO 8601"),
)

_BY_NAME = {c.name: c for c in COLUMNS}
_CAST = {"str": str, "int": int, "float": float, "bool": bool}


def names() -> list[str]:
    """Column names, in table order."""
    return [c.name for c in COLUMNS]


def empty_row() -> dict[str, Any]:
    """A row with every column present and empty (None)."""
    return dict.fromkeys(names())


def normalise_row(row: dict[str, Any]) -> dict[str, Any]:
    """Every declared column, cast to its type (None stays None); unknown keys refused.

    Raises
    ------
    KeyError
        For a key that is not a declared column (names the key).
    ValueError
        For a status outside :data:`STATUSES`.
    """
    unknown = set(row) - set(_BY_NAME)
    if unknown:
        raise KeyError(f"results row: unknown column(s) {sorted(unknown)}; columns are "
                       "declared in rbbench/schema.py")
    out = empty_row()
    for k, v in row.items():
        if v is None:
            continue
        cast = _CAST[_BY_NAME[k].dtype]
        if cast is float:
            v = float(v)
            out[k] = None if math.isnan(v) else v
        else:
            out[k] = cast(v)
    if out["status"] is not None and out["status"] not in STATUSES:
        raise ValueError(f"results row: status {out['status']!r}; valid: {', '.join(STATUSES)}")
    return out


def column_definitions() -> dict[str, dict[str, str]]:
    """``{name: {dtype, group, unit, doc}}`` for the manifest."""
    return {c.name: {"dtype": c.dtype, "group": c.group, "unit": c.unit, "doc": c.doc}
            for c in COLUMNS}


def case_record_problem(name: str, record: Any) -> str | None:
    """What is wrong with a case file's content (``cases/<case_id>-r<k>.json``), or ``None``.

    Parameters
    ----------
    name : str
        The file's name (its stem must be ``<case_id>-r<repetition>`` of the row).
    record : object
        The parsed JSON.

    Returns
    -------
    str or None
        ``None`` for a record ``{"row": {...}, "details": {...}}`` whose row has a
        ``case_id``, an integer ``repetition`` and a ``status`` of :data:`STATUSES`, under
        its own name; else the reason.
    """
    if not isinstance(record, dict) or not isinstance(record.get("row"), dict):
        return 'not a case record {"row": {...}, "details": {...}}'
    if not isinstance(record.get("details", {}), dict):
        return "its details are not a table"
    row = record["row"]
    cid, rep, status = row.get("case_id"), row.get("repetition"), row.get("status")
    if not isinstance(cid, str) or not cid:
        return f"its row has no case_id (case_id = {cid!r})"
    if not isinstance(rep, int) or isinstance(rep, bool) or rep < 0:
        return f"its row has no repetition number (repetition = {rep!r})"
    if status not in STATUSES:
        return f"its row's status {status!r} is not one of {', '.join(STATUSES)}"
    expected = f"{cid}-r{rep}.json"
    if name != expected:
        return f"it holds the case {expected} (copied or renamed?)"
    return None
