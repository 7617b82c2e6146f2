"""
One HF contact solve, checked against Hertz
===========================================

Two elastic half-disks pressed together (the scene ``hertz_halfdisks``, after Benaceur,
Drouet, Ehrlacher, Ern & Niakh's talk "Model order reduction methods: parametric
variational inequalities"): the radius of the upper one is the parameter mu. One solve
with the default components (scikit-fem, the mixed formulation with Lagrange multipliers,
the primal-dual active-set solver), and its pressure against 2D Hertz theory at the force
the solver computed.
"""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import rbbench

scene = rbbench.load_scene("hertz_halfdisks")
sol = rbbench.solve(scene, mu=1.0)
m = sol.metrics
print(m["stop_reason"], "after", m["iterations"], "active-set iterations;",
      m["n_dofs"], "dofs,", m["n_contact"], "multipliers")

# %%
# The Hertz check
# ---------------
# ``metrics["hertz"]`` evaluates 2D Hertz theory (half-width ``a``, peak pressure ``p0``)
# at the solver's own contact force ``P`` and gives signed relative errors,
# (computed - theory) / theory. ``metrics["definitions"]`` says what every number is.
h = m["hertz"]
pd.DataFrame(
    {"computed": [m["contact_half_width_gap"], m["max_pressure"]],
     "2D Hertz": [h["a"], h["p0"]],
     "relative error": [h["a_gap_rel_error"], h["p0_rel_error"]]},
    index=["half-width a (m, pointwise edge)", "peak pressure p0 (Pa)"])

# %%
# The pressure profile
# --------------------
# The multipliers are mean pressures over patches of two contact facets (LAC); the dashed
# line is Hertz's half-ellipse at the same force.
from rbbench.hf.output import contact_table

t = contact_table(sol)
order = np.argsort(t["x"])
x = t["x"][order] - np.sum(t["x"] * t["pressure"]) / np.sum(t["pressure"])
fig, ax = plt.subplots(figsize=(7, 3.5))
ax.step(x, t["pressure"][order], where="mid", label="computed multiplier")
xs = np.linspace(-h["a"], h["a"], 400)
ax.plot(xs, h["p0"] * np.sqrt(1 - (xs / h["a"]) ** 2), "r--",
        label=f"2D Hertz at P = {h['P']:.3g} N/m")
ax.set(xlim=(-1.5 * h["a"], 1.5 * h["a"]), xlabel="x (m), centred on the pressure centroid",
       ylabel="normal pressure (Pa)")
ax.legend()
fig.tight_layout()

# %%
# The same on the command line: ``rbbench solve hertz_halfdisks --mu 1`` writes
# ``summary.json`` (these numbers and their definitions), ``contact.csv``, ``solution.vtu``
# for ParaView and ``solution.png``.
