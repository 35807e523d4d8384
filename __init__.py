"""Photon Mapping render engine for Blender (extension entry point).

The add-on lives in addon/, the pure-Python engine in engine/ (no bpy).
"""
if __package__:
    from .addon import register, unregister  # noqa: F401
else:
    # Imported as a plain module, not as the extension's package: pytest does that when
    # it collects a checkout whose folder name is not a Python identifier ("photon-map").
    from addon import register, unregister  # noqa: F401

__all__ = ["register", "unregister"]
