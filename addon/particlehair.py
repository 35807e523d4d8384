"""Particle hair (a Particle System of type Hair, rendered as Path) as hair strands.

Blender's old hair system keeps its strands in the particle system: the parents' keys and,
when Children are on, the children interpolated from them at render time. Cycles reads
them through ParticleSystem.co_hair, one key at a time, and renders them as curves of the
emitter object (blender/curves.cpp, ObtainCacheParticleData and ExportCurveSegments); this
module reads them the same way, so the strands' keys, radii and material slots are
Cycles':
- which systems: those whose Particle System modifier is on (Render in a final render,
  Realtime in the viewport), of type Hair and rendered as Path;
- which strands: the children alone when the system has children, else the parents; a
  viewport's children are Viewport Display > Amount % of them (a final render's: all);
- keys per strand: 2^Steps + 1 (Render > Steps in a final render, Viewport Display >
  Strand Steps in the viewport), plus Kink > Extra Steps for a spiral kink;
- radius: Hair Shape's Diameter Root / Tip x Radius Scale / 2, blended along the strand by
  its share of the key polyline's length and Hair Shape's Strand Shape (shaperadius);
  Close Tip: the last key's radius 0;
- material: Render > Material (a slot of the emitter, counted from 1).
The keys come back in world space and are taken into the emitter's object space.
"""
from __future__ import annotations

import numpy as np

# Strands read between two polls of the caller's cancel (co_hair is ~2 us a key).
CANCEL_POLL_STRANDS = 2048


class Strands:
    """The hair strands of an object's particle systems, in its object space.

    points (P,3) float64 keys, radius (P,) float64 m, offsets (C+1,) int64 (strand c's
    keys are points[offsets[c]:offsets[c + 1]]), slot (C,) int32 material slot (0-based,
    not clamped), uv (C,2) float64 the emitter's render UV map at each strand's root (None
    without UV maps: Cycles' curve_uv, which a hair's UV-mapped textures read), systems:
    the names of the systems read."""

    __slots__ = ("points", "radius", "offsets", "slot", "uv", "systems")

    def __init__(self, points, radius, offsets, slot, systems, uv=None):
        self.points, self.radius, self.offsets = points, radius, offsets
        self.slot, self.systems, self.uv = slot, systems, uv


def hair_systems(obj, background: bool = True) -> list:
    """(modifier, particle system) of each particle system of obj (an evaluated object)
    rendered as hair strands: its modifier on (show_render for a final render, else
    show_viewport), type Hair, Render As Path (blender/curves.cpp)."""
    out = []
    for mod in getattr(obj, "modifiers", None) or ():
        if mod.type != "PARTICLE_SYSTEM":
            continue
        if not (mod.show_render if background else mod.show_viewport):
            continue
        psys = mod.particle_system
        part = psys.settings
        if part.type == "HAIR" and part.render_type == "PATH":
            out.append((mod, psys))
    return out


def shape_radius(shape: float, root: float, tip: float, time) -> np.ndarray:
    """Hair Shape's radius at `time` (the share of the strand's key polyline length from
    the root, array in [0, 1]): Cycles' shaperadius (blender/curves.cpp): (1 - time)
    raised to 1 + shape (shape < 0) or 1 / (1 - shape) (shape > 0), from tip to root."""
    falloff = 1.0 - np.clip(np.asarray(time, np.float64), 0.0, 1.0)
    if shape < 0.0:
        falloff = falloff ** (1.0 + shape)
    elif shape > 0.0:
        falloff = falloff ** (1.0 / (1.0 - shape)) if shape < 1.0 else np.zeros_like(falloff)
    return falloff * (root - tip) + tip


def strand_keys(psys, obj, first: int, last: int, keys: int, poll=None):
    """(last - first, keys, 3) float64 world-space keys of particles first..last-1 of
    psys (co_hair: parents are 0..len(particles)-1, children follow). poll() is called
    every CANCEL_POLL_STRANDS strands (it raises to cancel)."""
    co_hair = psys.co_hair
    out = np.empty((last - first, keys, 3))
    steps = range(keys)
    for start in range(first, last, CANCEL_POLL_STRANDS):
        if poll is not None:
            poll()
        stop = min(start + CANCEL_POLL_STRANDS, last)
        out[start - first:stop - first] = [[co_hair(obj, particle_no=p, step=s) for s in steps]
                                           for p in range(start, stop)]
    return out


def root_uvs(mod, psys, first: int, last: int, uv_no: int) -> np.ndarray:
    """(last - first, 2) the emitter's UV map uv_no at the roots of particles first..last-1
    (uv_on_emitter: a parent by its particle, a child by its number with the first parent
    as the particle argument, as Cycles' ObtainCacheParticleUV passes them)."""
    parents = psys.particles
    uv_on_emitter = psys.uv_on_emitter
    out = np.empty((last - first, 2))
    for p in range(first, last):
        particle = parents[p] if p < len(parents) else (parents[0] if len(parents) else None)
        out[p - first] = uv_on_emitter(mod, particle=particle, particle_no=p, uv_no=uv_no)
    return out


def particle_strands(obj, background: bool = True, poll=None) -> Strands | None:
    """The strands of obj's hair systems (hair_systems) in obj's object space, as Cycles
    exports them (module docstring); None when there is none. obj: an evaluated object
    (a depsgraph instance's). poll() is called while the keys are read (it raises the
    caller's cancel)."""
    systems = hair_systems(obj, background)
    if not systems:
        return None
    to_object = np.linalg.inv(np.array(obj.matrix_world, dtype=np.float64))
    layers = getattr(getattr(obj, "data", None), "uv_layers", None)
    uv_no = None
    if layers is not None and len(layers):
        uv_no = next((i for i, layer in enumerate(layers) if layer.active_render), 0)
    points, radius, counts, slots, uvs, names = [], [], [], [], [], []
    for mod, psys in systems:
        part = psys.settings
        parents = len(psys.particles)
        children = len(psys.child_particles)
        if not background:
            children = int(children * float(part.display_percentage) / 100.0)
        with_children = part.child_type != "NONE" and children != 0
        first = parents if with_children else 0
        last = parents + children if with_children else parents
        if last <= first:
            continue
        keys = (1 << int(part.render_step if background else part.display_step)) + 1
        if part.kink == "SPIRAL":
            keys += int(part.kink_extra_steps)
        world = strand_keys(psys, obj, first, last, keys, poll)
        local = world @ to_object[:3, :3].T + to_object[:3, 3]
        seg = np.linalg.norm(np.diff(local, axis=1), axis=2)  # (C, keys-1)
        run = np.concatenate([np.zeros((len(local), 1)), np.cumsum(seg, axis=1)], axis=1)
        length = run[:, -1:]
        time = np.divide(run, length, out=np.zeros_like(run), where=length > 0.0)
        half = float(part.radius_scale) * 0.5
        r = shape_radius(float(part.shape), half * float(part.root_radius),
                         half * float(part.tip_radius), time)
        if part.use_close_tip:
            r[:, -1] = 0.0
        points.append(local.reshape(-1, 3))
        radius.append(r.reshape(-1))
        counts.append(np.full(len(local), keys, np.int64))
        slots.append(np.full(len(local), int(part.material) - 1, np.int32))
        if uv_no is not None:
            uvs.append(root_uvs(mod, psys, first, last, uv_no))
        names.append(psys.name)
    if not points:
        return None
    offsets = np.concatenate([[0], np.cumsum(np.concatenate(counts))]).astype(np.int64)
    return Strands(np.concatenate(points), np.concatenate(radius), offsets,
                   np.concatenate(slots), names,
                   np.concatenate(uvs) if uv_no is not None else None)
