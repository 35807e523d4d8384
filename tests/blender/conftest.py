"""Fixtures for the Blender tests; the helpers live in blender_helpers.py (a unique module
name, so it cannot collide with tests/conftest.py)."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from blender_helpers import bpy_addon, fresh_scene, open_ground  # noqa: E402,F401
