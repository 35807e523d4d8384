"""No light leaks into a closed room (issue 14, promise 2).

A new user's room with 10 cm thick walls (overlapping boxes, as Blender users build
them), its window closed by a glass slab and a sun shining only on the outside of the
walls, showed round bright spots inside that the same room without the sun lacks (scene
c0 / c1 of the s17 newuser scenes). They are not sunlight: with the sky removed the
room's interior reads exactly zero, and every photon stored inside came through the
glass from the sky (docs/performance.md, "leak"). The spots are the sky's few
glow-photons (Caustic pass) through the glass, 3.6x fewer and 4x brighter because the
sun takes three quarters of the global shot's photons by its power.

Here the invariant that rules the leak out: the same kind of room, closed, lit from
outside only (a sun grazing its walls and roof, and a bright world), reads exactly zero
in every film pass, and its photon pass stores no photon inside.
"""
import math

import numpy as np

from engine import RenderSettings
from engine.api import PaperScene
from engine.render import prepare_context, render, shoot_photons
from engine.scene import Material

T = 0.1   # wall thickness, m
L = 4.0   # inside size of the room, m
H = 2.6   # inside height, m


def add_room_shell(s):
    """The room's materials ("wall", "wood") and five of its walls in s (a PaperScene):
    floor, ceiling, back, front and left boxes T thick, each L + 2T long so they overlap at
    the edges and corners; the right wall (+x) is the caller's. Returns L + 2T."""
    s.add_material(Material("wall", (0.8, 0.8, 0.78)))
    s.add_material(Material("wood", (0.5, 0.3, 0.15)))
    full = L + 2 * T
    s.add_box((0, 0, -T / 2), (full, full, T), "wood", name="floor")
    s.add_box((0, 0, H + T / 2), (full, full, T), "wall", name="ceiling")
    s.add_box((0, L / 2 + T / 2, H / 2), (full, T, H), "wall", name="back")
    s.add_box((0, -L / 2 - T / 2, H / 2), (full, T, H), "wall", name="front")
    s.add_box((-L / 2 - T / 2, 0, H / 2), (T, full, H), "wall", name="left")
    return full


def _closed_room(sun=True, world=True, width=32, height=24):
    """The newuser room (scene_c0_window_sun_outside.py) with the window walled up:
    six boxes T thick overlapping at the edges and corners (each L + 2T long), a block
    and a ball inside, camera inside; lit only from outside by a sun from -x, 35 degrees
    up (it lights the outside of the left wall and the roof) and a bright world."""
    s = PaperScene(width=width, height=height,
                   background=(0.3, 0.4, 0.6) if world else (0.0, 0.0, 0.0))
    s.background_is_light = world
    full = add_room_shell(s)
    s.add_box((L / 2 + T / 2, 0, H / 2), (T, full, H), "wall", name="right")
    s.add_box((-0.5, 0.5, 0.3), (0.6, 0.6, 0.6), "wall", name="block")
    if sun:
        a = math.radians(35.0)
        s.add_sun(direction=(math.cos(a), 0.0, -math.sin(a)), strength=5.0,
                  angle_degrees=0.5)
    s.set_camera((-1.9, -1.9, 1.7), (0.8, 0.3, 0.6), view_angle=80)
    return s


def _inside(p, margin=1e-3):
    """(N,) bool: points p (N,3) world space strictly inside the room's air."""
    return ((np.abs(p[:, 0]) < L / 2 - margin) & (np.abs(p[:, 1]) < L / 2 - margin)
            & (p[:, 2] > margin) & (p[:, 2] < H - margin))


SETTINGS = dict(spp=4, photons=60000, workers=2)


def test_closed_room_lit_from_outside_reads_exactly_zero_inside():
    """Sun and world outside a closed thick-walled room: every pass of the film is
    exactly zero (the same film as the room with no light at all)."""
    film = render(_closed_room(), RenderSettings(**SETTINGS))
    for name in ("direct", "indirect", "caustic", "specular", "emission"):
        got = np.asarray(getattr(film, name))
        assert not np.any(got), f"{name}: {np.count_nonzero(got[..., :3])} lit pixels"


def test_closed_room_photons_stay_outside():
    """The photon pass of the same room stores many photons on the outside of its walls
    and none inside: the walls' overlapping boxes and the ray offsets let none through."""
    ctx = prepare_context(_closed_room(), RenderSettings(**SETTINGS))
    shots = shoot_photons(ctx, {})
    stored = sum(len(ph) for ph in shots)
    assert stored > 10000
    for ph in shots:
        world = ph.position.astype(np.float64) + ctx.geo.offset
        assert not np.any(_inside(world)), world[_inside(world)][:5]
