"""A volume's face lying on another surface (a fog box standing on the floor, its side
against a wall): the surface belongs inside the medium.

A fog box whose bottom face lies in the floor's plane has two triangles at the same
place. Embree returns either of them for a ray inside the fog that reaches the floor: the
floor (lit and seen through the fog: right) or the box's face, which the ray crosses
(a transparent pass out of the medium, engine/media.py) and then, its origin offset past
both (engine/rayoffset.py), never meets the floor: it sees what lies under the floor (the
world), and a photon landing there is lost. Measured on newuser38's fog box (a spot inside
it over the floor, Volume bounces 0): the lit floor under the cone read 0.79 of the same
scene with the box sunk 0.1 m into the floor (our render), a speckled mixture of floor and
world. Cycles does the same at the same place: it skips only the primitive a ray leaves
(kernel/bvh/util.h intersection_skip_self), and its camera rays meet the floor in 56 % of
the samples there (Diffuse Color pass 0.226 of 0.400), reading 0.60 of the sunk box; the
share does not move with the scene's position (moved up 0.37 m or 1.913 m: 0.56, 0.56).
A user who stands a fog box on a floor means the floor inside the fog (the sunk box's
image, which both renderers agree on: docs/compatibility.md, fogfloor39).

seat_volume_faces makes that the geometry: each face of a volume-only material
(Material.volume_only) that lies in another surface's plane (all three corners within
CONTACT of that plane, facing along its normal, their boxes meeting) moves outward along
its own normal by SEAT, with every vertex at the same place in its mesh (a box's side
faces stretch with it: the mesh stays closed). The surface is then strictly inside the
medium: rays in the fog meet it first, and the rays leaving it (shadow rays, bounces,
photons) start inside the fog, past nothing. SEAT is far above the rounding of a hit
distance or a ray origin (~1e-7 of the coordinates) and far below what an image shows
(0.13 mm for a 4 m box on a 12 m floor). Partners are surfaces with no medium of their
own (a floor, a wall, clear glass), not other volumes. Not handled: placements without
a world-space copy (two-level instances) on either side; a box floating higher than
CONTACT above the floor is a real gap (the floor outside the fog, lit through it:
engine/shadowtransmittance.py).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

# Contact: a volume face's corners within this share of the size S (the touching meshes'
# largest coordinates plus their boxes' diagonals) of another surface's plane: 10x the ray
# offsets' ~1e-7 (engine/rayoffset.py G32_PLANE), ~40 float32 steps of Blender's vertex
# coordinates on a 10 m stage (S ~ 20 m: 20 micrometres).
CONTACT = 1e-6
# The move outward, a share of S: four contacts, so a face that touched from the outside
# side (up to CONTACT above the floor) ends at least 3 contacts past it.
SEAT = 4 * CONTACT
# Planes this close to parallel (|n_v . n_p|) may touch over an area.
PARALLEL = 1.0 - 1e-6
# Volume x partner face pairs tested in one numpy block (bounded scratch memory).
PAIR_BLOCK = 1 << 22


def _medium_free(materials, name) -> bool:
    """True for a surface a volume face may rest on: not volume-only, no medium inside."""
    m = materials.get(name)
    if m is None:
        return True
    if getattr(m, "volume_only", False):
        return False
    for field in ("absorption", "scattering", "volume_emission"):
        if np.any(np.asarray(getattr(m, field, (0.0, 0.0, 0.0)), np.float64) > 0):
            return False
    return True


def _slot_flags(mesh, test) -> np.ndarray:
    """(F,) bool: test(material name) for each face of mesh, evaluated once per slot."""
    names = list(mesh.materials) or ["default"]
    flags = np.array([bool(test(n)) for n in names], bool)
    if mesh.material_ids is None:
        return np.full(len(mesh.faces), flags[0], bool)
    return flags[np.clip(np.asarray(mesh.material_ids, np.int64), 0, len(names) - 1)]


def _faces(mesh, rows):
    """Corners (K,3,3) float64 and unit winding normals (K,3) of mesh's faces rows (K,),
    and (K,) bool which are not degenerate."""
    c = np.asarray(mesh.vertices, np.float64)[np.asarray(mesh.faces, np.int64)[rows]]
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    length = np.linalg.norm(n, axis=1)
    return c, n / np.maximum(length, 1e-300)[:, None], length > 0


def _faces_in_box(mesh, rows, lo, hi) -> np.ndarray:
    """The rows (of mesh's faces) whose bounding boxes meet the box lo..hi (3,): one axis
    at a time, so a large mesh far from the box costs one gather of one coordinate."""
    v = np.asarray(mesh.vertices, np.float64)
    f = np.asarray(mesh.faces, np.int64)
    for c in range(3):
        if not len(rows):
            break
        x = v[:, c][f[rows]]
        rows = rows[(x.max(axis=1) >= lo[c]) & (x.min(axis=1) <= hi[c])]
    return rows


def touching_faces(vol_c, vol_n, part_c, part_n, pad) -> np.ndarray:
    """(V,) bool: the volume faces (corners vol_c (V,3,3), unit normals vol_n (V,3)) lying
    on some partner face (part_c (P,3,3), part_n (P,3)): their boxes meet (to pad), the
    planes are parallel and the volume face's three corners lie within pad of the
    partner's plane."""
    out = np.zeros(len(vol_c), bool)
    if not len(vol_c) or not len(part_c):
        return out
    vlo, vhi = vol_c.min(axis=1) - pad, vol_c.max(axis=1) + pad
    plo, phi = part_c.min(axis=1), part_c.max(axis=1)
    pd = np.einsum("ij,ij->i", part_n, part_c[:, 0])
    step = max(1, PAIR_BLOCK // len(part_c))
    for a in range(0, len(vol_c), step):
        b = min(a + step, len(vol_c))
        meet = np.all((phi[None] >= vlo[a:b, None]) & (plo[None] <= vhi[a:b, None]), axis=2)
        vi, pi = np.nonzero(meet)
        if not len(vi):
            continue
        ok = np.abs(np.einsum("ij,ij->i", vol_n[a + vi], part_n[pi])) >= PARALLEL
        for k in range(3):
            dist = np.einsum("ij,ij->i", vol_c[a + vi, k], part_n[pi]) - pd[pi]
            ok &= np.abs(dist) <= pad
        out[a + vi[ok]] = True
    return out


def seat_volume_faces(meshes, materials) -> tuple[list, list]:
    """(meshes, seated): `meshes` (engine.scene.Mesh list) with the faces of volume-only
    materials that lie on another surface moved outward by SEAT x S (module docstring;
    new Mesh objects, the caller's unchanged, without their instance record: the copy
    no longer matches its prototype), and for each mesh moved (volume mesh name, [names
    of the meshes it rests on], the move in m) ([] and the list itself when none)."""
    vol_names = {n for n, m in materials.items() if getattr(m, "volume_only", False)}
    if not vol_names:
        return meshes, []
    plain = [i for i, m in enumerate(meshes) if len(m.faces) and not m.copyless]
    vols, parts = {}, {}
    for i in plain:
        is_vol = _slot_flags(meshes[i], lambda n: n in vol_names)
        if is_vol.any():
            vols[i] = np.nonzero(is_vol)[0]
        rest = _slot_flags(meshes[i], lambda n: _medium_free(materials, n)) & ~is_vol
        if rest.any():
            parts[i] = np.nonzero(rest)[0]
    if not vols or not parts:
        return meshes, []
    out, seated = list(meshes), []
    # Each partner's bounds (all its vertices: a cost filter and the size S).
    bounds = {j: (np.asarray(meshes[j].vertices, np.float64).min(axis=0),
                  np.asarray(meshes[j].vertices, np.float64).max(axis=0)) for j in parts}
    for i, vrows in vols.items():
        mesh = meshes[i]
        vc, vn, vok = _faces(mesh, vrows)
        lo, hi = vc.reshape(-1, 3).min(axis=0), vc.reshape(-1, 3).max(axis=0)
        touch = np.zeros(len(vc), bool)
        own = float(np.abs(vc).max()) + float(np.linalg.norm(hi - lo))
        size = 0.0  # S: the largest over the partners it touches
        partners = []
        for j, prows in parts.items():
            if j == i:
                continue
            plo, phi = bounds[j]
            s = own + float(max(np.abs(plo).max(), np.abs(phi).max())) + float(
                np.linalg.norm(phi - plo))
            pad = CONTACT * s
            if np.any(phi < lo - pad) or np.any(plo > hi + pad):
                continue
            near = _faces_in_box(meshes[j], prows, lo - pad, hi + pad)
            if not len(near):
                continue
            pc, pn, pok = _faces(meshes[j], near)
            hit = touching_faces(vc, vn, pc[pok], pn[pok], pad) & vok
            if hit.any():
                touch |= hit
                size = max(size, s)
                partners.append(meshes[j].name)
        if not touch.any():
            continue
        verts = np.asarray(mesh.vertices, np.float64)
        # Vertices at one place move together (a mesh split at its seams stays closed).
        _, group = np.unique(verts, axis=0, return_inverse=True)
        group = group.reshape(-1)
        faces = np.asarray(mesh.faces, np.int64)[vrows[touch]]
        normals = vn[touch]
        # Each distinct plane a vertex touches moves it once (a box's bottom corner on the
        # floor and against a wall moves down and out; the quad's two triangles once).
        key = np.round(normals * 1e6).astype(np.int64)
        g = group[faces].reshape(-1)
        k = np.repeat(key, 3, axis=0)
        pairs, first = np.unique(np.column_stack([g, k]), axis=0, return_index=True)
        move = np.zeros((group.max() + 1, 3))
        np.add.at(move, pairs[:, 0], np.repeat(normals, 3, axis=0)[first])
        out[i] = replace(mesh, vertices=verts + SEAT * size * move[group], prototype=None,
                         matrix=None)
        seated.append((mesh.name, partners, SEAT * size))
    return out, seated
