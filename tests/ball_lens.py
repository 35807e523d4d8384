"""A glass ball focusing a sun onto a floor, traced analytically (no engine code): the
reference for the caustic map's estimate (tests/test_caustic_radius.py,
bench/bench_caustic_radius.py).

A bundle of parallel rays of irradiance E (W/m^2 across the beam) fills the ball's
cross-section (radius R); each ray refracts into a perfect sphere of index n and out again
(unpolarised Fresnel transmittance at both interfaces, Snell's law) and lands on the floor
z = 0. Its power E pi R^2 / m x T_in x T_out is binned on the floor: the floor irradiance of
the L S S D paths. Paths with internal reflections (a few % of the power, spread wide) are
left out. A ball lens's paraxial focus lies n R / (2 (n - 1)) from its centre.
"""
from __future__ import annotations

import math

import numpy as np


def paraxial_focus(radius: float, n: float) -> float:
    """Distance (m) from a ball lens's centre to its paraxial focus."""
    return n * radius / (2.0 * (n - 1.0))


def _transmit(d, normal, eta):
    """Refract unit directions d (M,3) at unit normals facing them (M,3), eta = n_i / n_t:
    (new directions, unpolarised Fresnel transmittance); total internal reflection: T 0."""
    ci = -(d * normal).sum(1)
    s2 = eta * eta * (1.0 - ci * ci)
    ct = np.sqrt(np.maximum(1.0 - s2, 0.0))
    rs = ((eta * ci - ct) / (eta * ci + ct)) ** 2
    rp = ((eta * ct - ci) / (eta * ct + ci)) ** 2
    t = np.where(s2 < 1.0, 1.0 - 0.5 * (rs + rp), 0.0)
    return eta * d + (eta * ci - ct)[:, None] * normal, t


def _sphere_exit(p, d, centre, radius, far: bool):
    oc = p - centre
    b = (oc * d).sum(1)
    c = (oc * oc).sum(1) - radius * radius
    root = np.sqrt(np.maximum(b * b - c, 0.0))
    return p + (-b + root if far else -b - root)[:, None] * d


def trace_bundle(centre, radius: float, n: float, direction, irradiance: float,
                 rays: int = 2_000_000, seed: int = 0):
    """Rays of the bundle through the ball: (impact (M,2) offsets in the beam's plane, m;
    exit points (M,3); exit directions (M,3); powers (M,) W)."""
    centre = np.asarray(centre, np.float64)
    d0 = np.asarray(direction, np.float64)
    d0 = d0 / np.linalg.norm(d0)
    u = np.cross(d0, [0.0, 0.0, 1.0] if abs(d0[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(d0, u)
    rng = np.random.default_rng(seed)
    # Stratified in radius squared (equal-area rings): a smooth profile at fewer rays.
    r = radius * np.sqrt((np.arange(rays) + rng.random(rays)) / rays)
    a = 2.0 * math.pi * rng.random(rays)
    off = np.column_stack([r * np.cos(a), r * np.sin(a)])
    o = centre + off[:, :1] * u + off[:, 1:] * v - 2.0 * radius * d0
    d = np.tile(d0, (rays, 1))
    p = _sphere_exit(o, d, centre, radius, far=False)
    d, t_in = _transmit(d, (p - centre) / radius, 1.0 / n)
    p = _sphere_exit(p, d, centre, radius, far=True)
    d, t_out = _transmit(d, -(p - centre) / radius, n)
    power = irradiance * math.pi * radius * radius / rays * t_in * t_out
    return off, p, d, power


def floor_hits(centre, radius, n, direction, irradiance, rays=2_000_000, seed=0):
    """(points (M,2) on the floor z = 0, powers (M,) W) of the bundle's rays that leave
    the ball downwards."""
    _, p, d, power = trace_bundle(centre, radius, n, direction, irradiance, rays, seed)
    ok = (d[:, 2] < 0.0) & (power > 0.0)
    t = -p[ok, 2] / d[ok, 2]
    return p[ok, :2] + t[:, None] * d[ok, :2], power[ok]


def bin_irradiance(points, power, xs, ys, cell: float):
    """Irradiance (len(ys), len(xs)) W/m^2 in square cells of side `cell` centred on the
    grid xs x ys (rows: y)."""
    ex = np.r_[xs - cell / 2, xs[-1] + cell / 2]
    ey = np.r_[ys - cell / 2, ys[-1] + cell / 2]
    h, _, _ = np.histogram2d(points[:, 0], points[:, 1], [ex, ey], weights=power)
    return h.T / (cell * cell)


def encircled_radius(image, xs, ys, share: float = 0.5):
    """Radius (m) of the disc about the image's brightest cell that holds `share` of the
    image's power (a spot's width)."""
    i, j = np.unravel_index(np.argmax(image), image.shape)
    X, Y = np.meshgrid(xs, ys)
    d = np.hypot(X - xs[j], Y - ys[i]).ravel()
    order = np.argsort(d, kind="stable")
    acc = np.cumsum(image.ravel()[order])
    return float(d[order][np.searchsorted(acc, share * acc[-1])])


# The case tests/test_caustic_radius.py and bench/bench_caustic_radius.py share: a ball of
# radius R (m) and index IOR on the floor under a sun of SUN W/m^2 from SUN_DIR (travelling
# down, towards +y); the floor binned in CELL-sized cells over XS x YS (m).
R, IOR, SUN = 0.6, 1.5, 4.0
CENTRE = np.array([0.0, 0.0, R])
SUN_DIR = -np.array([1.0, -10.0, 7.0]) / math.sqrt(150.0)
CELL = 0.02
XS = np.arange(-0.5, 0.5 + 1e-9, CELL)
YS = np.arange(0.2, 2.2 + 1e-9, CELL)


def ball_scene():
    """The engine's scene of the case: the matte floor, the smooth glass ball (96
    segments), the sun as a point on the sky (angle 0) and an orthographic camera above."""
    from engine.api import PaperScene
    from engine.scene import Camera, Material
    s = PaperScene(width=32, height=32)
    s.add_material(Material("matte", (0.8,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 20.0, "matte", name="floor")
    s.add_sphere(tuple(CENTRE), R, "glass", name="ball", segments=96)
    s.add_sun(tuple(SUN_DIR), SUN, angle_degrees=0.0)
    s.camera = Camera(position=(0, 1.2, 3), rotation=np.eye(3), kind="ORTHO", ortho_scale=2.0)
    return s
