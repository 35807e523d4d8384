"""Translucent BSDF: Cycles' diffuse transmission (bsdf_translucent, f = colour / pi on the
far side of the surface), a lobe of its own in both passes (issue 14; the s29 new user's
lamp shade of Translucent BSDF blocked its lamp: the shade read 0.02 of Cycles, the room
0.80-0.83).

- The closure set-up gives the lobe its share x colour, exactly (Lambert transmits all it
  does not absorb), and every other layer keeps 1 - share.
- Its sampling and evaluation agree: cosine on the far hemisphere, f cos / pdf = the
  colour weight, the pdf integrates to 1.
- Direct light through it (next-event estimation from the far side, engine/glasslight.py)
  gives colour x E / pi under a sun, and a Mix with a diffuse side splits the light as
  Cycles' closure weights do.
- Photons through it (caustic-kind light, as through rough glass) light a floor beneath a
  wide translucent ceiling with rho / pi x colour x E x the ceiling's view factor.
"""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.closures import principled as pr
from engine.geometry import closure_params
from engine.scene import Material


def _lobes(material, base, cos_o=0.7):
    params = closure_params([material])
    return pr.setup_np(params, np.zeros(1, np.int64), np.asarray([base], float),
                       np.full(1, cos_o), np.ones(1, np.bool_))


def test_setup_gives_the_translucent_lobe_its_share_and_colour():
    base = (0.5, 0.6, 0.7)
    prm, w = _lobes(Material("t", base, translucent=1.0), base)
    assert np.allclose(w[0, pr.L_TRANSL], base)
    assert np.allclose(prm[0, pr.P_TL_W:pr.P_TL_W + 3], base)
    others = [l for l in range(pr.N_LOBES) if l != pr.L_TRANSL]
    assert np.all(w[0, others] == 0.0)
    # A Mix of Diffuse (base) and Translucent (its own colour) by 0.4: both colours kept.
    tcol = (0.1, 0.8, 0.2)
    _, w = _lobes(Material("m", base, translucent=0.4, translucent_color=tcol), base)
    assert np.allclose(w[0, pr.L_TRANSL], 0.4 * np.array(tcol))
    assert np.allclose(w[0, pr.L_DIFFUSE], 0.6 * np.array(base))
    # Under a Principled specular layer the translucent share is taken first: the
    # layer and the diffuse base below it share the rest.
    _, w_full = _lobes(Material("p", base, specular=1.0, roughness=0.5), base)
    _, w_mix = _lobes(Material("pm", base, specular=1.0, roughness=0.5, translucent=0.3,
                               translucent_color=tcol), base)
    assert np.allclose(w_mix[0, pr.L_SPEC], 0.7 * w_full[0, pr.L_SPEC])
    assert np.allclose(w_mix[0, pr.L_DIFFUSE], 0.7 * w_full[0, pr.L_DIFFUSE])
    assert np.allclose(w_mix[0, pr.L_TRANSL], 0.3 * np.array(tcol))


def test_sampling_and_evaluation_of_the_lobe_agree():
    base = (0.3, 0.5, 0.9)
    prm, _ = _lobes(Material("t", base, translucent=1.0), base)
    n = 20000
    rng = np.random.default_rng(3)
    ns = np.tile([0.0, 0.0, 1.0], (n, 1))
    wo = np.tile([0.6, 0.0, 0.8], (n, 1))
    prm_n = np.ascontiguousarray(np.repeat(prm, n, axis=0))
    d, w = np.empty((n, 3)), np.empty((n, 3))
    tr = np.empty(n, np.bool_)
    u = rng.random((3, n))
    pr.sample_lobes(prm_n, np.full(n, pr.L_TRANSL, np.int64), ns, wo, u[0], u[1], u[2], d,
                    w, tr)
    assert tr.all() and np.all(d[:, 2] < 0)
    assert np.allclose(w, base)
    # cos-weighted: E[|cos|] = 2/3 for a cosine distribution.
    assert abs(-d[:, 2]).mean() == pytest.approx(2 / 3, abs=0.01)
    # eval: f |cos| / pdf = the colour; the pdf over the sphere integrates to 1.
    out = np.empty((n, 4))
    pr.eval_translucent_many(prm_n, ns, wo, d, out)
    assert np.allclose(out[:, :3] / out[:, 3:4], base)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    pr.eval_translucent_many(prm_n, ns, wo, v, out)
    assert (out[:, 3] * 4 * math.pi).mean() == pytest.approx(1.0, abs=0.03)
    assert np.all(out[v[:, 2] >= 0] == 0.0)  # nothing on the viewer's side


def _sunlit_sheet(material, camera_z, strength=3.0):
    s = PaperScene(width=16, height=16)
    s.add_material(material)
    s.add_plane((0, 0, 0), (0, 0, 1), 40, material.name, name="sheet")
    s.add_sun(direction=(0, 0, -1), strength=strength)
    s.set_camera((0, 0, camera_z), (0, 0, 0), up=(0, 1, 0), view_angle=10.0)
    return s


@pytest.mark.parametrize("camera_z, expect", [(-3.0, "transmitted"), (3.0, "reflected")])
def test_sun_through_a_translucent_sheet_is_colour_times_irradiance_over_pi(camera_z,
                                                                              expect):
    """A sun of strength E straight above a sheet: seen from below, radiance
    share x colour x E / pi (direct light through the surface); from above, the diffuse
    side's (1 - share) x base x E / pi."""
    E = 3.0
    base, tcol, share = np.array([0.6, 0.2, 0.1]), np.array([0.2, 0.4, 0.8]), 0.4
    mat = Material("mix", base, translucent=share, translucent_color=tcol)
    film = _sunlit_sheet(mat, camera_z, E).render(
        RenderSettings(spp=4, photon_mapping=False, seed=1))
    got = film.combined.reshape(-1, 3).mean(axis=0)
    want = (share * tcol if expect == "transmitted" else (1 - share) * base) * E / math.pi
    assert np.allclose(got, want, rtol=0.01), (got, want)
    # The effect report names what the sheet shows.
    assert any("light through translucent 'sheet' (diffuse transmission" in line
               for line in film.stats["effects"]), film.stats["effects"]


def _corner_view_factor(X, Y):
    """View factor from a differential area to a parallel X x Y rectangle (in units of
    its height) with one corner straight above it (Howell's catalogue, B-3)."""
    x1, y1 = X / math.sqrt(1 + X * X), Y / math.sqrt(1 + Y * Y)
    return (x1 * math.atan(Y / math.sqrt(1 + X * X))
            + y1 * math.atan(X / math.sqrt(1 + Y * Y))) / (2 * math.pi)


def _view_factor(x, y, half, h):
    """From the floor point (x, y) to a square ceiling of half side `half`, `h` above,
    centred over the origin: its four corner rectangles."""
    return sum(_corner_view_factor((half + sx * x) / h, (half + sy * y) / h)
               for sx in (1, -1) for sy in (1, -1))


def test_photons_through_a_translucent_ceiling_light_the_floor():
    """A grey floor under a translucent ceiling 1 m up, a sun straight above: the floor's
    only light is what the ceiling lets through, spread as Lambert: radiance
    rho / pi x colour x E x F (F the ceiling's view factor, averaged over the pixels'
    floor points; nothing comes back: a pure translucent sheet reflects nothing).
    Over seeds 1-6 the image mean read 0.975-1.001 of it (2 M photons)."""
    E, rho, tcol, half, h = 2.0, 0.5, np.array([0.7, 0.5, 0.3]), 4.0, 1.0
    width, zc, fov = 24, 0.6, 60.0
    s = PaperScene(width=width, height=width)
    s.add_material(Material("shade", tcol, translucent=1.0))
    s.add_material(Material("grey", (rho, rho, rho)))
    s.add_plane((0, 0, h), (0, 0, 1), 2 * half, "shade", name="ceiling")
    s.add_plane((0, 0, 0), (0, 0, 1), 2 * half, "grey", name="floor")
    s.add_sun(direction=(0, 0, -1), strength=E)
    s.set_camera((0, 0, zc), (0, 0, 0), up=(0, 1, 0), view_angle=fov)
    film = s.render(RenderSettings(spp=4, photons=2_000_000, caustic_photons=0, seed=3))
    t = zc * math.tan(math.radians(fov / 2))
    c = (2 * (np.arange(width) + 0.5) / width - 1) * t
    F = np.mean([[_view_factor(x, y, half, h) for x in c] for y in c])
    got = film.combined.reshape(-1, 3).mean(axis=0)
    want = rho / math.pi * tcol * E * F
    assert np.allclose(got, want, rtol=0.04), (got / want)
    assert np.all(np.isfinite(film.combined))
    # The effect report says where that light comes from.
    assert any("translucent 'ceiling' lets through" in line for line in film.stats["effects"])
