"""Find the pure-Python engine package next to addon/.

Inside an installed extension the repository root is a package (e.g.
``bl_ext.user_default.photonmap``) and the engine is its ``engine`` sub-package. When the
add-on is used from a checkout (tests, ``python -m addon.batch``), ``addon`` is a top-level
package and the engine is the top-level ``engine`` package on sys.path.

The engine is imported lazily (it pulls in embreex and scipy), so the add-on registers
even when those are missing and can tell the user what is wrong at render time.
"""
import importlib


def set_kernel_cache_dir():
    """Point numba's cache (the engine's compiled kernels) at this extension's user
    folder, before the engine is imported: the extension's own folder may be read-only
    and numba cannot load its kernels without a writable cache. From a checkout (not an
    installed extension) the engine picks a user cache folder itself (engine/jit.py)."""
    import os
    package = (__package__ or "").rpartition(".")[0]  # the extension, without ".addon"
    if not package:
        return
    try:
        import bpy
        path = bpy.utils.extension_path_user(package, path="numba_cache", create=True)
    except Exception:  # noqa: BLE001 - not an extension, or an older Blender
        return
    if path:
        os.environ["NUMBA_CACHE_DIR"] = path


def load_engine():
    set_kernel_cache_dir()
    package = __package__ or ""
    if "." in package:  # "<root>.addon": installed as an extension
        return importlib.import_module("..engine", package)
    return importlib.import_module("engine")
