"""Small scenes with a refracting interface between the light and a diffuse floor, for
the refraction convention (docs/units.md, "Refraction"): our photons and camera paths
against Cycles. Shared by tests/test_refraction.py and tools/make_refraction_references.py.

Every scene: a diffuse floor (albedo 0.8, z = 0), an area light tilted in from the side
(so the specular reflection of the light is not in view), an orthographic camera looking
straight down at the middle of the floor. The floor is lit only through the glass.
"""
import numpy as np

from engine.api import PaperScene
from engine.scene import Camera, Material

WIDTH, HEIGHT = 48, 48
VIEW = 3.0            # ortho_scale: the camera sees the floor's middle 3 x 3 m
WATER_IOR = 1.33
GLASS_IOR = 1.5


def _base(ior):
    s = PaperScene(width=WIDTH, height=HEIGHT)
    s.add_material(Material("floor", (0.8, 0.8, 0.8)))
    s.add_material(Material("glass", (1.0, 1.0, 1.0), transmission=1.0, ior=ior,
                            roughness=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 6.0, "floor", name="floor")
    # 2 x 2 m light 3 m up and 2.6 m to the side, facing the floor's middle (its mirror
    # image in the water lies outside the view).
    c = np.array([2.6, 0.0, 3.0])
    s.add_rect_area_light(c, (2.0, 2.0), power=400.0, direction=-c / np.linalg.norm(c),
                          name="light")
    return s


def pool(camera_z=2.0):
    """The pool: camera above a single water plane (IOR 1.33, z = 0.5) over the floor."""
    s = _base(WATER_IOR)
    s.add_plane((0, 0, 0.5), (0, 0, 1), 6.0, "glass", name="water")
    s.camera = Camera(position=(0, 0, camera_z), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=VIEW)
    return s


def dry_pool():
    """The pool without water (the same floor in plain air)."""
    s = _base(WATER_IOR)
    s.camera = Camera(position=(0, 0, 2.0), rotation=np.eye(3), kind="ORTHO", ortho_scale=VIEW)
    return s


def window():
    """A room under a single-plane glass roof window (IOR 1.5, z = 1): the camera is in
    the room (z = 0.8), so only the light crosses the glass."""
    s = _base(GLASS_IOR)
    s.add_plane((0, 0, 1.0), (0, 0, 1), 6.0, "glass", name="window")
    s.camera = Camera(position=(0, 0, 0.8), rotation=np.eye(3), kind="ORTHO", ortho_scale=VIEW)
    return s


def slab_window():
    """The same room under a 5 cm glass slab (two interfaces)."""
    s = _base(GLASS_IOR)
    s.add_box((0, 0, 1.025), (6.0, 6.0, 0.05), "glass", name="slab")
    s.camera = Camera(position=(0, 0, 0.8), rotation=np.eye(3), kind="ORTHO", ortho_scale=VIEW)
    return s


SCENES = {"pool": pool, "dry_pool": dry_pool, "window": window, "slab_window": slab_window}


def floor_mean(img: np.ndarray) -> float:
    """Mean linear brightness (RGB mean) of the floor region: the whole image."""
    return float(np.asarray(img, np.float64)[..., :3].mean())
