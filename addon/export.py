"""Evaluated depsgraph -> engine Scene (meshes, instances, lights, camera, world).

Everything is read with foreach_get into numpy arrays; there is no per-vertex Python.
Geometry of an object that is instanced many times is extracted once and written as one
engine Prototype with a placement (matrix, material slots, visibility) per instance
(engine Mesh.place), not a world-space copy per instance; the engine shares or expands
it (engine/resources.instance_choice). Geometry with colour attributes, normal-map
tangents or texture coordinates a material reads is still copied per instance (with an
instance record).
"""
from __future__ import annotations

import math
import time

import numpy as np

from .materials import (CYCLES_STANDARD_ATTRIBUTES, MaterialConverter, object_attribute_key,
                        output_node)
from .normals import shading_normals
from .particlehair import particle_strands
from .world import export_worlds, sky_sun_lights, world_medium, world_mist



class ExportCancelled(Exception):
    """The user pressed Esc while the scene was being exported."""


class ExportError(Exception):
    """The scene cannot be rendered; the message is meant for the user."""


# --- geometry -----------------------------------------------------------------------

class LocalGeometry:
    """Triangles of one evaluated object in its local space."""

    __slots__ = ("co", "faces", "normals", "uvs", "material_index", "triangles", "colors",
                 "texspace", "tangents", "uv_name", "attributes", "named_tangents",
                 "generated")

    def __init__(self, co, faces, normals, uvs, material_index, colors=None, texspace=None,
                 tangents=None, uv_name="", attributes=None, named_tangents=None,
                 generated=None):
        self.co = co                    # (V,3) float64
        self.faces = faces              # (F,3) int64
        self.normals = normals          # None (flat), (V,3) or (F,3,3)
        self.uvs = uvs                  # None or (F,3,2)
        self.colors = colors            # None or (F,3,4) linear RGBA (colour attribute)
        self.texspace = texspace        # (location, size) of the mesh's texture space
        self.material_index = material_index  # (F,) int32
        self.triangles = len(faces)
        self.tangents = tangents        # None or (F,3,4) MikkTSpace tangent xyz, sign
        self.uv_name = uv_name          # the render UV map's name ("" without UVs)
        # Named attributes an Attribute / Color Attribute node reads (named_attributes):
        # name -> (vector (F,3,3), fac (F,3), alpha (F,3)) per corner
        self.attributes = attributes or {}
        # MikkTSpace tangents of the UV maps nodes name (named_tangent_maps):
        # name -> (F,3,4) as `tangents`
        self.named_tangents = named_tangents or {}
        # None (Generated from the corners' positions in `texspace`) or (F,3,3) per corner
        # (particle hair: each strand's root in its emitter's texture space)
        self.generated = generated


def _foreach(collection, attr, count, width, dtype):
    buf = np.empty(count * width, dtype=dtype)
    if count:
        collection.foreach_get(attr, buf)
    return buf.reshape(count, width) if width > 1 else buf


def _material_nodes(obj):
    """Every shader node of the object's materials, those inside their node groups too
    (each group's tree once)."""
    trees, seen = [], set()
    for slot in getattr(obj, "material_slots", ()):
        mat = slot.material
        tree = getattr(mat, "node_tree", None) if mat is not None else None
        if tree is not None:
            trees.append(tree)
    while trees:
        tree = trees.pop()
        if tree.as_pointer() in seen:
            continue
        seen.add(tree.as_pointer())
        for node in tree.nodes:
            yield node
            inner = getattr(node, "node_tree", None) if node.type == "GROUP" else None
            if inner is not None:
                trees.append(inner)


def _uses_tangent_normal_maps(obj) -> bool:
    """Some material of the object has a tangent-space Normal Map node (its tangents are
    worth computing)."""
    return any(node.type == "NORMAL_MAP" and getattr(node, "space", "TANGENT") == "TANGENT"
               for node in _material_nodes(obj))


def named_tangent_maps(obj) -> set:
    """The UV maps whose MikkTSpace tangents the object's materials read by name: those
    that tangent-space Normal Map nodes and Tangent nodes in UV Map mode name (their
    uv_map; "" = the render map, left out), as Cycles reads each one's tangent attribute
    (NormalMapNode / TangentNode::attributes: NAME.tangent, NAME.tangent_sign)."""
    return {str(node.uv_map) for node in _material_nodes(obj)
            if getattr(node, "uv_map", "") and (
                (node.type == "NORMAL_MAP" and getattr(node, "space", "TANGENT") == "TANGENT")
                or (node.type == "TANGENT"
                    and getattr(node, "direction_type", "") == "UV_MAP"))}


def attribute_requests(obj) -> set:
    """Names of the mesh attributes the object's materials read by name: Attribute nodes
    of type Geometry (attribute_name), Color Attribute nodes ("" = the render colour
    attribute) and UV Map nodes naming a map."""
    names = set()
    for node in _material_nodes(obj):
        if node.type == "ATTRIBUTE" and getattr(node, "attribute_type", "") == "GEOMETRY":
            name = str(node.attribute_name)
            if name not in CYCLES_STANDARD_ATTRIBUTES or name in (ISLAND, POINTINESS):
                names.add(name)
        elif node.type == "NEW_GEOMETRY":
            for out_name, attr in (("Random Per Island", ISLAND), ("Pointiness", POINTINESS)):
                out = node.outputs.get(out_name)
                if out is not None and out.is_linked:
                    names.add(attr)
        elif node.type == "VERTEX_COLOR":
            names.add(str(getattr(node, "layer_name", "")))
        elif node.type == "UVMAP" and getattr(node, "uv_map", ""):
            names.add(str(node.uv_map))
    return names


ISLAND = "random_per_island"  # Cycles' standard name of the Random Per Island attribute
POINTINESS = "pointiness"  # and of the Geometry node's Pointiness (engine/pointiness.py)

# Generic attribute data types read by name, and the RNA property holding their values
# (colours: `color`, scene linear for byte and float colours alike).
_ATTRIBUTE_VALUES = {"FLOAT": ("value", 1), "INT": ("value", 1), "INT8": ("value", 1),
                     "BOOLEAN": ("value", 1), "FLOAT2": ("vector", 2),
                     "FLOAT_VECTOR": ("vector", 3), "FLOAT_COLOR": ("color", 4),
                     "BYTE_COLOR": ("color", 4)}


def named_attributes(me, names, tris, loops, faces) -> dict:
    """{name: (vector (F,3,3), fac (F,3), alpha (F,3))} at the triangle corners of the mesh
    attributes `names` ("" = the render colour attribute) as Cycles' Attribute node reads
    them (kernel/svm/attribute.h svm_node_attr): a float f gives (f, f, f), Fac f; a 2-D
    vector (a UV map) (x, y, 0), Fac x; a 3-D vector itself, Fac its average; a colour its
    RGB, Fac their average, Alpha its alpha (else 1). Point, corner and face domains (a
    face's value on each of its triangles); names the mesh lacks are left out (they read
    0, alpha 1)."""
    out = {}
    attrs = me.attributes
    colours = getattr(me, "color_attributes", None)
    for name in names:
        attr = None
        if name == ISLAND:  # Cycles' standard attribute, computed from the topology
            r = np.repeat(random_per_island(me, faces)[:, None], 3, axis=1)
            out[name] = (np.repeat(r[..., None], 3, axis=2), r, np.ones_like(r))
            continue
        if name == POINTINESS:  # Cycles' standard attribute, per vertex (interpolated)
            p = mesh_pointiness(me)[faces].astype(np.float64)
            out[name] = (np.repeat(p[..., None], 3, axis=2), p, np.ones_like(p))
            continue
        if name == "":
            if colours is not None and len(colours):
                idx = getattr(colours, "render_color_index", -1)
                attr = colours[idx] if 0 <= idx < len(colours) else (
                    colours.active_color or colours[0])
        else:
            attr = attrs.get(name)
        if attr is None or attr.data_type not in _ATTRIBUTE_VALUES:
            continue
        prop, width = _ATTRIBUTE_VALUES[attr.data_type]
        count = {"POINT": len(me.vertices), "CORNER": len(me.loops),
                 "FACE": len(me.polygons)}.get(attr.domain)
        if count is None:  # (edge attributes: Cycles does not read them either)
            continue
        raw = _foreach(attr.data, prop, count, width,
                       np.float32 if attr.data_type != "BOOLEAN" else bool).astype(np.float64)
        raw = raw.reshape(count, width)
        if attr.domain == "POINT":
            vals = raw[faces]
        elif attr.domain == "CORNER":
            vals = raw[loops]
        else:
            poly = _foreach(tris, "polygon_index", len(tris), 1, np.int32)
            vals = np.repeat(raw[poly][:, None, :], 3, axis=1)
        alpha = np.ones(vals.shape[:2])
        if width == 1:
            vec, fac = np.repeat(vals, 3, axis=2), vals[..., 0]
        elif width == 2:
            vec = np.concatenate([vals, np.zeros(vals.shape[:2] + (1,))], axis=2)
            fac = vals[..., 0]
        else:
            vec, fac = vals[..., :3], vals[..., :3].mean(axis=2)
            if width == 4:
                alpha = vals[..., 3]
        out[name] = (vec, fac, alpha)
    return out


def mesh_pointiness(me) -> np.ndarray:
    """(V,) Cycles' pointiness of a Blender mesh's vertices (engine/pointiness.py: from its
    positions, Blender's vertex normals and its edges, as blender/mesh.cpp reads them)."""
    from .core import load_engine
    nv = len(me.vertices)
    co = _foreach(me.vertices, "co", nv, 3, np.float32)
    normals = getattr(me, "vertex_normals", None)  # (Blender 4.1+; before: vertex.normal)
    nrm = (_foreach(normals, "vector", nv, 3, np.float32) if normals is not None
           else _foreach(me.vertices, "normal", nv, 3, np.float32))
    edges = _foreach(me.edges, "vertices", len(me.edges), 2, np.int32)
    return load_engine().pointiness.pointiness(co, nrm, edges.reshape(-1, 2))


def _uses_uv_tangents(obj) -> bool:
    """Some material of the object has a Tangent node in UV Map mode (an anisotropic
    lobe's tangent may read its MikkTSpace tangents: MaterialConverter.uv_tangent_map)."""
    return any(node.type == "TANGENT" and getattr(node, "direction_type", "") == "UV_MAP"
               for node in _material_nodes(obj))


def _corner_tangents(me, layer, loops, warnings=None):
    """(F,3,4) MikkTSpace tangents (xyz) and bitangent signs at the triangle corners, as
    Blender computes them for Cycles' Normal Map node (Mesh.calc_tangents on the render
    UV map), or None when Blender cannot (n-gons: it needs triangles and quads)."""
    try:
        me.calc_tangents(uvmap=layer.name)
    except RuntimeError:
        return None
    n = len(me.loops)
    t = _foreach(me.loops, "tangent", n, 3, np.float32)
    sign = _foreach(me.loops, "bitangent_sign", n, 1, np.float32)
    out = np.concatenate([t, sign[:, None]], axis=1)
    return out[loops].astype(np.float64)


def extract_geometry(obj) -> LocalGeometry | None:
    """Loop triangles, normals, UVs and material indices of an evaluated object (and its
    MikkTSpace tangents when a material uses a tangent-space normal map)."""
    try:
        me = obj.to_mesh()
    except RuntimeError:
        return None
    try:
        if me is None:
            return None
        tris = me.loop_triangles
        nt = len(tris)
        if nt == 0:
            return None
        nv = len(me.vertices)
        co = _foreach(me.vertices, "co", nv, 3, np.float32).astype(np.float64)
        faces = _foreach(tris, "vertices", nt, 3, np.int32).astype(np.int64)
        loops = _foreach(tris, "loops", nt, 3, np.int32)
        mat_index = _foreach(tris, "material_index", nt, 1, np.int32)
        # The normals Cycles shades with, not the ones the viewport draws (addon/normals.py).
        normals = shading_normals(me, co, faces, loops)
        uvs = None
        tangents = None
        layers = me.uv_layers
        if len(layers):
            layer = next((lay for lay in layers if lay.active_render), None) or layers.active
            if layer is not None:
                data = layer.uv if hasattr(layer, "uv") else layer.data
                attr = "vector" if hasattr(layer, "uv") else "uv"
                uv = _foreach(data, attr, len(me.loops), 2, np.float32)
                uvs = uv[loops].astype(np.float64)
                if _uses_tangent_normal_maps(obj) or _uses_uv_tangents(obj):
                    tangents = _corner_tangents(me, layer, loops)
        named_tangents = {}
        for name in sorted(named_tangent_maps(obj)):
            named = layers.get(name)  # (a map the mesh lacks: none, as in Cycles)
            t = _corner_tangents(me, named, loops) if named is not None else None
            if t is not None:
                named_tangents[name] = t
        texspace = (np.array(me.texspace_location, np.float64),
                    np.array(me.texspace_size, np.float64))
        requests = attribute_requests(obj)
        return LocalGeometry(co, faces, normals, uvs, mat_index,
                             _corner_colors(me, tris, loops, faces), texspace, tangents,
                             layer.name if uvs is not None else "",
                             named_attributes(me, requests, tris, loops, faces)
                             if requests else None, named_tangents)
    finally:
        obj.to_mesh_clear()


def extract_hair_geometry(pm, obj) -> LocalGeometry | None:
    """A Curves object's (hair's) strands as triangle tubes in its local space
    (engine/hair.py: Cycles' Catmull-Rom curves through the control points, of the
    point attribute "radius" or Cycles' 0.005 m), smooth-shaded; the curve attribute
    "material_index" picks each strand's slot. None when no strand has 2 points."""
    curves = obj.data
    n_points, n_curves = len(curves.points), len(curves.curves)
    if n_points < 2 or n_curves == 0:
        return None
    points = _foreach(curves.position_data, "vector", n_points, 3, np.float32)
    offsets = _foreach(curves.curve_offset_data, "value", n_curves + 1, 1, np.int32)
    attrs = curves.attributes
    rad = attrs.get("radius")
    if rad is not None and rad.domain == "POINT" and rad.data_type == "FLOAT":
        radius = _foreach(rad.data, "value", n_points, 1, np.float32)
    else:
        radius = np.full(n_points, pm.hair.DEFAULT_RADIUS)
    mi = attrs.get("material_index")
    slot = None
    if mi is not None and mi.domain == "CURVE" and mi.data_type == "INT":
        slot = _foreach(mi.data, "value", n_curves, 1, np.int32)
    return hair_tubes(pm, obj, points, radius, offsets, slot)


def extract_particle_hair(pm, obj, background: bool = True,
                          should_cancel=None) -> LocalGeometry | None:
    """The strands of an object's particle hair systems (addon/particlehair.py, read as
    Cycles does) as triangle tubes in its local space, each system's strands in its
    Render > Material slot; None when it has none to render. Raises ExportCancelled when
    should_cancel() turns True while the keys are read."""
    def poll():
        if should_cancel is not None and should_cancel():
            raise ExportCancelled()

    strands = particle_strands(obj, background, poll)
    if strands is None:
        return None
    # Generated: each strand's root key in the emitter mesh's texture space, the same on
    # the whole strand (Cycles' blender/curves.cpp: co * size - loc of the first key,
    # mesh_texture_space; "ideally from Blender", its comment says).
    me = obj.data
    loc = np.array(me.texspace_location, np.float64)
    size = np.array(me.texspace_size, np.float64)
    size = np.where(np.abs(size) > 1e-12, size, 1.0)
    roots = np.asarray(strands.points, np.float64)[np.asarray(strands.offsets[:-1], np.int64)]
    geo = hair_tubes(pm, obj, strands.points, strands.radius, strands.offsets,
                     strands.slot, strands.uv,
                     strand_generated=(roots - loc) / (2.0 * size) + 0.5)
    if geo is not None and geo.uvs is not None:  # (the emitter's render UV map)
        geo.uv_name = next((layer.name for layer in obj.data.uv_layers if layer.active_render),
                           obj.data.uv_layers[0].name)
    return geo


def hair_tubes(pm, obj, points, radius, offsets, slot=None,
               strand_uv=None, strand_generated=None) -> LocalGeometry | None:
    """Hair strands (points (P,3) and radius (P,) in object space, offsets (C+1,), slot
    (C,) material slot or None: the first; strand_uv (C,2) each strand's UV, on every
    corner of its tubes, or None: no UVs; strand_generated (C,3) each strand's Generated
    coordinate, or None: the tubes' own bounds) as smooth-shaded triangle tubes
    (engine/hair.tube_mesh), with Curves Info's attributes when a material of obj reads
    them. None when no strand has 2 points."""
    # Curves Info, and the Principled Hair BSDF's Random Color / Random Roughness (the
    # strand's Random when its Random input is unlinked), read these attributes.
    info = any(node.type in ("HAIR_INFO", "BSDF_HAIR_PRINCIPLED")
               for node in _material_nodes(obj))
    verts, faces, normals, curve, *per_vertex = pm.hair.tube_mesh(points, radius, offsets,
                                                                 params=info)
    if len(faces) == 0:
        return None
    mat_index = np.zeros(len(faces), np.int32) if slot is None else \
        np.asarray(slot, np.int32)[curve]
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    texspace = ((lo + hi) / 2, np.maximum((hi - lo) / 2, 1e-6))  # Blender's auto space
    attributes = curves_info(points, offsets, faces, curve, *per_vertex) if info else None
    uvs = None
    if strand_uv is not None:
        uvs = np.repeat(np.asarray(strand_uv, np.float64)[curve][:, None, :], 3, axis=1)
    generated = None
    if strand_generated is not None:
        generated = np.repeat(np.asarray(strand_generated, np.float64)[curve][:, None, :], 3,
                              axis=1)
    return LocalGeometry(verts, faces, normals, uvs, mat_index, texspace=texspace,
                         attributes=attributes, generated=generated)


# Object types whose own data is rendered geometry (the depsgraph yields curves, text,
# metaballs and surfaces as MESH instances).
GEOMETRY_TYPES = ("MESH", "CURVES", "POINTCLOUD")


def extract_object_geometry(pm, obj) -> LocalGeometry | None:
    """An evaluated object's local geometry by its type (GEOMETRY_TYPES): a mesh's
    triangles, a Curves object's strand tubes, a point cloud's spheres."""
    if obj.type == "CURVES":
        return extract_hair_geometry(pm, obj)
    if obj.type == "POINTCLOUD":
        return extract_pointcloud_geometry(pm, obj)
    return extract_geometry(obj)


def extract_pointcloud_geometry(pm, obj) -> LocalGeometry | None:
    """A Point Cloud's points (Geometry Nodes points: Mesh to Points, Distribute Points
    on Faces, Points) as the spheres Cycles renders, each of its point attribute
    "radius" (Cycles' 0.01 m without it), all in the first material slot, as Cycles
    (engine/pointcloud.py: icospheres of the sphere's surface area, smooth-shaded); None
    without a point of positive radius."""
    cloud = obj.data
    n = len(cloud.points)
    if n == 0:
        return None
    attrs = cloud.attributes
    centres = _foreach(attrs["position"].data, "vector", n, 3, np.float32)
    rad = attrs.get("radius")
    if rad is not None and rad.domain == "POINT" and rad.data_type == "FLOAT":
        radius = _foreach(rad.data, "value", n, 1, np.float32)
    else:
        radius = np.full(n, pm.pointcloud.DEFAULT_RADIUS)
    verts, faces, normals, point = pm.pointcloud.sphere_mesh(centres, radius)
    if len(faces) == 0:
        return None
    # Every point in the first slot: Cycles' export_pointcloud fills its shaders with 0
    # (a "material_index" attribute is not read there either).
    mat_index = np.zeros(len(faces), np.int32)
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    texspace = ((lo + hi) / 2, np.maximum((hi - lo) / 2, 1e-6))  # Blender's auto space
    attributes = None
    if any(node.type == "POINT_INFO" for node in _material_nodes(obj)):
        attributes = point_info(centres, radius, faces, point)
    return LocalGeometry(verts, faces, normals, None, mat_index, texspace=texspace,
                         attributes=attributes)


def point_info(centres, radius, faces, point) -> dict:
    """The Point Info node's outputs per corner of a point cloud's spheres, as
    LocalGeometry attributes (read by addon/materials.py, POINT_INFO): 'point_position' the
    point's centre (object space here; corner_attributes takes it to world space, as
    Cycles' point_position), 'point_info' = (Radius, Random, 0) with Random
    hash_uint2_to_float(point index, 0) (Cycles' ATTR_STD_POINT_RANDOM) and the radius in
    object space (corner_attributes scales it as Cycles' point_radius). centres (N,3),
    radius (N,), faces (F,3), point (F,) each face's point."""
    random = (hash_uint2(np.arange(len(radius), dtype=np.int64), 0).astype(np.float32)
              / np.float32(4294967295.0)).astype(np.float64)
    ones = np.ones(faces.shape)
    position = np.repeat(np.asarray(centres, np.float64)[point][:, None, :], 3, axis=1)
    info = np.zeros(faces.shape + (3,))
    info[..., 0] = np.asarray(radius, np.float64)[point][:, None]
    info[..., 1] = random[point][:, None]
    return {"point_position": (position, position[..., 0], ones),
            "point_info": (info, info[..., 0], ones)}


def volume_mesh(pm, inst, obj, converter, materials: dict, warnings: list, info: dict,
                view_layer, scene, cache=None):
    """The engine Mesh of a Volume object instance (OpenVDB grids, Mesh to Volume, a
    Geometry Nodes volume): the box around its grids with the grids its material reads
    (addon/volumegrids.py), named as a mesh instance is; None when nothing renders
    (warned there)."""
    import bpy

    from .volumegrids import volume_object_mesh
    name = _instance_name(inst, obj, info)
    extra = dict(pass_index=pass_index(obj),
                 **object_info(obj, inst, converter.object_attribute_names),
                 **cryptomatte_names(obj), **ray_visibility(obj, inst, view_layer))
    frame = (getattr(scene, "frame_current", 1), getattr(scene, "frame_subframe", 0.0))
    mesh = volume_object_mesh(pm, bpy, inst, obj, converter, materials, warnings, name,
                              frame, extra, cache=cache)
    if mesh is not None:
        info["objects"] = info.get("objects", 0) + 1
        warn_unsupported_object_options(obj, warnings)
    return mesh


def camera_world(seen) -> dict:
    """Scene keywords for the world camera rays see (export_worlds' second: None when
    they see the scene's light)."""
    if seen is None:
        return {}
    background, environment = seen
    return {"camera_background": background, "camera_environment": environment}


def warn_empty_hair(obj, warnings: list) -> None:
    """A Curves object with curves but nothing to render (every strand of radius 0, or of
    fewer than 2 points): said, naming it (its radius-0 triangles read "mesh ...: dropped
    zero-area faces", newuser37). One without curves (just added) is left alone."""
    if len(obj.data.curves):
        warnings.append(f"object '{obj.name}': its hair has no strand to render (every "
                        "strand has radius 0 or fewer than 2 points), as in Cycles")


def curves_info(points, offsets, faces, curve, intercept, radius) -> dict:
    """The Curves Info node's outputs per corner of a hair's tubes, as LocalGeometry
    attributes (read by addon/materials.py, HAIR_INFO): 'curves_info' = (Intercept,
    Length, Random), 'curves_info2' = (Thickness, Is Strand 1, 0). Cycles
    (blender/curves.cpp export_hair_curves): Intercept the share of the key polyline's
    length from the root (engine/hair.py), Length that polyline's length, Random
    hash_uint2_to_float(curve index, 0), Thickness 2 x the radius (object space).
    points (P,3), offsets (C+1,), faces (F,3), curve (F,) the faces' curves, intercept and
    radius (V,) per tube vertex."""
    pts = np.asarray(points, np.float64)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    run = np.concatenate([[0.0], np.cumsum(seg)])
    offsets = np.asarray(offsets, np.int64)
    length = run[offsets[1:] - 1] - run[offsets[:-1]]  # (C,), over each curve's keys
    h = hash_uint2(np.arange(len(length), dtype=np.int64), 0)
    random = (h.astype(np.float32) / np.float32(4294967295.0)).astype(np.float64)
    per_face = np.stack([length[curve], random[curve]], 1)  # (F,2)
    vec = np.empty(faces.shape + (3,))
    vec[..., 0] = intercept[faces]
    vec[..., 1:] = per_face[:, None, :]
    vec2 = np.zeros(faces.shape + (3,))
    vec2[..., 0] = 2.0 * radius[faces]
    vec2[..., 1] = 1.0
    ones = np.ones(faces.shape)
    return {"curves_info": (vec, vec[..., 0], ones), "curves_info2": (vec2, vec2[..., 0], ones)}


def _corner_colors(me, tris, loops, faces):
    """(F,3,4) linear RGBA of the mesh's render colour attribute at each triangle corner
    (the one Cycles' Color Attribute node reads when its name is empty), or None."""
    attrs = getattr(me, "color_attributes", None)
    if attrs is None or not len(attrs):
        return None
    idx = getattr(attrs, "render_color_index", -1)
    attr = attrs[idx] if 0 <= idx < len(attrs) else (attrs.active_color or attrs[0])
    if attr is None:
        return None
    if attr.domain == "POINT":
        # `color` is scene-linear for byte and float attributes alike.
        col = _foreach(attr.data, "color", len(me.vertices), 4, np.float32)
        return col[faces].astype(np.float64)
    if attr.domain == "CORNER":
        col = _foreach(attr.data, "color", len(me.loops), 4, np.float32)
        return col[loops].astype(np.float64)
    return None


def object_normals(g: LocalGeometry) -> np.ndarray:
    """(F,3,3) per-corner object-space normals: the shading normals where the mesh has
    them, else each face's geometric normal (a flat face's N in Cycles)."""
    if g.normals is not None:
        n = np.asarray(g.normals, np.float64)
        return n if n.ndim == 3 else n[g.faces]
    p = g.co[g.faces]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    return np.repeat(fn[:, None, :], 3, axis=1)


def texture_coordinates(g: LocalGeometry, flipped: bool) -> dict:
    """Per-corner 'object' (local position), 'generated' (position in the mesh's
    texture space, 0..1 over its bounds: (co - location) / (2 size) + 0.5, as Cycles
    syncs ATTR_STD_GENERATED) coordinates and 'normal' (object_normals: the Texture
    Coordinate node's Normal, Box projection), (F,3,3) each, corners in the exported
    order; and per named attribute (LocalGeometry.attributes) 'attr:NAME' (its vector or
    colour), 'attr:NAME.fac', 'attr:NAME.transparency' (1 - alpha, so a mesh without
    the attribute reads alpha 1 as Cycles' Attribute node) and 'attr:NAME.alpha' (0 on a
    mesh without it, as Cycles' Color Attribute node), the last three repeated over the 3
    columns."""
    local = g.co[g.faces]
    loc, size = g.texspace
    size = np.where(np.abs(size) > 1e-12, size, 1.0)
    generated = getattr(g, "generated", None)
    if generated is None:
        generated = (local - loc) / (2.0 * size) + 0.5
    out = {"object": local, "generated": generated,
           "normal": object_normals(g)}
    for name, (vec, fac, alpha) in (getattr(g, "attributes", None) or {}).items():
        out[f"attr:{name}"] = vec
        out[f"attr:{name}.fac"] = np.repeat(fac[..., None], 3, axis=2)
        out[f"attr:{name}.transparency"] = np.repeat(1.0 - alpha[..., None], 3, axis=2)
        out[f"attr:{name}.alpha"] = np.repeat(alpha[..., None], 3, axis=2)
    if flipped:
        out = {k: a[:, [0, 2, 1]] for k, a in out.items()}
    return out


def radial_tangents(g: LocalGeometry, matrix: np.ndarray) -> np.ndarray:
    """(F,3,3) per-corner world-space radial tangent, the default Tangent of Cycles'
    anisotropic closures (a Tangent node, Radial, axis Z: svm_node_tangent's
    (-(g.y - 0.5), g.x - 0.5, 0) of the generated coordinate g, carried to world space by
    the object's normal transform inv(R)^T), corners as the mesh stores them. Linear in g,
    so the engine's interpolation over a triangle gives Cycles' value (engine/anisotropy.py)."""
    gen = texture_coordinates(g, False)["generated"]
    t = np.stack([-(gen[..., 1] - 0.5), gen[..., 0] - 0.5, np.zeros(gen.shape[:-1])], -1)
    try:
        return t @ np.linalg.inv(matrix[:3, :3])  # row form of inv(R)^T t
    except np.linalg.LinAlgError:
        return t @ matrix[:3, :3].T


def corner_attributes(g: LocalGeometry, matrix: np.ndarray, coordinates: bool,
                      radial: bool = False, uv_slots: tuple = ()) -> dict | None:
    """The mesh's per-corner attributes for engine Mesh.coordinates: the texture
    coordinates when a material reads them (texture_coordinates), the radial tangent
    ('radial_tangent', radial_tangents) when a material is anisotropic, and the MikkTSpace
    tangents in world space ('tangent', and 'tangent_sign' as 3 equal values: the
    bitangent's side, flipped with a mirroring transform) for tangent-space normal maps
    (engine/normalmap.py), and those of the UV maps nodes name ('tangent:NAME',
    'tangent_sign:NAME': LocalGeometry.named_tangents). uv_slots: per material slot, the
    UV map whose tangent is the material's anisotropy tangent (MaterialConverter.
    uv_tangent_map: "" the render map; None the radial default): those faces carry that
    MikkTSpace tangent in 'radial_tangent' instead (Cycles' Tangent node, UV Map mode: the
    attribute tangent by the object's normal transform, as the radial one:
    svm_node_tangent); a map the mesh lacks keeps the radial one (warned:
    uv_tangent_warnings). Corners in the exported order. None when there are none."""
    flipped = np.linalg.det(matrix[:3, :3]) < 0
    out = texture_coordinates(g, flipped) if coordinates else {}
    if "attr:point_position" in out:  # Point Info (point_info): world space, as Cycles'
        out["attr:point_position"] = out["attr:point_position"] @ matrix[:3, :3].T \
            + matrix[:3, 3]
        info = out["attr:point_info"].copy()  # point_radius: average(R (r, r, r))
        info[..., 0] *= float(matrix[:3, :3].sum(axis=1).mean())
        out["attr:point_info"] = info
    if radial:
        t = radial_tangents(g, matrix)
        named = getattr(g, "named_tangents", None) or {}
        slot_of = np.clip(g.material_index, 0, max(len(uv_slots) - 1, 0))
        for slot, want in enumerate(uv_slots):
            src = g.tangents if want == "" else named.get(want) if want else None
            if src is None:
                continue
            faces = slot_of == slot
            try:  # svm_node_tangent: object_normal_transform, as the radial one
                t[faces] = src[faces][..., :3] @ np.linalg.inv(matrix[:3, :3])
            except np.linalg.LinAlgError:
                t[faces] = src[faces][..., :3] @ matrix[:3, :3].T
        out["radial_tangent"] = t[:, [0, 2, 1]] if flipped else t
    named = getattr(g, "named_tangents", None) or {}
    for suffix, tangents in [("", g.tangents)] + [(":" + k, v) for k, v in named.items()]:
        if tangents is None:
            continue
        R = matrix[:3, :3]
        t = tangents[..., :3] @ R.T
        sign = np.repeat(tangents[..., 3:4] * (-1.0 if flipped else 1.0), 3, axis=-1)
        if flipped:
            t, sign = t[:, [0, 2, 1]], sign[:, [0, 2, 1]]
        out["tangent" + suffix], out["tangent_sign" + suffix] = t, sign
    return out or None


def transform_geometry(g: LocalGeometry, matrix: np.ndarray):
    """World-space vertices, faces, normals, uvs for one instance."""
    R = matrix[:3, :3]
    t = matrix[:3, 3]
    with np.errstate(invalid="ignore", over="ignore"):
        # (NaN / inf vertices stay so: the engine drops their faces and warns, naming
        # the object; numpy's own RuntimeWarning said nothing a user could act on)
        verts = g.co @ R.T + t
    faces, normals, uvs = g.faces, g.normals, g.uvs
    det = np.linalg.det(R)
    if normals is not None:
        try:
            N = np.linalg.inv(R)  # n' = inv(R)^T n  ->  row form: n @ inv(R)
        except np.linalg.LinAlgError:
            N = None
        if N is None:
            normals = None
        else:
            with np.errstate(invalid="ignore", over="ignore"):
                normals = normals @ N
                length = np.linalg.norm(normals, axis=-1, keepdims=True)
                normals = normals / np.maximum(length, 1e-30)
    if det < 0:
        # Mirrored instance: keep the winding (outside) consistent with the normals.
        faces = faces[:, [0, 2, 1]]
        if normals is not None and normals.ndim == 3:
            normals = normals[:, [0, 2, 1]]
        if uvs is not None:
            uvs = uvs[:, [0, 2, 1]]
    return verts, faces, normals, uvs


# --- ray visibility -----------------------------------------------------------------

VISIBILITY_FLAGS = ("visible_camera", "visible_diffuse", "visible_glossy",
                    "visible_transmission", "visible_shadow")


def _layer_flag(ob, getter: str, view_layer) -> bool:
    """holdout_get / indirect_only_get: they answer for the original object in the
    original view layer (the evaluated copy says False)."""
    ob = getattr(ob, "original", None) or ob
    fn = getattr(ob, getter, None)
    if fn is None or view_layer is None:
        return False
    try:
        return bool(fn(view_layer=view_layer))
    except (TypeError, RuntimeError):
        return False


def holdout_material(mat) -> bool:
    """A material whose Surface is a Holdout shader and nothing else (Cycles'
    holdout closure of weight 1: svm_node_closure_holdout). Such a surface is what an
    object holdout is - alpha 0 and no colour where the camera sees it, opaque to
    shadow rays and photons - so an object whose every slot holds one is exported as an
    object holdout (a product shot's holdout card). A Holdout mixed into other shaders
    is not one: the material converter warns about it."""
    nt = getattr(mat, "node_tree", None) if mat is not None else None
    if nt is None:
        return False
    out = output_node(nt)
    surface = out.inputs.get("Surface") if out is not None else None
    if surface is None or not surface.is_linked:
        return False
    src = surface.links[0].from_node
    return src.type == "HOLDOUT" and not getattr(surface.links[0], "is_muted", False)


def _all_slots_holdout(obj) -> bool:
    slots = [slot.material for slot in getattr(obj, "material_slots", ())]
    return bool(slots) and all(holdout_material(m) for m in slots)


def drop_holdout_warning(mat, engine_material):
    """The converter names a Holdout node 'not supported' (it has no closure for it);
    for a pure Holdout material the object holdout renders it, so that warning is
    wrong there."""
    if holdout_material(mat):
        engine_material.warnings[:] = [w for w in engine_material.warnings
                                       if "(HOLDOUT) is not supported" not in w]


def ray_visibility(obj, inst, view_layer) -> dict:
    """Mesh keyword arguments for an instance's ray visibility, holdout and indirect-only,
    read as Cycles does (blender/object.cpp sync_object): the object's own flags, ANDed
    with the instancer's for instanced geometry; holdout from the object or its
    collection (view layer); an indirect-only collection hides it from camera rays."""
    parent = inst.parent if inst.is_instance and inst.parent is not None else None
    out = {}
    for flag in VISIBILITY_FLAGS:
        on = bool(getattr(obj, flag, True))
        if parent is not None:
            on = on and bool(getattr(parent, flag, True))
        out[flag] = on
    owner = parent if parent is not None else obj
    out["holdout"] = (bool(getattr(obj, "is_holdout", False))
                      or bool(getattr(owner, "is_holdout", False))
                      or _layer_flag(owner, "holdout_get", view_layer)
                      or _all_slots_holdout(obj))
    if _layer_flag(owner, "indirect_only_get", view_layer):
        out["visible_camera"] = False
    # Object > Visibility > Shadow Catcher, the instancer's for its instances as Cycles
    # reads it (blender/object.cpp: the parent's or the object's own).
    out["shadow_catcher"] = (bool(getattr(obj, "is_shadow_catcher", False))
                             or bool(getattr(owner, "is_shadow_catcher", False)))
    return out


def warn_unsupported_object_options(obj, warnings: list):
    """Object options this engine cannot honour, once per object: the last Subdivision
    modifier's Adaptive Subdivision, Light / Shadow Linking."""
    mods = getattr(obj, "modifiers", None) or ()
    last = mods[-1] if len(mods) else None
    if (last is not None and getattr(last, "type", "") == "SUBSURF"
            and getattr(last, "use_adaptive_subdivision", False)
            and getattr(last, "show_render", True)):
        # Cycles dices such a mesh to its pixel size (Blender 5.0: the modifier's
        # Adaptive Subdivision); Blender hands us the modifier's Render levels instead.
        warnings.append(f"object '{obj.name}': Adaptive Subdivision is not made; the "
                        f"Subdivision modifier's render levels ({last.render_levels}) are "
                        "used, so true displacement is only as fine as those")
    warn_light_linking(obj, warnings)


def warn_light_linking(obj, warnings: list, who=None):
    """Object > Shading > Shadow Linking (Blender 4.0+) of an emitting mesh object, which
    this engine does not simulate (a lamp's is rendered, and an object's Light Linking:
    light_link_objects, resolve_light_links), said once per object (it was dropped
    silently, s37): every object blocks its emission."""
    linking = getattr(obj, "light_linking", None)
    who = who or f"object '{obj.name}'"
    for attr, what, effect in (
            ("blocker_collection", "Shadow Linking", "every object casts its shadows"),):
        coll = getattr(linking, attr, None) if linking is not None else None
        if coll is not None:
            warnings.append(f"{who}: {what} (collection '{coll.name}') is not supported; "
                            f"{effect}")


def light_link_objects(coll) -> tuple[list, list]:
    """The objects a Light Linking collection includes and excludes: (include, exclude)
    object names, as Blender's depsgraph resolves it (depsgraph_light_linking.cc,
    foreach_light_collection_object): the collection's own objects with their link state,
    and every object in a child collection (at any depth) with the state of the child
    collection's entry at the first level; an object reached twice takes the last one
    (children first, then the objects: link_object overwrites)."""
    state: dict = {}

    def inner(c, link_state):
        for child in c.children:
            inner(child, link_state)
        for ob in c.objects:
            state[ob.name] = link_state

    # collection_children / collection_objects follow children / objects (one list).
    for child, entry in zip(coll.children, coll.collection_children):
        inner(child, entry.light_linking.link_state)
    for ob, entry in zip(coll.objects, coll.collection_objects):
        state[ob.name] = entry.light_linking.link_state
    include = [n for n, st in state.items() if st == "INCLUDE"]
    exclude = [n for n, st in state.items() if st == "EXCLUDE"]
    return include, exclude


def resolve_light_links(lights: list, meshes: list, owners: dict) -> None:
    """Set the engine lights' receivers / non_receivers and blockers / non_blockers
    (engine mesh names) from the Blender objects convert_light noted
    (light._link_objects: the Light Linking and Shadow Linking collections'
    light_link_objects, or None): with any included object only the included ones
    (Blender: EmitterSetMembership.get_mask, the included sets alone), else every object
    but the excluded ones. owners: mesh name -> (object name, instancer name or None,
    the object's own Light Linking collection's light_link_objects or None)
    (_instance_name): an instance takes its instancer's links when the instancer is in
    any such collection, else its object's (Cycles' BlenderLightLink::
    get_receiver_light_set / get_blocker_shadow_set). An emitting object's own Light
    Linking sets its meshes' receivers / non_receivers alike (the engine reads them
    where the mesh emits)."""
    for mesh in meshes:
        # (cached viewport meshes keep their attributes: the links are set afresh)
        mesh.receivers, mesh.non_receivers = None, []
    emitters = [(mesh, owners[mesh.name][2]) for mesh in meshes
                if mesh.name in owners and len(owners[mesh.name]) > 2
                and owners[mesh.name][2] is not None]
    for k, (kind, non) in enumerate((("receivers", "non_receivers"),
                                     ("blockers", "non_blockers"))):
        links = [(light, light._link_objects[k]) for light in lights
                 if getattr(light, "_link_objects", None) is not None
                 and light._link_objects[k] is not None]
        if k == 0:
            # An emitting object's own Light Linking (engine Mesh.receivers).
            links += emitters
        if not links:
            continue
        named = {ob for _, (inc, exc) in links for ob in (*inc, *exc)}
        by_owner: dict = {}
        for mesh in meshes:
            ob, parent = owners.get(mesh.name, (mesh.cryptomatte_object or mesh.name,
                                                None))[:2]
            by_owner.setdefault(parent if parent in named else ob, []).append(mesh.name)
        for light, (include, exclude) in links:
            if include:
                setattr(light, kind, [m for ob in include for m in by_owner.get(ob, ())])
            else:
                setattr(light, non, [m for ob in exclude for m in by_owner.get(ob, ())])


# --- lights -------------------------------------------------------------------------

def light_node_tint(pm, nt):
    """The factor a light's node tree puts on its colour, as Cycles reads it (the
    light's strength times the shader's emission): Light Output <- Emission whose Color
    is a constant or a Blackbody node of a constant Temperature (a bulb's colour the
    way older tutorials set it) and whose Strength is a constant. RGB (3,) linear
    Rec.709, or None for any other tree (textures, falloff nodes: not supported; an IES
    Texture: light_node_shading)."""
    tint, ies = light_node_shading(pm, nt)
    return tint if ies is None else None


def ies_strength(socket):
    """(factor, IES Texture node) of an Emission Strength socket linked from an IES
    Texture's Fac, directly or through a Math Multiply by a constant (either input), the
    IES node's own Strength and Vector unlinked (its Vector's default: the direction
    from the lamp in its object space, as engine/ies.py evaluates); None otherwise."""
    node, factor = socket.links[0].from_node, 1.0
    if node.type == "MATH" and node.operation == "MULTIPLY" and not node.use_clamp:
        a, b = node.inputs[0], node.inputs[1]
        if a.is_linked == b.is_linked:
            return None
        linked, const = (a, b) if a.is_linked else (b, a)
        factor = float(const.default_value)
        node = linked.links[0].from_node
    if node.type != "TEX_IES":
        return None
    if node.inputs["Strength"].is_linked or node.inputs["Vector"].is_linked:
        return None
    return factor * float(node.inputs["Strength"].default_value), node


def light_node_shading(pm, nt):
    """(tint, ies): light_node_tint's RGB (3,) factor and, where the Emission Strength is
    an IES Texture's Fac (ies_strength), that IES node (its Strength and a Math
    Multiply's constant are in the tint), else None. (None, None) for any other tree."""
    out = output_node(nt, "OUTPUT_LIGHT")
    surface = out.inputs.get("Surface") if out is not None else None
    if surface is None or not surface.is_linked:
        return None, None
    emit = surface.links[0].from_node
    if emit.type != "EMISSION":
        return None, None
    ies = None
    if emit.inputs["Strength"].is_linked:
        found = ies_strength(emit.inputs["Strength"])
        if found is None:
            return None, None
        strength, ies = found
    else:
        strength = float(emit.inputs["Strength"].default_value)
    tint = _emission_colour(pm, emit)
    if tint is None:
        return None, None
    tint = tint * strength
    return (tint, ies) if np.all(np.isfinite(tint)) else (None, None)


def ies_profile(pm, node, name: str, warnings: list):
    """The engine IESProfile (engine/ies.py) of an IES Texture node: its file (External;
    relative paths through bpy.path.abspath) or its text datablock (Internal); None with a
    warning naming the light and the file when it cannot be read (the plain light
    renders, as Cycles' unreadable profile leaves the node without a table)."""
    iesmod = pm.ies
    try:
        if node.mode == "EXTERNAL":
            import bpy
            path = bpy.path.abspath(node.filepath)
            return iesmod.load(path)
        text = node.ies
        if text is None:
            raise iesmod.IESError("the IES Texture node has no text datablock")
        return iesmod.parse(text.as_string(), name=text.name)
    except iesmod.IESError as e:
        warnings.append(f"light '{name}': IES profile not used, the plain light renders "
                        f"({e})")
        return None


def _emission_colour(pm, emit):
    """RGB (3,) of an Emission's Color: a constant or a Blackbody of a constant
    Temperature; None otherwise."""
    col = emit.inputs["Color"]
    if not col.is_linked:
        rgb = np.asarray(tuple(col.default_value)[:3], np.float64)
    else:
        src = col.links[0].from_node
        if src.type != "BLACKBODY" or src.inputs["Temperature"].is_linked:
            return None
        # Cycles' Blackbody node: its fit, negatives clamped (svm_node_blackbody).
        rgb = np.maximum(pm.shadernodes.blackbody_rec709(
            float(src.inputs["Temperature"].default_value))[0], 0.0)
    return rgb


def convert_light(pm, obj, matrix: np.ndarray, name: str, warnings: list):
    """Blender light object -> engine Light with Cycles' units (docs/units.md) and Cycles'
    reading of the object matrix: position = translation, direction = -Z axis (normalised),
    area size = size x length of the X / Y axes (so negative scale flips only what it
    flips in Cycles), point radius and sun strength / angle unscaled, spot cone stretched
    by the scale (measured against Cycles 5.0 in tests/blender/test_blender_fidelity.py).
    An Area light with Cycles' Portal on emits nothing: an engine LightPortal instead
    (light_portal; export_scene parts them from the lights: split_portals)."""
    L = obj.data
    kind = L.type
    if kind == "AREA" and getattr(getattr(L, "cycles", None), "is_portal", False):
        return light_portal(pm, L, matrix, name, warnings)
    if kind not in pm.DECLARED_KINDS:  # the engine's light registry (engine/lights/)
        warnings.append(f"light '{name}': type {kind} is not supported and skipped")
        return None
    color = np.asarray(tuple(L.color)[:3], dtype=np.float64)
    if getattr(L, "use_temperature", False):
        color = color * np.asarray(tuple(L.temperature_color)[:3], dtype=np.float64)
    power = float(L.energy) * 2.0 ** float(getattr(L, "exposure", 0.0))
    if not (math.isfinite(power) and np.all(np.isfinite(color))):
        warnings.append(f"light '{name}': power {L.energy} W / colour {tuple(color)} is not "
                        "a finite number; the light is skipped")
        return None
    if power < 0 or np.any(color < 0):
        # Cycles subtracts light for a negative power; photons cannot carry negative flux.
        warnings.append(f"light '{name}': negative power ({power:g} W) or colour is not "
                        "supported; the light is skipped")
        return None
    if power == 0 or not np.any(color > 0):
        return None
    R = matrix[:3, :3]
    pos = matrix[:3, 3]
    direction = -R[:, 2]
    axis_u = R[:, 0]
    if np.linalg.norm(direction) < 1e-12:
        warnings.append(f"light '{name}': zero scale, skipped")
        return None
    kw = dict(name=name, kind=kind, power=power, color=color, position=pos,
              direction=direction, axis_u=axis_u if np.linalg.norm(axis_u) > 1e-12 else (1, 0, 0),
              # Cycles never shows a sun lamp's disc to camera rays, whatever the object's
              # camera visibility (measured: Cycles 5.0.1, a 20-degree sun in view reads 0);
              # a Sky Texture's disc is (world.sky_sun_lights).
              visible_camera=kind != "SUN" and bool(getattr(obj, "visible_camera", False)),
              **{flag: bool(getattr(obj, flag, True)) for flag in VISIBILITY_FLAGS[1:4]},
              lightgroup=str(getattr(obj, "lightgroup", "") or ""))
    if kind in ("POINT", "SPOT"):
        kw["radius"] = float(L.shadow_soft_size)
        # Soft Falloff (Blender >= 4.0, on by default): off, Cycles' light is a sphere
        # of that radius instead of the disk facing the shaded point (is_sphere).
        kw["soft_falloff"] = bool(getattr(L, "use_soft_falloff", True))
    if kind == "SPOT":
        kw["spot_size"] = float(L.spot_size)
        kw["spot_blend"] = float(L.spot_blend)
        # Cycles (>= 3.5) stretches the cone by the object's scale and shear: a direction
        # goes into cone space through the inverse object matrix (kernel/light/spot.h,
        # spot_light_to_local; with orthogonal axes its rows are X/|X|^2, Y/|Y|^2,
        # Z/|Z|^2; a sheared spot matched Cycles 5.0 only with the inverse), local -Z
        # being the cone's axis.
        try:
            inv = np.linalg.inv(R)
        except np.linalg.LinAlgError:
            inv = None
        if inv is not None and np.all(np.isfinite(inv)):
            kw["spot_frame"] = np.stack([inv[0], inv[1], -inv[2]])
    if kind == "AREA":
        sx = float(np.linalg.norm(R[:, 0]))
        sy = float(np.linalg.norm(R[:, 1]))
        shape = L.shape
        size_y = L.size_y if shape in ("RECTANGLE", "ELLIPSE") else L.size
        kw.update(shape=shape, size_x=float(L.size) * sx, size_y=float(size_y) * sy)
        if sx > 1e-12 and sy > 1e-12 and abs(np.dot(R[:, 0], R[:, 1])) > 1e-6 * sx * sy:
            kw["skew_axis_v"] = R[:, 1]  # sheared object matrix (a parent's scale)
        kw["spread"] = min(max(float(getattr(L, "spread", math.pi)), 0.0), math.pi)
    if kind == "SUN":
        kw["angle"] = float(L.angle)
    if hasattr(L, "normalize"):
        kw["normalize"] = bool(L.normalize)
    if getattr(L, "use_nodes", False) and L.node_tree is not None:
        tint, ies = light_node_shading(pm, L.node_tree)
        if tint is None:
            warnings.append(f"light '{name}': light node trees other than an Emission "
                            "of a constant colour or a Blackbody of a constant temperature, "
                            "its Strength a constant or an IES Texture's Fac (optionally "
                            "times a constant) are not supported; using the light's colour "
                            "and power")
        elif ies is not None and kind not in ("POINT", "SPOT"):
            warnings.append(f"light '{name}': an IES Texture on a {kind.lower()} light is "
                            "not supported (point and spot lights only); using the light's "
                            "colour and power")
        else:
            profile = ies_profile(pm, ies, name, warnings) if ies is not None else None
            if ies is None or profile is not None:
                kw["color"] = np.asarray(kw["color"], np.float64) * tint
                kw["ies_profile"] = profile
    if not getattr(L, "use_shadow", True):
        kw["cast_shadow"] = False
        warnings.append(f"light '{name}': 'cast shadow' off: its direct light passes every "
                        "object, as in Cycles; its indirect light (photons) is still shadowed")
    light = pm.Light(**kw)
    linking = getattr(obj, "light_linking", None)
    colls = [getattr(linking, a, None) for a in ("receiver_collection", "blocker_collection")]
    if any(c is not None for c in colls):
        # Light / Shadow Linking: resolved to engine meshes once they are known
        # (resolve_light_links).
        light._link_objects = tuple(None if c is None else light_link_objects(c)
                                    for c in colls)
    return light


def light_portal(pm, L, matrix: np.ndarray, name: str, warnings: list):
    """An Area light with Cycles' Portal on (light data L, world matrix (4,4)): emits
    nothing in Cycles, so no light here either; its rectangle (Square / Rectangle, or
    the one a Disk / Ellipse portal is inscribed in, round: Cycles' is_round portals) as
    engine.scene.LightPortal, its normal the light's local -Z (into the room), or None."""
    rnd = L.shape in ("DISK", "ELLIPSE")
    if not (rnd or L.shape in ("SQUARE", "RECTANGLE")):
        warnings.append(f"light portal '{name}': shape {L.shape} is not supported (only "
                        "Square, Rectangle, Disk and Ellipse portals); it is left out "
                        "(it emits nothing)")
        return None
    R = matrix[:3, :3]
    hx = 0.5 * float(L.size) * R[:, 0]
    hy = 0.5 * float(L.size_y if L.shape in ("RECTANGLE", "ELLIPSE") else L.size) * R[:, 1]
    c = matrix[:3, 3]
    corners = np.array([c - hx - hy, c + hx - hy, c + hx + hy, c - hx + hy])
    normal = -R[:, 2]
    if not (np.linalg.norm(np.cross(hx, hy)) > 0 and np.linalg.norm(normal) > 0):
        # (Cycles renders the sky's light through such a portal black: the new-user
        # trial's room 0.52 as bright as ours, which leaves the portal out.)
        warnings.append(f"light portal '{name}': its size is zero; it is left out (Cycles "
                        "lights the room far darker with it: give the portal the window's "
                        "size)")
        return None
    return pm.LightPortal(name=name, corners=corners, normal=normal, round=rnd)


def split_portals(pm, lights: list) -> tuple:
    """(lights, portals): convert_light's results parted into lights and LightPortals."""
    portals = [x for x in lights if isinstance(x, pm.LightPortal)]
    return [x for x in lights if not isinstance(x, pm.LightPortal)], portals


# --- camera -------------------------------------------------------------------------

def convert_camera(pm, cam_obj, width: int, height: int, render, warnings: list,
                   scene_objects=None):
    """The scene's Camera (engine.scene) from Blender camera object cam_obj; depth of field
    by camera_dof (scene_objects: the rendered scene's objects, to warn about a focus
    object outside it). Raises ExportError without a camera."""
    if cam_obj is None:
        raise ExportError("The scene has no active camera: add one and make it active "
                          "(Ctrl+Numpad 0)")
    cd = cam_obj.data
    M = np.array(cam_obj.matrix_world, dtype=np.float64)
    fit = cd.sensor_fit
    sensor = cd.sensor_height if fit == "VERTICAL" else cd.sensor_width
    kind = cd.type
    panorama = None
    fov = 2.0 * math.atan(sensor / (2.0 * cd.lens))
    # Blender's shift is in units of the sensor-fit dimension; the engine's in units of
    # the larger image dimension (a panorama's: of the image, as Cycles adds it).
    fit_dim = {"HORIZONTAL": width, "VERTICAL": height}.get(fit, max(width, height))
    shift_scale = fit_dim / max(width, height)
    if kind == "PANO":
        panorama = camera_panorama(pm, cd)
        shift_scale = 1.0
        if getattr(render, "use_multiview", False):
            warnings.append(f"camera '{cam_obj.name}': stereoscopy is not supported; "
                            "rendering one panorama from the camera's centre")
    dof = camera_dof(cam_obj, cd, kind, warnings, scene_objects)
    if abs(render.pixel_aspect_x - render.pixel_aspect_y) > 1e-6:
        warnings.append("non-square pixel aspect is not supported; using square pixels")
    return pm.Camera(position=M[:3, 3], rotation=M[:3, :3], fov=fov, kind=kind,
                     ortho_scale=cd.ortho_scale, shift_x=cd.shift_x * shift_scale,
                     shift_y=cd.shift_y * shift_scale, sensor_fit=fit,
                     clip_start=cd.clip_start, clip_end=cd.clip_end, panorama=panorama,
                     **dof)


def camera_panorama(pm, cd):
    """engine.panorama.Panorama of a panoramic Blender camera (data cd): its Panorama Type
    and that type's settings, as Cycles' blender/camera.cpp reads them (Blender 4.x
    stores them on the camera data)."""
    g = (lambda name, default: float(getattr(cd, name, default)))
    return pm.panorama.Panorama(
        kind=str(getattr(cd, "panorama_type", "FISHEYE_EQUISOLID")),
        fisheye_fov=g("fisheye_fov", math.pi), fisheye_lens=g("fisheye_lens", 10.5),
        sensor_width=g("sensor_width", 36.0), sensor_height=g("sensor_height", 24.0),
        latitude_min=g("latitude_min", -0.5 * math.pi),
        latitude_max=g("latitude_max", 0.5 * math.pi),
        longitude_min=g("longitude_min", -math.pi), longitude_max=g("longitude_max", math.pi),
        fisheye_polynomial=tuple(g(f"fisheye_polynomial_k{i}", 0.0) for i in range(5)),
        cylindrical_range=(g("central_cylindrical_range_u_min", -math.pi),
                           g("central_cylindrical_range_u_max", math.pi),
                           g("central_cylindrical_range_v_min", -1.0),
                           g("central_cylindrical_range_v_max", 1.0)),
        cylindrical_radius=g("central_cylindrical_radius", 1.0))


def camera_dof(cam_obj, cd, kind: str, warnings: list, scene_objects=None) -> dict:
    """Depth of field as Camera keywords (aperture_radius, focus_distance, aperture_blades,
    aperture_rotation, aperture_ratio), as Cycles' blender/camera.cpp reads it: the
    aperture radius is lens / (2 f-stop) with the lens in m (orthographic: 1 / (2 f-stop)),
    the f-stop at least 1e-5; a focus object gives the distance from the camera to its
    origin (or its focus bone's head) along the view axis. {} when Depth of Field is off.
    A focus object outside the scene, a focus bone it lacks, or a zero focus distance
    warn naming the camera."""
    d = getattr(cd, "dof", None)
    if d is None or not d.use_dof:
        return {}
    name = cam_obj.name
    fstop = max(float(d.aperture_fstop), 1e-5)
    aperture = (1.0 if kind == "ORTHO" else float(cd.lens) * 1e-3) / (2.0 * fstop)
    focus = float(d.focus_distance)
    target = d.focus_object
    if target is not None:
        M = np.array(target.matrix_world, dtype=np.float64)
        point = M[:3, 3]
        bone_name = getattr(d, "focus_subtarget", "")
        if bone_name and target.pose is not None:
            bone = target.pose.bones.get(bone_name)
            if bone is None:
                warnings.append(f"camera '{name}': focus bone '{bone_name}' is not in "
                                f"'{target.name}'; focusing on its origin")
            else:
                point = (M @ np.append(np.array(bone.head, dtype=np.float64), 1.0))[:3]
        if scene_objects is not None and target.name not in scene_objects:
            warnings.append(f"camera '{name}': focus object '{target.name}' is not in the "
                            "scene; focusing at its position all the same (as Cycles)")
        C = np.array(cam_obj.matrix_world, dtype=np.float64)
        view = C[:3, 2] / max(float(np.linalg.norm(C[:3, 2])), 1e-300)
        focus = abs(float(np.dot(view, C[:3, 3] - point)))
    if not (focus > 1e-6):
        warnings.append(f"camera '{name}': depth of field focuses at distance {focus:g} "
                        "m; rendering everything in focus")
        return {}
    return dict(aperture_radius=aperture, focus_distance=focus,
                aperture_blades=int(d.aperture_blades),
                aperture_rotation=float(d.aperture_rotation),
                aperture_ratio=max(float(d.aperture_ratio), 1e-6))


# --- scene --------------------------------------------------------------------------

def render_size(render) -> tuple[int, int]:
    """Output size in pixels with the resolution percentage applied."""
    pct = render.resolution_percentage / 100.0
    return max(1, int(render.resolution_x * pct)), max(1, int(render.resolution_y * pct))


CYCLES_PIXEL_FILTERS = {"BOX": "box", "GAUSSIAN": "gaussian",
                        "BLACKMAN_HARRIS": "blackman_harris"}


def pixel_filter_settings(scene) -> dict:
    """The pixel filter as RenderSettings keywords (pixel_filter, filter_width).

    Cycles reads its own Film > Pixel Filter (scene.cycles.pixel_filter_type and
    filter_width, default Blackman-Harris 1.5 px; the box is always 1 px wide: Cycles'
    blender/sync.cpp). We read the same properties, so a scene renders with the filter
    Cycles would use. Without the Cycles add-on (scene.cycles absent) Blender's
    render.filter_size (Film > Filter Size, EEVEE's, default 1.5 px) sets a
    Blackman-Harris width; 0 there means every ray through the pixel centre."""
    cycles = getattr(scene, "cycles", None)
    kind = getattr(cycles, "pixel_filter_type", None) if cycles is not None else None
    if kind in CYCLES_PIXEL_FILTERS:
        width = 1.0 if kind == "BOX" else float(cycles.filter_width)
        return dict(pixel_filter=CYCLES_PIXEL_FILTERS[kind], filter_width=width)
    return dict(pixel_filter="blackman_harris",
                filter_width=float(getattr(scene.render, "filter_size", 1.5)))


# Light Paths > Max Bounces: Cycles' property names, which ours (scene.photonmap) share.
LIGHT_PATH_LIMITS = ("max_bounces", "diffuse_bounces", "glossy_bounces",
                     "transmission_bounces", "transparent_max_bounces")


def cycles_source(scene, props, names):
    """Where settings both engines name alike come from: scene.cycles when the Cycles
    add-on is there with all of `names` registered (a scene set up for Cycles renders
    with its values here too, as other render engines read them), else props
    (scene.photonmap, which shares the names)."""
    cycles = getattr(scene, "cycles", None)
    if cycles is not None and all(hasattr(cycles, n) for n in names):
        return cycles
    return props


def volume_bounces_warning(scene, materials, warnings, world_medium=None) -> None:
    """Light Paths > Volume bounces above 0 (scene.cycles.volume_bounces; Cycles' default
    is 0) with a scattering medium in the scene: the camera paths scatter that many more
    times inside the medium, each scatter lit by the lamps (engine/volumescatter.py) and
    by the diffuse surfaces at its walk segments' ends (engine/volumewalk.py, from the
    gather map), and photons scatter in it onto the surfaces (engine/photonmedium.py);
    a glossy surface's light scattered in the fog is not followed: warned, naming the
    media and the sharp glossy, mirror or glass materials, only where the scene has such
    a material."""
    bounces = int(getattr(getattr(scene, "cycles", None), "volume_bounces", 0) or 0)
    if bounces <= 0:
        return
    names = sorted(name for name, m in materials.items()
                   if np.any(np.asarray(getattr(m, "scattering", 0.0)) > 0))
    names = [f"'{n}'" for n in names]
    if world_medium is not None and np.any(np.asarray(world_medium.scattering) > 0):
        names.insert(0, "the World Volume")  # (engine/worldmedium.py)
    # Surfaces whose light the walks do not follow: mirrors, metals, glass, sharp
    # specular layers (a rough one's glossy share is small, and newuser38 read the
    # warning in every fog scene as a promise of darkness that did not come).
    sharp = sorted(f"'{name}'" for name, m in materials.items()
                   if (float(np.max(np.atleast_1d(getattr(m, "metallic", 0.0)))) > 0.5
                       or float(np.max(np.atleast_1d(getattr(m, "transmission", 0.0)))) > 0.5
                       or (float(np.max(np.atleast_1d(getattr(m, "specular", 0.0)))) > 0
                           and float(np.min(np.atleast_1d(getattr(m, "roughness", 1.0))))
                           < 0.3)))
    if names and sharp:
        shown = ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")
        glossy = ", ".join(sharp[:3]) + (", ..." if len(sharp) > 3 else "")
        warnings.append(f"Light Paths > Volume bounces is {bounces}: the media of {shown} "
                        "scatter light up to that many more times (camera paths, photons, "
                        "the diffuse surfaces' light from the photon maps), but the light "
                        f"of the glossy, mirror or glass surfaces {glossy} scattered in "
                        "the medium is not followed: it is missing where Cycles has it "
                        "(at 0, Cycles' default, nothing is left out)")


def light_path_source(scene, props):
    """Where the Light Paths limits come from (cycles_source): a scene set to Diffuse 1
    for Cycles renders with 1 here too."""
    return cycles_source(scene, props, LIGHT_PATH_LIMITS)


def light_path_settings(scene, props) -> dict:
    """The Light Paths limits as RenderSettings keywords (LIGHT_PATH_LIMITS): Cycles' own
    properties when the Cycles add-on is there, else ours (light_path_source)."""
    src = light_path_source(scene, props)
    out = {n: int(getattr(src, n)) for n in LIGHT_PATH_LIMITS}
    # Cycles' Volume bounces (default 0), read from Cycles' settings only (ours has no
    # such property: without the Cycles add-on, 0).
    out["volume_bounces"] = int(getattr(getattr(scene, "cycles", None), "volume_bounces", 0)
                                or 0)
    return out


# Light Paths > Clamping: Cycles' property names (UI units, 0 = off), which ours share.
CLAMP_SETTINGS = ("sample_clamp_direct", "sample_clamp_indirect")


def clamp_source(scene, props):
    """Where Light Paths > Clamping comes from (cycles_source): a scene clamped for
    Cycles renders with its clamp here too."""
    return cycles_source(scene, props, CLAMP_SETTINGS)


def clamp_settings(scene, props) -> dict:
    """Clamp Direct / Indirect as RenderSettings keywords (clamp_direct, clamp_indirect,
    Cycles' UI values; engine/sampleclamp.py): Cycles' own properties when the Cycles
    add-on is there, else ours (clamp_source)."""
    src = clamp_source(scene, props)
    return dict(clamp_direct=float(src.sample_clamp_direct),
                clamp_indirect=float(src.sample_clamp_indirect))


def filter_glossy_settings(scene) -> dict:
    """Cycles' Light Paths > Caustics (Filter Glossy, Reflective, Refractive) as the
    RenderSettings keywords cycles_filter_glossy, cycles_caustics_reflective,
    cycles_caustics_refractive (0 / on / on without the Cycles add-on). Filter Glossy
    blurs the camera paths as Cycles' (engine/filterglossy.py) and the caustic / glow
    maps' paths (engine/glossysplit.py); the rest is named by the effect
    report where it changes Cycles' image (engine/settings.py)."""
    cycles = getattr(scene, "cycles", None)
    return dict(cycles_filter_glossy=float(getattr(cycles, "blur_glossy", 0.0) or 0.0),
                cycles_caustics_reflective=bool(getattr(cycles, "caustics_reflective", True)),
                cycles_caustics_refractive=bool(getattr(cycles, "caustics_refractive", True)))


def border_region(render, width: int, height: int):
    """Render border as engine region (x0, y0, x1, y1), top-left origin, or None.

    Same rounding as Blender (render_init_from_main: border * size in float32, truncated).
    In double precision 0.9 x 120 is 107.99999 -> 107 where Blender gets 108: the region
    was a row or column off Blender's, so the film landed one pixel off in the result
    Blender allocates for its own border (new-user trial, newuser29)."""
    if not render.use_border:
        return None

    def px(fraction, size):
        return int(np.float32(fraction) * np.float32(size))

    x0 = px(render.border_min_x, width)
    x1 = px(render.border_max_x, width)
    yb0 = px(render.border_min_y, height)
    yb1 = px(render.border_max_y, height)
    if x1 <= x0 or yb1 <= yb0:
        return None
    if (x0, yb0, x1, yb1) == (0, 0, width, height):
        return None
    return (x0, height - yb1, x1, height - yb0)


def terminator_offset(obj) -> float:
    """Cycles' Object > Shadow Terminator > Geometry Offset (default 0.1). (The Normal
    Offset beside it is EEVEE's; Cycles ignores it, and so do we.)"""
    value = float(getattr(obj, "shadow_terminator_geometry_offset", 0.1))
    return value if value >= 0 else 0.0


def terminator_shading(obj) -> float:
    """Cycles' Object > Shadow Terminator > Shading Offset (default 0; Cycles' formula
    divides by 1 - offset / 2, so values are kept below 2)."""
    value = float(getattr(obj, "shadow_terminator_shading_offset", 0.0))
    return min(max(value, 0.0), 1.999)


def _geometry_key(obj):
    """What identifies an evaluated object's geometry: its name and its data-block."""
    data = getattr(obj, "data", None)
    return (obj.name, data.as_pointer() if data is not None else 0)


# Object types whose triangles Blender generates (text, curves, surfaces, metaballs):
# their zero-area triangles (a bevelled text's caps) are dropped without a word, as
# Cycles renders them; a mesh's are warned (a broken mesh the user may want to fix).
GENERATED_GEOMETRY = ("FONT", "CURVE", "SURFACE", "META")


def quiet_generated_degenerates(inst, obj, mesh) -> None:
    """Drop the engine Mesh's 'zero-area faces' warning for an object of a
    GENERATED_GEOMETRY type (newuser40: every bevelled Text warned 'dropped 4 zero-area
    faces'). Blender 5 hands a text's triangles over as a mesh instance of the text
    object: its original's or instancer's type decides."""
    kinds = {getattr(obj, "type", "MESH"),
             getattr(getattr(obj, "original", None), "type", None),
             getattr(getattr(inst, "parent", None), "type", None) if inst.is_instance
             else None}
    if kinds & set(GENERATED_GEOMETRY):
        mesh.warnings[:] = [w for w in mesh.warnings if "zero-area faces" not in w]


def _instance_name(inst, obj, info) -> str:
    """The engine mesh name of a depsgraph instance (counts instances in info; notes
    its object and instancer in info["owners"] for resolve_light_links)."""
    owners = info.setdefault("owners", {})
    # An emitting object's own Light Linking collection (resolve_light_links).
    coll = getattr(getattr(obj, "light_linking", None), "receiver_collection", None)
    own = None if coll is None else light_link_objects(coll)
    if not inst.is_instance:
        owners[obj.name] = (obj.name, None, own)
        return obj.name
    parent = inst.parent.name if inst.parent is not None else "instance"
    # Numbered per instancer and object: 'Scatter/Chair#0', ...; an object whose own
    # evaluated geometry comes as instances of itself (Geometry Nodes on a mesh, a Text
    # in Blender 5) 'Text#0' (newuser40: a plain Text read 'Text/Text#360', numbered
    # after another object's 360 instances).
    numbers = info.setdefault("instance_numbers", {})
    k = numbers.get((parent, obj.name), 0)
    numbers[(parent, obj.name)] = k + 1
    name = f"{obj.name}#{k}" if parent == obj.name else f"{parent}/{obj.name}#{k}"
    info["instances"] += 1
    owners[name] = (obj.name, inst.parent.name if inst.parent is not None else None, own)
    return name


def slot_materials(obj, converter, materials: dict) -> list:
    """The engine material names of obj's material slots (object- or data-linked, as the
    evaluated object sees them; one default without slots), each converted once and added
    to materials (name -> engine Material)."""
    names = []
    for mat in [slot.material for slot in obj.material_slots] or [None]:
        m = converter.convert(mat)
        drop_holdout_warning(mat, m)
        materials[m.name] = m
        names.append(m.name)
    return names


def particle_hair_mesh(pm, inst, obj, geo: LocalGeometry, converter, materials: dict,
                       info: dict, view_layer):
    """The engine Mesh of an object's particle hair (extract_particle_hair's local
    geometry) at the instance's matrix, named '<object>/particle hair': the emitter's
    material slots, ray visibility, Object Info and Cryptomatte names (Cycles renders the
    strands as part of the emitter object), its Light Linking too (info["owners"])."""
    names = slot_materials(obj, converter, materials)
    base = _instance_name(inst, obj, info)
    name = f"{base}/particle hair"
    info["owners"][name] = info["owners"][base]
    matrix = np.array(inst.matrix_world, dtype=np.float64)
    verts, faces, normals, uvs = transform_geometry(geo, matrix)
    coords = corner_attributes(geo, matrix, any(converter.needs_coordinates(n) for n in names),
                               any(_radial(converter, n) for n in names),
                               _uv_slots(converter, names))
    return pm.Mesh(name=name, vertices=verts, faces=faces, normals=normals, uvs=uvs,
                   materials=names, material_ids=np.clip(geo.material_index, 0, len(names) - 1),
                   coordinates=coords, pass_index=pass_index(obj),
                   **object_info(obj, inst, converter.object_attribute_names),
                   **cryptomatte_names(obj), **ray_visibility(obj, inst, view_layer))


def _prototype(pm, name, geo: LocalGeometry, mids):
    """The engine Prototype of local geometry: object-space vertices, faces, normals,
    UVs and material slots, written once however often it is placed."""
    return pm.Prototype(name=name, vertices=geo.co, faces=geo.faces, normals=geo.normals,
                        uvs=geo.uvs, material_ids=mids)


def _placeable(geo: LocalGeometry, converter, names) -> bool:
    """Geometry a placement without a copy can carry (engine Mesh.place): no colour
    attribute, no tangents for normal maps and no texture coordinates a material reads
    (those stay per-instance copies with an instance record)."""
    return (geo.colors is None and geo.tangents is None and not geo.named_tangents
            and not any(converter.needs_coordinates(n) or _radial(converter, n)
                        for n in names))


def pass_index(obj) -> int:
    """The object's Pass Index (Object > Relations; an instance's own object), written by
    the Object Index data pass (Cycles' object_pass_id)."""
    return int(getattr(obj, "pass_index", 0) or 0)


def _uv_slots(converter, names) -> tuple:
    """Per material slot: the UV map whose tangent is the material's anisotropy tangent
    ("" the render map), or None (the radial default)."""
    f = getattr(converter, "uv_tangent_map", None)
    return tuple(f(n) if f else None for n in names)


def uv_tangent_warnings(obj, geo: LocalGeometry, converter, names, warnings):
    """Warn (naming object and material) where a material wants a UV map's tangent the
    export cannot give: no UV map / no MikkTSpace tangents, or a Tangent node naming a
    map the mesh lacks (the radial tangent is used); a Normal Map naming a map the mesh
    lacks (no perturbation, as Cycles renders it)."""
    f = getattr(converter, "uv_tangent_map", None)
    for n in dict.fromkeys(names):
        want = f(n) if f else None
        if want is None:
            continue
        if want == "" and geo.tangents is None:
            warnings.append(f"object '{obj.name}': the Tangent node of material '{n}' "
                            "reads a UV map the mesh does not have (or cannot give "
                            "tangents for); the default radial tangent is used")
        elif want and want not in geo.named_tangents:
            warnings.append(f"object '{obj.name}': material '{n}''s Tangent node names UV "
                            f"map '{want}', which the mesh does not have (or cannot give "
                            "tangents for); the default radial tangent is used")
    normal_maps = getattr(converter, "normal_map_uvs", {})
    for n in dict.fromkeys(names):
        want = normal_maps.get(n)
        if want and want not in geo.named_tangents:
            warnings.append(f"object '{obj.name}': material '{n}''s Normal Map names UV map "
                            f"'{want}', which the mesh does not have (or cannot give "
                            "tangents for): its normal is not perturbed there (as in Cycles)")


def _radial(converter, name) -> bool:
    """The material is anisotropic: its meshes carry the radial tangent (world space)."""
    f = getattr(converter, "needs_radial_tangent", None)
    return bool(f and f(name))


def cryptomatte_names(obj) -> dict:
    """Mesh keywords naming obj in Cryptomatte's object and asset layers: the object's
    name, which the instances of one object share (Cycles names instances by their real
    object), and its topmost parent's (Blender's BKE_cryptomatte_asset_hash)."""
    top = obj
    while top.parent is not None:
        top = top.parent
    return {"cryptomatte_object": obj.name, "cryptomatte_asset": top.name}


def _rot32(x, k):
    return ((x << k) | (x >> (32 - k))) & 0xFFFFFFFF


def _lookup3_final(a, b, c):
    """Bob Jenkins' lookup3 final() mix of uint32 a, b, c (Python ints or int64 arrays
    holding uint32 values); returns c (util/hash.h)."""
    m = 0xFFFFFFFF
    c = (c ^ b) & m; c = (c - _rot32(b, 14)) & m  # noqa: E702
    a = (a ^ c) & m; a = (a - _rot32(c, 11)) & m  # noqa: E702
    b = (b ^ a) & m; b = (b - _rot32(a, 25)) & m  # noqa: E702
    c = (c ^ b) & m; c = (c - _rot32(b, 16)) & m  # noqa: E702
    a = (a ^ c) & m; a = (a - _rot32(c, 4)) & m  # noqa: E702
    b = (b ^ a) & m; b = (b - _rot32(a, 14)) & m  # noqa: E702
    c = (c ^ b) & m; c = (c - _rot32(b, 24)) & m  # noqa: E702
    return c


def hash_uint_to_float(kx) -> np.ndarray:
    """Cycles' hash_uint_to_float (util/hash.h) of uint32 values kx (array): lookup3's
    hash_uint, (float)h / (float)0xFFFFFFFF in float32."""
    m = 0xFFFFFFFF
    init = (0xDEADBEEF + (1 << 2) + 13) & m
    k = np.asarray(kx, np.int64) & m
    h = _lookup3_final((init + k) & m, np.full_like(k, init), np.full_like(k, init))
    return (h.astype(np.float32) / np.float32(4294967295.0)).astype(np.float64)


def random_per_island(me, faces) -> np.ndarray:
    """(F,) Cycles' Random Per Island of each loop triangle (blender/mesh.cpp
    attr_create_random_per_island): the mesh's vertices joined along its edges in a
    disjoint set (util/disjoint_set.h: union by rank, the first argument's root kept on
    a tie), each triangle's value hash_uint_to_float of the root of its first vertex.
    faces: (F,3) the loop triangles' vertices as Blender orders them."""
    n = len(me.vertices)
    edges = _foreach(me.edges, "vertices", len(me.edges), 2, np.int32).tolist()
    parent = list(range(n))
    rank = [0] * n

    def find(x):
        root = x
        while parent[root] != root:
            root = parent[root]
        while parent[x] != root:
            parent[x], x = root, parent[x]
        return root

    for x, y in edges:
        rx, ry = find(x), find(y)
        if rx == ry:
            continue
        if rank[rx] < rank[ry]:
            rx, ry = ry, rx
        parent[ry] = rx
        if rank[rx] == rank[ry]:
            rank[rx] += 1
    roots = np.array([find(v) for v in range(n)], np.int64)
    return hash_uint_to_float(roots[np.asarray(faces)[:, 0]])


def cycles_name_random_id(name: str) -> int:
    """Cycles' random_id of an object that is not an instance: hash_uint2(hash_string(
    name), 0) (intern/cycles/blender/object.cpp; util/hash.h: hash_string's i * 37 + c over
    the name's bytes as C chars, then lookup3's final mix of a = kx, b = ky on the seed
    0xdeadbeef + (2 << 2) + 13). The depsgraph's random_id is 0 for such objects."""
    h = 0
    for byte in name.encode("utf-8"):
        c = byte - 256 if byte >= 128 else byte  # a signed char, widened to uint
        h = (h * 37 + c) & 0xFFFFFFFF
    return int(hash_uint2(h, 0))


def hash_uint2(kx, ky):
    """Cycles' hash_uint2 (util/hash.h) of uint32 kx, ky (Python ints or int64 arrays):
    lookup3's final mix of a = kx, b = ky on the seed 0xdeadbeef + (2 << 2) + 13."""
    m = 0xFFFFFFFF
    init = (0xDEADBEEF + (2 << 2) + 13) & m
    kx = np.asarray(kx, np.int64) & m
    return _lookup3_final((init + kx) & m, (init + (np.int64(ky) & m)) & m,
                          np.full_like(kx, init))


def _world_group(world) -> str:
    return str(getattr(world, "lightgroup", "") or "") if world is not None else ""


def set_world_lightgroup(scene, world) -> None:
    """scene.world_lightgroup from Blender's world.lightgroup (World > Settings > Light
    Group; engine/lightgroups.py)."""
    scene.world_lightgroup = _world_group(world)


def world_lights(pm, environment, seen, world) -> list:
    """The lights the world brings (a Sky Texture's sun disc: world.sky_sun_lights), in
    the world's light group."""
    out = sky_sun_lights(pm, environment, seen)
    for light in out:
        light.lightgroup = _world_group(world)
    return out


def object_info(obj, inst, attribute_requests=()) -> dict:
    """Mesh keywords of the Object Info node: random (Cycles' random_number: the
    random_id / (2^32 - 1) in float32, scene/object.cpp; an instance's random_id from the
    depsgraph, an object's from its name: cycles_name_random_id), object_color
    (object.color RGBA), location (the instance's world-space origin), object_linear (its
    matrix's 3x3 linear part: the Displacement node's Object space) and
    object_attributes (object_attributes of attribute_requests)."""
    if inst.is_instance:
        rid = int(getattr(inst, "random_id", 0) or 0) & 0xFFFFFFFF
    else:
        rid = cycles_name_random_id(obj.name)
    random = float(np.float32(rid) * np.float32(1.0 / 0xFFFFFFFF))
    color = tuple(float(c) for c in getattr(obj, "color", (1.0, 1.0, 1.0, 1.0)))[:4]
    # Object Info Location: Cycles' object_location, the object matrix's translation.
    matrix = np.array(inst.matrix_world, np.float64)
    location = tuple(float(x) for x in matrix[:3, 3])
    # A Displacement node's Object space: the matrix's linear part.
    linear = tuple(tuple(float(x) for x in row) for row in matrix[:3, :3])
    # Light Group (engine/lightgroups.py): the object's, else its instancer's (Cycles:
    # an instance without one of its own takes its parent's).
    group = str(getattr(obj, "lightgroup", "") or "")
    if not group and getattr(inst, "is_instance", False):
        group = str(getattr(getattr(inst, "parent", None), "lightgroup", "") or "")
    return dict(random=random, object_color=color, location=location, object_linear=linear,
                object_attributes=object_attributes(obj, inst, attribute_requests),
                lightgroup=group)


def _property_rgba(idblock, name):
    """RGBA of an ID's custom property or RNA path `name` as Blender converts it for
    Cycles' object attributes (blenkernel object_dupli.cc find_property_rgba): a number
    or boolean f gives (f, f, f, 1); a float or int array of up to 4 fills (0, 0, 0, 1)
    from the start; None when there is no such property or it is of another kind."""
    if idblock is None:
        return None
    val = None
    try:
        if name in idblock.keys():  # custom properties first
            val = idblock[name]
    except (TypeError, AttributeError):
        val = None
    if val is None:
        try:
            val = idblock.path_resolve(name)
        except (ValueError, TypeError, AttributeError):
            return None
    if isinstance(val, bool):
        f = 1.0 if val else 0.0
        return (f, f, f, 1.0)
    if isinstance(val, (int, float)):
        return (float(val),) * 3 + (1.0,)
    try:
        items = list(val)
    except TypeError:
        return None
    if not items or len(items) > 4 or any(isinstance(x, bool) or not isinstance(x, (int, float))
                                          for x in items):
        return None
    out = [0.0, 0.0, 0.0, 1.0]
    out[:len(items)] = [float(x) for x in items]
    return tuple(out)


def view_layer_attribute(scene, view_layer, name) -> tuple:
    """RGBA of an Attribute node of type View Layer (Blender's
    BKE_view_layer_find_rgba_attribute, which Cycles reads): the view layer's property
    `name` (custom or RNA path, _property_rgba), else the scene's, else its world's;
    (0, 0, 0, 0) when none has it."""
    for owner in (view_layer, scene, getattr(scene, "world", None)):
        value = _property_rgba(owner, name)
        if value is not None:
            return value
    return (0.0, 0.0, 0.0, 0.0)


def object_attributes(obj, inst, requests) -> dict | None:
    """Mesh.object_attributes of an object (an instance) for the Attribute nodes of type
    Object / Instancer its scene's materials hold (requests: (name, instancer) pairs), as
    Cycles' lookup_instance_property (blender/object.cpp) and Blender's
    BKE_object_dupli_find_rgba_attribute find them: for Instancer, the instancing
    object's property first; then the object's, then its data's (the mesh); (0, 0, 0,
    0) when none has it. (A particle system's settings and geometry-nodes instance
    attributes, which Instancer reads first, are not read.)"""
    if not requests:
        return None
    out = {}
    for name, instancer in requests:
        ids = [obj, getattr(obj, "data", None)]
        if instancer and inst.is_instance:
            ids.insert(0, inst.parent)
        value = next((v for v in (_property_rgba(i, name) for i in ids) if v is not None),
                     (0.0, 0.0, 0.0, 0.0))
        out[object_attribute_key(name, instancer)] = value
    return out


def _placement(pm, name, prototype, matrix, names, obj, visibility, info=None):
    """An engine placement (Mesh.place): the prototype by `matrix`, the object's
    material slots (the last repeated if it has fewer than the prototype uses)."""
    slots = int(prototype.material_ids.max()) + 1 if len(prototype.material_ids) else 1
    names = list(names) + [names[-1]] * max(0, slots - len(names))
    return pm.Mesh.place(name, prototype, matrix, materials=names,
                         pass_index=pass_index(obj), **(info or {}),
                         shadow_terminator_offset=terminator_offset(obj),
                         shadow_terminator_shading_offset=terminator_shading(obj),
                         **cryptomatte_names(obj), **visibility)


def render_enabled_objects(view_layer) -> set:
    """The as_pointer() of every original object a final render of view_layer may show by
    its collections: those in a collection that is neither excluded from the view layer
    nor disabled in renders (Collection.hide_render), itself and its parents. (An
    object's own hide_render is checked apart: render_hidden.)"""
    enabled = set()

    def walk(layer_collection, on):
        on = on and not layer_collection.exclude and not layer_collection.collection.hide_render
        if on:
            enabled.update(o.as_pointer() for o in layer_collection.collection.objects)
        for child in layer_collection.children:
            walk(child, on)
    walk(view_layer.layer_collection, True)
    return enabled


def render_hidden(inst, enabled: set) -> bool:
    """Whether a final render leaves out this depsgraph instance that a viewport
    depsgraph holds: its object (or, for an instance, the object instancing it) is
    disabled in renders (hide_render) or only in collections that are (enabled:
    render_enabled_objects); an instanced object disabled in renders is left out too."""
    obj = inst.object.original
    if obj.hide_render:
        return True
    if inst.is_instance:
        parent = inst.parent.original
        return parent.hide_render or parent.as_pointer() not in enabled
    return obj.as_pointer() not in enabled


def export_scene(pm, depsgraph, camera=None, width=None, height=None, progress=None,
                 should_cancel=None, render_visibility: bool = False):
    """Build an engine Scene from an evaluated depsgraph.

    progress(done, total) is called per object; should_cancel() is polled and raises
    ExportCancelled when it returns True. render_visibility: leave out what a final render
    leaves out (objects and collections disabled in renders: render_hidden) though the
    depsgraph holds it: for a viewport depsgraph (bpy.context.evaluated_depsgraph_get())
    that stands for an F12 render (the teaching images, scripts; a render's own depsgraph
    has already left them out, the rendered viewport shows them as Cycles' does).
    Modifiers keep the depsgraph's levels (a viewport depsgraph's Subdivision Surface
    evaluates its Levels Viewport). Returns (scene, info dict)."""
    scene_eval = depsgraph.scene_eval if hasattr(depsgraph, "scene_eval") else depsgraph.scene
    scene_orig = depsgraph.scene
    render = scene_orig.render
    if width is None or height is None:
        width, height = render_size(render)
    warnings: list[str] = []
    converter = MaterialConverter(pm)
    converter.view_layer = (scene_eval, getattr(depsgraph, "view_layer", None))
    materials: dict = {}
    meshes = []
    lights = []
    cache: dict = {}
    info = dict(objects=0, instances=0, triangles=0, lights=0, export_time=0.0)
    t0 = time.perf_counter()

    # Instance handles are only valid while iterating: count first, then convert. The
    # mesh geometry placed more than once gets one engine Prototype: the engine may then
    # trace it two-level instead of one BVH copy per placement (engine/instancing.py).
    uses: dict = {}
    total = 0
    for inst in depsgraph.object_instances:
        total += 1
        if inst.object.type in GEOMETRY_TYPES:
            key = _geometry_key(inst.object)
            uses[key] = uses.get(key, 0) + 1
    prototypes: dict = {}
    last_poll = time.perf_counter()
    view_layer = getattr(depsgraph, "view_layer", None)
    enabled = (render_enabled_objects(view_layer) if render_visibility and view_layer
               is not None else None)
    # A final render's particle hair (its children and Render Steps), or the viewport's.
    hair_background = render_visibility or getattr(depsgraph, "mode", "RENDER") == "RENDER"
    for i, inst in enumerate(depsgraph.object_instances):
        now = time.perf_counter()
        if should_cancel is not None and now - last_poll > 0.2:
            last_poll = now
            if should_cancel():
                raise ExportCancelled()
        if progress is not None and (i % 16 == 0 or i == total - 1):
            progress(i + 1, total)
        obj = inst.object
        otype = obj.type
        if enabled is not None and render_hidden(inst, enabled):
            continue
        if otype == "MESH" and getattr(inst, "show_particles", True) and \
                len(getattr(obj, "particle_systems", ()) or ()):
            # Particle hair: strands of the emitter's own, shown also when the emitter
            # itself is not (Object > Visibility > Show Instancer: Renders off).
            hkey = ("particle hair",) + _geometry_key(obj)
            if hkey not in cache:
                cache[hkey] = extract_particle_hair(pm, obj, hair_background,
                                                    should_cancel)
            if cache[hkey] is not None:
                mesh = particle_hair_mesh(pm, inst, obj, cache[hkey], converter, materials,
                                          info, view_layer)
                meshes.append(mesh)
                info["triangles"] += len(mesh.faces)
        if not inst.is_instance and not getattr(inst, "show_self", True):
            continue
        if otype == "LIGHT":
            matrix = np.array(inst.matrix_world, dtype=np.float64)
            name = obj.name if not inst.is_instance else \
                f"{inst.parent.name}/{obj.name}.{len(lights)}"
            light = convert_light(pm, obj, matrix, name, warnings)
            if light is not None:
                lights.append(light)
            continue
        if otype == "VOLUME":
            mesh = volume_mesh(pm, inst, obj, converter, materials, warnings, info,
                               view_layer, scene_eval, cache)
            if mesh is not None:
                meshes.append(mesh)
                info["triangles"] += len(mesh.faces)
            continue
        if otype not in GEOMETRY_TYPES:
            # Curve, surface, text and metaball objects: the depsgraph also yields their
            # evaluated geometry as MESH instances (parent = the object). Like Cycles
            # (blender/object.cpp, object_is_geometry: only Mesh data is geometry), the
            # object itself is skipped, or its geometry would be exported twice.
            continue
        key = _geometry_key(obj)
        if key not in cache:
            cache[key] = extract_object_geometry(pm, obj)
            if cache[key] is None and otype == "CURVES":
                warn_empty_hair(obj, warnings)
            elif cache[key] is None and otype == "POINTCLOUD" and len(obj.data.points):
                owner = inst.parent.name if inst.is_instance and inst.parent else obj.name
                warnings.append(f"object '{owner}': its points have radius 0 (or are not "
                                "finite): nothing to render, as in Cycles")
        geo = cache[key]
        if geo is None:
            continue
        names = slot_materials(obj, converter, materials)
        mids = np.clip(geo.material_index, 0, len(names) - 1)
        if uses.get(key, 0) > 1 and key not in prototypes:
            prototypes[key] = _prototype(pm, obj.name, geo, mids)
        matrix = np.array(inst.matrix_world, dtype=np.float64)
        if key in prototypes and _placeable(geo, converter, names):
            # Placed more than once: a record (prototype, matrix), no world-space copy.
            name = _instance_name(inst, obj, info)
            info["objects"] += 1
            warn_unsupported_object_options(obj, warnings)
            mesh = _placement(pm, name, prototypes[key], matrix, names, obj,
                              ray_visibility(obj, inst, view_layer),
                              object_info(obj, inst, converter.object_attribute_names))
            meshes.append(mesh)
            info["triangles"] += len(mesh.faces)
            continue
        verts, faces, normals, uvs = transform_geometry(geo, matrix)
        colors = geo.colors
        flipped = np.linalg.det(matrix[:3, :3]) < 0
        if colors is not None and flipped:
            colors = colors[:, [0, 2, 1]]  # same corner order as the flipped faces
        name = _instance_name(inst, obj, info)
        info["objects"] += 1
        warn_unsupported_object_options(obj, warnings)
        uv_tangent_warnings(obj, geo, converter, names, warnings)
        mesh = pm.Mesh(name=name, vertices=verts, faces=faces, normals=normals,
                       uvs=uvs, colors=colors, materials=names, material_ids=mids,
                       coordinates=corner_attributes(geo, matrix, any(
                           converter.needs_coordinates(n) for n in names),
                           any(_radial(converter, n) for n in names),
                           _uv_slots(converter, names)),
                       shadow_terminator_offset=terminator_offset(obj),
                       shadow_terminator_shading_offset=terminator_shading(obj),
                       pass_index=pass_index(obj),
                       **object_info(obj, inst, converter.object_attribute_names),
                       prototype=prototypes.get(key), matrix=matrix if key in prototypes else None,
                       **cryptomatte_names(obj), **ray_visibility(obj, inst, view_layer))
        quiet_generated_degenerates(inst, obj, mesh)
        meshes.append(mesh)
        info["triangles"] += len(mesh.faces)  # after dropping degenerate faces

    cam_obj = camera if camera is not None else scene_eval.camera
    if cam_obj is not None:
        cam_obj = cam_obj.evaluated_get(depsgraph)
    camera_out = convert_camera(pm, cam_obj, width, height, render, warnings,
                                scene_eval.objects)
    view = (pm.shadernodes.CameraView(camera_out, width, height)
            if camera_out is not None else None)  # (a world's Window coordinates)
    (background, environment), seen = export_worlds(pm, scene_eval.world, warnings, view)
    if (seen is not None and isinstance(seen[1], pm.worldgraph.WorldGraph)
            and camera_out.kind == "ORTHO"):
        # (Cycles projects an orthographic camera ray's origin; ours knows its direction)
        warnings.append(f"world '{scene_eval.world.name}': a Window-mapped background "
                        "behind an orthographic camera is not screen-mapped here: camera "
                        "rays see the image at the projection of their direction, as "
                        "Cycles' other rays do")
    lights, portals = split_portals(pm, lights)
    resolve_light_links(lights, meshes, info.pop("owners", {}))
    lights = lights + world_lights(pm, environment, seen, scene_eval.world)
    fog = world_medium(pm, scene_eval.world, warnings)
    volume_bounces_warning(scene_eval, materials, warnings, fog)
    scene = pm.Scene(meshes=meshes, materials=materials, lights=lights, camera=camera_out,
                     width=width, height=height, background=background,
                     background_is_light=True, environment=environment,
                     **camera_world(seen),
                     mist=world_mist(pm, scene_eval.world), portals=portals,
                     world_medium=fog)
    set_world_lightgroup(scene, scene_eval.world)
    scene.warnings.extend(warnings)
    info["lights"] = len(lights)
    info["export_time"] = time.perf_counter() - t0
    return scene, info


# --- viewport: partial re-export (addon/viewport.py) -----------------------------------

class ViewportUpdates:
    """What depsgraph.updates of one viewport update touched, as plain names.

    geometry: objects whose evaluated geometry changed (mesh data re-read); data:
    names of geometry data-blocks (Mesh, Curve, ...) that changed; materials: material
    names to convert again (all_materials: a node tree or image changed, so every one);
    lights / world: a light or the world changed."""

    def __init__(self):
        self.geometry: set = set()
        self.data: set = set()
        self.materials: set = set()
        self.all_materials = False
        self.lights = False
        self.world = False

    @classmethod
    def from_depsgraph(cls, depsgraph) -> "ViewportUpdates":
        out = cls()
        for update in depsgraph.updates:
            out.add(update.id, update.is_updated_geometry, update.is_updated_transform,
                    update.is_updated_shading)
        return out

    def add(self, idblock, geometry: bool, transform: bool, shading: bool) -> None:
        kind = type(idblock).__name__
        name = getattr(idblock, "name", "")
        if kind == "Object":
            if idblock.type == "LIGHT":
                self.lights = True
            elif geometry:
                self.geometry.add(name)
        elif kind == "Material":
            self.materials.add(name)
        elif kind.endswith("NodeTree"):
            # A material's or world's own tree comes with its owner's update; a node
            # group may be used by any material or the world.
            if not getattr(idblock, "is_embedded_data", False):
                self.all_materials = self.world = True
        elif kind in ("Image", "Texture"):
            self.all_materials = self.world = True
        elif kind == "Collection":
            # A Light / Shadow Linking collection's objects or link states changed: the
            # lamps' receivers and blockers are resolved again (resolve_light_links).
            self.lights = True
        elif kind.endswith("Light"):  # PointLight, SpotLight, SunLight, AreaLight
            self.lights = True
        elif kind == "World":
            self.world = True
        elif geometry and kind in ("Mesh", "Curve", "Curves", "MetaBall", "TextCurve",
                                   "SurfaceCurve", "PointCloud", "Volume", "GreasePencil"):
            self.data.add(name)
        elif kind == "Scene" and shading:
            self.world = True  # e.g. another world assigned to the scene


class ViewportExport:
    """Engine scene content kept between viewport updates so that an update re-reads only
    what changed: local geometry per object (re-read when the depsgraph says its
    geometry changed; a moved object is only transformed again), engine meshes per
    instance (reused while their geometry, matrix, materials and visibility are the
    same), converted materials (converted again when changed)."""

    def __init__(self, pm):
        self.pm = pm
        self.converter = MaterialConverter(pm)
        self.geometry: dict = {}   # (object name, data pointer) -> LocalGeometry | None
        self.meshes: dict = {}     # instance name -> (key, engine Mesh)
        self.prototypes: dict = {}  # geometry key -> (LocalGeometry, engine Prototype)
        self.light_names: list = []
        self.worlds = None  # (export_worlds' answer, its warnings) of the last update


def export_viewport(cache: ViewportExport, depsgraph, camera, width: int, height: int,
                    updates: ViewportUpdates | None = None):
    """Engine Scene for the viewport from an evaluated depsgraph, reusing `cache`.

    camera: the engine Camera of the view (addon/viewport.py); updates: None for the
    first export (everything read), else what changed since the last call. Returns
    (scene, info); info says what was done: geometry_read (objects whose mesh data was
    read), transformed (instances rebuilt from kept geometry), reused (instances kept
    as they were), deleted (instances gone since the last call), materials (converted
    again), and the flags geometry_changed (the mesh list differs: the renderer must
    merge triangles again), materials_changed, lights_changed, world_changed."""
    pm = cache.pm
    scene_eval = depsgraph.scene_eval if hasattr(depsgraph, "scene_eval") else depsgraph.scene
    render = depsgraph.scene.render
    view_layer = getattr(depsgraph, "view_layer", None)
    first = updates is None
    updates = updates or ViewportUpdates()
    converter = cache.converter
    converter.view_layer = (scene_eval, view_layer)
    if updates.all_materials:
        converter.cache.clear()
        converter.images.clear()
        converter.coordinate_users.clear()
    for name in updates.materials:
        converter.cache.pop(name, None)
        for key in [k for k in converter.cache  # (convert_volume_object's, scaled too)
                    if k.startswith(f"{name} (volume object)")]:
            converter.cache.pop(key)
        converter.coordinate_users.discard(name)
    info = dict(geometry_read=[], transformed=[], reused=[], deleted=[],
                materials=sorted(updates.materials), triangles=0, lights=0, instances=0)
    warnings: list[str] = []
    materials: dict = {}
    meshes, lights, seen = [], [], set()
    converted_before = set(converter.cache)
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type == "MESH" and getattr(inst, "show_particles", True) and \
                len(getattr(obj, "particle_systems", ()) or ()):
            hkey = ("particle hair",) + _geometry_key(obj)  # (export_scene's)
            if obj.name in updates.geometry or hkey not in cache.geometry:
                if hkey not in seen:
                    cache.geometry[hkey] = extract_particle_hair(
                        pm, obj, getattr(depsgraph, "mode", "VIEWPORT") == "RENDER")
            seen.add(hkey)
            if cache.geometry[hkey] is not None:
                mesh = particle_hair_mesh(pm, inst, obj, cache.geometry[hkey], converter,
                                          materials, info, view_layer)
                meshes.append(mesh)
                info["triangles"] += len(mesh.faces)
        if not inst.is_instance and not getattr(inst, "show_self", True):
            continue
        if obj.type == "LIGHT":
            name = obj.name if not inst.is_instance else \
                f"{inst.parent.name}/{obj.name}.{len(lights)}"
            light = convert_light(pm, obj, np.array(inst.matrix_world, dtype=np.float64),
                                  name, warnings)
            if light is not None:
                lights.append(light)
            continue
        if obj.type == "VOLUME":
            # Sampled again only when the volume, its material or its placement changed
            # (reading the grids evaluates the volume once more: addon/volumegrids.py)
            data = getattr(obj, "data", None)
            slot = obj.material_slots[0].material if len(obj.material_slots) else None
            vkey = ("volume", obj.name, data.as_pointer() if data is not None else 0,
                    np.array(inst.matrix_world, np.float64).tobytes(),
                    inst.parent.name if inst.is_instance and inst.parent else None,
                    slot.name if slot is not None else None)
            stale = (obj.name in updates.geometry or vkey not in cache.geometry
                     or (data is not None and data.name in updates.data)
                     or (slot is not None and slot.name in updates.materials)
                     or updates.all_materials)
            if stale:
                n0 = len(warnings)
                cache.geometry[vkey] = (volume_mesh(pm, inst, obj, converter, materials,
                                                    warnings, info, view_layer, scene_eval),
                                        warnings[n0:])
                info["geometry_read"].append(obj.name)
            mesh, said = cache.geometry[vkey]
            seen.add(vkey)
            if not stale:
                warnings.extend(w for w in said if w not in warnings)
                if mesh is not None:
                    materials[mesh.materials[0]] = (converter.cache.get(mesh.materials[0])
                                                    or converter.convert_volume_object(slot))
            if mesh is not None:
                meshes.append(mesh)
                info["triangles"] += len(mesh.faces)
            continue
        if obj.type not in GEOMETRY_TYPES:
            # (the depsgraph yields other geometry as MESH instances: export_scene)
            continue
        data = getattr(obj, "data", None)
        gkey = (obj.name, data.as_pointer() if data is not None else 0)
        if (obj.name in updates.geometry or (data is not None and data.name in updates.data)
                or gkey not in cache.geometry):
            if gkey not in seen:
                cache.geometry[gkey] = extract_object_geometry(pm, obj)
                info["geometry_read"].append(obj.name)
        seen.add(gkey)
        geo = cache.geometry[gkey]
        if geo is None:
            continue
        names = slot_materials(obj, converter, materials)
        iname = _instance_name(inst, obj, info)
        matrix = np.array(inst.matrix_world, dtype=np.float64)
        visibility = ray_visibility(obj, inst, view_layer)
        coords = (any(converter.needs_coordinates(n) for n in names),
                  any(_radial(converter, n) for n in names), _uv_slots(converter, names))
        oinfo = object_info(obj, inst, converter.object_attribute_names)
        key = (id(geo), matrix.tobytes(), tuple(names), coords,
               tuple(sorted(visibility.items())), terminator_offset(obj),
               terminator_shading(obj), pass_index(obj), tuple(sorted(oinfo.items())))
        old = cache.meshes.get(iname)
        if old is not None and old[0] == key:
            mesh = old[1]
            info["reused"].append(iname)
        elif inst.is_instance and _placeable(geo, converter, names):
            # An instance: a record on its geometry's prototype (kept while the local
            # geometry is), no world-space copy; the engine shares or expands it.
            proto = cache.prototypes.get(gkey)
            if proto is None or proto[0] is not geo:
                mids = np.clip(geo.material_index, 0, len(names) - 1)
                proto = cache.prototypes[gkey] = (geo, _prototype(pm, obj.name, geo, mids))
            mesh = _placement(pm, iname, proto[1], matrix, names, obj, visibility, oinfo)
            if obj.name not in info["geometry_read"]:
                info["transformed"].append(iname)
            cache.meshes[iname] = (key, mesh)
        else:
            verts, faces, normals, uvs = transform_geometry(geo, matrix)
            flipped = np.linalg.det(matrix[:3, :3]) < 0
            colors = geo.colors[:, [0, 2, 1]] if (geo.colors is not None and flipped) \
                else geo.colors
            mesh = pm.Mesh(name=iname, vertices=verts, faces=faces, normals=normals, uvs=uvs,
                           colors=colors, materials=names,
                           material_ids=np.clip(geo.material_index, 0, len(names) - 1),
                           coordinates=corner_attributes(geo, matrix, *coords),
                           shadow_terminator_offset=key[5],
                           shadow_terminator_shading_offset=key[6], pass_index=key[7],
                           **oinfo, **cryptomatte_names(obj), **visibility)
            if obj.name not in info["geometry_read"]:
                info["transformed"].append(iname)
            cache.meshes[iname] = (key, mesh)
        warn_unsupported_object_options(obj, warnings)
        uv_tangent_warnings(obj, geo, converter, names, warnings)
        quiet_generated_degenerates(inst, obj, mesh)
        meshes.append(mesh)
        info["triangles"] += len(mesh.faces)
    current = {m.name for m in meshes}
    info["deleted"] = sorted(n for n in cache.meshes if n not in current)
    for name in info["deleted"]:
        del cache.meshes[name]
    for gkey in [k for k in cache.geometry if k not in seen]:
        del cache.geometry[gkey]
        cache.prototypes.pop(gkey, None)
    if first or updates.world or cache.worlds is None:
        # (a world baked along directions or from maps and colours takes seconds: an
        # update that leaves the world as it was reuses the last one)
        world_warnings: list = []
        cache.worlds = (export_worlds(pm, scene_eval.world, world_warnings), world_warnings)
    (background, environment), seen = cache.worlds[0]
    warnings.extend(cache.worlds[1])
    lights, portals = split_portals(pm, lights)
    resolve_light_links(lights, meshes, info.pop("owners", {}))
    lights = lights + world_lights(pm, environment, seen, scene_eval.world)
    scene = pm.Scene(meshes=meshes, materials=materials, lights=lights, camera=camera,
                     width=int(width), height=int(height), background=background,
                     background_is_light=True, environment=environment,
                     **camera_world(seen),
                     mist=world_mist(pm, scene_eval.world), portals=portals,
                     world_medium=world_medium(pm, scene_eval.world, warnings))
    set_world_lightgroup(scene, scene_eval.world)
    scene.warnings.extend(warnings)
    light_names = [li.name for li in lights]
    info.update(
        lights=len(lights),
        geometry_changed=first or bool(info["geometry_read"] or info["transformed"]
                                       or info["deleted"]),
        materials_changed=first or bool(set(converter.cache) - converted_before),
        lights_changed=first or updates.lights or light_names != cache.light_names,
        world_changed=first or updates.world)
    cache.light_names = light_names
    if render.use_motion_blur:  # F12 renders it (engine/motionblur.py): time steps
        scene.warnings.append("motion blur is not shown in the viewport (a still at the "
                              "frame's time); the final render (F12) renders it")
    return scene, info
