"""Scene preparation: all meshes merged into flat triangle tables, re-centred near the origin.

Re-centring matters because Embree works in float32: at 1e5 m the spacing of float32 is
~8 mm, so a scene far from the origin would show acne and leaks (docs/design.md, Embree
(embreex) facts).
Ray offsets are not set here: they are bounds on each point's rounding error
(engine/rayoffset.py), never a share of the scene's size.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import raymaterials
from .rayoffset import surface_offset, triangle_tilt, ulp32
from .sampling import dot, luminance, normalize
from .parallel import Cancelled
from .instancing import Instances
from .sharedrows import RowColumn, SharedRows
from .scene import Material, Scene, emission_sides
from .resources import two_level_instances
from .worldmedium import table_materials
from .displacement import displace_meshes
from .volumecontact import seat_volume_faces

# Ray classes (Cycles' ray visibility): one bit each in Geometry.visibility.
CAMERA, DIFFUSE, GLOSSY, TRANSMISSION, SHADOW = 1, 2, 4, 8, 16
ALL_RAYS = CAMERA | DIFFUSE | GLOSSY | TRANSMISSION | SHADOW

# Material table columns (one row per material).
MAT_FIELDS = ("metallic", "roughness", "transmission", "ior", "specular", "alpha")


@dataclass
class MaterialTable:
    names: list
    base_color: np.ndarray    # (M,3)
    emission: np.ndarray      # (M,3)
    metallic: np.ndarray      # (M,)
    roughness: np.ndarray
    transmission: np.ndarray
    ior: np.ndarray
    specular: np.ndarray
    alpha: np.ndarray
    textures: list            # per material: engine.textures object (evaluate()) or None
    normal_maps: list = None  # per material: engine.normalmap.NormalMap or None
    alpha_textures: list = None  # per material: alpha node (Material.alpha_texture) or None
    closure_params: np.ndarray = None  # (M, principled.N_MAT): the closures' columns
    coat_weight: np.ndarray = None     # (M,)
    sheen_weight: np.ndarray = None    # (M,)
    translucent: np.ndarray = None     # (M,) the translucent lobe's share (Material.translucent)
    scalar_textures: list = None  # per material: [(closure column, node, lo, hi)] or None
    emission_textures: list = None  # per material: colour node on the emission, or None
    diffuse_share: np.ndarray = None   # (M,) (1 - metallic)(1 - transmission) at its
                          # largest over the material's textured values (textures.scalar_ranges)
    pass_index: np.ndarray = None      # (M,) float64 Material.pass_index (Material Index pass)
    emission_sides: np.ndarray = None  # (M,) int64 sides light sampling covers
                                       # (scene.emission_sides; None: both)
    absorption: np.ndarray = None      # (M,3) float64 sigma_a (1/m) of the medium inside
                                       # (Material.absorption; engine/media.py)
    scattering: np.ndarray = None      # (M,3) float64 sigma_s (1/m) of that medium
    anisotropy: np.ndarray = None      # (M,) float64 its Henyey-Greenstein g
                                       # (Material.scattering, .anisotropy;
                                       # engine/volumescatter.py)
    volume_emission: np.ndarray = None  # (M,3) float64 its emission (W/m^2/sr per m;
                                        # Material.volume_emission, engine/volumeemission.py)
    volume_only: np.ndarray = None     # (M,) bool a volume without a surface (its
                                       # surface a transparent pass: Material.volume_only)
    density_textures: list = None      # per material: its medium's density field
                                       # (Material.density_texture, a node; None: none;
                                       # engine/heterogeneous.py)
    aovs: list = None                  # per material: Material.aovs ({} without AOV
                                       # Output nodes; engine/datapasses.py)
    holdout: np.ndarray = None         # (M,) bool: camera rays see a hole (Material.holdout)
    ray_remap: dict = None             # {ray class bit: (M,) int64 row that class meets}
                                       # for the classes a Light Path variant changes
                                       # (engine/raymaterials.py; None / {}: none)
    volume_emission_textures: list = None  # per material: its medium's emission field
    albedo_textures: list = None       # and albedo field (Material.volume_emission_texture,
                                       # .albedo_texture; engine/volumefields.py)
    subsurface: list = None            # per material: its random-walk BSSRDF
                                       # (Material.subsurface, engine/subsurfacewalk.py) or None

    @classmethod
    def build(cls, materials: list[Material]) -> "MaterialTable":
        # The materials' Light Path variants become rows of their own after the given
        # ones (engine/raymaterials.py; none: the rows are the materials as given).
        materials, ray_remap = raymaterials.expand(materials)
        cols = {f: np.array([getattr(m, f) for m in materials], np.float64) for f in MAT_FIELDS}
        return cls(names=[m.name for m in materials],
                   base_color=np.array([m.base_color for m in materials], np.float64).reshape(-1, 3),
                   emission=np.array([m.emission for m in materials], np.float64).reshape(-1, 3),
                   textures=[m.texture for m in materials],
                   normal_maps=[m.normal_map for m in materials],
                   alpha_textures=[m.alpha_texture for m in materials],
                   closure_params=closure_params(materials),
                   coat_weight=np.array([m.coat_weight for m in materials], np.float64),
                   sheen_weight=np.array([m.sheen_weight for m in materials], np.float64),
                   translucent=np.array([getattr(m, "translucent", 0.0) for m in materials],
                                        np.float64),
                   scalar_textures=[scalar_columns(m) for m in materials],
                   emission_textures=[m.emission_texture for m in materials],
                   pass_index=np.array([getattr(m, "pass_index", 0) for m in materials],
                                       np.float64),
                   emission_sides=np.array([emission_sides(getattr(m, "emission_sampling",
                                                                   "AUTO"), m.emission)
                                            for m in materials], np.int64),
                   absorption=np.array([getattr(m, "absorption", (0.0, 0.0, 0.0))
                                        for m in materials], np.float64).reshape(-1, 3),
                   scattering=np.array([getattr(m, "scattering", (0.0, 0.0, 0.0))
                                        for m in materials], np.float64).reshape(-1, 3),
                   anisotropy=np.array([getattr(m, "anisotropy", 0.0) for m in materials],
                                       np.float64),
                   volume_emission=np.array([getattr(m, "volume_emission", (0.0, 0.0, 0.0))
                                             for m in materials],
                                            np.float64).reshape(-1, 3),
                   volume_only=np.array([bool(getattr(m, "volume_only", False))
                                         for m in materials], np.bool_),
                   density_textures=[getattr(m, "density_texture", None)
                                     for m in materials],
                   aovs=[getattr(m, "aovs", None) or {} for m in materials],
                   holdout=np.array([bool(getattr(m, "holdout", False))
                                     for m in materials], np.bool_),
                   volume_emission_textures=[getattr(m, "volume_emission_texture", None)
                                             for m in materials],
                   albedo_textures=[getattr(m, "albedo_texture", None) for m in materials],
                   subsurface=[getattr(m, "subsurface", None) for m in materials],
                   ray_remap=ray_remap, **cols)

    @property
    def has_scalar_textures(self) -> bool:
        return any(x is not None for x in (self.scalar_textures or ()))

    @property
    def has_diffuse(self) -> np.ndarray:
        share = (self.diffuse_share if self.diffuse_share is not None
                 else (1 - self.metallic) * (1 - self.transmission))
        if self.translucent is not None:
            share = share * (1 - self.translucent)
        return (share * self.alpha * self.base_color.max(axis=1)) > 0

    @property
    def has_specular(self) -> np.ndarray:
        """Materials with a lobe the camera side continues (mirror-like, refractive, glossy,
        sheen, translucent or a transparent pass)."""
        dielectric = (1 - self.metallic) * (1 - self.transmission)
        tl = self.translucent if self.translucent is not None else 0.0
        return ((self.metallic * self.base_color.max(axis=1) > 0) | (self.transmission > 0)
                | (dielectric * self.specular > 0) | (self.alpha < 1) | (tl > 0)
                | (self.coat_weight > 0) | (self.sheen_weight > 0) | self.has_alpha_texture) & True

    @property
    def has_alpha_texture(self) -> np.ndarray:
        """(M,) bool: materials whose alpha varies per hit (an alpha texture)."""
        nodes = self.alpha_textures or [None] * len(self.alpha)
        return np.array([n is not None for n in nodes], bool)


def scalar_columns(m: Material):
    """[(closure_params column, node, lo, hi)] of a material's texture-driven scalar
    inputs (Material.scalar_textures; lo, hi: Cycles' clamp), or None. A colour input
    (scene.COLOR_INPUTS) has a slice of its three columns for column."""
    if not m.scalar_textures:
        return None
    from .closures import principled as pr
    from .scene import SCALAR_INPUTS
    col = {"roughness": pr.M_ROUGH, "metallic": pr.M_METALLIC, "specular": pr.M_SPEC,
           "transmission": pr.M_TRANS,
           "specular_ior_level": pr.M_LEVEL, "coat_weight": pr.M_COAT_W,
           "coat_roughness": pr.M_COAT_ROUGH, "sheen_weight": pr.M_SHEEN_W,
           "sheen_roughness": pr.M_SHEEN_ROUGH,
           "ior": pr.M_IOR, "coat_ior": pr.M_COAT_IOR, "multiscatter": pr.M_MULTI,
           "anisotropic": pr.M_ANISO, "anisotropic_rotation": pr.M_AROT,
           "node": pr.M_NODE,
           "specular_tint": slice(pr.M_STINT, pr.M_STINT + 3),
           "coat_tint": slice(pr.M_CTINT, pr.M_CTINT + 3),
           "sheen_tint": slice(pr.M_SHEEN_TINT, pr.M_SHEEN_TINT + 3)}
    return [(col[k], node, *SCALAR_INPUTS[k]) for k, node in m.scalar_textures.items()]


def node_code(node: str) -> int:
    """closures/principled.py's code (its M_NODE column) of a Material.node name: the
    closure model whose colour and lobes the row takes ('principled', 'glossy', 'glass',
    'refraction')."""
    from .closures import principled as pr
    return {"principled": pr.NODE_PRINCIPLED, "glossy": pr.NODE_GLOSSY,
            "glass": pr.NODE_GLASS, "refraction": pr.NODE_REFRACTION}[node]


def closure_params(materials: list[Material]) -> np.ndarray:
    """(M, principled.N_MAT) float64 rows of the columns engine/closures/principled.py
    reads (its M_* constants)."""
    from .closures import principled as pr
    out = np.zeros((len(materials), pr.N_MAT))
    for i, m in enumerate(materials):
        row = out[i]
        row[pr.M_ALPHA] = m.alpha
        row[pr.M_METALLIC] = m.metallic
        row[pr.M_ROUGH] = m.roughness
        row[pr.M_TRANS] = m.transmission
        row[pr.M_IOR] = m.ior
        row[pr.M_SPEC] = m.specular
        row[pr.M_LEVEL] = m.specular_ior_level
        row[pr.M_STINT:pr.M_STINT + 3] = m.specular_tint
        row[pr.M_COAT_W] = m.coat_weight
        row[pr.M_COAT_ROUGH] = m.coat_roughness
        row[pr.M_COAT_IOR] = m.coat_ior
        row[pr.M_CTINT:pr.M_CTINT + 3] = m.coat_tint
        row[pr.M_MULTI] = 1.0 if m.multiscatter else 0.0
        row[pr.M_NODE] = node_code(m.node)
        if m.glossy_color is not None:
            row[pr.M_GCOL:pr.M_GCOL + 3] = m.glossy_color
            row[pr.M_HAS_GCOL] = 1.0
        row[pr.M_SHEEN_W] = m.sheen_weight
        row[pr.M_SHEEN_ROUGH] = m.sheen_roughness
        row[pr.M_SHEEN_TINT:pr.M_SHEEN_TINT + 3] = m.sheen_tint
        row[pr.M_TTINT:pr.M_TTINT + 3] = m.transparent_tint
        row[pr.M_ADD] = m.closure_weight - 1.0
        row[pr.M_ANISO] = m.anisotropic
        row[pr.M_AROT] = m.anisotropic_rotation
        row[pr.M_TL] = getattr(m, "translucent", 0.0)
        tcol = getattr(m, "translucent_color", None)
        if tcol is not None:
            row[pr.M_TLCOL:pr.M_TLCOL + 3] = tcol
            row[pr.M_HAS_TLCOL] = 1.0
    return out


PIECE_TRIANGLES = 1 << 16  # triangles prepared between two cancel checks (~0.05 s)


class PerTriangle:
    """A per-triangle quantity computed from Geometry's edge tables when it is read instead
    of being stored (it would cost 8-72 B per triangle): x[prim], x[mask] and
    np.take(x, prim, axis=0) compute only those rows (bit-identical to computing them all),
    in pieces of PIECE_TRIANGLES rows so a large read needs little scratch memory;
    np.asarray(x) computes every row."""

    def __init__(self, geo: "Geometry", rows):
        self._geo = geo
        self._rows = rows  # rows(geo, idx) -> (len(idx), ...) values

    def __len__(self) -> int:
        return self._geo.count

    def __getitem__(self, key):
        if isinstance(key, (int, np.integer)):
            return self[np.array([key])][0]
        key = np.asarray(key) if not isinstance(key, slice) else key
        if isinstance(key, slice):
            idx = np.arange(self._geo.count)[key]
        elif key.dtype == np.bool_:
            idx = np.nonzero(key)[0]
        else:
            idx = key.astype(np.int64, copy=False)
        flat = idx.reshape(-1)
        if len(flat) <= PIECE_TRIANGLES:
            out = self._rows(self._geo, flat)
        else:
            parts = [self._rows(self._geo, flat[a:a + PIECE_TRIANGLES])
                     for a in range(0, len(flat), PIECE_TRIANGLES)]
            out = np.concatenate(parts)
        return out.reshape(idx.shape + out.shape[1:])

    def take(self, indices, axis=None, out=None, mode="raise"):
        """np.take(x, prim, axis=0) (and axis=None for a quantity of one value a row)."""
        if out is not None or mode != "raise" or axis not in (0, None):
            raise ValueError("PerTriangle.take: only axis=0 without out or mode")
        rows = self[indices]
        if axis is None and rows.ndim > np.ndim(indices):
            raise ValueError("PerTriangle.take: axis=None of a multi-valued quantity")
        return rows

    def __array__(self, dtype=None, copy=None):
        out = self[slice(None)]
        return out if dtype is None else out.astype(dtype)


def _ng_rows(geo, idx):
    c = np.cross(np.take(geo.e1, idx, axis=0), np.take(geo.e2, idx, axis=0))
    return c / np.maximum(np.linalg.norm(c, axis=1), 1e-300)[:, None]


def _area_rows(geo, idx):
    c = np.cross(np.take(geo.e1, idx, axis=0), np.take(geo.e2, idx, axis=0))
    return np.linalg.norm(c, axis=1) / 2.0


def _round32_rows(geo, idx):
    v0 = np.take(geo.v0, idx, axis=0)
    corners = np.stack([v0, v0 + np.take(geo.e1, idx, axis=0),
                        v0 + np.take(geo.e2, idx, axis=0)], axis=1)
    # Half a float32 spacing, as a bound continuous in the coordinates (rayoffset.ulp32).
    return 0.5 * ulp32(corners)


def _tilt32_rows(geo, idx):
    v0 = np.take(geo.v0, idx, axis=0)
    corners = np.stack([v0, v0 + np.take(geo.e1, idx, axis=0),
                        v0 + np.take(geo.e2, idx, axis=0)], axis=1)
    return triangle_tilt(corners.astype(np.float32))


def _terminator_rows(geo, idx):
    return geo.object_terminator[np.take(geo.object_id, idx)]


def _terminator_shading_rows(geo, idx):
    return geo.object_terminator_shading[np.take(geo.object_id, idx)]


def area_sum(geo, mask) -> float:
    """Total area (m^2) of the triangles where mask (T,) bool is True, a piece at a time."""
    if getattr(geo, "shared", None) is not None:
        return geo.shared.area_sum(mask)
    total = 0.0
    for a in range(0, geo.count, PIECE_TRIANGLES):
        idx = a + np.nonzero(mask[a:a + PIECE_TRIANGLES])[0]
        total += float(_area_rows(geo, idx).sum())
    return total


@dataclass
class Geometry:
    """Merged triangles in re-centred world space (world = local + offset).

    Memory per triangle (docs/performance.md, "Memory per triangle"): v0, e1, e2 (72 B),
    material, object_id (8 B), smooth, visibility, holdout (3 B); corner normals (36 B)
    only when some mesh has normals, corner UVs (24 B) only when some mesh has UVs. ng,
    area, round32 and tilt32 are computed from the corners when read, terminator and
    terminator_shading from the per-object values (PerTriangle). vertices32 / faces32 (float32 corners shared as in the
    meshes, int32 indices) feed the BVH build; Embree reads them in place (shared
    buffers, engine/accel.py), so the Accel keeps them and release_build_arrays only
    drops the Geometry's references."""

    offset: np.ndarray        # (3,) translation removed from everything
    extent: float             # bounding-box diagonal (scene size; never a length floor)
    v0: np.ndarray            # (T,3) triangle corners, float64
    e1: np.ndarray            # v1 - v0
    e2: np.ndarray            # v2 - v0
    corner_normals: np.ndarray  # (T,3,3) float32 unit shading normals at the corners, or
                              # (0,3,3) when no mesh has normals (every triangle flat)
    smooth: np.ndarray        # (T,) bool: shading normals differ from the geometric one
    corner_uvs: np.ndarray | None  # (T,3,2) float32, None when no mesh has UVs (reads 0)
    material: np.ndarray      # (T,) int32 index into the material table
    object_id: np.ndarray     # (T,) int32 index into object_names
    object_names: list
    visibility: np.ndarray    # (T,) uint8 ray-class bits of the rays that see the triangle
    holdout: np.ndarray       # (T,) bool: camera rays that hit it give alpha 0
    vertices32: np.ndarray | None  # (V,3) float32 mesh vertices for Embree (build only)
    object_terminator: np.ndarray  # (O,) float32 Cycles' shadow terminator geometry
                              # offset per object (Mesh.shadow_terminator_offset)
    object_terminator_shading: np.ndarray  # (O,) float32 the shading offset per object
    faces32: np.ndarray | None  # (T,3) int32 into vertices32 (build only)
    bounds: np.ndarray        # (2,3) re-centred bounding box
    corner_colors: np.ndarray | None = None  # (T,3,3) linear colour attribute; None: no
                              # mesh has one (a mesh without one reads black, as in Cycles)
    corner_coordinates: dict | None = None  # name -> (T,3,3) texture coordinates (Mesh);
                              # zeros on meshes without them
    shared: "SharedRows | None" = None  # instanced rows stored once per prototype
                              # (engine/sharedrows.py); the per-triangle fields are then
                              # RowColumn views and vertices32 / faces32 hold the static rows
    instances: "Instances | None" = None  # meshes placed from a shared prototype
                              # (Mesh.prototype): the rows they occupy, for two-level
                              # tracing (engine/instancing.py); None when there are none
    object_pass_index: np.ndarray | None = None  # (O,) float64 Mesh.pass_index per object
                              # (the Object Index data pass); None reads 0
    object_has_uvs: np.ndarray | None = None  # (O,) bool: the object has a UV map (the
                              # UV data pass: 0, 0, 0 without one, as Cycles)
    object_random: np.ndarray | None = None  # (O,) float64 Mesh.random (Object Info
                              # Random); None reads 0
    object_color: np.ndarray | None = None  # (O,4) float64 Mesh.object_color (Object
                              # Info Color, Alpha); None reads white
    object_location: np.ndarray | None = None  # (O,3) float64 Mesh.location, world space
                              # (Object Info Location); None reads the origin
    object_linear: np.ndarray | None = None  # (O,3,3) float64 Mesh.object_linear (the
                              # Displacement node's Object space); None reads identities
    object_attributes: dict | None = None  # name -> (O,4) float64 Mesh.object_attributes
                              # (Attribute node, type Object / Instancer); absent: zeros
    volume_grids: dict | None = None  # object -> {name: voxelgrid.VoxelGrid}: Volume
                              # objects' grids (Mesh.volume_grids); None: none
    camera_view: "object | None" = None  # shadernodes.CameraView of the scene's camera
                              # and frame (Texture Coordinate Camera / Window); None reads
                              # zeros. Set by prepare and again when a view moves
                              # (set_camera_view)
    view_footprint: "object | None" = None  # bump.ViewFootprint of the camera (set_camera_view)
    tracer: "object | None" = None  # the render's BVH, answering on the calling thread,
                              # for shader nodes that trace rays (Ambient Occlusion:
                              # ambientocclusion.attach_tracer); None before it is built

    def __post_init__(self):
        self.ng = PerTriangle(self, _ng_rows)  # (T,3) unit geometric normals (winding)
        self.area = PerTriangle(self, _area_rows)  # (T,)
        # (T,3,3) bound on |float32 corner - float64 corner|
        self.round32 = PerTriangle(self, _round32_rows)
        # (T,) bound on the float32 plane's tilt, radians (rayoffset.triangle_tilt)
        self.tilt32 = PerTriangle(self, _tilt32_rows)
        # (T,) float32 shadow terminator offsets of each triangle's object
        self.terminator = PerTriangle(self, _terminator_rows)
        self.terminator_shading = PerTriangle(self, _terminator_shading_rows)

    @property
    def count(self) -> int:
        return len(self.v0)

    def release_build_arrays(self):
        """Drop the Geometry's references to vertices32 / faces32 once the BVH is built
        (the Accel keeps what Embree reads)."""
        self.vertices32 = self.faces32 = None

    def used_materials(self) -> np.ndarray:
        """Sorted material indices some triangle uses (for shared instances: every
        material in the instances' slots, a superset)."""
        if self.shared is None:
            return np.unique(self.material)
        r = self.shared
        slots = r.slots[r.slots >= 0]
        return np.unique(np.concatenate([r.static["material"].astype(np.int64),
                                         slots.astype(np.int64)]))

    def hit_tables(self, prim, *names):
        """(rows, tables): what a compiled kernel that reads triangle tables by row needs
        for the hits prim (N,) int (< 0: a miss, kept as -1). Without shared instances:
        prim itself and the Geometry's arrays `names`; with shared instances
        (engine/sharedrows.py), the hits' own rows of each table gathered in world space
        and rows = 0..N-1. This is the one place compiled readers of corners by prim
        (camerakernels.hit_geometry, photonkernels.photon_surfaces / scatter,
        directlight.terminator_lift) learn about instances."""
        prim = np.ascontiguousarray(prim, dtype=np.int64)
        if self.shared is None:
            return prim, tuple(getattr(self, n) for n in names)
        ok = prim >= 0
        idx = np.where(ok, prim, 0)
        rows = np.where(ok, np.arange(len(prim), dtype=np.int64), -1)
        tables = []
        for name in names:
            x = getattr(self, name)
            tables.append(np.ascontiguousarray(x[idx]) if isinstance(x, RowColumn) else x)
        return rows, tuple(tables)

    def hit_points(self, prim: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Positions from barycentrics in float64: more exact than origin + t*dir."""
        # np.take(axis=0) gathers rows ~4x faster than fancy indexing (same values).
        return (np.take(self.v0, prim, axis=0) + u[:, None] * np.take(self.e1, prim, axis=0)
                + v[:, None] * np.take(self.e2, prim, axis=0))

    def instance_offset_floor(self, prim, p, n):
        """(N,) least ray-origin offset (m, along the unit geometric normals n (N,3)) at
        hit points p (N,3) on rows prim (N,) of shared instances, 0 on other rows; None
        when the Geometry has no shared instances. A shared instance is traced in its
        object space (engine/instancing.py): its float32 corners and the ray origin
        rounded to float32 there each err by up to half a float32 spacing of the
        object-space coordinates, which the instance's matrix A carries into world space
        (|A| times it), and its float32 plane may tilt (rayoffset.triangle_tilt) by up to
        cond(A) times more. The world-space offset of the expanded triangle
        (camerakernels.hit_geometry) does not cover that: a ray leaving a translated box's
        top started below it in object space and was blocked at t = 0 (black faces)."""
        shared = self.shared
        if shared is None:
            return None
        prim = np.asarray(prim, np.int64).reshape(-1)
        floor = np.zeros(len(prim))
        hit = np.nonzero(prim >= 0)[0]
        inst, _, rows, which = shared.locate(prim[hit])
        if not inst.any():
            return floor
        sel, r, i = hit[inst], rows[inst], which[inst]
        v0 = np.take(shared.tables["v0"], r, axis=0)
        corners = np.stack([v0, v0 + np.take(shared.tables["e1"], r, axis=0),
                            v0 + np.take(shared.tables["e2"], r, axis=0)], axis=1)
        A = shared.to_world[i][:, :, :3]
        # Corners' and origin's rounding (half a spacing each) and as much again for
        # Embree's float32 plane test, per object-space component, into world space.
        err = np.einsum("nij,nj->ni", np.abs(A), 2.0 * ulp32(np.abs(corners).max(axis=1)))
        n = np.asarray(n, np.float64).reshape(-1, 3)[sel]
        floor[sel] = np.einsum("ni,ni->n", np.abs(n), err)
        with np.errstate(divide="ignore", invalid="ignore"):
            cond = np.nan_to_num(np.linalg.cond(A), nan=1.0, posinf=1.0)
        world = np.einsum("nij,nkj->nki", A, corners) + shared.to_world[i][:, None, :, 3]
        far = np.linalg.norm(world - np.asarray(p, np.float64).reshape(-1, 3)[sel][:, None],
                             axis=2).max(axis=1)
        floor[sel] += triangle_tilt(corners.astype(np.float32)) * cond * far
        return floor

    def origin_offset(self, prim, u, v, p, n) -> np.ndarray:
        """(N,) distance along the unit geometric normal n that takes ray origins at hit
        points p clear of their own triangles (engine/rayoffset.py: the float64 and float32
        rounding error of p plus Embree's float32 plane test)."""
        # round32 / tilt32 are computed when read (PerTriangle): gather the hit rows once
        # and run the fused kernel on them (row i of the gathered tables is hit i).
        prim = np.ascontiguousarray(prim, dtype=np.int64)
        rows = np.arange(len(prim), dtype=np.int64)
        offset = surface_offset(np.take(self.v0, prim, axis=0), np.take(self.e1, prim, axis=0),
                                np.take(self.e2, prim, axis=0),
                                np.ascontiguousarray(self.round32[prim]),
                                np.ascontiguousarray(self.tilt32[prim]), rows,
                                np.ascontiguousarray(u, dtype=np.float64),
                                np.ascontiguousarray(v, dtype=np.float64),
                                np.ascontiguousarray(p, dtype=np.float64),
                                np.ascontiguousarray(n, dtype=np.float64))
        floor = self.instance_offset_floor(prim, p, n)
        return offset if floor is None else np.maximum(offset, floor)

    def shading_normals(self, prim, u, v) -> np.ndarray:
        if not len(self.corner_normals):
            return self.ng[prim]
        n = normalize(_corner_lerp(self.corner_normals, prim, u, v))
        # Same tests as isfinite(n).all(axis=1) and abs(n).sum(axis=1), written per component
        # (short-axis reductions are slow in numpy); |n| <= 1 here so the sum cannot overflow.
        a = np.abs(n)
        s = a[:, 0] + a[:, 1] + a[:, 2]
        bad = ~np.isfinite(s) | (s < 0.5)
        if bad.any():
            n[bad] = self.ng[prim[bad]]
        return n

    def colors(self, prim, u, v) -> np.ndarray:
        """(N,3) colour attribute interpolated at the hits (zeros where there is none)."""
        if self.corner_colors is None:
            return np.zeros((len(prim), 3))
        return _corner_lerp(self.corner_colors, prim, u, v)

    def coordinates(self, name, prim, u, v) -> np.ndarray:
        """(N,3) texture coordinates `name` interpolated at the hits (zeros where none)."""
        cc = (self.corner_coordinates or {}).get(name)
        if cc is None:
            return np.zeros((len(prim), 3))
        return _corner_lerp(cc, prim, u, v)

    def uv_tangents(self, prim) -> tuple[np.ndarray, np.ndarray]:
        """Per-triangle UV tangent dP/du (N,3, not normalised; zero where the UVs are
        degenerate) and the UV map's orientation sign (N,) (+1: counter-clockwise)."""
        if self.corner_uvs is None:
            return np.zeros((len(prim), 3)), np.ones(len(prim))
        cu = np.take(self.corner_uvs, prim, axis=0).astype(np.float64)
        d1 = cu[:, 1] - cu[:, 0]
        d2 = cu[:, 2] - cu[:, 0]
        det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
        e1 = np.take(self.e1, prim, axis=0)
        e2 = np.take(self.e2, prim, axis=0)
        inv = np.where(np.abs(det) > 1e-20, 1.0 / np.where(det == 0, 1.0, det), 0.0)
        t = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv[:, None]
        return t, np.where(det < 0, -1.0, 1.0)

    def uvs(self, prim, u, v) -> np.ndarray:
        if self.corner_uvs is None:
            return np.zeros((len(prim), 2))
        return _corner_lerp(self.corner_uvs, prim, u, v)


def _corner_lerp(corners, prim, u, v) -> np.ndarray:
    """Per-corner values corners (T,3,C) of triangles prim (N,) interpolated at barycentric
    (u, v): (N,C) float64. np.take(axis=0) gathers rows ~4x faster than fancy indexing."""
    c = np.take(corners, prim, axis=0).astype(np.float64, copy=False)
    w = (1.0 - u - v)[:, None]
    return w * c[:, 0] + u[:, None] * c[:, 1] + v[:, None] * c[:, 2]


def _corners(values, f, a, b):
    """Per-corner values (n,3,C) of faces [a, b): per-vertex values (V,C) gathered through
    the faces f, or per-corner values (F,3,C) sliced."""
    return values[f] if values.ndim == 2 else values[a:b]


def prepare(scene: Scene, should_cancel=None) -> tuple[Geometry, MaterialTable]:
    """Merge the scene's meshes into one triangle table and re-centre it. Works through
    the meshes in pieces of PIECE_TRIANGLES and asks should_cancel() between them (raises
    engine.parallel.Cancelled when it returns True)."""
    stop = should_cancel if should_cancel is not None else (lambda: False)
    mat_names = list(scene.materials.keys())
    mat_index = {n: i for i, n in enumerate(mat_names)}
    # (the world volume's medium, when the scene has one, is the table's last row:
    # engine/worldmedium.py; no triangle uses it)
    table = MaterialTable.build(table_materials(scene))
    # Cycles' true displacement ("Displacement Only" / "Displacement and Bump") moves
    # the vertices before anything is merged (engine/displacement.py).
    meshes = displace_meshes(scene.meshes, scene.materials, should_cancel)
    # A fog box standing on the floor: its face in the floor's plane moves just below it,
    # so that the floor lies inside the fog (engine/volumecontact.py).
    meshes, seated = seat_volume_faces(meshes, scene.materials)
    names = [mesh.name for mesh in meshes]

    # Bounds of the corners (vertices no face uses do not count).
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    corners_of = {}  # id(prototype) -> the vertices its faces use
    for mesh in meshes:
        if not len(mesh.faces):
            continue
        if mesh.copyless:  # a placement: its prototype's used vertices placed (no copy)
            if stop():
                raise Cancelled()
            P, M = mesh.prototype, mesh.matrix
            if id(P) not in corners_of:
                corners_of[id(P)] = P.vertices[np.unique(P.faces)]
            placed = corners_of[id(P)] @ M[:, :3].T + M[:, 3]
            lo = np.minimum(lo, placed.min(axis=0))
            hi = np.maximum(hi, placed.max(axis=0))
            continue
        verts = mesh.vertices
        used = np.zeros(len(verts), bool)
        used[mesh.faces.reshape(-1)] = True
        for a in range(0, len(used), 3 * PIECE_TRIANGLES):
            if stop():
                raise Cancelled()
            piece = verts[a:a + 3 * PIECE_TRIANGLES][used[a:a + 3 * PIECE_TRIANGLES]]
            if len(piece):
                lo = np.minimum(lo, piece.min(axis=0))
                hi = np.maximum(hi, piece.max(axis=0))
    T = int(sum(len(mesh.faces) for mesh in meshes))
    if not T:
        c = scene.camera.position if scene.camera is not None else np.zeros(3)
        lo, hi = c - 1.0, c + 1.0
    offset = (lo + hi) / 2.0
    extent = float(np.linalg.norm(hi - lo))
    if not np.isfinite(extent) or extent <= 0:
        extent = 1.0

    instances, mesh_instance = _instances(meshes, offset)
    # Two-level tracing (engine/resources.two_level_instances) also shares the tables:
    # the instanced rows are stored once per prototype (engine/sharedrows.py).
    shared = instances is not None and two_level_instances(instances)
    if not shared:
        # Expanded: placements without a copy get theirs now (the budget found it small).
        meshes = [m.expanded() for m in meshes]
    any_normals = any(_has(m, "normals") for m in meshes if len(m.faces))
    any_uvs = any(_has(m, "uvs") for m in meshes if len(m.faces))
    if instances is not None:
        instances.two_level = shared
        instances.compact_static = shared
    if shared:
        T_all = T
        T = len(instances.static)
    v0, e1, e2 = np.empty((T, 3)), np.empty((T, 3)), np.empty((T, 3))
    corner_normals = np.empty((T if any_normals else 0, 3, 3), np.float32)
    corner_uvs = np.zeros((T, 3, 2), np.float32) if any_uvs else None
    smooth = np.zeros(T, bool)
    material = np.empty(T, np.int32)
    object_id = np.empty(T, np.int32)
    visibility = np.empty(T, np.uint8)
    holdout = np.empty(T, bool)
    terminator = np.array([m.shadow_terminator_offset for m in meshes], np.float32)
    terminator_shading = np.array([m.shadow_terminator_shading_offset for m in meshes],
                                  np.float32)
    # One spare row: Embree reads the vertices in place and loads 4 bytes past the last
    # one (accel.padded_vertices).
    is_static = [not (shared and mesh_instance[oi] >= 0) for oi in range(len(meshes))]
    n_vertices = sum(len(m.vertices) for m, st in zip(meshes, is_static) if len(m.faces) and st)
    vertices32 = np.zeros((n_vertices + 1, 3), np.float32)[:n_vertices]
    faces32 = np.empty((T, 3), np.int32)
    ccols = []
    any_colors = any(m.colors is not None for m in meshes)
    start = vbase = 0
    for oi, mesh in enumerate(meshes):
        f = mesh.faces
        n = len(f)
        if n == 0 or not is_static[oi]:
            continue
        nv = len(mesh.vertices)
        for a in range(0, nv, 3 * PIECE_TRIANGLES):
            if stop():
                raise Cancelled()
            b = min(nv, a + 3 * PIECE_TRIANGLES)
            vertices32[vbase + a:vbase + b] = mesh.vertices[a:b] - offset
        remap = np.array([mat_index[name] for name in mesh.materials], np.int32)
        s = slice(start, start + n)
        object_id[s] = oi
        visibility[s] = mesh.visibility
        holdout[s] = mesh.holdout
        for a in range(0, n, PIECE_TRIANGLES):
            if stop():
                raise Cancelled()
            b = min(n, a + PIECE_TRIANGLES)
            r = slice(start + a, start + b)
            fa = f[a:b]
            tri = mesh.vertices[fa] - offset  # (n,3,3) corners, re-centred
            v0[r] = tri[:, 0]
            e1[r] = tri[:, 1] - tri[:, 0]
            e2[r] = tri[:, 2] - tri[:, 0]
            cross = np.cross(e1[r], e2[r])
            ng = cross / np.maximum(np.linalg.norm(cross, axis=1), 1e-300)[:, None]
            if mesh.normals is not None:
                cn = normalize(np.asarray(_corners(mesh.normals, fa, a, b), np.float64))
                bad = ~(np.linalg.norm(cn, axis=2) > 0.5)
                cn = np.where(bad[:, :, None], ng[:, None, :], cn)
                smooth[r] = np.any(np.abs(dot(cn, ng[:, None, :]) - 1.0) > 1e-6, axis=1)
                corner_normals[r] = cn
            elif any_normals:
                corner_normals[r] = ng[:, None, :]
            if mesh.uvs is not None:
                corner_uvs[r] = _corners(mesh.uvs, fa, a, b)
            material[r] = remap[mesh.material_ids[a:b]]
            faces32[r] = fa + vbase
        if any_colors:  # a mesh without a colour attribute reads black, as in Cycles
            c = mesh.colors
            ccols.append(np.zeros((n, 3, 3)) if c is None else c[f] if c.ndim == 2 else c)
        start += n
        vbase += nv
    if stop():
        raise Cancelled()
    coordinates = _corner_coordinates([m for m, st in zip(meshes, is_static) if st])
    colors = np.concatenate(ccols) if ccols else None
    if shared:
        rows = _shared_rows(meshes, mesh_instance, instances, T_all, offset, mat_index,
                            dict(v0=v0, e1=e1, e2=e2, corner_normals=corner_normals,
                                 smooth=smooth, corner_uvs=corner_uvs, material=material,
                                 object_id=object_id, visibility=visibility, holdout=holdout,
                                 corner_colors=colors, coordinates=coordinates),
                            any_normals, stop)
        col = lambda name: RowColumn(rows, name)  # noqa: E731
        v0, e1, e2, smooth = col("v0"), col("e1"), col("e2"), col("smooth")
        material, object_id = col("material"), col("object_id")
        visibility, holdout = col("visibility"), col("holdout")
        if any_normals:
            corner_normals = col("corner_normals")
        if corner_uvs is not None:
            corner_uvs = col("corner_uvs")
        if colors is not None:
            colors = col("corner_colors")
        if coordinates is not None:
            coordinates = {k: col("coord:" + k) for k in coordinates}
    geo = Geometry(
        offset=offset, extent=extent, v0=v0, e1=e1, e2=e2,
        corner_normals=corner_normals, smooth=smooth, corner_uvs=corner_uvs,
        material=material, object_id=object_id, object_names=names,
        vertices32=vertices32, faces32=faces32,
        object_terminator=terminator, object_terminator_shading=terminator_shading,
        object_pass_index=np.array([getattr(m, "pass_index", 0) for m in meshes], np.float64),
        object_has_uvs=np.array([_has(m, "uvs") for m in meshes], bool),
        object_random=np.array([getattr(m, "random", 0.0) for m in meshes], np.float64),
        object_color=np.array([getattr(m, "object_color", (1.0, 1.0, 1.0, 1.0))
                               for m in meshes], np.float64).reshape(-1, 4),
        object_location=np.array([getattr(m, "location", (0.0, 0.0, 0.0))
                                  for m in meshes], np.float64).reshape(-1, 3),
        object_linear=_object_linear(meshes),
        object_attributes=_object_attributes(meshes),
        volume_grids={i: m.volume_grids for i, m in enumerate(meshes)
                      if getattr(m, "volume_grids", None)} or None,
        visibility=visibility, holdout=holdout,
        bounds=np.stack([lo - offset, hi - offset]),
        corner_colors=colors,
        corner_coordinates=coordinates,
        instances=instances,
        shared=rows if shared else None,
    )
    set_camera_view(geo, scene)
    geo.seated_volumes = seated  # for the effect report (engine/effects.py)
    # Texture-driven scalar inputs: one value per material for the effect analysis.
    from .textures import scalar_ranges
    scalar_ranges(table, geo)
    return geo, table


def _object_linear(meshes) -> np.ndarray:
    """(O,3,3) each mesh's Mesh.object_linear (identity where None or not finite)."""
    out = np.tile(np.eye(3), (len(meshes), 1, 1))
    for i, m in enumerate(meshes):
        lin = getattr(m, "object_linear", None)
        if lin is not None:
            a = np.asarray(lin, np.float64)
            if a.shape == (3, 3) and np.isfinite(a).all():
                out[i] = a
    return out


def _object_attributes(meshes) -> dict | None:
    """name -> (O,4) RGBA of every Mesh.object_attributes name over the meshes (zeros
    where a mesh has no value: Cycles' value of a property not found)."""
    names = sorted({k for m in meshes for k in (getattr(m, "object_attributes", None) or {})})
    if not names:
        return None
    return {k: np.array([(getattr(m, "object_attributes", None) or {}).get(
        k, (0.0, 0.0, 0.0, 0.0)) for m in meshes], np.float64).reshape(-1, 4) for k in names}


def set_camera_view(geo: Geometry, scene: Scene) -> None:
    """geo.camera_view for the scene's camera and image size (None without a camera):
    what the Texture Coordinate node's Camera and Window outputs read; and
    geo.view_footprint, the ray footprint Bump nodes take their differences over where
    a hit's own is not passed (engine/bump.py)."""
    from .bump import attach_view
    from .shadernodes import CameraView
    cam = scene.camera
    geo.camera_view = None if cam is None else CameraView(cam, scene.width, scene.height)
    attach_view(geo, scene)


def _instances(meshes, offset):
    """(Instances or None, mesh_instance): the instance records of the merged table:
    meshes whose Mesh.prototype and matrix describe them (Mesh.instance_matches; a mesh
    whose record does not match is kept as ordinary triangles and warned about); None
    when no mesh is an instance. mesh_instance: per mesh, its instance index or -1."""
    mesh_instance = [-1] * len(meshes)
    prototypes, index = [], {}
    proto, base, to_world, flip, vis, static = [], [], [], [], [], []
    start = 0
    for mi, mesh in enumerate(meshes):
        n = len(mesh.faces)
        if not n:
            continue
        if mesh.prototype is not None:
            if mesh.instance_matches():
                mesh_instance[mi] = len(proto)
                key = id(mesh.prototype)
                if key not in index:
                    index[key] = len(prototypes)
                    prototypes.append((mesh.prototype.vertices, mesh.prototype.faces))
                M = mesh.matrix.copy()
                M[:, 3] -= offset
                proto.append(index[key])
                base.append(start)
                to_world.append(M)
                flip.append(np.linalg.det(M[:, :3]) < 0)
                vis.append(mesh.visibility)
            else:
                note = (f"mesh '{mesh.name}': its instance record does not match its "
                        "vertices and faces; traced as a copy")
                if note not in mesh.warnings:
                    mesh.warnings.append(note)
                static.append(np.arange(start, start + n))
        else:
            static.append(np.arange(start, start + n))
        start += n
    if not proto:
        return None, mesh_instance
    return Instances(prototypes=prototypes, prototype=np.array(proto, np.int64),
                     base=np.array(base, np.int64), to_world=np.array(to_world),
                     flip=np.array(flip, bool), visibility=np.array(vis, np.uint8),
                     static=np.concatenate(static) if static else np.zeros(0, np.int64)
                     ), mesh_instance


def _has(mesh, attr) -> bool:
    """The mesh (or, for a placement without a copy, its prototype) has `attr`."""
    src = mesh.prototype if mesh.copyless else mesh
    return getattr(src, attr, None) is not None


def _prototype_order(values, mesh, flip):
    """(F,3,C) per-corner values of mesh (per vertex or per corner) in its prototype's
    corner order (a mirrored instance's faces are the prototype's with corners 0, 2, 1)."""
    c = _corners(np.asarray(values), mesh.faces, 0, len(mesh.faces))
    return c[:, [0, 2, 1]] if flip else c


def _world_corner_normals(mesh, ng):
    """(F,3,3) unit corner normals of a mesh with normals, the geometric normal ng
    (F,3) where one is unusable, and (F,) smooth flags, as prepare computes them."""
    cn = normalize(np.asarray(_corners(mesh.normals, mesh.faces, 0, len(mesh.faces)),
                              np.float64))
    bad = ~(np.linalg.norm(cn, axis=2) > 0.5)
    cn = np.where(bad[:, :, None], ng[:, None, :], cn)
    return cn, np.any(np.abs(dot(cn, ng[:, None, :]) - 1.0) > 1e-6, axis=1)


def _shared_rows(meshes, mesh_instance, instances, count, offset, mat_index, static,
                 any_normals, stop) -> SharedRows:
    """The SharedRows of a prepared scene (engine/sharedrows.py): static holds the
    tables of the triangles of no instance; each instance mesh either reads an existing
    per-prototype table (same prototype, same material slots, UVs, colours, coordinates
    and, transformed, normals) or starts a new one from its own data in object space."""
    tables = {k: [] for k in ("v0", "e1", "e2", "corner_normals", "smooth", "slot",
                              "corner_uvs", "corner_colors")}
    coord_names = sorted((static.get("coordinates") or {}).keys())
    for k in coord_names:
        tables["coord:" + k] = []
    reps = {}   # id(prototype) -> [(table index, representative data)]
    table_start, n_rows = [], 0
    seg_start, seg_kind, seg_static = [], [], []
    I = instances.count
    table_of = np.zeros(I, np.int64)
    K = max([len(m.materials) for m in meshes if len(m.faces)] + [1])
    slots = np.full((I, K), -1, np.int32)
    object_id = np.zeros(I, np.int32)
    visibility = np.zeros(I, np.uint8)
    holdout = np.zeros(I, bool)
    start = static_start = 0
    for oi, mesh in enumerate(meshes):
        n = len(mesh.faces)
        if not n:
            continue
        i = mesh_instance[oi]
        seg_start.append(start)
        seg_kind.append(i)
        seg_static.append(static_start if i < 0 else 0)
        start += n
        if i < 0:
            static_start += n
            continue
        if stop():
            raise Cancelled()
        object_id[i] = oi
        visibility[i] = mesh.visibility
        holdout[i] = mesh.holdout
        slots[i, :len(mesh.materials)] = [mat_index[m] for m in mesh.materials]
        M = instances.to_world[i]
        flip = bool(instances.flip[i])
        P = mesh.prototype
        key = (id(P), "placement")
        if not mesh.copyless or key not in reps:
            V = np.asarray(P.vertices, np.float64)
            F = P.faces
            v0 = V[F[:, 0]]
            e1, e2 = V[F[:, 1]] - v0, V[F[:, 2]] - v0
        if mesh.copyless:
            # A placement: every table row from the prototype's object-space data.
            if key not in reps:
                reps[key] = _placement_table(P, v0, e1, e2, tables, coord_names,
                                             n_rows, len(table_start))
                table_start.append(n_rows)
                n_rows += n
            table_of[i] = reps[key]
            continue
        data = {"slot": np.asarray(mesh.material_ids, np.int32)}
        if mesh.uvs is not None:
            data["corner_uvs"] = _prototype_order(mesh.uvs, mesh, flip).astype(np.float32)
        if mesh.colors is not None:
            data["corner_colors"] = _prototype_order(mesh.colors, mesh, flip)
        for k in coord_names:
            c = (mesh.coordinates or {}).get(k)
            if c is not None:
                data["coord:" + k] = _prototype_order(c, mesh, flip)
        wn = None
        if mesh.normals is not None:
            # World corner normals as prepare computes them for a copy (winding of the
            # copy: corners back in prototype order), then into object space by M^T.
            we1 = (M[:, :3] @ e1.T).T
            we2 = (M[:, :3] @ e2.T).T
            cross = np.cross(we2, we1) if flip else np.cross(we1, we2)
            wng = cross / np.maximum(np.linalg.norm(cross, axis=1), 1e-300)[:, None]
            wn, sm = _world_corner_normals(mesh, wng)
            wn = wn[:, [0, 2, 1]] if flip else wn
            data["smooth"] = sm
        found = None
        for t, rep in reps.get(id(P), []):
            if _same_rows(rep, data, wn, instances, i):
                found = t
                break
        if found is None:
            found = len(table_start)
            table_start.append(n_rows)
            n_rows += n
            if wn is not None:
                on = normalize(np.einsum("ji,fkj->fki", M[:, :3], wn))
            else:
                ng = np.cross(e1, e2)
                ng = ng / np.maximum(np.linalg.norm(ng, axis=1), 1e-300)[:, None]
                on = np.broadcast_to(ng[:, None, :], (n, 3, 3))
            tables["v0"].append(v0)
            tables["e1"].append(e1)
            tables["e2"].append(e2)
            tables["corner_normals"].append(np.asarray(on, np.float32))
            tables["smooth"].append(data.get("smooth", np.zeros(n, bool)))
            tables["slot"].append(data["slot"])
            tables["corner_uvs"].append(data.get("corner_uvs", np.zeros((n, 3, 2), np.float32)))
            tables["corner_colors"].append(data.get("corner_colors", np.zeros((n, 3, 3))))
            for k in coord_names:
                tables["coord:" + k].append(data.get("coord:" + k, np.zeros((n, 3, 3))))
            data["table"] = found
            data["normals"] = on if wn is not None else None
            reps.setdefault(id(P), []).append((found, data))
        table_of[i] = found
    joined = {k: np.concatenate(v) if v else np.zeros(0) for k, v in tables.items()}
    st = {k: static[k] for k in ("v0", "e1", "e2", "smooth", "material", "object_id",
                                 "visibility", "holdout")}
    if any_normals:
        st["corner_normals"] = static["corner_normals"]
    if static["corner_uvs"] is not None:
        st["corner_uvs"] = static["corner_uvs"]
    if static["corner_colors"] is not None:
        st["corner_colors"] = static["corner_colors"]
    elif any(m.colors is not None for m in meshes if len(m.faces)):
        st["corner_colors"] = np.zeros((len(static["v0"]), 3, 3))
    for k in coord_names:
        st["coord:" + k] = static["coordinates"][k]
    return SharedRows(count, seg_start, seg_kind, seg_static, st, joined, table_start,
                      table_of, instances.to_world, instances.flip, slots, object_id,
                      visibility, holdout)


def _placement_table(P, v0, e1, e2, tables, coord_names, start, index) -> int:
    """Append prototype P's object-space table (placements without a copy) to tables;
    returns its table index. Unusable normals fall back to the geometric one."""
    n = len(P.faces)
    ng = np.cross(e1, e2)
    ng = ng / np.maximum(np.linalg.norm(ng, axis=1), 1e-300)[:, None]
    if P.normals is not None:
        cn = normalize(np.asarray(_corners(P.normals, P.faces, 0, n), np.float64))
        bad = ~(np.linalg.norm(cn, axis=2) > 0.5)
        cn = np.where(bad[:, :, None], ng[:, None, :], cn)
        smooth = np.any(np.abs(dot(cn, ng[:, None, :]) - 1.0) > 1e-6, axis=1)
    else:
        cn = np.broadcast_to(ng[:, None, :], (n, 3, 3))
        smooth = np.zeros(n, bool)
    tables["v0"].append(v0)
    tables["e1"].append(e1)
    tables["e2"].append(e2)
    tables["corner_normals"].append(np.asarray(cn, np.float32))
    tables["smooth"].append(smooth)
    tables["slot"].append(np.asarray(P.material_ids, np.int32))
    tables["corner_uvs"].append(np.zeros((n, 3, 2), np.float32) if P.uvs is None else
                                _corners(P.uvs, P.faces, 0, n).astype(np.float32))
    tables["corner_colors"].append(np.zeros((n, 3, 3)))
    for k in coord_names:
        tables["coord:" + k].append(np.zeros((n, 3, 3)))
    return index


def _same_rows(rep, data, wn, instances, i) -> bool:
    """True when an instance's per-triangle data (data, world corner normals wn) are
    those of a table's representative rep once placed by instance i's matrix."""
    for k in set(rep) | set(data):
        if k in ("table", "normals"):
            continue
        if (k in rep) != (k in data):
            return False
        a, b = rep[k], data[k]
        if a is not b and (a.shape != b.shape or not np.array_equal(a, b)):
            return False
    if (rep["normals"] is None) != (wn is None):
        return False
    if wn is None:
        return True
    N = np.linalg.inv(instances.to_world[i][:, :3]).T
    placed = normalize(np.einsum("ij,fkj->fki", N, rep["normals"]))
    return bool(np.all(np.abs(placed - wn) <= 1e-5))


def emissive_triangles(geo: Geometry, table: MaterialTable):
    """Indices, radiance and area of triangles whose material emits (mesh lights).
    Emitters invisible to diffuse rays light no diffuse surface (Cycles), so they are left
    out; camera, mirror and glass rays still see them glow."""
    if not geo.count:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0)
    # Per material first: a per-triangle (T,3) radiance table would cost 24 B a triangle.
    emits = luminance(table.emission) > 0
    idx = np.nonzero(emits[geo.material] & ((geo.visibility & DIFFUSE) != 0))[0]
    L = table.emission[geo.material[idx]]
    if any(t is not None for t in (table.emission_textures or ())):
        from .textures import triangle_average_emission
        L = triangle_average_emission(table, geo, idx, L)
    return idx, L, geo.area[idx]


def _corner_coordinates(meshes) -> dict | None:
    """name -> (T,3,3) per-corner texture coordinates over all meshes' triangles."""
    names = sorted({k for m in meshes for k in (m.coordinates or {})})
    if not names:
        return None
    out = {}
    for name in names:
        parts = [(m.coordinates or {}).get(name, None) for m in meshes if len(m.faces)]
        sizes = [len(m.faces) for m in meshes if len(m.faces)]
        out[name] = np.concatenate([np.zeros((n, 3, 3)) if a is None else a
                                    for a, n in zip(parts, sizes)])
    return out
