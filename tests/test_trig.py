"""engine/trig.py: the photon pass's cos / sin of a turn against long-double references
(the true values to ~1e-19) and against libm."""
import math

import numpy as np
import pytest
from numba import njit

from engine.trig import sincos_small, sincos_turn

EXTENDED = np.finfo(np.longdouble).eps < 1e-18  # x86's 80-bit long double


@njit
def _turns(u, c, s):
    for i in range(u.shape[0]):
        c[i], s[i] = sincos_turn(u[i])


def _numbers():
    rng = np.random.default_rng(5)
    eighths = np.arange(9) / 8.0
    edges = np.concatenate([eighths, np.nextafter(eighths, -1.0), np.nextafter(eighths, 2.0),
                            [5e-324, 1e-300, 1e-17, 2.0 ** -53]])
    # uniform()'s grid (k 2^-53) and arbitrary doubles in [0, 1]
    grid = np.floor(rng.random(100_000) * 2.0 ** 53) * 2.0 ** -53
    u = np.concatenate([rng.random(100_000), grid, edges])
    return u[(u >= 0.0) & (u <= 1.0)]


@pytest.mark.skipif(not EXTENDED, reason="needs an extended long double for the reference")
def test_sincos_turn_within_2e16_of_the_true_values():
    u = _numbers()
    c, s = np.empty_like(u), np.empty_like(u)
    _turns(u, c, s)
    turn = 2 * np.arccos(np.longdouble(-1.0)) * u.astype(np.longdouble)
    assert float(np.max(np.abs(c - np.cos(turn)))) <= 2e-16
    assert float(np.max(np.abs(s - np.sin(turn)))) <= 2e-16
    # libm's cos(fl(2 pi u)) carries the argument's rounding (up to 4.4e-16 rad): the two
    # differ by less than that plus both errors
    lc, ls = np.cos(2.0 * math.pi * u), np.sin(2.0 * math.pi * u)
    assert np.max(np.abs(c - lc)) <= 8e-16 and np.max(np.abs(s - ls)) <= 8e-16


def test_sincos_turn_exact_at_the_quadrants_and_unit_length():
    for u, (ec, es) in ((0.0, (1.0, 0.0)), (0.25, (0.0, 1.0)), (0.5, (-1.0, 0.0)),
                        (0.75, (0.0, -1.0)), (1.0, (1.0, 0.0))):
        assert sincos_turn(u) == (ec, es)
    u = _numbers()
    c, s = np.empty_like(u), np.empty_like(u)
    _turns(u, c, s)
    assert np.max(np.abs(c * c + s * s - 1.0)) <= 5e-16


def test_sincos_small_against_libm_on_its_range():
    for t in np.linspace(-math.pi / 4, math.pi / 4, 2001):
        c, s = sincos_small(t)
        assert abs(c - math.cos(t)) <= 3e-16 and abs(s - math.sin(t)) <= 3e-16
