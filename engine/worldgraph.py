"""A world shader's colour nodes evaluated along ray directions, for camera rays that see
a screen-mapped backplate (issue 14).

A world whose Background colour reads the Texture Coordinate node's Window or Camera
output (a photo behind the scene: Image Texture of Window coordinates) depends on the
camera: Cycles projects each direction through the camera (svm_node_tex_coord,
NODE_TEXCO_WINDOW: camera_world_to_ndc of P = D, the camera's position added for a
perspective camera, kernel/camera/projection.h). Baked into an environment map (the
scene's light, addon/world.py) such an image is as sharp as the map's texels; camera rays
instead evaluate the graph at their own direction (`WorldGraph.radiance`), so the
backplate lands on the pixels as sharp as the image.

The graph's nodes are engine/shadernodes nodes; the geometry they read is a
`WorldDirections` (Cycles' shader_setup_from_background: P = D, N = Ng = I = -D, no UVs).
"""
from __future__ import annotations

import numpy as np


class WorldDirections:
    """What engine/shadernodes asks of a Geometry, for a world shader evaluated along
    world directions dirs (n,3) (unit), as Cycles sets up a background's ShaderData
    (shader_setup_from_background: P = D, N = Ng = I = -D, no UVs): Generated and Object
    coordinates and the Geometry node's Position read the direction, Normal, True Normal
    and Incoming its opposite; UVs and colour attributes 0. camera_view: a
    shadernodes.CameraView for the Texture Coordinate node's Camera and Window outputs
    (view_points), or None (they read zeros)."""

    def __init__(self, dirs, camera_view=None):
        self.dirs = np.asarray(dirs, np.float64).reshape(-1, 3)
        self.ng = -self.dirs
        self.offset = np.zeros(3)
        self.camera_view = camera_view

    def coordinates(self, name, prim, u, v):
        d = self.dirs[np.asarray(prim, np.int64)]
        return -d if name == "normal" else d

    def hit_points(self, prim, u, v):
        return self.dirs[np.asarray(prim, np.int64)]

    def view_points(self, prim, u, v):
        """(N,3) the points Cycles projects for the Camera and Window outputs of a
        background (camera_world_to_ndc, svm_texco_camera): P = D plus the camera's
        position, except for an orthographic camera (Cycles adds it for a perspective
        camera only; a panorama's projection reads the direction either way)."""
        d = self.dirs[np.asarray(prim, np.int64)]
        view = self.camera_view
        if view is None or view.ortho:
            return d
        return d + view.position

    def uvs(self, prim, u, v):
        return np.zeros((len(prim), 2))

    def colors(self, prim, u, v):
        return np.zeros((len(prim), 3))


def factor(values, kind) -> np.ndarray:
    """A world term's factor along the directions, by kind (addon/world.py _Weight's):
    "fac" a Mix Shader factor clamped to 0..1 (as svm_node_mix_closure), "1-fac" one
    minus that, "strength" a Strength as it is."""
    if kind == "strength":
        return values
    f = np.clip(values, 0.0, 1.0)
    return f if kind == "fac" else 1.0 - f


def direction_values(node, geo) -> np.ndarray:
    """(n,) a shadernodes node's value along geo's n directions (a WorldDirections; a
    colour: its luminance, Rec. 709 weights as Cycles converts colour to float; NaN and
    inf read 0)."""
    n = len(geo.dirs)
    val = np.asarray(node.evaluate(geo, np.arange(n), np.zeros(n), np.zeros(n)), np.float64)
    if val.ndim == 2:
        val = val[:, :3] @ np.array([0.2126, 0.7152, 0.0722])
    return np.nan_to_num(np.broadcast_to(val, (n,)), nan=0.0, posinf=0.0, neginf=0.0)


class WorldGraph:
    """The radiance a world's shader sends along directions, evaluated exactly (no map):
    the sum over terms of weight x colour, as Cycles sums a world's Background closures.

    terms: [(const, factors, colour)]: const a float; factors [(node, kind)] (shadernodes
    nodes of the direction, kind "fac", "1-fac" or "strength": see factor); colour an
    RGB (3,) (W m^-2 sr^-1), an engine Environment (its radiance(d)) or a shadernodes
    colour node. camera_view: shadernodes.CameraView for the Camera and Window outputs.
    Negative radiance is read as 0 (the add-on warns, as for the baked map)."""

    def __init__(self, terms, camera_view=None, name="world"):
        self.terms = list(terms)
        self.camera_view = camera_view
        self.name = name

    def radiance(self, d) -> np.ndarray:
        """(N,3) float64 radiance (W m^-2 sr^-1) along unit directions d (N,3)."""
        d = np.asarray(d, np.float64).reshape(-1, 3)
        n = len(d)
        out = np.zeros((n, 3))
        if n == 0:
            return out
        geo = WorldDirections(d, self.camera_view)
        for const, factors, colour in self.terms:
            w = np.full(n, float(const))
            for node, kind in factors:
                w = w * factor(direction_values(node, geo), kind)
            if hasattr(colour, "radiance"):
                rgb = np.asarray(colour.radiance(d), np.float64)
            elif hasattr(colour, "evaluate"):
                rgb = np.asarray(colour.evaluate(geo, np.arange(n), np.zeros(n), np.zeros(n)),
                                 np.float64)
                if rgb.ndim == 1:
                    rgb = np.repeat(rgb[:, None], 3, axis=1)
                rgb = np.broadcast_to(rgb[..., :3], (n, 3))
            else:
                rgb = np.broadcast_to(np.asarray(colour, np.float64)[:3], (n, 3))
            out += w[:, None] * rgb
        return np.clip(np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0), 0.0, None)
