"""A photon's path state is its ray's, not its slot's (docs/accuracy.md "slots56").

At a surface that some of its ray kinds do not see, a photon goes on as two rays in one
bounce: its continuation off the surface and a copy passing behind it (photonkernels
_scatter's split-off), both in the photon's slot (the same random numbers). What the path
carries - the Filter Glossy reverse-pdf state, the medium it is in, its volume scatters,
whether its last hit met a touching glass face from inside - must then be each ray's: the
copy keeps what its path had before the surface, the continuation takes the update. Kept
by slot, the copy read its sibling's update (or the sibling the copy's)."""
import numpy as np

from engine import RenderSettings
from engine import photonkernels as pk
from engine.accel import Accel
from engine.api import PaperScene
from engine.coincident import CoincidentSurfaces
from engine.geometry import prepare
from engine.lights import allocate_photons, prepare_lights
from engine.photons import trace_photons
from engine.render import Context, prepare_context
from engine.scene import Material


def _traced(scene, settings):
    ctx = prepare_context(scene, settings)  # (its Accel sees the ray kinds' visibility)
    ph = trace_photons(ctx, ctx.lights, allocate_photons(ctx.lights, settings.photons), False, 1)
    return ph, ph.position.astype(np.float64) + ctx.geo.offset, ctx


def test_a_copy_behind_a_glossy_card_keeps_its_filter_glossy_state():
    """A narrow spot down onto a rough metal patch (the photons' first non-diffuse
    scatter S_1: state inf), whose reflections meet a rough metal card overhead that
    diffuse rays do not see: the continuation off the card takes its reverse pdf (S_2, a
    finite state), the diffuse kind passes on behind the card in a copy to a white
    ceiling. The copy's path has scattered once (S_1 alone): its CAUSTIC stores there
    carry an infinite blur pdf. It read its sibling's S_2 pdf where the state was kept
    by slot."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("metal", (0.9, 0.9, 0.9), roughness=0.3, metallic=1.0))
    s.add_material(Material("white", (0.8, 0.8, 0.8), specular=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 0.6, "metal", name="patch")
    card = s.add_plane((0, 0, 1.5), (0, 0, -1), 6.0, "metal", name="card")
    card.visible_diffuse = False
    s.add_plane((0, 0, 2.5), (0, 0, -1), 30.0, "white", name="ceiling")
    s.add_spot_light((0, 0, 1.0), (0, 0, 0), power=100.0, spot_size_degrees=4.0, blend=0.0)
    s.set_camera((0, -3, 1), (0, 0, 1))
    ph, pos, _ = _traced(s, RenderSettings(photons=20_000, seed=2, cycles_filter_glossy=1.0))
    total = ph.bounces[:, 0].astype(np.int64)
    on_ceiling = np.abs(pos[:, 2] - 2.5) < 1e-3
    copies = on_ceiling & (ph.kind == pk.CAUSTIC) & (total == 1)
    assert copies.sum() > 1_000
    assert np.all(np.isinf(ph.blur_pdf[copies]))


def test_a_copy_into_an_absorbing_box_leaves_its_continuation_outside():
    """A narrow spot down onto a box of a matte material filling it with an absorbing
    medium (sigma_a 3 / m), which glossy rays do not see: the diffuse continuation off
    its top stays outside (a reflection keeps the medium), the glossy kind passes into
    the box in a copy. The continuation's light reaches the ceiling 1 m above unabsorbed:
    its INDIRECT stores there carry the emitted power (albedo 0.5 / roulette 0.5, no
    exp(-3 s)). Kept by slot, the copy's crossing put the continuation inside the box's
    medium too: they read exp(-3 x ~1 m) = 0.05 of it."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("ink", (0.5, 0.5, 0.5), specular=0.0, absorption=(3.0, 3.0, 3.0)))
    s.add_material(Material("white", (0.8, 0.8, 0.8), specular=0.0))
    box = s.add_box((0, 0, 0.5), (2.0, 2.0, 1.0), "ink", name="box")
    box.visible_glossy = False
    s.add_plane((0, 0, 2.0), (0, 0, -1), 30.0, "white", name="ceiling")
    s.add_spot_light((0, 0, 1.5), (0, 0, 0), power=100.0, spot_size_degrees=4.0, blend=0.0)
    s.set_camera((0, -4, 1), (0, 0, 1))
    ph, pos, _ = _traced(s, RenderSettings(photons=20_000, seed=3))
    total = ph.bounces[:, 0].astype(np.int64)
    top = (np.abs(pos[:, 2] - 1.0) < 1e-3) & (ph.kind == pk.DIRECT)
    ceiling = (np.abs(pos[:, 2] - 2.0) < 1e-3) & (ph.kind == pk.INDIRECT) & (total == 1)
    assert top.sum() > 5_000 and ceiling.sum() > 1_000
    emitted = np.median(ph.power[top].astype(np.float64), axis=0)
    assert np.allclose(ph.power[top], emitted, rtol=1e-6)
    assert np.allclose(ph.power[ceiling], emitted, rtol=1e-6)


def test_the_touching_glass_record_is_each_rays_own():
    """CoincidentSurfaces.meet_hits' record of which rays met a touching glass face from
    inside, for two rays of one photon in one bounce (a continuation and a copy of the
    same slot): one arriving at a glass slab's bottom, lying on a floor, from inside, the
    other at the same face from below. Only the first is recorded; the second, refracted
    up into the slab, goes on to the slab's top (a ray whose last hit met the face from
    inside would go into the floor there and end: reflected_inside). Kept by slot, the
    first ray's record was the second's too. (In a trace the two rays of one slot start
    at one point, so both sides of a closed glass are met in one bounce only at ties of
    coincident faces; the record is per ray all the same.)"""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s.add_material(Material("glass", (1, 1, 1), transmission=1.0, ior=1.5))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    s.add_box((0, 0, 0.025), (4.0, 4.0, 0.05), "glass", name="slab")
    s.add_sun((0, 0, -1), strength=3.0)
    s.set_camera((0, -5, 3), (0, 0, 0))
    s.validate()
    geo, table = prepare(s)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    ctx = Context(s, RenderSettings(photons=1000), geo, table, accel,
                  prepare_lights(s, geo, table))
    co = CoincidentSurfaces.for_context(ctx)
    assert co is not None
    ng = np.asarray(geo.ng)
    slab = np.asarray(geo.object_id) == list(geo.object_names).index("slab")
    bottom = np.nonzero(slab & (ng[:, 2] < -0.99))[0]
    top = np.nonzero(slab & (ng[:, 2] > 0.99))[0]
    z0 = float(np.asarray(geo.v0)[bottom[0], 2])  # the bottom's plane (scene offset)

    def hits(o, d, tri):
        """Embree's answer for rays o, d (N,3) meeting triangle rows tri (one mesh)."""
        t = np.abs((z0 - o[:, 2]) / d[:, 2]).astype(np.float32)
        return (np.zeros(len(o), np.int32), np.asarray(tri, np.int32),
                np.full(len(o), 0.25, np.float32), np.full(len(o), 0.25, np.float32), t,
                np.zeros(1, np.int64))

    # Bounce b: ray 0 down inside the slab, ray 1 up from below the floor (a copy
    # passing it), both meeting the bottom face near x = y = 0.3; neither left a face.
    o = np.array([[0.3, 0.3, z0 + 0.02], [0.3, 0.3, z0 - 0.5]], np.float32)
    d = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    geom, prim, u, v, t, starts = hits(o, d, [bottom[0], bottom[0]])
    arrived = np.zeros(2, bool)
    co.meet_hits(o, d, np.full(2, -1, np.int64), np.zeros((2, 3)), geom, prim, u, v, t,
                 starts, arrived)
    assert arrived.tolist() == [True, False]
    # Bounce b + 1: ray 1 refracted up into the slab from the bottom face it met, with
    # its own record; it goes on to the slab's top.
    off = np.array([[0.0, 0.0, 1e-5]])
    o1 = (np.array([[0.3, 0.3, z0]]) + off).astype(np.float32)
    d1 = np.array([[0.0, 0.0, 1.0]])
    geom, prim, u, v, t, starts = hits(o1, d1, [top[0]])
    t[:] = 0.05
    co.meet_hits(o1, d1, np.array([bottom[0]], np.int64), off, geom, prim, u, v, t,
                 starts, arrived[1:].copy())
    assert geom[0] == 0 and prim[0] == top[0]
    # (and with the first ray's record it would have ended at the floor)
    geom, prim, u, v, t, starts = hits(o1, d1, [top[0]])
    co.meet_hits(o1, d1, np.array([bottom[0]], np.int64), off, geom, prim, u, v, t,
                 starts, np.ones(1, bool))
    assert geom[0] == -1
