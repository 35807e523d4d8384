"""Volume objects (OpenVDB grids, Mesh to Volume, Volume Displace, Geometry Nodes volumes)
as heterogeneous media: their grids read through Geometry Nodes, their boundary the box
around their active voxels.

Blender's Python has no OpenVDB module, but Geometry Nodes 5.0 reads grids: a temporary
mesh object whose vertices sit at the grid's voxel centres carries a node group

    Object Info (the volume object, Original space) -> Get Named Grid (name)
      -> Sample Grid (Position) -> Store Named Attribute ("<name>" on the points)

one chain per grid (and one more per grid for its active voxels: Field to Grid of 1 on
its topology), evaluated in a temporary scene's depsgraph (the render's depsgraph
cannot take new objects) at the render's frame; the values are read from the evaluated
mesh with foreach_get, and every temporary datablock (scene, object, mesh, node group)
is removed in a `finally`, on error too. The lattice: the grid's own voxel centres (the
integer points of its index space, grid.matrix_object) over the object's bounds (Blender
bounds a volume by its grids' active voxels, half a voxel beyond their centres), one
background voxel of padding on every side so the interpolated field falls to 0 at the
lattice's faces. At voxel centres Sample Grid returns the voxel's own value, whatever its
interpolation, so the engine's trilinear interpolation of the lattice
(engine/voxelgrid.py) is Cycles' linear interpolation of the grid. The medium's boundary:
the box of its active voxels above the Volume's Clipping, padded as Cycles pads them
(active_box: measured against Cycles 5.0).

Memory: at most MAX_VOXELS lattice points per object (256^3 float32 = 64 MiB per scalar
grid, 3x for a colour grid; the temporary mesh's positions take 12 bytes a point while
sampling). A larger grid is sampled at every s-th voxel (s the smallest stride that fits,
a point sample of the voxels there: small features may alias) and warned.

Which grids: the ones the volume object's material reads (MaterialConverter records the
GridAttribute nodes it makes for a volume object's material: Principled Volume's
Density and Color Attribute, its Temperature Attribute when Blackbody Intensity > 0,
Attribute and Volume Info nodes), of those the object has; none of them: nothing renders,
as in Cycles (its volume mesh is built from the grids its shader asks for). The
temporary datablocks are made on Blender's main thread (on_main_thread). Blender 4.2 -
4.5 lack the grid nodes: there a volume object is warned and left out.
"""
from __future__ import annotations

import numpy as np

MAX_VOXELS = 256 ** 3  # lattice points per volume object (see the module docstring)
_TMP = "photonmap-volume-grids"  # the temporary datablocks' name


def has_grid_nodes(bpy) -> bool:
    """Whether this Blender's Geometry Nodes read grids (5.0 and later)."""
    return all(hasattr(bpy.types, n) for n in ("GeometryNodeGetNamedGrid",
                                               "GeometryNodeSampleGrid"))


def grid_kind(data_type: str) -> str:
    """The grid nodes' data type that reads a VolumeGrid of data_type: VECTOR for vector
    grids, FLOAT for the rest (a boolean / integer grid read as a value)."""
    return "VECTOR" if str(data_type).startswith("VECTOR") else "FLOAT"


def object_grids(obj) -> dict:
    """{name: data_type} of the grids of an evaluated Volume object."""
    grids = getattr(getattr(obj, "data", None), "grids", None)
    if grids is None:
        return {}
    try:
        grids.load()
    except Exception:  # noqa: BLE001 - an unreadable file has no grids (warned by caller)
        pass
    return {g.name: g.data_type for g in grids}


def _grid_matrix(obj, name) -> np.ndarray | None:
    for g in obj.data.grids:
        if g.name == name:
            return np.array(g.matrix_object, np.float64)
    return None


def lattice(bounds_lo, bounds_hi, index_to_object, max_voxels: int = MAX_VOXELS):
    """The lattice of voxel centres over an object-space box [bounds_lo, bounds_hi] (3,)
    of a grid whose index -> object map is index_to_object (4,4): (first (3,) int,
    counts (3,) int, stride int). Voxel centres are the integer index points; the box
    reaches half a voxel beyond the active ones (Blender's bounds); one voxel of padding
    on each side; the stride grows until the count fits max_voxels."""
    lo, hi = np.asarray(bounds_lo, np.float64), np.asarray(bounds_hi, np.float64)
    c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                  for z in (lo[2], hi[2])])
    inv = np.linalg.inv(index_to_object)
    idx = c @ inv[:3, :3].T + inv[:3, 3]
    first = np.floor(idx.min(axis=0) + 0.5 + 1e-6).astype(np.int64) - 1
    last = np.ceil(idx.max(axis=0) - 0.5 - 1e-6).astype(np.int64) + 1
    span = np.maximum(last - first, 1)
    stride = 1
    while np.prod(span // stride + 1) > max_voxels:
        stride += 1
    counts = span // stride + 1
    # (the stride's lattice covers last: one more point where it falls short)
    counts = np.where(first + (counts - 1) * stride < last, counts + 1, counts)
    return first, counts, stride


START_WAIT = 30.0  # s a render thread waits for the main thread to take the sampling


class MainThreadBusy(RuntimeError):
    """The main thread did not take a job handed to it within START_WAIT seconds."""


def on_main_thread(bpy, fn):
    """fn() on Blender's main thread: a final render runs the engine on a render thread,
    and datablocks made or removed there race the interface (Cycles never writes to
    bpy.data while it renders). From another thread fn goes to a bpy.app.timers call
    and this waits for it; when the main thread does not take it within START_WAIT
    seconds (its event loop busy), MainThreadBusy is raised (the caller warns and leaves
    the volume out: datablocks written from a render thread may crash Blender, a missing
    volume does not). On the main thread (background renders, scripts, the viewport's
    update): fn() directly."""
    import threading
    if threading.current_thread() is threading.main_thread():
        return fn()
    lock = threading.Lock()
    started, done = threading.Event(), threading.Event()
    state: dict = {"who": None}

    def run():
        with lock:
            if state["who"] is not None:
                return None
            state["who"] = "main"
        started.set()
        try:
            state["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - handed to the waiting thread
            state["error"] = exc
        finally:
            done.set()
        return None

    bpy.app.timers.register(run, first_interval=0.0)
    if not started.wait(START_WAIT):
        with lock:
            if state["who"] is None:
                state["who"] = "nobody"
        if state["who"] == "nobody":
            raise MainThreadBusy(f"Blender's main thread did not take the grid sampling "
                                 f"within {START_WAIT:g} s")
    done.wait()
    if "error" in state:
        raise state["error"]
    return state["value"]


# A Blackbody temperature above this (K) is a unit slip, not fire: a "temperature" grid
# already in kelvin times the Principled Volume's default Temperature 1000 reads millions
# of kelvin (newuser41b: 1.8 M K, a white-blue glare in both engines; Cycles took minutes).
HOT_KELVIN = 50_000.0


def hot_blackbody_warnings(material, values: dict, owner: str) -> list:
    """A warning per Principled Volume of material whose Blackbody reads a temperature
    grid in `values` ({grid name: lattice}) to above HOT_KELVIN (its Temperature times
    the grid's largest value), naming both and the likely fix; [] otherwise."""
    out = []
    tree = getattr(material, "node_tree", None)
    for node in getattr(tree, "nodes", ()) if tree is not None else ():
        if node.type != "PRINCIPLED_VOLUME":
            continue
        b, t = node.inputs.get("Blackbody Intensity"), node.inputs.get("Temperature")
        if b is None or t is None or b.is_linked or t.is_linked:
            continue
        attr = node.inputs.get("Temperature Attribute")
        name = str(getattr(attr, "default_value", "") or "") if attr is not None else ""
        grid = values.get(name)
        if not b.default_value > 0 or grid is None or not grid.size:
            continue
        peak = float(np.max(grid))
        kelvin = float(t.default_value) * max(peak, 0.0)
        if kelvin > HOT_KELVIN:
            out.append(f"object '{owner}': material '{material.name}': the Blackbody "
                       f"temperature reaches {kelvin:,.0f} K (Temperature "
                       f"{t.default_value:g} x the '{name}' grid's largest value {peak:.4g}); "
                       "a grid already in kelvin wants Temperature 1 (both engines render "
                       "what is set: a white-blue glare)")
    return out


def sample_grids(bpy, obj, names: dict, frame, max_voxels: int | None = None):
    """Sample grids `names` ({name: data_type}) of the evaluated Volume object obj at
    its lattice (`lattice`): ({name: values (nx,ny,nz) or (nx,ny,nz,3) float32},
    active (nx,ny,nz) bool: a voxel active in one of the grids (OpenVDB's topology,
    tiles included: whatever its value), lattice_to_object (4,4), stride, counts (3,),
    first (3,): the grid index of lattice index 0). frame: (frame, subframe) the temporary scene
    evaluates at. Every temporary datablock is removed before returning or raising."""
    max_voxels = MAX_VOXELS if max_voxels is None else max_voxels
    ref = "density" if "density" in names else sorted(names)[0]
    M = _grid_matrix(obj, ref)
    if M is None or abs(np.linalg.det(M[:3, :3])) < 1e-30:
        raise ValueError(f"grid '{ref}' has no usable transform")
    bb = np.array([tuple(v) for v in obj.bound_box], np.float64)
    first, counts, stride = lattice(bb.min(axis=0), bb.max(axis=0), M, max_voxels)
    # the voxel centres in object space, built in float32 in place (16.7 M points: 200
    # MB, where index and float64 copies would take 1 GB)
    pts = np.empty((int(counts[0]), int(counts[1]), int(counts[2]), 3), np.float32)
    pts[:] = M[:3, 3]
    for a, shape in enumerate(((-1, 1, 1, 1), (1, -1, 1, 1), (1, 1, -1, 1))):
        axis = (first[a] + stride * np.arange(counts[a])).astype(np.float64)
        pts += (axis.reshape(shape) * M[:3, a]).astype(np.float32)
    pts = pts.reshape(-1, 3)
    lat_to_obj = M @ np.array([[stride, 0, 0, first[0]], [0, stride, 0, first[1]],
                               [0, 0, stride, first[2]], [0, 0, 0, 1]], np.float64)
    data = bpy.data
    scene = mesh = ob = tree = None
    try:
        scene = data.scenes.new(_TMP)
        scene.frame_set(int(frame[0]), subframe=float(frame[1]))
        mesh = data.meshes.new(_TMP)
        mesh.vertices.add(len(pts))
        mesh.vertices.foreach_set("co", pts.ravel())
        ob = data.objects.new(_TMP, mesh)
        scene.collection.objects.link(ob)
        tree = data.node_groups.new(_TMP, "GeometryNodeTree")
        tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
        nodes, links = tree.nodes, tree.links
        gin, gout = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
        info = nodes.new("GeometryNodeObjectInfo")
        info.inputs["Object"].default_value = getattr(obj, "original", None) or obj
        info.transform_space = "ORIGINAL"  # the grid in the volume object's own space
        pos = nodes.new("GeometryNodeInputPosition")
        geom = gin.outputs[0]
        keys = {}
        for i, (name, dtype) in enumerate(sorted(names.items())):
            kind = grid_kind(dtype)
            get = nodes.new("GeometryNodeGetNamedGrid")
            get.data_type = kind
            get.inputs["Name"].default_value = name
            smp = nodes.new("GeometryNodeSampleGrid")
            smp.data_type = kind
            store = nodes.new("GeometryNodeStoreNamedAttribute")
            store.data_type = "FLOAT_VECTOR" if kind == "VECTOR" else "FLOAT"
            store.domain = "POINT"
            keys[name] = f"pmvdb_{i}"
            store.inputs["Name"].default_value = keys[name]
            links.new(info.outputs["Geometry"], get.inputs["Volume"])
            links.new(get.outputs["Grid"], smp.inputs["Grid"])
            links.new(pos.outputs["Position"], smp.inputs["Position"])
            links.new(geom, store.inputs["Geometry"])
            links.new(smp.outputs[0], store.inputs["Value"])
            geom = store.outputs[0]
        # the active voxels (tiles included) of each grid: Field to Grid of 1 on its
        # topology, sampled as the values are
        for i, (name, dtype) in enumerate(sorted(names.items())):
            kind = grid_kind(dtype)
            get = nodes.new("GeometryNodeGetNamedGrid")
            get.data_type = kind
            get.inputs["Name"].default_value = name
            topo = nodes.new("GeometryNodeFieldToGrid")
            topo.data_type = kind
            topo.grid_items.new("FLOAT", "Active")
            topo.inputs[1].default_value = 1.0
            smp = nodes.new("GeometryNodeSampleGrid")
            smp.data_type = "FLOAT"
            store = nodes.new("GeometryNodeStoreNamedAttribute")
            store.data_type = "FLOAT"
            store.domain = "POINT"
            store.inputs["Name"].default_value = f"pmvdb_active_{i}"
            links.new(info.outputs["Geometry"], get.inputs["Volume"])
            links.new(get.outputs["Grid"], topo.inputs["Topology"])
            links.new(topo.outputs[0], smp.inputs["Grid"])
            links.new(pos.outputs["Position"], smp.inputs["Position"])
            links.new(geom, store.inputs["Geometry"])
            links.new(smp.outputs[0], store.inputs["Value"])
            geom = store.outputs[0]
        links.new(geom, gout.inputs[0])
        mod = ob.modifiers.new(_TMP, "NODES")
        mod.node_group = tree
        layer = scene.view_layers[0]
        layer.update()
        ev = ob.evaluated_get(layer.depsgraph)
        me = ev.to_mesh()
        try:
            out = {}
            n = len(me.vertices)
            if n != len(pts):
                raise ValueError(f"sampled {n} points of {len(pts)}")
            shape = tuple(int(c) for c in counts)
            for name, dtype in names.items():
                attr = me.attributes.get(keys[name])
                if attr is None:
                    raise ValueError(f"grid '{name}' was not sampled")
                if grid_kind(dtype) == "VECTOR":
                    buf = np.zeros(n * 3, np.float32)
                    attr.data.foreach_get("vector", buf)
                    out[name] = buf.reshape(shape + (3,))
                else:
                    buf = np.zeros(n, np.float32)
                    attr.data.foreach_get("value", buf)
                    out[name] = buf.reshape(shape)
            active = np.zeros(n, bool)
            buf = np.zeros(n, np.float32)
            for i in range(len(names)):
                attr = me.attributes.get(f"pmvdb_active_{i}")
                if attr is None:
                    raise ValueError("the grids' active voxels were not sampled")
                attr.data.foreach_get("value", buf)
                active |= buf > 0.5
        finally:
            ev.to_mesh_clear()
        return out, active.reshape(shape), lat_to_obj, stride, counts, first
    finally:
        if ob is not None:
            data.objects.remove(ob)
        if mesh is not None:
            data.meshes.remove(mesh)
        if tree is not None:
            data.node_groups.remove(tree)
        if scene is not None:
            data.scenes.remove(scene)


def active_voxels(values: dict, topology: np.ndarray, clipping: float) -> np.ndarray:
    """(nx,ny,nz) bool: the voxels Cycles' volume region is built around: active in the
    used grids' topology (`topology`: Field to Grid's mask, tiles included) and, for a
    scalar grid, above the Volume's Clipping (0.001 by default: "value under which
    voxels are considered empty space"); a vector grid's nonzero voxels."""
    keep = np.zeros(topology.shape, bool)
    for v in values.values():
        keep |= (np.abs(v) > clipping) if v.ndim == 3 else np.any(v != 0.0, axis=3)
    return topology & keep


def active_box(active: np.ndarray, stride: int) -> tuple:
    """(lo (3,), hi (3,)) lattice index coordinates of the volume's region: the active
    voxels' bounding box from one grid voxel below the first to two above the last.
    Measured against Cycles 5.0 (a Mesh to Volume sphere of 0.1 m voxels, emission
    only, seen orthographically along each axis): its volume fills exactly that box
    (x -0.8 .. 0.9, z 0.4 .. 2.1 for voxels above the Clipping at indices -7 .. 7 and
    5 .. 19: Cycles' mesh builder pads the active voxels by the linear interpolation's
    1 voxel and converts the last voxel's exclusive bound to an inclusive one, +1;
    scene/volume.cpp), a box, not the sphere's shape."""
    idx = np.argwhere(active)
    return (idx.min(axis=0) - 1.0 / stride, idx.max(axis=0) + 2.0 / stride)


def box_mesh(lo, hi, to_world: np.ndarray) -> tuple:
    """(vertices (8,3), faces (12,3) int32) the box [lo, hi] (lattice index
    coordinates) in world space (to_world: lattice index -> world), faces outward."""
    c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                  for z in (lo[2], hi[2])], np.float64)
    verts = c @ to_world[:3, :3].T + to_world[:3, 3]
    # corners i*4 + j*2 + k; each face counter-clockwise seen from outside
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
             (1, 5, 7, 3)]
    faces = np.array([t for a, b, c_, d in quads for t in ((a, b, c_), (a, c_, d))],
                     np.int32)
    if np.linalg.det(to_world[:3, :3]) < 0:
        faces = faces[:, [0, 2, 1]]
    return verts, faces


def volume_density_scale(volume, matrix) -> float:
    """Cycles' object volume density of a Volume object (object.cpp, from Blender's
    BKE_volume_density_scale): in Object space (Volume > Render > Space, the default)
    1 / |M (1, 1, 1) / sqrt(3)| for the object's matrix M (a volume scaled 2x is half
    as dense: its density is per unit of object space), 1 in World space."""
    space = str(getattr(getattr(volume, "render", None), "space", "OBJECT") or "OBJECT")
    if space != "OBJECT":
        return 1.0
    u = np.asarray(matrix, np.float64)[:3, :3] @ (np.ones(3) / np.sqrt(3.0))
    n = float(np.linalg.norm(u))
    return 1.0 / n if n > 0.0 else 1.0


def volume_object_mesh(pm, bpy, inst, obj, converter, materials: dict, warnings: list,
                       name: str, frame, extra: dict, max_voxels: int | None = None,
                       cache: dict | None = None):
    """The engine Mesh of a Volume object instance: the box around its active voxels in
    world space (active_box) carrying the object's material (converted for a volume
    object: its nodes read the grids; scaled by Cycles' object volume density) and the
    grids it reads (engine Mesh.volume_grids); None (warned, naming the object) when it
    has no grid, none its material reads, its grids are empty, or Blender cannot read
    them.
    extra: the Mesh's other keywords (ray visibility, Object Info, Cryptomatte). cache:
    the export's, so the copies of one instanced volume sample its grids once."""
    from importlib import import_module
    max_voxels = MAX_VOXELS if max_voxels is None else max_voxels
    VoxelGrid = import_module(pm.__name__ + ".voxelgrid").VoxelGrid
    owner = inst.parent.name if inst.is_instance and inst.parent is not None else obj.name
    if not has_grid_nodes(bpy):
        warnings.append(f"object '{owner}': volume objects need Blender 5.0's grid nodes "
                        "to be read; not rendered in this Blender version")
        return None
    grids = object_grids(obj)
    if not grids:
        warnings.append(f"object '{owner}': the volume has no grids (an empty or missing "
                        "OpenVDB file, or a modifier that made none); nothing to render, "
                        "as in Cycles")
        return None
    slot = obj.material_slots[0].material if len(obj.material_slots) else None
    if slot is None:
        # A Geometry Nodes volume carries no material unless a Set Material node gives it
        # one: the object's own slots are not used (as in Cycles; newuser41b expected
        # them to be).
        source = inst.parent if inst.is_instance and inst.parent is not None else None
        source = source if source is not None else getattr(obj, "original", None)
        unused = [sl.material.name for sl in getattr(source, "material_slots", ())
                  if getattr(sl, "material", None) is not None]
        if unused:
            warnings.append(f"object '{owner}': its Geometry Nodes volume has no material "
                            "(a Set Material node in the node tree gives it one), so it "
                            "renders with Cycles' default volume shader, as in Cycles; the "
                            f"object's material '{unused[0]}' is not used")
    if len(obj.material_slots) > 1:
        warnings.append(f"object '{owner}': a volume renders with its first material "
                        "slot, as in Cycles; the others are not used")
    scale = volume_density_scale(obj.data, np.array(inst.matrix_world, np.float64))
    mat = converter.convert_volume_object(slot, 1.0 if abs(scale - 1.0) < 1e-6 else scale)
    materials[mat.name] = mat
    wanted = converter.volume_grid_names.get(mat.name, set())
    names = {n: grids[n] for n in wanted if n in grids}
    if not names:
        # Cycles loads the grids its shader asks for and builds the volume's mesh from
        # them: none, no mesh (measured: a volume with only a "temperature" grid renders
        # nothing under the default volume shader, a density-1 box under a Blackbody one)
        warnings.append(f"object '{owner}': none of the grids its material reads "
                        f"({', '.join(sorted(wanted)) or 'none'}) is in the volume (it has "
                        f"{', '.join(sorted(grids))}); nothing to render, as in Cycles")
        return None
    key = ("volume grids", getattr(getattr(obj, "original", None), "name", obj.name),
           obj.data.as_pointer(), tuple(sorted(names)), max_voxels)
    try:
        if cache is not None and key in cache:
            values, active, lat_to_obj, stride, counts, first = cache[key]
        else:
            values, active, lat_to_obj, stride, counts, first = on_main_thread(
                bpy, lambda: sample_grids(bpy, obj, names, frame, max_voxels))
            if cache is not None:
                cache[key] = (values, active, lat_to_obj, stride, counts, first)
    except Exception as exc:  # noqa: BLE001 - a grid Blender cannot read: warned
        warnings.append(f"object '{owner}': its grids could not be read ({type(exc).__name__}:"
                        f" {exc}); not rendered")
        return None
    if stride > 1:
        warnings.append(f"object '{owner}': its grids exceed {max_voxels} voxels "
                        f"({round(max_voxels ** (1 / 3))}^3); sampled at every {stride}th "
                        "voxel (fine detail may alias)")
    clipping = float(getattr(getattr(obj.data, "render", None), "clipping", 0.001) or 0.0)
    warnings.extend(hot_blackbody_warnings(slot, values, owner))
    active = active_voxels(values, active, clipping)
    if not active.any():
        warnings.append(f"object '{owner}': its grids {sorted(values)} are empty (no "
                        f"active voxel above the Clipping {clipping:g}); nothing to render")
        return None
    to_world = np.array(inst.matrix_world, np.float64) @ lat_to_obj
    vgrids = {n: VoxelGrid(v, to_world, n) for n, v in values.items()}
    verts, faces = box_mesh(*active_box(active, stride), to_world)
    interp = "LINEAR"
    if slot is not None:
        interp = str(getattr(getattr(slot, "cycles", None), "volume_interpolation",
                             "LINEAR") or "LINEAR")
    if interp != "LINEAR":
        warnings.append(f"material '{slot.name}': Volume Interpolation {interp.title()} on "
                        f"volume object '{owner}' is rendered Linear")
    return pm.Mesh(name=name, vertices=verts, faces=faces, materials=[mat.name],
                   material_ids=np.zeros(len(faces), np.int32),
                   volume_grids=vgrids or None, **extra)
