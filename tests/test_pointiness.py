"""Cycles' Pointiness (engine/pointiness.py) on meshes whose value is known: a cube's
corners, a flat grid, a dent, and the same meshes with their vertices split (welded back
as Cycles welds them)."""
import numpy as np

from engine.pointiness import pointiness, weld_map


def _cube():
    co = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    edges = [(i, j) for i in range(8) for j in range(i + 1, 8)
             if np.abs(co[i] - co[j]).sum() == 2]
    return co, co / np.linalg.norm(co, axis=1, keepdims=True), np.array(edges)


def _grid(n=5, dent=0.0):
    """(n x n) vertices on z = 0 over [-1, 1]^2, the centre vertex moved by `dent` along
    z; normals +z; edges along x and y."""
    xs = np.linspace(-1, 1, n)
    co = np.array([[x, y, 0.0] for y in xs for x in xs])
    co[(n * n) // 2, 2] = dent
    idx = np.arange(n * n).reshape(n, n)
    edges = np.concatenate([np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], 1),
                            np.stack([idx[:-1].ravel(), idx[1:].ravel()], 1)])
    nrm = np.tile([0.0, 0.0, 1.0], (n * n, 1))
    return co, nrm, edges


def test_cube_corners_read_the_angle_to_their_edges():
    co, nrm, edges = _cube()
    # Each corner: normal along the diagonal, its three edges' mean -diagonal / 3:
    # acos(-1/sqrt(3)) / pi, and every neighbour the same (the blur keeps it).
    np.testing.assert_allclose(pointiness(co, nrm, edges),
                               np.arccos(-1.0 / np.sqrt(3.0)) / np.pi, rtol=1e-6)


def test_flat_interior_is_one_half_and_a_dent_reads_its_angles():
    co, nrm, edges = _grid()
    p = pointiness(co, nrm, edges).reshape(5, 5)
    # Interior vertices (with interior neighbours): edges balance, raw acos(0) / pi.
    np.testing.assert_allclose(p[2, 2], 0.5, atol=1e-6)
    dent = pointiness(*_grid(dent=-0.3)).reshape(5, 5)
    bump = pointiness(*_grid(dent=+0.3)).reshape(5, 5)
    # The dent's centre: its 4 edges rise by 0.3 over 0.5, mean direction z = s = 0.3 /
    # |(0.5, 0.3)|: raw acos(s) / pi; each neighbour's 4 edges (one falls) average
    # -s / 4: acos(-s / 4) / pi; the blur averages the centre with its 4 neighbours.
    s = 0.3 / np.hypot(0.5, 0.3)
    want = (np.arccos(s) + 4.0 * np.arccos(-s / 4.0)) / np.pi / 5.0
    np.testing.assert_allclose(dent[2, 2], want, rtol=1e-6)
    assert dent[2, 2] < 0.5 < bump[2, 2]
    # Symmetric: a dent of depth d reads 1 - (a bump of height d) at the centre.
    np.testing.assert_allclose(dent[2, 2] + bump[2, 2], 1.0, atol=1e-6)


def test_split_vertices_are_welded_as_cycles_welds_them():
    """Every vertex duplicated (an edge-split mesh: each face its own corners): the
    values equal the welded mesh's, the duplicates' original being the lower index."""
    co, nrm, edges = _grid(dent=0.2)
    n = len(co)
    co2 = np.vstack([co, co])
    nrm2 = np.vstack([nrm, nrm])
    # The copies carry half the edges each (as split faces do), on their own indices.
    half = len(edges) // 2
    edges2 = np.vstack([edges[:half], edges[half:] + n])
    np.testing.assert_array_equal(weld_map(co2), np.concatenate([np.arange(n)] * 2))
    p2 = pointiness(co2, nrm2, edges2)
    np.testing.assert_allclose(p2[:n], pointiness(co, nrm, edges), rtol=1e-6)
    np.testing.assert_array_equal(p2[:n], p2[n:])


def test_weld_tolerance_is_cycles_float_epsilon():
    co = np.array([[0.0, 0.0, 0.0], [0.0, 1e-4, -1e-4], [0.0, 1e-2, -1e-2]], np.float32)
    # Equal coordinate sums; squared distance 2e-8 < FLT_EPSILON welds, 2e-4 does not.
    np.testing.assert_array_equal(weld_map(co), [0, 0, 2])
