"""Cycles' Light Group passes in the engine (engine/lightgroups.py): each group's pass is
the render of its emitters alone (lamps, emissive meshes, the world), the groups sum to
Combined, an ungrouped emitter is in no pass, a group without emitters is black, the
image keeps its bits. Live Cycles: tests/blender/test_light_groups_cycles.py."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.lightgroups import group_scene, key, members
from engine.render import render
from engine.scene import Material, Mesh

W, H = 16, 12


def _quad(z, half):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]],
                 float)
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def _scene():
    """A floor lit by two point lamps (groups a and b), an emissive panel above it in
    view (group b; its material shared with an ungrouped panel out of view) and a grey
    world (group w)."""
    s = PaperScene(W, H, background=(0.3, 0.3, 0.3))
    s.add_material(Material("m", (0.5, 0.5, 0.5)))
    s.add_material(Material("glow", (0.5, 0.5, 0.5), emission=(4.0, 2.0, 1.0)))
    v, f = _quad(0.0, 3.0)
    s.add_mesh(Mesh("floor", v, f, materials=["m"]))
    v, f = _quad(0.6, 0.3)
    s.add_mesh(Mesh("panel", v, f, materials=["glow"], lightgroup="b"))
    v, f = _quad(0.6, 0.3)
    s.add_mesh(Mesh("stray", v + [0.0, 9.0, 5.0], f, materials=["glow"]))
    s.add_point_light((1.0, 0.0, 1.5), power=100.0)
    s.add_point_light((-1.0, 0.5, 1.5), power=60.0)
    s.lights[0].lightgroup, s.lights[1].lightgroup = "a", "b"
    s.world_lightgroup = "w"
    s.set_camera((0.0, -3.0, 3.0), (0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), view_angle=60)
    return s


def _settings(**kw):
    return RenderSettings(workers=1, spp=8, seed=3, photons=20_000, caustic_photons=2_000,
                          **kw)


def test_group_scene_keeps_the_groups_emitters():
    s = _scene()
    assert members(s, "a") == 1 and members(s, "b") == 2 and members(s, "w") == 1
    assert members(s, "nobody") == 0
    a = group_scene(s, "a")
    assert [li.lightgroup for li in a.lights] == ["a"]
    assert np.all(a.background == 0.0)
    dark = {m.name: a.materials[m.materials[0]] for m in a.meshes}
    assert not dark["panel"].is_emissive and not dark["stray"].is_emissive
    b = group_scene(s, "b")
    kept = {m.name: b.materials[m.materials[0]] for m in b.meshes}
    assert kept["panel"].is_emissive and not kept["stray"].is_emissive
    assert s.materials["glow"].is_emissive and len(s.lights) == 2  # (s untouched)
    assert np.all(np.asarray(group_scene(s, "w").background) == 0.3)


def test_groups_sum_to_combined_and_match_their_emitters_alone():
    s = _scene()
    film = render(s, _settings(light_groups=("a", "b", "w", "empty")))
    total = sum(film.data[key(g)] for g in "abw")
    assert abs(total.mean() / film.combined.mean() - 1.0) < 0.01
    assert np.all(film.data[key("empty")] == 0.0)
    # Group a's pass is the render of lamp a alone (the same settings and seed).
    alone = render(group_scene(s, "a"), _settings())
    assert np.array_equal(film.data[key("a")], alone.combined)
    # The world's group holds the background seen directly (the image's corners).
    assert np.allclose(film.data[key("w")][0, 0], 0.3, atol=1e-6)
    assert np.all(film.data[key("a")][0, 0] == 0.0)


def test_ungrouped_emitter_is_in_no_pass():
    s = _scene()
    s.lights[1].lightgroup = ""  # lamp b ungrouped: in no group's pass
    film = render(s, _settings(light_groups=("a", "b", "w")))
    total = sum(film.data[key(g)] for g in "abw")
    assert total.mean() < 0.95 * film.combined.mean()


def test_light_groups_leave_the_image_bits():
    s = _scene()
    a = render(s, _settings())
    b = render(s, _settings(light_groups=("a", "w")))
    for name in ("direct", "indirect", "caustic", "specular", "emission"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_light_groups_setting():
    assert RenderSettings(light_groups="key").light_groups == ("key",)
    assert RenderSettings(light_groups=("a", "b", "a")).light_groups == ("a", "b")
    for bad in (("",), (3,)):
        with pytest.raises(ValueError, match="light_groups"):
            RenderSettings(light_groups=bad)


SCENE_FILE = """
background = [0.2, 0.2, 0.2]
world_lightgroup = "sky"

[render]
width = 12
height = 9
spp = 2
photons = 3000
caustic_photons = 300

[camera]
position = [0, -4, 3]
look_at = [0, 0, 0]
up = [0, 0, 1]
fov = 50

[materials.grey]
base_color = [0.5, 0.5, 0.5]

[[objects]]
type = "plane"
name = "floor"
center = [0, 0, 0]
normal = [0, 0, 1]
size = 6
material = "grey"

[[lights]]
type = "point"
name = "lamp"
position = [0, 0, 2]
power = 200
lightgroup = "key"
"""


def test_scene_file_and_cli_write_light_groups(tmp_path):
    """The scene file's lightgroup / world_lightgroup and `photonmap render --light-groups
    key,sky --save-passes` write each group's pass as name.lightgroup_NAME.exr, summing to
    the image."""
    from engine.cli import main
    from engine.imageio import read_image
    path = tmp_path / "lg.toml"
    path.write_text(SCENE_FILE)
    out = tmp_path / "lg.exr"
    assert main(["render", str(path), "-o", str(out), "--light-groups", "key,sky",
                 "--save-passes", "--quiet"]) == 0
    key_pass = read_image(str(tmp_path / "lg.lightgroup_key.exr"))
    sky_pass = read_image(str(tmp_path / "lg.lightgroup_sky.exr"))
    image = read_image(str(out))[..., :3]
    assert key_pass.shape == sky_pass.shape == (9, 12, 3)
    assert key_pass.mean() > 0.05 and np.allclose(sky_pass[0, 0], 0.2, atol=1e-3)
    total = key_pass + sky_pass
    assert abs(total.mean() / image.mean() - 1.0) < 0.1


def test_memory_estimate_counts_the_group_render():
    """engine/resources.py counts a light group's render (its scene and photon maps, one
    group at a time beside the main render's) and the groups' passes."""
    from engine.resources import estimate_memory
    s = _scene()
    plain = estimate_memory(s, _settings())
    grouped = estimate_memory(s, _settings(light_groups=("a", "b")))
    assert "light group render" not in plain.parts
    assert grouped.parts["light group render"] >= plain.parts["photon maps"]
    assert grouped.parts["data passes"] == W * H * 6 * 12  # (3 channels a group)


def test_progressive_passes_average_the_groups():
    """Progressive passes render each group every pass (their scenes built once) and
    average its pass as the image's: the groups still sum to Combined."""
    from engine import Budget, render_progressive
    film = render_progressive(_scene(), _settings(light_groups=("a", "b", "w")),
                              Budget(passes=2))
    assert film.stats["passes"] == 2
    total = sum(film.data[key(g)] for g in "abw")
    assert abs(total.mean() / film.combined.mean() - 1.0) < 0.01


def test_world_volume_glow_is_the_worlds():
    """An emitting World > Volume glows in the world's group only."""
    from engine.scene import WorldMedium
    s = _scene()
    s.world_medium = WorldMedium(absorption=(0.01, 0.01, 0.01), emission=(0.02, 0.02, 0.02))
    assert np.all(np.asarray(group_scene(s, "a").world_medium.emission) == 0.0)
    assert np.all(np.asarray(group_scene(s, "w").world_medium.emission) == 0.02)


def test_light_groups_are_reported_and_get_their_span_of_the_bar():
    """The effect report says what the groups cost (newuser41b: four groups took 5.5x
    the time, unexplained) and names an empty group; the render tells its plan, and the
    bar's last groups / (groups + 1) is theirs (it sat at 100 % through them)."""
    from engine.stagespans import StageSpans, stage_spans
    s = _scene()
    spans = StageSpans(True, 22_000, W * H * 8)
    plans, marks = [], []

    def on_plan(work):
        plans.append(dict(work))
        spans.plan(work)

    film = render(s, _settings(light_groups=("a", "b", "empty")), on_plan=on_plan,
                  progress=lambda stage, fraction, text: marks.append(
                      (stage, spans.whole(stage, fraction))))
    line = next(x for x in film.stats["effects"] if x.startswith("light groups"))
    assert "2 Light Group passes ('a', 'b')" in line and "3 times as long" in line, line
    assert "'empty': no lamp, emissive object or world in it, black" in line, line
    assert {"light_groups": 2} in plans
    assert spans.spans["light groups"] == pytest.approx((1 / 3, 2 / 3))
    seen = [w for stage, w in marks if stage == "light groups" and w is not None]
    assert seen and min(seen) >= 1 / 3 - 1e-9 and seen[-1] == pytest.approx(1.0)
    render_end = [w for stage, w in marks if stage == "render" and w is not None]
    assert max(render_end) <= 1 / 3 + 1e-9
    # With a catcher pass too: main render, catcher pass, then the groups.
    both = stage_spans(True, 1000, 1000, 0.0, catcher=True, groups=1)
    assert both["light groups"] == pytest.approx((0.5, 0.5))
    assert sum(both["shadow catcher"]) == pytest.approx(0.5)


def test_a_shadow_catcher_is_black_in_the_group_renders():
    """Cycles leaves a shadow catcher black in its group passes (newuser41b): a holdout
    in the groups' scenes, the main render's catcher untouched."""
    s = _scene()
    floor = next(m for m in s.meshes if m.name == "floor")
    floor.shadow_catcher = True
    g = group_scene(s, "a")
    caught = next(m for m in g.meshes if m.name == "floor")
    assert caught.holdout and not caught.shadow_catcher
    assert floor.shadow_catcher and not floor.holdout
