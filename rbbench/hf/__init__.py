"""High fidelity: contact geometry, the condensed LCP, friction and Nitsche algebra, analytic
references (Hertz, Cattaneo-Mindlin), the HF model (:class:`rbbench.hf.model.HFModel`),
snapshots and the files of a solve.

Data flow: scene -> backend operators (:mod:`.contact_geometry`: :mod:`.facets`,
:mod:`.facet_chains`, :mod:`.pairing`) -> formulation + solver (:mod:`.model`, :mod:`.lcp`,
:mod:`.friction_algebra` and :mod:`.friction_solvers`, :mod:`.nitsche_algebra`) -> snapshots
(:mod:`.snapshots`).
"""
