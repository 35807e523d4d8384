"""Voxel grids of Volume objects (engine/voxelgrid.py, vdb41): trilinear interpolation
between voxel centres, the GridAttribute node per object, the majorant cells bounded by
the voxels under them, and the medium they make: a constant grid renders as the
homogeneous medium of that density, a grid linear in z has the closed-form
transmittance of that ramp."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.render import prepare_context, render
from engine.scene import Material, Mesh
from engine.shadernodes import Math
from engine.voxelgrid import GridAttribute, VoxelGrid, field_bounds

SIGMA_A = np.array([0.5, 1.0, 2.0])  # 1/m at density 1
A = 4.0  # the ramp: density A z


def _lattice_to_world(origin, step):
    M = np.eye(4)
    M[:3, :3] *= np.asarray(step, np.float64)
    M[:3, 3] = origin
    return M


def _grid(fn, lo, hi, counts, name="density"):
    """A VoxelGrid of fn(x, y, z) at the voxel centres of a lattice of `counts` points
    from lo to hi (both included)."""
    lo, hi, counts = (np.asarray(x, np.float64) for x in (lo, hi, counts))
    step = (hi - lo) / (counts - 1)
    axes = [lo[a] + step[a] * np.arange(int(counts[a])) for a in range(3)]
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    return VoxelGrid(fn(X, Y, Z).astype(np.float32), _lattice_to_world(lo, step), name)


def test_trilinear_interpolation_between_voxel_centres():
    rng = np.random.default_rng(3)
    g = _grid(lambda x, y, z: 1.0 + 2.0 * x - 3.0 * y + 0.5 * z, (-1, -1, 0), (1, 2, 1),
              (5, 7, 4))
    p = np.array([-1, -1, 0]) + np.array([2, 3, 1]) * rng.random((500, 3))
    # a linear function is reproduced exactly by trilinear interpolation
    np.testing.assert_allclose(g.sample(p), 1.0 + 2.0 * p[:, 0] - 3.0 * p[:, 1]
                               + 0.5 * p[:, 2], rtol=1e-5, atol=1e-5)
    # voxel centres give the voxels' values; outside the lattice: the background 0
    v = np.asarray(g.values, np.float64)
    np.testing.assert_allclose(g.sample(np.array([[-1.0, -1.0, 0.0], [1.0, 2.0, 1.0]])),
                               [v[0, 0, 0], v[-1, -1, -1]], rtol=1e-6)
    np.testing.assert_array_equal(g.sample(np.array([[1.01, 0.0, 0.5], [0, 0, -0.2]])), 0.0)
    # a product x y is bilinear: exact too, and the midpoint of a cell is the mean of 8
    b = _grid(lambda x, y, z: x * y * z, (0, 0, 0), (1, 1, 1), (2, 2, 2))
    assert b.sample(np.array([[0.5, 0.5, 0.5]]))[0] == pytest.approx(1 / 8)
    # a vector grid: (n,3)
    c = VoxelGrid(np.ones((3, 3, 3, 3), np.float32) * [0.2, 0.4, 0.6], np.eye(4), "color")
    np.testing.assert_allclose(c.sample(np.array([[1.0, 1.5, 0.5]])), [[0.2, 0.4, 0.6]],
                               rtol=1e-6)


class _Points:
    """A PointGeometry stand-in: points (n,3) of objects obj (n,), grids per object."""

    def __init__(self, points, obj, grids):
        self.points, self.obj, self.volume_grids = points, obj, grids
        self.offset = np.zeros(3)

    def hit_points(self, prim, u, v):
        return self.points[prim]


def test_grid_attribute_reads_the_points_object():
    ramp = _grid(lambda x, y, z: z, (0, 0, 0), (1, 1, 1), (3, 3, 3))
    temp = _grid(lambda x, y, z: 1000.0 + 0 * x, (0, 0, 0), (1, 1, 1), (2, 2, 2),
                 "temperature")
    pts = np.array([[0.5, 0.5, 0.25], [0.5, 0.5, 0.25], [0.5, 0.5, 0.75]])
    geo = _Points(pts, np.array([0, 1, 0]), {0: {"density": ramp, "temperature": temp}})
    prim = np.arange(3)
    z = np.zeros(3)
    # object 1 has no grids: `missing`
    np.testing.assert_allclose(GridAttribute("density", "FAC", 1.0).evaluate(geo, prim, z, z),
                               [0.25, 1.0, 0.75])
    np.testing.assert_allclose(GridAttribute("density", "COLOR").evaluate(geo, prim, z, z),
                               [[0.25] * 3, [0.0] * 3, [0.75] * 3])
    np.testing.assert_allclose(GridAttribute("temperature").evaluate(geo, prim, z, z),
                               [1000.0, 0.0, 1000.0])
    np.testing.assert_allclose(GridAttribute("flame").evaluate(geo, prim, z, z), 0.0)
    np.testing.assert_allclose(GridAttribute("density", "ALPHA").evaluate(geo, prim, z, z),
                               [1.0, 0.0, 1.0])
    with pytest.raises(ValueError):
        GridAttribute("density", "NORMAL")


def test_field_bounds_hold_the_voxels_between_samples():
    """A 64^3 grid of zeros with one voxel of 5 (a puff smaller than the majorant's
    lattice spacing): the boxes' bounds from the voxels hold the interpolated field at
    random points, through a tree's arithmetic (Density 2 x the grid), and the spike's
    box reaches 10."""
    v = np.zeros((64, 64, 64), np.float32)
    v[33, 17, 41] = 5.0
    g = VoxelGrid(v, _lattice_to_world((0, 0, 0), (1 / 63,) * 3))
    tree = Math("MULTIPLY", 2.0, GridAttribute("density", "FAC", 1.0))
    n = 16
    ii = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    lo = ii / n
    hi = lo + 1.0 / n
    b_lo, b_hi = field_bounds(tree, 0, {"density": g}, lo, hi)
    spike = np.array([33, 17, 41]) / 63.0
    cell = np.floor(spike * n).astype(int)
    assert b_hi[(cell[0] * n + cell[1]) * n + cell[2]] == pytest.approx(10.0)
    rng = np.random.default_rng(1)
    p = rng.random((20000, 3))
    p[:5000] = spike + (rng.random((5000, 3)) - 0.5) * 2.0 / 63.0  # around the spike
    p = np.clip(p, 0.0, 1.0 - 1e-9)
    f = 2.0 * g.sample(p)
    c = np.floor(p * n).astype(int)
    flat = (c[:, 0] * n + c[:, 1]) * n + c[:, 2]
    assert f.max() > 5.0
    assert np.all(f <= b_hi[flat] + 1e-6) and np.all(f >= b_lo[flat] - 1e-6)
    # a node the bounds do not know: None (the sampled lattice stays)
    from engine.shadernodes import Noise, ObjectSpacePosition
    assert field_bounds(Noise(ObjectSpacePosition(np.eye(4)), {}), 0, {"density": g},
                        lo, hi) is None


def _slab(grid, floor=0.25, density=None):
    """Looking straight down through a 20 x 20 x 0.5 m volume-only slab (z 0..0.5) that
    carries `grid` as its "density" grid (a Volume object's box) read by Principled
    Volume's Density Attribute (density: a Density socket value scaling it), an
    emissive floor of radiance 1 at z = floor, black world."""
    s = PaperScene(8, 8)
    node = GridAttribute("density", "FAC", 1.0)
    if density is not None:
        node = Math("MULTIPLY", density, node)
    s.add_material(Material("smoke", volume_only=True, absorption=SIGMA_A,
                            density_texture=node))
    box = s.add_box((0, 0, 0.25), (20.0, 20.0, 0.5), "smoke", name="smoke")
    s.meshes[-1].volume_grids = {"density": grid}
    s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
    s.add_plane((0, 0, floor), (0, 0, 1), 30.0, "glow", name="floor")
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    del box
    return s


def _image(scene, spp=64):
    film = render(scene, RenderSettings(workers=1, spp=spp, photon_mapping=False, seed=4))
    return np.asarray(film.combined, np.float64)[..., :3]


def test_a_constant_grid_renders_as_the_homogeneous_medium():
    """A grid of 0.35 everywhere under Density 2: the slab's transmittance to a floor
    inside it (z = 0.25) is exp(-sigma_a 0.7 x 0.25), as the homogeneous slab of density
    0.7 (the majorant cells' bounds are the voxels' exact range: nothing to track)."""
    g = _grid(lambda x, y, z: 0.35 + 0 * x, (-10, -10, 0), (10, 10, 0.5), (5, 5, 6))
    img = _image(_slab(g, density=2.0), spp=16)
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0),
                               np.exp(-SIGMA_A * 0.7 * 0.25), rtol=1e-6)
    ctx = prepare_context(_slab(g, density=2.0), RenderSettings(workers=1))
    assert np.all(ctx.hetero.grid.rad == 0.0)


def test_the_transmittance_of_a_linear_ramp_grid():
    """A grid A z (0 at the slab's bottom, 2 at its top) on 41 voxels along z: the floor
    at z = 0.25 seen through the upper half keeps exp(-sigma_a A (0.5^2 - 0.25^2) / 2)
    per channel (ratio tracking against the voxel-bounded majorant; 8 x 8 px x 256 spp,
    within 1.5 %)."""
    g = _grid(lambda x, y, z: A * z + 0 * x, (-10, -10, 0), (10, 10, 0.5), (4, 4, 41))
    img = _image(_slab(g), spp=256)
    expect = np.exp(-SIGMA_A * A * (0.25 - 0.0625) / 2)
    assert np.isfinite(img).all()
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0), expect, rtol=0.015)


def test_mesh_keeps_its_grids():
    g = _grid(lambda x, y, z: x, (0, 0, 0), (1, 1, 1), (2, 2, 2))
    m = Mesh("v", g.corners(), np.array([[0, 1, 3]]), volume_grids={"density": g})
    assert m.volume_grids["density"] is g
    # the box of the lattice: corners at the first and last voxel centres
    np.testing.assert_allclose(g.corners().min(axis=0), 0.0)
    np.testing.assert_allclose(g.corners().max(axis=0), 1.0)


def test_a_tree_the_bounds_do_not_follow_keeps_the_voxels_cells_open():
    """Density = (Noise + 0.5) x a grid of zeros with one voxel of 4 (a wisp between the
    majorant's lattice points): field_bounds cannot bound the Noise, the sampled lattice
    reads 0 around the wisp, and the cell holding it must still have a positive
    sampling majorant (a pdf of 0 there would lose its scattering; checked to fail
    without voxelgrid.occupied)."""
    from engine.shadernodes import Noise, ObjectSpacePosition
    # 192 voxels across under 32 majorant cells sampled every 3 voxels: the wisp's
    # footprint (91 +- 1 voxels) lies between the samples at 90 and 93
    v = np.zeros((193, 193, 193), np.float32)
    v[91, 91, 91] = 4.0
    g = VoxelGrid(v, _lattice_to_world((-1.0, -1.0, 0.0), (2.0 / 192,) * 3))
    tree = Math("MULTIPLY", Math("ADD", Noise(ObjectSpacePosition(np.eye(4)), {}), 0.5),
                GridAttribute("density", "FAC", 1.0))
    s = PaperScene(8, 8)
    s.add_material(Material("wisp", volume_only=True, absorption=SIGMA_A,
                            scattering=(0.5, 0.5, 0.5), density_texture=tree))
    s.add_box((0, 0, 1.0), (2.0, 2.0, 2.0), "wisp", name="wisp")
    s.meshes[-1].volume_grids = {"density": g}
    s.add_sun((0, 0, -1), 1.0)
    s.set_camera((0, -5, 1), (0, 0, 1))
    ctx = prepare_context(s, RenderSettings(workers=1))
    het = ctx.hetero
    (m, _), = het.fields.items()
    k = int(het.object[0])
    grid = het.grid
    slot = int(grid.slot_of[k, m])
    p = np.array([-1.0, -1.0, 0.0]) + np.array([91, 91, 91]) * 2.0 / 192
    n = grid.dims[slot]
    i = np.clip(np.floor((p - ctx.geo.offset - grid.origin[slot]) / grid.cell[slot])
                .astype(int), 0, n - 1)
    flat = grid.offset[slot] + (i[0] * n[1] + i[1]) * n[2] + i[2]
    f = het.density(m, (p - ctx.geo.offset)[None], np.array([k]))[0]
    assert f > 1.0
    assert grid.sup[flat] > 0.0 and grid.rad[flat] > 0.0
    # cells far from the wisp stay empty (no tracking there)
    assert (grid.sup[grid.offset[slot]:grid.offset[slot] + np.prod(n)] == 0).mean() > 0.9
