"""A lamp with a size whose Diffuse ray visibility is off (an artist's highlight-only lamp)
is light-sampled for the rough reflective lobes, its shadow rays MIS-weighted against the
glossy continuation (engine/integrator.py reflection_only_lights, lamp_mis), as Cycles
samples it for the closures SHADER_EXCLUDE_DIFFUSE leaves (lampvis51, issue 14;
docs/accuracy.md "lampvis51"). Before, only the continuation found it: the same mean at
~200x Cycles' pixel variance a sample.

Invariant: on a Principled floor the dielectric specular layer's reflection does not
depend on the base colour, so the floor of base 0.5 under the Diffuse-off lamp shows what
the floor of base 0 (no diffuse response) shows under the same lamp with every visibility
on: the same expectation, and with both light-sampled about the same noise."""
import numpy as np
import pytest

from engine import RenderSettings
from engine import integrator
from engine.api import PaperScene
from engine.render import render
from engine.scene import Light, Material

W, H = 32, 24
SEEDS = range(4)


def _scene(kind, base, visible_diffuse, specular=1.0, faint=0):
    """A Principled floor (roughness 0.3, base colour `base`) seen obliquely with the
    lamp's highlight in view, black world: an AREA lamp (0.5 m square, 60 W) or a POINT
    lamp of radius 0.1 m (60 W), 1.5 m above it, or a SUN of 5 degrees (3 W/m^2)."""
    s = PaperScene(W, H, background=(0.0, 0.0, 0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0,
                Material("floor", (base,) * 3, roughness=0.3, specular=specular), name="floor")
    if kind == "AREA":
        s.add_light(Light("lamp", "AREA", 60.0, position=(0.0, 1.0, 1.5), direction=(0, 0, -1),
                          size_x=0.5, size_y=0.5, visible_diffuse=visible_diffuse))
    elif kind == "POINT":
        s.add_light(Light("lamp", "POINT", 60.0, position=(0.0, 1.0, 1.5), radius=0.1,
                          visible_diffuse=visible_diffuse))
    else:
        # A sun of 5 degrees whose reflection in the floor is in view.
        d = np.array([0.0, -0.8, -0.35])
        s.add_light(Light("lamp", "SUN", 3.0, direction=tuple(d / np.linalg.norm(d)),
                          angle=np.radians(5.0), visible_diffuse=visible_diffuse))
    for i in range(faint):
        # Faint point lamps behind the view: with more than SAMPLE_ALL_UP_TO of them the
        # light tree picks the shadow rays' lights.
        s.add_light(Light(f"faint{i}", "POINT", 0.5, position=(-3.5 + 0.4 * i, 3.0, 2.0)))
    s.set_camera((0.0, -4.0, 2.0), (0.0, 1.0, 0.0), view_angle=40.0)
    return s


def _renders(scene, spp=16):
    """(seeds, H, W): the combined image's RGB mean a pixel at each seed of SEEDS."""
    out = []
    for seed in SEEDS:
        film = render(scene, RenderSettings(workers=1, spp=spp, seed=seed, photons=5_000,
                                            caustic_photons=2_000))
        out.append(np.asarray(film.combined, np.float64).mean(axis=2))
    return np.stack(out)


def _variance(imgs):
    """Pixel variance over the seeds, averaged over the pixels."""
    return float(imgs.var(axis=0, ddof=1).mean())


@pytest.mark.parametrize("kind", ["AREA", "POINT", "SUN"])
def test_a_diffuse_off_lamps_highlight_is_the_glossy_part_and_light_sampled(kind):
    """The floor of base 0.5 under the Diffuse-off lamp against the floor of base 0 under
    the lamp with every visibility on (seeds 0-3, 16 spp): sample for sample the same
    image (measured: equal to the bit; the shadow rays draw the same numbers, the diffuse
    lobe is cut from them, and the continuation's MIS weights are those of a lamp every
    ray sees). The continuation alone (REFLECTION_ONLY_SAMPLING off, the next test) is
    another estimator: mean 0.98, variance ~110x."""
    highlight = _renders(_scene(kind, 0.5, False))
    glossy = _renders(_scene(kind, 0.0, True))
    assert glossy.mean() > 0.01
    np.testing.assert_allclose(highlight, glossy, rtol=1e-6, atol=1e-9)


def test_without_the_shadow_rays_the_highlight_is_as_bright_but_noisy(monkeypatch):
    """The regression the test above catches: the continuation alone (the switch off)
    gives the same expectation (measured 0.979, seeds 0-3: its seeds' means spread ~4 %)
    at many times the variance (measured 113x)."""
    monkeypatch.setattr(integrator, "REFLECTION_ONLY_SAMPLING", False)
    highlight = _renders(_scene("AREA", 0.5, False))
    monkeypatch.setattr(integrator, "REFLECTION_ONLY_SAMPLING", True)
    sampled = _renders(_scene("AREA", 0.5, False))
    print("continuation / sampled: mean", highlight.mean() / sampled.mean(), "variance",
          _variance(highlight) / _variance(sampled))
    assert highlight.mean() / sampled.mean() == pytest.approx(1.0, abs=0.1)
    assert _variance(highlight) > 10.0 * _variance(sampled)


def test_a_diffuse_off_lamp_lights_no_diffuse_surface():
    """A Lambert floor (specular 0) under the Diffuse-off lamp: black, shadow rays and
    photons alike (photons.py: the lamp's first segment is no shadow or diffuse ray),
    though its shadow rays are now traced for the reflective lobes."""
    film = render(_scene("AREA", 0.5, False, specular=0.0),
                  RenderSettings(workers=1, spp=4, seed=0, photons=5_000,
                                 caustic_photons=2_000))
    assert float(np.asarray(film.combined).max()) == 0.0


@pytest.mark.parametrize("kind", ["POINT0", "POINT"])
def test_a_diffuse_off_lamp_beside_the_light_tree(kind):
    """With 17 faint lamps the light tree picks the shadow rays' lights; a lamp whose
    Diffuse visibility is off is none of its members and takes shadow rays of its own
    (integrator.glossy_only_lights). Before, a delta one (POINT0: radius 0) gave no
    highlight at all there (the image read the faint lamps' alone, 0.0051 against
    0.0210), one with a size (POINT: radius 0.1) the continuation's alone. The image
    with the tree less the faint lamps' image equals the lamp's own highlight (no tree)
    within 2 % (measured 1.000 and 0.997, seeds 0-3 at 16 spp)."""
    import engine.lights.selection as selection
    assert 17 > selection.SAMPLE_ALL_UP_TO
    radius_zero = kind == "POINT0"

    def scene(faint, with_lamp=True):
        s = _scene("POINT", 0.5, False, faint=faint)
        if radius_zero:
            s.lights[0].radius = 0.0
        if not with_lamp:
            s.lights = s.lights[1:]
        return s

    both = _renders(scene(17)).mean()
    faint = _renders(scene(17, with_lamp=False)).mean()
    alone = _renders(scene(0)).mean()
    print(kind, "tree + lamp", both, "tree", faint, "lamp alone", alone)
    assert alone > 0.01
    assert (both - faint) / alone == pytest.approx(1.0, abs=0.02), (both, faint, alone)
