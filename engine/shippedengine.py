"""Where a Dask worker keeps the engine the client shipped (engine/distributed.py).

Inside Blender the engine is bl_ext.<repo>.<id>.engine, a package no worker can import, so
the client sends it as a zip (distributed.engine_zip). Client.upload_file would put that
zip in each worker's own scratch folder, a new path for every worker process, cluster and
restart; numba files its kernel cache by source path and (mtime, size), so each of them
compiled every kernel again (minutes of CPU before the first pass). UnpackEngine unpacks
the zip once per machine and user into a folder named by its contents, with the files'
own modification times, and puts that folder first on the worker's sys.path: every later
render, worker process and restarted worker on that machine loads the compiled kernels.
A worker on the client's own machine (a local cluster started from Blender) does better:
where the client's engine folder is there with the same files, it imports those very files
under the package's name (local_shim) and loads the kernels the client compiled.

This module is pickled by value (cloudpickle.register_pickle_by_value) because the
workers cannot import it under its package name: it imports only the standard library and
distributed, and refers to nothing else of the engine.
"""
from __future__ import annotations

import getpass
import hashlib
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


def engine_files(directory: str) -> list[str]:
    """The engine's files under directory (its package folder), sorted, without bytecode."""
    files = []
    for root, dirs, names in os.walk(directory):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(names):
            if not name.endswith((".pyc", ".pyo")):
                files.append(os.path.join(root, name))
    return files


def engine_digest(directory: str, package: str) -> str:
    """16 hex digits identifying the engine's files under directory (their paths relative
    to it and contents) and its package name."""
    digest = hashlib.sha1(package.encode())
    for path in engine_files(directory):
        digest.update(os.path.relpath(path, directory).encode())
        with open(path, "rb") as f:
            digest.update(f.read())
    return digest.hexdigest()[:16]


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


def local_shim(source: str, package: str, name: str):
    """Where the client's own engine folder `source` exists on this machine with the same
    files (a local cluster: Blender's extension folder), a folder to put on sys.path that
    imports `package` from those very files: parent packages whose last one's __path__ is
    source's parent. numba then finds the kernels the client compiled (the same source
    paths and mtimes; a local cluster's workers inherit its NUMBA_CACHE_DIR). None when
    source is missing or differs (another machine), or for a top-level package."""
    parts = package.split(".")
    if len(parts) < 2 or not os.path.isdir(source) or os.path.basename(source) != parts[-1]:
        return None
    if engine_digest(source, package) != name.rpartition("_")[2]:
        return None
    base = engines_folder()
    os.makedirs(base, mode=0o700, exist_ok=True)
    if not _private(base):
        return None
    root = os.path.join(base, name + "-local")
    init = os.path.join(root, *parts[:-1], "__init__.py")
    body = f"__path__ = [{os.path.dirname(source)!r}]\n"
    if not (os.path.isfile(init) and open(init).read() == body):
        scratch = tempfile.mkdtemp(dir=base, prefix=".shim-")
        for depth in range(1, len(parts)):
            folder = os.path.join(scratch, *parts[:depth])
            os.makedirs(folder, exist_ok=True)
            with open(os.path.join(folder, "__init__.py"), "w") as f:
                f.write(body if depth == len(parts) - 1 else "")
        shutil.rmtree(root, ignore_errors=True)
        try:
            os.rename(scratch, root)
        except OSError:
            shutil.rmtree(scratch, ignore_errors=True)
    return root


class UnpackEngine(WorkerPlugin):
    """A Dask worker plugin (Client.register_plugin: every worker, also those that join or
    restart later): import `package` from the client's own files where this machine has
    them unchanged (local_shim), else from the shipped zip unpacked once (unpack).

    data: the zip's bytes; name: a folder name unique to its contents and package
    ('photonmap_engine_<engine_digest>'); package: the engine's module name, e.g.
    'bl_ext.user_default.photonmap.engine'; source: the client's engine folder.
    Modules of the package's top level imported from elsewhere (an older engine, the
    scheduler's upload) are dropped from sys.modules, so the next task imports this one."""

    def __init__(self, data: bytes, name: str, package: str, source: str = ""):
        self.data, self.name, self.package, self.source = data, name, package, source

    def setup(self, worker=None):
        root = local_shim(self.source, self.package, self.name) if self.source else None
        self.root = root = root or unpack(self.data, self.name)
        if root in sys.path:
            sys.path.remove(root)
        sys.path.insert(0, root)
        loaded = sys.modules.get(self.package)
        top = sys.modules.get(self.package.split(".")[0])
        if loaded is None or os.path.dirname(os.path.abspath(getattr(top, "__file__", "") or "")) \
                != os.path.join(root, self.package.split(".")[0]):
            first = self.package.split(".")[0]
            for module in [m for m in sys.modules if m == first or m.startswith(first + ".")]:
                del sys.modules[module]
        importlib.invalidate_caches()

    def teardown(self, worker=None):
        # Replaced by another engine's plugin (the same name) or the worker closing.
        root = getattr(self, "root", None)
        if root in sys.path:
            sys.path.remove(root)
