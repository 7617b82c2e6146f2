"""
One reduction: offline, validation, the reduced model
=====================================================

A reduced model of the obstacle problem ``membrane_obstacle`` (-Laplace u = f on the unit
square, u >= psi(mu), two parameters: the obstacle's height and curvature): POD of the
displacement snapshots, a cone of multipliers (mCPG), PGA stabilisation, the exact affine
decomposition of the operators. ``rbbench.reduce`` builds it offline, then validates it
against HF solves at random parameters it was not trained on.
"""

import tempfile

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import rbbench

work = tempfile.mkdtemp(prefix="rbbench-")  # this example's HF snapshot cache
scene = rbbench.load_scene("membrane_obstacle")
res = rbbench.reduce(scene, N=8, R=8, n_train=25, n_valid=10, dual="mcpg", stabilizer="pga",
                     cache_dir=f"{work}/cache")
s = res.summary()

# %%
# What the validation measured
# ----------------------------
# Errors are relative, u in the X norm and the multiplier lam in the W norm, max over the
# 10 validation parameters; ``lam_best_max`` is the best any multiplier in the reduced cone
# could do (the floor of ``err_lam_max``). The inf-sup constant of the reduced saddle point
# is divided by the continuity constant of the same form (dimensionless). Times are
# medians with one BLAS thread, on the machine that built these docs.
rows = ["err_u_max", "err_lam_max", "lam_best_max", "beta_on_rel_min",
        "t_online_median_s", "t_hf_median_s", "speedup"]
pd.DataFrame({"value": [s[k] for k in rows]}, index=rows)

# %%
# Each of those numbers has a definition in the result (``result.json`` on the command
# line):
print(s["definitions"]["err_u"])

# %%
# Errors per validation parameter
# -------------------------------
fig, ax = plt.subplots(figsize=(7, 3.5))
k = np.arange(len(res.err_u))
ax.semilogy(k, res.err_u, "o-", label="u, X norm")
ax.semilogy(k, res.err_lam, "s-", label="lam, W norm")
ax.semilogy(k, res.histories["lam_best_valid"], "k:", label="lam, best in the cone")
ax.set(xlabel="validation parameter", ylabel="relative error")
ax.legend()
fig.tight_layout()

# %%
# The reduced model
# -----------------
# ``res.model`` is small and independent of the mesh: it pickles, and ``solve(mu)`` checks
# mu against the scene's domain and returns the reduced coordinates with the iterations,
# the stop reason and the time; ``reconstruct`` gives the HF vectors. Every model of
# rbbench, HF or reduced, has this interface (:class:`rbbench.interfaces.Model`).
model = res.model
print(model.parameters)
red = model.solve([0.3, 5.0])
print(red.stop_reason, red.iterations, f"{red.time_s * 1e6:.0f} us")
u_rb = model.reconstruct(red).u
hf = rbbench.solve(scene, mu=[0.3, 5.0])
print(f"max |u_HF - u_RB| / max |u_HF| = "
      f"{np.abs(hf.u[hf.problem.free] - u_rb).max() / np.abs(hf.u).max():.2e}")
try:
    model.solve([0.9, 5.0])  # outside D: the height lies in [0.1, 0.4]
except ValueError as err:
    print(err)
