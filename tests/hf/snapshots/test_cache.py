"""hf.snapshots.cache: a cached snapshot is used only when its checksum matches its
content; a modified, corrupted or older file is recomputed (a warning names a modified or
corrupted one)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from rbbench.hf.snapshots.cache import (
    CHECKED,
    Snapshot,
    load_if_complete,
    save_snapshot,
    verify,
)


def _snap() -> Snapshot:
    rng = np.random.default_rng(0)
    return Snapshot(mu=np.array([0.3, 5.0]), u=rng.standard_normal(12), lam=rng.random(5),
                    iterations=4, stop_reason="converged", time_s=0.1,
                    free=np.arange(12), n_dofs=14)


def _rewrite(path, **changes):
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    data.update(changes)
    np.savez(path, **data)


def test_a_saved_snapshot_round_trips(tmp_path):
    p = tmp_path / "s.npz"
    save_snapshot(p, _snap())
    assert verify(p) is None
    got = load_if_complete(p, np.array([0.3, 5.0]))
    assert np.array_equal(got.u, _snap().u) and got.iterations == 4


@pytest.mark.parametrize("change, why", [
    ({"u": _snap().u * 1000}, "checksum does not match"),
    ({"lam": np.full(5, np.nan)}, "checksum does not match"),
    ({"stop_reason": np.str_("max_iterations")}, "checksum does not match"),
])
def test_a_modified_file_is_recomputed_with_a_warning(tmp_path, change, why):
    p = tmp_path / "s.npz"
    save_snapshot(p, _snap())
    _rewrite(p, **change)
    assert why in verify(p)
    with pytest.warns(RuntimeWarning, match=f"{p.name}: cached snapshot not used.*{why}"):
        assert load_if_complete(p, np.array([0.3, 5.0])) is None


def test_a_consistent_but_non_finite_or_misshapen_file_is_refused(tmp_path):
    from rbbench.hf.snapshots.cache import checksum

    p = tmp_path / "s.npz"
    for u, why in ((np.full(12, np.inf), "non-finite"), (np.zeros(7), "7 entries for 12")):
        save_snapshot(p, _snap())
        with np.load(p, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
        data["u"] = u
        data["checksum"] = np.str_(checksum({k: data[k] for k in CHECKED}))
        np.savez(p, **data)
        assert why in verify(p)


def test_an_older_file_without_checksum_is_recomputed_silently(tmp_path):
    p = tmp_path / "s.npz"
    save_snapshot(p, _snap())
    with np.load(p, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files if k != "checksum"}
    np.savez(p, **data)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_if_complete(p, np.array([0.3, 5.0])) is None
