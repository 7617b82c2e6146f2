"""The linear scenes without contact (stationary diffusion, the heat equation): their HF
problem and model (:mod:`.model`) and ``rbbench solve`` of them (:mod:`.solve`)."""

from rbbench.hf.linear.model import (
    NO_CONTACT,
    LinearHF,
    LinearProblem,
    hf_row,
    linear_backend,
    linear_snapshots,
    solve_linear,
    space_time_norm,
)

__all__ = ["NO_CONTACT", "LinearHF", "LinearProblem", "hf_row", "linear_backend",
           "linear_snapshots", "solve_linear", "space_time_norm"]
