"""
Cones of contact multipliers: CPG, mCPG, ENG
============================================

A reduced contact model keeps the multipliers non-negative by looking for them in a
cone ``Span^+(v_1, ..., v_R)`` of non-negative generators. The dual compressors build that
cone greedily from the HF multiplier snapshots; their figure of merit is ``e_proj(r)``,
the largest W-norm projection error of a snapshot onto the cone of the first r generators,
relative to the snapshot (Benaceur et al., slides on the Cone Projected Greedy algorithm).
Here the three greedy compressors of rbbench on the frictionless Hertz problem (coarse
mesh, 21 training parameters), called as any plugin is, through the registry.
"""

import tempfile

import matplotlib.pyplot as plt
import numpy as np

import rbbench
from rbbench.hf.components import make_components
from rbbench.hf.model import ProblemCache
from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.registry import default_registry
from rbbench.scene.sampling import parameter_set

scene = rbbench.load_scene("hertz_halfdisks",
                           overrides=["discretization.h_contact=0.01", "discretization.h_max=0.2"])
mus = parameter_set(scene, "train", 21)
snaps = compute_snapshots(scene, mus, cache_dir=tempfile.mkdtemp(prefix="rbbench-"),
                          progress=False)
registry = default_registry()
backend, formulation, _ = make_components(scene, registry=registry)
W = ProblemCache(backend, formulation)(scene.default_mu).W  # the multipliers' inner product
print(f"{snaps.LAM.shape[1]} snapshots of {snaps.LAM.shape[0]} multipliers")

# %%
# Each compressor, up to 20 generators:
bases = {name: registry.create("dual", name)(snaps.LAM, W, tol=1e-6, r_max=20)
         for name in ("cpg", "mcpg", "eng")}
fig, ax = plt.subplots(figsize=(6.5, 3.5))
for name, basis in bases.items():
    e = np.asarray(basis.e_proj)
    ax.semilogy(np.arange(1, e.size + 1), e, "o-", ms=3,
                label=f"{name}: {basis.generators.shape[1]} generators, "
                      f"stop {basis.info.get('stop')}")
ax.set(xlabel="r (generators)", ylabel="e_proj(r), max over the snapshots")
ax.legend(fontsize=7)
fig.tight_layout()

# %%
# Every generator is non-negative (a cone of multipliers) and of unit W-norm:
for name, basis in bases.items():
    V = basis.generators
    print(f"{name}: min entry {V.min():.1e}, W-norms "
          f"{np.sqrt(np.einsum('ir,ir->r', V, W @ V)).round(12).min():g} .. "
          f"{np.sqrt(np.einsum('ir,ir->r', V, W @ V)).round(12).max():g}")
