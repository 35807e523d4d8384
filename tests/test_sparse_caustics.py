"""Caustic light that reaches a surface thinly (issue 14): the camera side's caustic and
secondary-caustic estimates (integrator._smooth_estimate) take every photon of the search
disc however few (integrator.smooth_min_photons), outside paper mode. With fewer than k
photons the k-NN estimate is the photons of the whole disc over its area, an unbiased
estimate; zeroing it below min_photons (8) darkened light that arrives sparsely: a
constant world reflected by a rough metal ball and a glossy floor onto a diffuse ball
(tools/glossy_noise.py's dielectric ball under a world read 0.977 of Cycles, 0.981 with
this; docs/accuracy_time.md, "Glossy noise against Cycles")."""
from types import SimpleNamespace

import numpy as np
import pytest

from engine.integrator import _smooth_estimate, smooth_min_photons
from engine.photonmap import PhotonMap
from engine.photons import Photons
from engine.settings import RenderSettings

E = 2.0          # W/m^2 the photons stand for, on the plane z = 0
SIDE = 10.0      # m, the photons' square
COUNT = 20_000   # 200 photons / m^2
RADIUS = 0.08    # ~4 photons per search disc: most discs hold fewer than 8


def _sparse_plane_map(rng):
    n = COUNT
    pos = np.column_stack([rng.uniform(-SIDE / 2, SIDE / 2, n), rng.uniform(-SIDE / 2, SIDE / 2, n),
                           np.zeros(n)]).astype(np.float32)
    power = np.full((n, 3), E * SIDE * SIDE / n, np.float32)
    down = np.tile(np.array([0.0, 0.0, -1.0], np.float32), (n, 1))
    up = np.tile(np.array([0.0, 0.0, 1.0], np.float32), (n, 1))
    return PhotonMap(Photons(pos, power, down, up, np.ones(n, np.uint8)))


@pytest.mark.parametrize("paper_mode", [False, True])
def test_sparse_caustic_estimate_keeps_its_light(paper_mode):
    """Photons of irradiance E spread ~4 to a search disc: the mean estimate over the
    square's middle is E (the middle holds ~7,000 photons: ~1.2 % noise) outside paper
    mode; the paper's min_photons rule (kept in paper mode) zeroes most discs."""
    rng = np.random.default_rng(4)
    pmap = _sparse_plane_map(rng)
    settings = RenderSettings(paper_mode=paper_mode, estimator="knn_simpson")
    ctx = SimpleNamespace(settings=settings)
    m = 4000
    p = np.column_stack([rng.uniform(-3, 3, m), rng.uniform(-3, 3, m), np.zeros(m)])
    hit = SimpleNamespace(p=p, ng=np.tile([0.0, 0.0, 1.0], (m, 1)))
    f = np.ones((m, 3))
    got = _smooth_estimate(ctx, pmap, RADIUS, hit, f, None)[:, 0].mean()
    if paper_mode:
        assert smooth_min_photons(settings) == settings.min_photons == 8
        assert got < 0.3 * E
    else:
        assert smooth_min_photons(settings) == 1
        assert got == pytest.approx(E, rel=0.05)


@pytest.mark.parametrize("spp, per_pixel", [(100, 16), (128, 16), (50, 4), (7, 16), (200, 4)])
def test_strided_estimate_keeps_each_pixels_mean(spp, per_pixel):
    """A smooth estimate taken at one sample in `stride` of a pixel is weighted so the
    pixel's mean is the estimate at its point, whatever spp is: sub-samples 0, stride, ...
    of spp = 100 with 16 a pixel are 15 samples, not 100 / 7 (the weight was the stride,
    +5 % at 100 spp and +4 % at 200 with 4)."""
    rng = np.random.default_rng(5)
    pmap = _sparse_plane_map(rng)
    ctx = SimpleNamespace(settings=RenderSettings(spp=spp, estimator="knn_simpson"))
    pixels = 40
    centres = np.column_stack([rng.uniform(-3, 3, pixels), rng.uniform(-3, 3, pixels),
                               np.zeros(pixels)])
    p = np.repeat(centres, spp, axis=0)  # every sample of a pixel at its centre
    sample_id = np.tile(np.arange(spp), pixels)
    hit = SimpleNamespace(p=p, ng=np.tile([0.0, 0.0, 1.0], (len(p), 1)))
    f = np.ones((len(p), 3))
    strided = _smooth_estimate(ctx, pmap, RADIUS, hit, f, sample_id, per_pixel=per_pixel)
    every = _smooth_estimate(ctx, pmap, RADIUS, hit, f, None)
    assert np.allclose(strided[:, 0].reshape(pixels, spp).mean(axis=1),
                       every[:, 0].reshape(pixels, spp).mean(axis=1), rtol=1e-12, atol=0)
