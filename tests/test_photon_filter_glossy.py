"""Filter Glossy on the photons' scatters past a diffuse bounce (photonkernels._scatter's
gather_fg; docs/accuracy.md "### photonblur49").

Cycles blurs every microfacet lobe its path meets after a diffuse bounce, keeping the
weights of the unblurred roughness, so in a closed box of a glossy Principled each deeper
bounce returns less light: bench/roomglossy49_box.py measured Cycles' per-bounce albedo
of Base Color 0.8, roughness 0.1 at 0.818 at Filter Glossy 0 and 0.768 at Filter Glossy 1
(docs/accuracy.md "### roomglossy49"). The global map's photons are read past the
camera's diffuse bounce, so theirs must fall the same way."""
import numpy as np
import pytest

from engine import RenderSettings
from engine import photonkernels as pk
from engine import photons as photons_module
from engine.api import PaperScene
from engine.scene import Material

from test_energy import shoot

# Cycles' per-bounce albedo of the roughness-0.1 box (roomglossy49's geometric-series fit).
CYCLES_RHO = {0.0: 0.818, 1.0: 0.768}


def _glossy_box():
    """roomglossy49's box: a closed 2 m cube of Principled Base Color 0.8, roughness 0.1,
    Blender's specular layer (IOR 1.5, level 0.5), a point light inside."""
    s = PaperScene(width=32, height=24)
    s.add_material(Material("wall", (0.8,) * 3, roughness=0.1, specular=1.0))
    s.add_box((0, 0, 1), (2, 2, 2), "wall", name="room")
    s.add_point_light((0.3, 0.2, 1.5), power=100.0)
    s.set_camera((-0.6, -0.7, 0.7), (0, 0, 1), view_angle=90)
    return s


def _shoot(fg):
    deep = dict(max_bounces=64, diffuse_bounces=64, glossy_bounces=64,
                transmission_bounces=64)
    return shoot(_glossy_box(), RenderSettings(photons=20_000, max_photon_depth=40,
                                               cycles_filter_glossy=fg, **deep))


def _per_bounce_albedo(ph, lo=3, hi=12):
    """The stored power's ratio per scatter (a geometric fit over total scatter counts
    lo..hi: a few bounces in, the box's light is near uniform)."""
    total = ph.bounces[:, 0].astype(np.int64)
    p = np.array([ph.power[total == k, 0].astype(np.float64).sum()
                  for k in range(lo, hi + 1)])
    assert np.all(p > 0.0)
    return (p[-1] / p[0]) ** (1.0 / (hi - lo))


@pytest.mark.parametrize("fg", [0.0, 1.0])
def test_glossy_box_loses_cycles_light_per_bounce(fg):
    rho = _per_bounce_albedo(_shoot(fg))
    assert abs(rho - CYCLES_RHO[fg]) < 0.012, (fg, rho)


def test_only_photons_past_a_diffuse_bounce_blur(monkeypatch):
    """The photons stored before any scatter (direct) and those whose path had no diffuse
    bounce before their store (L S+ D: the caustic map's, blurred from the camera side by
    the Filter Glossy split) are those of Filter Glossy 0, bit for bit, at a tiny Filter
    Glossy (blur_alpha 0: nothing raised) and with the switch off; blurred photons differ."""
    a = _shoot(0.0)
    b = _shoot(1.0)
    for kind in (pk.DIRECT, pk.CAUSTIC):
        sa, sb = a.kind == kind, b.kind == kind
        assert sa.sum() > 100
        np.testing.assert_array_equal(a.power[sa], b.power[sb])
        np.testing.assert_array_equal(a.position[sa], b.position[sb])
    deep_a = a.power[(a.kind == pk.INDIRECT) & (a.bounces[:, 0] >= 3)]
    deep_b = b.power[(b.kind == pk.INDIRECT) & (b.bounces[:, 0] >= 3)]
    assert deep_b.astype(np.float64).sum() < 0.95 * deep_a.astype(np.float64).sum()
    monkeypatch.setattr(photons_module, "BLUR_GATHER_PHOTONS", False)
    c = _shoot(1.0)
    np.testing.assert_array_equal(a.power, c.power)
    np.testing.assert_array_equal(a.position, c.position)
