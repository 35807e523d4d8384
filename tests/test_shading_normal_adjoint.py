"""Photons off a surface whose shading normal is not its geometric one (smooth shading, a
Normal Map or Bump) take Veach's adjoint (1997, sec. 5.3): f |wi.Ns| |wo.Ng| / (|wi.Ng| pdf)
instead of the camera side's f |wo.Ns| / pdf (engine/photonkernels.py, _scatter), so that
the light they carry off a metal is what the camera side (and Cycles, which traces from
the camera) finds there (glow36: the floor beside a normal-mapped rough metal read 1.14x
Cycles without it; docs/accuracy.md).

The analytic check: a sun lights a 2 x 2 m metal quad (roughness 0.05: a narrow lobe; the ratio below holds for a narrow one) whose
corner normals are all tilted 15 degrees from its face normal; the light arrives 40 degrees
from the shading normal and 55 from the face normal, and reflects 40 degrees the other
side of the shading normal: 25 degrees from the face normal, onto a dark wall. Per unit of
the quad's area the camera side's reflected flux is R E |wo.Ng| (R: the lobe's albedo at
40 degrees, E the sun's irradiance), while E |wi.Ng| arrives; against the same quad with
flat shading under a sun 40 degrees off its normal (reflected flux R E cos 40, arriving
E cos 40) the reflected / arriving ratio is cos 25 / cos 55 = 1.58 (1 without the adjoint)."""
import math

import numpy as np

from engine import RenderSettings
from engine.api import PaperScene
from engine.photons import CAUSTIC
from engine.scene import Material

from test_energy import shoot

TILT, INCIDENCE = math.radians(15.0), math.radians(40.0)
SUN = 3.0  # W/m^2
QUAD = 4.0  # m^2


def _scene(tilted: bool):
    """The metal quad at z = 0 (face normal +z), the wall at y = 3 facing it, and the sun
    from the -y side: 40 degrees from the shading normal (tilted towards -y by TILT)."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("metal", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.05))
    s.add_material(Material("wall", (0.05, 0.05, 0.05), specular=0.0))
    v = np.array([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], float)
    tau = TILT if tilted else 0.0
    ns = np.tile([0.0, -math.sin(tau), math.cos(tau)], (4, 1))
    s.add_triangles(v, [(0, 1, 2), (0, 2, 3)], "metal", name="Metal", normals=ns)
    s.add_triangles(np.array([(-4, 3, 0), (4, 3, 0), (4, 3, 12), (-4, 3, 12)], float),
                    [(0, 1, 2), (0, 2, 3)], "wall", name="Wall")
    phi = -(INCIDENCE + tau)  # the sun's direction (towards it) from +z, towards -y
    to_sun = np.array([0.0, math.sin(phi), math.cos(phi)])
    s.add_sun(direction=tuple(-to_sun), strength=SUN)
    s.set_camera((0, -6, 3), (0, 0, 1))
    return s, to_sun[2]  # cos(wi, Ng)


def _reflected_share(tilted: bool, seed: int) -> float:
    """Caustic flux stored on the wall / the sun's flux onto the quad."""
    scene, cos_g = _scene(tilted)
    ph = shoot(scene, RenderSettings(photons=1_000_000, seed=seed, max_photon_depth=4))
    keep = ph.kind == CAUSTIC
    flux = float(ph.power[keep].astype(np.float64).sum(axis=0).mean())
    return flux / (SUN * QUAD * cos_g)


def test_photons_off_a_tilted_shading_normal_carry_the_camera_sides_flux():
    flat = _reflected_share(False, seed=1)
    tilted = _reflected_share(True, seed=2)
    # The flat quad reflects its lobe's albedo at 40 degrees (a 0.9 metal: ~0.9).
    assert 0.8 < flat < 0.97, flat
    want = math.cos(INCIDENCE - TILT) / math.cos(INCIDENCE + TILT)  # 1.58
    assert abs(tilted / flat / want - 1.0) < 0.04, (tilted / flat, want)
