"""Small scene builders shared by the engine tests."""
import math
import os

import numpy as np

from engine.api import PaperScene
from engine.scene import Camera, Material

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def top_down_plane(albedo=0.5, size=8.0, res=64, view=4.0):
    """A diffuse plane at z=0 seen by an orthographic camera looking straight down.
    Pixel (i, j) centre maps to world (x, y) returned by pixel_to_world."""
    s = PaperScene(width=res, height=res)
    s.add_material(Material("matte", (albedo,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), size, "matte", name="plane")
    s.camera = Camera(position=(0, 0, 5), rotation=np.eye(3), kind="ORTHO", ortho_scale=view)
    return s


def pixel_to_world(scene, view):
    res = scene.width
    c = (np.arange(res) + 0.5) / res * view - view / 2
    x = np.tile(c, (res, 1))
    y = np.tile(-c[:, None], (1, res))  # row 0 is the top of the image (+y)
    return x, y


def rel_err(a, b):
    return abs(float(a) - float(b)) / max(abs(float(b)), 1e-12)


def rect_corner_factor(a, b, h):
    """Irradiance / radiance at a point under one corner of a parallel a x b rectangle at
    height h (closed-form differential-area form factor times pi)."""
    X, Y = a / h, b / h
    return 0.5 * (X / math.sqrt(1 + X * X) * math.atan(Y / math.sqrt(1 + X * X))
                  + Y / math.sqrt(1 + Y * Y) * math.atan(X / math.sqrt(1 + Y * Y)))


def rays_from_inside(ctx, n, seed):
    """n rays from random points inside the middle 80 % of the scene's bounding box in
    uniformly random directions, and their hits: (prim, u, v (K,), d (K,3)) of the K rays
    that hit something; ctx: a render Context (engine.render.prepare_context)."""
    from engine.sampling import uniform_sphere
    rng = np.random.default_rng(seed)
    lo, hi = ctx.geo.bounds
    o = lo + (hi - lo) * (0.1 + 0.8 * rng.random((n, 3)))
    d = uniform_sphere(rng.random(n), rng.random(n))
    t, prim, u, v = ctx.accel.intersect(o, d)
    k = prim >= 0
    return prim[k], u[k], v[k], d[k]


def hits_from_inside(ctx, n, seed):
    """The surface hits (engine.bsdf.SurfaceHit) of rays_from_inside(ctx, n, seed)."""
    from engine.bsdf import surface_hit
    return surface_hit(ctx.geo, ctx.table, *rays_from_inside(ctx, n, seed))


def assert_mis_matches_continuation(mis, mis2, cont, cont2, noise_limit, cont_spp=64,
                                    mis_spp=64):
    """Light sampling with MIS against the lobes' continuation alone (two unbiased
    estimators of the same light), each rendered at two seeds (images (H, W, 3)):
    MIS's pixel noise (the difference of its two renders: the image's own shape cancels)
    must be below noise_limit x the continuation's, scaled to mis_spp samples, and the two
    means must agree within 4 standard errors of the continuation's mean (or 2 %)."""
    raw_cont = np.std(cont - cont2)
    noise_mis = np.std(mis - mis2)
    noise_cont = raw_cont * math.sqrt(cont_spp / mis_spp)
    assert noise_cont > 0, "the continuation must see the light"
    assert noise_mis < noise_limit * noise_cont, (noise_mis, noise_cont)
    m_mis, m_cont = 0.5 * (mis.mean() + mis2.mean()), 0.5 * (cont.mean() + cont2.mean())
    se = raw_cont / math.sqrt(2.0) / math.sqrt(2.0 * mis.size)
    assert m_mis > 0
    assert abs(m_mis - m_cont) <= max(4.0 * se, 0.02 * m_cont), (m_mis, m_cont, se)


def random_environment(seed=3, h=12, w=24, rotation=None, interpolation="Linear"):
    """A small random equirectangular Environment (h x w) with a bright texel (a sun) and a
    black bottom row (zero pdf there unless the filter covers it)."""
    from engine import Environment
    rng = np.random.default_rng(seed)
    px = rng.random((h, w, 3)) ** 3
    px[2, 5] = 300.0   # a sun
    px[h - 1, :] = 0.0  # a black band
    return Environment(px, 1.3, rotation, interpolation)


def sphere_grid(n_theta, n_phi):
    """Cell-midpoint directions (K,3) of a (theta, phi) grid over the sphere, their
    sin(theta) (K,) and the d(theta) d(phi) of a cell."""
    th = (np.arange(n_theta) + 0.5) / n_theta * math.pi
    ph = (np.arange(n_phi) + 0.5) / n_phi * 2 * math.pi
    t, p = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    return d, np.sin(t).reshape(-1), (math.pi / n_theta) * (2 * math.pi / n_phi)


def assert_unbiased(e, want, label="", rel=0.01):
    """Samples e (N,) of an estimator against the exact value want: the mean within 4
    standard errors and within rel of it (printed with the per-sample std / mean)."""
    se = e.std() / math.sqrt(len(e))
    print(label, f"mean/want {e.mean() / want:.4f} se/want {se / want:.4f} "
          f"std/mean {e.std() / e.mean():.3f}")
    assert abs(e.mean() - want) < 4 * se
    assert abs(e.mean() / want - 1.0) <= rel
