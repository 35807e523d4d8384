"""Heterogeneous media beside and on shared instances (two-level tracing with the
instanced rows stored once per prototype, engine/sharedrows.py): the media's triangles
are read through SharedRows (heterogeneous.medium_rows), so a textured-density cube
beside 200 instanced pebbles renders as it does with the pebbles expanded, and
instanced copies of a textured cloud are each their own medium."""
import numpy as np
import pytest

from engine import RenderSettings, resources
from engine.api import PaperScene
from engine.geometry import prepare
from engine.heterogeneous import HeterogeneousMedia, medium_rows
from engine.render import render
from engine.scene import Material, Mesh, Prototype
from engine.shadernodes import Math, ObjectSpacePosition, SeparateChannel

SIGMA_A = (0.8, 1.2, 1.6)  # 1/m at density 1
SIGMA_S = (1.5, 1.5, 1.5)
N_PEBBLES = 200

_CUBE_V = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
_CUBE_F = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                    [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])


def _density():
    """A ramp along world x: 3 (x + 0.5) (0 to 3 across the cube at the origin)."""
    x = SeparateChannel(ObjectSpacePosition(np.eye(4)), 0)
    return Math("MULTIPLY", Math("ADD", x, 0.5), 3.0)


def _pebble_matrices(n=N_PEBBLES, seed=3):
    """Small rotated, scaled pebbles on the floor in a ring around the cube (some
    mirrored), none between the cube and the lamp."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        A = q @ np.diag(rng.uniform(0.06, 0.14, 3))
        if i % 5 == 4:
            A[:, 2] *= -1
        ang = 2 * np.pi * i / n
        r = rng.uniform(1.4, 2.4)
        M = np.eye(4)
        M[:3, :3] = A
        M[:3, 3] = [r * np.cos(ang), r * np.sin(ang), 0.08]
        out.append(M)
    return out


def _scene(instanced_cloud=False):
    """A floor, a 1 m cube of fog whose density ramps along x (or, with
    instanced_cloud, three placements of one cube prototype with that fog, one
    mirrored), 200
    instanced pebbles, a point light, looking down at an angle."""
    s = PaperScene(40, 30)
    s.add_material(Material("fog", volume_only=True, absorption=SIGMA_A,
                            scattering=SIGMA_S, density_texture=_density()))
    s.add_material(Material("white", (0.8, 0.8, 0.8)))
    s.add_material(Material("stone", (0.5, 0.4, 0.3), roughness=0.5))
    s.add_plane((0, 0, 0), (0, 0, 1), 12.0, "white", name="floor")
    if instanced_cloud:
        cube = Prototype("cube", _CUBE_V, _CUBE_F)
        for i, x in enumerate((-1.2, 0.0, 1.2)):
            M = np.eye(4)
            # (the middle copy mirrored: its corners 0, 2, 1, e1 and e2 swapped)
            M[:3, :3] = np.diag([-0.9 if i == 1 else 0.9, 0.9, 0.9 + 0.2 * i])
            M[:3, 3] = [x, 0.0, 0.6]
            s.add_mesh(Mesh.place(f"cloud.{i}", cube, M, materials=["fog"]))
    else:
        s.add_box((0, 0, 0.6), (1.0, 1.0, 1.0), "fog", name="cloud")
    pebble = Prototype("pebble", _CUBE_V, _CUBE_F)
    for i, M in enumerate(_pebble_matrices()):
        s.add_mesh(Mesh.place(f"pebble.{i:03d}", pebble, M, materials=["stone"]))
    s.add_point_light((0.3, -0.4, 3.0), power=400.0)
    s.set_camera((0, -4.5, 3.2), (0, 0, 0.5), view_angle=50)
    return s


def _two_level(monkeypatch, on):
    if on:
        monkeypatch.setattr(resources, "INSTANCE_BUDGET_FRACTION", 0.0)
    else:
        monkeypatch.setattr(resources, "INSTANCE_BUDGET_FRACTION", 1e9)
        monkeypatch.setattr(resources, "INSTANCE_RATIO", 10 ** 12)


def _media(monkeypatch, on, **kw):
    _two_level(monkeypatch, on)
    geo, table = prepare(_scene(**kw))
    assert (geo.shared is not None) == on
    return geo, HeterogeneousMedia.for_scene(geo, table, seed=3)


@pytest.mark.parametrize("instanced_cloud", [False, True])
def test_media_rows_read_through_shared_instances(monkeypatch, instanced_cloud):
    """The media's rows, corners, objects and coordinate maps, the stand-in's mean and
    the majorant grids: equal with the instances shared and expanded (bitwise for a
    static cube; instanced copies' corners are placed by their matrices in both, within
    rounding)."""
    geo_x, het_x = _media(monkeypatch, False, instanced_cloud=instanced_cloud)
    geo_s, het_s = _media(monkeypatch, True, instanced_cloud=instanced_cloud)
    assert isinstance(het_s, HeterogeneousMedia) and not het_s.limits()
    assert het_s.tracked and set(het_s.fields) == set(het_x.fields)
    np.testing.assert_array_equal(het_s.rows, het_x.rows)
    assert len(het_s.rows) == 12 * (3 if instanced_cloud else 1)
    np.testing.assert_array_equal(het_s.material, het_x.material)
    np.testing.assert_array_equal(het_s.object, het_x.object)
    assert len(np.unique(het_s.object)) == (3 if instanced_cloud else 1)
    fog = geo_s.material[het_s.rows[:1]][0]
    # medium_rows reads the shared Geometry without building its material column
    np.testing.assert_array_equal(medium_rows(geo_s, [fog]),
                                  np.flatnonzero(np.asarray(geo_x.material) == fog))
    tol = dict(rtol=1e-12, atol=1e-12) if instanced_cloud else dict(rtol=0, atol=0)
    np.testing.assert_allclose(het_s.normal, het_x.normal, **tol)
    for key in het_x.maps:
        np.testing.assert_allclose(het_s.maps[key], het_x.maps[key], rtol=1e-9, atol=1e-9)
    f_s, f_x = het_s.fields[fog], het_x.fields[fog]
    if not instanced_cloud:
        assert f_x.f_mean == pytest.approx(1.5, rel=0.02)  # the ramp's mean over the cube
    assert f_s.f_mean == pytest.approx(f_x.f_mean, rel=1e-9)
    assert f_s.f_max == pytest.approx(f_x.f_max, rel=1e-9)
    np.testing.assert_allclose(het_s.grid.sup, het_x.grid.sup, rtol=1e-9, atol=1e-12)
    if instanced_cloud:
        assert geo_s.shared.flip[:3].tolist() == [False, True, False]  # (the clouds)
    # 500 rays from above the scene down through the clouds: the same tracked correction
    # (the ratio-tracking streams are keyed by the ray: equal rays, equal draws)
    rng = np.random.default_rng(7)
    half = 1.6 if instanced_cloud else 0.5
    o = np.column_stack([rng.uniform(-half, half, 500), rng.uniform(-0.4, 0.4, 500),
                         np.full(500, 3.0)]) - np.asarray(geo_s.offset)  # (re-centred)
    d = np.column_stack([rng.uniform(-0.3, 0.3, (500, 2)), -np.ones(500)])
    c_s = het_s.correction(o, d, np.full(500, 3.0))
    c_x = het_x.correction(o, d, np.full(500, 3.0))
    assert (c_x != 1.0).any(axis=1).mean() > 0.5  # most rays cross a cloud
    if instanced_cloud:
        np.testing.assert_allclose(c_s, c_x, rtol=1e-9)
    else:
        np.testing.assert_array_equal(c_s, c_x)


def _image(monkeypatch, on, **kw):
    _two_level(monkeypatch, on)
    film = render(_scene(**kw), RenderSettings(workers=1, spp=16, photons=20000,
                                               caustic_photons=0, seed=4))
    return film, np.asarray(film.combined, np.float64)[..., :3]


def test_a_textured_cube_beside_shared_instances_renders_as_expanded(monkeypatch):
    """The render with the 200 pebbles traced two-level (shared) and expanded: the same
    image within noise, the fog heterogeneous in both (its darker -x side: the ramp),
    and no warning about shared instances."""
    film_x, img_x = _image(monkeypatch, False)
    film_s, img_s = _image(monkeypatch, True)
    warn = film_s.stats.get("warnings", [])
    assert not any("homogeneous" in w for w in warn), warn
    assert any("density texture of 'fog'" in line for line in film_s.stats["effects"])
    assert img_s.mean() == pytest.approx(img_x.mean(), rel=0.01)
    # The cube's pixels, its -x and +x halves on screen: equal within noise (the
    # photon maps differ in rounding: the pebbles' hits are float32 in object space);
    # the thin -x side brighter than the dense +x side, the ramp's signature (measured
    # 1.38 for both; the homogeneous stand-in at the mean density 1.5 gives 0.65).
    rows = slice(11, 19)
    halves = [(img[rows, 15:20].mean(), img[rows, 20:25].mean()) for img in (img_s, img_x)]
    (left_s, right_s), (left_x, right_x) = halves
    assert left_s == pytest.approx(left_x, rel=0.03)
    assert right_s == pytest.approx(right_x, rel=0.03)
    assert left_s / right_s > 1.15 and left_x / right_x > 1.15
