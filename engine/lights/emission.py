"""Photon emission in compiled kernels: what every light kind's emit kernels share.

Each light kind emits with kernels of its own module (point.py, spot.py, area.py, sun.py,
mesh.py, world.py), reached through two methods of engine/lights/base.py's Light:

  emit_into(key, first, n, count, out, start)            natural emission
  emit_towards_into(key, first, n, count, aim, out, start)  aimed at caustic casters

Photon i of a call is the photon in slot first + i of its chunk. Its origin, direction and
power are written straight into `out` (EmissionBuffers: float32 origins and directions for
Embree, float64 directions and power, slots), compacted: photons of no power (outside a
spot's mask, aimed outside a one-sided light's hemisphere) take no row. Power per photon is
the light's flux / count (count: the light's photons over all chunks), so the chunks' sum
is the flux.

Random numbers: the photon's slot owns them, as in the scattering kernels
(engine/photonkernels.py, SplitMix64 at counter (slot, bounce, dimension)); emission reads
dimension `dim` at the reserved bounce EMIT_BOUNCE - dim // N_DIMS, beyond any bounce a
photon can take (settings cap max_photon_depth far below). Same seed = same photons for any
thread count.

Aiming (POV-Ray-style photon targets): a finite light picks a caster's bounding sphere in
proportion to the solid angle it subtends from the light (aim_weights), a direction
uniformly in that sphere's cone, and weights the photon by natural pdf / aimed pdf, the
aimed pdf being the mixture over every sphere whose cone holds the direction
(aim_direction). Lights at infinity pick a caster's shadow disk by its area and weight by
the natural disk's density over the aimed one (aim_origin).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel, register_warm_up
from ..photonkernels import MAX_BOUNCES, N_DIMS, uniform
from ..trig import sincos_turn

EMIT_BOUNCE = MAX_BOUNCES - 1  # emission counts bounces down from here
TWO_PI = 2.0 * math.pi
PI_4 = math.pi / 4.0
PI_2 = math.pi / 2.0


@kernel
def emit_uniform(key, slot, dim):
    """Uniform number `dim` of the emission of the photon in `slot` (module docstring)."""
    return uniform(key, slot, EMIT_BOUNCE - dim // N_DIMS, dim % N_DIMS)


@kernel
def meets_sphere(o0, o1, o2, d0, d1, d2, c0, c1, c2, r, infinite):
    """Whether a photon (origin o, unit direction d, float64) meets the sphere (centre c,
    radius r) as aimed emission could have drawn it (aim_origin / aim_direction): a light
    at infinity (infinite) when the line passes within r of c (the sphere's shadow
    disk); a finite light when d lies in the cone from o holding the sphere, or o lies
    inside it. Operation for operation as the numpy it replaced
    (visualimportance.meets_spheres before issue 13's s17: same booleans)."""
    t0 = c0 - o0
    t1 = c1 - o1
    t2 = c2 - o2
    along = t0 * d0 + t1 * d1 + t2 * d2
    dist2 = t0 * t0 + t1 * t1 + t2 * t2
    if infinite:
        return dist2 - along * along <= r * r
    if cone_misses(dist2, along, r):
        return False  # the test below's answer, without its square roots
    dist = math.sqrt(dist2)
    cos_max = math.sqrt(max(0.0, 1.0 - r * r / max(dist2, 1e-300)))
    return dist <= r or along >= cos_max * dist


@kernel
def sphere_meets(o, d, centers, radii, infinite, out):
    """meets_sphere for photons (origins o, unit directions d (N,3) float64) and spheres
    (centers (K,3), radii (K,)). out (N, K) bool: sphere by sphere; out (N, 1) with K > 1:
    whether any sphere (the test stops at the first met)."""
    n, K = o.shape[0], radii.shape[0]
    each = out.shape[1] == K
    for i in range(n):
        met_any = False
        for k in range(K):
            met = meets_sphere(o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2],
                               centers[k, 0], centers[k, 1], centers[k, 2], radii[k],
                               infinite)
            if each:
                out[i, k] = met
            elif met:
                met_any = True
                break
        if not each:
            out[i, 0] = met_any


@kernel
def drop_meeting(o32, d32, d, power, slot, lo, hi, centers, radii, infinite):
    """Rows lo .. hi - 1 of an emission's output (EmissionBuffers' arrays) compacted in
    place, in order, to the photons that meet none of the spheres (meets_sphere on the
    float64 origin, as visualimportance.meets_region tests them); returns the new end.
    The region emitter's cull of its natural photons in one pass (before: float64 copies
    of the origins, a mask and five boolean-indexed copies)."""
    j = lo
    for i in range(lo, hi):
        o0, o1, o2 = np.float64(o32[i, 0]), np.float64(o32[i, 1]), np.float64(o32[i, 2])
        met = False
        for k in range(radii.shape[0]):
            if meets_sphere(o0, o1, o2, d[i, 0], d[i, 1], d[i, 2], centers[k, 0],
                            centers[k, 1], centers[k, 2], radii[k], infinite):
                met = True
                break
        if met:
            continue
        if j != i:
            for c in range(3):
                o32[j, c] = o32[i, c]
                d32[j, c] = d32[i, c]
                d[j, c] = d[i, c]
                power[j, c] = power[i, c]
            slot[j] = slot[i]
        j += 1
    return j


# ---------------------------------------------------------------------- sampling, scalar
# One direction at a time, operation for operation as engine/sampling.py's numpy versions,
# but for the azimuth's cos and sin: engine/trig.sincos_turn (not libm; within 2e-16 of
# the true values, not bitwise numpy's). concentric_disk keeps libm: the camera pass's
# light sampling (engine/directlight.py) shares it.

@kernel
def uniform_sphere(u1, u2):
    z = 1.0 - 2.0 * u1
    r = math.sqrt(max(0.0, 1.0 - z * z))
    c, s = sincos_turn(u2)
    return r * c, r * s, z


@kernel
def cosine_hemisphere(u1, u2):
    r = math.sqrt(u1)
    c, s = sincos_turn(u2)
    return r * c, r * s, math.sqrt(max(0.0, 1.0 - u1))


@kernel
def uniform_cone(u1, u2, cos_max):
    z = 1.0 - u1 * (1.0 - cos_max)
    r = math.sqrt(max(0.0, 1.0 - z * z))
    c, s = sincos_turn(u2)
    return r * c, r * s, z


@kernel
def concentric_disk(u1, u2):
    """Shirley-Chiu: a uniform point on the unit disk."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    if abs(a) > abs(b):
        r = a
        phi = PI_4 * (b / (a if a != 0 else 1e-300))
    else:
        r = b
        phi = PI_2 - PI_4 * (a / (b if b != 0 else 1e-300))
    return r * math.cos(phi), r * math.sin(phi)


@kernel
def to_world(l0, l1, l2, n0, n1, n2):
    """Local (l0, l1, l2) in the frame (t, b, n) of sampling.orthonormal_basis(n)."""
    sign = 1.0 if n2 >= 0.0 else -1.0
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    x = l0 * (1.0 + sign * n0 * n0 * a) + l1 * b + l2 * n0
    y = l0 * (sign * b) + l1 * (sign + n1 * n1 * a) + l2 * n1
    z = l0 * (-sign * n0) + l1 * (-n1) + l2 * n2
    return x, y, z


@kernel
def pick(cdf, u):
    """searchsorted(cdf, u, side="right"), clipped to the last entry: the index an
    inverse-CDF choice over len(cdf) items makes."""
    lo, hi = 0, cdf.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if cdf[mid] <= u:
            lo = mid + 1
        else:
            hi = mid
    return min(lo, cdf.shape[0] - 1)


# ---------------------------------------------------------------------- output
@kernel
def put(o32, d32, d, power, slot, j, o0, o1, o2, d0, d1, d2, p0, p1, p2, s):
    """Write one photon at row j if it carries power; returns the next free row."""
    if not ((p0 > 0.0 or p1 > 0.0 or p2 > 0.0) and p0 == p0 and p1 == p1 and p2 == p2):
        return j
    o32[j, 0], o32[j, 1], o32[j, 2] = o0, o1, o2
    d32[j, 0], d32[j, 1], d32[j, 2] = d0, d1, d2
    d[j, 0], d[j, 1], d[j, 2] = d0, d1, d2
    power[j, 0], power[j, 1], power[j, 2] = p0, p1, p2
    slot[j] = s
    return j + 1


class EmissionBuffers:
    """Rows for up to n emitted photons: o32, d32 (n,3) float32 (the arrays handed to
    Embree), d, power (n,3) float64, slot (n,) int64."""

    def __init__(self, n: int, arrays=None):
        """arrays: (o32, d32, d, power, slot) with at least n rows to write into (the
        photon pass lends its continued-ray buffers), else new ones."""
        if arrays is None:
            arrays = (np.empty((n, 3), np.float32), np.empty((n, 3), np.float32),
                      np.empty((n, 3)), np.empty((n, 3)), np.empty(n, np.int64))
        self.o32, self.d32, self.d, self.power, self.slot = arrays

    @property
    def arrays(self):
        return self.o32, self.d32, self.d, self.power, self.slot

    def head(self, m: int):
        """The first m rows of each array (views)."""
        return tuple(a[:m] for a in self.arrays)


# ---------------------------------------------------------------------- aiming
class Aim:
    """Caustic casters' bounding spheres (centers (K,3), radii (K,)) with the choice
    probabilities (probs, cdf (K,)) of one light."""

    def __init__(self, centers, radii, probs):
        self.centers = np.ascontiguousarray(centers, np.float64).reshape(-1, 3)
        self.radii = np.ascontiguousarray(radii, np.float64)
        self.probs = np.ascontiguousarray(probs, np.float64)
        cdf = np.cumsum(self.probs)
        if len(cdf):
            cdf[-1] = 1.0
        self.cdf = cdf

    @property
    def arrays(self):
        return self.centers, self.radii, self.probs, self.cdf


# The aim of natural emission (the kernels take one argument list for both).
NO_AIM = Aim(np.zeros((0, 3)), np.zeros(0), np.zeros(0))


def aim_weights(centers, radii, anchor) -> Aim:
    """Aim of a finite light at spheres (centers (K,3), radii (K,)): each chosen in
    proportion to the solid angle it subtends from `anchor` (the light's centre)."""
    centers = np.asarray(centers, np.float64).reshape(-1, 3)
    radii = np.asarray(radii, np.float64)
    dist = np.linalg.norm(centers - anchor, axis=1)
    sin_a = np.clip(radii / np.maximum(dist, 1e-300), 0.0, 1.0)
    omega = np.maximum(2.0 * math.pi * (1.0 - np.sqrt(1.0 - sin_a ** 2)), 1e-12)
    return Aim(centers, radii, omega / omega.sum())


def aim_disks(centers, radii) -> Aim:
    """Aim of a light at infinity: each caster's shadow disk chosen by its area."""
    radii = np.asarray(radii, np.float64)
    return Aim(centers, radii, radii ** 2 / np.sum(radii ** 2))


# cone_misses' margins: dist2 beyond r^2 by this factor has sqrt(dist2) > r whatever the
# rounding; below MISS_TINY the exact test runs. Outside by MISS_OUT, x = r^2 / dist2 <
# 1 / MISS_OUT, the exact tests' threshold sqrt(1 - (r/dist)^2) dist (or sqrt(1 - r r /
# dist2) dist) is sqrt(dist2 - r^2) within a relative ~3 u x / (1 - x) + 4 u < 4e-9
# (u = 2^-53 the rounding unit; 1 - x loses the digits x shares with 1), and the quick
# side's dist2 - r r is within u x / (1 - x) + u < 2e-9: both far inside MISS_SLACK's
# 5e-7 on the distance. (Issue 13's s19 also asked dist2 > 2 r^2, x < 1/2, where the
# errors are ~1e-15: origins within 1.4 radii of a sphere then always ran the exact test,
# the region emitter's point light's most common case; s22 photonpass3 dropped it.)
MISS_OUT = 1.0 + 1e-7
MISS_SLACK = 1.0 - 1e-6
MISS_TINY = 1e-100


@kernel
def cone_misses(dist2, along, r):
    """True only where a direction d from o certainly lies outside the cone from o that
    holds the sphere of radius r centred at o + t (dist2 = t.t, along = d.t, unit d), and
    o outside the sphere: where _cone_cos's test (d.t >= cos_max dist, every direction
    from inside) and sphere_meets' would both say no. False where unsure (near the
    cone's edge or the sphere, tiny or non-finite values): the caller runs the exact
    test, so the answers are the same bits, found without two square roots and a
    division for most (photon, sphere) pairs (the region emitter's 20-64 spheres)."""
    if not (dist2 > MISS_TINY and dist2 > r * r * MISS_OUT):
        return False  # o may be inside, or too close to tell: exact test
    if along < 0.0:
        return True  # cos_max >= 0 outside: the cone lies in d.t > 0
    return along * along < (dist2 - r * r) * MISS_SLACK


@kernel
def _cone_cos(c0, c1, c2, r, o0, o1, o2):
    """(cosine of the cone from o holding the sphere (c, r), -1 from inside it; distance,
    and the vector o -> c)."""
    t0, t1, t2 = c0 - o0, c1 - o1, c2 - o2
    dist = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    ds = max(dist, 1e-300)
    cos_max = math.sqrt(max(0.0, 1.0 - (r / ds) ** 2))
    if dist <= r:
        cos_max = -1.0
    return cos_max, dist, t0, t1, t2


@kernel
def _misses(centers, radii, k, o0, o1, o2, d0, d1, d2):
    """cone_misses for sphere k of the tables and the direction d from o (_cone_cos's
    vector o -> c and dot product, the same operations)."""
    t0, t1, t2 = centers[k, 0] - o0, centers[k, 1] - o1, centers[k, 2] - o2
    return cone_misses(t0 * t0 + t1 * t1 + t2 * t2, d0 * t0 + d1 * t1 + d2 * t2, radii[k])


@kernel
def aim_direction(centers, radii, probs, cdf, o0, o1, o2, us, u1, u2):
    """A direction from o aimed at one of the spheres (chosen by us from cdf; uniform in
    its cone by u1, u2), and its aimed pdf (1/sr): the mixture over all spheres whose cone
    holds it (sphere k contributes probs[k] / its cone's solid angle)."""
    j = pick(cdf, us)
    cos_max, dist, t0, t1, t2 = _cone_cos(centers[j, 0], centers[j, 1], centers[j, 2],
                                          radii[j], o0, o1, o2)
    ds = max(dist, 1e-300)
    n0, n1, n2 = t0 / ds, t1 / ds, t2 / ds
    if not dist > 0.0:
        # o at the sphere's centre (a lamp centred in its globe or tube): t is 0, which
        # made no frame (directions of length < 1 and no z: a smooth glass tube round a
        # point lamp stored no caustic photon, roughcaustic48). From inside the cone is
        # every direction (cos_max -1): any axis.
        n0, n1, n2 = 0.0, 0.0, 1.0
    l0, l1, l2 = uniform_cone(u1, u2, cos_max)
    d0, d1, d2 = to_world(l0, l1, l2, n0, n1, n2)
    aimed = 0.0
    for k in range(centers.shape[0]):
        if _misses(centers, radii, k, o0, o1, o2, d0, d1, d2):
            continue  # the test below fails: nothing added
        ck, dk, k0, k1, k2 = _cone_cos(centers[k, 0], centers[k, 1], centers[k, 2], radii[k],
                                       o0, o1, o2)
        if d0 * k0 + d1 * k1 + d2 * k2 >= ck * dk:
            aimed += probs[k] / (TWO_PI * (1.0 - ck))
    return d0, d1, d2, max(aimed, 1e-300)


@kernel
def disk_origin(center, R, d0, d1, d2, u1, u2):
    """Natural origin of a photon from infinity travelling along d: a uniform point on the
    disk of radius R across d, 2 R before the scene's centre."""
    x, y = concentric_disk(u1, u2)
    s0, s1, s2 = to_world(x, y, 0.0, d0, d1, d2)
    return (center[0] - 2.0 * R * d0 + R * s0, center[1] - 2.0 * R * d1 + R * s1,
            center[2] - 2.0 * R * d2 + R * s2)


@kernel
def aim_origin(center, R, centers, radii, probs, cdf, d0, d1, d2, us, u1, u2):
    """Origin of a photon from infinity travelling along d, aimed at a caster: a uniform
    point of one caster's shadow disk (chosen by us) in the plane of the natural disk; and
    the weight natural density / aimed density of that point."""
    s0 = center[0] - 2.0 * R * d0
    s1 = center[1] - 2.0 * R * d1
    s2 = center[2] - 2.0 * R * d2
    j = pick(cdf, us)
    x, y = concentric_disk(u1, u2)
    t0, t1, t2 = to_world(x, y, 0.0, d0, d1, d2)
    c0, c1, c2 = centers[j, 0], centers[j, 1], centers[j, 2]
    h = (c0 - s0) * d0 + (c1 - s1) * d1 + (c2 - s2) * d2
    r = radii[j]
    o0 = c0 - h * d0 + r * t0
    o1 = c1 - h * d1 + r * t1
    o2 = c2 - h * d2 + r * t2
    aimed = 0.0
    for k in range(centers.shape[0]):
        c0, c1, c2 = centers[k, 0], centers[k, 1], centers[k, 2]
        h = (c0 - s0) * d0 + (c1 - s1) * d1 + (c2 - s2) * d2
        e0, e1, e2 = o0 - (c0 - h * d0), o1 - (c1 - h * d1), o2 - (c2 - h * d2)
        if math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) <= radii[k]:
            aimed += probs[k] / (math.pi * radii[k] * radii[k])
    e0, e1, e2 = o0 - s0, o1 - s1, o2 - s2
    natural = (1.0 / (math.pi * R * R)
               if math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) <= R else 0.0)
    return o0, o1, o2, natural / max(aimed, 1e-300)


@kernel
def _uniforms(key, slot, dims, out):
    for i in range(slot.shape[0]):
        for k in range(dims):
            out[i, k] = emit_uniform(key, slot[i], k)


def emission_uniforms(key, slots, dims: int) -> np.ndarray:
    """(N, dims) emission numbers of photons in slots (N,) (for tests of the stream)."""
    slots = np.ascontiguousarray(slots, np.int64)
    out = np.empty((len(slots), dims))
    _uniforms(np.uint64(key), slots, dims, out)
    return out


def f64(a) -> np.ndarray:
    """a as a C-contiguous, writable float64 array (the one type the kernels are compiled
    for: numba compiles a readonly array, e.g. an np.broadcast_to view, as another type,
    a compile inside the user's first render). Copies only when a is not that already."""
    return np.require(a, np.float64, ["C", "W"])


@register_warm_up
def _warm_up():
    """Compile (or load) every kind's emission kernel: one photon each, natural and
    aimed."""
    from .area import AreaLight
    from .mesh import MeshLight
    from .point import PointLight
    from .spot import SpotLight
    from .sun import SunLight
    from .world import WorldLight
    from .environment import Environment
    from .base import emit_arrays
    emission_uniforms(1, np.zeros(1, np.int64), 2)
    for infinite in (False, True):
        for width in (1, 2):
            sphere_meets(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((2, 3)), np.ones(2),
                         infinite, np.zeros((1, width), np.bool_))
        drop_meeting(np.zeros((2, 3), np.float32), np.zeros((2, 3), np.float32),
                     np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(2, np.int64), 0, 2,
                     np.ones((1, 3)), np.ones(1), infinite)
    z, ez = np.zeros(3), np.array([0.0, 0.0, 1.0])
    one = np.ones(3)
    common = dict(pos=z, dir=-ez, radius=0.1, center=z, scene_radius=1.0, flux=one,
                  photon_flux=one, intensity=one)
    tri = dict(v0=np.zeros((1, 3)), e1=np.eye(3)[:1], e2=np.eye(3)[1:2], tri_ng=ez[None],
               tri_L=np.ones((1, 3)), tri_area=np.full(1, 0.5), prob=np.ones(1),
               cdf=np.ones(1), round32=np.zeros((1, 3, 3)), tilt32=np.zeros(1))
    lights = [PointLight("p", **common),
              SpotLight("s", spot_frame=np.eye(3), spot_size=1.0, spot_blend=0.1,
                        spot_cos_bound=0.8, **common),
              AreaLight("a", du=np.eye(3)[0], dv=np.eye(3)[1], size_x=1.0, size_y=1.0,
                        shape="RECTANGLE", spread=1.0, **common),
              SunLight("sun", cos_half_angle=0.99, **common),
              WorldLight("w", **common),
              WorldLight("e", environment=Environment(np.ones((2, 4, 3))), **common),
              MeshLight("m", **tri, **common)]
    rng = np.random.default_rng(0)
    for light in lights:
        emit_arrays(light, 1, rng)
        emit_arrays(light, 1, rng, (np.array([[0.0, 0.0, -2.0]]), np.ones(1)))
