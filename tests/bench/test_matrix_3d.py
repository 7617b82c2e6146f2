"""The 3D run matrices (``problems/matrices/sphere_hf.toml``, ``sphere_rb.toml``): they
validate, the mode-hf solver options are checked at load time, a small HF run of
``sphere_hf`` through the runner gives 3D rows (contact radius, Hertz errors) and its
report; (slow) a small run of ``sphere_rb``."""

from __future__ import annotations

import importlib.util
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rbbench.bench.matrix import MatrixError, load_matrix
from rbbench.bench.report import report
from rbbench.bench.runner import run_matrix
from rbbench.registry import default_registry
from rbbench.scene.loading import PROBLEMS_DIR, tomllib

pytestmark = pytest.mark.timeout(900)

#: a coarse level-0 mesh for the small runs (1,266 P1 dofs)
COARSE = '["discretization.level=0", "discretization.h_contact=0.06", ' \
         '"discretization.h_max=0.4"]'


def _coarse(name: str, tmp_path: Path, extra: dict[str, str] | None = None) -> Path:
    """The shipped matrix ``name`` with its scenes on the coarse mesh (and ``extra``
    replacements of its text)."""
    text = (PROBLEMS_DIR / "matrices" / f"{name}.toml").read_text()
    data = tomllib.loads(text)
    for scene, ov in data["scene_overrides"].items():
        old = f'"{scene}" = {json.dumps(ov)}'
        assert old in text, old
        rigid = [o for o in ov if o.startswith("geometry.")]
        new = COARSE[:-1] + "".join(f', "{o}"' for o in rigid) + "]"
        text = text.replace(old, f'"{scene}" = {new}')
    for a, b in (extra or {}).items():
        assert a in text, a
        text = text.replace(a, b)
    p = tmp_path / f"{name}.toml"
    p.write_text(text)
    return p


def test_the_3d_matrices_validate():
    reg = default_registry()
    hf = load_matrix("sphere_hf", registry=reg)
    assert {c.mode for c in hf.cases} == {"hf"}
    # NGSolve (and Netgen, the 3D mesher) and PETSc are extras: without them the cases
    # are "not_installed" rows
    netgen = importlib.util.find_spec("netgen") is not None
    optional = {"ngsolve": "ngsolve", "petsc-tao": "petsc4py", "petsc-vi": "petsc4py"}
    for c in hf.cases:
        missing = [m for name, m in optional.items()
                   if name in (c.components["backend"], c.components["solver"])
                   and importlib.util.find_spec(m) is None]
        assert c.status == ("not_installed" if missing or not netgen else "run"), c
    # ssn: 2 condensations x 2 linear solvers, uzawa: 2 condensations, tao, vi; 2 backends
    assert len(hf.cases) == 2 * (4 + 2 + 1 + 1)
    ssn = {json.dumps(c.solver_options, sort_keys=True) for c in hf.cases
           if c.components["solver"] == "ssn"}
    assert len(ssn) == 4 and all("condensation" in s for s in ssn)
    assert all(c.solver_options == {} for c in hf.cases
               if c.components["solver"].startswith("petsc"))
    rb = load_matrix("sphere_rb", registry=reg)
    assert {c.mode for c in rb.cases} == {"rb"}
    assert {c.status for c in rb.cases} == {"run" if netgen else "not_installed"}
    assert netgen or all("Netgen" in c.reason for c in rb.cases)
    assert {c.scene for c in rb.cases} == {"hertz_sphere@L0", "hertz_sphere@rigid_L0"}
    assert {c.components["hyper"] for c in rb.cases} == {"eim", "none", "affine"}
    assert len(rb.cases) == 2 * 2 * 2 * 3


@pytest.mark.parametrize("table, match", [
    ('[params.solver.ssn]\ncondensation = ["schur", "nope"]\n',
     r"\[params.solver.ssn\]: \{'condensation': 'nope'\}: ValueError: option condensation = "
     r"'nope' is not valid; expected one of 'schur', 'columns'"),
    ('[params.solver.ssn]\nmax_iter = [inf]\n',
     r"\[params.solver.ssn\]: \{'max_iter': inf\}: OverflowError"),
    ('[params.solver.ssn]\ncondensaton = ["schur"]\n',
     r"\[params.solver.ssn\]: \{'condensaton': 'schur'\}: .*condensaton"),
    ('[params.solver.newton]\ntol = [1e-9]\n',
     r"\[params.solver.newton\]: 'newton' is not in \[components\] solver"),
    ('[params.dual.mcpg]\ntol_dual = [0.1]\n',
     r"\[params\] \(mode hf: solver options only\): unknown key\(s\) \['dual'\]"),
    ('[params.solver.uzawa]\nomega = [[1]]\n',
     r"\[params.solver.uzawa\]: omega = \[1\]; expected a string, number or boolean"),
])
def test_mode_hf_solver_options_are_checked_at_load(tmp_path, table, match):
    p = tmp_path / "m.toml"
    p.write_text('[matrix]\nname = "m"\nmode = "hf"\nscenes = ["membrane_obstacle"]\n'
                 '[components]\nsolver = ["ssn", "uzawa"]\n' + table)
    with pytest.raises(MatrixError, match=match):
        load_matrix(p, registry=default_registry())


@pytest.mark.netgen
def test_a_small_sphere_hf_run_gives_3d_rows_and_a_report(tmp_path):
    """sphere_hf on the coarse mesh, skfem, ssn with its four condensation settings, one
    repeat, serial executor: every row ok and 3D; the four settings solve one problem
    exactly (ssn stops on an exact active set): the same force to round-off; the radius
    and Hertz errors of the row are those of the HF summary; the report has the HF table
    and figure."""
    from rbbench.hf.model import solve_hf
    from rbbench.scene.loading import load_scene

    p = _coarse("sphere_hf", tmp_path, {"repeats = 3": "repeats = 1"})
    m = load_matrix(p, selectors=["backend=skfem", "solver=ssn"], registry=default_registry())
    assert len(m.cases) == 4
    t0 = time.perf_counter()
    run_matrix(m, tmp_path / "run", executor="serial", cache_dir=tmp_path / "cache",
               progress=False)
    elapsed = time.perf_counter() - t0
    df = pd.read_parquet(tmp_path / "run" / "results.parquet")
    assert set(df["status"]) == {"ok"} and (df["dim"] == 3).all() and (df["mode"] == "hf").all()
    assert df["contact_half_width"].isna().all()  # the 2D columns stay empty in 3D
    f = df["contact_force"].to_numpy()
    np.testing.assert_allclose(f, f[0], rtol=1e-10)
    scene = load_scene("hertz_sphere", overrides=json.loads(df["scene_overrides"].iloc[0]))
    ref = solve_hf(scene, None, "skfem", "mixed", "ssn", floor=False).metrics
    assert ref["dim"] == 3
    row = df.iloc[0]
    assert row["contact_force"] == pytest.approx(ref["contact_force"], rel=1e-10)
    assert row["contact_radius"] == ref["contact_radius"] > 0
    assert row["contact_radius_gap"] == pytest.approx(ref["contact_radius_gap"], rel=1e-8)
    for k in ("a_rel_error", "a_gap_rel_error", "p0_rel_error"):
        assert row[f"hertz_{k}"] == pytest.approx(ref["hertz"][k], rel=1e-8, abs=1e-12)
    out = report(tmp_path / "run", formats=("png",))
    assert "hf" in out.figures
    md = out.summary_md.read_text()
    assert "## HF solves (4)" in md and "contact_radius" in md
    assert "condensation=columns, linear_solver=superlu" in md
    assert "Best combination" not in md  # an HF-only run has no reduced errors
    print(f"small sphere_hf run: {elapsed:.1f} s")


@pytest.mark.netgen
@pytest.mark.slow
def test_a_small_sphere_rb_run(tmp_path):
    """sphere_rb at small sizes on the coarse mesh, mCPG + PGA only: the EIM and plain
    models run on both scenes and the affine decomposition on the rigid flat; its refusal
    on the two hemispheres is a row with the reason."""
    p = _coarse("sphere_rb", tmp_path, {"pairs = [[20, 20]]": "pairs = [[4, 4]]",
                                        "n_train = 21": "n_train = 6",
                                        "n_valid = 10": "n_valid = 2",
                                        "online_repeats = 5": "online_repeats = 1"})
    m = load_matrix(p, selectors=["dual=mcpg", "stabilizer=pga"], registry=default_registry())
    assert len(m.cases) == 6
    run_matrix(m, tmp_path / "run", executor="serial", cache_dir=tmp_path / "cache",
               progress=False)
    df = pd.read_parquet(tmp_path / "run" / "results.parquet")
    assert (df["dim"] == 3).all()
    st = df.set_index(["scene", "hyper"])["status"]
    assert st[("hertz_sphere@L0", "affine")] != "ok"
    assert "affine" in df.set_index(["scene", "hyper"]).loc[
        ("hertz_sphere@L0", "affine"), "reason"]
    ok = df[df["status"] == "ok"]
    assert len(ok) == 5
    assert (ok["err_u_max"] < 0.5).all() and np.isfinite(ok["err_lam_max"]).all()
    out = report(tmp_path / "run", formats=("png",))
    assert {"pareto", "error_vs_size"} <= set(out.figures)
