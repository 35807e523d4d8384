"""The same .blend exports the same arrays in every process: a Geometry Nodes scene
(Distribute Points on Faces, Instance on Points of a Collection Info, Pick Instance by a
Random Value) saved once, then exported in two fresh processes, every array of the two
engine Scenes compared bit for bit (docs/design.md, Blender facts: the export adds no
order of its own)."""
import json
import subprocess

import pytest

from blender_helpers import PYTHON, ROOT

pytestmark = pytest.mark.blender

BUILD = r"""
import sys
sys.path.insert(0, ROOT)
import bpy
import bmesh
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
col = bpy.data.collections.new("Shapes")
from tools.canonical_mesh import canonical_faces, primitive_uv_sphere_add
for k, (u, v) in enumerate([(8, 6), (12, 8)]):
    me = bpy.data.meshes.new(f"Shape{k}")
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=u, v_segments=v, radius=0.05, calc_uvs=True)
    bmesh.ops.create_cube(bm, size=0.04)  # flat quads beside the smooth sphere
    bm.to_mesh(me)
    bm.free()
    for p in me.polygons[: len(me.polygons) - 6]:
        p.use_smooth = True
    if CANONICAL:
        canonical_faces(me)
    col.objects.link(bpy.data.objects.new(f"Shape{k}", me))
if CANONICAL:  # the operator's sphere (UV map, Shade Smooth) as a scene object
    primitive_uv_sphere_add(radius=0.2, location=(0.5, 0.5, 0.3), segments=16, ring_count=8)
    bpy.ops.object.shade_smooth()
bpy.ops.mesh.primitive_plane_add(size=2.0)
ground = bpy.context.active_object
ng = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
n, link = ng.nodes, ng.links.new
gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
dist = n.new("GeometryNodeDistributePointsOnFaces")
dist.inputs["Density"].default_value = 20.0
info = n.new("GeometryNodeCollectionInfo")
info.inputs["Collection"].default_value = col
info.inputs["Separate Children"].default_value = True
info.inputs["Reset Children"].default_value = True
pick = n.new("FunctionNodeRandomValue")
pick.data_type = "INT"
pick.inputs[4].default_value, pick.inputs[5].default_value = 0, 1
inst = n.new("GeometryNodeInstanceOnPoints")
inst.inputs["Pick Instance"].default_value = True
link(gin.outputs[0], dist.inputs["Mesh"])
link(dist.outputs["Points"], inst.inputs["Points"])
link(info.outputs[0], inst.inputs["Instance"])
link(pick.outputs[2], inst.inputs["Instance Index"])
join = n.new("GeometryNodeJoinGeometry")
link(inst.outputs[0], join.inputs[0])
link(gin.outputs[0], join.inputs[0])
link(join.outputs[0], gout.inputs[0])
ground.modifiers.new("Scatter", "NODES").node_group = ng
bpy.ops.object.camera_add(location=(0, 0, 3))
scene.camera = bpy.context.active_object
bpy.ops.wm.save_as_mainfile(filepath=BLEND)
"""

EXPORT = r"""
import hashlib, json, sys
sys.path.insert(0, ROOT)
import numpy as np
import bpy
from addon import export
from addon.core import load_engine
bpy.ops.wm.open_mainfile(filepath=BLEND)
scene, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get())
out, seen = {}, set()
def walk(path, x):
    if isinstance(x, np.ndarray):
        out[path] = x.dtype.str + str(x.shape) + hashlib.sha1(
            np.ascontiguousarray(x).tobytes()).hexdigest()
    elif isinstance(x, (list, tuple)):
        for i, y in enumerate(x):
            walk(f"{path}[{i}]", y)
    elif isinstance(x, dict):
        for k in sorted(x, key=str):
            walk(f"{path}[{k!r}]", x[k])
    elif hasattr(x, "__dict__") and id(x) not in seen:
        seen.add(id(x))
        for k, y in vars(x).items():
            walk(f"{path}.{k}", y)
walk("scene", scene)
prototypes = {id(m.prototype) for m in scene.meshes if getattr(m, "prototype", None)}
print(json.dumps({"arrays": out, "meshes": len(scene.meshes), "prototypes": len(prototypes)}))
"""


def _child(code, **names):
    head = "".join(f"{k} = {v!r}\n" for k, v in names.items())
    res = subprocess.run([PYTHON, "-c", head + code], cwd=ROOT, capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    return res.stdout


def test_gn_instances_export_the_same_arrays_in_two_processes(tmp_path):
    blend = str(tmp_path / "scatter.blend")
    _child(BUILD, ROOT=ROOT, BLEND=blend, CANONICAL=False)
    runs = [json.loads(_child(EXPORT, ROOT=ROOT, BLEND=blend).strip().splitlines()[-1])
            for _ in range(2)]
    first, second = runs
    # Instanced on the plane: many placements of the two shapes' prototypes.
    assert first["meshes"] > 20 and first["prototypes"] == 2, first["meshes"]
    assert any(".faces" in k and "prototype" in k for k in first["arrays"])
    differ = sorted(k for k in first["arrays"] if first["arrays"][k] != second["arrays"].get(k))
    assert first["arrays"].keys() == second["arrays"].keys()
    assert differ == [], differ[:10]


def test_script_built_uv_spheres_export_the_same_arrays_in_two_processes(tmp_path):
    """The scene built anew in each of two processes, its UV spheres (bmesh.ops and
    bpy.ops) put in order by tools/canonical_mesh.py: the same arrays, bit for bit. Without
    it Blender 5.0.1's create_uvsphere orders their faces anew in every process
    (docs/design.md, Blender facts)."""
    runs = []
    for k in range(2):
        blend = str(tmp_path / f"built{k}.blend")
        _child(BUILD, ROOT=ROOT, BLEND=blend, CANONICAL=True)
        runs.append(json.loads(_child(EXPORT, ROOT=ROOT, BLEND=blend).strip().splitlines()[-1]))
    first, second = runs
    assert first["meshes"] > 20 and first["prototypes"] == 2, first["meshes"]
    assert first["arrays"].keys() == second["arrays"].keys()
    differ = sorted(k for k in first["arrays"] if first["arrays"][k] != second["arrays"][k])
    assert differ == [], differ[:10]
