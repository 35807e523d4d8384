"""Shadow rays to an emissive mesh choose the triangle by a stratified number (issue 14):
the pixel's samples spread over a panel's triangles in proportion to their power, and the
same number, rescaled within the chosen triangle's CDF bin, places the point on it
(integrator.mesh_light_numbers, directlight.sample_lights; pbrt-v4's SampleDiscrete).

A 3 x 3-quad panel (18 triangles) tilted over a floor, direct light only, 16 samples a
"pixel" (one floor point): the mean matches Lambert's closed form for the panel's polygon,
the pixel noise is well below that of a triangle chosen by its own random number (the
choice before; measured 0.50-0.67x), and the same seed gives the same numbers.
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


@pytest.fixture(scope="module")
def setup():
    verts, faces, corners = _panel()
    s = PaperScene(width=4, height=4)
    s.add_material(Material("lamp", (0.0, 0.0, 0.0), emission=(L, L, L)))
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, "white_diffuse", name="floor")
    s.add_mesh(Mesh("panel", verts, faces, materials=["lamp"]))
    s.camera = Camera(position=(0, -10, 3), rotation=np.eye(3))
    ctx = prepare_context(s, RenderSettings(**DIRECT_ONLY))
    assert len(ctx.lights) == 1 and len(ctx.lights[0].cdf) == 18
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
    own_choice: the triangle chosen by its own random number (the choice before)."""
    ctx, hit, sub, pix, _ = setup
    rng = np.random.default_rng(seed)
    sampler = StratifiedSampler(sub, pix, SPP, rng, camera_dimensions(0, [1]), salt=seed)
    if own_choice:
        monkeypatch.setattr(integrator, "mesh_light_numbers",
                            lambda u1, u2, m: (u2, rng.random(len(u1))))
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
    assert (noise < 0.8 * noise_own).all(), (noise, noise_own)


def test_stratified_triangle_choice_is_seeded(setup):
    a, b, c = _pixels(setup, 7), _pixels(setup, 7), _pixels(setup, 8)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_mesh_light_numbers_are_uniform_and_independent():
    """The choice (the cell read as one of m^2 strata) and the second coordinate (the
    jitter of u2 in its cell) from uniform (u1, u2): each uniform, uncorrelated, the choice
    stratified when the cells are."""
    rng = np.random.default_rng(3)
    m = 4
    cell = np.arange(m * m).repeat(2000)
    u1 = (cell % m + rng.random(len(cell))) / m
    u2 = (cell // m + rng.random(len(cell))) / m
    second, choice = integrator.mesh_light_numbers(u1, u2, m)
    assert ((0 <= choice) & (choice < 1) & (0 <= second) & (second < 1)).all()
    # every cell maps to its own 1/m^2 interval of the choice
    assert np.array_equal(np.floor(choice * m * m).astype(int), cell)
    for x in (choice, second):
        hist = np.histogram(x, bins=16, range=(0, 1))[0]
        assert hist.min() > 0.9 * len(x) / 16 and hist.max() < 1.1 * len(x) / 16
    assert abs(np.corrcoef(choice, second)[0, 1]) < 0.03
