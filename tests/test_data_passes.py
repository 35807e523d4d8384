"""Cycles' data passes in the engine (engine/datapasses.py, RenderSettings.data_passes):
analytic values on a Lambert plane seen from straight above (albedo = the base colour,
Denoising Depth = the camera distance along each ray, the normal in camera space),
Cycles' 25 % rule and its colour passes through a half-transparent sheet, the same
passes from the adaptive and progressive paths, and the image's bits untouched by them.
The comparison against live Cycles is tests/blender/test_blender_data_passes.py."""
import numpy as np
import pytest

from engine import Budget, RenderSettings, render_progressive
from engine.api import PaperScene
from engine.render import render
from engine.scene import Material

W, H = 12, 9
BASE = (0.6, 0.3, 0.1)
UNDER = (0.2, 0.5, 0.9)
HEIGHT = 5.0
EFFECTS = ("direct", "indirect", "caustic", "specular", "emission")


def _plane_scene(sheet_alpha=None):
    """A Lambert plane (BASE) filling the view of a camera HEIGHT m above it looking
    straight down; with sheet_alpha, a Lambert sheet (UNDER) 1 m above it of that alpha."""
    s = PaperScene(W, H, background=(0.2, 0.2, 0.2))
    top = Material("top", BASE)
    s.add_plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 40.0, top, name="floor")
    if sheet_alpha is not None:
        sheet = Material("sheet", UNDER, alpha=sheet_alpha)
        s.add_plane((0.0, 0.0, 1.0), (0.0, 0.0, 1.0), 40.0, sheet, name="sheet")
    s.add_point_light((1.0, 1.0, 3.0), power=100.0)
    s.set_camera((0.0, 0.0, HEIGHT), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), view_angle=30.0)
    return s


def _settings(**kw):
    base = dict(workers=1, spp=8, seed=3, photons=2_000, caustic_photons=200)
    base.update(kw)
    return RenderSettings(**base)


def test_plane_values():
    film = render(_plane_scene(), _settings(data_passes=("denoising", "color")))
    d = film.data
    assert set(d) == {"denoising_normal", "denoising_albedo", "denoising_depth",
                      "diffuse_color", "glossy_color", "transmission_color"}
    np.testing.assert_allclose(d["denoising_albedo"], np.broadcast_to(BASE, (H, W, 3)),
                               rtol=1e-6)
    np.testing.assert_allclose(d["diffuse_color"], np.broadcast_to(BASE, (H, W, 3)),
                               rtol=1e-6)
    assert not d["glossy_color"].any() and not d["transmission_color"].any()
    # Facing the camera: (0, 0, -1) in Cycles' camera space (z forward).
    np.testing.assert_allclose(d["denoising_normal"],
                               np.broadcast_to((0.0, 0.0, -1.0), (H, W, 3)), atol=1e-6)
    # Depth along the ray (not the z depth): HEIGHT / cos of the ray's angle to the axis,
    # between HEIGHT at the centre and HEIGHT / cos(the corner's half diagonal).
    depth = d["denoising_depth"]
    assert depth.shape == (H, W)
    assert HEIGHT <= depth.min() and depth.max() < HEIGHT / np.cos(np.radians(20.0))
    assert depth[H // 2, W // 2] < HEIGHT * 1.002
    np.testing.assert_allclose(depth, depth[:, ::-1], rtol=2e-3)  # symmetric


def test_half_transparent_sheet():
    """alpha 0.5: the sheet's closures are half diffuse (non-specular), half the
    transparent pass, so Cycles writes its features there (more than 25 % non-specular):
    Denoising Albedo = 0.5 x UNDER, exactly. The colour passes follow the transparent
    chain: 0.5 UNDER + 0.5 BASE in expectation (the pass is sampled: noise)."""
    film = render(_plane_scene(0.5), _settings(spp=64, data_passes=("denoising", "color")))
    d = film.data
    np.testing.assert_allclose(d["denoising_albedo"],
                               np.broadcast_to(0.5 * np.array(UNDER), (H, W, 3)), rtol=1e-6)
    mean = d["diffuse_color"].reshape(-1, 3).mean(axis=0)
    np.testing.assert_allclose(mean, 0.5 * np.array(UNDER) + 0.5 * np.array(BASE),
                               rtol=0.03)


@pytest.mark.parametrize("extra", [{}, {"adaptive_threshold": 0.05,
                                        "adaptive_min_samples": 4}])
def test_image_bits_unchanged(extra):
    """The data passes draw no number and change no path: the effect passes keep their
    bits (plain and adaptive sampling), and the adaptive film carries the passes too."""
    s = _plane_scene(0.5)
    a = render(s, _settings(**extra))
    b = render(s, _settings(data_passes=("denoising", "color"), **extra))
    for name in EFFECTS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert not a.data
    np.testing.assert_allclose(b.data["denoising_albedo"],
                               np.broadcast_to(0.5 * np.array(UNDER), (H, W, 3)), rtol=1e-6)


def test_progressive_averages_passes():
    film = render_progressive(_plane_scene(), _settings(data_passes=("denoising",)),
                              Budget(passes=2))
    assert set(film.data) == {"denoising_normal", "denoising_albedo", "denoising_depth"}
    np.testing.assert_allclose(film.data["denoising_albedo"],
                               np.broadcast_to(BASE, (H, W, 3)), rtol=1e-6)


def test_settings_refuse_unknown_pass():
    assert RenderSettings(data_passes="Color").data_passes == ("color",)
    with pytest.raises(ValueError, match="data_passes"):
        RenderSettings(data_passes=("shadow",))


def test_cli_writes_data_passes_as_exr(tmp_path, capsys):
    """`photonmap render --data-passes denoising,color --save-passes` writes each data pass
    as linear OpenEXR beside the image: unit camera-space normals, depths inside the box,
    albedos of the box's Lambert walls (non-negative; through the glass ball a sample's
    path throughput can pass 1, its expectation cannot)."""
    from engine.cli import main
    from engine.imageio import read_image
    out = tmp_path / "f6.png"
    assert main(["render", "scenes/figure6.toml", "-o", str(out), "--width", "16", "--height",
                 "12", "--spp", "2", "--photons", "3000", "--data-passes", "denoising,color",
                 "--save-passes", "--quiet"]) == 0
    names = ("denoising_normal", "denoising_albedo", "denoising_depth", "diffuse_color",
             "glossy_color", "transmission_color")
    images = {n: read_image(str(tmp_path / f"f6.{n}.exr")) for n in names}
    assert all(img.shape == (12, 16, 3) and np.isfinite(img).all() for img in images.values())
    length = np.linalg.norm(images["denoising_normal"], axis=2)
    assert np.median(length) == pytest.approx(1.0, abs=0.05)
    depth = images["denoising_depth"][..., 0]
    assert (depth > 0).all() and np.allclose(depth, images["denoising_depth"][..., 2])
    for n in ("denoising_albedo", "diffuse_color"):
        assert 0.0 <= images[n].min() and 0.1 < images[n].mean() < 1.0
    # Without --data-passes nothing of the kind is written.
    assert main(["render", "scenes/figure6.toml", "-o", str(tmp_path / "g.png"), "--width", "8",
                 "--height", "6", "--spp", "1", "--photons", "1000", "--save-passes",
                 "--quiet"]) == 0
    assert not list(tmp_path.glob("g.*.exr"))


def test_cli_refuses_unknown_data_pass(capsys):
    from engine.cli import main
    with pytest.raises(SystemExit):
        main(["render", "scenes/figure6.toml", "-o", "x.png", "--data-passes", "albedo"])
    err = capsys.readouterr().err
    assert "--data-passes" in err and "'albedo'" in err


def test_memory_estimate_counts_data_passes():
    """The estimate's 'data passes' part holds at least the buffers a render makes: the
    Film's float32 passes and the accumulator's float64 sums of each channel."""
    from engine.resources import estimate_memory
    scene = _plane_scene()
    settings = _settings(data_passes=("denoising", "color"))
    film = render(scene, settings)
    film_bytes = sum(a.nbytes for a in film.data.values())
    sums = 2 * film_bytes  # float64 against float32, channel for channel
    part = estimate_memory(scene, settings).parts["data passes"]
    assert film_bytes + sums <= part <= 1.5 * (film_bytes + sums)
    assert "data passes" not in estimate_memory(scene, _settings()).parts
    assert estimate_memory(scene, settings, in_blender=True).parts["data passes"] > part


def test_memory_estimate_counts_the_clamped_gather_rays(monkeypatch):
    """Clamp Indirect per gather ray (integrator.CLAMP_PER_GATHER_RAY) keeps each
    final-gather ray's light apart until it is clamped (integrator.gather_indirect:
    (G, n, 3) float64, twice with Filter Glossy's chains): the estimate counts it, growing
    with Gather Rays, and not without the clamp or with the switch off."""
    from engine import integrator
    from engine.parallel import chunk_length
    from engine.resources import estimate_memory
    scene = _plane_scene()
    monkeypatch.setattr(integrator, "CLAMP_PER_GATHER_RAY", False)
    assert "clamped gather rays" not in estimate_memory(
        scene, _settings(clamp_indirect=10.0)).parts
    monkeypatch.setattr(integrator, "CLAMP_PER_GATHER_RAY", True)
    assert "clamped gather rays" not in estimate_memory(scene, _settings()).parts
    few = estimate_memory(scene, _settings(clamp_indirect=10.0, gather_rays=2))
    many = estimate_memory(scene, _settings(clamp_indirect=10.0, gather_rays=64))
    samples = scene.width * scene.height * _settings().spp
    chunk = chunk_length(samples, _settings().chunk_size)
    assert few.parts["clamped gather rays"] >= chunk * 2 * 24
    assert many.parts["clamped gather rays"] == 32 * few.parts["clamped gather rays"]
    assert many.total > few.total

