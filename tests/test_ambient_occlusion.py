"""Ambient Occlusion node (engine/ambientocclusion.py) against the analytic value under a
parallel ceiling, its options (Inside, Only Local, Distance), the ray visibility it
honours, and its samples: a function of the hit alone (any batch, any worker count).

Under an infinite ceiling at height h, a cosine-weighted direction at angle theta meets
it at h / cos(theta); cos^2(theta) is uniform for cosine-weighted directions, so the
share of rays that reach Distance D unblocked is (h / D)^2 (D > h), 1 for D <= h."""
import numpy as np
import pytest

from engine.ambientocclusion import (AmbientOcclusion, OcclusionCore, ao_directions,
                                     concentric_disk)
from engine.api import PaperScene
from engine.render import prepare_context
from engine.scene import Material, Mesh
from engine.settings import RenderSettings


def _room(ceiling=True, shadow=True, one_object=False):
    """A floor (z = 0, facing up) and a ceiling 1 m above it (facing down), both 40 m
    wide; one_object: both in one mesh. The ceiling casts no shadows with shadow=False."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    if one_object:
        w = 20.0
        quad = np.array([[-w, -w], [w, -w], [w, w], [-w, w]])
        verts = np.vstack([np.column_stack([quad, np.zeros(4)]),
                           np.column_stack([quad, np.ones(4)])])
        faces = np.array([[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]])  # ceiling faces down
        s.add_mesh(Mesh("room", verts, faces, materials=["grey"]))
    else:
        s.add_plane((0, 0, 0), (0, 0, 1), 40.0, "grey", name="floor")
        if ceiling:
            top = s.add_plane((0, 0, 1), (0, 0, -1), 40.0, "grey", name="ceiling")
            top.visible_shadow = shadow
    s.set_camera((0, 0, 5), (0, 0, 0), view_angle=30)
    return s


def _floor_hits(ctx, n=64, seed=3):
    """prim, u, v of n hits spread over the floor's middle (rays from below)."""
    rng = np.random.default_rng(seed)
    o = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), np.full(n, -0.5)])
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    _, prim, u, v = ctx.accel.intersect(o - ctx.geo.offset, d)
    assert (prim >= 0).all()
    return prim, u, v


@pytest.fixture(scope="module")
def room():
    return prepare_context(_room(), RenderSettings(workers=1))


@pytest.mark.parametrize("distance", [0.5, 1.5, 2.0, 4.0])
def test_ao_under_a_ceiling_is_the_analytic_share(room, distance):
    prim, u, v = _floor_hits(room, n=256)
    ao = OcclusionCore(distance, samples=16).evaluate(room.geo, prim, u, v)
    want = min(1.0, (1.0 / distance) ** 2)
    print(distance, ao.mean(), want)
    assert ao.min() >= 0.0 and ao.max() <= 1.0
    # 256 hits x 16 samples: within 3 binomial standard deviations (stratified samples
    # do better; none at D <= h, where every ray is clear)
    assert abs(ao.mean() - want) <= 3.0 * np.sqrt(want * (1.0 - want) / (256 * 16)) + 1e-12


def test_color_output_is_ao_times_color(room):
    prim, u, v = _floor_hits(room)
    core = OcclusionCore(2.0)
    col = AmbientOcclusion(core, (0.2, 0.5, 1.0)).evaluate(room.geo, prim, u, v)
    ao = AmbientOcclusion(core, output="AO").evaluate(room.geo, prim, u, v)
    np.testing.assert_allclose(col, ao[:, None] * [0.2, 0.5, 1.0])


def test_inside_traces_below_the_floor(room):
    """Inside flips the normal: from the floor the rays go down, where nothing is."""
    prim, u, v = _floor_hits(room)
    np.testing.assert_array_equal(
        OcclusionCore(2.0, inside=True).evaluate(room.geo, prim, u, v), 1.0)


def test_only_local_sees_its_own_object_alone():
    """The ceiling a separate object: Only Local ignores it (AO 1); floor and ceiling in
    one mesh: Only Local sees it as the plain node does."""
    apart = prepare_context(_room(), RenderSettings(workers=1))
    prim, u, v = _floor_hits(apart)
    np.testing.assert_array_equal(
        OcclusionCore(2.0, only_local=True).evaluate(apart.geo, prim, u, v), 1.0)
    joined = prepare_context(_room(one_object=True), RenderSettings(workers=1))
    prim, u, v = _floor_hits(joined)
    local = OcclusionCore(2.0, only_local=True).evaluate(joined.geo, prim, u, v)
    plain = OcclusionCore(2.0).evaluate(joined.geo, prim, u, v)
    np.testing.assert_array_equal(local, plain)
    assert abs(plain.mean() - 0.25) < 0.02


def test_only_local_passes_other_objects_in_between():
    """A third object (a sheet 0.5 m up, between floor and a ceiling of the floor's own
    mesh) is passed by Only Local rays: the floor still sees its own ceiling."""
    scene = _room(one_object=True)
    scene.add_plane((0, 0, 0.5), (0, 0, -1), 40.0, "grey", name="sheet")
    ctx = prepare_context(scene, RenderSettings(workers=1))
    prim, u, v = _floor_hits(ctx)
    local = OcclusionCore(2.0, only_local=True).evaluate(ctx.geo, prim, u, v)
    assert abs(local.mean() - 0.25) < 0.02
    plain = OcclusionCore(2.0).evaluate(ctx.geo, prim, u, v)  # the sheet at 0.5 m
    assert abs(plain.mean() - 0.0625) < 0.01


def test_surfaces_without_shadows_do_not_occlude():
    """Object > Visibility > Shadow off: Cycles' AO rays (opaque shadow rays) pass it."""
    ctx = prepare_context(_room(shadow=False), RenderSettings(workers=1))
    prim, u, v = _floor_hits(ctx)
    np.testing.assert_array_equal(OcclusionCore(2.0).evaluate(ctx.geo, prim, u, v), 1.0)


def test_no_tracer_or_no_distance_reads_one(room):
    prim, u, v = _floor_hits(room)
    assert (OcclusionCore(0.0).evaluate(room.geo, prim, u, v) == 1.0).all()
    assert (OcclusionCore(2.0).evaluate(None, prim, u, v) == 1.0).all()


def test_a_hit_gets_the_same_ao_in_any_batch(room):
    """The samples are a function of the hit: a batch, its reverse and its halves agree
    (so chunks and worker counts do not change the image)."""
    prim, u, v = _floor_hits(room, n=40)
    full = OcclusionCore(2.0).evaluate(room.geo, prim, u, v).copy()
    rev = OcclusionCore(2.0).evaluate(room.geo, prim[::-1], u[::-1], v[::-1])
    np.testing.assert_array_equal(full, rev[::-1])
    half = OcclusionCore(2.0).evaluate(room.geo, prim[:20], u[:20], v[:20])
    np.testing.assert_array_equal(full[:20], half)


def test_directions_are_cosine_weighted_about_the_normal():
    n = np.tile(np.array([0.3, -0.4, 0.866]) / np.linalg.norm([0.3, -0.4, 0.866]), (500, 1))
    rng = np.random.default_rng(1)
    d = ao_directions(n, 16, rng.integers(0, 100, 500), rng.random(500), rng.random(500))
    np.testing.assert_allclose(np.linalg.norm(d, axis=2), 1.0, atol=1e-12)
    cos = np.einsum("nsk,nk->ns", d, n)
    assert cos.min() >= 0.0
    # cos^2 uniform on [0, 1] for cosine-weighted directions: mean 1/2, mean of cos 2/3
    assert abs((cos ** 2).mean() - 0.5) < 0.01 and abs(cos.mean() - 2.0 / 3.0) < 0.01
    xy = concentric_disk(np.array([0.5, 1.0, 0.5]), np.array([0.5, 0.5, 1.0]))
    np.testing.assert_allclose(xy, [[0, 0], [1, 0], [0, 1]], atol=1e-12)


def test_worker_count_does_not_change_an_ao_image():
    """A sun-lit floor with a box on it, the floor's colour the AO node (read by the
    photon pass and the camera pass alike): one worker or two, the same image."""
    s = _room(ceiling=False)
    core = OcclusionCore(1.5, samples=8)
    s.materials["dirt"] = Material("dirt", (1.0, 1.0, 1.0), texture=AmbientOcclusion(
        core, (0.9, 0.7, 0.5)))
    s.meshes[0].materials = ["dirt"]
    s.add_box((0.3, 0.2, 0.25), (0.5, 0.5, 0.5), "grey")
    s.add_sun(direction=(0.3, 0.2, -1.0), strength=2.0)
    s.set_camera((0, -0.6, 0.9), (0.3, 0.2, 0.0), view_angle=60)
    st = dict(photons=4000, caustic_photons=0, spp=2, seed=3)
    one = s.render(RenderSettings(workers=1, **st)).combined
    two = s.render(RenderSettings(workers=2, **st)).combined
    np.testing.assert_array_equal(one, two)
    assert np.ptp(one) > 0  # something rendered
