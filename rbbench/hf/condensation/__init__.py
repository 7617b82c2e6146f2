"""The contact problem condensed on its contact unknowns: the Delassus operator
``D = B A^{-1} B^T`` from dense columns of ``A^{-1} B^T`` (:mod:`.dense`) or as the Schur
complement of the KKT matrix (:mod:`.schur`; SuperLU, or Intel MKL PARDISO: :mod:`.pardiso`).
"""
