"""The adjoint subgradient of Theta(alpha) = ||lam||_6^6 against central finite differences at
designs where the active sets are stable (1e-5 relative), and the partition of ``gph Q``
(model B table) of the talk "On coupling of complementarity with friction in contact shape
optimization"."""
import numpy as np
import pytest

from rbbench.optim.shape_adjoint import branch_margins, evaluate
from rbbench.optim.shape_scene import load_shape_scene
from rbbench.optim.shape_state import objective, solve_state

COARSE = {"geometry.contact_nodes": 21, "geometry.ny": 8}


def _theta(sc, alpha):
    st = solve_state(sc, alpha, tol=1e-14)
    return objective(sc, st.lam), st


def _central(sc, alpha, d, h):
    (jp, sp), (jm, sm) = _theta(sc, alpha + h * d), _theta(sc, alpha - h * d)
    return (jp - jm) / (2 * h), (sp, sm)


def _richardson(sc, alpha, d, h=1e-6):
    """Central differences at h and h / 2, extrapolated: O(h^4); both active sets recorded."""
    d1, s1 = _central(sc, alpha, d, h)
    d2, s2 = _central(sc, alpha, d, h / 2)
    return (4 * d2 - d1) / 3, s1 + s2


DESIGNS = {
    "parabola": ({}, None),
    "vee, slip-dependent F": ({"design.initial": "vee", "design.initial_height": 0.12,
                               "friction.slip_scale": 0.01}, None),
}


@pytest.mark.parametrize("name", list(DESIGNS))
def test_subgradient_matches_central_differences(name):
    over, _ = DESIGNS[name]
    sc = load_shape_scene(overrides={**COARSE, **over})
    alpha = sc.initial_design()
    ev = evaluate(sc, alpha)
    m = branch_margins(sc, ev.state)
    assert m["contact"] > 1e-3 and m["friction"] > 1e-4, m    # strict complementarity
    rng = np.random.default_rng(7)
    checked = 0
    mid = np.eye(len(alpha))[len(alpha) // 2]
    for d in [rng.standard_normal(len(alpha)) for _ in range(2)] + [mid]:
        fd, states = _richardson(sc, alpha, d)
        for s in states:                                    # the active sets did not move
            assert (s.contact == ev.state.contact).all()
            assert (s.stick == ev.state.stick).all()
        assert abs(ev.xi @ d - fd) <= 1e-5 * abs(fd), (ev.xi @ d, fd)
        checked += 1
    assert checked == 3


def test_slip_dependence_enters_the_subgradient():
    """With F varying on the slip scale the F' term changes xi (else the test above is moot)."""
    base = {**COARSE, "design.initial": "vee", "design.initial_height": 0.12}
    a = evaluate(load_shape_scene(overrides={**base, "friction.slip_scale": 0.01}),
                 load_shape_scene(overrides=base).initial_design())
    assert a.partition["sliding"] > 0
    sc_const = load_shape_scene(overrides={**base, "friction.slip_scale": 1e6})
    b = evaluate(sc_const, sc_const.initial_design())
    assert np.linalg.norm(a.xi - b.xi) > 1e-3 * np.linalg.norm(b.xi)


def test_partition_counts_cover_the_contact_nodes():
    sc = load_shape_scene(overrides=COARSE)
    ev = evaluate(sc, sc.initial_design())
    p = ev.partition
    assert p["no_contact"] + p["weak_contact"] + p["strong_contact"] == sc.n_contact
    assert p["no_contact"] > 0 and p["strong_contact"] > 0


def test_every_component_matches_central_differences():
    """The whole FD gradient (h = 1e-6, Richardson) against xi, relative to max |xi|.

    A component of a node out of contact is ~1e-5 of the largest one: there the FD quotient
    is at its round-off level, so the test measures all components in the max norm.
    """
    sc = load_shape_scene(overrides=COARSE)
    alpha = sc.initial_design()
    ev = evaluate(sc, alpha)
    fd = np.array([_richardson(sc, alpha, e)[0] for e in np.eye(len(alpha))])
    assert np.abs(fd - ev.xi).max() <= 1e-5 * np.abs(ev.xi).max()
