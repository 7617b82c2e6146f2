"""Compiled (numba) kernels and offline plans shared by the formulations' online paths:
the packed plan layout (:mod:`~rbbench.rb.kernels.layout`, :mod:`~rbbench.rb.kernels.plan`),
the 2D contact pairing and magic entries of the contact EIM
(:mod:`~rbbench.rb.kernels.pairing`), their 3D counterparts on triangulated surfaces
(:mod:`~rbbench.rb.kernels.surface_pairing`, offline side
:mod:`~rbbench.rb.kernels.surface_plan`) and the Gram-form NNLS
(:mod:`~rbbench.rb.kernels.nnls`). The numba modules import numba at the top: import them
only when numba is installed.
"""
