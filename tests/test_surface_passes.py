"""Cycles' surface data passes in the engine (engine/datapasses.py SURFACE): Object Index,
Material Index, Position, UV and Mist. Analytic values on a UV-mapped plane seen from
above (at 1 sample a pixel the UV is the map of the Position, the Mist Cycles' formula of
its distance, all three from the same sample), the background's values, Depth as
Cycles' sample 0 writes it, the single pass
through half-transparent sheets on either side of the Alpha Threshold, mist through a
sheet (Cycles' throughput x alpha weighting), the first-sample passes kept as written by
adaptive and progressive rendering, the image's bits untouched, the scene file's
pass_index / [mist] and the CLI. The comparison against live Cycles is
tests/blender/test_blender_surface_passes.py."""
import numpy as np
import pytest

from engine import Budget, RenderSettings, render_progressive
from engine.api import PaperScene
from engine.render import render
from engine.scene import Material, Mesh

W, H = 12, 9
HEIGHT = 5.0
HALF = 2.5  # the plane's half size (m): at view 60 the background shows left and right
SURFACE = ("object_index", "material_index", "position", "uv", "mist")
EFFECTS = ("direct", "indirect", "caustic", "specular", "emission")


def _quad(z, half, uv_scale=None):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = None if uv_scale is None else v[:, :2] / (2.0 * uv_scale) + 0.5
    return v, f, uv


def _scene(sheet_alpha=None, mist=(1.0, 8.0, 0.5), view=60.0):
    """A UV-mapped plane (object pass index 7, material 3) under a camera HEIGHT m above
    it looking straight down (its rim and the background in the corners at view 60);
    with sheet_alpha a sheet 1 m above it (object 4, material 6, UVs u, v = 0.25, 0.75
    everywhere) of that alpha."""
    s = PaperScene(W, H, background=(0.2, 0.2, 0.2))
    s.add_material(Material("top", (0.6, 0.3, 0.1), pass_index=3))
    v, f, uv = _quad(0.0, HALF, HALF)
    s.add_mesh(Mesh("floor", v, f, uvs=uv, materials=["top"], pass_index=7))
    if sheet_alpha is not None:
        s.add_material(Material("sheet", (0.2, 0.5, 0.9), alpha=sheet_alpha, pass_index=6))
        v, f, _ = _quad(1.0, 40.0)
        s.add_mesh(Mesh("sheet", v, f, uvs=np.tile([0.25, 0.75], (4, 1)),
                        materials=["sheet"], pass_index=4))
    s.add_point_light((1.0, 1.0, 3.0), power=100.0)
    s.set_camera((0.0, 0.0, HEIGHT), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), view_angle=view)
    s.mist = mist
    return s


def _settings(**kw):
    base = dict(workers=1, spp=1, seed=3, photons=2_000, caustic_photons=200,
                data_passes=SURFACE)
    base.update(kw)
    return RenderSettings(**base)


def _mist(dist, mist):
    start, depth, falloff = mist
    return np.clip((dist - start) / depth, 0.0, 1.0) ** falloff


@pytest.mark.parametrize("falloff", [2.0, 1.0, 0.5])
def test_plane_values_one_sample(falloff):
    mist = (1.0, 8.0, falloff)
    film = render(_scene(mist=mist), _settings())
    d = film.data
    assert set(d) == set(SURFACE)
    seen = d["object_index"] > 0
    assert 0.5 * seen.size < seen.sum() < seen.size  # the rim: background in the corners
    assert np.all(d["object_index"][seen] == 7) and np.all(d["material_index"][seen] == 3)
    p = d["position"][seen].astype(np.float64)
    np.testing.assert_allclose(p[:, 2], 0.0, atol=1e-6)
    assert np.all(np.abs(p[:, :2]) <= HALF + 1e-5)
    # The same sample writes all three: UV = the map of the Position, Mist its formula.
    uv = d["uv"][seen]
    np.testing.assert_allclose(uv[:, :2], p[:, :2] / (2 * HALF) + 0.5, atol=1e-5)
    np.testing.assert_allclose(uv[:, 2], 1.0)
    dist = np.linalg.norm(p - (0.0, 0.0, HEIGHT), axis=1)
    np.testing.assert_allclose(d["mist"][seen], _mist(dist, mist), atol=1e-5)
    # Rows top to bottom: the top rows see +y.
    assert p[:, 1][np.nonzero(seen)[0] < H // 2].min() > 0.0
    # The background (Cycles' film_write_data_passes_background; mist: nothing added).
    assert not d["position"][~seen].any() and not d["uv"][~seen].any()
    assert not d["material_index"][~seen].any()
    np.testing.assert_array_equal(d["mist"][~seen], 1.0)


def test_many_samples_average_uv_and_mist_not_indices():
    """UV and Mist are per-sample averages; the indices and Position the first sample's
    values as written (not divided by the samples)."""
    one = render(_scene(), _settings(spp=1)).data
    many = render(_scene(), _settings(spp=16)).data
    inner = (one["object_index"] > 0) & (many["object_index"] > 0)
    inner[[0, -1], :] = inner[:, [0, -1]] = False
    assert np.all(many["object_index"][inner] == 7)
    np.testing.assert_array_equal(many["position"][inner][:, 2], 0.0)
    # A pixel is 0.48 m wide at the plane: the averages stay within it of the sample's.
    assert np.abs(many["uv"][inner] - one["uv"][inner]).max() < 0.5 / (2 * HALF)
    assert 0.0 < np.abs(many["mist"][inner] - one["mist"][inner]).max() < 0.1


@pytest.mark.parametrize("alpha", [0.3, 0.7])
def test_single_pass_through_a_sheet(alpha):
    """Below the Alpha Threshold (0.5) the sheet's first-sample indices and Position are
    overwritten by the floor's (our camera chain always passes a sheet: it continues
    specular lobes only, the sheet's diffuse light comes from the maps; Cycles' first
    sample stops there with its closure choice's probability: docs/compatibility.md)
    and the UV is the floor's; at or above it the sheet ends the single pass: its
    indices, Position and UV (0.25, 0.75)."""
    film = render(_scene(sheet_alpha=alpha, view=30.0), _settings(spp=4))
    d = film.data
    p = d["position"].reshape(-1, 3)
    if alpha >= 0.5:
        np.testing.assert_array_equal(d["object_index"], 4)
        np.testing.assert_array_equal(d["material_index"], 6)
        np.testing.assert_allclose(p[:, 2], 1.0, atol=1e-6)
        np.testing.assert_allclose(d["uv"], np.broadcast_to((0.25, 0.75, 1.0), (H, W, 3)),
                                   atol=1e-6)
    else:
        np.testing.assert_array_equal(d["object_index"], 7)
        np.testing.assert_array_equal(d["material_index"], 3)
        np.testing.assert_allclose(p[:, 2], 0.0, atol=1e-6)
        # (4 samples a pixel: their average stays within the pixel's 0.2 m at the floor.)
        np.testing.assert_allclose(d["uv"].reshape(-1, 3)[:, :2], p[:, :2] / (2 * HALF) + 0.5,
                                   atol=0.25 / (2 * HALF))
        np.testing.assert_allclose(d["uv"][..., 2], 1.0, rtol=1e-6)


@pytest.mark.parametrize("alpha", [0.3, 0.7])
def test_depth_is_the_first_samples_single_pass_surface(alpha):
    """Cycles writes Depth at sample 0 only, at the surface that ends the single pass
    (kernel/film/data_passes.h; 0, read as 1e10, where it met none): through a sheet
    below the Alpha Threshold the floor's depth (HEIGHT m along the view axis), at or
    above it the sheet's (1 m nearer); a pixel whose first sample missed the floor has
    none (inf) even where later samples hit it: pixel for pixel where the Object Index
    (sample 0's too) is not the floor's. It was the average over the samples' first hits
    (the sheet's depth at either alpha, and a rim pixel's any of whose samples hit)."""
    film = render(_scene(sheet_alpha=alpha, view=60.0),
                  _settings(spp=16, data_passes=("object_index",)))
    depth, index = film.depth, film.data["object_index"]
    if alpha >= 0.5:
        np.testing.assert_allclose(depth, HEIGHT - 1.0, rtol=1e-6)
        np.testing.assert_array_equal(index, 4)
        return
    floor = index == 7
    assert floor.any() and not floor.all()  # the plane's rim in view
    np.testing.assert_array_equal(np.isfinite(depth), floor)
    np.testing.assert_allclose(depth[floor], HEIGHT, rtol=1e-6)


def test_mist_through_a_sheet():
    """Mist adds (1 - m) x average(throughput x alpha) at every camera-chain surface:
    through a sheet of alpha a over the floor, 1 - [(1 - m_sheet) a + (1 - m_floor)(1 - a)]
    in expectation (the transparent pass is sampled: noise)."""
    a, mist = 0.4, (0.0, 10.0, 1.0)
    film = render(_scene(sheet_alpha=a, mist=mist, view=20.0), _settings(spp=64))
    # At the image centre: sheet 4 m away, floor 5 m.
    expect = 1.0 - ((1 - _mist(4.0, mist)) * a + (1 - _mist(5.0, mist)) * (1 - a))
    centre = film.data["mist"][H // 2 - 1:H // 2 + 1, W // 2 - 1:W // 2 + 1]
    assert abs(centre.mean() - expect) < 0.01, (centre.mean(), expect)


@pytest.mark.parametrize("extra", [{}, {"adaptive_threshold": 0.05,
                                        "adaptive_min_samples": 4}])
def test_image_bits_unchanged(extra):
    """The surface passes draw no number and change no path: the effect passes keep their
    bits (plain and adaptive sampling)."""
    s = _scene(sheet_alpha=0.5)
    a = render(s, _settings(spp=8, data_passes=(), **extra))
    b = render(s, _settings(spp=8, **extra))
    for name in EFFECTS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert set(b.data) == set(SURFACE)


def test_adaptive_and_progressive_keep_the_first_sample():
    """Adaptive rounds and progressive passes do not sum or average the first sample's
    passes: the same indices, Position in the plane; UV and Mist averaged as ever."""
    plain = render(_scene(), _settings(spp=8)).data
    adaptive = render(_scene(), _settings(spp=16, adaptive_threshold=0.05,
                                          adaptive_min_samples=4))
    progressive = render_progressive(_scene(), _settings(spp=4), Budget(passes=3))
    for film in (adaptive, progressive):
        # Depth is the first sample's as well: finite exactly where it met the floor.
        d = film.data
        np.testing.assert_array_equal(np.isfinite(film.depth), d["object_index"] == 7)
        np.testing.assert_allclose(film.depth[d["object_index"] == 7], HEIGHT, rtol=1e-6)
        assert set(d) == set(SURFACE)
        inner = (plain["object_index"] > 0) & (d["object_index"] > 0)
        assert inner.sum() > 0.5 * inner.size
        np.testing.assert_array_equal(d["object_index"][inner], 7)
        np.testing.assert_array_equal(d["material_index"][inner], 3)
        assert np.abs(d["position"][inner][:, 2]).max() < 1e-6
        assert np.all(np.abs(d["position"][inner][:, :2]) <= HALF + 1e-5)
        np.testing.assert_allclose(d["uv"][inner][:, 2], 1.0, rtol=1e-6)
        assert np.abs(d["mist"][inner] - plain["mist"][inner]).max() < 0.05


def test_scene_file_pass_index_and_mist(tmp_path):
    """The scene file's objects / materials take pass_index, [mist] Blender's start /
    depth / falloff (by name)."""
    from engine.scenefile import SceneFileError, load_scene
    text = """
[render]
width = 8
height = 6
[camera]
position = [0, 0, 5]
look_at = [0, 0, 0]
up = [0, 1, 0]
[materials.m]
base_color = [0.5, 0.5, 0.5]
pass_index = 12
[[objects]]
type = "plane"
name = "p"
material = "m"
size = 20
pass_index = 3
[[lights]]
type = "point"
position = [0, 0, 3]
power = 50
[mist]
start = 2
depth = 4
falloff = "LINEAR"
"""
    path = tmp_path / "s.toml"
    path.write_text(text)
    scene, _ = load_scene(str(path))
    assert scene.mist == (2.0, 4.0, 1.0)
    assert scene.materials["m"].pass_index == 12
    assert [m.pass_index for m in scene.meshes] == [3]
    film = render(scene, _settings())
    np.testing.assert_array_equal(film.data["object_index"], 3)
    np.testing.assert_array_equal(film.data["material_index"], 12)
    path.write_text(text.replace('"LINEAR"', '"CUBIC"'))
    with pytest.raises(SceneFileError, match="INVERSE_QUADRATIC"):
        load_scene(str(path))


def test_cli_writes_surface_passes(tmp_path):
    from engine.cli import main
    from engine.imageio import read_image
    out = tmp_path / "f6.png"
    assert main(["render", "scenes/figure6.toml", "-o", str(out), "--width", "16", "--height",
                 "12", "--spp", "1", "--photons", "2000", "--data-passes",
                 ",".join(SURFACE), "--save-passes", "--quiet"]) == 0
    images = {n: read_image(str(tmp_path / f"f6.{n}.exr")) for n in SURFACE}
    assert all(img.shape == (12, 16, 3) and np.isfinite(img).all() for img in images.values())
    mist = images["mist"][..., 0]
    assert (0.0 <= mist).all() and (mist <= 1.0).all()
    # The box's walls fill the view: every pixel sees a surface.
    assert (np.abs(images["position"]).sum(axis=2) > 0).all()


def test_memory_estimate_counts_surface_passes():
    from engine.resources import estimate_memory
    scene = _scene()
    settings = _settings()
    film = render(scene, settings)
    film_bytes = sum(a.nbytes for a in film.data.values())
    part = estimate_memory(scene, settings).parts["data passes"]
    assert 3 * film_bytes <= part <= 1.5 * 3 * film_bytes
