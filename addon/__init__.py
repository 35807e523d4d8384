"""Blender side of the photon mapping renderer: translates, never renders.

register()/unregister() are re-exported by the extension's root __init__.py. The modules
(which import bpy) are imported by register(), not by importing this package: the batch
command (`python -m addon.batch`) sets up its Ctrl-C handling and checks its arguments
before Blender loads (importing bpy takes a second, and an interrupt inside it is lost or
crashes Blender's module initialisation).
"""


def _modules():
    from . import engine, operators, properties, ui
    return (properties, engine, operators, ui)


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
