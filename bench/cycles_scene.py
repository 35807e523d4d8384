"""Render an engine Scene with Cycles (from the bpy wheel) for reference images.

Builds the same scene in bpy (meshes, materials, lights, camera, black world) and renders
it with the settings that make Cycles comparable: no denoising, no clamping, no glossy
filter, the engine's default bounce limits (Cycles' own defaults: RenderSettings' max /
diffuse / glossy / transmission / transparent bounces, so our default renders and Cycles'
count the same paths), box pixel filter of 1 px (our film's filter). Used by the benchmarks;
the Blender tests compare through the add-on instead.
"""
from __future__ import annotations

import os
import tempfile
import time

import numpy as np

from engine.settings import RenderSettings


def _material(bpy, m):
    bm = bpy.data.materials.new(m.name)
    bm.use_nodes = True
    nt = bm.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    color = (*[float(c) for c in m.base_color], 1.0)
    if m.transmission > 0:
        node = nt.nodes.new("ShaderNodeBsdfGlass")
        node.inputs["IOR"].default_value = m.ior
        node.inputs["Roughness"].default_value = m.roughness
        node.inputs["Color"].default_value = color
    elif m.metallic > 0 or m.specular > 0 or m.is_emissive:
        node = nt.nodes.new("ShaderNodeBsdfPrincipled")
        node.inputs["Base Color"].default_value = color
        node.inputs["Metallic"].default_value = m.metallic
        node.inputs["Roughness"].default_value = m.roughness
        node.inputs["IOR"].default_value = m.ior
        node.inputs["Specular IOR Level"].default_value = 0.5 * m.specular
        if m.is_emissive:
            node.inputs["Emission Color"].default_value = (*[float(c) for c in m.emission], 1.0)
            node.inputs["Emission Strength"].default_value = 1.0
    else:
        node = nt.nodes.new("ShaderNodeBsdfDiffuse")
        node.inputs["Color"].default_value = color
    nt.links.new(node.outputs[0], out.inputs[0])
    return bm


def build(scene):
    """Replace the current bpy scene's content with `scene` (an engine Scene)."""
    import bpy
    import mathutils

    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    mats = {name: _material(bpy, m) for name, m in scene.materials.items()}
    for mesh in scene.meshes:
        mesh = mesh.expanded()  # a placement without a copy (Mesh.place): its copy
        me = bpy.data.meshes.new(mesh.name)
        me.from_pydata(mesh.vertices.tolist(), [], mesh.faces.tolist())
        if mesh.normals is not None:
            me.shade_smooth()
        for name in mesh.materials:
            me.materials.append(mats[name])
        me.polygons.foreach_set("material_index", mesh.material_ids.astype(np.int32))
        ob = bpy.data.objects.new(mesh.name, me)
        sc.collection.objects.link(ob)
    for light in scene.lights:
        ld = bpy.data.lights.new(light.name, light.kind)
        ld.energy = light.power
        ld.color = [float(c) for c in light.color]
        if light.kind == "AREA":
            ld.shape = "DISK" if light.shape == "DISK" else "RECTANGLE"
            if light.shape == "DISK":
                ld.shape = "ELLIPSE"
            ld.size, ld.size_y = light.size_x, light.size_y
        if light.kind in ("POINT", "SPOT"):
            ld.shadow_soft_size = light.radius
        if light.kind == "SPOT":
            ld.spot_size, ld.spot_blend = light.spot_size, light.spot_blend
        if light.kind == "SUN":
            ld.angle = light.angle
        ob = bpy.data.objects.new(light.name, ld)
        z = -light.direction
        x = light.axis_u
        y = np.cross(z, x)
        M = np.eye(4)
        M[:3, 0], M[:3, 1], M[:3, 2], M[:3, 3] = x, y, z, light.position
        ob.matrix_world = mathutils.Matrix(M.tolist())
        sc.collection.objects.link(ob)
    cam = bpy.data.cameras.new("Camera")
    cam.sensor_fit = scene.camera.sensor_fit
    if scene.camera.kind == "ORTHO":
        cam.type = "ORTHO"
        cam.ortho_scale = scene.camera.ortho_scale
    else:
        cam.angle = scene.camera.fov
    cam.shift_x, cam.shift_y = scene.camera.shift_x, scene.camera.shift_y
    co = bpy.data.objects.new("Camera", cam)
    M = np.eye(4)
    M[:3, :3] = scene.camera.rotation
    M[:3, 3] = scene.camera.position
    co.matrix_world = mathutils.Matrix(M.tolist())
    sc.collection.objects.link(co)
    sc.camera = co
    world = bpy.data.worlds.new("World")
    sc.world = world
    bg = [float(c) for c in scene.background]
    world.color = bg
    if world.node_tree is not None:  # Blender 5 worlds default to a 0.05 grey background
        for node in world.node_tree.nodes:
            if node.type == "BACKGROUND":
                node.inputs["Color"].default_value = (*bg, 1.0)
                node.inputs["Strength"].default_value = 1.0
    sc.render.resolution_x, sc.render.resolution_y = scene.width, scene.height
    sc.render.resolution_percentage = 100
    return sc


def render(scene, samples: int, seed: int = 0) -> tuple[np.ndarray, float]:
    """(linear HxWx3 float32 image, seconds) rendered by Cycles."""
    import bpy

    sc = build(scene)
    c = sc.cycles
    sc.render.engine = "CYCLES"
    c.device = "CPU"
    c.samples = samples
    c.seed = seed
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    ours = RenderSettings()
    for attr in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                 "transparent_max_bounces"):
        setattr(c, attr, getattr(ours, attr))
    c.caustics_reflective = c.caustics_refractive = True
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "cycles.exr")
        sc.render.filepath = path
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        seconds = time.perf_counter() - t0
        from engine.imageio import read_image
        return read_image(path), seconds
