"""The Bump node's differences over the ray footprint (engine/bump.py), as Cycles'
svm_node_set_bump takes them: the height at P + filter_width dP/dx and P + filter_width
dP/dy, dP/dx and dP/dy the compact differential along make_orthonormals(Ng) (Blender 5.0
kernel/svm/displace.h, kernel/util/differential.h); the camera's differential
(kernel/camera/camera.h)."""
import math

import numpy as np
import pytest

from engine import shadernodes as sn
from engine.bsdf import surface_hit
from engine.bump import DEEPER, Bump, ViewFootprint, camera_differential, make_orthonormals
from engine.geometry import prepare
from engine.scene import Camera, Material, Mesh, Scene


def _quad(nmap, camera=None):
    """A unit quad at z = 0 facing +z, UV = xy, of one material with normal map nmap."""
    s = Scene(camera=camera, width=64, height=64)
    s.add_material(Material("b", (0.8,) * 3, normal_map=nmap))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    s.add_mesh(Mesh("quad", v, np.array([[0, 1, 2], [0, 2, 3]]), uvs=v[:, :2],
                    materials=["b"]))
    return prepare(s)


def _normals(geo, table, xy, footprint=None):
    """Shading normals seen from above at points xy (N,2) of _quad's plane."""
    xy = np.asarray(xy, float)
    low = xy[:, 0] >= xy[:, 1]  # triangle 0: p = (u + v, v); triangle 1: p = (u, u + v)
    prim = np.where(low, 0, 1)
    bu = np.where(low, xy[:, 0] - xy[:, 1], xy[:, 0])
    bv = np.where(low, xy[:, 1], xy[:, 1] - xy[:, 0])
    d = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
    return surface_hit(geo, table, prim, bu, bv, d, footprint=footprint).ns


def test_differences_of_a_linear_height_are_its_gradient_at_any_footprint():
    # h = 0.5 x: n' = normalize((0, 0, 1) - 0.8 (0.5, 0, 0)) whatever the step.
    h = sn.Math("MULTIPLY", sn.SeparateChannel(sn.UVCoord(), 0), 0.5)
    geo, table = _quad(Bump(h, distance=0.8))
    want = np.array([-0.4, 0, 1]) / math.hypot(0.4, 1)
    xy = [[0.3, 0.2], [0.2, 0.6], [0.7, 0.65]]
    for r in (1e-4, 1e-2, 0.3):
        got = _normals(geo, table, xy, np.full(3, r))
        np.testing.assert_allclose(got, np.tile(want, (3, 1)), atol=1e-9)


def test_a_step_bends_the_normal_over_the_filter_width_of_the_footprint():
    """h = 1 beyond x = 0.5. make_orthonormals((0, 0, 1)) gives a = (1, -1, 0) / sqrt 2,
    b = (1, 1, 0) / sqrt 2: at a point delta before the step both samples (s a, s b away,
    s = filter_width r) cross it while delta < s / sqrt 2, and the gradient is
    (a + b) / s = (sqrt 2 / s, 0, 0); beyond that the normal is unbent. Twice the
    footprint: twice the band, half the slope."""
    h = sn.Math("GREATER_THAN", sn.SeparateChannel(sn.UVCoord(), 0), 0.5)
    a, b = make_orthonormals(np.array([[0.0, 0.0, 1.0]]))
    np.testing.assert_allclose(a[0], [1 / math.sqrt(2), -1 / math.sqrt(2), 0], atol=1e-12)
    np.testing.assert_allclose(b[0], [1 / math.sqrt(2), 1 / math.sqrt(2), 0], atol=1e-12)
    dist = 0.05
    geo, table = _quad(Bump(h, distance=dist))
    for r in (0.02, 0.04):
        s = 0.1 * r
        delta = np.array([0.2, 0.6, 0.9, 1.2]) * s / math.sqrt(2)
        xy = np.column_stack([0.5 - delta, np.full(4, 0.3)])
        got = _normals(geo, table, xy, np.full(4, r))
        bent = np.array([-math.sqrt(2) * dist / s, 0.0, 1.0])
        bent /= np.linalg.norm(bent)
        np.testing.assert_allclose(got[:3], np.tile(bent, (3, 1)), atol=1e-9)
        np.testing.assert_allclose(got[3], [0, 0, 1], atol=1e-12)


def test_zero_filter_width_or_footprint_leaves_the_normal():
    h = sn.Math("MULTIPLY", sn.SeparateChannel(sn.UVCoord(), 0), 0.5)
    geo, table = _quad(Bump(h, distance=0.8, filter_width=0.0))
    np.testing.assert_allclose(_normals(geo, table, [[0.3, 0.2]], np.array([0.01])),
                               [[0, 0, 1]], atol=1e-12)
    geo, table = _quad(Bump(h, distance=0.8))
    np.testing.assert_allclose(_normals(geo, table, [[0.3, 0.2]], np.array([0.0])),
                               [[0, 0, 1]], atol=1e-12)


def _cycles_dd(cam, width, height, px, py):
    """Cycles' compact camera dD at pixel (px, py) by its definition: the normalised
    directions through the pixel and one pixel to the right / up, differenced."""
    hw, hh = cam.half_extents(width, height)
    pixel = 2 * hw / width

    def ray(x, y):
        c = np.array([(x - width / 2) * pixel, (y - height / 2) * pixel, -1.0])
        w = cam.rotation @ c
        return w / np.linalg.norm(w)
    d = ray(px, py)
    return d, 0.5 * (np.linalg.norm(ray(px + 1, py) - d) + np.linalg.norm(ray(px, py + 1) - d))


def test_camera_differential_is_cycles_per_pixel_direction_difference():
    cam = Camera.look_at((0, -3, 1), (0.3, 0, 0.2), fov_degrees=90.0)
    for px, py in ((32, 24), (2, 3), (60, 45), (5, 40)):
        d, want = _cycles_dd(cam, 64, 48, px, py)
        got = camera_differential(cam, 64, 48, d[None])[0]
        assert got == pytest.approx(want, rel=0.03)
    ortho = Camera.look_at((0, -3, 1), (0, 0, 0), kind="ORTHO", ortho_scale=2.0)
    np.testing.assert_allclose(camera_differential(ortho, 64, 48, np.zeros((2, 3))),
                               2.0 / 64)


def test_hits_without_a_footprint_take_the_cameras_at_their_distance():
    """surface_hit without footprints: the geometry's ViewFootprint, the camera's
    differential towards the hit times DEEPER times its distance (set by prepare)."""
    h = sn.Math("GREATER_THAN", sn.SeparateChannel(sn.UVCoord(), 0), 0.5)
    cam = Camera.look_at((0.5, 0.5, 2.0), (0.5, 0.5, 0.0), fov_degrees=40.0)
    geo, table = _quad(Bump(h, distance=0.05), camera=cam)
    assert isinstance(geo.view_footprint, ViewFootprint)
    p = np.array([[0.49, 0.3, 0.0]]) - geo.offset
    r = geo.view_footprint.at(p)
    d = (p + geo.offset) - cam.position
    dist = np.linalg.norm(d)
    assert r[0] == pytest.approx(camera_differential(cam, 64, 64, d / dist)[0] * dist * DEEPER)
    xy = [[0.49, 0.3], [0.495, 0.7]]
    hp = np.array([[0.49, 0.3, 0.0], [0.495, 0.7, 0.0]]) - geo.offset
    np.testing.assert_allclose(_normals(geo, table, xy),
                               _normals(geo, table, xy, geo.view_footprint.at(hp)),
                               atol=1e-12)


def _bumped_room():
    """A diffuse floor and back wall with a Bump (a linear height in x) under an area
    lamp, a camera in front: the gather rays from the floor end on the floor's far side
    and on the wall."""
    from engine.api import PaperScene
    h = sn.Math("MULTIPLY", sn.SeparateChannel(sn.ObjectSpacePosition(np.eye(4)), 0), 0.5)
    s = PaperScene(width=16, height=12, background=(0.0, 0.0, 0.0))
    s.add_material(Material("white", (0.8, 0.8, 0.8), specular=0.0,
                            normal_map=Bump(h, distance=0.1)))
    s.add_plane((0, 0, 0), size=4.0, material="white", name="Floor")
    s.add_plane((0, 2.0, 2.0), normal=(0, -1, 0), size=4.0, material="white", name="Wall")
    s.add_rect_area_light((0.0, 0.0, 2.5), size=(0.5, 0.5), power=300.0)
    s.set_camera((0.0, -3.0, 2.6), (0.0, 1.0, 0.8), view_angle=40)
    return s


@pytest.mark.parametrize("spread", [2e-3, 0.0])
def test_gather_ends_take_the_hits_footprint_transferred_over_the_ray(monkeypatch, spread):
    """Cycles' differential_transfer_compact: a gather ray's end has the footprint of the
    hit it left plus its length x the path's dD (the camera's, kept through the diffuse
    bounce; 0 for an orthographic camera, whose footprint stays the pixel's width):
    r0 + t dD, by hand from the end's distance to the gathering point. The Bump at each
    end takes exactly that (not the view footprint)."""
    from engine import RenderSettings, integrator
    from engine.bump import transfer_footprint
    from engine.integrator import Counters, gather_indirect
    from engine.render import _photon_pass, prepare_context
    monkeypatch.setattr(integrator, "MAX_GATHER_LEVEL", 0)  # level 0's ends alone
    ctx = prepare_context(_bumped_room(), RenderSettings(workers=1, photons=3_000,
                                                         caustic_photons=0, seed=2))
    try:
        _photon_pass(ctx, {}, None, None)
        n = 40
        o = np.tile([0.3, -1.0, 1.0], (n, 1)) - ctx.geo.offset
        d = np.tile(np.array([0.0, 0.6, -1.0]) / math.hypot(0.6, 1.0), (n, 1))
        t, prim, u, v = ctx.accel.intersect(o, d)
        assert np.all(prim >= 0)
        r0 = 0.004 + 1e-4 * np.arange(n)  # each hit's own footprint
        hit = surface_hit(ctx.geo, ctx.table, prim, u, v, d, footprint=r0)
        hit.footprint, hit.spread = r0, np.full(n, spread)
        seen = []
        real = Bump.perturb

        def spy(self, geo, prim, u, v, nrm, footprint=None):
            seen.append((geo.hit_points(prim, u, v), footprint))
            return real(self, geo, prim, u, v, nrm, footprint=footprint)

        monkeypatch.setattr(Bump, "perturb", spy)
        gather_indirect(ctx, hit, np.random.default_rng(5), Counters(), rays=8)
    finally:
        ctx.accel.close()
    assert len(seen) >= 8
    p0 = hit.p[0]
    for p, got in seen:
        assert got is not None
        # (the hits share a point: any of their footprints, the smallest row's first)
        t_end = np.linalg.norm(p - p0, axis=1)
        assert np.all(t_end > 0.05)
        lo, hi = transfer_footprint(r0[0], spread, t_end), transfer_footprint(r0[-1], spread,
                                                                             t_end)
        # (the engine's ray length is Embree's float32 distance, this one from the
        # points: they differ by ~1e-6 m, so the footprints by ~1e-6 m x dD; an Intel
        # Xeon's Embree put an end 2e-9 over the bound that 1e-12 allowed)
        slack = 1e-5 * spread + 1e-12
        assert np.all(got >= lo - slack) and np.all(got <= hi + slack)
        # by hand: each end's footprint minus its length x dD is one of the hits' own
        # (within the ray origin's offset and Embree's float32 distance, ~1e-6 m x dD;
        # the hits' footprints are 1e-4 m apart)
        np.testing.assert_allclose(
            np.min(np.abs((got - spread * t_end)[:, None] - r0[None, :]), axis=1), 0.0,
            atol=1e-8)


def test_camera_hits_footprint_is_dd_times_the_whole_camera_distance(monkeypatch):
    """Cycles starts a camera ray at its clip start with dP = nearclip x dD
    (kernel/camera/camera.h), so a camera hit's footprint is dD x its whole distance from
    the camera, not from the clip start (a 0.5 m clip start here: 14 % of the floor's
    distance); the gather rays' ends go on from there (longer paths: larger ratios)."""
    from engine import RenderSettings
    from engine.render import render
    s = _bumped_room()
    s.camera.clip_start = 0.5
    seen = []
    real = Bump.perturb

    def spy(self, geo, prim, u, v, nrm, footprint=None):
        if footprint is not None:
            view = geo.view_footprint
            p = geo.hit_points(prim, u, v) - view.position
            dist = np.linalg.norm(p, axis=1)
            dd = camera_differential(view.camera, view.width, view.height, p / dist[:, None])
            seen.append(footprint / (dd * dist))
        return real(self, geo, prim, u, v, nrm, footprint=footprint)

    monkeypatch.setattr(Bump, "perturb", spy)
    render(s, RenderSettings(workers=1, photons=2_000, caustic_photons=0, spp=1, seed=1))
    assert len(seen) > 2
    # (Embree's float32 distances: 1e-6)
    np.testing.assert_allclose(seen[0], 1.0, rtol=1e-6)  # the camera's first hits
    ratios = np.concatenate(seen[1:])
    assert np.all(ratios >= 1.0 - 1e-6)  # the gather ends': dD x (t_cam + t_gather)
    assert np.median(ratios) > 1.05
