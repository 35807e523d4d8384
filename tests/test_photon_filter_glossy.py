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


def _ggx_albedo_at_normal_view(alpha, n=200_000):
    """A GGX metal's directional albedo seen along its normal (Fresnel 1: a white metal's
    F82 tint), by quadrature: visible normals at normal incidence are D(h) cos(theta_h),
    the reflected direction leaves at 2 theta_h, weighted by Smith's G1 there (G2 / G1 of
    the height-correlated form, Lambda 0 for the view); 0 below the horizon (Heitz 2014)."""
    th = (np.arange(n) + 0.5) * (0.5 * np.pi / n)
    t2 = np.tan(th) ** 2
    a2 = alpha * alpha
    dens = a2 / (np.pi * np.cos(th) ** 4 * (a2 + t2) ** 2) * np.cos(th) * np.sin(th) \
        * 2.0 * np.pi * (0.5 * np.pi / n)
    ti = 2.0 * th
    up = ti < 0.5 * np.pi
    g1 = np.zeros(n)
    lam = 0.5 * (np.sqrt(1.0 + a2 * np.tan(ti[up]) ** 2) - 1.0)
    g1[up] = 1.0 / (1.0 + lam)
    return float((dens * g1).sum() / dens.sum())


def _metal_patch_room():
    """A closed 2 m room of Lambert walls (0.8), on its floor a 0.3 m patch of white GGX
    metal (roughness 0.1), which a narrow spot light straight above lights alone: every
    photon's first scatter is the metal's reflection, before any diffuse bounce."""
    s = PaperScene(width=16, height=12)
    s.add_material(Material("wall", (0.8,) * 3, specular=0.0))
    s.add_material(Material("metal", (1.0,) * 3, roughness=0.1, metallic=1.0))
    s.add_box((0, 0, 1), (2, 2, 2), "wall", name="room")
    s.add_plane((0, 0, 0.001), size=0.3, material="metal", name="patch")
    s.add_spot_light((0, 0, 1.9), (0, 0, 0), power=100.0, spot_size_degrees=4.0, blend=0.0)
    s.set_camera((-0.6, -0.7, 0.7), (0, 0, 0), view_angle=90)
    return s


def _metal_patch_ratio(fg, photons=50_000):
    """The light one diffuse bounce past the metal's caustic over the caustic map's: the
    CAUSTIC_DIFFUSE photons (L S D: read past the camera's diffuse bounce) stored after two
    scatters (metal, wall) over the CAUSTIC ones stored after one (the metal)."""
    ph = shoot(_metal_patch_room(), RenderSettings(photons=photons, max_photon_depth=3,
                                                   cycles_filter_glossy=fg))
    total = ph.bounces[:, 0]
    ind = ph.power[(ph.kind == pk.CAUSTIC_DIFFUSE) & (total == 2), 0].astype(np.float64).sum()
    cau = ph.power[(ph.kind == pk.CAUSTIC) & (total == 1), 0].astype(np.float64).sum()
    assert cau > 0.0
    return ind / cau, ph


def test_pre_diffuse_scatter_blurs_for_the_gather_map_alone(monkeypatch):
    """photonblur50: a photon's non-diffuse scatter before its first diffuse bounce is read
    past the camera's diffuse bounce (where Cycles blurs it) by its later CAUSTIC_DIFFUSE /
    INDIRECT stores, but at the camera's first hit by its CAUSTIC ones. Split into
    an unblurred copy for the caustic map and a blurred one for the others, the metal's
    light reaches the gather map with the albedo of the blurred lobe (Filter Glossy 1:
    alpha blur_alpha(1, (2/3)/pi) = 0.444; roughness 0.1's alpha 0.01; the energy
    compensation stays the material's, as Cycles'), at normal incidence E(0.444) / E(0.01)
    = 0.7437 of Filter Glossy 0's (measured 0.7432 at 50 000 photons; without the split
    1.0000: photonblur49 left this scatter unblurred), while the caustic map's photons
    stay bit for bit those without it."""
    expect = (_ggx_albedo_at_normal_view(pk.blur_alpha(1.0, pk.GATHER_PDF))
              / _ggx_albedo_at_normal_view(0.01))
    monkeypatch.setattr(photons_module, "SPLIT_GATHER_PHOTONS", True)  # (the default)
    r0, _ = _metal_patch_ratio(0.0)
    r1, split = _metal_patch_ratio(1.0)
    assert abs(r1 / r0 - expect) < 0.012, (r1 / r0, expect)
    monkeypatch.setattr(photons_module, "SPLIT_GATHER_PHOTONS", False)
    r_off, whole = _metal_patch_ratio(1.0)
    assert abs(r_off / r0 - 1.0) < 0.012, r_off / r0
    for kind in (pk.DIRECT, pk.CAUSTIC):
        sa, sb = split.kind == kind, whole.kind == kind
        np.testing.assert_array_equal(split.power[sa], whole.power[sb])
        np.testing.assert_array_equal(split.position[sa], whole.position[sb])
