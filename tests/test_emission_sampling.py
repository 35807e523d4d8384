"""A material's Emission Sampling (Blender's material.emission_sampling, Cycles'
EmissionSampling) changes which sides of an emissive mesh shadow rays sample, never how
bright the scene is: the sides left out arrive through the rays that meet them (gather
rays, glossy continuations), counted in full (scene.emission_sides, MeshLight.sides,
integrator.unsampled_emission).

A closed white room lit by a panel whose front faces the floor and whose back lights the
ceiling: each mode as bright as Front and Back (both sides sampled). A 1 m panel over an
open floor (no gather map: a flat floor cannot light itself) checks the rest against
Lambert's closed form: there shadow rays sample every side whatever the mode (nothing
else would bring the other side's light), and with gathering the shadow-ray kernel
refuses an unsampled side.
"""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.scene import EMISSION_SAMPLING, Camera, Material, Mesh, SceneError, emission_sides
from helpers import pixel_to_world, top_down_plane
from test_ray_offsets import _lambert_polygon

L = 10.0
H = 1.0
VIEW = 4.0
RES = 24
ALBEDO = 0.5
CORNERS = np.array([[-0.5, -0.5, H], [0.5, -0.5, H], [0.5, 0.5, H], [-0.5, 0.5, H]])


def _scene(mode, facing_down=True, emission=L):
    s = top_down_plane(ALBEDO, res=RES, view=VIEW)
    s.add_material(Material("lamp", (0.0, 0.0, 0.0), emission=(emission,) * 3,
                            emission_sampling=mode))
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    if facing_down:  # winding normal -z: the front faces the floor
        faces = faces[:, ::-1]
    s.add_mesh(Mesh("panel", CORNERS.copy(), faces, materials=["lamp"]))
    return s


def _expected(s):
    x, y = pixel_to_world(s, VIEW)
    E = np.array([[_lambert_polygon(np.array([a, b, 0.0]), np.array([0.0, 0.0, 1.0]),
                                    CORNERS) for a, b in zip(ra, rb)] for ra, rb in zip(x, y)])
    floor = (np.abs(x) > 0.6) | (np.abs(y) > 0.6)  # pixels that see the floor
    return ALBEDO * L * E / math.pi, floor


def _room(mode, glossy=False, size=4.0, height=3.0, panel=1.6):
    """A closed white room (size x size x height, Lambert 0.7; glossy: Principled grey
    0.5 of roughness 0.25) lit only by a black-based panel of radiance L, 0.5 m under the
    ceiling, its front facing the floor: the back lights the ceiling above it. The camera
    looks from a corner at the panel's side."""
    s = PaperScene(width=24, height=18)
    s.add_material(Material("white", (0.5,) * 3, specular=1.0, roughness=0.25) if glossy
                   else Material("white", (0.7, 0.7, 0.7)))
    s.add_material(Material("lamp", (0.0, 0.0, 0.0), emission=(L,) * 3,
                            emission_sampling=mode))
    h = size / 2
    for c, n in (((0, 0, 0), (0, 0, 1)), ((0, 0, height), (0, 0, -1)),
                 ((-h, 0, height / 2), (1, 0, 0)), ((h, 0, height / 2), (-1, 0, 0)),
                 ((0, -h, height / 2), (0, 1, 0)), ((0, h, height / 2), (0, -1, 0))):
        s.add_plane(c, n, (size, height) if n[2] == 0 else size, "white",
                    up=(0, 0, 1) if n[2] == 0 else None)
    s.add_plane((0, 0, height - 0.5), (0, 0, -1), panel, "lamp", name="panel")
    s.camera = Camera.look_at((-1.6, -1.6, 1.2), (0.3, 0.3, 2.2), fov_degrees=75.0)
    return s


SETTINGS = dict(spp=32, gather_rays=8, photons=40_000, caustic_photons=0)


@pytest.mark.parametrize("glossy", [False, True], ids=["lambert", "glossy"])
def test_every_mode_is_as_bright_as_front_and_back(glossy):
    """The room under each of the five modes against Front and Back (shadow rays to both
    sides, as before the setting was read): the light the panel sends to the room (the
    image without the panel seen directly) and its top third (the ceiling lit by the
    panel's back) within 2 % over two seeds. Front: the ceiling's direct light by
    gather rays alone (glossy: and by the specular layer's continuations, MIS weight 1);
    Back: the floor's and walls'; None: all of it. Measured: within 0.16 % (Lambert and
    glossy alike, docs/accuracy.md emissamp)."""
    means = {}
    for mode in EMISSION_SAMPLING:
        vals = []
        for seed in (1, 2):
            film = _room(mode, glossy).render(RenderSettings(seed=seed, **SETTINGS))
            # Without the panel seen directly (the Emission pass, the same in every mode):
            # the light it sends to the room.
            img = (film.combined[..., :3].astype(np.float64)
                   - film.emission[..., :3]).mean(axis=2)
            vals.append((img.mean(), img[: img.shape[0] // 3].mean()))
        means[mode] = np.mean(vals, axis=0)
    ref = means["FRONT_BACK"]
    for mode, m in means.items():
        r = m / ref
        print(f"{mode:10s} image {r[0]:.4f} top third {r[1]:.4f} x Front and Back")
        assert np.all(np.abs(r - 1.0) < 0.02), (mode, r)


def test_without_final_gathering_every_side_is_sampled():
    """No final gathering (photon mapping off): nothing else would bring an unsampled
    side's direct light to the floor, so shadow rays sample both sides in every mode
    (prepare_lights' gathered): the floor within 1 % of the closed form by shadow rays
    alone, whichever side faces it."""
    for mode, down in (("FRONT_BACK", True), ("AUTO", True), ("FRONT", False),
                       ("BACK", True), ("NONE", True)):
        s = _scene(mode, down)
        film = s.render(RenderSettings(spp=16, photon_mapping=False, max_depth=0))
        ref, floor = _expected(s)
        ratio = film.combined[..., 1][floor] / ref[floor]
        assert abs(float(ratio.mean()) - 1.0) < 0.01, (mode, down, ratio.mean())


def test_unsampled_side_takes_no_shadow_ray():
    """With final gathering, shadow rays from the floor to a panel whose sampled side
    faces away (or None) find no light: the kernel refuses the other side."""
    from engine.integrator import Counters, direct_irradiance
    from engine.render import prepare_context
    from test_ray_offsets import _floor_hits
    for mode, down, lit in (("FRONT", False, False), ("BACK", True, False),
                            ("NONE", True, False), ("FRONT", True, True),
                            ("BACK", False, True)):
        ctx = prepare_context(_scene(mode, down), RenderSettings(spp=1))
        hit = _floor_hits(ctx, np.array([0.8]), np.array([0.3]), 2000)
        E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
        ref = L * _lambert_polygon(np.array([0.8, 0.3, 0.0]), np.array([0.0, 0.0, 1.0]),
                                   CORNERS)
        if lit:
            assert abs(float(E[:, 1].mean()) / ref - 1.0) < 0.03, (mode, down, E[:, 1].mean())
        else:
            assert float(np.abs(E).max()) == 0.0, (mode, down)
        ctx.accel.close()


def test_emission_sides_follow_cycles():
    """AUTO as Cycles' Shader::estimate_emission: both sides above 0.5 W/m^2/sr in some
    channel, none at or below; black emission is never sampled; unknown names refused."""
    assert emission_sides("AUTO", (0.6, 0.0, 0.0)) == 3
    assert emission_sides("AUTO", (0.5, 0.5, 0.5)) == 0
    assert emission_sides("FRONT", (0.1, 0.1, 0.1)) == 1
    assert emission_sides("BACK", (2.0, 2.0, 2.0)) == 2
    assert emission_sides("FRONT_BACK", (0.0, 0.0, 0.0)) == 0
    assert emission_sides("NONE", (9.0, 9.0, 9.0)) == 0
    assert Material("m", emission_sampling="front").emission_sampling == "FRONT"
    with pytest.raises(SceneError, match="material 'm' emission_sampling"):
        Material("m", emission_sampling="SIDEWAYS")


def test_scene_files_carry_emission_sampling(tmp_path):
    """[materials.NAME] emission_sampling, any case, reaches Material; a wrong word is
    refused naming the key."""
    from engine.scenefile import SceneFileError, load_scene
    head = ('[camera]\nposition = [0, -5, 1]\nlook_at = [0, 0, 1]\n'
            '[materials.lamp]\nemission = [5, 5, 5]\n')
    path = tmp_path / "scene.toml"
    path.write_text(head + 'emission_sampling = "front"\n')
    scene, _ = load_scene(str(path))
    assert scene.materials["lamp"].emission_sampling == "FRONT"
    path.write_text(head + 'emission_sampling = "sideways"\n')
    with pytest.raises(SceneFileError, match="emission_sampling"):
        load_scene(str(path))
