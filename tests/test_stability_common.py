"""Shared helpers of the hard-case stability suite (issue 5; docs/stability.md).

Every stability test renders through `run()`, which asserts that the render ended, that
every pass of the Film is free of NaN/Inf (depth may be +inf only where no camera ray hit
anything) and that no pass is negative. Images are tiny so the suite stays fast.
"""
import math
import time

import numpy as np

from engine import RenderSettings
from engine.accel import Accel
from engine.api import PaperScene
from engine.geometry import prepare
from engine.lights import allocate_photons, prepare_lights
from engine.photons import trace_photons
from engine.render import Context
from engine.scene import Material

FAST = dict(photons=4000, caustic_photons=2000, spp=4, seed=1)
# CPU seconds (all threads) any single tiny render may take: a runaway search or a hang
# fails loudly, while other jobs on a shared machine (wall-clock time) do not count.
CPU_LIMIT = 60.0


def assert_film_sane(film):
    for name, buf in film.passes().items():
        buf = np.asarray(buf)
        assert not np.isnan(buf).any(), f"NaN in pass {name}"
        if name == "depth":
            assert not np.isneginf(buf).any()
            # Depth is the first sample's (Cycles' sample 0): inf where that sample met no
            # surface, so some sample of the pixel missed (alpha below 1).
            inf = np.isinf(buf)
            assert np.all(film.alpha[inf] < 1), "depth is inf where every camera ray hit"
        else:
            assert np.isfinite(buf).all(), f"Inf in pass {name}"
        if name not in ("normal",):
            assert (buf >= 0).all(), f"negative values in pass {name}"


def run(scene, **settings):
    st = dict(FAST)
    st.update(settings)
    t0 = time.process_time()
    film = scene.render(RenderSettings(**st))
    cpu = time.process_time() - t0
    assert cpu < CPU_LIMIT, f"render took {cpu:.1f} CPU s"
    assert not film.stats.get("cancelled")
    assert_film_sane(film)
    return film


def relmse(x, ref):
    x = np.asarray(x, np.float64)
    ref = np.asarray(ref, np.float64)
    return float(np.mean((x - ref) ** 2 / (ref * ref + 0.01)))


def shoot_photons(scene, **settings):
    """Run only the photon pass; returns (photons, prepared lights)."""
    st = dict(FAST)
    st.update(settings)
    s = RenderSettings(**st)
    scene.validate()
    geo, table = prepare(scene)
    accel = Accel(geo.vertices32, geo.faces32, s.threads)
    lights = prepare_lights(scene, geo, table)
    ctx = Context(scene, s, geo, table, accel, lights)
    try:
        ph = trace_photons(ctx, lights, allocate_photons(lights, s.photons), False, 1)
    finally:
        accel.close()
    return ph, lights


def box_room(scale=1.0, shift=(0.0, 0.0, 0.0), albedo=0.7, power=40.0, width=32, height=24):
    """A closed 4 m room (single-sided walls facing in), a block, an area light under the
    ceiling, camera inside. scale / shift move everything; power scales with scale^2 so
    irradiance (and so the image) is unchanged."""
    c = np.asarray(shift, np.float64)
    k = float(scale)
    s = PaperScene(width=width, height=height)
    s.add_material(Material("wall", (albedo,) * 3))
    s.add_material(Material("red", (albedo, 0.1, 0.1)))
    L = 4.0
    P = lambda *p: c + k * np.asarray(p, np.float64)  # noqa: E731
    s.add_plane(P(0, 0, 0), (0, 0, 1), k * L, "wall", name="floor")
    s.add_plane(P(0, 0, L), (0, 0, -1), k * L, "wall", name="ceiling")
    s.add_plane(P(0, L / 2, L / 2), (0, -1, 0), k * L, "wall", name="back")
    s.add_plane(P(0, -L / 2, L / 2), (0, 1, 0), k * L, "wall", name="front")
    s.add_plane(P(-L / 2, 0, L / 2), (1, 0, 0), k * L, "red", name="left")
    s.add_plane(P(L / 2, 0, L / 2), (-1, 0, 0), k * L, "wall", name="right")
    s.add_box(P(0.6, 0.5, 0.6), k * np.array([1.0, 1.0, 1.2]), "wall", name="block")
    s.add_rect_area_light(P(0, 0, L - 0.02), (k * 1.0, k * 1.0), power=power * k * k,
                          name="ceiling_light")
    s.set_camera(P(0, -1.9, 2.0), P(0, 0, 1.5), (0, 0, 1), view_angle=70)
    return s


def sphere_points_inside(center, radius):
    return lambda p: np.linalg.norm(p - np.asarray(center), axis=-1) < radius


__all__ = ["FAST", "assert_film_sane", "run", "relmse", "shoot_photons", "box_room", "math"]
