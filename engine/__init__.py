"""Photon mapping render engine (Jensen; Yu, Lowther & Shene 2005) on Embree.

Python on numpy, embreex, scipy and numba (compiled kernels); never imports bpy.

    from engine import render, RenderSettings
    from engine.api import PaperScene
"""
from . import imageio, presets, resources, shadernodes, teaching
from .film import Film
from .lights import DECLARED_KINDS
from .lights.environment import Environment
from .progressive import Budget, render_progressive
from .render import render
from .resources import ResourceError
from .scene import Camera, Light, Material, Mesh, Prototype, Scene, SceneError
from .settings import RenderSettings
from .normalmap import Bump, NormalMap
from .textures import ColorAttribute, ImageTexture, TextureError

__all__ = ["render", "render_progressive", "Budget", "presets", "resources", "shadernodes",
           "teaching", "imageio",
           "RenderSettings",
           "Film", "Scene", "Mesh", "Prototype", "Material", "Light", "Camera", "SceneError", "ResourceError",
           "ImageTexture", "ColorAttribute", "TextureError", "NormalMap", "Bump",
           "DECLARED_KINDS", "Environment"]
__version__ = "0.1.0"
