"""High fidelity: one-way from the scene to the snapshots.

* :mod:`.geometry`: the contact boundaries, pairing and contact operators (backend-agnostic);
* :mod:`.references`: analytic references (2D Hertz, Cattaneo-Mindlin);
* :mod:`.condensation`: the contact problem condensed on its contact unknowns (Delassus);
* :mod:`.algebra`: the algebra of the friction and Nitsche formulations;
* :mod:`.solvers`: the LCP and friction solvers on the condensed problem;
* :mod:`.components` (the backend, formulation and solver by name), :mod:`.model` (the HF
  model: one solve), :mod:`.metrics` (its labelled numbers), :mod:`.output` (its files);
* :mod:`.snapshots`: HF snapshots, cached; :mod:`.linear`: the linear scenes without contact.
"""

from rbbench._compat import deprecated_names

__getattr__ = deprecated_names(__name__)  # the names of rbbench 0.1's flat rbbench.hf
