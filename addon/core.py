"""Find the pure-Python engine package next to addon/.

Inside an installed extension the repository root is a package (e.g.
``bl_ext.user_default.photonmap``) and the engine is its ``engine`` sub-package. When the
add-on is used from a checkout (tests, ``python -m addon.batch``), ``addon`` is a top-level
package and the engine is the top-level ``engine`` package on sys.path.

The engine is imported lazily (it pulls in embreex and scipy), so the add-on registers
even when those are missing and can tell the user what is wrong at render time.
"""
import importlib


def load_engine():
    package = __package__ or ""
    if "." in package:  # "<root>.addon": installed as an extension
        return importlib.import_module("..engine", package)
    return importlib.import_module("engine")
