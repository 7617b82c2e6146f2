"""The report figure of the certified error bound: bound and true error against the validation
parameter, and their maxima against the primal size N."""

from __future__ import annotations

from typing import Any

import numpy as np

from rbbench.bench.report.analysis import _Ctx, _size_req
from rbbench.bench.report.common import _num
from rbbench.bench.report.detail_figures import _ok_details
from rbbench.bench.report.plotting import _PANEL_H, _PANEL_W, _figure, _Skip

_CAPTION = (
    "Left, per scene: the certified bound err_bound_u (Delta_u / ||u||_X, Haasdonk, Salomon "
    "& Wohlmuth's bound in the natural multiplier norm) and the true error err_u (||u - "
    "u_N||_X / ||u||_X, the same norm and normalisation) at each validation parameter, for "
    "the ok case with the largest (N, R) that has the bound (the first repetition); x: the "
    "parameter when it is scalar, else its index; the title gives the effectivity (bound / "
    "error) min / median / max and whether the bound is online ('rigorous') or evaluated "
    "with the HF operators. Right: err_bound_u_max and err_u_max (max over the validation "
    "set) of every ok case with the bound against its primal size N.")


def _cases(ctx: _Ctx) -> list[tuple[dict[str, Any], dict]]:
    return [(r, det) for r, det in _ok_details(ctx)
            if (det.get("per_mu") or {}).get("err_bound_u")]


def _fig_bound(ctx: _Ctx):
    have = _cases(ctx)
    if not have:
        raise _Skip("no ok case with a certified error bound (details.per_mu.err_bound_u)")
    scenes = [sc for sc in ctx.scenes if any(str(r.get("scene")) == sc for r, _ in have)]
    fig, axes = _figure(len(scenes), 2, w=_PANEL_W + 0.6, h=_PANEL_H + 0.4)
    for i, sc in enumerate(scenes):
        mine = [(r, d) for r, d in have if str(r.get("scene")) == sc]
        r, det = max(mine, key=lambda p: (_size_req(p[0]), -int(p[0].get("repetition") or 0)))
        _per_mu_panel(axes[i, 0], sc, r, det)
        _size_panel(axes[i, 1], sc, [r for r, _ in mine])
    fig.suptitle("Certified error bound and true error", fontsize=11)
    return fig, _CAPTION


def _per_mu_panel(ax, sc: str, r: dict, det: dict) -> None:
    per = det["per_mu"]
    bound = np.asarray([_num(v) for v in per["err_bound_u"]])
    err = np.asarray([_num(v) for v in per["err_u"]])
    mus = np.asarray(det.get("valid_mus") or [], dtype=float)
    scalar = mus.ndim == 2 and mus.shape[1] == 1 and mus.shape[0] == err.size
    x = mus[:, 0] if scalar else np.arange(err.size)
    order = np.argsort(x)
    ax.semilogy(x[order], bound[order], "o-", color="tab:red", ms=4, label="bound err_bound_u")
    ax.semilogy(x[order], err[order], "s-", color="tab:blue", ms=4, label="true err_u")
    eff = bound / np.where(err > 0, err, np.nan)
    eff = eff[np.isfinite(eff)]
    stats = (f"eff {eff.min():.3g} / {np.median(eff):.3g} / {eff.max():.3g}" if eff.size
             else "eff -")
    ax.set_title(f"{sc}, N = {r.get('N')}, R = {r.get('R')}\n{stats} "
                 f"({r.get('certified') or '?'})", fontsize=9)
    ax.set_xlabel("validation mu" if scalar else "validation parameter (index)", fontsize=9)
    ax.set_ylabel("relative error in X", fontsize=9)
    ax.legend(fontsize=8)


def _size_panel(ax, sc: str, rows: list[dict]) -> None:
    pts = sorted((_num(r.get("N")), _num(r.get("err_bound_u_max")), _num(r.get("err_u_max")))
                 for r in rows)
    N, b, e = (np.asarray(v) for v in zip(*pts, strict=True))
    ax.semilogy(N, b, "o", color="tab:red", label="err_bound_u_max")
    ax.semilogy(N, e, "s", color="tab:blue", label="err_u_max")
    ax.set_xlabel("N (primal size asked)", fontsize=9)
    ax.set_ylabel("max over the validation set", fontsize=9)
    ax.set_title(f"{sc}: against N", fontsize=9)
    ax.legend(fontsize=8)
