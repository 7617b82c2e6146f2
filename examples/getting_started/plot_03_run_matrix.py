"""
A run matrix and its report
===========================

A run matrix crosses scenes, components, sizes and parameters; every combination is one
case and one row of a results table, also when it fails (its status says why). The
shipped matrix ``quick`` crosses 3 dual cone compressors with 3 stabilisers and 2 sizes on
two scenes; here only its membrane cases run, on local processes.
"""

import tempfile

import matplotlib.pyplot as plt

import rbbench
from rbbench.bench.report import report

work = tempfile.mkdtemp(prefix="rbbench-")  # this example's results and snapshot cache
run = rbbench.run("quick", out=f"{work}/quick", cache_dir=f"{work}/cache",
                  select=["scene=membrane_obstacle"], progress=False)

# %%
# The results table
# -----------------
# ``load_results`` reads it with its declared types; ``manifest.json`` beside it defines
# every column (unit, norm, max or mean over which set).
df = rbbench.load_results(run.out_dir)
columns = ["dual", "stabilizer", "N", "R", "status", "err_u_max", "err_lam_max",
           "lam_best_max", "beta_on_min", "beta_on_kind", "t_online_median_s"]
df.sort_values(["N", "dual", "stabilizer"])[columns]

# %%
# The report
# ----------
# ``rbbench report`` (or :func:`rbbench.bench.report.report`) writes figures and
# ``summary.md`` / ``summary.html``. The Pareto front: error against online time, one
# point per case, the fastest case at each error level marked.
out = report(run.out_dir, formats=("png",))
fig, ax = plt.subplots(figsize=(9, 6))
ax.imshow(plt.imread(run.out_dir / "report" / "pareto.png"))
ax.set_axis_off()
fig.tight_layout()

# %%
# On the command line: ``rbbench run quick -s scene=membrane_obstacle`` then
# ``rbbench report results/quick``; ``rbbench compare OLD NEW`` lists what changed between
# two runs. :doc:`/user_guide/matrices` describes the matrix files,
# :doc:`/user_guide/report` every figure and column.
