"""Shadow rays to an emissive mesh choose the triangle by a stratified number (issue 14):
the pixel's samples spread over a panel's triangles (by the triangle tree's pmf at the
point since meshlight: tests/test_mesh_light_tree.py), and the same number, remapped on
the way, places the point on the chosen triangle with a second stratified number
(integrator.mesh_light_numbers, multi-jittered; directlight.sample_lights, pbrt-v4's
SampleDiscrete). The "choice before" here is still a number of its own, drawn through
the power CDF.

A panel of one quad and one of 3 x 3 quads (18 triangles), tilted over a floor, direct light only, 16 samples a
"pixel" (one floor point): the mean matches Lambert's closed form for the panel's polygon,
the pixel noise is well below that of a triangle chosen by its own random number (the
choice before), and the same seed gives the same numbers.
"""
import math

import numpy as np
import pytest

import engine.integrator as integrator
from engine import RenderSettings
from engine.api import PaperScene
from engine.integrator import Counters, camera_dimensions, direct_irradiance
from engine.render import prepare_context
from engine.sampling import StratifiedSampler
from engine.scene import Camera, Material, Mesh

from test_ray_offsets import DIRECT_ONLY, _floor_hits, _lambert_polygon

L = 20.0
SPP = 16
PIXELS = 1000  # pixels (repeats of one floor point) per point
POINTS_X = np.array([0.0, 0.6, 1.5])
POINTS_Y = np.array([0.0, 0.2, 0.0])


def _panel(n=3, size=1.0, height=1.0, tilt_deg=20.0):
    """(vertices, faces, outline corners) of a size x size panel of n x n quads (2 n^2
    triangles) at `height`, tilted about the y axis."""
    t = math.radians(tilt_deg)
    ax = np.array([math.cos(t), 0.0, math.sin(t)])
    ay = np.array([0.0, 1.0, 0.0])
    c = np.array([0.0, 0.0, height])
    h = size / 2
    verts = np.array([c + (-h + size * i / n) * ax + (-h + size * j / n) * ay
                      for j in range(n + 1) for i in range(n + 1)])
    faces = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            faces += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
    corners = np.array([c - h * ax - h * ay, c + h * ax - h * ay, c + h * ax + h * ay,
                        c - h * ax + h * ay])
    return verts, np.array(faces), corners


@pytest.fixture(scope="module", params=[1, 3], ids=["1x1_quad", "3x3_quads"])
def setup(request):
    verts, faces, corners = _panel(request.param)
    s = PaperScene(width=4, height=4)
    s.add_material(Material("lamp", (0.0, 0.0, 0.0), emission=(L, L, L)))
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, "white_diffuse", name="floor")
    s.add_mesh(Mesh("panel", verts, faces, materials=["lamp"]))
    s.camera = Camera(position=(0, -10, 3), rotation=np.eye(3))
    ctx = prepare_context(s, RenderSettings(**DIRECT_ONLY))
    assert len(ctx.lights) == 1 and len(ctx.lights[0].cdf) == 2 * request.param ** 2
    hit = _floor_hits(ctx, np.repeat(POINTS_X, PIXELS), np.repeat(POINTS_Y, PIXELS), SPP)
    npix = len(POINTS_X) * PIXELS
    sub = np.tile(np.arange(SPP), npix)
    pix = np.repeat(np.arange(npix), SPP)
    ref = np.array([L * _lambert_polygon(np.array([x, y, 0.0]), np.array([0.0, 0.0, 1.0]),
                                         corners) for x, y in zip(POINTS_X, POINTS_Y)])
    yield ctx, hit, sub, pix, ref
    ctx.accel.close()


def _pixels(setup, seed, own_choice=False, monkeypatch=None):
    """(points, PIXELS) pixel means of the irradiance (green channel) over SPP samples.
    own_choice: the triangle chosen by its own random number, the point by the sampler's
    (u1, u2) (the sampling before)."""
    ctx, hit, sub, pix, _ = setup
    rng = np.random.default_rng(seed)
    sampler = StratifiedSampler(sub, pix, SPP, rng, camera_dimensions(0, [1]), salt=seed)
    if own_choice:
        cdf = ctx.lights[0].cdf
        lo = np.concatenate([[0.0], cdf[:-1]])

        def before(sampler, key):
            u1, u2 = sampler.uv(key)
            t = np.minimum(np.searchsorted(cdf, rng.random(len(u1)), side="right"),
                           len(cdf) - 1)
            # the choice that the kernel rescales back to u1 within triangle t's bin
            return u1, u2, lo[t] + u1 * (cdf[t] - lo[t])
        monkeypatch.setattr(integrator, "mesh_light_numbers", before)
    E = direct_irradiance(ctx, hit, rng, Counters(), sampler=sampler)
    return E[:, 1].reshape(len(POINTS_X), PIXELS, SPP).mean(axis=2)


def test_stratified_triangle_choice_keeps_the_mean(setup):
    ref = setup[4]
    px = _pixels(setup, 5)
    mean = px.mean(axis=1)
    se = px.std(axis=1) / math.sqrt(PIXELS)
    assert (np.abs(mean - ref) <= np.maximum(4.0 * se, 0.005 * ref)).all(), (mean / ref, se / ref)
    assert (np.abs(mean / ref - 1.0) < 0.01).all(), mean / ref


def test_stratified_triangle_choice_lowers_pixel_noise(setup, monkeypatch):
    ref = setup[4]
    noise = _pixels(setup, 6).std(axis=1) / ref
    noise_own = _pixels(setup, 6, own_choice=True, monkeypatch=monkeypatch).std(axis=1) / ref
    assert (noise < 0.75 * noise_own).all(), (noise, noise_own)


def test_stratified_triangle_choice_is_seeded(setup):
    a, b, c = _pixels(setup, 7), _pixels(setup, 7), _pixels(setup, 8)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_mesh_light_numbers_are_stratified_both_ways():
    """The choice x of each pixel's samples fills all m^2 strata of [0, 1) and stays in its
    sample's cell column (the points (x, u2) keep the 2-D cells); over many pixels x and u2
    are uniform and uncorrelated."""
    spp, npix = 16, 4000
    m = 4
    sub = np.tile(np.arange(spp), npix)
    pix = np.repeat(np.arange(npix), spp)
    sampler = StratifiedSampler(sub, pix, spp, np.random.default_rng(3),
                                camera_dimensions(0, [1]), salt=3)
    u1, u2, x = integrator.mesh_light_numbers(sampler, ("light", 0, 0))
    assert ((0 <= x) & (x < 1) & (0 <= u2) & (u2 < 1)).all()
    strata = np.floor(x * m * m).astype(int).reshape(npix, spp)
    assert (np.sort(strata, axis=1) == np.arange(spp)).all()
    assert np.array_equal(np.floor(x * m), np.floor(u1 * m))
    cells = (np.floor(u1 * m) + m * np.floor(u2 * m)).reshape(npix, spp)
    assert (np.sort(cells, axis=1) == np.arange(spp)).all()
    for v in (x, u2):
        hist = np.histogram(v, bins=64, range=(0, 1))[0]
        assert hist.min() > 0.85 * len(v) / 64 and hist.max() < 1.15 * len(v) / 64
    assert abs(np.corrcoef(x, u2)[0, 1]) < 0.02
    # the sub-column offset varies from pixel to pixel (else the points would cover only
    # 1/m of each cell in every pixel alike)
    offset = ((np.floor(x * m * m) - m * np.floor(u1 * m)) - np.floor(u2 * m)) % m
    assert len(np.unique(offset.reshape(npix, spp)[:, 0])) == m
