"""3D Hertz reference against independent facts: equilibrium of the profile, the inverted
approach-load law, Johnson's closed forms and the half-space surface displacement."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from rbbench.hf.references.hertz3d import (
    hertz3d_of_bodies,
    hertz_3d,
    hertz_3d_at_approach,
    hertz_3d_load,
)

loads = st.floats(1e2, 1e8)
radii = st.floats(0.1, 5.0)
moduli = st.floats(1e9, 3e11)
poisson = st.floats(0.0, 0.45)


@settings(max_examples=50, deadline=None)
@given(loads, radii, radii, moduli, poisson, moduli, poisson)
def test_the_profile_integrates_to_the_load_and_the_approach_law_inverts(P, R1, R2, E1, n1,
                                                                         E2, n2):
    h = hertz_3d(P, R1, R2, E1, n1, E2, n2)
    force, _ = quad(lambda r: 2.0 * math.pi * r * float(h.pressure(r)), 0.0, h.a,
                    epsabs=0.0, epsrel=1e-11, limit=200)
    assert force == pytest.approx(P, rel=1e-9)
    assert h.pressure(1.0001 * h.a) == 0.0
    assert hertz_3d_load(h.delta, h.R_star, h.E_star) == pytest.approx(P, rel=1e-12)
    back = hertz_3d_at_approach(h.delta, R1, R2, E1, n1, E2, n2)
    assert back.P == pytest.approx(P, rel=1e-12)
    assert back.a == pytest.approx(h.a, rel=1e-12)
    assert back.p0 == pytest.approx(h.p0, rel=1e-12)


@settings(max_examples=50, deadline=None)
@given(loads, radii, radii, moduli, poisson, moduli, poisson)
def test_johnsons_closed_forms(P, R1, R2, E1, n1, E2, n2):
    """Johnson (1985) eqs. 4.22-4.24 in their other forms:
    ``p0 = (6 P E*^2 / (pi^3 R*^2))^(1/3)``, ``a = pi p0 R* / (2 E*)``,
    ``delta = (9 P^2 / (16 R* E*^2))^(1/3)``, with R*, E* from the two bodies."""
    h = hertz_3d(P, R1, R2, E1, n1, E2, n2)
    Rs = 1.0 / (1.0 / R1 + 1.0 / R2)
    Es = 1.0 / ((1 - n1**2) / E1 + (1 - n2**2) / E2)
    assert h.R_star == pytest.approx(Rs, rel=1e-13)
    assert h.E_star == pytest.approx(Es, rel=1e-13)
    assert h.p0 == pytest.approx((6 * P * Es**2 / (math.pi**3 * Rs**2)) ** (1 / 3), rel=1e-12)
    assert h.a == pytest.approx(math.pi * h.p0 * Rs / (2 * Es), rel=1e-12)
    assert h.delta == pytest.approx((9 * P**2 / (16 * Rs * Es**2)) ** (1 / 3), rel=1e-12)


def test_surface_displacement_of_the_half_spaces_closes_the_gap_inside_the_contact():
    """Johnson eq. 3.41a: the pressure ``p0 sqrt(1 - r^2/a^2)`` displaces a half-space
    surface by ``(1 - nu^2)/E pi p0 (2 a^2 - r^2) / (4 a)`` for r <= a; the two bodies'
    displacements add to ``delta - r^2 / (2 R*)`` (the spheres' initial separation closed)."""
    E1, n1, E2, n2 = 2.1e11, 0.3, 7.0e10, 0.33
    h = hertz_3d(5.0e4, 1.2, 0.8, E1, n1, E2, n2)
    r = np.linspace(0.0, h.a, 11)
    disp = sum((1 - n**2) / E * math.pi * h.p0 * (2 * h.a**2 - r**2) / (4 * h.a)
               for E, n in ((E1, n1), (E2, n2)))
    assert np.allclose(disp, h.delta - r**2 / (2 * h.R_star), rtol=1e-12)


def test_a_rigid_flat_keeps_the_sphere_radius_and_modulus():
    h = hertz_3d(1.0e3, 0.9, None, 2.0e11, 0.3)
    assert h.R_star == 0.9
    assert h.E_star == pytest.approx(2.0e11 / (1 - 0.3**2), rel=1e-14)
    assert hertz_3d(1.0e3, 0.9, math.inf, 2.0e11, 0.3, math.inf, None).a == h.a


def test_of_bodies_reads_radii_and_materials():
    class Body:
        def __init__(self, E, nu):
            self.E, self.nu = E, nu

    geo = {"R1": 1.1, "R2": 1.0}
    h = hertz3d_of_bodies(2.0e3, geo, [Body(1e9, 0.25), Body(2e9, 0.35)])
    assert h == hertz_3d(2.0e3, 1.1, 1.0, 1e9, 0.25, 2e9, 0.35)
    assert hertz3d_of_bodies(2.0e3, {"R1": 1.1, "R2": None}, [Body(1e9, 0.25)]) \
        == hertz_3d(2.0e3, 1.1, None, 1e9, 0.25)


@pytest.mark.parametrize(("kw", "match"), [
    ({"P": 0.0}, "P = 0.0 must be finite and > 0"),
    ({"P": math.nan}, "P = nan must be finite"),
    ({"R1": -1.0}, "R1 = -1.0 must be finite and > 0"),
    ({"nu1": 0.5}, r"nu1 = 0.5 must lie in \(-1, 0.5\)"),
    ({"E2": 1e9}, r"nu2 = None must lie in \(-1, 0.5\) with E2"),
])
def test_bad_input_names_the_quantity(kw, match):
    args = {"P": 1.0, "R1": 1.0, "R2": None, "E1": 1e9, "nu1": 0.3} | kw
    with pytest.raises(ValueError, match=match):
        hertz_3d(**args)
