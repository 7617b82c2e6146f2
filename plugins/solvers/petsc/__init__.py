"""PETSc solvers for the mixed contact problem: SNES VI on the KKT system, TAO on the dual.

The problem (Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
parametric variational inequalities" (talk), slide "Mixed formulation";
:class:`rbbench.interfaces.ContactProblem`)::

    A u + B^T lam = F,  lam >= 0,  G - B u >= 0,  lam . (G - B u) = 0.

* :class:`PetscVISolver` writes it as a mixed complementarity problem in
  ``x = (u, lam)`` and solves it with a PETSc SNES variational-inequality
  Newton method (``vinewtonrsls``, reduced-space active set, by default).
* :class:`PetscTaoSolver` condenses it on the contact unknowns with
  :func:`rbbench.hf.condensation.dense.condense` and solves the bound-constrained dual QP
  ``min_{lam >= 0} 1/2 lam^T D lam + q^T lam`` with PETSc TAO (``tron``).

Both also solve a :class:`rbbench.interfaces.FrictionProblem` over its load
steps (:func:`rbbench_plugins.solvers.friction.solve_steps`): Tresca, the box QP
``min 1/2 x^T D x + q^T x``, ``lam_n >= 0``, ``|lam_t| <= s`` on the condensed nodal
problem (:mod:`rbbench.hf.algebra.friction`), by SNES VI as a mixed complementarity
problem or by TAO with bounds (``tresca``); Coulomb by Benaceur et al.'s fixed point on it
(``s = nu_F lam_n`` of the previous iterate), model B by the fixed point on the
coefficient around that.

``petsc4py`` is imported on first use only (:func:`petsc`), and PETSc is initialised
once without reading ``sys.argv``. Every PETSc object gets its own options
prefix (``rbbench_<solver><k>_``); options passed through ``petsc_options``
are written under that prefix for one solve and removed afterwards, so
instances never see each other's options.

The code: :mod:`rbbench_plugins.solvers.petsc.common` (PETSc initialisation, reasons, KKT
check, options, the shared base class), :mod:`rbbench_plugins.solvers.petsc.vi` (SNES VI)
and :mod:`rbbench_plugins.solvers.petsc.tao` (TAO); this module re-exports their names.
"""

from __future__ import annotations

from rbbench_plugins.solvers.petsc.common import _reason_name as _reason_name
from rbbench_plugins.solvers.petsc.common import kkt_errors, map_reason, petsc
from rbbench_plugins.solvers.petsc.tao import TAO_TYPES, PetscTaoSolver
from rbbench_plugins.solvers.petsc.vi import ORDERINGS, SNES_TYPES, PetscVISolver

__all__ = ["ORDERINGS", "SNES_TYPES", "TAO_TYPES", "PetscTaoSolver", "PetscVISolver",
           "kkt_errors", "map_reason", "petsc"]
