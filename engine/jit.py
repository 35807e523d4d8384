"""Compiled kernels: numba set-up (cache directory, the one decorator) and the first-use
compile step.

Every kernel is `@kernel`: numba's `njit(nogil=True, cache=True)`. nogil lets
engine/parallel.py's threads run kernels on all cores; there is no parallel=True / prange
(numba's threading layers conflict with Blender's libtbb and abort on concurrent calls).
cache=True writes the machine code to NUMBA_CACHE_DIR, so only the first render on a
machine compiles (minutes of CPU, shared out to helper processes on several cores:
engine/compilepool.py); later processes load it (a few seconds). The cache
lives in a subfolder named by a hash of all engine sources (numba alone would miss a
change in a kernel that another module's kernel calls).

NUMBA_CACHE_DIR must be set before numba is imported. The Blender add-on sets it to its
extension's user folder (addon/core.py); otherwise this module picks a user cache folder
(XDG_CACHE_HOME or ~/.cache, %LOCALAPPDATA%, ~/Library/Caches: photonmap/numba), unless
NUMBA_CACHE_DIR is set already. numba raises at decoration time when it cannot write its
cache, so an unwritable folder is replaced by one in the temporary directory.
"""
from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import time

COMPILE_MESSAGE = "Compiling render kernels (first render only)"
# The count after each kernel module, short enough for the CLI's and the batch's bar
# (42 / 46 characters of description: the long message's count was cut off there, and a
# new user watched "Compiling render kernels (first render only): 0%" for an hour).
COMPILE_PROGRESS = "Compiling kernels {}/{}, first render only"


def is_compile_text(text) -> bool:
    """True for the stats texts of the kernel compile (COMPILE_MESSAGE, COMPILE_PROGRESS)."""
    return str(text).startswith((COMPILE_MESSAGE, "Compiling kernels "))


def _user_cache_dir() -> str:
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or os.path.expanduser("~\\AppData\\Local")
    elif sys.platform == "darwin":
        base = os.path.expanduser("~/Library/Caches")
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    return os.path.join(base, "photonmap", "numba")


def _writable(path: str) -> bool:
    try:
        os.makedirs(path, exist_ok=True)
        probe = tempfile.NamedTemporaryFile(dir=path, prefix=".probe", delete=True)
        probe.close()
        return True
    except OSError:
        return False


def _choose_cache_dir() -> str:
    path = os.environ.get("NUMBA_CACHE_DIR") or _user_cache_dir()
    if not _writable(path):
        user = getattr(os, "getuid", lambda: "user")()
        path = os.path.join(tempfile.gettempdir(), f"photonmap-numba-{user}")
        os.makedirs(path, exist_ok=True)
    return path


def _engine_stamp() -> str:
    """Hash of every engine module that defines kernels, the tables they read (.npz: numba
    freezes global arrays into the machine code), and the numba version. numba's cache checks only
    a kernel's own file: a kernel calling one in another module (directlight ->
    closures.principled -> closures.ggx) would load stale machine code after that module
    changed. One cache folder per stamp rules that out."""
    try:
        from importlib.metadata import version
        h = hashlib.sha1(version("numba").encode())
    except Exception:  # noqa: BLE001  (no metadata: the sources alone still tell versions apart)
        h = hashlib.sha1()
    pkg = os.path.dirname(os.path.abspath(__file__))
    if os.path.isdir(pkg):
        for root, dirs, files in os.walk(pkg):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            for name in sorted(files):
                if name.endswith((".py", ".npz")):
                    path = os.path.join(root, name)
                    with open(path, "rb") as f:
                        text = f.read()
                    # kernels call kernels only; .npz: tables kernels read as constants
                    if b"@kernel" in text or name.endswith(".npz"):
                        h.update(os.path.relpath(path, pkg).encode())
                        h.update(text)
    else:  # imported from a zip (the engine shipped to Dask workers)
        import zipfile
        archive = getattr(__loader__, "archive", None)
        prefix = os.path.relpath(pkg, archive).replace(os.sep, "/") + "/" if archive else ""
        if archive:
            with zipfile.ZipFile(archive) as z:
                for name in sorted(z.namelist()):
                    if name.startswith(prefix) and name.endswith((".py", ".npz")):
                        text = z.read(name)
                        if b"@kernel" in text or name.endswith(".npz"):
                            h.update(name.encode())
                            h.update(text)
    return h.hexdigest()[:16]


# Other versions' kernel caches are kept while they may still be used: several checkouts
# (or an extension and a checkout) on one machine each have their own stamp, and deleting
# every other folder made them recompile each other's kernels in turn (minutes each).
KEEP_VERSIONS = 8      # at most this many cache folders (the most recently used)
KEEP_DAYS = 14         # and none unused for longer


def _prune(root: str, keep: str, now: float | None = None) -> list[str]:
    """Remove other engine versions' cache folders (16 hex digits) unused for KEEP_DAYS
    or beyond the KEEP_VERSIONS most recently used (a folder's modification time: each
    process touches its own). Best effort; returns the folders removed."""
    import shutil
    now = time.time() if now is None else now
    try:
        names = os.listdir(root)
    except OSError:
        return []
    others = []
    for name in names:
        path = os.path.join(root, name)
        if (name != keep and len(name) == 16 and os.path.isdir(path)
                and all(c in "0123456789abcdef" for c in name)):
            try:
                others.append((os.path.getmtime(path), path))
            except OSError:
                continue
    others.sort(reverse=True)  # most recently used first
    removed = []
    for rank, (mtime, path) in enumerate(others):
        if rank >= KEEP_VERSIONS - 1 or now - mtime > KEEP_DAYS * 86400:
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


CACHE_ROOT = _choose_cache_dir()
_STAMP = _engine_stamp()
if os.path.basename(os.path.normpath(CACHE_ROOT)) == _STAMP:
    CACHE_ROOT = os.path.dirname(os.path.normpath(CACHE_ROOT))  # inherited from a parent
CACHE_DIR = os.path.join(CACHE_ROOT, _STAMP)
os.makedirs(CACHE_DIR, exist_ok=True)
try:
    os.utime(CACHE_DIR)  # "used now": _prune keeps the most recently used versions
except OSError:
    pass
_prune(CACHE_ROOT, _STAMP)
os.environ["NUMBA_CACHE_DIR"] = CACHE_DIR
if "numba" in sys.modules:  # imported earlier (another add-on): make it see the folder
    import numba.core.config
    numba.core.config.reload_config()

import numba  # noqa: E402  (after NUMBA_CACHE_DIR is set)

from . import compilepool  # noqa: E402

# Saves into our cache folders take a lock file: processes compiling at once (the
# compile's helpers, two first renders) must not give two signatures one data file.
compilepool.install_save_lock(CACHE_ROOT)

kernel = numba.njit(nogil=True, cache=True)

# Kernel modules register a warm-up (a call on tiny inputs that compiles or loads every
# specialisation a render uses) here when they are imported.
_warm_ups: list = []
_warm = False


def register_warm_up(fn):
    """Decorator: fn() compiles (or loads from the cache) one module's kernels."""
    _warm_ups.append(fn)
    return fn


def _stamp() -> str:
    """Identifies the kernels' source and the numba version: the cache is current for
    exactly this stamp."""
    h = hashlib.sha1(numba.__version__.encode())
    for fn in _warm_ups:
        module = sys.modules[fn.__module__]
        try:
            with open(module.__file__, "rb") as f:
                h.update(f.read())
        except OSError:
            # Imported from a zip (the engine shipped to Dask workers): ask its loader.
            h.update(module.__loader__.get_data(module.__file__))
    return h.hexdigest()[:16]


def _marker() -> str:
    # numba files its cache by each kernel's source path: a checkout elsewhere compiles
    # anew, so the marker names the package's folder too (the compile message shows).
    where = hashlib.sha1(os.path.dirname(os.path.abspath(__file__)).encode()).hexdigest()[:8]
    return os.path.join(CACHE_DIR, f"photonmap-{_stamp()}-{where}.compiled")


def needs_compile() -> bool:
    """True when the next ensure_compiled() will compile (no usable cache on disk)."""
    if _warm:
        return False
    _import_kernel_modules()
    return not os.path.exists(_marker())


def ensure_compiled(progress=None) -> float:
    """Compile (first run on this machine) or load (later processes) every kernel, once
    per process. progress(stage, fraction, text) hears COMPILE_MESSAGE before a compile
    starts, so the user knows why the first render pauses, and then COMPILE_PROGRESS
    ("Compiling kernels i/n, first render only") after each module (a compile takes
    minutes on a busy machine: the count moves; the bars also redraw their clock while it
    runs, engine/console.py keep_alive). Returns the seconds spent."""
    global _warm
    if _warm:
        return 0.0
    t0 = time.perf_counter()
    compiling = needs_compile()
    if compiling and progress is not None:
        progress("compile", 0.0, COMPILE_MESSAGE)

    def report(done, total):
        if compiling and progress is not None:
            progress("compile", done / total, COMPILE_PROGRESS.format(done, total))

    shared = False
    if compiling:
        # A cold compile: helper processes take a share (engine/compilepool.py); the loop
        # below then loads what they wrote and compiles what is left.
        processes = compilepool.compile_processes(len(_warm_ups))
        if processes > 1:
            compilepool.compile_shared(_warm_ups, processes, progress=report)
            shared = True
    for i, fn in enumerate(_warm_ups):
        fn()
        if not shared:
            report(i + 1, len(_warm_ups))
    if shared:
        report(len(_warm_ups), len(_warm_ups))
    _warm = True
    if compiling:
        try:
            open(_marker(), "w").close()
        except OSError:
            pass  # only the message's accuracy depends on it
    return time.perf_counter() - t0


def _import_kernel_modules():
    # The modules that define kernels (each registers its warm-up when imported).
    from . import (camerakernels, camerarays, directlight, filterglossy,  # noqa: F401
                   gatherkernels, hashgrid, normalmap,
                   kdtree, majorant, media, panekernels, photonkernels, photonmap,  # (warm-ups)
                   photonvisibility,
                   procedural, rayoffset, shadowtransmittance, subsurfacewalk, toplevel,
                   volumeemission, volumescatter)
