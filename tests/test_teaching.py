"""Teaching mode: the methods differ as they must, and the labelled grids, ladders and
strips have the right tiles (engine/teaching.py, engine/cli.py compare / sweep)."""
import os

import numpy as np
import pytest

from engine import teaching
from engine.api import PaperScene
from engine.cli import main
from engine.imageio import to_8bit
from engine.integrator import camera_rays
from engine.render import render
from engine.scenefile import load_scene
from engine.settings import RenderSettings
from helpers import ROOT

FIGURE3 = os.path.join(ROOT, "scenes", "figure3.toml")
FAST = dict(spp=4, photons=20_000, caustic_photons=10_000, workers=2, seed=3)


def figure3(width=64, height=48, sphere=True):
    scene, _ = load_scene(FIGURE3)
    scene.width, scene.height = width, height
    if not sphere:
        scene.meshes = [m for m in scene.meshes if m.name != "ball"]
    return scene


def figure7(width=64, height=48):
    """The paper's Figure 7 room (example_blends/make_blends.py): a 4 m box, a tall
    blocker left of a downward disk light under the ceiling. The ceiling gets no direct
    light: the light is one-sided, facing the floor."""
    s = PaperScene(width=width, height=height)
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "white_diffuse", name="floor")
    s.add_plane((0, 0, 4), (0, 0, -1), 4.0, "white_diffuse", name="ceiling")
    s.add_plane((0, 2, 2), (0, -1, 0), 4.0, "white_diffuse", name="back")
    s.add_plane((-2, 0, 2), (1, 0, 0), 4.0, "white_diffuse", name="left")
    s.add_plane((2, 0, 2), (-1, 0, 0), 4.0, "white_diffuse", name="right")
    s.add_box((-0.3, 0.2, 1.5), (0.1, 2.6, 3.0), "white_diffuse", name="blocker")
    s.add_rect_area_light((0.9, 0.0, 3.0), (0.6, 0.6), power=60.0, disk=True, name="light")
    s.set_camera((0, -7.6, 2.0), (0, 0, 1.8), (0, 0, 1), view_angle=38.0)
    return s


def world_points(scene, film):
    """(H, W, 3) world position of each pixel centre's first hit (from the depth pass)."""
    cam = scene.camera
    h, w = scene.height, scene.width
    py, px = np.mgrid[0:h, 0:w]
    px, py = px.ravel().astype(float), py.ravel().astype(float)
    o, d, _ = camera_rays(cam, np.zeros(3), w, h, px, py, np.full(len(px), 0.5),
                          np.full(len(px), 0.5))
    forward = -cam.rotation[:, 2]
    t = film.depth.ravel() / (d @ forward)
    return (cam.position + d * t[:, None]).reshape(h, w, 3)


def test_local_casts_no_shadow_raytrace_does():
    """Figure 3: the floor under the sphere is as bright with the sphere as without it in
    local illumination; ray tracing darkens it (the shadow)."""
    settings = dict(FAST, spp=8)
    with_ball = figure3()
    films = {m: render(with_ball, RenderSettings(method=m, **settings))
             for m in ("local", "raytrace")}
    bare = render(figure3(sphere=False), RenderSettings(method="local", **settings))
    depth_a = np.nan_to_num(films["local"].depth, posinf=-1.0)
    depth_b = np.nan_to_num(bare.depth, posinf=-2.0)
    floor = (films["local"].normal[..., 2] > 0.99) & (bare.normal[..., 2] > 0.99) & (
        np.abs(depth_a - depth_b) < 1e-3)
    lum = {k: f.direct.mean(axis=2) for k, f in films.items()}
    lum_bare = bare.direct.mean(axis=2)
    shadow = floor & (lum["raytrace"] < 0.5 * lum_bare)
    assert shadow.sum() >= 20  # ray tracing: a shadow on the floor
    ratio = lum["local"][shadow].mean() / lum_bare[shadow].mean()
    assert abs(ratio - 1.0) < 0.03, ratio  # local: none
    assert lum["raytrace"][shadow].mean() < 0.3 * lum_bare[shadow].mean()


def test_ceiling_above_the_blocker_black_in_raytrace_lit_in_photon():
    scene = figure7()
    films = {m: render(scene, RenderSettings(method=m, **FAST)) for m in ("raytrace", "photon")}
    f = films["photon"]
    p = world_points(scene, f)
    ceiling = (f.normal[..., 2] < -0.99) & (np.abs(p[..., 0] + 0.3) < 0.5) & (p[..., 2] > 3.9)
    assert ceiling.sum() >= 10
    ray = films["raytrace"].combined[ceiling].mean()
    lit = f.combined[ceiling].mean()
    assert ray == 0.0  # no direct light reaches it, and ray tracing has no indirect light
    assert lit > 0.01, lit
    # Indirect light is what lights it.
    assert f.indirect[ceiling].mean() > 0.9 * lit


def test_methods_reported_and_validated(tmp_path):
    s = figure3(32, 24)
    film = render(s, RenderSettings(method="local", spp=1, workers=1))
    report = "\n".join(film.stats["effects"])
    assert film.stats["effects"][0].startswith("method: local - local illumination")
    assert "soft shadows 'area': off - method 'local' has no shadows" in report
    assert "photon mapping: off" in report
    assert "specular reflection / refraction: off - method 'local'" in report
    assert "shadow rays: off - method 'local'" in report
    assert not film.caustic.any() and not film.indirect.any() and not film.specular.any()
    with pytest.raises(ValueError, match="'method' must be one of local, raytrace, photon"):
        RenderSettings(method="opengl")
    assert RenderSettings(method="RayTrace").method == "raytrace"
    # The scene file takes it in [render].
    text = open(FIGURE3).read().replace("[render]", '[render]\nmethod = "raytrace"')
    path = tmp_path / "f3.toml"
    path.write_text(text)
    _, overrides = load_scene(str(path))
    assert overrides["method"] == "raytrace"
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('"raytrace"', '"gl"'))
    with pytest.raises(ValueError, match="method"):
        load_scene(str(bad))


def test_api_method_keyword():
    s = figure3(32, 24)
    film = s.render(method="raytrace", spp=1, workers=1)
    assert film.stats["effects"][0].startswith("method: raytrace - ray tracing (paper Fig. 5b)")
    plain = s.render(photon_mapping=False, spp=1, workers=1)
    assert not any(line.startswith("method:") for line in plain.stats["effects"])
    full = s.render(photons=1000, caustic_photons=0, spp=1, workers=1)
    assert full.stats["effects"][0].startswith("method: photon - photon mapping")


def _check_grid(img, tiles, columns):
    """Tiles where compose() puts them, each exactly its sRGB image; the label band
    below each holds text (white pixels) that the render does not have there."""
    h, w = tiles[0].image.shape[:2]
    rows = -(-len(tiles) // columns)
    band = (img.shape[0] + teaching.GAP) // rows - teaching.GAP - h
    assert band > 10
    assert img.shape == (rows * (h + band + teaching.GAP) - teaching.GAP,
                         columns * (w + teaching.GAP) - teaching.GAP, 3)
    for t, (x, y, tw, th) in zip(tiles, teaching.tile_boxes((h, w), len(tiles), columns, band)):
        np.testing.assert_array_equal(img[y:y + th, x:x + tw], to_8bit(t.image))
        label = img[y + th:y + th + band, x:x + tw]
        assert (label.max(axis=2) > 64).sum() > 30  # text pixels (antialiased)
        assert label.max() > 200
        assert label.min() == 0  # on black
    return band


def test_compare_grid_has_four_labelled_tiles():
    scene = teaching.preview_scene(figure3(320, 240), 64)
    assert (scene.width, scene.height) == (64, 48)
    tiles = teaching.compare_methods(scene, RenderSettings(**FAST))
    assert [t.lines[0] for t in tiles] == ["Local illumination", "Ray tracing",
                                          "Photon mapping", "Photon hits"]
    assert "0 photons" in tiles[0].lines[1] and "0 photons" in tiles[1].lines[1]
    assert "30,000 photons" in tiles[2].lines[1]
    assert tiles[2].lines[2] == "brightness: the reference"
    ref = teaching.displayed_brightness(tiles[2].image)
    d = (teaching.displayed_brightness(tiles[1].image) - ref) / ref
    assert tiles[1].lines[2] == f"brightness {100 * d:+.0f} % vs photon"
    assert d < 0  # ray tracing misses the indirect light
    assert tiles[3].image.any()  # the photon hits are drawn
    img = teaching.compose(tiles, columns=2)
    _check_grid(img, tiles, 2)


def test_the_series_progress_never_goes_back():
    """A sweep's progress is the fraction of the whole series: it rises through each
    render's photon, map and pixel stages and through the tiles, never back (each
    stage's own fraction was sent as the render's: polish38)."""
    seen = []
    settings = RenderSettings(**{**FAST, "chunk_size": 512})
    teaching.sweep(teaching.preview_scene(figure3(320, 240), 64), settings,
                   {"photons": [2_000, 8_000]},
                   progress=lambda stage, fraction, text: seen.append(fraction))
    assert len(seen) > 6 and seen == sorted(seen), seen
    assert 0.0 <= seen[0] < 0.5 and seen[-1] == pytest.approx(1.0)


def box(width=48, height=36):
    from engine.api import cornell_box
    return cornell_box(width, height, glass_sphere=False)


def test_sweep_error_falls_as_photons_rise():
    settings = RenderSettings(spp=2, final_gather=False, estimator="classic", radius=0.3,
                              caustics="off", workers=2, seed=1)
    tiles = teaching.sweep(box(), settings, {"photons": [500, 4_000, 32_000, 256_000]})
    errors = [t.error for t in tiles[:-1]]
    assert tiles[-1].error is None and tiles[-1].lines[2] == "reference (finest)"
    assert errors[0] > errors[1] > errors[2], errors
    assert errors[0] > 4 * errors[2]
    for t, n in zip(tiles, (500, 4_000, 32_000, 256_000)):
        assert t.lines[0] == f"{n:,} photons"
        assert t.lines[1].endswith(" s")
    img = teaching.compose(tiles)
    _check_grid(img, tiles, 4)
    # Against a reference image: every tile gets an error, the finest too.
    tiles2 = teaching.sweep(box(), settings, {"photons": [500, 256_000]},
                            reference=tiles[-1].image)
    assert tiles2[1].error == 0.0 and tiles2[0].error == pytest.approx(errors[0])


def test_sweep_arguments_refused_with_names():
    with pytest.raises(ValueError, match="NAME one of photons, radius, k"):
        teaching.parse_param("photon=1,2")
    with pytest.raises(ValueError, match="'x' is not a whole number"):
        teaching.parse_param("photons=10,x")
    assert teaching.parse_param("MaxRayPerLightSrc=1000,2000") == ("photons", [1000, 2000])
    assert teaching.parse_param("radius=0.5, 0.25") == ("radius", [0.5, 0.25])
    s = RenderSettings(spp=1)
    with pytest.raises(ValueError, match="same number of values"):
        teaching.sweep(box(8, 6), s, {"photons": [1, 2], "radius": [0.1]})
    with pytest.raises(ValueError, match="'k_nearest' must be >= 1"):
        teaching.sweep(box(8, 6), s, {"k": [0]})
    with pytest.raises(ValueError, match="reference image is 4x4"):
        teaching.sweep(box(8, 6), s, {"spp": [1]}, reference=np.zeros((4, 4, 3)))


def test_paper_ladder_preset():
    preset = teaching.SWEEP_PRESETS["paper-ladder"]
    assert preset["params"]["photons"] == [1_000, 10_000, 100_000, 200_000]
    np.testing.assert_allclose(preset["params"]["radius"], [0.8, 0.4, 0.2, 0.08])
    assert preset["settings"] == dict(estimator="classic", final_gather=False)


def test_effects_strip_sums():
    film = render(figure3(48, 36), RenderSettings(**FAST))
    tiles = teaching.effects_strip(film)
    assert [t.lines[0] for t in tiles] == ["Direct", "Indirect", "Caustic", "Specular",
                                          "Emission", "Sum (the image)"]
    np.testing.assert_allclose(sum(t.image for t in tiles[:5]), tiles[5].image, atol=1e-5)
    shares = [float(t.lines[1].split(" %")[0]) for t in tiles[:5]]
    assert abs(sum(shares) - 100) <= 3
    _check_grid(teaching.compose(tiles, columns=6), tiles, 6)


def test_compose_refuses_mixed_sizes():
    a = teaching.Tile(np.zeros((4, 4, 3)), ["a"])
    b = teaching.Tile(np.zeros((4, 5, 3)), ["b"])
    with pytest.raises(ValueError, match="tiles differ in size"):
        teaching.compose([a, b])


def test_cli_compare_sweep_strip(tmp_path, capsys):
    from PIL import Image
    out = tmp_path / "grid.png"
    common = ["--preview-size", "48", "--spp", "2", "--photons", "5000", "--caustic-photons",
              "2000", "--workers", "2", "--quiet"]
    assert main(["compare", FIGURE3, "-o", str(out)] + common) == 0
    img = np.asarray(Image.open(out))
    assert img.shape[1] == 4 * 48 + 3 * teaching.GAP and img.shape[2] == 3
    ladder = tmp_path / "ladder.png"
    assert main(["sweep", FIGURE3, "-o", str(ladder), "--param", "spp=1,2,4"] + common) == 0
    assert np.asarray(Image.open(ladder)).shape[1] == 3 * 48 + 2 * teaching.GAP
    assert main(["sweep", FIGURE3, "-o", str(ladder), "--param", "depth=1,2"] + common) == 1
    assert "NAME one of photons" in capsys.readouterr().err
    assert main(["sweep", FIGURE3, "-o", str(ladder)] + common) == 1
    assert "--preset paper-ladder" in capsys.readouterr().err
    assert main(["compare", FIGURE3, "-o", str(tmp_path / "g.exr")] + common) == 1
    assert "for a labelled image" in capsys.readouterr().err
    render_out = tmp_path / "r.png"
    assert main(["render", FIGURE3, "-o", str(render_out), "--width", "32", "--height", "24",
                 "--spp", "1", "--method", "local", "--strip", "--quiet"]) == 0
    strip = np.asarray(Image.open(tmp_path / "r.strip.png"))
    # Six cells: 32-pixel tiles, widened where a label word is wider (never clipped).
    cell = (strip.shape[1] + teaching.GAP) // 6 - teaching.GAP
    assert strip.shape[1] == 6 * cell + 5 * teaching.GAP and cell >= 32


def _measure(text, size):
    from PIL import ImageFont
    return ImageFont.load_default(size=size).getlength(text)


@pytest.mark.parametrize("tile", [24, 32, 48, 64, 96])
def test_labels_are_never_clipped_at_small_preview_sizes(tile):
    """The compare / sweep / strip labels at small --preview-size (64 clipped 'Local
    illumination' and 'brightness -35 % vs photon'): the text shrinks, then wraps, then
    the cell widens; every label's text ends inside its band, with its margin."""
    labels = [["Local illumination", "0.4 s, 0 photons", "brightness -35 % vs photon"],
              ["Photon mapping", "1.2 s, 30,000 photons", "brightness: the reference"],
              ["Photon hits", "12,345 hits stored", "from 30,000 photons"],
              ["1,000 photons, r 0.8 m", "0.3 s", "relMSE 0.1234"],
              ["Sum (the image)", "MaxPhotonSearchRadius"]]  # one word wider than a tile
    for lines in labels:
        fitted, size, width = teaching.fit_label(lines, tile, teaching.label_font_size(tile),
                                                 _measure)
        assert width >= tile and size >= teaching.MIN_FONT
        assert " ".join(fitted).split() == " ".join(lines).split()  # every word, in order
        for line in fitted:
            assert _measure(line, size) + 2 * teaching.LABEL_PAD <= width, (line, width)
        mask = teaching.pillow_label_mask(lines, tile, teaching.label_font_size(tile))
        assert mask.shape[1] == width
        ink = np.flatnonzero(mask.max(axis=0) > 0.05)
        assert ink.size and ink[-1] < width - 1, (lines, tile)  # a blank right margin
    tiles = [teaching.Tile(np.full((tile * 3 // 4, tile, 3), 0.2, np.float32), lines)
             for lines in labels]
    img = teaching.compose(tiles, columns=len(tiles))
    cell = (img.shape[1] + teaching.GAP) // len(tiles) - teaching.GAP
    h = tiles[0].image.shape[0]
    for i, (x, y, w, th) in enumerate(teaching.tile_boxes((h, tile), len(tiles), len(tiles),
                                                         img.shape[0] - h, cell)):
        np.testing.assert_array_equal(img[y:y + th, x:x + w], to_8bit(tiles[i].image))
        x0 = i * (cell + teaching.GAP)
        band = img[y + th:, x0:x0 + cell].max(axis=2)
        ink = np.flatnonzero(band.max(axis=0) > 12)
        assert ink.size and ink[-1] < cell - 1, (i, tile)  # the text ends inside its cell


def test_one_glint_does_not_set_the_brightness_label():
    """The compare grid's label compares what the tiles show: a pixel of radiance 4,600
    (a lamp seen in a polished ring) no longer makes alike tiles read -33 % (newuser42)."""
    img = np.full((20, 20, 3), 0.4)
    ref = img.copy()
    ref[3, 4] = 4600.0
    assert abs(teaching.brightness_difference(img, ref)) < 0.01
    assert teaching.brightness_difference(img * 0.5, ref) < -0.45
