"""Where a Dask worker keeps the engine the client shipped (engine/distributed.py).

Inside Blender the engine is bl_ext.<repo>.<id>.engine, a package no worker can import, so
the client sends it as a zip (distributed.engine_zip). Client.upload_file would put that
zip in each worker's own scratch folder, a new path for every worker process, cluster and
restart; numba files its kernel cache by source path and (mtime, size), so each of them
compiled every kernel again (minutes of CPU before the first pass). UnpackEngine unpacks
the zip once per machine and user into a folder named by its contents, with the files'
own modification times, and puts that folder first on the worker's sys.path: every later
render, worker process and restarted worker on that machine loads the compiled kernels.

This module is pickled by value (cloudpickle.register_pickle_by_value) because the
workers cannot import it under its package name: it imports only the standard library and
distributed, and refers to nothing else of the engine.
"""
from __future__ import annotations

import getpass
import importlib
import io
import os
import shutil
import stat
import sys
import tempfile
import time
import zipfile

from distributed.diagnostics.plugin import WorkerPlugin


def engines_folder() -> str:
    """The folder that holds unpacked engines on this machine, one per user (a shared
    temporary folder of another user's would not be writable)."""
    try:
        user = getpass.getuser()
    except Exception:  # noqa: BLE001 - no user name (some containers): the uid, or nothing
        user = str(os.getuid()) if hasattr(os, "getuid") else "user"
    return os.path.join(tempfile.gettempdir(), f"photonmap_engines_{user}")


COMPLETE = ".complete"  # written last: a folder without it (cut short, cleaned) is unpacked again


def _private(folder: str) -> bool:
    """True when folder is a real directory (not a link) that only this user can write:
    another local user must not be able to plant code a worker would import."""
    try:
        st = os.lstat(folder)
    except OSError:
        return False
    if not stat.S_ISDIR(st.st_mode):
        return False
    if hasattr(os, "getuid") and (st.st_uid != os.getuid() or st.st_mode & 0o022):
        return False
    return True


def _extract(data: bytes, folder: str) -> None:
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        z.extractall(folder)
        for info in z.infolist():
            t = time.mktime(info.date_time + (0, 0, -1))
            os.utime(os.path.join(folder, info.filename), (t, t))
    with open(os.path.join(folder, COMPLETE), "w"):
        pass


def unpack(data: bytes, name: str) -> str:
    """Unpack the zip `data` into engines_folder()/name once (name identifies its
    contents) and return that folder. Files keep the modification times stored in the
    zip, so a folder unpacked again (a cleaned temporary folder) matches numba's cache.
    Workers unpacking at the same time each unpack into a folder of their own and the
    first rename wins. Where engines_folder() is not this user's alone (a link, another
    owner, group- or world-writable), the engine goes to a new private temporary folder
    (correct, but its kernels compile in each worker)."""
    base = engines_folder()
    os.makedirs(base, mode=0o700, exist_ok=True)
    if not _private(base):
        scratch = tempfile.mkdtemp(prefix="photonmap_engine_")
        _extract(data, scratch)
        return scratch
    root = os.path.join(base, name)
    if os.path.isfile(os.path.join(root, COMPLETE)):
        return root
    scratch = tempfile.mkdtemp(dir=base, prefix=".unpacking-")
    try:
        _extract(data, scratch)
        if os.path.isdir(root):  # cut short or cleaned by a temp cleaner: replaced
            shutil.rmtree(root, ignore_errors=True)
        try:
            os.rename(scratch, root)
        except OSError:
            if not os.path.isfile(os.path.join(root, COMPLETE)):
                raise
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return root


class UnpackEngine(WorkerPlugin):
    """A Dask worker plugin (Client.register_plugin: every worker, also those that join or
    restart later): unpack the shipped engine (unpack) and import `package` from there.

    data: the zip's bytes; name: a folder name unique to its contents and package;
    package: the engine's module name, e.g. 'bl_ext.user_default.photonmap.engine'.
    Modules of the package's top level imported from elsewhere (an older engine, the
    scheduler's upload) are dropped from sys.modules, so the next task imports this one."""

    def __init__(self, data: bytes, name: str, package: str):
        self.data, self.name, self.package = data, name, package

    def setup(self, worker=None):
        self.root = root = unpack(self.data, self.name)
        if root in sys.path:
            sys.path.remove(root)
        sys.path.insert(0, root)
        loaded = sys.modules.get(self.package)
        here = os.path.join(root, "")
        if loaded is None or not os.path.abspath(getattr(loaded, "__file__", "") or "").startswith(here):
            top = self.package.split(".")[0]
            for module in [m for m in sys.modules if m == top or m.startswith(top + ".")]:
                del sys.modules[module]
        importlib.invalidate_caches()

    def teardown(self, worker=None):
        # Replaced by another engine's plugin (the same name) or the worker closing.
        root = getattr(self, "root", None)
        if root in sys.path:
            sys.path.remove(root)
