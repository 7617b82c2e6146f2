"""Hardening of ``rbbench reduce`` on the cheap membrane scene (seconds): the
dimensionless inf-sup constants beside the raw ones, progress during validation, the HF
snapshot time, ``-N`` beyond the training set."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from rbbench.cli import main
from rbbench.hf.components import make_components
from rbbench.hf.model import ProblemCache
from rbbench.hf.snapshots.cache import cache_path, load_snapshot
from rbbench.hf.snapshots.key import snapshot_key
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.config import make_config
from rbbench.rb.offline import reduce
from rbbench.scene.loading import load_scene
from rbbench.scene.sampling import parameter_set

FAST = ["discretization.n_cells=8"]


@pytest.fixture(scope="module")
def scene():
    return load_scene("membrane_obstacle", FAST)


@pytest.fixture(scope="module")
def reduced(scene, tmp_path_factory):
    """mCPG + PGA (rows hf, dec, on, off), 3 validation mus; the progress lines kept."""
    cache = tmp_path_factory.getbasetemp() / "cache_hardening"
    lines: list[str] = []
    cfg = make_config(dual="mcpg", stabilizer="pga", n_jobs=1, n_train=9, n_valid=3,
                       cache_dir=str(cache), online_repeats=1)
    res = reduce(scene, cfg, progress=lines.append)
    return res, lines


def test_span_constants_dense_and_scale_free():
    """span_constants = (sqrt(lambda_min), sqrt(lambda_max)) of the pencil (dense eigh,
    independent), and the ratio beta / c does not change when X (hence S) is rescaled."""
    rng = np.random.default_rng(0)
    C = rng.standard_normal((7, 5))
    S, M = C.T @ C, np.diag(rng.uniform(0.5, 2.0, 5))
    w = sla.eigh(S, M, eigvals_only=True)
    beta, c = inf.span_constants(S, M)
    assert beta == pytest.approx(np.sqrt(w[0]), rel=1e-10)
    assert c == pytest.approx(np.sqrt(w[-1]), rel=1e-10)
    assert (beta, c) == (inf.infsup_span(S, M), inf.boundedness_constant(S, M))
    b2, c2 = inf.span_constants(S / 2e11, 3.0 * M)  # X scaled by E, W by 3
    assert b2 / c2 == pytest.approx(beta / c, rel=1e-10)
    assert b2 == pytest.approx(beta / np.sqrt(6e11), rel=1e-10)


def test_beta_rows_normalised_by_c_hf(scene, reduced):
    """value_rel = value / c_HF(mu) for every row, c_HF recomputed densely (independent of
    the factorised supremizer operator); every ratio <= 1 (beta <= c_HF: a property of the
    raw values); summary keys are the minima of the rows."""
    res, _ = reduced
    s = res.summary()
    assert set(res.beta) == {"hf", "dec", "on", "off"}
    b, f, _ = make_components(scene)  # the problem at the first validation mu
    p = ProblemCache(b, f, scene)(res.valid_mus[0])
    X = p.X[p.free][:, p.free].toarray()
    B = p.B.toarray() if sp.issparse(p.B) else np.asarray(p.B)
    W = p.W.toarray() if sp.issparse(p.W) else np.asarray(p.W)
    c_dense = np.sqrt(sla.eigh(B @ np.linalg.solve(X, B.T), W, eigvals_only=True)[-1])
    assert res.beta["hf"][0]["c"] == pytest.approx(c_dense, rel=1e-8)
    for name, rows in res.beta.items():
        for j, r in enumerate(rows):
            c_hf = res.beta["hf"][j]["c"]
            assert r["value_rel"] == pytest.approx(r["value"] / c_hf, rel=1e-12)
            assert r["span_rel"] == pytest.approx(r["span"] / c_hf, rel=1e-12)
            assert r["value"] <= c_hf * (1 + 1e-9) and r["value_rel"] <= 1 + 1e-9
        assert s[f"beta_{name}_rel_min"] == pytest.approx(min(r["value_rel"] for r in rows))
        assert s[f"beta_{name}_span_rel_min"] == pytest.approx(
            min(r["span_rel"] for r in rows))
        assert s[f"beta_{name}_zero_undecided"] == 0
    assert "c_HF" in res.definitions["beta"] and "beta_<name>_rel_min" in \
        res.definitions["beta_rel"]


def test_validation_progress_per_mu(reduced):
    """One progress line per validation mu, in order, after the announcement."""
    _, lines = reduced
    i = next(k for k, x in enumerate(lines) if x.startswith("online validation (3 mus"))
    per_mu = [x for x in lines[i + 1:] if x.startswith("online validation ")]
    assert [x.split(":")[0] for x in per_mu] == [f"online validation {j}/3" for j in (1, 2, 3)]


def test_reduce_cli_progress_respects_quiet(tmp_path, capsys, monkeypatch):
    """``rbbench reduce`` prints the per-mu lines on stderr, none with --quiet."""
    monkeypatch.chdir(tmp_path)  # the snapshot cache goes to ./.rbbench_cache
    args = ["reduce", "membrane_obstacle", "--set", FAST[0], "--n-train", "5", "--n-valid",
            "2", "--jobs", "1", "--dual", "cpg", "--stabilizer", "none", "--out",
            str(tmp_path / "red")]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "online validation 1/2" in err and "online validation 2/2" in err
    assert main([*args, "--quiet"]) == 0
    assert "online validation" not in capsys.readouterr().err


def test_snapshot_hf_time_from_the_cache(scene, reduced, tmp_path_factory):
    """t_snapshots_hf_s is the sum of the HF times stored with the training snapshots (read
    back from the cache files), the same when a second run reads them from the cache;
    t_offline_s of the first (serial) run contains them, t_offline_hf_s is the stated
    formula."""
    res, _ = reduced
    s = res.summary()
    cache = tmp_path_factory.getbasetemp() / "cache_hardening"
    key = snapshot_key(scene)
    mus = res.config["n_train"]
    files = sorted((cache / key).glob("mu_*.npz"))
    assert len(files) == mus + 3
    stored = sum(load_snapshot(cache_path(cache, key, mu)).time_s
                 for mu in parameter_set(scene, "train", mus))
    assert s["t_snapshots_hf_s"] == pytest.approx(stored, rel=1e-12)
    assert s["n_snapshots_cached"] == 0
    assert s["timings"]["snapshots_s"] >= s["t_snapshots_hf_s"]  # serial: wall >= sum
    assert s["t_offline_hf_s"] == pytest.approx(
        s["t_offline_s"] - s["timings"]["snapshots_s"] + s["t_snapshots_hf_s"])
    again = reduce(scene, make_config(dual="cpg", stabilizer="none", n_jobs=1, n_train=9,
                                       n_valid=3, cache_dir=str(cache), online_repeats=1))
    s2 = again.summary()
    assert s2["n_snapshots_cached"] == mus + 3
    assert s2["t_snapshots_hf_s"] == s["t_snapshots_hf_s"]
    assert s2["t_snapshots_hf_valid_s"] == s["t_snapshots_hf_valid_s"] > 0
    for k in ("t_offline_s", "t_snapshots_hf_s", "t_offline_hf_s", "n_snapshots_cached"):
        assert k in s2["definitions"], k


def test_n_above_training_set_clipped_with_warning(tmp_path, capsys, monkeypatch):
    """-N larger than the training set: clipped to it (N in result.json the size built, equal
    to the POD's count of modes), with the warning naming -N and the maximum in result.json
    and on the console."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "red"
    code = main(["reduce", "membrane_obstacle", "--set", FAST[0], "--n-train", "9", "-N", "10",
                 "--jobs", "1", "--dual", "cpg", "--stabilizer", "none", "--n-valid", "2",
                 "--out", str(out)])
    assert code == 0
    cap = capsys.readouterr()
    res = json.loads((out / "result.json").read_text())
    assert res["n_train"] == 9 and res["N"] == len(res["histories"]["pod_singular_values"])
    assert res["N"] <= 9
    assert res["warnings"] == [f"-N 10: the basis built has {res['N']} only (at most the 9 "
                               "training snapshots; clipped)"]
    assert "WARNING: -N 10" in cap.out and "WARNING: -N 10" in cap.err


def test_n_above_numerical_rank_warns(scene, tmp_path_factory, monkeypatch, capsys):
    """-N within the training set but above the POD's numerical rank (its eigenvalue cut-off
    raised for the test): the basis built is smaller, and result.json and the console say
    so."""
    import rbbench.rb.algorithms.pod as pod_mod
    from rbbench.cli.console import _print_reduce_summary

    monkeypatch.setattr(pod_mod, "EIG_DROP", 1e-4)
    cache = tmp_path_factory.getbasetemp() / "cache_hardening"
    lines: list[str] = []
    res = reduce(scene, make_config(dual="cpg", stabilizer="none", n_jobs=1, n_train=9,
                                     n_valid=3, N=9, cache_dir=str(cache), online_repeats=1),
                 progress=lines.append)
    s = res.summary()
    rank = len(s["histories"]["pod_singular_values"])
    assert s["N"] == rank < 9
    assert s["warnings"] == [f"-N 9: the basis built has {rank} only (the numerical rank of "
                             "the 9 training snapshots; clipped)"]
    assert any(x.startswith("WARNING: -N 9") for x in lines)
    _print_reduce_summary(s, "mixed")
    assert "WARNING: -N 9" in capsys.readouterr().out
