"""The exact test for ``beta = 0`` on a cone ``Span+(Vg)`` (:mod:`rbbench.rb.algorithms.infsup`).

``beta = 0`` iff ``C alpha = 0`` for some ``alpha >= 0, sum(alpha) = 1`` (``C = H^T Vg``,
:func:`rbbench.rb.algorithms.infsup.cone_coupling`): the origin lies in the convex hull of the
columns. With the columns normalised (``Cn = C D``, ``D = diag(1 / ||C_j||)``, scale-free) and the
thin SVD ``Cn = U diag(s) V^T``:

* a lower bound without any LP: ``||Cn a||_2 >= s_min ||a||_2 >= s_min / sqrt(R)`` for
  ``a`` in the simplex when ``Cn`` has ``k >= R`` rows (``s_min`` the R-th singular value).
  Above ``rtol`` it certifies ``beta != 0`` (method ``"svd-bound"``). The HF row of the
  membrane (n_cells = 28: a dense 729 x 729 ``C``, full rank) is decided so in 0.3 s,
  where the LP took 20-50 s;
* else the LP ``min ||Rc a||_1, a >= 0, sum(a) = 1`` on ``Rc = diag(s) V^T`` restricted to
  ``s > 1e-3 rtol`` (the rows dropped change ``||Cn a||_2`` by less than ``1e-3 rtol``): HiGHS
  (``"highs"``), then its dual simplex and its interior point method when a run returns no
  point (seen: "beta = 0 LP failed: (HiGHS Status 0: Not Set)" on the membrane,
  n_cells = 28, cpg, R = 4; not reproduced here: 20 validation mus x 3 rotations of the
  factor ``H`` all solved). A point the LP returns is a witness whatever its status:
  ``||Cn a||_2 <= rtol`` proves ``beta = 0``; ``beta != 0`` needs an optimal LP.
  No method decides: ``is_zero = None`` with the reason (``note``), not an exception.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

__all__ = ["ZeroTest", "beta_zero_certificate", "beta_zero_test", "zero_test"]

#: HiGHS variants tried in turn (default choice, dual simplex, interior point)
LP_METHODS = ("highs", "highs-ds", "highs-ipm")


@dataclass(frozen=True)
class ZeroTest:
    """Outcome of :func:`zero_test`: ``is_zero`` (None: undecided), the distance ``dist``
    of the witness ``alpha`` (``||Cn a||_2``; for ``"svd-bound"`` the lower bound), the
    ``method`` that decided and a ``note`` (why undecided)."""

    is_zero: bool | None
    dist: float
    alpha: np.ndarray
    method: str
    note: str = ""


def _normalised(C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(Cn, norms)``: unit columns, norms computed without overflow (scaled by the
    column's max first)."""
    cmax = np.abs(C).max(axis=0)
    safe = np.where(cmax > 0, cmax, 1.0)
    norms = cmax * np.linalg.norm(C / safe, axis=0)
    return C / np.where(norms > 0, norms, 1.0), norms


def _lp(Rc: np.ndarray, Cn: np.ndarray, method: str):
    """One LP run: ``(a or None, ||Cn a||_2, optimal, message)``."""
    kr, R = Rc.shape
    I = np.eye(kr)
    res = linprog(np.concatenate([np.zeros(R), np.ones(kr)]),
                  A_ub=np.block([[Rc, -I], [-Rc, -I]]), b_ub=np.zeros(2 * kr),
                  A_eq=np.concatenate([np.ones(R), np.zeros(kr)])[None, :], b_eq=[1.0],
                  bounds=(0, None), method=method,
                  options={"primal_feasibility_tolerance": 1e-10,
                           "dual_feasibility_tolerance": 1e-10})
    if res.x is None or not np.all(np.isfinite(res.x[:R])) or res.x[:R].max() <= 0:
        return None, float("nan"), False, str(res.message)
    a = np.clip(res.x[:R], 0.0, None)
    a /= a.sum()
    return a, float(np.linalg.norm(Cn @ a)), res.status == 0, str(res.message)


def _alpha(a: np.ndarray, norms: np.ndarray) -> np.ndarray:
    """The witness in the original columns: ``D a / sum(D a)``."""
    alpha = a / norms
    return alpha / alpha.sum()


def _special(C: np.ndarray) -> ZeroTest | None:
    """Empty, non-finite and zero-column cases, decided without an LP (else None)."""
    R = C.shape[1]
    if R == 0:
        return ZeroTest(False, float("inf"), np.zeros(0), "empty")
    if not np.all(np.isfinite(C)):
        return ZeroTest(None, float("nan"), np.full(R, np.nan), "undecided",
                        "non-finite entries in C")
    norms = np.abs(C).max(axis=0)
    if np.any(norms == 0):
        alpha = (norms == 0).astype(float)
        return ZeroTest(True, 0.0, alpha / alpha.sum(), "zero-column")
    return None


def zero_test(C: np.ndarray, *, rtol: float = 1e-9, svd_bound: bool = True) -> ZeroTest:
    """Is ``beta = 0`` on the cone: ``exists alpha >= 0, sum 1, C alpha = 0``? (module
    docstring; ``svd_bound = False`` always runs the LP)."""
    C = np.asarray(C, dtype=float)
    special = _special(C)
    if special is not None:
        return special
    k, R = C.shape
    Cn, norms = _normalised(C)
    _, s, Vt = np.linalg.svd(Cn, full_matrices=False)
    lower = float(s[-1]) / np.sqrt(R) if k >= R else 0.0
    if svd_bound and lower > rtol:
        return ZeroTest(False, lower, np.full(R, np.nan), "svd-bound")
    keep = s > 1e-3 * rtol
    Rc = s[keep, None] * Vt[keep]
    notes = []
    for method in LP_METHODS:
        a, dist, optimal, message = _lp(Rc, Cn, method)
        if a is not None and (dist <= rtol or optimal):
            return ZeroTest(bool(dist <= rtol), dist, _alpha(a, norms), f"lp:{method}")
        notes.append(f"{method}: {message}" + ("" if a is None else f" (dist {dist:.3g})"))
    return ZeroTest(None, float("nan"), np.full(R, np.nan), "undecided",
                    "no LP decided: " + "; ".join(notes))


def beta_zero_certificate(C: np.ndarray) -> tuple[float, np.ndarray]:
    """Distance from the origin to the convex hull of the unit-normalised columns of ``C``,
    by the LP of :func:`zero_test` (always run).

    Returns
    -------
    dist : float
        ``||C D a||_2`` recomputed in floating point at the LP's ``a`` (clipped to
        ``>= 0``, renormalised): 0 iff ``beta = 0`` on the cone (exactly); in general the
        LP minimiser is within a factor ``sqrt(R)`` of the Euclidean distance of the hull.
        NaN when no LP method returned a point; ``inf`` for ``R = 0``.
    alpha : (R,) ndarray
        ``D a / sum(D a)``: the candidate non-negative null vector of ``C`` (``sum = 1``).
    """
    r = zero_test(C, rtol=0.0, svd_bound=False)
    return r.dist, r.alpha


def beta_zero_test(C: np.ndarray, *, rtol: float = 1e-9) -> bool | None:
    """Exact test for ``beta = 0`` on the cone (:func:`zero_test`): True / False, or None
    when no method decided (see ``zero_test(C).note``).

    ``C`` (k x R) is :func:`rbbench.rb.algorithms.infsup.cone_coupling` (or ``Z^T B^T Vg``, ``B^T
    Vg``: same null space). Decision: some convex combination of the *unit-normalised* columns of
    ``C`` has Euclidean norm at most ``rtol`` (scale-free; the LP is solved to 1e-10).
    ``False`` for ``R = 0``.
    """
    return zero_test(C, rtol=rtol).is_zero
