"""Blender side of the photon mapping renderer: translates, never renders.

register()/unregister() are re-exported by the extension's root __init__.py.
"""
from . import engine, operators, properties, ui

_modules = (properties, engine, operators, ui)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
