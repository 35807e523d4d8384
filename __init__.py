"""Photon Mapping render engine for Blender (extension entry point).

The add-on lives in addon/, the pure-Python engine in engine/ (no bpy).
"""
from .addon import register, unregister  # noqa: F401

__all__ = ["register", "unregister"]
