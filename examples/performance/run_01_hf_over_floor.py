"""
The HF contact solve against one factorisation
==============================================

The frictionless HF solve (``ssn``: semismooth Newton on the condensed problem) costs
more than one sparse factorisation and solve of the stiffness (the floor: no contact
solver can do with less), by the condensation ``D = B A^-1 B^T``. Three ways to form it
are timed side by side on ``hertz_halfdisks`` at mu = 1, the mesh refined ``level`` times:

* ``columns``: ``A^-1 B^T`` column by column (the reference);
* ``superlu`` / ``pardiso``: ``D`` read off one factorisation of the KKT matrix as its Schur
  complement on the multiplier rows (PARDISO when the extra ``pardiso`` is installed).

Each timed call is one solve with the problem built (assembly excluded), one BLAS thread,
medians of interleaved repeats; ratios are to the SuperLU floor of the same run (and to the
PARDISO floor when available). The code is ``benchmarks/bench_hf_condensation.py``
(``python -m benchmarks.bench_hf_condensation --levels 0 1 2 --repeats 5``); the docs build
runs levels 0 and 1 with 3 repeats, ``RBBENCH_DOCS_FULL=1`` adds level 2 with 5.
"""

import os
import sys
from pathlib import Path

import pandas as pd

import rbbench
from rbbench.provenance import machine_statement
from rbbench.studies.formatting import significant

sys.path.insert(0, str(Path(rbbench.__file__).resolve().parents[1]))  # the checkout's root
from benchmarks.bench_hf_condensation import side_by_side  # noqa: E402

full = os.environ.get("RBBENCH_DOCS_FULL") == "1"
runs = [side_by_side(level, repeats=5 if full else 3, columns_repeats=1)
        for level in ((0, 1, 2) if full else (0, 1))]
rows = []
for r in runs:
    row = {"level": r["level"], "dofs": r["n_dofs"], "multipliers": r["n_mult"]}
    row.update({f"{k} (s)": v for k, v in r["median_s"].items()})
    row.update({f"{k} / SuperLU floor": v for k, v in r["over_floor"].items()})
    if "floor_pardiso" in r["median_s"]:
        row["pardiso / PARDISO floor"] = (r["median_s"]["pardiso"]
                                          / r["median_s"]["floor_pardiso"])
    rows.append(row)
table = pd.DataFrame(rows).set_index("level")
significant(table.T)

# %%
# The three condensations give the same solution: the largest difference of u to the
# columns path, relative to ``max |u|``, per level:
print({r["level"]: r["u_rel_diff"] for r in runs})

# %%
# Measured on (the load averages say whether other work shared the machine):
print(machine_statement())
