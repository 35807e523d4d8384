"""The environment map's cosine-weighted distributions (engine/lights/environment.py,
build_cosine_distributions) and the world's shadow-ray mixture that uses them
(engine/lights/world.py, engine/directlight.py): pdfs that integrate to 1, samples that
follow their pdf (texel histogram against the pdf, chi-square), unbiased irradiance, the
kernel's light pdf equal to the one multiple importance sampling uses for escaping rays
(so the two strategies' power-heuristic weights sum to 1), and an analytic render."""
import math

import numpy as np
import pytest

from engine import Environment, RenderSettings
from engine.geometry import prepare
from engine.integrator import _hit_arrays
from engine.directlight import DirectLightBuffers, NO_HROWS, NO_ROWS3, sample_lights
from engine.lights import WorldLight, prepare_lights
from engine.lights.environment import (N_OCT, SPREAD_SHARE, build_cosine_distributions,
                                       octahedral_centre, octahedral_spread,
                                       texel_function)
from engine.lights.packing import pack_lights
from engine.lights.selection import empty_tree
from engine.sampling import luminance
from engine.scene import euler_rotation
from helpers import random_environment, sphere_grid, top_down_plane

NORMALS = [(0, 0, 1.0), (0.3, -0.2, 0.9), (0, 0, -1.0), (1.0, 0, 0), (-0.5, 0.7, -0.2)]




def _unit(n):
    n = np.asarray(n, float)
    return n / np.linalg.norm(n)


@pytest.mark.parametrize("n", NORMALS)
def test_cosine_pdf_integrates_to_one(n):
    env = random_environment()
    # pdf x sin(theta) is constant on each texel: a grid 4x finer than the texels,
    # aligned with them, integrates it exactly (to the float32 pixels' rounding).
    d, sin_t, cell = sphere_grid(4 * env.height, 4 * env.width)
    total = float(np.sum(env.cosine_pdf(d, _unit(n)[None]) * sin_t) * cell)
    assert abs(total - 1.0) < 1e-9, total


def test_cosine_pdf_integrates_to_one_on_a_coarse_grid_and_rotated():
    # A map larger than the coarse grid (cells of several texels, uneven): exact on a
    # texel-aligned grid.
    rng = np.random.default_rng(7)
    px = rng.random((150, 290, 3)) ** 4
    px[40:42, 100:103] = 500.0
    env = Environment(px)
    rows, cols, mass, prefix, cell = env.cosine_distributions
    assert mass.shape[1:] == (64, 128) and np.allclose(mass.sum(axis=(1, 2)), 1.0)
    d, sin_t, c = sphere_grid(2 * 150, 2 * 290)
    for n in NORMALS:
        total = float(np.sum(env.cosine_pdf(d, _unit(n)[None]) * sin_t) * c)
        assert abs(total - 1.0) < 1e-9, (n, total)
    # Rotated: no longer texel-aligned, a fine quadrature.
    env = random_environment(rotation=euler_rotation((0.4, -0.3, 1.1)))
    d, sin_t, c = sphere_grid(400, 800)
    for n in NORMALS:
        total = float(np.sum(env.cosine_pdf(d, _unit(n)[None]) * sin_t) * c)
        assert abs(total - 1.0) < 2e-3, (n, total)


def _texel_of(env, wi):
    tex = wi @ env.rotation.T
    u = (0.5 - np.arctan2(tex[:, 1], tex[:, 0]) / (2 * math.pi)) % 1.0
    i = np.minimum((np.arccos(np.clip(tex[:, 2], -1, 1)) / math.pi * env.height).astype(int),
                   env.height - 1)
    j = np.minimum((u * env.width).astype(int), env.width - 1)
    return i * env.width + j


@pytest.mark.parametrize("shape, rotation", [((12, 24), None),
                                             ((150, 290), euler_rotation((0.2, 0.5, -0.7)))])
def test_cosine_samples_follow_their_pdf_chi_square(shape, rotation):
    rng = np.random.default_rng(0)
    px = rng.random((*shape, 3)) ** 3
    px[2, 5] = 300.0
    env = Environment(px, rotation=rotation)
    H, W = shape
    n_samples = 400_000
    for n in (_unit((0.3, -0.2, 0.9)), _unit((0, 0, -1.0))):
        wi, pdf = env.cosine_sample(rng.random(n_samples), rng.random(n_samples), n[None])
        assert np.all(pdf > 0) and np.allclose(np.linalg.norm(wi, axis=1), 1.0)
        assert np.allclose(pdf, env.cosine_pdf(wi, n[None]), rtol=1e-9)
        # Expected texel frequencies from the pdf: the mean of pdf_uv over the texel / (H W)
        # (pdf_uv is bilinear on each quarter of a texel (texel_warp): the midpoints of
        # 8 x 8 sub-squares, aligned with the quarters, integrate it exactly).
        sub = (np.arange(8) + 0.5) / 8
        th = math.pi * (np.arange(H)[:, None] + sub[None, :]).reshape(-1) / H
        u = (np.arange(W)[:, None] + sub[None, :]).reshape(-1) / W
        T, U = np.meshgrid(th, u, indexing="ij")
        phi = 2 * math.pi * (0.5 - U)
        tex = np.stack([np.sin(T) * np.cos(phi), np.sin(T) * np.sin(phi), np.cos(T)], -1)
        world = tex.reshape(-1, 3) @ env.rotation  # R^T t
        p_uv = env.cosine_pdf(world, n[None]) * 2 * math.pi ** 2 * np.sin(T).reshape(-1)
        p_uv = p_uv.reshape(H, 8, W, 8).mean(axis=(1, 3)).reshape(-1)
        expected = p_uv / (H * W) * n_samples
        observed = np.bincount(_texel_of(env, wi), minlength=H * W)
        big = expected > 20
        chi2 = float(np.sum((observed[big] - expected[big]) ** 2 / expected[big]))
        dof = int(big.sum()) - 1
        # chi-square with dof degrees of freedom: mean dof, sd sqrt(2 dof); 5 sd.
        assert chi2 < dof + 5 * math.sqrt(2 * dof), (chi2, dof)
        assert observed[~big].sum() <= expected[~big].sum() + 5 * math.sqrt(
            expected[~big].sum()) + 5


@pytest.mark.parametrize("n", NORMALS)
def test_cosine_sampling_estimates_irradiance_without_bias(n):
    env = random_environment(rotation=euler_rotation((0.2, 0.5, -0.7)))
    n = _unit(n)
    rng = np.random.default_rng(11)
    N = 300_000
    wi, pdf = env.cosine_sample(rng.random(N), rng.random(N), n[None])
    c = np.maximum(wi @ n, 0.0)
    est = (env.radiance(wi) * (c / pdf)[:, None]).mean(axis=0)
    d, sin_t, cell = sphere_grid(400, 800)
    quad = (env.radiance(d) * (np.maximum(d @ n, 0) * sin_t * cell)[:, None]).sum(axis=0)
    assert np.allclose(est, quad, rtol=0.01), (est, quad)


def test_cosine_distribution_has_no_mass_below_the_clusters_horizon():
    env = random_environment()
    rows, cols, mass, prefix, cell = env.cosine_distributions
    k = (N_OCT // 2) * N_OCT + N_OCT // 2   # the cell of +Z
    assert np.allclose(octahedral_centre(k), [0, 0, 1])
    H = env.height
    Hc = mass.shape[1]
    # Cells entirely below the horizon of every normal of the +Z cluster (theta > 90
    # degrees + the cluster's spread) get nothing ...
    spread = octahedral_spread(k)
    top = math.pi * (np.arange(Hc) * H // Hc) / H           # each cell row's smallest theta
    below = top >= 0.5 * math.pi + spread + 1e-9
    assert below.any()
    assert mass[k][below].sum() < 1e-12  # (cos of 90 degrees rounds to 6e-17)
    # ... while the map's own function is there.
    assert cell[below].sum() > 0
    # Rows just below the centre's horizon but above an edge normal's get a share
    # (SPREAD_SHARE: a sun setting for the centre is still found for the cluster's edge).
    band = (top >= 0.5 * math.pi) & (top < 0.5 * math.pi + spread - 0.05)
    assert band.any() and mass[k][band].sum() > 0
    # ... and no more than that share: a cell's weight over its map function is at most
    # SPREAD_SHARE there, against 1 + SPREAD_SHARE overhead.
    ratio = np.where(cell > 0, mass[k] / np.where(cell > 0, cell, 1.0), 0.0)
    assert ratio[band].max() <= SPREAD_SHARE / (1 + SPREAD_SHARE) * ratio.max() * (1 + 1e-9)
    # The per-row prefix sums are those of the map's function.
    f = texel_function(env.pixels, True)
    assert np.allclose(prefix[:, -1], f.sum(axis=1))


def test_cluster_of_a_normal_is_the_octahedral_cell_it_falls_in():
    env = random_environment()
    rng = np.random.default_rng(2)
    n = rng.normal(size=(2000, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    # Every normal's cluster centre lies within the cell's angular reach (~17 degrees for
    # a 9 x 9 octahedral grid).
    from engine.lights.environment import octahedral_cell
    ks = np.array([octahedral_cell(N_OCT, *v) for v in n])
    centres = np.array([octahedral_centre(k) for k in range(N_OCT * N_OCT)])
    cos = np.einsum("ij,ij->i", n, centres[ks])
    assert cos.min() > math.cos(math.radians(25))
    assert octahedral_cell(N_OCT, 0.0, 0.0, 1.0) == (N_OCT // 2) * N_OCT + N_OCT // 2
    del env


def _world_light_samples(env, normals, n=20000, seed=4):
    """sample_lights on n hits at the origin with shading normals `normals` (n,3) under
    the world `env`: (rows, irradiance without visibility, wdir, lpdf, light)."""
    s = top_down_plane(0.5, res=4)
    s.environment = env
    geo, table = prepare(s)
    lights = prepare_lights(s, geo, table)
    li = [i for i, light in enumerate(lights) if isinstance(light, WorldLight)][0]
    rng = np.random.default_rng(seed)
    p = np.zeros((n, 3))
    ns = np.ascontiguousarray(normals, np.float64)
    hit = (p, ns, ns, ns, np.zeros(n), np.zeros(0), np.zeros(0), np.zeros((0, 3)), ns)
    u1, u2, sel = rng.random((3, n))
    buf = DirectLightBuffers().ensure(n)
    codes, params, arrays = pack_lights(lights)
    m_all, _ = sample_lights(*hit, codes, params, *arrays, *empty_tree(),
                             np.ones(len(codes), np.bool_), np.array([li], np.int64),
                             np.ones(1, np.bool_), u1[None], u2[None], sel[None], buf.contrib,
                             buf.row, buf.kidx, buf.ray, buf.o32, buf.d32, buf.t32, buf.wdir,
                             buf.lpdf, buf.bump, NO_HROWS, NO_ROWS3)
    return (buf.row[:m_all].copy(), buf.contrib[:m_all].copy(), buf.wdir[:m_all].copy(),
            buf.lpdf[:m_all].copy(), lights[li])


def assert_world_irradiance_unbiased(env, normal, bound, grid):
    """The world's shadow rays (100,000 at one normal, visibility left out) estimate the
    irradiance that quadrature of env over a grid (rows, columns) gives within 1 %, with
    a per-sample relative variance under bound."""
    n = np.asarray(normal) / np.linalg.norm(normal)
    N = 100_000
    row, contrib, _, _, _ = _world_light_samples(env, np.tile(n, (N, 1)), n=N, seed=9)
    x = np.zeros(N)
    np.add.at(x, row, luminance(contrib))
    d, sin_t, cell = sphere_grid(*grid)
    quad = float(np.sum(luminance(env.radiance(d)) * np.maximum(d @ n, 0) * sin_t) * cell)
    assert abs(x.mean() / quad - 1) < 0.01, (x.mean(), quad)
    assert x.var() / x.mean() ** 2 < bound


def test_shadow_ray_pdf_is_the_one_mis_uses_and_weights_sum_to_one():
    env = random_environment(rotation=euler_rotation((0.2, 0.5, -0.7)))
    rng = np.random.default_rng(5)
    normals = rng.normal(size=(20000, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    row, contrib, wdir, lpdf, world = _world_light_samples(env, normals)
    assert len(row) > 10000
    # The kernel's light pdf of each sample = WorldLight.pdf (integrator.mis_light_pdf):
    # the pdf a BSDF-sampled ray that escapes in that direction is weighted against.
    ref = world.pdf(wdir, normals[row])
    assert np.allclose(lpdf, ref, rtol=1e-12)
    # Power-heuristic weights of the two strategies for the same direction sum to 1
    # (directlight.accumulate_bsdf's for the shadow ray, integrator._mis_weight's for
    # the continuation), with any BSDF pdf.
    pb = rng.random(len(row)) * 3.0
    w_light = lpdf ** 2 / (lpdf ** 2 + pb ** 2)
    w_bsdf = pb ** 2 / (pb ** 2 + ref ** 2)
    assert np.allclose(w_light + w_bsdf, 1.0)


@pytest.mark.parametrize("n", NORMALS[:4])
def test_shadow_ray_mixture_estimates_irradiance_without_bias(n):
    env = random_environment(rotation=euler_rotation((0.2, 0.5, -0.7)))
    n = _unit(n)
    N = 200_000
    row, contrib, _, _, _ = _world_light_samples(env, np.tile(n, (N, 1)), n=N)
    est = contrib.sum(axis=0) / N
    d, sin_t, cell = sphere_grid(400, 800)
    quad = (env.radiance(d) * (np.maximum(d @ n, 0) * sin_t * cell)[:, None]).sum(axis=0)
    assert np.allclose(est, quad, rtol=0.015), (est, quad)


def test_random_environment_lights_an_open_plane_with_its_irradiance():
    """Analytic: an open diffuse plane of albedo rho under a map reflects rho E / pi with
    E the map's cosine-weighted integral over the upper hemisphere."""
    rho = 0.5
    env = random_environment(rotation=euler_rotation((0.3, 0.2, 0.4)))
    s = top_down_plane(rho, res=16)
    s.environment = env
    # The image mean scatters by ~0.6 % over seeds (the sun texel): 4 seeds' mean.
    got = np.mean([s.render(RenderSettings(spp=64, seed=seed, photon_mapping=False,
                                           max_depth=0)).combined.reshape(-1, 3).mean(axis=0)
                   for seed in range(1, 5)], axis=0)
    d, sin_t, cell = sphere_grid(400, 800)
    E = (env.radiance(d) * (np.maximum(d[:, 2], 0) * sin_t * cell)[:, None]).sum(axis=0)
    expected = rho * E / math.pi
    assert np.allclose(got, expected, rtol=0.01), (got, expected)
