"""Image texture lookups (engine/textures.py) against values worked out by hand from
Cycles' rules: texel centres at (i + 0.5) / w, wrap modes per texel, B-spline cubic,
sRGB converted after interpolation, UDIM tile numbers."""
import numpy as np
import pytest

from engine.bsdf import surface_hit
from engine.geometry import prepare
from engine.scene import Material, Mesh, Scene, SceneError
from engine.imageio import srgb_decode
from engine.textures import ColorAttribute, ImageTexture, TextureError

# A 1-row image of 4 texels (stored top row first; one row so v does not matter).
ROW = np.array([[[0.1] * 3, [0.2] * 3, [0.4] * 3, [0.8] * 3]], np.float32)


def _red(tex, us, v=0.5):
    uv = np.stack([np.asarray(us, float), np.full(len(us), v)], axis=1)
    return tex.sample(uv)[:, 0]


def _centre(i, w=4):
    return (i + 0.5) / w


def test_linear_reproduces_texel_centres_and_averages_between():
    t = ImageTexture(ROW, extension="EXTEND")
    np.testing.assert_allclose(_red(t, [_centre(i) for i in range(4)]), [0.1, 0.2, 0.4, 0.8],
                               atol=1e-6)
    np.testing.assert_allclose(_red(t, [0.5]), [0.3], atol=1e-6)  # between texels 1 and 2


@pytest.mark.parametrize("ext, expect", [
    # texel index -1 (u = -0.125) and 4 (u = 1.125), and one image over (u = 1.375 -> 5)
    ("REPEAT", [0.8, 0.1, 0.2]),
    ("EXTEND", [0.1, 0.8, 0.8]),
    ("CLIP", [0.0, 0.0, 0.0]),
    ("MIRROR", [0.1, 0.8, 0.4]),
])
def test_extension_modes_outside_the_image(ext, expect):
    t = ImageTexture(ROW, extension=ext, interpolation="Closest")
    np.testing.assert_allclose(_red(t, [-0.125, 1.125, 1.375]), expect, atol=1e-6)


def test_clip_fades_to_black_over_half_a_texel_with_linear():
    t = ImageTexture(ROW, extension="CLIP")
    # At the image edge (u = 0) a linear lookup is half texel 0, half the black outside.
    np.testing.assert_allclose(_red(t, [0.0, 1.0, -0.125, 1.2]), [0.05, 0.4, 0.0, 0.0],
                               atol=1e-6)


def test_closest_gives_only_stored_values_when_magnified():
    t = ImageTexture(ROW, interpolation="Closest")
    vals = _red(t, np.linspace(0.001, 0.999, 997))
    assert set(np.round(vals, 6)) == {0.1, 0.2, 0.4, 0.8}
    lin = _red(ImageTexture(ROW), np.linspace(0.001, 0.999, 997))
    assert len(set(np.round(lin, 6))) > 100  # the fault Closest fixes: in-between values


@pytest.mark.parametrize("mode", ["Cubic", "Smart"])
def test_cubic_is_cycles_uniform_b_spline(mode):
    t = ImageTexture(ROW, extension="REPEAT", interpolation=mode)
    # At a texel centre the B-spline weights are 1/6, 4/6, 1/6 (not interpolating).
    got = _red(t, [_centre(1), _centre(0)])
    np.testing.assert_allclose(got, [(0.1 + 4 * 0.2 + 0.4) / 6, (0.8 + 4 * 0.1 + 0.2) / 6],
                               atol=1e-6)
    # Half-way between texels: weights 1/48, 23/48, 23/48, 1/48.
    np.testing.assert_allclose(_red(t, [0.5]), [(0.1 + 23 * 0.2 + 23 * 0.4 + 0.8) / 48],
                               atol=1e-6)
    flat = ImageTexture(np.full((5, 7, 3), 0.3), interpolation=mode, extension="EXTEND")
    rng = np.random.default_rng(1)
    np.testing.assert_allclose(flat.sample(rng.random((50, 2))), 0.3, atol=1e-6)


def test_srgb_is_converted_after_interpolation():
    # Black and white texels, 8-bit sRGB: half-way reads encoded 0.5 -> 0.214 linear, not
    # the 0.5 of converting first (the issue-15 checker that came out 1.68x too bright).
    img = np.array([[[0.0] * 3, [1.0] * 3]], np.float32)
    t = ImageTexture(img, srgb=True, extension="EXTEND")
    np.testing.assert_allclose(_red(t, [0.5]), srgb_decode(0.5), atol=1e-6)
    np.testing.assert_allclose(srgb_decode(0.5), 0.21404, atol=1e-5)
    np.testing.assert_allclose(_red(t, [0.25, 0.75], ), [0.0, 1.0], atol=1e-6)


def test_udim_tiles_use_their_own_image_and_missing_tiles_are_magenta():
    t = ImageTexture(tiles={1001: np.full((2, 2, 3), 0.2), 1002: np.full((2, 2, 3), 0.6),
                            1011: np.full((2, 2, 3), 0.9)}, srgb=False)
    uv = np.array([[0.5, 0.5], [1.5, 0.5], [0.5, 1.5], [2.5, 0.5], [-0.5, 0.5]])
    got = t.sample(uv)
    np.testing.assert_allclose(got[:3, 0], [0.2, 0.6, 0.9], atol=1e-6)
    np.testing.assert_allclose(got[3:], [[1, 0, 1], [1, 0, 1]], atol=1e-6)
    ts = ImageTexture(tiles={1001: np.full((2, 2, 3), 0.5)}, srgb=True)
    np.testing.assert_allclose(ts.sample(uv[[0, 3]]), [[srgb_decode(0.5)] * 3, [1, 0, 1]],
                               atol=1e-6)


def test_alpha_channel_is_sampled_and_reported():
    img = np.zeros((2, 2, 4), np.float32)
    img[..., 3] = [[1, 0], [1, 0]]
    t = ImageTexture(img, interpolation="Closest")
    assert t.has_alpha
    np.testing.assert_allclose(t.sample_rgba(np.array([[0.25, 0.5], [0.75, 0.5]]))[:, 3],
                               [1, 0])
    assert not ImageTexture(ROW).has_alpha


def test_bad_settings_name_the_texture_and_argument():
    with pytest.raises(TextureError, match="'wood'.*extension"):
        ImageTexture(ROW, extension="WRAP", name="wood")
    with pytest.raises(TextureError, match="interpolation"):
        ImageTexture(ROW, interpolation="Lanczos")
    with pytest.raises(TextureError, match="tile 1001"):
        ImageTexture(tiles={1001: np.zeros((2, 2, 2))})
    with pytest.raises(SceneError, match="material 'm'.*HxWx4"):
        Material("m", texture=np.zeros((2, 2, 5)))


def _textured_quad(texture):
    """A unit quad at z=0 whose UVs run from -1 to 2 (so a third of it is inside 0..1)."""
    s = Scene()
    s.add_material(Material("t", (1, 1, 1), texture=texture))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    s.add_mesh(Mesh("quad", v, np.array([[0, 1, 2], [0, 2, 3]]), uvs=v[:, :2] * 3 - 1,
                    materials=["t"]))
    return prepare(s)


def test_surface_hit_applies_the_texture_settings():
    img = np.full((4, 4, 3), 0.5, np.float32)
    geo, table = _textured_quad(ImageTexture(img, extension="CLIP"))
    # Hits on triangle 0 (corners 0, 1, 2): point (u + v, v), uv = 3 point - 1, here
    # uv (0.5, 0.2) inside the image, (-0.7, -0.85) and (1.7, -0.7) outside.
    u = np.array([0.1, 0.05, 0.8]); v = np.array([0.4, 0.05, 0.1])
    prim = np.zeros(3, np.int64)
    hit = surface_hit(geo, table, prim, u, v, np.tile([0.0, 0.0, -1.0], (3, 1)))
    uv = geo.uvs(prim, u, v)
    inside = (uv >= 0).all(axis=1) & (uv <= 1).all(axis=1)
    assert inside.any() and (~inside).any()
    np.testing.assert_allclose(hit.base[inside], 0.5, atol=1e-6)
    np.testing.assert_allclose(hit.base[~inside], 0.0, atol=1e-6)


def test_bare_array_texture_keeps_repeat_linear():
    img = np.random.default_rng(0).random((3, 5, 3)).astype(np.float32)
    m = Material("legacy", texture=img)
    assert m.texture.extension == "REPEAT" and m.texture.interpolation == "Linear"
    uv = np.array([[0.3, 0.7], [1.3, -0.3]])
    got = m.texture.sample(uv)
    np.testing.assert_allclose(got[0], got[1], atol=1e-6)


def test_color_attribute_interpolates_corner_colours_and_is_black_without_one():
    s = Scene()
    s.add_material(Material("vc", (1, 1, 1), texture=ColorAttribute("Col")))
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    s.add_mesh(Mesh("tri", v, np.array([[0, 1, 2]]), materials=["vc"],
                    colors=np.array([[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]], float)))
    s.add_mesh(Mesh("plain", v + [0, 0, 1], np.array([[0, 1, 2]]), materials=["vc"]))
    geo, table = prepare(s)
    u = np.array([0.2, 0.2]); v_ = np.array([0.3, 0.3])
    hit = surface_hit(geo, table, np.array([0, 1]), u, v_, np.tile([0.0, 0, -1], (2, 1)))
    np.testing.assert_allclose(hit.base, [[0.5, 0.2, 0.3], [0, 0, 0]], atol=1e-9)
    with pytest.raises(SceneError, match="'bad'.*colors"):
        Mesh("bad", v, np.array([[0, 1, 2]]), colors=np.zeros((2, 3)))


def _normal_mapped_quad(color, space="TANGENT", strength=1.0, flip_u=False):
    """Unit quad at z=0 (normal +z), UVs = xy (or u mirrored), a constant normal-map colour."""
    from engine.normalmap import NormalMap
    s = Scene()
    tex = ImageTexture(np.array([[color]], np.float32))
    s.add_material(Material("n", (0.8,) * 3, normal_map=NormalMap(tex, strength, space)))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    uv = v[:, :2].copy()
    if flip_u:
        uv[:, 0] = 1 - uv[:, 0]
    s.add_mesh(Mesh("quad", v, np.array([[0, 1, 2], [0, 2, 3]]), uvs=uv, materials=["n"]))
    geo, table = prepare(s)
    d = np.tile([0.0, 0.0, -1.0], (2, 1))
    return surface_hit(geo, table, np.array([0, 1]), np.array([0.3, 0.2]),
                       np.array([0.3, 0.5]), d).ns


def test_tangent_space_normal_map_tilts_along_the_uv_axes():
    th = np.radians(30)
    c = [0.5 + 0.5 * np.sin(th), 0.5, 0.5 + 0.5 * np.cos(th)]  # tilt towards +u
    np.testing.assert_allclose(_normal_mapped_quad(c), [[np.sin(th), 0, np.cos(th)]] * 2,
                               atol=1e-6)
    # Mirrored UVs: +u runs along -x there, and the bitangent keeps +v along +y.
    np.testing.assert_allclose(_normal_mapped_quad(c, flip_u=True),
                               [[-np.sin(th), 0, np.cos(th)]] * 2, atol=1e-6)
    cy = [0.5, 0.5 + 0.5 * np.sin(th), 0.5 + 0.5 * np.cos(th)]  # tilt towards +v
    np.testing.assert_allclose(_normal_mapped_quad(cy, flip_u=True),
                               [[0, np.sin(th), np.cos(th)]] * 2, atol=1e-6)
    flat = _normal_mapped_quad(c, strength=0.0)
    np.testing.assert_allclose(flat, [[0, 0, 1]] * 2, atol=1e-9)


def test_tangent_space_strength_scales_x_y_and_blends_z_as_cycles():
    """svm_node_normal_map: x, y times the strength, z blended from 1 (not a blend of the
    normals), then normalised."""
    th = np.radians(30)
    c = [0.5 + 0.5 * np.sin(th), 0.5, 0.5 + 0.5 * np.cos(th)]
    for s in (0.5, 2.0):
        m = np.array([s * np.sin(th), 0.0, 1.0 + (np.cos(th) - 1.0) * min(s, 1.0)])
        np.testing.assert_allclose(_normal_mapped_quad(c, strength=s),
                                   [m / np.linalg.norm(m)] * 2, atol=1e-6)


def test_world_space_normal_map_and_bad_input():
    from engine.normalmap import NormalMap, NormalMapError
    n = np.array([0.0, 0.6, 0.8])
    np.testing.assert_allclose(_normal_mapped_quad(0.5 + 0.5 * n, space="WORLD"), [n] * 2,
                               atol=1e-6)
    with pytest.raises(NormalMapError, match="space"):
        NormalMap(ImageTexture(ROW), space="OBJECTISH")
    with pytest.raises(SceneError, match="'m' normal_map"):
        Material("m", normal_map=ImageTexture(ROW))


def _plane_geo(texture):
    """Unit quad, UV = xy; returns a function uv -> base colour at those UVs."""
    s = Scene()
    s.add_material(Material("n", (1, 1, 1), texture=texture))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    s.add_mesh(Mesh("quad", v, np.array([[0, 1, 2], [0, 2, 3]]), uvs=v[:, :2], materials=["n"]))
    geo, table = prepare(s)

    def at(uv):
        uv = np.asarray(uv, float)
        # triangle 0 covers x >= y: corners (0,0), (1,0), (1,1) -> p = (u + v, v)
        prim = np.zeros(len(uv), np.int64)
        bv = uv[:, 1]
        bu = uv[:, 0] - uv[:, 1]
        return surface_hit(geo, table, prim, bu, bv, np.tile([0.0, 0, -1], (len(uv), 1))).base
    return at


def test_shader_nodes_mix_invert_ramp_math_checker_mapping():
    from engine import shadernodes as sn
    uvc = sn.UVCoord()
    u_only = sn.SeparateChannel(uvc, 0)
    at = _plane_geo(sn.MixColor(u_only, (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
    np.testing.assert_allclose(at([[0.25, 0.1]]), [[0.75, 0, 0.25]], atol=1e-9)
    at = _plane_geo(sn.MixColor(0.5, (0.5, 0.5, 0.5), (0.2, 0.4, 1.0), blend="MULTIPLY"))
    np.testing.assert_allclose(at([[0.5, 0.2]]), [[0.3, 0.35, 0.5]], atol=1e-9)
    at = _plane_geo(sn.Invert(1.0, (0.2, 0.3, 0.9)))
    np.testing.assert_allclose(at([[0.5, 0.2]]), [[0.8, 0.7, 0.1]], atol=1e-9)
    ramp = sn.ColorRamp(u_only, [0.0, 0.5], [(0, 0, 0), (1, 1, 1)])
    np.testing.assert_allclose(_plane_geo(ramp)([[0.25, 0.1], [0.75, 0.1]]),
                               [[0.5] * 3, [1.0] * 3], atol=1e-9)
    const = sn.ColorRamp(u_only, [0.0, 0.5], [(0.1, 0, 0), (0.9, 0, 0)],
                         interpolation="CONSTANT")
    np.testing.assert_allclose(_plane_geo(const)([[0.4, 0.1], [0.6, 0.1]])[:, 0], [0.1, 0.9])
    m = sn.Math("MULTIPLY", u_only, 2.0, clamp=True)
    np.testing.assert_allclose(_plane_geo(sn.Combine(m, 0.0, 0.0))([[0.3, 0.1], [0.8, 0.1]])
                               [:, 0], [0.6, 1.0], atol=1e-9)
    # Checker with scale 2 on UV: cells of 0.5; (0.25, 0.1) is cell (0, 0) -> colour2.
    chk = sn.Checker(uvc, (0.9, 0.9, 0.9), (0.1, 0.1, 0.1), scale=2.0)
    np.testing.assert_allclose(_plane_geo(chk)([[0.25, 0.1], [0.75, 0.1], [0.75, 0.6]])[:, 0],
                               [0.1, 0.9, 0.1], atol=1e-9)
    # Mapping (Point): scale 2 then shift by 0.25 in u; an image lookup sees u' = 2u + 0.25.
    img = ImageTexture(ROW, extension="EXTEND", interpolation="Closest")
    lk = sn.ImageLookup(img, sn.Mapping(uvc, location=(0.25, 0, 0), scale=(2, 1, 1)))
    np.testing.assert_allclose(_plane_geo(lk)([[0.05, 0.02], [0.2, 0.1]])[:, 0], [0.2, 0.4],
                               atol=1e-9)
    with pytest.raises(ValueError, match="blend type"):
        sn.MixColor(0.5, 0, 0, blend="OVERLAYISH")


def test_bump_tilts_against_the_height_gradient():
    from engine import shadernodes as sn
    from engine.bump import Bump
    # h = 0.5 u on a unit quad with uv = xy: grad h = (0.5, 0, 0); distance 0.8 ->
    # n' = normalize((0, 0, 1) - 0.8 (0.5, 0, 0)) = normalize(-0.4, 0, 1).
    h = sn.Math("MULTIPLY", sn.SeparateChannel(sn.UVCoord(), 0), 0.5)
    want = np.array([-0.4, 0, 1]) / np.hypot(0.4, 1)
    for prim_uv in ([0.3, 0.2], [0.2, 0.6]):  # one point in each triangle
        got = _bumped(Bump(h, distance=0.8), prim_uv)
        np.testing.assert_allclose(got, want, atol=1e-6)
    np.testing.assert_allclose(_bumped(Bump(h, distance=0.8, invert=True), [0.3, 0.2]),
                               want * [-1, 1, 1], atol=1e-6)
    half = _bumped(Bump(h, strength=0.5, distance=0.8), [0.3, 0.2])
    np.testing.assert_allclose(half, normalize_(0.5 * want + 0.5 * np.array([0, 0, 1.0])),
                               atol=1e-6)


def test_bump_seen_from_the_back_is_the_front_bumped_normal_turned_over():
    """From a back face the shading normal is the front's bumped normal turned over,
    -normalize(n - d grad h), as Cycles renders it (tests/blender/
    test_bump_back_face_cycles.py: the tilt mirrored instead reads against Cycles')."""
    from engine import shadernodes as sn
    from engine.bump import Bump
    h = sn.Math("MULTIPLY", sn.SeparateChannel(sn.UVCoord(), 0), 0.5)  # grad h = (0.5, 0, 0)
    want = np.array([0.4, 0, -1]) / np.hypot(0.4, 1)
    for prim_uv in ([0.3, 0.2], [0.2, 0.6]):
        got = _bumped(Bump(h, distance=0.8), prim_uv, d=[0.0, 0, 1])
        np.testing.assert_allclose(got, want, atol=1e-6)


def test_normal_map_takes_procedural_values_and_constant_colours():
    """A Normal Map's Color from any node: a procedural colour (per hit), a value (grey,
    as Cycles converts a float into a colour) or a constant colour; bad constants raise."""
    from engine import shadernodes as sn
    from engine.normalmap import NormalMap, NormalMapError
    th = np.radians(30)
    tilt_u = np.array([0.5 + 0.5 * np.sin(th), 0.5, 0.5 + 0.5 * np.cos(th)])
    chk = sn.Checker(sn.UVCoord(), tuple(tilt_u), (0.5, 0.5, 1.0), scale=2.0)  # 0.5 cells
    got = np.array([_bumped(NormalMap(chk), xy) for xy in ([0.25, 0.1], [0.75, 0.1])])
    np.testing.assert_allclose(got, [[0, 0, 1], [np.sin(th), 0, np.cos(th)]], atol=1e-6)
    grey = sn.Math("ADD", sn.Math("MULTIPLY", sn.SeparateChannel(sn.UVCoord(), 0), 0.0), 0.7)
    want = normalize_(np.full(3, 2 * 0.7 - 1))  # x T + y B + z N with x = y = z = 0.4
    np.testing.assert_allclose(_bumped(NormalMap(grey), [0.3, 0.2]), want, atol=1e-6)
    np.testing.assert_allclose(_bumped(NormalMap(tilt_u), [0.3, 0.2]),
                               [np.sin(th), 0, np.cos(th)], atol=1e-6)
    np.testing.assert_allclose(_bumped(NormalMap(tilt_u, space="WORLD"), [0.2, 0.6]),
                               [np.sin(th), 0, np.cos(th)], atol=1e-6)
    with pytest.raises(NormalMapError, match="finite"):
        NormalMap([np.nan, 0.5, 1.0])
    with pytest.raises(NormalMapError, match="constant colour"):
        NormalMap("blue")


def normalize_(x):
    return x / np.linalg.norm(x)


def _bumped(nmap, xy, d=(0.0, 0, -1)):
    s = Scene()
    s.add_material(Material("b", (0.8,) * 3, normal_map=nmap))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    s.add_mesh(Mesh("quad", v, np.array([[0, 1, 2], [0, 2, 3]]), uvs=v[:, :2], materials=["b"]))
    geo, table = prepare(s)
    x, y = xy
    if x >= y:   # triangle 0: p = (u + v, v)
        prim, bu, bv = 0, x - y, y
    else:        # triangle 1 (corners 0, 2, 3): p = (u, u + v)
        prim, bu, bv = 1, x, y - x
    return surface_hit(geo, table, np.array([prim]), np.array([bu]), np.array([bv]),
                       np.array([d], float)).ns[0]


def test_hue_saturation_and_gradient():
    import colorsys
    from engine import shadernodes as sn
    rng = np.random.default_rng(3)
    c = rng.random((40, 3))
    hsv = sn.rgb_to_hsv(c)
    want = np.array([colorsys.rgb_to_hsv(*row) for row in c])
    np.testing.assert_allclose(hsv, want, atol=1e-12)
    np.testing.assert_allclose(sn.hsv_to_rgb(hsv), c, atol=1e-12)
    col = (0.8, 0.2, 0.1)
    # Hue 0.5 / saturation 1 / value 1 is the identity; hue 0.5 + 1/3 rotates R -> G.
    same = _plane_geo(sn.HueSaturation(0.5, 1.0, 1.0, 1.0, col))([[0.3, 0.1]])
    np.testing.assert_allclose(same, [col], atol=1e-9)
    rot = _plane_geo(sn.HueSaturation(0.5 + 1 / 3, 1.0, 1.0, 1.0, col))([[0.3, 0.1]])
    np.testing.assert_allclose(rot, [[0.1, 0.8, 0.2]], atol=1e-9)
    grey = _plane_geo(sn.HueSaturation(0.5, 0.0, 0.5, 1.0, col))([[0.3, 0.1]])
    np.testing.assert_allclose(grey, [[0.4, 0.4, 0.4]], atol=1e-9)
    g = _plane_geo(sn.Gradient(sn.UVCoord(), "EASING"))([[0.25, 0.1]])
    np.testing.assert_allclose(g, [[0.15625] * 3], atol=1e-9)
    d = _plane_geo(sn.Gradient(sn.UVCoord(), "DIAGONAL"))([[0.5, 0.1]])
    np.testing.assert_allclose(d, [[0.3] * 3], atol=1e-9)


def test_mesh_coordinates_feed_procedural_nodes():
    from engine import shadernodes as sn
    s = Scene()
    s.add_material(Material("g", (1, 1, 1), texture=sn.Gradient(sn.Coordinates("generated"))))
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0]], float)
    gen = (v / 2.0)[None]  # generated = position over the bounds
    s.add_mesh(Mesh("tri", v, np.array([[0, 1, 2]]), materials=["g"],
                    coordinates={"generated": gen}))
    s.add_mesh(Mesh("none", v + [0, 0, 1], np.array([[0, 1, 2]]), materials=["g"]))
    geo, table = prepare(s)
    hit = surface_hit(geo, table, np.array([0, 1]), np.array([0.3, 0.3]),
                      np.array([0.1, 0.1]), np.tile([0.0, 0, -1], (2, 1)))
    np.testing.assert_allclose(hit.base[:, 0], [0.3, 0.0], atol=1e-9)
    with pytest.raises(SceneError, match="coordinates\\['generated'\\]"):
        Mesh("bad", v, np.array([[0, 1, 2]]), coordinates={"generated": np.zeros((1, 3, 2))})
