"""The Vector pass' motion: the scene exported one frame before and after the rendered
frame (as Cycles' motion pass samples it: blender/sync.cpp, frame -1 and +1 with
motion blur off), turned into the engine's vectorpass.SceneMotion (the cameras, and
each mesh's object transform relative to the frame's, matched by the export's mesh
names). A mesh whose vertices move within its object (armature, shape keys,
simulations) is named in a warning: its vectors follow the object's transform only."""
from __future__ import annotations

import importlib

import numpy as np

from . import export

# A vertex further than this share of its mesh's size from where the object's transform
# puts it counts as deformed.
DEFORM_TOLERANCE = 1e-5


def _world_vertices(mesh):
    if mesh.vertices is not None:
        return np.asarray(mesh.vertices, np.float64)
    if mesh.prototype is None or mesh.matrix is None:
        return np.zeros((0, 3))
    m = np.asarray(mesh.matrix, np.float64)
    return np.asarray(mesh.prototype.vertices, np.float64) @ m[:, :3].T + m[:, 3]


def scene_motion(engine, pm, depsgraph, pm_scene, width, height):
    """(SceneMotion, warnings) for pm_scene (exported at the current frame), from the
    scene exported at frame - 1 and frame + 1 through RenderEngine.frame_set (restored
    after). engine: the RenderEngine; pm: the engine package."""
    vp = importlib.import_module(pm.__name__ + ".vectorpass")
    scene = depsgraph.scene
    frame, subframe = scene.frame_current, scene.frame_subframe
    others = []
    try:
        for step in (-1, 1):
            engine.frame_set(frame + step, subframe=subframe)
            out, _ = export.export_scene(pm, depsgraph, camera=engine.camera_override,
                                         width=width, height=height,
                                         should_cancel=engine._should_cancel)
            others.append(out)
    finally:
        engine.frame_set(frame, subframe=subframe)
    prev, nxt = others
    by_name = [{m.name: m for m in s.meshes} for s in others]
    objects = {}
    deformed = []
    for mesh in pm_scene.meshes:
        maps = []
        for table in by_name:
            other = table.get(mesh.name)
            if other is None:
                maps.append(vp.SceneMotion.object_map(mesh.object_linear, mesh.location,
                                                      mesh.object_linear, mesh.location))
                continue
            maps.append(vp.SceneMotion.object_map(mesh.object_linear, mesh.location,
                                                  other.object_linear, other.location))
            if mesh.name not in deformed:
                a, b = _world_vertices(mesh), _world_vertices(other)
                if a.shape == b.shape and len(a):
                    m = maps[-1]
                    moved = a @ m[:, :3].T + m[:, 3]
                    size = float(np.ptp(a, axis=0).max()) or 1.0
                    if float(np.abs(moved - b).max()) > DEFORM_TOLERANCE * size:
                        deformed.append(mesh.name)
        identity = np.allclose(maps[0][:, :3], np.eye(3)) and np.allclose(maps[1][:, :3],
                                                                          np.eye(3))
        if not (identity and not maps[0][:, 3].any() and not maps[1][:, 3].any()):
            objects[mesh.name] = (maps[0], maps[1])
    warnings = []
    if deformed:
        names = ", ".join(f"'{n}'" for n in deformed[:5]) + (
            f" and {len(deformed) - 5} more" if len(deformed) > 5 else "")
        warnings.append(f"Vector pass: the vertices of {names} move within the object "
                        "(armature, shape keys, simulation): their vectors follow the "
                        "object's transform only")
    return vp.SceneMotion(prev_camera=prev.camera, next_camera=nxt.camera,
                          objects=objects), warnings
