"""The first render's kernel compile, shared by several processes.

numba compiles under one lock per process (numba.core.compiler_lock), so threads cannot
share a cold compile; processes can. Each helper process imports the engine from the same
files, claims warm-ups (engine/jit.py's register_warm_up: one module's kernels each) one
at a time and runs them, writing the machine code into the shared cache folder
(NUMBA_CACHE_DIR, which the helpers inherit). The calling process claims and compiles its
share too, and then runs every warm-up as before: what the helpers compiled it loads
from the cache (numba checks the cache before compiling any new signature), what they
did not (a helper failed or was killed) it compiles itself. So the result is the serial
compile's whatever happens to the helpers; only the time changes.

numba's cache files are not safe for two processes saving overloads of one function at
once (IndexDataCacheFile.save reads the index, picks the first free data file name and
writes both: two writers can give two signatures one data file, and a later process would
load one signature's machine code for the other). Helpers compiling different warm-ups do
save the same shared kernels (closures, lights), and so can two Blender sessions rendering
for the first time: install_save_lock serialises those saves with a lock file per cache
folder.

A helper ends soon after the calling process dies, however it dies (Blender killed with
SIGKILL, a crash): its stdin is a pipe whose writing end only the caller holds, and a
thread in the helper that waits on it sees the end of the pipe when the caller's end is
closed, by the caller or by the system as it dies, and ends the helper (watch_parent).
A pipe's end of file works alike on Linux, macOS and Windows; before it, helpers ran on
up to HELPER_TIMEOUT_S compiling for nobody.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import warnings

# At most this many processes compile (the calling one included): a helper holds ~0.3-0.5
# GB while LLVM runs, and the largest warm-ups bound the gain beyond a few.
COMPILE_PROCESSES_MAX = 6
# The environment variable that sets the count (1: compile in the calling process alone).
PROCESSES_ENV = "PHOTONMAP_COMPILE_PROCESSES"
# A helper still running after this long is stopped (the calling process compiles what
# it had claimed and not finished).
HELPER_TIMEOUT_S = 3600.0
# A job waits this long at most for the jobs it depends on (run_claimed).
DEPENDENCY_WAIT_S = 120.0
# A lock file older than this is a dead process's (a save takes milliseconds).
STALE_LOCK_S = 60.0


# The last compile_shared of this process: processes, helpers_finished, jobs, run_here
# (diagnostics: the extension's install test reads it).
LAST_RUN: dict = {}


def compile_processes(n_warm_ups: int) -> int:
    """How many processes share a cold compile of n_warm_ups warm-ups: PROCESSES_ENV if set
    (an integer >= 1), else the CPU count, at most COMPILE_PROCESSES_MAX; 1 where helpers
    cannot start the same engine (no Python interpreter as sys.executable, an engine
    imported from a zip)."""
    want = os.environ.get(PROCESSES_ENV, "").strip()
    if want:
        try:
            n = max(1, int(want))
        except ValueError:
            raise ValueError(f"{PROCESSES_ENV}={want!r}: expected a whole number >= 1") from None
    else:
        n = min(os.cpu_count() or 1, COMPILE_PROCESSES_MAX)
    if not _can_start_helpers():
        return 1
    return max(1, min(n, n_warm_ups))


def _can_start_helpers() -> bool:
    exe = os.path.basename(sys.executable or "").lower()
    if not exe.startswith("python"):
        return False  # (Blender's own binary in builds that do not point it at Python)
    return os.path.isfile(os.path.join(os.path.dirname(__file__), "jit.py"))


def claim(folder: str, i: int) -> bool:
    """True if this process takes warm-up i (the first to create its claim file)."""
    try:
        os.close(os.open(os.path.join(folder, f"claim-{i}"),
                         os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        return True
    except FileExistsError:
        return False


def done_count(folder: str) -> int:
    """How many warm-ups have finished in any process."""
    try:
        return sum(name.startswith("done-") for name in os.listdir(folder))
    except OSError:
        return 0


def run_claimed(jobs, folder: str, on_done=None, deps=None) -> list[int]:
    """Run each of jobs (callables; every process holds the same list) this process claims
    in `folder` (by position; the first claimable in list order); mark each finished one
    ("done-j"). deps: per job the positions whose machine code it reuses (job_dependencies):
    a job is claimed once they are done (else two processes would compile the shared
    kernels twice), or after DEPENDENCY_WAIT_S of waiting (their process may have died:
    then compiling them again is only slower). on_done(): after each. Returns the
    positions run here."""
    deps = deps or [()] * len(jobs)
    ran = []
    pending = list(range(len(jobs)))
    waited_since = None
    while pending:
        taken = None
        patient = waited_since is None or time.monotonic() - waited_since < DEPENDENCY_WAIT_S
        for j in pending:
            if os.path.exists(os.path.join(folder, f"claim-{j}")):
                taken = j  # someone else's: drop it
                break
            ready = all(os.path.exists(os.path.join(folder, f"done-{d}")) for d in deps[j])
            if (ready or not patient) and claim(folder, j):
                jobs[j]()
                open(os.path.join(folder, f"done-{j}"), "w").close()
                ran.append(j)
                if on_done is not None:
                    on_done()
                taken = j
                break
        if taken is not None:
            pending.remove(taken)
            waited_since = None
        else:
            waited_since = waited_since or time.monotonic()
            time.sleep(0.05)
    return ran


def job_dependencies(jobs, registered) -> list[tuple]:
    """Per job (warm-ups in the shared order), the positions of the jobs whose module its
    module uses (a kernel module, or a kernel, among its globals) and that were
    registered before it (registered: jit's list, in import order: a module imports what
    it calls before it registers its own warm-up, so this order has no cycles)."""
    import types
    rank = {id(fn): r for r, fn in enumerate(registered)}
    position = {}
    for j, fn in enumerate(jobs):
        position.setdefault(fn.__module__, []).append(j)
    out = []
    for fn in jobs:
        module = sys.modules.get(fn.__module__)
        used = set()
        for value in vars(module).values() if module is not None else ():
            if isinstance(value, types.ModuleType):
                used.add(value.__name__)
            elif hasattr(value, "py_func"):
                used.add(getattr(value.py_func, "__module__", None))
        used.discard(fn.__module__)
        mine = rank.get(id(fn), len(registered))
        out.append(tuple(sorted(j for name in used for j in position.get(name, ())
                                if rank.get(id(jobs[j]), len(registered)) < mine)))
    return out


def warm_up_name(fn) -> str:
    """A warm-up's name, the same in every process that imports the engine alike."""
    return f"{fn.__module__}.{fn.__qualname__}"


def heaviest_first(warm_ups) -> list[int]:
    """Warm-up indices, the longest modules' first (their compile time grows with their
    kernels: the longest jobs first leave the shortest tail)."""
    def size(i):
        module = sys.modules.get(getattr(warm_ups[i], "__module__", ""), None)
        try:
            return os.path.getsize(module.__file__)
        except (AttributeError, OSError, TypeError):
            return 0
    return sorted(range(len(warm_ups)), key=lambda i: (-size(i), i))


def compile_shared(warm_ups, processes: int, progress=None, indices=None, join=True):
    """Compile warm_ups (jit's list) in processes - 1 helper processes and, with join, in
    this one. indices: the positions in warm_ups to share out (default all).
    progress(done, total): as warm-ups finish in any process (called on this thread
    only). Returns (helpers that ran to the end, the positions in warm_ups run here).
    The caller runs every warm-up afterwards (ensure_compiled): it loads what the helpers
    wrote and compiles what they did not."""
    wanted = None if indices is None else set(indices)
    order = [i for i in heaviest_first(warm_ups) if wanted is None or i in wanted]
    jobs = [warm_ups[i] for i in order]
    names = [warm_up_name(fn) for fn in jobs]
    if processes <= 1 or len(order) <= 1 or len(set(names)) < len(names):
        return 0, []
    package = __name__.rpartition(".")[0]
    folder = tempfile.mkdtemp(prefix="photonmap-compile-")
    helpers = []
    total = len(order)
    try:
        env = dict(os.environ)
        env[PROCESSES_ENV] = "1"
        env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
        flags = getattr(subprocess, "CREATE_NO_WINDOW", 0)  # (no console under Windows)
        pkg_dir = os.path.dirname(os.path.abspath(__file__))
        logs = []
        for k in range(processes - 1):
            # stderr to a file: an unread pipe would block a helper that writes much.
            log = open(os.path.join(folder, f"helper-{k}.log"), "w+b")
            try:
                helpers.append(subprocess.Popen(
                    [sys.executable, "-c", _HELPER_CODE, package, pkg_dir, folder,
                     ",".join(names)],
                    # stdin: the pipe whose end tells the helper this process is gone
                    # (watch_parent); written never, closed when the helpers are done.
                    env=env, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                    stderr=log, creationflags=flags))
            except OSError as e:  # (no process may be started here: compile alone)
                log.close()
                warnings.warn(f"Kernel compile helpers could not start ({e}); this process "
                              "compiles them.")
                break
            logs.append(log)
        shown = [-1]

        def report():
            done = done_count(folder)
            if progress is not None and done != shown[0]:
                shown[0] = done
                progress(done, total)

        deps = job_dependencies(jobs, warm_ups)
        ran = run_claimed(jobs, folder, on_done=report, deps=deps) if join else []
        start = time.monotonic()
        # Wait until every warm-up is done (then the helpers' machine code is all saved:
        # a warm-up is marked done after it returns) or every helper has stopped.
        while (done_count(folder) < total and any(h.poll() is None for h in helpers)
               and time.monotonic() - start < HELPER_TIMEOUT_S):
            time.sleep(0.25)
            report()
        finished = 0
        for h, log in zip(helpers, logs):
            try:
                h.wait(timeout=2.0)  # (the interpreter's exit)
            except subprocess.TimeoutExpired:
                h.kill()
                h.wait()
            if h.returncode == 0 or done_count(folder) == total:
                finished += 1
            else:
                log.seek(0)
                tail = log.read()[-600:].decode("utf-8", "replace").strip()
                warnings.warn(f"A kernel compile helper stopped (exit code {h.returncode}); "
                              f"this process compiles its share. {tail}")
            log.close()
        report()
        here = [order[j] for j in ran]
        LAST_RUN.update(processes=processes, helpers_finished=finished, jobs=total,
                        run_here=len(here))
        return finished, here
    finally:
        for h in helpers:
            if h.poll() is None:
                h.kill()
                h.wait()
            try:
                h.stdin.close()
            except OSError:
                pass
        shutil.rmtree(folder, ignore_errors=True)


def helper_main(package: str, pkg_dir: str, folder: str, names: str) -> None:
    """A helper process: import the engine as `package` from pkg_dir (its parent packages
    stubbed, so that no add-on code runs: the kernels' module names, and so their cached
    machine code, are the caller's), then run the warm-ups it claims. Ends as soon as its
    caller is gone (watch_parent)."""
    watch_parent()
    import importlib
    import types
    parts = package.split(".")
    if len(parts) == 1:
        sys.path.insert(0, os.path.dirname(pkg_dir))
    for k in range(1, len(parts)):
        name = ".".join(parts[:k])
        if name not in sys.modules:
            here = pkg_dir
            for _ in range(len(parts) - k):
                here = os.path.dirname(here)
            stub = types.ModuleType(name)
            stub.__path__ = [here]
            sys.modules[name] = stub
    jit = importlib.import_module(package + ".jit")
    jit._import_kernel_modules()
    mine = {warm_up_name(fn): fn for fn in jit._warm_ups}
    # (A name this process lacks is left to the caller, which runs every warm-up.)
    jobs = [mine.get(name, _nothing) for name in names.split(",") if name]
    run_claimed(jobs, folder, deps=job_dependencies(jobs, jit._warm_ups))


def _nothing():
    pass


# A helper's exit status when its caller died (the caller, if alive, would report it).
PARENT_GONE_EXIT = 3


def watch_parent(stream=None) -> threading.Thread:
    """In a helper: a daemon thread that reads `stream` (default: this process's stdin,
    the pipe compile_shared holds open and never writes) until its end, which comes when
    the caller closes it or dies, and then ends this process at once (os._exit: a compile
    in progress is dropped; numba writes its cache files whole, by a replace, and the
    save lock this process holds is released first). Returns the thread."""
    fd = (stream if stream is not None else sys.stdin).fileno()

    def watch():
        try:
            while os.read(fd, 4096):
                pass
        except OSError:
            pass  # (a closed or broken pipe: its caller is gone as well)
        # Release the save lock held here, if any (another process may wait on it): the
        # saves lock through the engine's own copy of this module (install_save_lock),
        # which a helper imports besides the copy it runs (_HELPER_CODE).
        for name, module in list(sys.modules.items()):
            if name.endswith("compilepool"):
                for path in list(getattr(module, "_HELD_LOCKS", ())):
                    try:
                        os.unlink(path)
                    except OSError:
                        pass
        os._exit(PARENT_GONE_EXIT)

    thread = threading.Thread(target=watch, daemon=True, name="compile helper: caller alive")
    thread.start()
    return thread


_HELPER_CODE = (
    "import os, sys\n"
    "package, pkg_dir = sys.argv[1], sys.argv[2]\n"
    # Load this module by its file (its package's __init__ may import the add-on).
    "import importlib.util as u\n"
    "spec = u.spec_from_file_location('_photonmap_compilepool', os.path.join(pkg_dir, 'compilepool.py'))\n"
    "m = u.module_from_spec(spec); spec.loader.exec_module(m)\n"
    "m.helper_main(*sys.argv[1:5])\n"
)


_LOCK_GUARD = threading.Lock()


def install_save_lock(cache_root: str) -> None:
    """Make numba's cache saves under cache_root hold a lock file of their cache folder
    (module docstring); other folders' saves are unchanged. numba's method is wrapped
    once per process, whatever copies of the engine are imported (their roots are
    added to the one wrapper's: a second wrapper would wait on the first's lock)."""
    with _LOCK_GUARD:
        from numba.core import caching
        current = caching.IndexDataCacheFile.save
        roots = getattr(current, "photonmap_roots", None)
        if roots is None:
            original = current
            roots = set()

            def save(self, key, data):
                path = os.path.normcase(os.path.abspath(self._cache_path))
                if not any(path == r or path.startswith(r + os.sep) for r in roots):
                    return original(self, key, data)
                with folder_lock(self._cache_path):
                    return original(self, key, data)

            save.__wrapped__ = original
            save.photonmap_roots = roots
            caching.IndexDataCacheFile.save = save
        roots.add(os.path.normcase(os.path.abspath(cache_root)))


# The lock files this process holds (a helper whose caller died releases them as it ends).
_HELD_LOCKS: set = set()


class folder_lock:
    """An inter-process lock: the file `.save.lock` in folder, created exclusively; a
    lock older than STALE_LOCK_S is taken over (its holder died). Threads of one process
    also wait on it (the file is the lock)."""

    def __init__(self, folder: str):
        self.path = os.path.join(folder, ".save.lock")

    def __enter__(self):
        delay = 0.001
        while True:
            try:
                os.close(os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
                _HELD_LOCKS.add(self.path)
                return self
            except FileExistsError:
                try:
                    if time.time() - os.path.getmtime(self.path) > STALE_LOCK_S:
                        os.unlink(self.path)
                        continue
                except OSError:
                    continue  # released meanwhile
                time.sleep(delay)
                delay = min(delay * 2, 0.05)

    def __exit__(self, *exc):
        _HELD_LOCKS.discard(self.path)
        try:
            os.unlink(self.path)
        except OSError:
            pass
        return False
