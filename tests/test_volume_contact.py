"""A fog box standing on the floor (engine/volumecontact.py): its bottom face in the
floor's plane, the floor belongs inside the fog. The floor seen from above through an
absorbing slab, lit by a point light inside the slab and by one above it, against
Beer-Lambert's exp(-sigma_t d) along the light's and the camera's paths; the box resting
on the floor, sunk 1 mm into it and (a real gap) floating 1 mm over it agree; a box
against a wall; the seating's geometry."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene, box_mesh
from engine.geometry import prepare
from engine.render import render
from engine.scene import Material, Mesh
from engine.volumecontact import SEAT, seat_volume_faces

SIGMA = np.array([0.9, 0.5, 0.2])  # 1/m, absorption only (nothing scattered in)
H = 0.6  # the slab's height (m); it stands on the floor at z = 0
RHO = 0.8  # the floor's diffuse albedo
POWER = 300.0
WIDTH = 8  # pixels across the 1 m orthographic film


def _tilt():
    """A rotation by 30 degrees about (1, 1, 0): the floor and the box's bottom in one
    tilted plane, where Embree's two distances to them round differently (an
    axis-aligned pair ties exactly and Embree returns the floor)."""
    a, k = math.radians(30.0), np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


def _scene(light_z, lift=0.0):
    """A 20 x 20 m white floor at z = 0, a 6 x 6 x H volume-only absorbing box standing
    on it (its bottom at z = lift: 0 on the floor, < 0 sunk), a point light of POWER W
    at (0, 0, light_z), an orthographic camera looking straight down at a 1 m square;
    all of it turned by _tilt (the same image)."""
    R = _tilt()
    s = PaperScene(WIDTH, WIDTH)
    s.add_material(Material("fog", volume_only=True, absorption=SIGMA))
    s.add_material(Material("floor", (RHO, RHO, RHO), roughness=1.0, specular=0.0))
    s.add_plane((0, 0, 0), tuple(R[:, 2]), 20.0, "floor", name="floor")
    v, f = box_mesh((0, 0, lift + H / 2), (6.0, 6.0, H))
    s.add_triangles(v @ R.T, f, "fog", name="fog")
    s.add_point_light(tuple(R @ (0.0, 0.0, light_z)), power=POWER)
    s.set_camera(tuple(R @ (0, 0, 3.0)), (0, 0, 0), up=tuple(R[:, 1]), kind="ORTHO",
                 ortho_scale=1.0)
    return s


def _floor_radiance(light_z, lift=0.0):
    """The image's mean (3,): over the pixel centres, rho / pi x E x the camera ray's
    exp(-sigma (H + lift)) (it crosses the box from its top at H + lift to the floor),
    E = I cos / r^2 exp(-sigma l), I = P / 4 pi, l the light's path inside the box (all
    of r for a light inside it; the part below the top for one above)."""
    xs = (np.arange(WIDTH) + 0.5) / WIDTH - 0.5
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    r = np.sqrt(X * X + Y * Y + light_z * light_z)
    top = H + lift
    inside = r if light_z < top else r * top / light_z
    E = POWER / (4 * math.pi) * (light_z / r) / r ** 2
    out = [(RHO / math.pi * E * np.exp(-s * (inside + top))).mean() for s in SIGMA]
    return np.array(out)


def _mean(scene, seed=3):
    film = render(scene, RenderSettings(workers=1, spp=16, photon_mapping=False, seed=seed))
    return np.asarray(film.combined, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)


@pytest.mark.parametrize("light_z", [0.45, 1.6], ids=["lamp-inside", "lamp-above"])
def test_floor_under_a_fog_box_standing_on_it_matches_beer_lambert(light_z):
    """Every camera ray meets the floor inside the fog (without the seating, a ray that
    Embree gave the box's bottom face crossed out of the fog and saw the black world
    under the floor); the floor's shadow rays keep the fog's extinction. Within 1 %."""
    np.testing.assert_allclose(_mean(_scene(light_z)), _floor_radiance(light_z), rtol=0.01)


def test_standing_sunk_and_floating_boxes_agree():
    """On the floor, sunk 1 mm into it, floating 1 mm over it (a real gap: the floor
    outside the fog, lit through it): the same floor within 1 % (the gap's and the sunk
    box's own 1 mm of path taken into the analytic value)."""
    for lift in (0.0, -1e-3, 1e-3):
        got = _mean(_scene(0.45, lift))
        expect = _floor_radiance(0.45, lift) if lift >= 0 else _floor_radiance(0.45)
        np.testing.assert_allclose(got, expect, rtol=0.01, err_msg=f"lift {lift}")


FOG = Material("fog", volume_only=True, absorption=SIGMA)
WALL = Material("wall", (0.5, 0.5, 0.5))


def test_seating_moves_touching_faces_outward_and_keeps_the_box_closed():
    """A box standing on the floor and against a wall (x = 1): its bottom moves down, its
    +x side out into the wall, by SEAT x the size; the corner on both moves both ways;
    vertices elsewhere stay; a box floating 1 cm above the floor (~500 contacts) and a
    floor with a medium of its own move nothing; the caller's mesh is unchanged."""
    v, f = box_mesh((0.5, 0.0, 0.5), (1.0, 1.0, 1.0))
    box = Mesh("box", v, f, materials=["fog"])
    pv, pf = box_mesh((0.0, 0.0, -0.05), (10.0, 10.0, 0.1))  # a thick floor, top at z = 0
    floor = Mesh("floor", pv, pf, materials=["wall"])
    wv = np.array([[1.0, -5, -1], [1.0, 5, -1], [1.0, 5, 5], [1.0, -5, 5]])
    wall = Mesh("wall", wv, np.array([[0, 2, 1], [0, 3, 2]]), materials=["wall"])
    mats = {"fog": FOG, "wall": WALL}
    out, seated = seat_volume_faces([box, floor, wall], mats)
    assert [(name, on) for name, on, _ in seated] == [("box", ["floor", "wall"])]
    assert out[1] is floor and out[2] is wall
    np.testing.assert_array_equal(box.vertices, v)  # the caller's copy untouched
    moved = out[0].vertices - v
    step = np.abs(moved).max()
    assert 0 < step < 1e-3
    # Size: the box's and the floor's largest coordinates and box diagonals (the larger
    # of its two partners' sums).
    size = 1.0 + math.sqrt(3.0) + 5.0 + math.sqrt(200.0 + 0.01)
    assert step == pytest.approx(SEAT * size, rel=1e-12) == seated[0][2]
    for p, d in zip(v, moved):
        expect = np.array([step if p[0] == 1.0 else 0.0, 0.0, -step if p[2] == 0.0 else 0.0])
        np.testing.assert_allclose(d, expect, atol=1e-15)
    # The faces stay a closed box: every edge still shared by exactly two triangles.
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, count = np.unique(edges, axis=0, return_counts=True)
    assert np.all(count == 2)
    # Not touching: a 1 cm gap; not a partner: a medium on the floor.
    hv, _ = box_mesh((0.5, 0.0, 0.51), (1.0, 1.0, 1.0))
    far = Mesh("far", hv, f, materials=["fog"])
    assert seat_volume_faces([far, floor], mats)[1] == []
    murky = {"fog": FOG, "wall": Material("wall", absorption=(1.0, 1.0, 1.0))}
    assert seat_volume_faces([box, floor], murky)[1] == []


def test_prepare_seats_the_box_below_the_floor():
    """Through engine.geometry.prepare: the box's bottom ends strictly below the floor's
    plane (in the float32 copy Embree traces too), its top where it was."""
    s = _scene(0.45)
    geo, _ = prepare(s)
    fog = geo.object_names.index("fog")
    rows = np.asarray(geo.object_id) == fog
    up = _tilt()[:, 2]  # the floor's normal
    z = (np.asarray(geo.v0)[rows] + geo.offset) @ up
    z32 = (geo.vertices32[np.asarray(geo.faces32)[rows]].astype(np.float64) + geo.offset) @ up
    assert z.min() < 0 and z.min() > -1e-3
    assert z32.min() < 0
    assert z.max() == pytest.approx(H, abs=1e-12)


def test_effect_report_names_the_seated_box_and_what_it_rests_on():
    """The "volume contact" line names the box and the floor (Cycles renders the contact
    with a hole: a user comparing needs to know); a sunk box gets none."""
    def lines(lift):
        film = render(_scene(0.45, lift), RenderSettings(workers=1, spp=1,
                                                         photon_mapping=False, seed=1))
        return [x for x in film.stats["effects"] if x.startswith("volume contact")]
    got = lines(0.0)
    assert len(got) == 1 and "'fog' on 'floor'" in got[0] and "sink" in got[0], got
    assert lines(-1e-3) == []
