"""The bound-driven greedy: HF solves only at its picks, each pick then certified exactly."""

from __future__ import annotations

import numpy as np

from rbbench.hf.components import make_components
from rbbench.hf.model import ProblemCache, solve_hf
from rbbench.rb.algorithms.infsup import make_solver
from rbbench.rb.mixed.greedy import bound_greedy
from rbbench.scene.loading import load_scene
from rbbench.scene.sampling import parameter_set


def test_bound_greedy_on_a_small_membrane():
    sc = load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    comps = make_components(sc)
    at = ProblemCache(comps[0], comps[1], sc)
    X = at.X_free(sc.default_mu)
    free = at(sc.default_mu).free
    solved = []

    def hf(mu):
        solved.append(np.array(mu))
        s = solve_hf(sc, mu, components=comps, floor=False)
        return s.result.u[free], s.result.lam

    train = parameter_set(sc, "train", 40, kind="lhs", seed=3)
    states = []
    g = bound_greedy(at, hf, X, make_solver(X), sc.bounds, train, tol=1e-12, n_max=5,
                     on_step=states.append)
    assert g.stop == "n_max" and g.n_hf == len(solved) == 5 == len(g.picks)
    assert len(set(g.picks[1:])) == 4  # a picked parameter is never picked again
    # the bound of the last model vanishes (to sqrt round-off) at every HF-solved parameter
    for mu in solved:
        res = g.model.solve(mu, path="python", method="daqp")
        assert g.bound(mu, res.c, res.alpha).delta_u <= 1e-5 * np.linalg.norm(res.c)
    # and is positive elsewhere: the picks were the training maxima
    assert all(b > 0 for b in g.max_bound)
    assert [s.n_hf for s in states] == [1, 2, 3, 4, 5]
