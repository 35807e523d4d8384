"""Fixtures for the Blender tests; the helpers live in blender_helpers.py (a unique module
name, so it cannot collide with tests/conftest.py)."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from blender_helpers import bpy_addon, fresh_scene, open_ground  # noqa: E402,F401


import pytest  # noqa: E402


@pytest.fixture(autouse=True)
def _converter_raises_on_unreadable_trees(monkeypatch):
    """A node tree the add-on's converter cannot read fails the test that meets it
    (addon.materials.RAISE_UNREADABLE_TREES) instead of rendering its viewport colour with
    a warning no test reads; the fallback's own test turns it off."""
    try:
        from addon import materials
    except ImportError:  # (no bpy: the Blender tests skip anyway)
        return
    monkeypatch.setattr(materials, "RAISE_UNREADABLE_TREES", True)
