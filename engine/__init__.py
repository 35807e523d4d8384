"""Photon mapping render engine (Jensen; Yu, Lowther & Shene 2005) on Embree.

Python on numpy, embreex, scipy and numba (compiled kernels); never imports bpy.

    from engine import render, RenderSettings
    from engine.api import PaperScene
"""
import os as _os
import signal as _signal
import sys as _sys


def _interrupted_while_loading(signum, frame):
    # Nothing is rendered or written yet: leave at once, without a traceback.
    _sys.stderr.write("\nphotonmap: interrupted while loading; nothing was written\n")
    _os._exit(128 + int(signum))


# The `photonmap` command: Ctrl-C (or SIGTERM) in its first moment, while numpy, scipy,
# numba and Embree load (~1 s), stops quietly; the command installs its own cancel
# handler (engine.cli.CancelOnInterrupt) once it runs.
if (_sys.argv and _os.path.splitext(_os.path.basename(_sys.argv[0]))[0] == "photonmap"
        and _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler):
    for _sig in (_signal.SIGINT, _signal.SIGTERM):
        _signal.signal(_sig, _interrupted_while_loading)

from . import (ambientocclusion, bevel, displacement, hair, hairbsdf, ies, imageio,  # noqa: E402
               motionblur, panorama, pointcloud, pointiness, presets, resources, shadernodes,
               stagespans, subsurface, subsurfacewalk, teaching, worldgraph)
from .film import Film  # noqa: E402
from .lights import DECLARED_KINDS  # noqa: E402
from .lights.environment import Environment  # noqa: E402
from .progressive import Budget, render_progressive  # noqa: E402
from .render import render  # noqa: E402
from .resources import ResourceError  # noqa: E402
from .scene import (Camera, Light, LightPortal, Material, Mesh, Prototype, Scene,  # noqa: E402
                    SceneError, WorldMedium)
from .settings import RenderSettings  # noqa: E402
from .bump import Bump  # noqa: E402
from .normalmap import NormalMap  # noqa: E402
from .textures import ColorAttribute, ImageTexture, TextureError  # noqa: E402

__all__ = ["render", "render_progressive", "Budget", "presets", "resources", "shadernodes", "ies",
           "teaching", "imageio",
           "RenderSettings",
           "Film", "Scene", "Mesh", "Prototype", "Material", "Light", "Camera", "SceneError", "ResourceError",
           "ImageTexture", "ColorAttribute", "TextureError", "NormalMap", "Bump",
           "DECLARED_KINDS", "Environment", "WorldMedium"]
__version__ = "0.1.0"
