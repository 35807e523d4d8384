"""The Vector pass' motion: the scene exported one frame before and after the rendered
frame (as Cycles' motion pass samples it: blender/sync.cpp, frame -1 and +1 with
motion blur off), turned into the engine's vectorpass.SceneMotion (the cameras, and
each mesh's object transform relative to the frame's, matched by the export's mesh
names). A mesh whose vertices move within its object (armature, shape keys,
modifiers) carries its vertices' displacements (SceneMotion.deform, Cycles' deformation
motion); one whose vertex count changes between the frames is named in a warning: its
vectors follow the object's transform only."""
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
    deform = {}
    changed = []  # meshes whose vertex count differs between the frames
    for mesh in pm_scene.meshes:
        maps, moves, bent = [], [], False
        a = _world_vertices(mesh)
        for table in by_name:
            other = table.get(mesh.name)
            if other is None:
                maps.append(vp.SceneMotion.object_map(mesh.object_linear, mesh.location,
                                                      mesh.object_linear, mesh.location))
                moves.append(None)
                continue
            maps.append(vp.SceneMotion.object_map(mesh.object_linear, mesh.location,
                                                  other.object_linear, other.location))
            b = _world_vertices(other)
            moves.append(b - a if a.shape == b.shape else None)
            if not len(a):
                continue
            if a.shape != b.shape:
                if mesh.name not in changed:
                    changed.append(mesh.name)
                continue
            m = maps[-1]
            size = float(np.ptp(a, axis=0).max()) or 1.0
            bent |= float(np.abs(a @ m[:, :3].T + m[:, 3] - b).max()) > DEFORM_TOLERANCE * size
        if bent:  # (a frame without the mesh, or of another count: no displacement)
            deform[mesh.name] = tuple(d if d is not None else
                                      a @ mp[:, :3].T + mp[:, 3] - a
                                      for d, mp in zip(moves, maps))
        identity = np.allclose(maps[0][:, :3], np.eye(3)) and np.allclose(maps[1][:, :3],
                                                                          np.eye(3))
        if not (identity and not maps[0][:, 3].any() and not maps[1][:, 3].any()):
            objects[mesh.name] = (maps[0], maps[1])
    warnings = []
    if changed:
        names = ", ".join(f"'{n}'" for n in changed[:5]) + (
            f" and {len(changed) - 5} more" if len(changed) > 5 else "")
        warnings.append(f"Vector pass: {names} change their vertex count between frames "
                        "(a modifier or simulation remeshes them): their vectors follow the "
                        "object's transform only")
    return vp.SceneMotion(prev_camera=prev.camera, next_camera=nxt.camera,
                          objects=objects, deform=deform), warnings
