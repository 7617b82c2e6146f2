"""
Accuracy against online time
============================

What a reduced model buys is speed, what it costs is accuracy; both grow with its sizes.
Here the obstacle membrane reduced at several primal sizes N and cone sizes R (POD, mCPG,
PGA, exact affine decomposition), each validated against HF solves at the same 10 random
parameters; the HF snapshots are shared through one cache. The errors are relative, max
over the validation set (u in the X norm, lam in the W norm); the online time is the median
of the timed online solves with one BLAS thread. ``rbbench run`` does the same sweep from a
run matrix (``[params] N = [...]``), and its report draws the same trade for every scene
(error against online time, the Pareto front marked).
"""

import tempfile

import matplotlib.pyplot as plt
import pandas as pd

import rbbench
from rbbench.studies.formatting import significant

scene = rbbench.load_scene("membrane_obstacle")
cache = tempfile.mkdtemp(prefix="rbbench-")
rows = []
for size in (2, 4, 8, 12, 16):
    s = rbbench.reduce(scene, N=size, R=size, n_train=25, n_valid=10, dual="mcpg",
                       stabilizer="pga", cache_dir=cache).summary()
    rows.append({"N = R": size, "err_u_max": s["err_u_max"], "err_lam_max": s["err_lam_max"],
                 "online median (us)": 1e6 * s["t_online_median_s"],
                 "speed-up": s["speedup"]})
table = pd.DataFrame(rows)
significant(table)

# %%
fig, ax = plt.subplots(figsize=(6, 3.5))
ax.loglog(table["online median (us)"], table["err_u_max"], "o-", label="u, X norm")
ax.loglog(table["online median (us)"], table["err_lam_max"], "s-", label="lam, W norm")
for _, r in table.iterrows():
    ax.annotate(f"N = R = {r['N = R']:.0f}", (r["online median (us)"], r["err_u_max"]),
                fontsize=7, xytext=(3, 3), textcoords="offset points")
ax.set(xlabel="online median (us), one BLAS thread", ylabel="relative error, max")
ax.legend()
fig.tight_layout()
