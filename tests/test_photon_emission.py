"""Photon emission in compiled kernels (engine/lights/emission.py and each light kind's
emit kernel): flux per light, direction and origin distributions against their analytic
forms, aimed photons against natural ones, and the random numbers' ownership by slot.

The kernels were checked against the numpy emission they replaced, fed the same uniform
numbers: origins and directions bitwise equal for every kind, power to 3e-13 relative
(docs/performance.md, "Fourth slice: photon emission")."""
import math

import numpy as np
import pytest

from engine import photonkernels
from engine.geometry import prepare
from engine.lights import prepare_lights
from engine.lights.emission import EMIT_BOUNCE, EmissionBuffers, emission_uniforms
from engine.lights.environment import Environment
from engine.scene import Light, Material, spot_mask, spread_attenuation
from helpers import top_down_plane

N = 100_000


def _light(light=None, env=None, emissive=False, background=None):
    s = top_down_plane()
    if light is not None:
        s.add_light(light)
    if env is not None:
        s.environment = env
    if background is not None:
        s.background = background
    if emissive:
        s.add_material(Material("glow", (0.5, 0.5, 0.5), emission=(2.0, 1.5, 1.0)))
        s.add_sphere((0.2, -0.3, 0.8), 0.3, "glow", name="lamp", segments=8)
    s.validate()
    geo, table = prepare(s)
    lights = prepare_lights(s, geo, table)
    return lights[0] if light is not None else lights[-1]


def _env(interpolation="Linear"):
    rng = np.random.default_rng(3)
    px = rng.random((6, 12, 3)) ** 3
    px[1, 5] = 300.0  # a sun
    return Environment(px, 1.3, None, interpolation)


SCALED = np.stack([np.array([1.0, 0, 0]) / 2.0, np.array([0, 1.0, 0]) / 0.5,
                   np.array([0, 0, -1.0])])
SHEAR_V = np.array([math.cos(math.radians(60)), math.sin(math.radians(60)), 0.0])
LIGHTS = {
    "point": lambda: _light(Light("p", "POINT", 100.0, position=(0.1, 0.2, 2.0))),
    "point radius": lambda: _light(Light("p", "POINT", 100.0, position=(0.1, 0.2, 2.0),
                                         radius=0.3)),
    "spot": lambda: _light(Light("s", "SPOT", 100.0, position=(0, 0, 3), direction=(0, 0, -1),
                                 spot_size=math.radians(40), spot_blend=0.3)),
    "spot radius scaled": lambda: _light(Light(
        "s", "SPOT", 100.0, position=(0, 0, 3), direction=(0.2, 0, -1),
        spot_size=math.radians(40), spot_blend=0.2, radius=0.2, spot_frame=SCALED)),
    "area rectangle": lambda: _light(Light("a", "AREA", 50.0, position=(0, 0, 2),
                                           direction=(0.1, 0, -1), size_x=1.0, size_y=0.5)),
    "area disk": lambda: _light(Light("a", "AREA", 50.0, position=(0, 0, 2),
                                      direction=(0, 0, -1), size_x=1.0, size_y=1.0,
                                      shape="DISK")),
    "area ellipse spread": lambda: _light(Light(
        "a", "AREA", 50.0, position=(0, 0, 2), direction=(0, 0, -1), size_x=1.0, size_y=0.4,
        shape="DISK", spread=math.radians(40))),
    "area sheared": lambda: _light(Light("a", "AREA", 50.0, position=(0, 0, 2),
                                         direction=(0, 0, -1), size_x=1.0, size_y=0.5,
                                         skew_axis_v=SHEAR_V)),
    "sun": lambda: _light(Light("sun", "SUN", 3.0, direction=(0.3, 0.2, -1))),
    "sun angle": lambda: _light(Light("sun", "SUN", 3.0, direction=(0.3, 0.2, -1),
                                      angle=math.radians(10))),
    "mesh": lambda: _light(emissive=True),
    "world": lambda: _light(background=(0.2, 0.3, 0.4)),
    "world map": lambda: _light(env=_env()),
}
# Kinds whose photons do not all carry the same power: their flux holds in expectation.
VARYING = {"spot", "spot radius scaled", "area ellipse spread", "world map"}


def _emit(light, n=N, key=11, targets=None, first=0, count=None):
    out = EmissionBuffers(n)
    count = n if count is None else count
    if targets is None:
        m = light.emit_into(np.uint64(key), first, n, count, out, 0)
    else:
        m = light.emit_towards_into(np.uint64(key), first, n, count, targets, out, 0)
    return out.head(m)


def _chi2(values, weights, edges, expected_fraction):
    """Chi-square-like statistic of a (power-)weighted histogram against expected
    fractions, with the weights' own spread as the variance."""
    w = weights / weights.sum()
    got = np.histogram(values, edges, weights=w)[0]
    var = np.histogram(values, edges, weights=w * w)[0]
    return float(np.sum((got - expected_fraction) ** 2 / np.maximum(var, 1e-30)))


@pytest.mark.parametrize("name", sorted(LIGHTS))
def test_emitted_power_is_the_lights_flux(name):
    light = LIGHTS[name]()
    o32, d32, d, power, slot = _emit(light)
    assert o32.dtype == d32.dtype == np.float32 and d.dtype == power.dtype == np.float64
    np.testing.assert_array_equal(d32, d.astype(np.float32))
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    assert np.all(power.max(axis=1) > 0) and np.all(np.diff(slot) > 0)
    rtol = 0.02 if name in VARYING else 1e-9
    np.testing.assert_allclose(power.sum(axis=0), light.photon_flux, rtol=rtol)


def _cos_to(d, axis):
    return d @ (np.asarray(axis) / np.linalg.norm(axis))


def test_direction_distributions_of_lights_of_equal_power_photons():
    """cos to the axis: uniform over [-1, 1] for a point light and a constant world,
    uniform over [cos_half, 1] for a sun's disk, and cos^2 uniform over [0, 1] about
    the normal for cosine emitters (area lights, a point light's sphere, emissive
    triangles on either side)."""
    flat = np.full(20, 1 / 20)
    limit = 60.0  # 19 degrees of freedom: p ~ 1e-6

    def uniform_check(x, lo=0.0, hi=1.0):
        e = np.linspace(lo, hi, 21)
        return _chi2(x, np.ones(len(x)), e, flat)

    light = LIGHTS["point"]()
    o32, _, d, _, _ = _emit(light)
    assert np.all(o32 == light.pos.astype(np.float32))
    assert uniform_check(d[:, 2], -1, 1) < limit
    light = LIGHTS["world"]()
    o32, _, d, _, _ = _emit(light)
    assert uniform_check(d[:, 0], -1, 1) < limit
    # Origins 2 R before the centre, on a disk of radius R across d.
    rel = o32 - light.center
    along = np.einsum("ij,ij->i", rel, d)
    np.testing.assert_allclose(along, -2.0 * light.scene_radius, rtol=1e-5)
    across = np.linalg.norm(rel - along[:, None] * d, axis=1)
    assert across.max() <= light.scene_radius * (1 + 1e-5)
    assert uniform_check((across / light.scene_radius) ** 2) < limit  # uniform on the disk
    light = LIGHTS["sun angle"]()
    _, _, d, _, _ = _emit(light)
    assert uniform_check(_cos_to(d, light.dir), light.cos_half_angle, 1.0) < limit
    for name in ("area rectangle", "area disk", "area sheared"):
        light = LIGHTS[name]()
        _, _, d, _, _ = _emit(light)
        assert uniform_check(_cos_to(d, light.dir) ** 2) < limit, name
    light = LIGHTS["point radius"]()
    o32, _, d, _, _ = _emit(light)
    nrm = (o32 - light.pos) / light.radius
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-5)
    assert uniform_check(np.einsum("ij,ij->i", d, nrm) ** 2) < limit
    light = LIGHTS["mesh"]()
    o32, _, d, power, _ = _emit(light, 20_000)
    # Each photon's triangle: the one its origin lies on (within the offset), inside it.
    rel = o32[:, None, :].astype(np.float64) - light.v0[None]
    height = np.einsum("ntc,tc->nt", rel, light.tri_ng)
    e1e1 = np.einsum("tc,tc->t", light.e1, light.e1)
    e2e2 = np.einsum("tc,tc->t", light.e2, light.e2)
    e1e2 = np.einsum("tc,tc->t", light.e1, light.e2)
    r1 = np.einsum("ntc,tc->nt", rel, light.e1)
    r2 = np.einsum("ntc,tc->nt", rel, light.e2)
    det = e1e1 * e2e2 - e1e2 ** 2
    b1 = (e2e2 * r1 - e1e2 * r2) / det
    b2 = (e1e1 * r2 - e1e2 * r1) / det
    on = (np.abs(height) < 1e-4) & (b1 > -1e-5) & (b2 > -1e-5) & (b1 + b2 < 1 + 1e-5)
    assert np.all(on.any(axis=1))
    tri = np.argmax(on, axis=1)
    rows = np.arange(len(d))
    c = np.einsum("nc,nc->n", d, light.tri_ng[tri])
    assert np.all(np.sign(height[rows, tri]) == np.sign(c))  # offset to the side it leaves by
    assert abs(np.mean(c > 0) - 0.5) < 5 * 0.5 / math.sqrt(len(c))  # both sides emit
    assert uniform_check(c ** 2) < limit


def test_direction_distributions_of_masked_and_spread_lights():
    """Power-weighted histograms: a spot's follows Cycles' smoothstep mask over the cone's
    cosine, an area light with a spread cos x the spread attenuation."""
    light = LIGHTS["spot"]()
    _, _, d, power, _ = _emit(light)
    c = _cos_to(d, light.dir)
    edges = np.linspace(light.spot_cos_bound, 1.0, 21)
    fine = np.linspace(edges[0], edges[-1], 20 * 256 + 1)
    mask = spot_mask(fine, light.spot_size, light.spot_blend)
    per_bin = np.add.reduceat(mask[:-1], np.arange(0, len(fine) - 1, 256))
    assert _chi2(c, power[:, 0], edges, per_bin / per_bin.sum()) < 60
    light = LIGHTS["area ellipse spread"]()
    _, _, d, power, _ = _emit(light)
    c = _cos_to(d, light.dir)
    edges = np.linspace(math.cos(light.spread / 2), 1.0, 21)
    fine = np.linspace(edges[0], edges[-1], 20 * 256 + 1)
    density = fine * spread_attenuation(fine, light.spread)
    per_bin = np.add.reduceat(density[:-1], np.arange(0, len(fine) - 1, 256))
    assert c.min() >= edges[0] - 1e-9
    assert _chi2(c, power[:, 0], edges, per_bin / per_bin.sum()) < 60


def test_world_map_photons_carry_each_texels_power():
    """Closest interpolation: the power arriving from each texel row is that row's
    radiance x solid angle x pi R^2 (Environment.integral, row by row)."""
    light = _light(env=_env("Closest"))
    env = light.environment
    _, _, d, power, _ = _emit(light, 200_000)
    theta = np.arccos(np.clip(-d[:, 2], -1, 1))  # photons travel against the direction
    H = env.height
    row = np.minimum((theta / math.pi * H).astype(int), H - 1)
    got = np.bincount(row, weights=power[:, 1], minlength=H)
    t0 = math.pi * np.arange(H) / H
    omega = (np.cos(t0) - np.cos(t0 + math.pi / H)) * 2 * math.pi / env.width
    want = (env.pixels[:, :, 1].astype(np.float64).sum(axis=1) * omega
            * math.pi * light.scene_radius ** 2)
    np.testing.assert_allclose(got, want, rtol=0.05)


def _power_into_sphere(o, d, power, center, radius):
    oc = o - center
    b = np.einsum("ij,ij->i", oc, d)
    c = np.einsum("ij,ij->i", oc, oc) - radius * radius
    disc = b * b - c
    hit = (disc > 0) & (-b + np.sqrt(np.maximum(disc, 0)) > 0)
    return power[hit].sum(axis=0)


@pytest.mark.parametrize("name", ["area rectangle", "area ellipse spread", "mesh", "sun",
                                  "world map"])
def test_aimed_photons_carry_what_natural_ones_send_at_the_target(name):
    """The aimed photons' power into a caster's sphere equals the natural photons' (the
    point and spot lights: tests/test_effects.py)."""
    light = LIGHTS[name]()
    center, radius = np.array([[0.3, 0.1, 0.5]]), np.array([0.4])
    o32, _, d, power, _ = _emit(light, 1_000_000)
    natural = _power_into_sphere(o32.astype(np.float64), d, power, center[0], radius[0])
    o32, _, d, power, _ = _emit(light, 100_000, key=12, targets=(center, radius))
    aimed = _power_into_sphere(o32.astype(np.float64), d, power, center[0], radius[0])
    np.testing.assert_allclose(aimed, natural, rtol=0.03)


@pytest.mark.parametrize("name", ["point radius", "spot radius scaled", "mesh", "world map"])
def test_a_photons_emission_depends_only_on_its_slot(name):
    """Emitting slots 0..n-1 in one call or in two (first = 0 and n/2) gives the same
    photons: a chunk's photons are the same whatever emits them (a light alone or in a
    group) and for any thread count."""
    light = LIGHTS[name]()
    n = 4000
    whole = _emit(light, n)
    halves = [_emit(light, n // 2, first=f, count=n) for f in (0, n // 2)]
    for a, b, c in zip(whole, *halves):
        np.testing.assert_array_equal(a, np.concatenate([b, c]))
    assert not np.array_equal(whole[2], _emit(light, n, key=12)[2])


def test_emission_numbers_are_their_own_dimensions_of_the_photons_stream():
    """Emission reads the photon stream at bounces counted down from the last one, which
    no photon reaches (max_photon_depth is capped far below), so emission and scattering
    never share a number."""
    from engine.settings import LIMITS
    assert LIMITS["max_photon_depth"] < EMIT_BOUNCE - 2  # 12 emission dimensions free
    slot = np.arange(1000)
    u = emission_uniforms(5, slot, 8)
    for dim in range(8):
        ref = np.empty(len(slot))
        photonkernels.uniforms(np.uint64(5), slot, EMIT_BOUNCE - dim // photonkernels.N_DIMS,
                               dim % photonkernels.N_DIMS, ref)
        np.testing.assert_array_equal(u[:, dim], ref)
    assert len(np.unique(u)) == u.size


def _chi2_2d(a, b, bins):
    """Pearson chi-square of the bins x bins histogram of pairs (a, b) in [0, 1)^2
    against independent uniform numbers."""
    cells = np.minimum((a * bins).astype(np.int64), bins - 1) * bins \
        + np.minimum((b * bins).astype(np.int64), bins - 1)
    counts = np.bincount(cells, minlength=bins * bins)
    expected = len(a) / (bins * bins)
    return float(((counts - expected) ** 2 / expected).sum())


def test_emission_numbers_are_independent_of_the_scattering_numbers_of_the_same_photon():
    """Issue 13's suspect for the glass-window cases' darkening: each emission dimension
    (a point on the light, a direction, an aimed target) against each scattering
    dimension (roulette, diffuse direction, lobe sample) of the same slot at the first
    eight bounces, and against the other emission dimensions: the pairs fill a 16 x 16
    grid as independent uniform numbers do. The numbers are SplitMix64 at counters
    (slot * 65536 + bounce) * 6 + dim, the slots' counters 393216 apart (a step with 17
    trailing zero bits: the structure a weak mix would show). 500 pairs, each at
    p = 1e-7 (chi-square, 255 degrees of freedom), so the test fails by chance about
    once in 20 000 runs. Measured beyond it (2 keys x 2^21 slots, 64 x 64 bins, 4
    emission x 36 scattering dimensions): the smallest of 288 p-values was 0.002, as
    expected of independent numbers (docs/performance.md, "Fourth slice: photon
    emission")."""
    from scipy.stats import chi2
    slot = np.arange(1 << 16)
    limit = chi2.isf(1e-7, 255)
    for key in (3, 0x9E3779B97F4A7C15 >> 1):
        emit = emission_uniforms(key, slot, 5)
        for k in range(5):
            for j in range(k + 1, 5):
                assert _chi2_2d(emit[:, k], emit[:, j], 16) < limit, (key, k, j)
        for bounce in range(8):
            for dim in range(photonkernels.N_DIMS):
                scatter = np.empty(len(slot))
                photonkernels.uniforms(np.uint64(key), slot, bounce, dim, scatter)
                for k in range(5):
                    assert _chi2_2d(emit[:, k], scatter, 16) < limit, (key, k, bounce, dim)
