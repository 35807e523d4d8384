"""The seventh slice's glue cuts (docs/performance.md, "Seventh slice: scaling"), each
against the numpy stage it replaced, bitwise: the scalar film passes' scatter-adds
(camerakernels.film_add_scalar, film_first_normals) against np.bincount, the generator drawn
in one call against the calls it replaced, Accel.intersect against raw embreex, and the
photon pass's tilt cache against the uncached offsets."""
import numpy as np
import pytest

from engine import photonkernels as pk
from engine.accel import Accel
from engine.camerakernels import film_add_scalar, film_first_normals
from engine.geometry import prepare
from engine.integrator import Accumulator

from test_photon_kernels import _scene


def _bincount(lo, pix, w, npix):
    return np.bincount(pix - lo, weights=w, minlength=npix)


def test_film_add_scalar_equals_bincount_accumulation():
    rng = np.random.default_rng(11)
    n, lo, npix = 5000, 19, 97
    pix = lo + rng.integers(0, npix, n)  # many rows per pixel: the summation order counts
    w = rng.random(n) * np.exp(rng.normal(size=n) * 4)
    start = rng.random(npix)
    want = start + _bincount(lo, pix, w, npix)
    got = start.copy()
    film_add_scalar(got, lo, pix, w)
    assert np.array_equal(got, want)
    acc = Accumulator(npix, lo)
    acc.alpha[:] = start
    acc.add_scalar(acc.alpha, pix, (w > 1.0).astype(float))  # the alpha pass's weights
    assert np.array_equal(acc.alpha, start + _bincount(lo, pix, (w > 1.0).astype(float), npix))


def test_film_first_normals_equals_the_bincounts_it_replaced():
    rng = np.random.default_rng(12)
    n, lo, npix = 6000, 5, 130
    pix = np.sort(lo + rng.integers(0, npix, n))
    ns = rng.normal(size=(n, 3))
    front = rng.random(n) < 0.7
    acc = Accumulator(npix, lo)
    acc.normal[:] = rng.random(acc.normal.shape)  # not zero: the sums are added, not assigned
    ref = acc.normal.copy()
    # The numpy stage (integrator._trace_paths before this slice).
    facing = np.where(front, 1.0, -1.0)
    for c in range(3):
        ref[:, c] += _bincount(lo, pix, ns[:, c] * facing, npix)
    acc.add_first_normals(pix, ns, front)
    assert np.array_equal(acc.normal, ref)
    # An empty batch adds nothing.
    film_first_normals(lo, np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.bool_),
                       acc.normal)
    assert np.array_equal(acc.normal, ref)


@pytest.mark.parametrize("rows", [3, 0])
def test_one_generator_call_draws_the_numbers_of_several(rows):
    """The camera path draws (u1, u2[, u3]) per row in one call: the same numbers, and the
    generator left in the same state, as the separate calls it replaced."""
    n = 1000
    a = np.random.default_rng([1, 7, 3])
    b = np.random.default_rng([1, 7, 3])
    one = a.random((rows, n))
    several = [b.random(n) for _ in range(rows)]
    for i in range(rows):
        assert np.array_equal(one[i], several[i])
        assert one[i].flags.c_contiguous
    assert np.array_equal(a.random(17), b.random(17))


def test_accel_intersect_equals_raw_embree_with_and_without_tmax():
    s = _scene()
    s.validate()
    geo, _ = prepare(s)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    rng = np.random.default_rng(4)
    n = 3000
    o = (0.1, -0.2, 1.6) - geo.offset + 0.3 * rng.random((n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    tmax = rng.random(n) * 1.5  # some rays end before any surface
    scene = accel._scene
    for far in (None, tmax):
        t, prim, u, v = accel.intersect(o, d, far)
        f32 = (np.full(n, np.finfo(np.float32).max, np.float32) if far is None
               else far.astype(np.float32))
        res = scene.run(o.astype(np.float32), d.astype(np.float32), dists=f32.copy(),
                        output=True)
        hit = res["geomID"] >= 0
        assert 0 < hit.sum() and (far is None or hit.sum() < n)
        assert np.array_equal(prim, np.where(hit, res["primID"], -1))
        assert np.array_equal(t, np.where(hit, res["tfar"].astype(np.float64), np.inf))
        assert np.array_equal(u, res["u"].astype(np.float64))
        assert np.array_equal(v, res["v"].astype(np.float64))
        assert prim.dtype == np.int64 and t.dtype == u.dtype == v.dtype == np.float64
    # Occlusion up to tmax (the copy of tmax Embree writes into is the call's own).
    t, prim, _, _ = accel.intersect(o, d, tmax)
    keep = tmax.copy()
    blocked = accel.occluded(o, d, tmax)
    assert np.array_equal(tmax, keep)
    raw = np.asarray(scene.run(o.astype(np.float32), d.astype(np.float32),
                               dists=tmax.astype(np.float32), query="OCCLUDED")) == 0
    assert np.array_equal(blocked, raw) and np.array_equal(blocked, prim >= 0)
    assert accel.intersect(np.zeros((0, 3)), np.zeros((0, 3)))[1].shape == (0,)


def test_tilt_cache_gives_the_uncached_offsets_on_colliding_triangles():
    """photon_surfaces' offsets over a whole batch (tilts read from the per-call cache)
    equal the same kernel's offsets hit by hit (a fresh cache per call: every tilt
    computed), on a mesh of more triangles than cache slots (rows t and t + 1024 share a
    slot: evictions) with tilted triangles, and stay close to Geometry.origin_offset."""
    from engine.api import PaperScene, sphere_mesh
    from engine.scene import Material
    s = PaperScene(width=16, height=12)
    s.add_material(Material("wall", (0.6, 0.5, 0.4)))
    s.add_box((0, 0, 1), (2, 2, 2), "wall", name="room")
    v, f, nrm, _ = sphere_mesh((0.1, 0.1, 0.9), 0.6, segments=64, rings=40)  # ~5k triangles
    s.add_triangles(v, f, "wall", name="ball", normals=nrm)
    s.add_point_light((0.1, -0.2, 1.6), power=10.0)
    s.set_camera((0, -0.9, 1), (0, 0, 1), view_angle=90)
    s.validate()
    geo, table = prepare(s)
    assert len(geo.faces32) > 2 * pk._TILT_SLOTS
    accel = Accel(geo.vertices32, geo.faces32, 1)
    rng = np.random.default_rng(9)
    n = 20000
    o = np.tile((0.1, -0.2, 1.8) - geo.offset, (n, 1)) + 0.05 * rng.random((n, 3))
    o[n // 2:] = (0.1, 0.1, 0.9) - geo.offset  # from inside the ball: its triangles
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    _, prim, u, v = accel.intersect(o, d)
    assert len(np.unique(prim[prim >= 0])) > pk._TILT_SLOTS
    surf = pk.surface_arrays(n)
    pk.photon_surfaces(prim, u, v, d, geo.v0, geo.e1, geo.e2, geo.corner_normals,
                       geo.material, table.base_color, table.alpha, *surf)
    hit = np.nonzero(prim >= 0)[0]
    one = pk.surface_arrays(1)
    for i in hit[::7]:
        pk.photon_surfaces(prim[i:i + 1], u[i:i + 1], v[i:i + 1], d[i:i + 1], geo.v0, geo.e1,
                           geo.e2, geo.corner_normals, geo.material, table.base_color,
                           table.alpha, *one)
        assert one[7][0] == surf[7][i]
    want = geo.origin_offset(prim[hit], u[hit], v[hit], surf[0][hit], surf[1][hit])
    np.testing.assert_allclose(surf[7][hit], want, rtol=1e-9, atol=0)


def _area_intersect_numpy(light, o, d, tmax):
    """AreaLight.intersect's numpy stage before intersect_area (the oracle)."""
    import math
    from engine.sampling import dot
    from engine.scene import DISK, spread_attenuation
    n = len(o)
    denom = dot(d, light.dir)
    facing = denom < -1e-12
    t = np.where(facing, dot(light.pos - o, light.dir) / np.where(facing, denom, -1.0), np.inf)
    hitp = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - light.pos
    x, y = dot(hitp, light.u) / (light.size_x / 2), dot(hitp, light.v) / (light.size_y / 2)
    inside = ((x * x + y * y <= 1.0) if light.shape == DISK
              else ((np.abs(x) <= 1) & (np.abs(y) <= 1)))
    mask = facing & inside & (t > 0) & (t < tmax)
    L = np.broadcast_to(light.radiance, (n, 3))
    if light.spread < math.pi:
        L = L * spread_attenuation(-denom, light.spread)[:, None]
    return mask, t, L


@pytest.mark.parametrize("shape, spread", [("RECTANGLE", np.pi), ("DISK", np.pi),
                                           ("DISK", 0.7), ("RECTANGLE", 1.2)])
def test_area_light_intersect_kernel_equals_numpy_stage(shape, spread):
    from engine.api import cornell_box
    from engine.render import prepare_context
    from engine.settings import RenderSettings
    from engine.scene import AREA
    s = cornell_box(16, 12, glass_sphere=False)
    area = [li for li in s.lights if li.kind == AREA]
    if not area:
        pytest.skip("no area light in the box")
    area[0].shape = shape
    area[0].spread = spread
    ctx = prepare_context(s, RenderSettings(workers=1))
    light = next(li for li in ctx.lights if li.kind == AREA)
    rng = np.random.default_rng(21)
    n = 20000
    # Rays from below the light towards it (many hits near the edge) and random ones.
    o = light.pos + rng.normal(size=(n, 3)) * 0.6
    o[:, 2] = light.pos[2] - np.abs(rng.normal(size=n))
    target = light.pos + rng.normal(size=(n, 3)) * 0.3
    d = target - o
    d[n // 2:] = rng.normal(size=(n - n // 2, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    tmax = np.where(rng.random(n) < 0.2, rng.random(n) * 0.5, np.inf)
    want = _area_intersect_numpy(light, o, d, tmax)
    got = light.intersect(o, d, tmax)
    assert want[0].sum() > 100
    for a, b in zip(got, want):
        assert np.array_equal(a, b)
    got = light.intersect(o, d, 1.0)  # a scalar tmax
    assert np.array_equal(got[0], _area_intersect_numpy(light, o, d, 1.0)[0])
