"""Cattaneo-Mindlin partial slip (rbbench.hf.references.hertz.mindlin_2d) against its own theory."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from rbbench.hf.references.hertz import hertz_2d, mindlin_2d, mindlin_from_hertz

HERTZ = hertz_2d(1.0e5, 0.5, 0.5, 2.0e11, 0.3)
F = 0.2


@pytest.mark.parametrize("ratio", [0.0, 0.1, 0.5, 0.9, 0.999])
def test_shear_traction_integrates_to_q(ratio):
    Q = ratio * F * HERTZ.P
    mi = mindlin_from_hertz(HERTZ, Q, F)
    pts = [-mi.c, mi.c] if 0 < mi.c < mi.a else None
    total = quad(mi.shear_traction, -mi.a, mi.a, points=pts, limit=200, epsabs=0,
                 epsrel=1e-12)[0]
    if Q == 0:
        assert abs(total) <= 1e-9 * F * HERTZ.P
    else:
        assert abs(total - Q) <= 1e-6 * Q


def test_continuity_at_the_stick_edge_and_slip_zone_traction():
    mi = mindlin_from_hertz(HERTZ, 0.5 * F * HERTZ.P, F)
    eps = 1e-12 * mi.a  # the stick term has a square-root edge: jump ~ sqrt(2 eps / c)
    for c in (mi.c, -mi.c):
        left, mid, right = mi.shear_traction(np.array([c - eps, c, c + eps]))
        assert abs(left - right) <= 1e-5 * F * mi.p0
        assert mid == F * HERTZ.pressure(np.array([c]))[0]
    x = np.linspace(mi.c, mi.a, 50)
    assert np.allclose(mi.shear_traction(x), F * HERTZ.pressure(x), rtol=0,
                       atol=1e-12 * F * mi.p0)
    assert np.allclose(mi.shear_traction(-x), F * HERTZ.pressure(x), rtol=0,
                       atol=1e-12 * F * mi.p0)
    assert np.all(mi.shear_traction(np.array([-2 * mi.a, 1.01 * mi.a])) == 0.0)
    inside = np.linspace(-0.99 * mi.c, 0.99 * mi.c, 41)
    assert np.all(mi.shear_traction(inside) < F * HERTZ.pressure(inside))


def test_stick_zone_limits():
    a, P = HERTZ.a, HERTZ.P
    assert mindlin_2d(P, 0.0, F, a, HERTZ.p0).c == a
    assert abs(mindlin_2d(P, 1e-12 * F * P, F, a, HERTZ.p0).c - a) <= 1e-11 * a
    c = mindlin_2d(P, (1 - 1e-10) * F * P, F, a, HERTZ.p0).c
    assert c <= 1e-4 * a
    assert math.isclose(mindlin_2d(P, 0.75 * F * P, F, a, HERTZ.p0).c, 0.5 * a, rel_tol=1e-14)


@pytest.mark.parametrize(("kwargs", "word"), [
    ({"Q": F * HERTZ.P}, "Q"), ({"Q": 2 * F * HERTZ.P}, "F P"), ({"Q": -1.0}, "Q"),
    ({"F": -0.1}, "F"), ({"P": 0.0}, "P"), ({"a": float("nan")}, "a"),
    ({"p0": 2 * HERTZ.p0}, "p0"),
])
def test_bad_input_raises_naming_the_quantity(kwargs, word):
    args = {"P": HERTZ.P, "Q": 0.5 * F * HERTZ.P, "F": F, "a": HERTZ.a, "p0": HERTZ.p0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=word):
        mindlin_2d(**args)
