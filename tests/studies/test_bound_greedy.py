"""The bound-greedy study's table: the greedy's curve, the comparison line and, when asked
for, the POD's curve (figures from a real run of the membrane, rounded)."""

from __future__ import annotations

from rbbench.studies.bound_greedy import markdown


def _out(pod_curve):
    return {"curve": [{"n_hf": 1, "dim_primal": 2, "R": 1, "max_bound_train": 0.899,
                       "err_u_max_valid": 0.849},
                      {"n_hf": 12, "dim_primal": 24, "R": 12, "max_bound_train": 0.102,
                       "err_u_max_valid": 0.0482}],
            "pod": {"n_hf": 25, "N": 8, "R": 8, "K_pga": 2, "err_u_max_valid": 0.0509},
            "n_train_greedy": 1000, "greedy_reaches_pod_at_n_hf": 12, "hf_ratio": 25 / 12,
            "pod_curve": pod_curve}


def test_table_with_and_without_the_pod_curve():
    plain = markdown(_out([]))
    assert "after 12 HF solves (2.08x fewer)" in plain
    assert "POD: HF solves (training grid)" not in plain
    table = markdown(_out([{"n_hf": 9, "N": 8, "R": 8, "err_u_max_valid": 0.0648},
                           {"n_hf": 16, "N": 8, "R": 8, "err_u_max_valid": 0.0443}]))
    rows = table.split("POD: HF solves (training grid)")[1].splitlines()
    assert rows[2:] == ["| 9 | 8 | 8 | 0.0648 |", "| 16 | 8 | 8 | 0.0443 |"]
