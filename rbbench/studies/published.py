"""Published figures and settings of the source talks that the studies reproduce, as data
(standard library only, so the command line reads its defaults without loading numerics).

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "Relative error on the Alart-Curnier reformulation".
"""

from __future__ import annotations

__all__ = ["PUBLISHED_EAC", "PUBLISHED_H", "PUBLISHED_SETTING"]

#: e_AC^n in % at h = 5, 2.5, 1.25 mm for mu = 0.7, 1, 1.3 m.
PUBLISHED_EAC = {0.7: (1.0, 0.52, 0.28), 1.0: (1.45, 0.72, 0.33), 1.3: (1.17, 1.1, 0.43)}
#: the published mesh sizes (m)
PUBLISHED_H = (0.005, 0.0025, 0.00125)
#: the published setting (load d = 0.09 m, P2 displacements) with the two contact options
#: that give the published order (smooth slave normals, segment-to-segment quadrature):
#: scene overrides, ``key -> value``
PUBLISHED_SETTING = {"load.displacement": 0.09, "discretization.degree": 2,
                     "discretization.quadrature": 0, "discretization.normals": "smooth",
                     "discretization.contact_integration": "segmented"}
