"""Run as a script (tests/test_warm_up.py): jit.ensure_compiled(), then render small scenes
of many kinds and print, as JSON, every kernel signature the renders added (each one is a
compile inside a user's first render of such a scene: seconds to minutes). A fresh
process, so that no earlier test has compiled the variant already."""
import json
import sys

import numba
import numpy as np

from engine.jit import ensure_compiled


def signatures() -> dict:
    out = {}
    for name, module in list(sys.modules.items()):
        if not name.startswith("engine") or module is None:
            continue
        for value in list(vars(module).values()):
            if isinstance(value, numba.core.registry.CPUDispatcher):
                out[f"{value.py_func.__module__}.{value.__name__}"] = {
                    str(s) for s in value.signatures}
    return out


def scenes():
    """(name, scene, settings) small scenes covering the light kinds, a world HDRI,
    textures, a normal map, instances, data passes, adaptive sampling, transparent film,
    a glass pane's shadow rays, absorbing media, fog, a textured density, subsurface
    scattering."""
    from engine.api import PaperScene, cornell_box
    from engine.normalmap import NormalMap
    from engine.scene import Material
    from engine.settings import RenderSettings
    from engine.textures import ImageTexture

    base = dict(workers=1, spp=2, photons=3000, caustic_photons=1000, seed=3)
    yield ("cornell box, data passes", cornell_box(24, 18),
           RenderSettings(data_passes=("denoising", "color", "light"), **base))
    s = PaperScene(24, 18)
    rng = np.random.default_rng(1)
    px = rng.random((8, 16, 3)) ** 3
    px[2, 5] = 200.0  # a sun in the HDRI
    s.set_environment(px, 0.5)
    tex = ImageTexture(rng.random((4, 4, 3)).astype(np.float32))
    s.add_material(Material("bumpy", (0.6, 0.6, 0.6), normal_map=NormalMap(
        ImageTexture(np.full((2, 2, 3), (0.6, 0.5, 0.9), np.float32)), 1.0, "TANGENT")))
    s.add_material(Material("textured", (1.0, 1.0, 1.0), texture=tex, scalar_textures={
        "roughness": ImageTexture(rng.random((4, 4, 3)).astype(np.float32))}))
    s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(3.0, 3.0, 3.0)))
    s.add_box((1.5, 1.5, 1.0), (0.4, 0.4, 0.4), material="glow", name="glow")
    s.add_plane((0, 0, 0), size=6.0, material="bumpy", name="floor")
    ball = s.add_sphere((0.0, 0.0, 0.5), 0.5, material="textured", segments=12)
    for x in (-1.5, 1.5):
        m = np.eye(4)
        m[0, 3] = x
        s.add_instance(ball, m)
    s.add_point_light((1.0, -1.0, 2.0), power=50.0, radius=0.2)
    s.add_point_light((-1.0, -1.0, 2.0), power=50.0, radius=0.2, soft_falloff=False)
    s.add_spot_light((0.0, -2.0, 2.0), (0.0, 0.0, 0.0), power=80.0, radius=0.1)
    s.add_sun((0.3, 0.2, -1.0), 1.0, angle_degrees=5.0)
    s.add_rect_area_light((0.0, 1.0, 2.5), (0.5, 0.5), power=40.0)
    s.set_camera((0.0, -4.0, 2.0), (0.0, 0.0, 0.3), view_angle=50.0)
    yield ("HDRI, every light kind, texture, normal map, instances", s,
           RenderSettings(**base))
    yield ("same, adaptive sampling, transparent film, data passes", s,
           RenderSettings(adaptive_threshold=0.05, film_transparent=True,
                          data_passes=("denoising", "color", "light"),
                          **dict(base, spp=4)))
    # A room with a window of one glass plane (engine/panelight.py: the pane's shadow
    # rays, engine/panekernels.py): a sun and an HDRI world, then a constant world.
    for world in ("sun and HDRI", "constant world"):
        r = PaperScene(24, 18, background=(1.0, 1.0, 1.0))
        r.add_material(Material("plaster", (0.8, 0.8, 0.8)))
        r.add_material(Material("glass", (1.0, 1.0, 1.0), transmission=1.0, ior=1.5,
                                roughness=0.0))
        for c, sz in (((0, 0, -0.05), (4.2, 3.2, 0.1)), ((0, 0, 2.65), (4.2, 3.2, 0.1)),
                      ((-2.05, 0, 1.3), (0.1, 3.2, 2.6)), ((2.05, 0, 1.3), (0.1, 3.2, 2.6)),
                      ((0, -1.55, 1.3), (4.0, 0.1, 2.6)), ((0, 1.55, 0.45), (4.0, 0.1, 0.9)),
                      ((0, 1.55, 2.25), (4.0, 0.1, 0.7)),
                      ((-1.3, 1.55, 1.4), (1.4, 0.1, 1.0)),
                      ((1.3, 1.55, 1.4), (1.4, 0.1, 1.0))):
            r.add_box(c, sz, "plaster")
        v = np.array([[-0.6, 1.55, 0.9], [0.6, 1.55, 0.9], [0.6, 1.55, 1.9],
                      [-0.6, 1.55, 1.9]])
        r.add_triangles(v, np.array([[0, 2, 1], [0, 3, 2]]), "glass", name="pane")
        if world == "sun and HDRI":
            r.set_environment(px, 0.5)
            r.add_sun((-0.26, -0.72, -0.64), 4.0, angle_degrees=3.0)
        r.set_camera((1.8, 1.3, 2.0), (-0.2, -1.1, 2.7), view_angle=90.0)
        yield (f"window pane, {world}", r, RenderSettings(**base))
    # Absorbing media (engine/media.py): a tinted glass ball, a thin absorbing glass slab
    # (a flat passage for shadow rays) and a volume-only box, with instances (shared rows).
    v = PaperScene(24, 18)
    v.add_plane((0, 0, 0), (0, 0, 1), 6.0, "white_diffuse", name="floor")
    v.add_material(Material("tinted", (1.0, 1.0, 1.0), transmission=1.0, ior=1.45,
                            absorption=(1.0, 0.5, 0.1)))
    v.add_material(Material("liquid", volume_only=True, absorption=(0.2, 0.8, 1.5)))
    tinted = v.add_sphere((0.0, 0.0, 0.6), 0.5, "tinted", segments=12)
    m = np.eye(4)
    m[0, 3] = 1.3
    v.add_instance(tinted, m)
    v.add_box((0.0, 0.0, 1.6), (1.5, 1.5, 0.02), "tinted", name="slab")
    v.add_box((-1.3, 0.0, 0.3), (0.6, 0.6, 0.6), "liquid", name="liquid")
    v.add_sun((0.3, 0.2, -1.0), 2.0)
    v.set_camera((0.0, -4.0, 2.0), (0.0, 0.0, 0.3), view_angle=50.0)
    yield ("absorbing media", v, RenderSettings(**base))
    # A scattering fog box (engine/volumescatter.py) under a spot and a point light inside
    # it, seen from outside: camera and final-gather segments' single scattering.
    f = PaperScene(24, 18)
    f.add_plane((0, 0, 0), (0, 0, 1), 6.0, "white_diffuse", name="floor")
    f.add_material(Material("fog", volume_only=True, absorption=(0.1, 0.1, 0.2),
                            scattering=(0.5, 0.5, 0.4), anisotropy=0.3))
    f.add_box((0.0, 0.0, 1.0), (1.6, 1.6, 1.2), "fog", name="fog")
    f.add_spot_light((0.0, 0.0, 2.5), (0, 0, 0), power=300.0, spot_size_degrees=40.0)
    f.add_point_light((0.3, 0.2, 1.0), power=20.0)
    f.set_camera((0.0, -4.0, 1.5), (0.0, 0.0, 0.8), view_angle=50.0)
    yield ("scattering fog", f, RenderSettings(**base))
    # A textured density (engine/heterogeneous.py, engine/majorant.py): the majorant
    # grid's tracking and distance kernels, with Volume bounces (the walks) and photons.
    from engine.shadernodes import Math, ObjectSpacePosition, SeparateChannel
    h = PaperScene(24, 18)
    h.add_plane((0, 0, 0), (0, 0, 1), 6.0, "white_diffuse", name="floor")
    h.add_material(Material("cloud", volume_only=True, absorption=(0.1, 0.1, 0.1),
                            scattering=(0.8, 0.8, 0.8), density_texture=Math(
                                "MULTIPLY", SeparateChannel(ObjectSpacePosition(np.eye(4)),
                                                            2), 2.0)))
    h.add_box((0.0, 0.0, 1.0), (1.6, 1.6, 1.2), "cloud", name="cloud")
    h.add_spot_light((0.0, 0.0, 2.5), (0, 0, 0), power=300.0, spot_size_degrees=40.0)
    h.set_camera((0.0, -4.0, 1.5), (0.0, 0.0, 0.8), view_angle=50.0)
    yield ("textured density", h, RenderSettings(volume_bounces=2, **base))
    # Random-walk subsurface scattering (engine/subsurfacewalk.py: the walk kernel).
    from engine.subsurfacewalk import SubsurfaceParams
    w = PaperScene(24, 18)
    sp = SubsurfaceParams.make(1.0, (0.8, 0.5, 0.4), (0.05, 0.01, 0.005), 1.5, 0.2, 0.5)
    w.add_material(Material("skin", tuple(sp.stand_in()), roughness=0.5, subsurface=sp))
    w.add_sphere((0.0, 0.0, 0.5), 0.5, material="skin", segments=12)
    w.add_plane((0, 0, 0), (0, 0, 1), 6.0, "white_diffuse", name="floor")
    w.add_sun((0.3, 0.2, -1.0), 3.0)
    w.set_camera((0.0, -3.0, 1.0), (0.0, 0.0, 0.5), view_angle=40.0)
    yield ("subsurface walk", w, RenderSettings(**base))


def main():
    from engine.render import render
    ensure_compiled()
    added = {}
    for name, scene, settings in scenes():
        before = signatures()
        render(scene, settings)
        for kernel, sigs in signatures().items():
            new = sigs - before.get(kernel, set())
            if new:
                added.setdefault(name, {})[kernel] = sorted(new)
    print(json.dumps(added))


if __name__ == "__main__":
    main()
