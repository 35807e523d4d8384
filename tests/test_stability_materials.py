"""Stability groups 3 (glass traps) and 7 (materials). See docs/stability.md."""
import math

import numpy as np
import pytest

from engine.api import PaperScene
from engine.bsdf import fresnel_dielectric, lobe_weights, refract, SurfaceHit
from engine.geometry import MaterialTable
from engine.scene import Material

from test_stability_common import relmse, run, shoot_photons

# ---------------------------------------------------------------- 3. glass traps


def _floor_scene(res=24):
    s = PaperScene(width=res, height=res)
    s.add_material(Material("matte", (0.7,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "matte", name="floor")
    s.set_camera((0, -5, 4), (0, 0, 0.8), view_angle=45)
    return s


def test_light_inside_a_closed_glass_sphere():
    """Shadow rays are blocked by the glass; light escapes only as caustic photons. Paths
    bouncing inside the sphere end (depth limit, roulette); the floor gets the caustic."""
    s = _floor_scene()
    s.add_sphere((0, 0, 1.2), 0.6, "glass", name="glass_ball")
    s.add_point_light((0, 0, 1.2), power=500.0, name="trapped")
    film = run(s, photons=4000, caustic_photons=4000, max_photon_depth=12, max_depth=12)
    assert film.direct.max() == 0.0  # the glass blocks shadow rays (documented)
    assert film.caustic.mean() > 0, "no light escaped the glass sphere"
    ph, _ = shoot_photons(s, photons=4000, max_photon_depth=12)
    assert ph.power.astype(np.float64).sum(axis=0).max() <= 500.0 * 1.01 / (1 - 0.7)


def test_nested_glass_spheres():
    s = _floor_scene()
    s.add_material(Material("glass2", (1, 1, 1), transmission=1.0, ior=1.9))
    s.add_material(Material("water", (1, 1, 1), transmission=1.0, ior=1.33))
    s.add_sphere((0, 0, 1.2), 0.9, "glass", name="outer")
    s.add_sphere((0, 0, 1.2), 0.6, "glass2", name="middle")
    s.add_sphere((0, 0, 1.2), 0.3, "water", name="inner")
    s.add_rect_area_light((0, 0, 4), (1, 1), power=300.0)
    film = run(s, max_depth=16, max_photon_depth=16)
    assert film.specular.mean() > 0  # we see the floor through three shells of glass
    assert film.caustic.max() > 0


def test_total_internal_reflection_in_a_prism():
    """A 45-45-90 prism (IOR 1.5, critical angle 41.8 deg): light entering a short face
    meets the hypotenuse at 45 deg and must be totally reflected (Fresnel = 1)."""
    cos45 = math.cos(math.radians(45))
    assert fresnel_dielectric(np.array([cos45]), np.array([1 / 1.5]))[0] == 1.0
    d = np.array([[math.sin(math.radians(45)), 0.0, -cos45]])
    _, tir = refract(d, np.array([[0.0, 0.0, 1.0]]), np.array([1.5]))
    assert tir[0]
    # Render a prism: paths inside end, image finite.
    s = _floor_scene()
    v = np.array([[-1, -1, 0.01], [1, -1, 0.01], [-1, -1, 2.01], [-1, 1, 0.01], [1, 1, 0.01],
                  [-1, 1, 2.01]], float)
    f = np.array([[0, 1, 2], [3, 5, 4], [0, 3, 4], [0, 4, 1], [0, 2, 5], [0, 5, 3],
                  [1, 4, 5], [1, 5, 2]])
    s.add_triangles(v, f, "glass", name="prism")
    s.add_sun((0.3, 0.1, -1), strength=5.0)
    film = run(s, max_depth=20, max_photon_depth=20)
    assert film.caustic.max() > 0


def _wall_behind_sphere(material):
    s = PaperScene(width=24, height=24)
    s.add_material(Material("matte", (0.6, 0.5, 0.4)))
    s.add_plane((0, 5, 1), (0, -1, 0), 4.0, "matte", name="wall")
    if material is not None:
        s.add_material(material)
        s.add_sphere((0, 2, 1), 0.6, material.name, name="ball")
    # Sun shadow of the ball falls below the part of the wall in view.
    s.add_sun((0, 0.6, -0.8), strength=2.0)
    s.set_camera((0, -2, 1), (0, 5, 1), view_angle=25)
    return s


def test_glass_with_ior_1_renders_as_if_absent():
    clear = Material("clear", (1, 1, 1), transmission=1.0, ior=1.0)
    with_ball = run(_wall_behind_sphere(clear), photon_mapping=False, spp=4)
    without = run(_wall_behind_sphere(None), photon_mapping=False, spp=4)
    assert without.combined.mean() > 0
    assert relmse(with_ball.combined, without.combined) < 1e-4


@pytest.mark.parametrize("ior", [1e-3, 0.5, 1.0001, 3.0, 100.0, 1e4])
def test_extreme_ior_stays_finite_and_bounded(ior):
    s = _floor_scene()
    s.add_material(Material("weird", (1, 1, 1), transmission=1.0, ior=ior))
    s.add_sphere((0, 0, 1.0), 0.8, "weird", name="ball", segments=16)
    s.add_point_light((0.5, -0.5, 3.0), power=200.0)
    run(s, max_depth=10, max_photon_depth=10)
    ph, _ = shoot_photons(s, photons=3000, max_photon_depth=30)
    # Photons never gain power: stored <= emitted / (1 - albedo of the floor).
    assert ph.power.astype(np.float64).sum(axis=0).max() <= 200.0 / (1 - 0.7) * 1.01


def test_path_depth_limits_end_every_path_in_a_mirror_box():
    """Two parallel perfect mirrors: camera and photon paths bounce until max depth."""
    s = _floor_scene()
    s.add_material(Material("perfect_mirror", (1, 1, 1), metallic=1.0))
    s.add_plane((0, -1.5, 1), (0, 1, 0), 6.0, "perfect_mirror", name="m1")
    s.add_plane((0, 1.5, 1), (0, -1, 0), 6.0, "perfect_mirror", name="m2")
    s.add_point_light((0, 0, 2), power=100.0)
    s.set_camera((0, -1.4, 1), (0, 1.5, 0.9), view_angle=30)
    film = run(s, max_depth=64, max_photon_depth=64)
    assert film.specular.mean() > 0


# ---------------------------------------------------------------- 7. materials


def test_albedo_zero_reflects_nothing():
    s = _floor_scene()
    s.materials["matte"] = Material("matte", (0, 0, 0))
    s.add_point_light((0, 0, 2), power=100.0)
    film = run(s)
    assert film.combined.max() == 0.0


def test_albedo_above_one_is_kept_and_stays_finite():
    """A base colour above 1 is kept (as Cycles keeps it) with a note; a closed room of it
    gains energy at every bounce, yet renders and traces photons without inf / NaN (Russian
    roulette survives with probability 1 and the photon power carries the factor)."""
    hot = Material("Hot", (3.0, 1.5, 0.5))
    assert "Hot" in " ".join(hot.warnings) and hot.base_color.max() == 3.0
    s = PaperScene(width=16, height=16)
    s.add_material(hot)
    v, f = __import__("engine.api", fromlist=["box_mesh"]).box_mesh((0, 0, 1), 2.0)
    s.add_triangles(v, f, "Hot", name="room")
    s.add_point_light((0.1, 0.2, 1.1), power=50.0)
    s.set_camera((0, -0.9, 1), (0, 0, 1), view_angle=90)
    film = run(s)
    assert any("Hot" in w and "above 1" in w for w in film.warnings)
    assert np.all(np.isfinite(film.combined))
    ph, _ = shoot_photons(s, photons=3000, max_photon_depth=64)
    tot = ph.power.astype(np.float64).sum(axis=0)
    assert np.all(np.isfinite(tot)) and np.all(ph.power >= 0)
    # Red (3) gains, blue (0.5) loses at each bounce: stored red power far above blue.
    assert tot[0] > 10 * tot[2]


@pytest.mark.parametrize("roughness", [0.0, 1.0])
@pytest.mark.parametrize("kind", ["metal", "glass", "plastic"])
def test_roughness_extremes(roughness, kind):
    s = _floor_scene()
    m = {"metal": Material("m", (0.9, 0.8, 0.7), metallic=1.0, roughness=roughness),
         "glass": Material("m", (1, 1, 1), transmission=1.0, roughness=roughness),
         "plastic": Material("m", (0.5, 0.1, 0.1), specular=1.0, roughness=roughness)}[kind]
    s.add_material(m)
    s.add_sphere((0, 0, 1), 0.8, "m", name="ball", segments=16)
    s.add_rect_area_light((1, -1, 3), (1, 1), power=300.0)
    film = run(s)
    assert film.combined.mean() > 0


def test_metallic_and_transmission_together():
    s = _floor_scene()
    s.add_material(Material("both", (0.9, 0.9, 0.9), metallic=1.0, transmission=1.0,
                            roughness=0.3, specular=1.0, alpha=0.7))
    s.add_sphere((0, 0, 1), 0.8, "both", name="ball", segments=16)
    s.add_point_light((1, -1, 3), power=300.0)
    run(s)


def test_lobe_weights_never_exceed_one():
    """For any mix of metallic / transmission / specular / alpha / IOR and any angle, the
    lobes sum to at most 1 per channel (no energy created)."""
    rng = np.random.default_rng(3)
    mats = [Material(f"m{i}", rng.random(3) * 1.0, metallic=rng.choice([0, 1, rng.random()]),
                     roughness=rng.random(), transmission=rng.choice([0, 1, rng.random()]),
                     ior=float(rng.choice([1e-3, 0.5, 1.0, 1.5, 1e3])),
                     specular=rng.choice([0, 1, rng.random()]),
                     alpha=rng.choice([0, 1, rng.random()])) for i in range(60)]
    table = MaterialTable.build(mats)
    n = 20000
    mat = rng.integers(0, len(mats), n)
    ns = np.tile([0.0, 0.0, 1.0], (n, 1))
    cos = rng.random(n) ** 3
    wo = np.stack([np.sqrt(1 - cos ** 2), np.zeros(n), cos], axis=1)
    hit = SurfaceHit(p=np.zeros((n, 3)), ng=ns, ns=ns, wo=wo, front=rng.random(n) < 0.5,
                     mat=mat, base=table.base_color[mat], prim=np.zeros(n, int))
    w = lobe_weights(table, hit)
    total = sum(w.values())
    assert np.all(np.isfinite(total))
    assert total.max() <= 1.0 + 1e-9
    assert min(v.min() for v in w.values()) >= 0.0


def test_buffers_asked_for_no_rows_first():
    """A gather level (or a chunk's bounce, or a light sample) can have no rows at all: the
    per-thread buffers' first call then asks for 0 rows. Their arrays were made only for
    n > size = 0, so gather_indirect on no hits raised AttributeError ('GatherBuffers'
    object has no attribute 'idx'; seen in a 16x12 render with 2 workers of a rough
    metal floor under an area light, a sun, a wall and a glass slab)."""
    from engine.directlight import DirectLightBuffers
    from engine.integrator import BounceBuffers, GatherBuffers
    idx, o, d, tp = GatherBuffers().rays(0)
    assert len(idx) == len(o) == len(d) == len(tp) == 0
    assert all(len(a) == 0 for a in BounceBuffers().take(0))
    b = DirectLightBuffers()
    b.ensure(0)
    assert b.contrib.shape == (0, 3)
