"""``rbbench solve`` / ``rbbench reduce`` / ``rbbench studies`` on the linear scenes,
through :func:`rbbench.cli.main` and the Python face, against independent values: the
series solution of -Laplace u = 1 on the unit square, the discrete heat balance tested with
v = 1 (computed from the mesh), and the Galerkin compliance identity."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

import rbbench
from rbbench.cli import main
from rbbench.hf.model import solve_hf
from rbbench.scene.loading import SceneError, load_scene

pytestmark = pytest.mark.timeout(120)
SMALL_TB = ["--set", "discretization.n_cells=8"]
SMALL_HEAT = ["--set", "discretization.n_cells=8", "--set", "time.steps=5"]


def _poisson_series(terms: int = 401) -> tuple[float, float]:
    """``int u`` and ``u(1/2, 1/2)`` of ``-Laplace u = 1``, ``u = 0`` on the unit square:
    ``u = sum_{m, n odd} 16 / (pi^4 m n (m^2 + n^2)) sin(m pi x) sin(n pi y)``."""
    m = np.arange(1, terms + 1, 2, dtype=float)[:, None]
    n = m.T
    c = 16.0 / (np.pi ** 4 * m * n * (m ** 2 + n ** 2))
    s = np.sin(m * np.pi / 2) * np.sin(n * np.pi / 2)
    return float(np.sum(c * 4.0 / (m * n * np.pi ** 2))), float(np.sum(c * s))


def _solve(tmp_path, name, *argv) -> dict:
    out = tmp_path / name
    assert main(["solve", *argv, "--out", str(out), "--quiet", "--no-plot"]) == 0
    return json.loads((out / "summary.json").read_text())


def test_solve_thermal_block_matches_the_poisson_series(tmp_path, capsys):
    integral, centre = _poisson_series()
    errs = []
    for n in (32, 64):
        s = _solve(tmp_path, f"tb{n}", "thermal_block", "--mu", "1", "1", "1", "1", "--set",
                   f"discretization.n_cells={n}")
        assert s["formulation"] == "linear" and "n_contact" not in s and "lam" not in s
        assert s["residual_rel"] < 1e-10 and s["u_min"] == 0.0
        errs.append(abs(s["u_integral"] - integral) / integral)
        assert abs(s["u_max"] - centre) / centre < 5e-3
    assert errs[1] < 1.5e-3 and 3.0 < errs[0] / errs[1] < 5.0  # P1: O(h^2)
    out = capsys.readouterr().out
    assert "u_integral" in out and "no contact" in out and "contact_force" not in out
    # A(c mu) = c A(mu): u scales by 1 / c (raw values, no tolerance games)
    s2 = _solve(tmp_path, "tb_half", "thermal_block", "--mu", "0.5", "0.5", "0.5", "0.5",
                "--set", "discretization.n_cells=64")
    assert s2["u_integral"] == pytest.approx(2 * s["u_integral"], rel=1e-10)
    u64 = np.load(tmp_path / "tb64" / "solution.npz")["u"]
    u_half = np.load(tmp_path / "tb_half" / "solution.npz")["u"]
    assert np.allclose(u_half, 2 * u64, rtol=1e-10, atol=1e-14)


def _p1_integrals(npz) -> tuple[np.ndarray, np.ndarray]:
    """``int_Omega u^k`` and ``int_boundary u^k`` of every row of a P1 trajectory, from the
    mesh alone (a P1 function is linear on triangles and edges)."""
    pts, tri, vd = npz["points"], npz["triangles"], npz["vertex_dofs"][:, 0]
    U = npz["u"][:, vd]  # vertex values
    a, b, c = (pts[tri[:, i]] for i in range(3))
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                        - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    vol = (U[:, tri].mean(axis=2) * area).sum(axis=1)
    bnd = np.zeros(len(U))
    for axis, value in ((1, 0.0), (1, 1.0), (0, 0.0), (0, 1.0)):
        on = np.flatnonzero(np.isclose(pts[:, axis], value))
        on = on[np.argsort(pts[on, 1 - axis])]
        bnd += np.trapezoid(U[:, on], pts[on, 1 - axis], axis=1)
    return vol, bnd


def test_solve_heat_robin_satisfies_the_discrete_heat_balance(tmp_path):
    """Implicit Euler tested with v = 1: (int u^k - int u^(k-1)) / dt + h0 int_bd u^k =
    int f = 1 (h0 = 1, f = 1, u0 = 0), each side computed from the mesh."""
    s = _solve(tmp_path, "heat", "heat_robin", "--mu", "0.3", *SMALL_HEAT)
    assert s["steps"] == 5 and s["dt"] == pytest.approx(0.2) and "n_contact" not in s
    npz = np.load(tmp_path / "heat" / "solution.npz")
    assert npz["u"].shape == (6, s["n_dofs"]) and np.allclose(npz["t"], 0.2 * np.arange(6))
    vol, bnd = _p1_integrals(npz)
    assert np.allclose(np.diff(vol) / s["dt"] + bnd[1:], 1.0, rtol=0, atol=1e-10)
    assert vol[-1] == pytest.approx(s["u_integral"], rel=1e-12)


def test_reduce_thermal_block_through_the_cli(tmp_path, capsys):
    out = tmp_path / "red"
    argv = ["reduce", "thermal_block", *SMALL_TB, "-N", "4", "--n-train", "10", "--n-valid",
            "3", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "err_u_max" in text and "effectivity_min" in text and "err_lam" not in text
    assert "X the H1_0 seminorm" in text and "max/mean/min over the validation set" in text
    s = json.loads((out / "result.json").read_text())
    assert s["config"]["formulation"] == "linear" and s["N"] == 4 and s["R"] is None
    err, est = np.array(s["per_mu"]["err_u"]), np.array(s["per_mu"]["err_est"])
    assert s["err_u_max"] == pytest.approx(err.max()) and np.all(est >= err)  # rigorous bound


def test_reduce_heat_robin_through_the_cli(tmp_path, capsys):
    out = tmp_path / "heat"
    argv = ["reduce", "heat_robin", *SMALL_HEAT, "-N", "3", "--n-train", "5", "--n-valid",
            "2", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    assert "L2(0, T; X) norm, X the H1" in capsys.readouterr().out
    s = json.loads((out / "result.json").read_text())
    assert s["N"] == 3 and s["effectivity_min"] >= 1.0


def test_api_reduce_errors_agree_with_the_compliance_identity(tmp_path):
    """Galerkin on a symmetric coercive problem: J - J_N = a(e, e) >= 0 (J = F u, the
    compliance of an independent HF solve), and min mu |e|_1^2 <= a(e, e),
    a(u, u) <= max mu |u|_1^2: the reported err_u (X = |.|_1) is bracketed per mu."""
    scene = load_scene("thermal_block", ["discretization.n_cells=8"])
    res = rbbench.reduce(scene, N=3, n_train=10, n_valid=3, cache_dir=str(tmp_path),
                         online_repeats=1)
    assert res.config["formulation"] == "linear"
    for mu, err in zip(res.valid_mus, res.err_u, strict=True):
        sol = rbbench.solve(scene, mu)
        J = sol.metrics["u_integral"]  # f = 1: F u = int u
        th = res.model.theta(mu)
        J_N = float((th @ res.model.F) @ res.model.solve(mu).u)
        rel = (J - J_N) / J
        assert rel >= -1e-12
        ratio = mu.max() / mu.min()
        assert rel / ratio - 1e-12 <= err ** 2 <= rel * ratio + 1e-12


def test_linear_scene_refuses_contact_choices(tmp_path, capsys):
    scene = load_scene("thermal_block", ["discretization.n_cells=8"])
    with pytest.raises(SceneError, match="option 'dual': not an option of the linear "
                       "formulation .* an option of the mixed formulation"):
        rbbench.reduce(scene, dual="mcpg", cache_dir=str(tmp_path))
    with pytest.raises(SceneError, match="solved by"):
        solve_hf(scene)
    assert main(["reduce", "thermal_block", *SMALL_TB, "--formulation", "nitsche",
                 "--quiet"]) == 2
    assert main(["solve", "thermal_block", *SMALL_TB, "--formulation", "nitsche",
                 "--quiet"]) == 2
    assert "formulation 'linear'" in capsys.readouterr().err


def test_studies_group_lists_and_runs_both(capsys, monkeypatch):
    with pytest.raises(SystemExit) as exc:
        main(["studies", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    assert "pymor-thermal-block" in text and "heat-robin" in text
    monkeypatch.setitem(sys.modules, "pymor", None)  # the not_installed row, quickly
    assert main(["studies", "pymor-thermal-block", "--n-cells", "8", "-N", "3", "--n-train",
                 "8", "--n-valid", "2", "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    assert "| max relative error, H1_0 seminorm |" in out and "pip install pymor" in out
    assert main(["studies", "heat-robin", "--n-cells", "8", "-N", "3", "--repeats", "1"]) == 0
    assert "| N | 25 | 3 |" in capsys.readouterr().out
    # the former name of the subcommand, a deprecated alias
    assert main(["studies", "heat-seed", "--n-cells", "8", "-N", "3", "--repeats", "1"]) == 0
    assert "| N | 25 | 3 |" in capsys.readouterr().out
