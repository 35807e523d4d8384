"""Cycles' Light Group passes (View Layer > Light Groups; RenderSettings.light_groups).

In Cycles 5.0 each lamp, emissive object and the world names a light group
(`object.lightgroup`, `world.lightgroup`); the view layer lists the groups it makes, and
each gets a pass "Combined_<group>" (blender/sync.cpp, scene/film.cpp PASS_COMBINED with
its lightgroup; kernel/film/light_passes.h: film_write_combined_pass adds every
contribution into the pass of the lightgroup of the emitter it came from, the path's
state carrying it from the light sample or the emitter met). A group's pass holds all
the light that left its emitters: direct, indirect, caustics, volume scattering, and
its emitters seen directly (a lamp visible to the camera, an emissive surface, the
world's background). The groups and the ungrouped emitters' light sum to Combined.

Light is linear in the emitters, so a group's pass is the image of the scene with only
that group's emitters on. Here each group is rendered so: a photon pass and a camera
pass of a scene that keeps the group's lamps, switches the other emissive meshes'
materials dark (surface and volume emission) and the world black unless it is the
group's (group_scene), with the render's own settings and seed, the data passes, mattes
and light groups off (group_settings). Each group costs a render of its own (the
Combined image and every other pass are the main render's, bit for bit as without light
groups); the groups' passes sum to Combined in expectation, each with its own noise
(not sample by sample, as Cycles' split of one path's light does). A scene's shadow
catchers are holdouts in the groups' renders: black, as Cycles leaves them in its group
passes (there neither engine's groups sum to Combined).

Film.data[KEY_PREFIX + name] holds a group's (H,W,3) per-sample average radiance, as
the data passes (averaged over progressive passes and motion-blur steps alike).
"""
from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np

KEY_PREFIX = "lightgroup:"
# A dark copy of a material is named NAME + DARK (no Blender name holds a control
# character).
DARK = "\x1flightgroup-dark"


def key(name: str) -> str:
    """Film.data key of group `name`'s pass."""
    return KEY_PREFIX + name


def _dark(material):
    """material with no emission (surface, its texture, volume)."""
    return replace(material, name=material.name + DARK, emission=(0.0, 0.0, 0.0),
                   emission_texture=None, volume_emission=(0.0, 0.0, 0.0),
                   volume_emission_texture=None)


def _emits(material) -> bool:
    return (bool(np.any(np.asarray(material.emission) > 0))
            or bool(np.any(np.asarray(material.volume_emission) > 0))
            or getattr(material, "volume_emission_texture", None) is not None)


def members(scene, name: str) -> int:
    """How many emitters of scene are in group `name` (lamps, emissive meshes, the
    world)."""
    n = sum(1 for light in scene.lights if light.lightgroup == name)
    n += sum(1 for m in scene.meshes if m.lightgroup == name
             and any(_emits(scene.materials[k]) for k in m.materials))
    return n + int(scene.world_lightgroup == name)  # (the world: its colour, map, glow)


def group_scene(scene, name: str):
    """scene with only light group `name`'s emitters (module docstring): its lamps; the
    emissive materials of meshes outside it swapped for dark copies; the world black
    (and its volume's emission off) unless it is the group's; shadow catchers as
    holdouts, no motion vectors, no warnings (the whole scene's are told once)."""
    materials = dict(scene.materials)
    meshes = []
    for m in scene.meshes:
        dark_needed = m.lightgroup != name and any(_emits(scene.materials[k])
                                                   for k in m.materials)
        if not dark_needed and not m.shadow_catcher:
            meshes.append(m)
            continue
        c = copy.copy(m)  # (shallow: a placement keeps its prototype; arrays shared)
        # A shadow catcher is black in Cycles' group passes (newuser41b: ours drew it as a
        # lit ground, the sun group 7.9x Cycles'): a holdout here, which still occludes.
        c.holdout = c.holdout or c.shadow_catcher
        c.shadow_catcher, c.warnings = False, []
        if dark_needed:
            names = []
            for k in m.materials:
                mat = scene.materials[k]
                if _emits(mat):
                    if k + DARK not in materials:
                        materials[k + DARK] = _dark(mat)
                    names.append(k + DARK)
                else:
                    names.append(k)
            c.materials = names
        meshes.append(c)
    out = copy.copy(scene)
    out.meshes = meshes
    out.materials = materials
    out.lights = [light for light in scene.lights if light.lightgroup == name]
    out.warnings = []
    out.vector_motion = None
    if scene.world_lightgroup != name:
        out.background = np.zeros(3)
        out.environment = None
        out.camera_background = None
        out.camera_environment = None
        fog = scene.world_medium
        if fog is not None and np.any(np.asarray(fog.emission) > 0):
            out.world_medium = replace(fog, emission=(0.0, 0.0, 0.0))  # (its glow)
    return out


def group_settings(settings):
    """The render settings of a group's render: the main one's (seed, samples, photons),
    without data passes, Shader AOVs, Cryptomatte, light groups or the photon-hit view."""
    return replace(settings, data_passes=(), shader_aovs=(), cryptomatte=(),
                   light_groups=(), show_photons=False)
