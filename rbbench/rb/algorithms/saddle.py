"""Small dense saddle points A c + B^T x = F condensed on the multipliers by one dense
Cholesky of A: the online algebra shared by the reduced contact models."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla


def condense_dense(A: np.ndarray, F: np.ndarray, B: np.ndarray, G: np.ndarray,
                   cho: tuple | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Condense a small saddle point ``A c + B^T x = F`` on the multipliers by one dense
    Cholesky of ``A`` (``cho``: a factor computed once): ``c = c0 - K x`` with
    ``c0 = A^-1 F``, ``K = A^-1 B^T``, the symmetrised Delassus ``D = B K`` and
    ``q = G - B c0``. Returns ``(c0, K, D, q)``."""
    cho = sla.cho_factor(A) if cho is None else cho
    c0 = sla.cho_solve(cho, F)
    K = sla.cho_solve(cho, B.T)
    D = B @ K
    return c0, K, 0.5 * (D + D.T), G - B @ c0
