"""cos and sin of a turn for the photon pass's sampling kernels, without libm.

The photon pass samples an azimuth phi = 2 pi u from a uniform number u in [0, 1) for
every diffuse bounce (engine/photonkernels.py) and most emitted photons (cosine
hemisphere, sphere and cone directions, engine/lights/emission.py): ~2-3M (cos, sin)
pairs a render. libm's `sincos` reduces an arbitrary argument (Payne-Hanek for large
ones) and costs ~18 ns a call here; the angle of a turn needs none of that:

  q = round(4 u)           quadrant, 0..4 (4 is quadrant 0 of the next turn)
  f = u - q / 4            exact (u and q / 4 share a grid, |f| <= 1/8)
  t = 2 pi f               |t| <= pi / 4, one rounding
  cos t, sin t             Taylor polynomials in t^2 (terms to t^16 / t^17: the first
                           term left out is < 2e-18 at pi / 4), Horner's rule
  (cos, sin)(2 pi u)       the quadrant's rotation of (cos t, sin t): exact sign swaps

Accuracy (tests/test_trig.py, against long-double references on 2M numbers): |error|
<= 1.8e-16 of the true cos(2 pi u), sin(2 pi u), where libm's cos(fl(2 pi u)) is off by
up to 7e-16 (its argument's rounding: fl(2 pi u) is off by up to 4.4e-16 rad near u = 1);
the two agree bit for bit on ~22 % of the numbers. 11.6 ns a pair against libm's 19.8 in
a compiled loop (docs/performance.md, photonpass2). The camera pass keeps libm (its
results stay bitwise); only the photon pass's sampling uses this.
"""
from __future__ import annotations

import math

from .jit import kernel

TWO_PI = 2.0 * math.pi

# 1 / n! for the Taylor series of cos (even n) and sin (odd n), highest first.
_C16 = 1.0 / 20922789888000.0
_C14 = -1.0 / 87178291200.0
_C12 = 1.0 / 479001600.0
_C10 = -1.0 / 3628800.0
_C8 = 1.0 / 40320.0
_C6 = -1.0 / 720.0
_C4 = 1.0 / 24.0
_C2 = -1.0 / 2.0
_S17 = 1.0 / 355687428096000.0
_S15 = -1.0 / 1307674368000.0
_S13 = 1.0 / 6227020800.0
_S11 = -1.0 / 39916800.0
_S9 = 1.0 / 362880.0
_S7 = -1.0 / 5040.0
_S5 = 1.0 / 120.0
_S3 = -1.0 / 6.0


@kernel
def sincos_small(t):
    """(cos t, sin t) for |t| <= pi / 4 (radians), to ~2 ulp of 1."""
    t2 = t * t
    c = _C16
    c = c * t2 + _C14
    c = c * t2 + _C12
    c = c * t2 + _C10
    c = c * t2 + _C8
    c = c * t2 + _C6
    c = c * t2 + _C4
    c = c * t2 + _C2
    c = c * t2 + 1.0
    s = _S17
    s = s * t2 + _S15
    s = s * t2 + _S13
    s = s * t2 + _S11
    s = s * t2 + _S9
    s = s * t2 + _S7
    s = s * t2 + _S5
    s = s * t2 + _S3
    s = (s * t2) * t + t
    return c, s


@kernel
def sincos_turn(u):
    """(cos(2 pi u), sin(2 pi u)) for a fraction of a turn u in [0, 1] (the module
    docstring: quadrant reduction, then sincos_small)."""
    q = math.floor(4.0 * u + 0.5)
    c, s = sincos_small(TWO_PI * (u - 0.25 * q))
    k = int(q) & 3
    if k == 0:
        return c, s
    if k == 1:
        return -s, c
    if k == 2:
        return -c, -s
    return s, -c
