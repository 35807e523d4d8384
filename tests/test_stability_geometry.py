"""Stability groups 1 (scale and position), 2 (grazing angles, shading normals) and
4 (bad geometry). See docs/stability.md."""
import math

import numpy as np
import pytest

from engine.api import PaperScene, box_mesh
from engine.scene import Camera, Material, Mesh

from test_stability_common import box_room, relmse, run

# ---------------------------------------------------------------- 1. scale and position


@pytest.fixture(scope="module")
def room_reference():
    return run(box_room(), photons=6000, spp=4)


@pytest.mark.parametrize("scale,shift", [(1e-3, 0.0), (1e3, 0.0), (1.0, 1e5), (1e3, 1e5)],
                         ids=["scale_1e-3", "scale_1e3", "translate_1e5", "scale_1e3_translate_1e5"])
def test_scaled_and_translated_room_renders_the_same_image(room_reference, scale, shift):
    ref = room_reference
    film = run(box_room(scale, (shift, -0.5 * shift, 0.25 * shift)), photons=6000, spp=4)
    assert ref.combined.mean() > 0
    for name in ("combined", "direct", "indirect"):
        err = relmse(getattr(film, name), getattr(ref, name))
        assert err < 2e-3, f"{name}: relMSE {err:.2e} vs the unscaled room"
    assert np.all(film.alpha == 1.0)


def _ortho_plane_with_point_light(shift, scale, res=24):
    s = PaperScene(width=res, height=res)
    s.add_material(Material("matte", (0.5,) * 3))
    c = np.array([shift, shift, shift], float)
    s.add_plane(c, (0, 0, 1), 8 * scale, "matte", name="plane")
    s.camera = Camera(position=c + (0, 0, 5 * scale), kind="ORTHO", ortho_scale=4 * scale)
    s.add_point_light(c + (0, 0, 2 * scale), power=100.0 * scale * scale)
    return s, c


@pytest.mark.parametrize("scale,shift", [(1.0, 0.0), (1e-3, 0.0), (1e3, 0.0), (1.0, 1e5),
                                         (1e-3, 1e5)])
def test_no_shadow_acne_on_a_lit_plane(scale, shift):
    """Every pixel of an unoccluded plane gets the analytic direct light: a self-hit of a
    shadow ray (acne) would black out pixels."""
    res = 24
    s, c = _ortho_plane_with_point_light(shift, scale, res)
    film = run(s, photon_mapping=False, spp=16)
    view = 4.0
    x = (np.arange(res) + 0.5) / res * view - view / 2
    X, Y = np.meshgrid(x, -x)
    d2 = X * X + Y * Y + 4.0
    expected = 0.5 / math.pi * 100.0 / (4 * math.pi) * (2.0 / np.sqrt(d2)) / d2
    ratio = film.direct[..., 0] / expected
    # Jitter inside the pixel moves single samples by a few %; a self-shadowed sample
    # would remove 1/16 of a pixel (6 %) or all of it.
    assert ratio.min() > 0.96 and ratio.max() < 1.04, (ratio.min(), ratio.max())
    assert abs(ratio.mean() - 1) < 0.005


@pytest.mark.parametrize("scale,shift,gap", [
    (1.0, 0.0, 0.5), (1e-3, 0.0, 0.5), (1e3, 0.0, 0.5), (1.0, 1e5, 0.5),
    # Ground coplanar with the room floor: final gather must not take the ground's light
    # under the walls (GatherMap's visibility test).
    (1.0, 0.0, 0.0),
], ids=["scale_1", "scale_1e-3", "scale_1e3", "translate_1e5", "coplanar_ground"])
def test_no_light_leaks_into_a_closed_box(scale, shift, gap):
    """Camera inside a closed box (shared corner vertices, zero-thickness walls), all light
    outside: walls, corners and photon estimates must stay black."""
    k = scale
    c = np.array([shift, 0.0, shift])
    s = PaperScene(width=24, height=24)
    s.add_material(Material("wall", (0.8,) * 3))
    v, f = box_mesh(c, 2.0 * k)
    s.add_triangles(v, f, "wall", name="closed_box")
    s.add_plane(c + (0, 0, -(1.0 + gap) * k), (0, 0, 1), 10 * k, "wall", name="ground_outside")
    s.add_point_light(c + (0.3 * k, 0.2 * k, 1.5 * k), power=1e4 * k * k)
    s.add_sun((0.3, 0.2, -1.0), strength=50.0)
    s.add_rect_area_light(c + (0, 0, 1.01 * k), (2.5 * k, 2.5 * k), power=1e4 * k * k,
                          direction=(0, 0, -1))  # lies on the lid, facing it
    # Corner view: looks into the corner where three walls meet.
    s.set_camera(c + (-0.5 * k, -0.5 * k, -0.5 * k), c + (0.9 * k, 0.9 * k, 0.9 * k),
                 (0, 0, 1), view_angle=100)
    film = run(s, photons=20000, spp=2)
    assert np.all(film.alpha == 1.0)
    assert film.combined.max() == 0.0, f"light leaked in: max {film.combined.max()}"


# ---------------------------------------------------------------- 2. grazing angles


def test_camera_at_89_9_degrees_to_a_plane():
    s = PaperScene(width=32, height=16)
    s.add_material(Material("matte", (0.5,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 2000.0, "matte", name="plane")
    s.add_sun((0, 0, -1), strength=3.0)
    elev = math.radians(0.1)
    s.set_camera((0, 0, 1.0), (0, math.cos(elev) * 100, 1.0 - math.sin(elev) * 100),
                 (0, 0, 1), view_angle=0.05)
    film = run(s, spp=2)
    lit = film.alpha == 1.0
    assert lit.mean() > 0.3
    direct = film.direct[..., 0][lit]
    expected = 0.5 * 3.0 / math.pi
    # No black (self-shadowed) pixels and no spikes at the grazing view.
    assert np.all(np.abs(direct / expected - 1) < 0.01), (direct.min(), direct.max())


@pytest.mark.parametrize("angle_deg", [89.0, 89.9])
def test_light_at_grazing_incidence(angle_deg):
    """A sun 89.9 deg off the normal: irradiance E cos(theta), not black, not a spike."""
    s = PaperScene(width=16, height=16)
    s.add_material(Material("matte", (0.5,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 10.0, "matte", name="plane")
    th = math.radians(angle_deg)
    s.add_sun((math.sin(th), 0, -math.cos(th)), strength=1000.0)
    s.camera = Camera(position=(0, 0, 3), kind="ORTHO", ortho_scale=4)
    film = run(s, spp=1)
    expected = 0.5 * 1000.0 * math.cos(th) / math.pi
    ratio = film.direct[..., 0] / expected
    assert ratio.min() > 0.99 and ratio.max() < 1.01


@pytest.mark.parametrize("segments", [6, 8, 12])
def test_smooth_low_poly_sphere_has_no_black_ring_or_spike(segments):
    """Shading normals of a coarse smooth sphere disagree strongly with the facets. Sun
    along the view direction: every visible point is lit, none brighter than rho E / pi."""
    s = PaperScene(width=32, height=32)
    s.add_material(Material("matte", (0.6,) * 3))
    s.add_sphere((0, 0, 0), 1.0, "matte", name="lowpoly", segments=segments)
    s.add_sun((0, 0, -1), strength=2.0)
    s.camera = Camera(position=(0, 0, 5), kind="ORTHO", ortho_scale=2.4)
    film = run(s, spp=4, photons=3000)
    hit = film.alpha == 1.0
    assert hit.sum() > 200
    d = film.direct[..., 0]
    assert np.all(d[hit] > 0), "black pixels on the lit side"
    peak = 0.6 * 2.0 / math.pi
    assert d.max() <= peak * 1.001
    assert film.combined.max() <= peak * 1.5


def test_shading_normals_pointing_below_the_surface():
    """Custom normals that point away from the viewer / into the surface fall back to
    the geometric normal: no black pixels, no NaN."""
    s = PaperScene(width=16, height=16)
    s.add_material(Material("matte", (0.5,) * 3))
    v = np.array([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    n = np.array([[0, 0, -1], [1, 0, 0.01], [0, 0, 0], [0.3, 0.3, -1]], float)  # bad normals
    s.add_triangles(v, f, "matte", name="bad_normals", normals=n)
    s.add_sun((0, 0, -1), strength=1.0)
    s.camera = Camera(position=(0, 0, 3), kind="ORTHO", ortho_scale=3)
    film = run(s, spp=2)
    assert np.all(film.direct[..., 0] <= 0.5 / math.pi * 1.001)
    assert film.direct.mean() > 0.3 * 0.5 / math.pi


# ---------------------------------------------------------------- 4. bad geometry


def _bad_geometry_scene(mesh):
    s = PaperScene(width=24, height=24)
    s.add_material(Material("matte", (0.6,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 6.0, "matte", name="floor")
    s.add_mesh(mesh)
    s.add_rect_area_light((0, 0, 3), (1, 1), power=200.0)
    s.set_camera((0, -5, 3), (0, 0, 0.5), view_angle=50)
    return s


def _quad(z=1.0, x0=-0.5):
    v = np.array([[x0, -0.5, z], [x0 + 1, -0.5, z], [x0 + 1, 0.5, z], [x0, 0.5, z]], float)
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def test_invalid_triangles_are_dropped_with_a_named_warning():
    v, f = _quad()
    nanv = np.array([[np.nan, 0, 1], [np.inf, 1, 1], [0, -np.inf, 1]])
    verts = np.concatenate([v, nanv, v[:1]])  # index 7 duplicates vertex 0
    faces = np.concatenate([f, [[4, 5, 6], [0, 1, 4], [0, 1, 99], [-1, 0, 1], [0, 0, 1],
                                [0, 7, 1], [0, 1, 1]]])
    mesh = Mesh("Broken.Teapot", verts, faces, materials=["matte"])
    clean = Mesh("Clean.Teapot", v, f, materials=["matte"])
    text = " ".join(mesh.warnings)
    assert "Broken.Teapot" in text
    for word in ("NaN", "outside", "zero-area"):
        assert word in text, text
    assert len(mesh.faces) == 2
    a = run(_bad_geometry_scene(mesh))
    b = run(_bad_geometry_scene(clean))
    assert any("Broken.Teapot" in w for w in a.warnings)
    np.testing.assert_allclose(a.combined, b.combined, rtol=1e-5, atol=1e-7)


def test_mesh_with_only_invalid_faces_leaves_the_rest_rendering():
    v = np.array([[np.nan, 0, 0], [0, 0, 0], [1, 1, 1]])
    mesh = Mesh("AllBad", v, [[0, 1, 2], [1, 1, 2], [0, 5, 2]], materials=["matte"])
    assert len(mesh.faces) == 0
    film = run(_bad_geometry_scene(mesh))
    assert any("AllBad" in w for w in film.warnings)
    assert film.direct.mean() > 0


def test_sliver_triangles_do_not_produce_nan():
    """Near-degenerate (1e-9 thin) triangles that survive validation: normals stay unit."""
    v = np.array([[-1, 0, 0.5], [1, 0, 0.5], [0, 1e-9, 0.5], [0, -1e-9, 0.5]], float)
    mesh = Mesh("Sliver", v, [[0, 1, 2], [1, 0, 3]], materials=["matte"])
    run(_bad_geometry_scene(mesh))


def test_duplicate_vertices_render_like_a_welded_mesh():
    v, f = _quad()
    dup = np.concatenate([v, v])
    f2 = np.array([[0, 1, 6], [4, 2, 3]])  # same triangles through duplicated vertices
    a = run(_bad_geometry_scene(Mesh("Dup", dup, f2, materials=["matte"])))
    b = run(_bad_geometry_scene(Mesh("Dup", v, f, materials=["matte"])))
    np.testing.assert_allclose(a.combined, b.combined, rtol=1e-5, atol=1e-7)


def test_inside_out_mesh_renders_like_the_right_way_round():
    v, f = box_mesh((0, 0, 0.6), 1.0)
    a = run(_bad_geometry_scene(Mesh("InsideOut", v, f[:, ::-1], materials=["matte"])))
    b = run(_bad_geometry_scene(Mesh("InsideOut", v, f, materials=["matte"])))
    assert relmse(a.combined, b.combined) < 1e-6


def test_non_manifold_and_coplanar_overlaps_render():
    """Three faces on one edge (non-manifold) and two coincident quads (z-fighting, same
    material): finite and the overlap looks like one quad."""
    v, f = _quad(z=1.0)
    fin = np.array([[-0.5, -0.5, 1.0], [0.5, -0.5, 1.0], [0.0, -0.5, 2.0], [0.0, -1.2, 1.0]])
    verts = np.concatenate([v, fin])
    nm = np.concatenate([f, [[4, 5, 6], [4, 5, 7]]])  # edge 0-1 shared by 3 faces
    run(_bad_geometry_scene(Mesh("NonManifold", verts, nm, materials=["matte"])))
    doubled = Mesh("Doubled", np.concatenate([v, v]), np.concatenate([f, f + 4, f[:, ::-1]]),
                   materials=["matte"])
    single = Mesh("Doubled", v, f, materials=["matte"])
    a = run(_bad_geometry_scene(doubled))
    b = run(_bad_geometry_scene(single))
    assert relmse(a.combined, b.combined) < 1e-3
