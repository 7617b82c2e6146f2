"""What the ``rbbench`` commands print on the console: progress lines, the summary of
``rbbench solve`` (with the Hertz and Cattaneo-Mindlin lines) and of ``rbbench reduce``, each
number with its unit, and tables fitted to the terminal (``rbbench plugins``, ``scenes``).
No imports beyond the standard library (the shared base of the package)."""

from __future__ import annotations

import shutil
import sys
import textwrap
import time


class _Progress:
    """One status line per stage, with the elapsed time, on stderr."""

    def __init__(self, quiet: bool = False):
        self.quiet = quiet
        self.t0 = time.perf_counter()

    def __call__(self, stage: str) -> None:
        if not self.quiet:
            print(f"[{time.perf_counter() - self.t0:7.2f} s] {stage}", file=sys.stderr,
                  flush=True)


def terminal_width() -> int | None:
    """The width the tables fit: ``COLUMNS``, else the terminal's; ``None`` (no limit: one
    line per row, for grep) when standard output is not a terminal and ``COLUMNS`` is unset."""
    return shutil.get_terminal_size(fallback=(0, 0)).columns or None


#: a wrapped column is never narrower than this (a narrow terminal: the line overflows)
MIN_WRAP_WIDTH = 16


def _column_widths(natural: list[int], wrap: set[int], width: int | None, gap: int) -> list[int]:
    """Each column's width: its widest cell, the columns in ``wrap`` narrowed, the narrowest
    first, to share what the others leave of ``width`` (none below :data:`MIN_WRAP_WIDTH`)."""
    if width is None or sum(natural) + gap * (len(natural) - 1) <= width:
        return list(natural)
    widths = list(natural)
    avail = width - gap * (len(natural) - 1) - sum(n for i, n in enumerate(natural)
                                                   if i not in wrap)
    order = sorted(wrap, key=lambda i: natural[i])
    for k, i in enumerate(order):
        share = avail // (len(order) - k)
        widths[i] = min(natural[i], max(share, MIN_WRAP_WIDTH))
        avail -= widths[i]
    return widths


def _wrap_cell(cell: str | list[str], width: int) -> list[str]:
    """The lines of one cell ``width`` wide: a text wraps at spaces, a list of items (joined
    by ", ") between items; a word or item wider than ``width`` stays whole (never cut)."""
    if isinstance(cell, str):
        return textwrap.wrap(cell, width, break_long_words=False, break_on_hyphens=False) or [""]
    lines = [""]
    for k, item in enumerate(cell):
        piece = item + ("," if k < len(cell) - 1 else "")
        if lines[-1] and len(lines[-1]) + 1 + len(piece) > width:
            lines.append(piece)
        else:
            lines[-1] = f"{lines[-1]} {piece}" if lines[-1] else piece
    return lines


#: a last column that would wrap narrower than this goes under its row instead
STACK_WIDTH = 24
#: the indent of a column under its row
STACK_INDENT = 4


def format_table(rows: list[list], wrap: set[int] = frozenset(), width: int | None = None,
                 gap: int = 2) -> list[list[str]]:
    """``rows`` (the header first, if any) as aligned columns that fit ``width``
    (:func:`terminal_width`): the lines of each row, the columns in ``wrap`` wrapped onto more
    lines (:func:`_wrap_cell`), the others as wide as their widest cell; nothing is cut. A
    last column in ``wrap`` that would be narrower than :data:`STACK_WIDTH` goes under its
    row, indented, wrapped to the full width."""
    natural = [max(len(", ".join(c) if isinstance(c, list) else c) for c in col)
               for col in zip(*rows, strict=True)]
    widths = _column_widths(natural, set(wrap), width, gap)
    last = len(natural) - 1
    if width is not None and last in wrap and widths[last] < min(STACK_WIDTH, natural[last]):
        head = format_table([r[:-1] for r in rows], set(wrap) - {last}, width, gap)
        return [block + [" " * STACK_INDENT + line
                         for line in _wrap_cell(row[-1], width - STACK_INDENT)]
                for block, row in zip(head, rows, strict=True)]
    blocks = []
    for row in rows:
        cells = [_wrap_cell(c, w) if i in wrap else [c if isinstance(c, str) else ", ".join(c)]
                 for i, (c, w) in enumerate(zip(row, widths, strict=True))]
        blocks.append([(" " * gap).join((cell[k] if k < len(cell) else "").ljust(w)
                                        for cell, w in zip(cells, widths, strict=True)).rstrip()
                       for k in range(max(map(len, cells)))])
    return blocks


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def _unit(key: str, units: dict) -> str:
    """The unit printed after the number ``key``: ``units[key]`` (``summary.json`` ``units``,
    :data:`rbbench.hf.metrics.SI_UNITS`), seconds for a time (the ``_s`` suffix); nothing
    for a count, a ratio or a nondimensional scene's number (``"1"``)."""
    unit = units.get(key) or ("s" if key.endswith("_s") else "")
    return "" if unit == "1" else unit


def _valued(key: str, value, units: dict) -> str:
    """``value`` formatted, then its unit."""
    unit = _unit(key, units)
    return f"{_fmt(value)} {unit}" if unit else _fmt(value)


def _mu_line(mu: dict, mu_units: dict | None = None) -> str:
    """``mu: name = value [unit], ...`` (``mu_units``: the scene's parameter units)."""
    units = mu_units or {}
    return "mu: " + ", ".join(f"{k} = {v:g}" + (f" {units[k]}" if units.get(k) else "")
                              for k, v in mu.items())


def _nondimensional_note(units: dict) -> None:
    """A line saying so when every number of ``units`` is nondimensional (the scalar
    scenes)."""
    if units and set(units.values()) == {"1"}:
        print("  (nondimensional scene: its numbers carry no unit; times in s)")


def print_summary(m: dict, mu: dict, mu_units: dict | None = None) -> None:
    """The summary lines of an HF solve (``m``: its metrics, units from ``m["units"]``;
    ``mu``: the parameter values, ``mu_units`` their units)."""
    keys = ["n_dofs", "n_contact", "n_active", "iterations", "stop_reason", "final_residual",
            "solver_stop_reason", "solve_time_s", "floor_s", "solve_over_floor",
            "contact_force", "contact_half_width",
            "contact_half_width_gap", "contact_half_width_gap_tol", "contact_radius",
            "contact_radius_max", "contact_radius_gap", "contact_radius_gap_tol", "max_pressure",
            "complementarity", "penetration_max", "zone_saturated", "e_ac",
            "tangential_force", "n_stick", "n_slip", "n_open", "stick_half_width",
            "friction_residual"]
    units = m.get("units") or {}
    print(_mu_line(mu, mu_units))
    notes = {"floor_s": "  (one factorisation + one solve of A, this run)",
             "solve_over_floor": "  (solver time times_s.solve_s / floor_s)",
             "contact_half_width": "  (quantised to whole multiplier supports)",
             "contact_half_width_gap": "  (pointwise gap <= contact_half_width_gap_tol, "
                                       "edges interpolated)",
             "contact_radius": "  (area of the active multiplier supports, as a disc)",
             "contact_radius_max": "  (outermost active multiplier support)",
             "contact_radius_gap": "  (area of the closed cells, as a disc)",
             "contact_force": "  (whole bodies)" if m.get("symmetry_copies", 1) > 1 else ""}
    for k in keys:
        if k in m and m[k] is not None:
            print(f"  {k:<26} {_valued(k, m[k], units)}{notes.get(k, '')}")
    _nondimensional_note(units)
    if "hertz" in m:
        _print_hertz(m, units)
    _print_mindlin(m.get("mindlin"), units)
    reason = (m.get("solver_info") or {}).get("reason")
    if reason and m.get("stop_reason") != "converged":
        print(f"  reason: {reason}")
    for w in m.get("warnings", ()):
        print(f"  WARNING: {w}")
    if m.get("zone_saturated"):
        print("  WARNING: the contact patch reaches the edge of the potential contact zone")


def _print_hertz(m: dict, units: dict) -> None:
    """The 2D or 3D Hertz lines of an HF solve (``summary.json`` ``hertz``)."""
    h = m["hertz"]
    width = "contact_radius" if m.get("dim") == 3 else "contact_half_width"

    def a(v):
        return _valued(width, v, units)

    print(f"  {'3D' if m.get('dim') == 3 else '2D'} Hertz at the computed force P:")
    print(f"    a   = {a(h['a'])}   computed {a(m[width])}   "
          f"rel. error {100 * h['a_rel_error']:+.2f} % (quantised)")
    if h.get("a_gap_rel_error") is not None:
        print(f"    a   = {a(h['a'])}   gap edge {a(m[width + '_gap'])}   "
              f"rel. error {100 * h['a_gap_rel_error']:+.2f} %")
    print(f"    p0  = {_valued('max_pressure', h['p0'], units)}  computed "
          f"{_valued('max_pressure', m['max_pressure'], units)}  "
          f"rel. error {100 * h['p0_rel_error']:+.2f} %")
    if "profile_fit_a" in h:
        print(f"    profile fit p^2 = p0^2 (1 - r^2/a^2): a rel. error "
              f"{100 * h['profile_fit_a_rel_error']:+.2f} %, p0 rel. error "
              f"{100 * h['profile_fit_p0_rel_error']:+.2f} %")
    if "peak_patch_p0" in h:
        print(f"    p0 over the peak support = "
              f"{_valued('max_pressure', h['peak_patch_p0'], units)}  rel. error "
              f"{100 * h['peak_patch_rel_error']:+.2f} % (patch mean vs pointwise p0: "
              f"{100 * h['peak_patch_averaging']:+.2f} %)")


def _print_mindlin(b: dict | None, units: dict) -> None:
    """The Cattaneo-Mindlin lines of a friction solve (``summary.json`` ``mindlin``)."""
    if not b:
        return
    if b.get("c_theory") is None:
        print(f"  Cattaneo-Mindlin: not applicable ({b.get('reason')})")
        return
    print(f"  Cattaneo-Mindlin at the computed P = {_valued('contact_force', b['P'], units)}, "
          f"Q = {_valued('tangential_force', b['Q'], units)} "
          f"(Q / F P = {b['Q_over_FP']:.3f}):")
    print(f"    c   = {_valued('stick_half_width', b['c_theory'], units)}   computed "
          f"{_valued('stick_half_width', b['c'], units)}   "
          f"rel. error {100 * b['c_rel_error']:+.2f} %")
    print(f"    shear traction: relative L2(-a, a) error {100 * b['traction_l2_rel_error']:.2f} "
          f"% (even part {100 * b['traction_l2_rel_error_even']:.2f} %)")


#: what a reduction's timing lines are, printed beside them
_REDUCE_NOTES = {
    "t_online_median_s": "  (median over validation mus x repeats, protocol online_protocol)",
    "t_hf_median_s": "  (timed HF solve, median over the snapshots)",
    "speedup": "  (against the timed HF solve: t_hf_median_s / t_online_median_s)",
    "floor_s": "  (HF floor: one factorisation + one solve of A(mu), median over validation)",
    "speedup_floor": "  (against the HF floor: floor_s / t_online_median_s)",
}


def _print_reduce_summary(s: dict, formulation: str, units: dict | None = None) -> None:
    """The main numbers of ``rbbench reduce`` (``s``: the reduction's summary; ``units``: the
    scene's, :func:`rbbench.hf.metrics.units_of`)."""
    units = units or {}
    keys = ["N", "R", "K_pga", "hyper", "M_eim", "n_train", "n_valid", "n_hf_dofs", "err_u_max",
            "err_u_mean", "err_lam_max", "err_lam_mean", "lam_best_max", "penetration_max",
            "beta_hf_min", "beta_dec_min", "beta_on_min", "beta_off_min", "beta_kind",
            "beta_hf_rel_min", "beta_dec_rel_min", "beta_on_rel_min", "beta_off_rel_min",
            "t_offline_s", "t_snapshots_hf_s", "t_offline_hf_s", "n_snapshots_cached",
            "t_online_median_s", "t_hf_median_s", "speedup", "floor_s", "speedup_floor",
            "S", "S_q",
            "gcns_iterations", "gcns_stop", "err_lam_t_max", "err_lam_t_mean", "lam_t_best_max",
            "friction_residual_max", "friction_law_residual_max", "slip_law_residual_max",
            "certified", "err_bound_u_max", "effectivity_min",
            "effectivity_median", "effectivity_max", "t_bound_median_s",
            "t_bound_solve_median_s", "t_bound_ratio", "t_bound_hf_median_s"]
    for k in keys:
        if k in s and not (k.startswith("t_bound") and s[k] is None):
            print(f"  {k:<20} {_valued(k, s[k], units)}{_REDUCE_NOTES.get(k, '')}")
    _nondimensional_note(units)
    for w in s.get("warnings", ()):
        print(f"  WARNING: {w}")
    if formulation == "nitsche":
        eim = s["histories"].get("eim", {})
        for k in ("method", "rows", "e_eim_valid", "e_eim_cv_valid", "e_eim_tangent_cv_valid"):
            if k in eim:
                print(f"  {'eim.' + k:<20} {_fmt(eim[k])}")
        print("  (Nitsche: err_lam is the contact pressure -[P_gamma]_- in L2(Gamma_c); no dual "
              "space, no inf-sup constants; see result.json definitions)")
    else:
        print("  (errors: relative, u in the X norm, lam in the W norm, max/mean over the "
              "validation set; beta: min over the validation set, raw (units of the X, W "
              "norms); beta_*_rel: beta / c_HF(mu), dimensionless; see result.json "
              "definitions)")


_SOLVE_KEYS = ("physics", "n_dofs", "n_free", "steps", "dt", "stop_reason", "residual_rel",
               "solve_time_s", "u_max", "u_min", "u_integral", "u_norm_X", "u_norm_L2X")


_REDUCE_KEYS = ("N", "hyper", "n_train", "n_valid", "n_hf_dofs", "err_u_max", "err_u_mean",
                "err_est_max", "effectivity_min", "effectivity_max", "alpha_lb_max",
                "energy_err_max", "t_offline_s", "t_offline_hf_s", "n_snapshots_cached",
                "t_online_median_s", "t_hf_median_s", "speedup", "floor_s", "speedup_floor")


def print_linear_summary(m: dict, mu: dict, mu_units: dict | None = None) -> None:
    """The lines of a linear HF solve (``m``: :func:`rbbench.hf.linear.solve.linear_metrics`)."""
    print(_mu_line(mu, mu_units))
    at_t = " (at T)" if "steps" in m else ""
    for k in _SOLVE_KEYS:
        if k in m:
            tail = at_t if k in ("u_max", "u_min", "u_integral", "u_norm_X") else ""
            print(f"  {k:<14} {_valued(k, m[k], {})}{tail}")
    print("  (linear scene, no contact, nondimensional (no unit but the times'): residual_rel "
          "recomputed from the assembled operators; see summary.json definitions)")


def print_linear_reduce(s: dict, parabolic: bool, inner: str) -> None:
    """The main numbers of a linear reduction (``s``: ``ReduceResult.summary()``;
    ``parabolic``: a ``heat`` scene, errors in L2(0, T; X); ``inner``: X, the scene's
    ``inner_product``)."""
    for k in _REDUCE_KEYS:
        if k in s and s[k] is not None:
            print(f"  {k:<20} {_valued(k, s[k], {})}{_REDUCE_NOTES.get(k, '')}")
    for w in s.get("warnings", ()):
        print(f"  WARNING: {w}")
    x = {"h1_semi": "H1_0 seminorm |.|_1", "h1": "H1"}.get(inner, inner)
    norm = f"L2(0, T; X) norm, X the {x}" if parabolic else f"X norm, X the {x}"
    print(f"  (linear scene, no contact: err_u = ||u - u_N|| / ||u|| in the {norm}, "
          "err_est = the a posteriori bound / ||u||, effectivity = bound / error (>= 1: "
          "rigorous), max/mean/min over the validation set; no dual space, stabiliser or "
          "contact solver: --dual, --stabilizer, -R, -S, --solver do not apply; see "
          "result.json definitions)")
