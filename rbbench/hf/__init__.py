"""High fidelity: contact geometry, the condensed LCP, Nitsche algebra, analytic references
(Hertz), the HF model (:func:`rbbench.hf.model.solve_hf`), snapshots and the files of a solve.

Data flow: scene -> backend operators (:mod:`.contact_geometry`) -> formulation + solver
(:mod:`.model`, :mod:`.lcp`, :mod:`.nitsche_algebra`) -> snapshots (:mod:`.snapshots`).
"""
