"""Test set-up shared by every test.

pytest runs with --import-mode=importlib (pyproject.toml): the repository root holds the
extension's __init__.py, and pytest's default mode would import the root as a package
named after the checkout folder and put that folder's parent on sys.path, where any
sibling folder (another checkout named 'distributed', say) shadows a real package. So
sys.path gets exactly the repository root (engine/, addon/) and this folder (helpers)."""
import os
import sys

TESTS = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(TESTS)
for path in (TESTS, ROOT):
    if path not in sys.path:
        sys.path.insert(0, path)
