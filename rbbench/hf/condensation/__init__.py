"""The contact problem condensed on its contact unknowns: the Delassus operator
``D = B A^{-1} B^T`` from dense columns of ``A^{-1} B^T`` (:mod:`.dense`) or as the Schur
complement of the KKT matrix (:mod:`.schur`; SuperLU, or Intel MKL PARDISO: :mod:`.pardiso`).
"""

from rbbench.hf.condensation.dense import Condensed, condense, delassus_scaling, factorize
from rbbench.hf.condensation.schur import (
    CONDENSATIONS,
    LINEAR_SOLVERS,
    SchurCondensed,
    SchurFactor,
    check_options,
    condense_problem,
    condense_schur,
    kkt_matrix,
    schur_factor,
    schur_superlu,
)

__all__ = ["CONDENSATIONS", "LINEAR_SOLVERS", "Condensed", "SchurCondensed", "SchurFactor",
           "check_options", "condense", "condense_problem", "condense_schur",
           "delassus_scaling", "factorize", "kkt_matrix", "schur_factor", "schur_superlu"]
