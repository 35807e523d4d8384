"""engine.subsurfacewalk with a textured Base Color / Subsurface Weight (issue 14, ssstex41).

A texture of two constant halves (one colour, weight and radius left of x = 0, another
right of it) on two balls, one in each half, renders as the two constant materials side by side
(per-hit colour, weight and radius at each walk's entry, each walk's medium fitted from its own
albedo): with the same seed, to rounding. Untextured materials take the materials'
constants (their images are unchanged: tests/test_subsurface_walk.py)."""
import numpy as np

from engine import RenderSettings
from engine import subsurfacewalk as sw
from engine.api import PaperScene
from engine.scene import Material
from engine.subsurface import SubsurfaceColor

LEFT, RIGHT = (0.9, 0.35, 0.2), (0.25, 0.6, 0.85)
W_LEFT, W_RIGHT = 1.0, 0.6
R_LEFT, R_RIGHT = (0.6, 0.3, 0.15), (0.2, 0.4, 0.8)
RADIUS, IOR, G, ROUGH = R_LEFT, 1.4, 0.0, 0.5


class _Halves:
    """A node (engine/shadernodes.py protocol): `left` where the hit triangle's first
    corner has x < 0, else `right` ((N,3) for colours, (N,) for values)."""

    def __init__(self, left, right):
        self.left, self.right = np.asarray(left, float), np.asarray(right, float)

    def evaluate(self, geo, prim, u, v):
        x = np.asarray(geo.v0, float)[np.asarray(prim, np.int64), 0]
        side = (x < 0.0).reshape((-1,) + (1,) * self.left.ndim)
        return np.where(side, self.left, self.right).astype(float)


def _scene(textured: bool, spp=8, seed=2, workers=1):
    s = PaperScene(width=48, height=24, background=(0.9, 0.9, 0.9))
    s.add_sun((0.3, 0.6, -1.0), strength=3.0)
    if textured:
        colour, weight = _Halves(LEFT, RIGHT), _Halves(W_LEFT, W_RIGHT)
        sp = sw.SubsurfaceParams.make(1.0, (1.0,) * 3, (1.0,) * 3, IOR, G, ROUGH,
                                      color_node=colour, weight_node=weight,
                                      radius_node=_Halves(R_LEFT, R_RIGHT))
        s.add_material(Material("skin", (1.0, 1.0, 1.0), roughness=ROUGH, specular=0.0,
                                texture=SubsurfaceColor(colour, weight), subsurface=sp))
        names = ("skin", "skin")
    else:
        for name, c, w, r in (("left", LEFT, W_LEFT, R_LEFT),
                              ("right", RIGHT, W_RIGHT, R_RIGHT)):
            sp = sw.SubsurfaceParams.make(w, c, r, IOR, G, ROUGH)
            s.add_material(Material(name, tuple(sp.stand_in()), roughness=ROUGH,
                                    specular=0.0, subsurface=sp))
        names = ("left", "right")
    s.add_sphere((-1.1, 0, 0), 1.0, names[0], segments=32)
    s.add_sphere((1.1, 0, 0), 1.0, names[1], segments=32)
    s.set_camera((0, -6, 0), (0, 0, 0), view_angle=45)
    film = s.render(RenderSettings(photons=20_000, caustic_photons=0, spp=spp, seed=seed,
                                   workers=workers))
    return np.asarray(film.combined, np.float64)[..., :3]


def test_per_hit_colour_and_weight_of_the_nodes():
    sp = sw.SubsurfaceParams.make(0.5, (0.2, 0.2, 0.2), RADIUS, IOR, G, ROUGH,
                                  color_node=_Halves((1.4, 0.5, -0.1), (0.3, 0.3, 0.3)))
    assert sp.textured and not sw.SubsurfaceParams.make(0.5, (0.2,) * 3, RADIUS, IOR, G,
                                                        ROUGH).textured

    class Geo:
        v0 = np.array([[-1.0, 0, 0], [1.0, 0, 0]])

    c, w, r = sp.per_hit(Geo(), np.array([0, 1, 0]), np.zeros(3), np.zeros(3))
    # Clamped to [0, 1] as the constant colour is (SubsurfaceParams.make).
    np.testing.assert_allclose(c, [[1.0, 0.5, 0.0], [0.3, 0.3, 0.3], [1.0, 0.5, 0.0]])
    np.testing.assert_allclose(w, 0.5)
    np.testing.assert_allclose(r, np.tile(RADIUS, (3, 1)))
    sp = sw.SubsurfaceParams.make(0.5, (0.2,) * 3, RADIUS, IOR, G, ROUGH,
                                  radius_node=_Halves((0.1, -0.2, 0.3), (0.0, 0.0, 0.0)))
    assert sp.textured
    _, _, r = sp.per_hit(Geo(), np.array([0, 1]), np.zeros(2), np.zeros(2))
    np.testing.assert_allclose(r, [[0.1, 0.0, 0.3], [0.0, 0.0, 0.0]])


def test_texture_of_two_halves_renders_as_two_materials():
    """Same seed: every walk draws the same numbers and sees the same colour, weight and
    stand-in in both scenes, so the images agree to rounding (they are bitwise equal
    now); the walk moves the balls' means 1-5 % from the stand-in's here."""
    tex = _scene(True)
    const = _scene(False)
    np.testing.assert_allclose(tex, const, rtol=1e-9, atol=1e-12)
    # The two balls differ (the texture's halves really differ).
    left, right = tex[7:17, 7:18].mean(axis=(0, 1)), tex[7:17, 30:41].mean(axis=(0, 1))
    assert left[0] > 1.5 * right[0] and right[2] > 1.5 * left[2]


def test_textured_walks_same_image_any_worker_count():
    np.testing.assert_array_equal(_scene(True, spp=2), _scene(True, spp=2, workers=2))
