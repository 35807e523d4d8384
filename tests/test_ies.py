"""IES light profiles (engine/ies.py): the LM-63 parser as Cycles' IESFile, its
interpolation, a floor lit by an IES point / spot against I f(w) cos / r^2, the photons'
emitted distribution against the profile, a broken file warned and the plain light
rendered."""
import math

import numpy as np
import pytest

from engine import ies
from engine.api import PaperScene
from engine.geometry import prepare
from engine.lights import prepare_lights
from engine.scene import Light, Material
from engine.settings import RenderSettings
from helpers import top_down_plane

K = ies.CANDELA_TO_CYCLES

# Type C, one quadrant (h 0 .. 90), v 0 .. 90: mirrored to the whole circle by Cycles.
QUADRANT = """IESNA:LM-63-2002
[TEST] quadrant
TILT=NONE
1 1000 2.0 4 2 1 2 0 0 0
0.5 1.0 100
0 30 60 90
0 90
1000 800 400 0
1000 600 200 0
"""

# Type C, the whole circle: a forward throw towards h = 90 degrees (the lamp's local -X,
# svm_node_ies: h = atan2(x, y) + pi) and a batwing (peak at v = 40), over v 0 .. 180.
FORWARD = """IESNA:LM-63-2002
[TEST] forward throw, batwing
TILT=NONE
1 -1 1.0 7 5 1 2 0.3 0.3 0.1
1.0 1.0 60
0 20 40 60 80 90 180
0 90 180 270 360
400 500 600 300 100 0 0
400 700 1200 900 300 0 0
400 500 600 300 100 0 0
400 300 200 100 50 0 0
400 500 600 300 100 0 0
"""


def _write(tmp_path, text, name="test.ies"):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


# ---------------------------------------------------------------------- parser
def test_quadrant_is_mirrored_and_scaled_as_cycles():
    p = ies.parse(QUADRANT, "q")
    np.testing.assert_allclose(np.degrees(p.h_angles), [0, 90, 180, 270, 360])
    np.testing.assert_allclose(np.degrees(p.v_angles), [0, 30, 60, 90])
    factor = 2.0 * 0.5 * 1.0 * K  # candela multiplier x ballast x ballast-lamp x 4pi/177.83
    want = factor * np.array([[1000, 800, 400, 0], [1000, 600, 200, 0],
                              [1000, 800, 400, 0], [1000, 600, 200, 0], [1000, 800, 400, 0]])
    np.testing.assert_allclose(p.intensity, want)


def test_interpolation_at_the_nodes_and_between():
    """At table nodes f is the table value (the cubic passes through them); between two
    nodes of equal value with flat neighbours, that value; above the last vertical angle 0;
    the direction convention svm_node_ies: v = acos(-z), h = atan2(x, y) + pi."""
    p = ies.parse(FORWARD, "f")
    f = lambda h, v: p.evaluate(ies.direction_from_angles(np.radians(h), np.radians(v)))[0]
    assert f(0.0, 0.0) == pytest.approx(400 * K)
    assert f(90.0, 40.0) == pytest.approx(1200 * K)
    assert f(270.0, 20.0) == pytest.approx(300 * K)
    assert f(45.0, 40.0) > 600 * K and f(45.0, 40.0) < 1200 * K
    assert f(90.0, 120.0) == 0.0
    # h = 90 degrees is the lamp's -X: atan2(-1, 0) + pi = pi / 2.
    down_x = p.evaluate([[-math.sin(0.7), 0.0, -math.cos(0.7)]])[0]
    assert down_x == pytest.approx(f(90.0, math.degrees(0.7)))


@pytest.mark.parametrize("text, words", [
    ("no tilt line\n1 2 3\n", "TILT"),
    (QUADRANT.replace("1000 600 200 0\n", "1000 600\n"), "ends before the candela"),
    (QUADRANT.replace("0 30 60 90", "0 30 sixty 90"), "'sixty' is not a number"),
    (QUADRANT.replace("1 1000 2.0 4 2 1 2", "1 1000 2.0 4 2 4 2"), "type 4 is unknown"),
    (QUADRANT.replace("0 30 60 90", "0 60 30 90"), "do not increase"),
    (QUADRANT.replace("1 1000 2.0 4 2", "1 1000 2.0 1 2"), "1 vertical"),
    ("", "TILT"),
])
def test_malformed_profiles_raise_clear_errors(text, words):
    with pytest.raises(ies.IESError, match=words):
        ies.parse(text, "bad.ies")


def test_missing_file_names_it(tmp_path):
    with pytest.raises(ies.IESError, match="nowhere.ies"):
        ies.load(str(tmp_path / "nowhere.ies"))


# ---------------------------------------------------------------------- direct light
H, ALBEDO, POWER = 1.0, 0.5, 100.0


def _floor_radiance(ies_path, light_xy, kind="point"):
    """Mean radiance of a narrow view of the floor's origin lit from (light_xy, H) by a
    lamp pointing down (-Z) with the profile: no photons, direct light only."""
    s = PaperScene(width=4, height=4)
    s.add_material(Material("grey", (ALBEDO,) * 3, specular=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, "grey", name="floor")
    pos = (light_xy[0], light_xy[1], H)
    if kind == "point":
        s.add_point_light(pos, POWER, ies=ies_path)
    else:
        s.add_spot_light(pos, (pos[0], pos[1], 0.0), POWER, spot_size_degrees=110.0,
                         blend=0.0, ies=ies_path)
    s.set_camera((0, 0, 6.0), (0, 0, 0), up=(0, 1, 0), view_angle=0.02)
    film = s.render(RenderSettings(spp=4, photon_mapping=False, seed=3, workers=1))
    return float(film.combined.mean())


@pytest.mark.parametrize("kind, xy", [("point", (0.0, 0.0)), ("point", (0.8, 0.0)),
                                      ("point", (0.0, -1.2)), ("point", (-0.5, 0.6)),
                                      ("spot", (0.8, 0.0))])
def test_floor_reads_intensity_times_profile(tmp_path, kind, xy):
    """Radiance rho / pi x I f(w) cos / r^2, w the direction from the lamp to the floor
    point in the lamp's frame (its -Z down, X and Y the world's): per direction of the
    asymmetric profile. The spot's 110-degree cone holds every w here (mask 1)."""
    path = _write(tmp_path, FORWARD)
    p = ies.load(path)
    w = np.array([-xy[0], -xy[1], -H])
    r = float(np.linalg.norm(w))
    want = ALBEDO / math.pi * POWER / (4 * math.pi) * p.evaluate(w[None])[0] * H / r ** 3
    assert want > 0
    assert _floor_radiance(path, xy, kind) == pytest.approx(want, rel=2e-3)


def test_broken_file_warns_and_renders_the_plain_light(tmp_path):
    path = _write(tmp_path, QUADRANT.replace("TILT=NONE", "TILT=NOPE\n\n"), "broken.ies")
    s = PaperScene(width=4, height=4)
    s.add_material(Material("grey", (ALBEDO,) * 3, specular=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, "grey", name="floor")
    s.add_point_light((0, 0, H), POWER, ies=str(tmp_path / "missing.ies"), name="lamp")
    warnings = s.all_warnings()
    assert any("lamp" in w and "missing.ies" in w for w in warnings), warnings
    s.set_camera((0, 0, 6.0), (0, 0, 0), up=(0, 1, 0), view_angle=0.02)
    film = s.render(RenderSettings(spp=4, photon_mapping=False, seed=3, workers=1))
    want = ALBEDO / math.pi * POWER / (4 * math.pi) / H ** 2
    assert float(film.combined.mean()) == pytest.approx(want, rel=2e-3)
    assert ies.parse(open(path).read(), "broken.ies") is not None  # TILT=<file> skipped


def test_ies_on_an_area_light_is_warned_and_ignored(tmp_path):
    light = Light("panel", "AREA", ies_path=_write(tmp_path, FORWARD))
    assert light.ies_profile is None
    assert any("point and spot" in w for w in light.warnings)


# ---------------------------------------------------------------------- photons
def _prepared(light):
    s = top_down_plane()
    s.add_light(light)
    s.validate()
    geo, table = prepare(s)
    return prepare_lights(s, geo, table)[0]


def _profile_power_in_bins(light, profile, edges_cos, spot=None):
    """Power (W, RGB summed / 3 as the colour is white) the profile sends into bands of
    cos v edges_cos (lamp frame = world, -Z down), by a fine midpoint quadrature."""
    n = 400
    out = []
    for lo, hi in zip(edges_cos[:-1], edges_cos[1:]):
        cz = lo + (np.arange(n) + 0.5) / n * (hi - lo)
        h = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * math.pi
        C, Hh = np.meshgrid(cz, h, indexing="ij")
        w = ies.direction_from_angles(Hh.ravel(), np.arccos(C.ravel()))
        f = profile.evaluate(w)
        if spot is not None:
            f = f * spot(w)
        out.append(light.power / (4 * math.pi) * f.mean() * (hi - lo) * 2 * math.pi)
    return np.array(out)


@pytest.mark.parametrize("kind", ["POINT", "SPOT"])
def test_photons_follow_the_profile(tmp_path, kind):
    """The photons' power in bands of the angle from straight down and in the four
    horizontal quadrants matches the integral of I f(w) (x the spot's mask) there; the
    total equals photon_flux."""
    path = _write(tmp_path, FORWARD)
    light = Light("lamp", kind, power=POWER, position=(0, 0, 2), direction=(0, 0, -1),
                  spot_size=math.radians(100), spot_blend=0.2, ies_path=path)
    pl = _prepared(light)
    o, d, power = pl.emit(400_000, np.random.default_rng(7))
    p = ies.load(path)
    spot = pl._falloff_plain
    edges = np.cos(np.radians([0, 15, 30, 45, 60, 75, 90]))[::-1] * -1  # cos v = -z
    cz = -d[:, 2]
    got = np.array([power[(cz >= lo) & (cz < hi), 0].sum() for lo, hi in
                    zip(edges[:-1], edges[1:])])
    want = _profile_power_in_bins(light, p, edges, None if kind == "POINT" else spot)
    np.testing.assert_allclose(got, want, rtol=0.03, atol=0.002 * want.sum())
    assert power[:, 0].sum() == pytest.approx(float(pl.photon_flux[0]), rel=0.01)
    # The forward throw: the quadrant round h = 90 degrees (local -X) carries the most.
    h = np.degrees(np.arctan2(d[:, 0], d[:, 1]) + math.pi)
    forward = power[np.abs(h - 90) < 45, 0].sum()
    back = power[np.abs(h - 270) < 45, 0].sum()
    assert forward > 2.0 * back


def test_type_a_b_and_upward_layouts_as_cycles():
    """Cycles 5.0's IESFile::process: a type C table of vertical angles 90 .. 180 kept
    (lighting upwards, 0 below the horizon), type B transposed and mirrored about 90
    degrees, type A's horizontal -90 .. 90 mapped to 270 .. 90 (tests/blender/
    test_ies_cycles.py renders the first two against Cycles)."""
    up = ies.parse(QUADRANT.replace("0 30 60 90", "90 120 150 180"), "up")
    np.testing.assert_allclose(np.degrees(up.v_angles), [90, 120, 150, 180])
    assert up.evaluate([[0.0, 0.0, -1.0]])[0] == 0.0  # straight down: below its range
    assert up.evaluate([[0.0, 0.3, 1.0]])[0] > 0.0
    b = ies.parse(QUADRANT.replace("1 1000 2.0 4 2 1 2", "1 1000 2.0 4 2 2 2")
                  .replace("\n0 90\n", "\n-90 90\n"), "b")
    np.testing.assert_allclose(np.degrees(b.h_angles), [0, 30, 60, 90, 120, 150, 180])
    np.testing.assert_allclose(np.degrees(b.v_angles), [0, 180])
    assert b.intensity.shape == (7, 2)
    a = ies.parse(QUADRANT.replace("1 1000 2.0 4 2 1 2", "1 1000 2.0 4 2 3 2"), "a")
    np.testing.assert_allclose(np.degrees(a.h_angles), [90, 180, 270])
    np.testing.assert_allclose(np.degrees(a.v_angles), [90, 120, 150, 180])


def test_sphere_lamp_reads_the_profile_along_each_ray(tmp_path):
    """Soft Falloff off: a sphere of radius R, each point of radiance I / (pi R^2) x f
    along the ray from that point to the shaded point (as Cycles 5.0 renders it,
    tests/blender/test_ies_cycles.py; f along the sphere's normal there read up to 56 %
    off). The floor's irradiance is the integral over the sphere's visible half of that
    radiance x cos at the floor x cos at the sphere / d^2 (a fine quadrature), which
    differs from the normal's reading by far more than the tolerance."""
    path = _write(tmp_path, FORWARD)
    p = ies.load(path)
    R, xy = 0.5, (0.9, -0.3)
    light_pos = np.array([xy[0], xy[1], H])
    # Quadrature over the sphere: uniform in (cos, phi) is uniform in area.
    n = 800
    cz = (np.arange(n) + 0.5) / n * 2 - 1
    ph = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * math.pi
    C, P = np.meshgrid(cz, ph, indexing="ij")
    s = np.sqrt(1 - C ** 2)
    normal = np.stack([s * np.cos(P), s * np.sin(P), C], axis=-1).reshape(-1, 3)
    dA = 4 * math.pi * R * R / len(normal)
    to_p = -(light_pos + R * normal)  # from the sphere point to the floor's origin
    d = np.linalg.norm(to_p, axis=1)
    cos_l = np.einsum("ij,ij->i", normal, to_p) / d
    cos_f = np.maximum(-to_p[:, 2] / d, 0.0)  # the floor's normal +Z; to_p points down
    seen = cos_l > 0
    L0 = POWER / (4 * math.pi) / (math.pi * R * R)
    geometry = (cos_f * cos_l * dA / d ** 2)[seen]
    want = ALBEDO / math.pi * float(np.sum(L0 * p.evaluate(to_p[seen]) * geometry))
    by_normal = ALBEDO / math.pi * float(np.sum(L0 * p.evaluate(normal[seen]) * geometry))
    s = PaperScene(width=4, height=4)
    s.add_material(Material("grey", (ALBEDO,) * 3, specular=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, "grey", name="floor")
    s.add_point_light(tuple(light_pos), POWER, radius=R, soft_falloff=False, ies=path)
    s.set_camera((0, 0, 6.0), (0, 0, 0), up=(0, 1, 0), view_angle=0.02)
    got = float(s.render(RenderSettings(spp=256, photon_mapping=False, seed=3,
                                        workers=1)).combined.mean())
    assert abs(by_normal / want - 1) > 0.05
    assert got == pytest.approx(want, rel=0.01)


def test_scene_file_reads_a_profile_relative_to_itself(tmp_path):
    from engine.scenefile import load_scene
    _write(tmp_path, FORWARD, "lamp.ies")
    (tmp_path / "s.toml").write_text(
        'background = [0, 0, 0]\n[camera]\nposition = [0, -6, 2]\nlook_at = [0, 0, 0]\n'
        '[[lights]]\ntype = "point"\nposition = [0, 0, 2]\npower = 100\nies = "lamp.ies"\n')
    scene, _ = load_scene(str(tmp_path / "s.toml"))
    light = scene.lights[0]
    assert light.ies_profile is not None and light.ies_profile.name == "lamp.ies"
