"""The cold compile shared by processes (engine/compilepool.py): the warm-ups are split
between the processes without overlap or gap, a helper's machine code is what a later
process loads (nothing compiled again), and numba's cache saves under our folders are
serialised so that concurrent writers keep every signature's own code."""
import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from engine import compilepool

ROOT = Path(__file__).resolve().parent.parent


def test_claims_give_each_job_to_exactly_one_runner(tmp_path):
    ran = {name: [] for name in ("a", "b", "c")}
    jobs = [lambda j=j: None for j in range(40)]
    barrier = threading.Barrier(3)

    def runner(name):
        barrier.wait()
        ran[name] = compilepool.run_claimed(jobs, str(tmp_path))

    threads = [threading.Thread(target=runner, args=(n,)) for n in ran]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    every = sorted(j for got in ran.values() for j in got)
    assert every == list(range(40))
    assert compilepool.done_count(str(tmp_path)) == 40


def test_a_job_waits_for_the_jobs_it_depends_on(tmp_path):
    """Job 2 reuses jobs 0 and 1's kernels: no runner starts it before both are done
    (another runner would compile their kernels again), and every job runs once."""
    import time
    log = []

    def job(j, seconds):
        def run():
            log.append(("start", j, time.monotonic()))
            time.sleep(seconds)
            log.append(("end", j, time.monotonic()))
        return run

    jobs = [job(0, 0.3), job(1, 0.1), job(2, 0.0), job(3, 0.0)]
    deps = [(), (), (0, 1), ()]
    ran = []
    threads = [threading.Thread(target=lambda: ran.extend(
        compilepool.run_claimed(jobs, str(tmp_path), deps=deps))) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(ran) == [0, 1, 2, 3]
    at = {(kind, j): t for kind, j, t in log}
    assert at[("start", 2)] >= max(at[("end", 0)], at[("end", 1)])


def test_dependencies_follow_the_kernel_modules_imports():
    """The engine's warm-ups: the camera kernels wait for the closures they call, and no
    job depends on one registered after it (no cycle)."""
    from engine import jit
    jit._import_kernel_modules()
    jobs = list(jit._warm_ups)
    deps = compilepool.job_dependencies(jobs, jit._warm_ups)
    names = [compilepool.warm_up_name(fn) for fn in jobs]
    cam = names.index("engine.camerakernels._warm_up")
    assert names.index("engine.closures.principled._warm_up") in deps[cam]
    assert all(d < j for j, ds in enumerate(deps) for d in ds)  # (jobs in import order here)


def test_helpers_that_cannot_start_leave_the_compile_to_this_process(monkeypatch):
    """Where no process may be started (a sandbox), the caller runs every warm-up itself
    and says why, instead of failing the render."""
    ran = []

    def first():
        ran.append("first")

    def second():
        ran.append("second")

    def refuse(*args, **kwargs):
        raise PermissionError("not allowed here")

    monkeypatch.setattr(compilepool.subprocess, "Popen", refuse)
    with pytest.warns(UserWarning, match="could not start"):
        helpers, here = compilepool.compile_shared([first, second], 3)
    assert helpers == 0 and sorted(here) == [0, 1] and sorted(ran) == ["first", "second"]


def test_process_count_from_the_environment(monkeypatch):
    monkeypatch.setenv(compilepool.PROCESSES_ENV, "3")
    assert compilepool.compile_processes(10) in (1, 3)  # 1 only without a Python executable
    assert compilepool.compile_processes(2) in (1, 2)
    monkeypatch.setenv(compilepool.PROCESSES_ENV, "1")
    assert compilepool.compile_processes(10) == 1
    monkeypatch.setenv(compilepool.PROCESSES_ENV, "many")
    with pytest.raises(ValueError, match=compilepool.PROCESSES_ENV):
        compilepool.compile_processes(10)
    monkeypatch.delenv(compilepool.PROCESSES_ENV)
    n = compilepool.compile_processes(100)
    assert 1 <= n <= compilepool.COMPILE_PROCESSES_MAX


def test_locked_saves_keep_every_signature(tmp_path):
    """Threads saving different keys of one function's cache at once: each key loads its
    own data (unlocked, numba's save can file two keys under one data name)."""
    from numba.core.caching import IndexDataCacheFile
    compilepool.install_save_lock(str(tmp_path))
    folder = tmp_path / "kernels"
    folder.mkdir()
    cache = IndexDataCacheFile(str(folder), "module.kernel-1.py311", ("stamp", 1))
    keys = [f"sig{i}" for i in range(48)]
    barrier = threading.Barrier(8)

    def saver(part):
        barrier.wait()
        for key in keys[part::8]:
            cache.save(key, {"code for": key})

    threads = [threading.Thread(target=saver, args=(p,)) for p in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for key in keys:
        assert cache.load(key) == {"code for": key}
    assert not (folder / ".save.lock").exists()


def test_a_stale_lock_is_taken_over(tmp_path):
    lock = tmp_path / ".save.lock"
    lock.write_text("")
    old = os.path.getmtime(lock) - compilepool.STALE_LOCK_S - 5
    os.utime(lock, (old, old))
    with compilepool.folder_lock(str(tmp_path)):
        assert lock.exists()
    assert not lock.exists()


_SCRIPT = r"""
import importlib, json, os, sys, types
package = os.environ["TEST_ENGINE_PACKAGE"]
if package != "engine":  # an installed extension's layout: stub its parent packages
    pkg_dir = os.environ["TEST_ENGINE_DIR"]
    parts = package.split(".")
    for k in range(1, len(parts)):
        here = pkg_dir
        for _ in range(len(parts) - k):
            here = os.path.dirname(here)
        stub = types.ModuleType(".".join(parts[:k]))
        stub.__path__ = [here]
        sys.modules[stub.__name__] = stub
compilepool = importlib.import_module(package + ".compilepool")
jit = importlib.import_module(package + ".jit")
jit._import_kernel_modules()
names = [package + "." + n for n in sys.argv[2].split(",")]
picked = [i for i, fn in enumerate(jit._warm_ups) if compilepool.warm_up_name(fn) in names]
assert len(picked) == len(names), (names, [compilepool.warm_up_name(f) for f in jit._warm_ups])
if sys.argv[1] == "compile":
    helpers, here = compilepool.compile_shared(jit._warm_ups, 2, indices=picked,
                                              join=sys.argv[3] == "join")
    print(json.dumps({"helpers": helpers, "here": here, "picked": picked}))
else:  # load: run the warm-ups, count what came from the cache and what was compiled
    import numba
    for i in picked:
        jit._warm_ups[i]()
    hits = misses = 0
    for name, module in list(sys.modules.items()):
        if not name.startswith(package) or module is None:
            continue
        for value in vars(module).values():
            if isinstance(value, numba.core.registry.CPUDispatcher) and value.signatures:
                hits += sum(value.stats.cache_hits.values())
                misses += sum(value.stats.cache_misses.values())
    print(json.dumps({"hits": hits, "misses": misses}))
"""

# Small warm-ups (a few CPU seconds together).
_SMALL = ("normalmap._warm_up", "rayoffset._warm_up", "lights.point._warm_up")


def _run(tmp_path, package, engine_dir, *args):
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               TEST_ENGINE_PACKAGE=package, TEST_ENGINE_DIR=str(engine_dir))
    env.pop(compilepool.PROCESSES_ENV, None)
    res = subprocess.run([sys.executable, "-c", _SCRIPT, *args], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


# "helpers only" is slow (each case compiles ~9 CPU s): the default run keeps "join" (a
# helper and this process compile, the engine package) and the installed extension's
# test below (the helper alone compiles), which together cover it.
@pytest.mark.parametrize("join", [pytest.param("helpers only", marks=pytest.mark.slow), "join"])
def test_a_helper_compiles_what_a_later_process_loads(tmp_path, join):
    """compile_shared in a fresh cache folder (a helper process, and with join the calling
    one too), then a new process runs the same warm-ups: every kernel comes from the
    cache, none is compiled again."""
    got = _run(tmp_path, "engine", ROOT / "engine", "compile", ",".join(_SMALL), join)
    assert got["helpers"] == 1
    if join == "join":
        assert set(got["here"]) <= set(got["picked"])
    else:
        assert got["here"] == []  # the helper did them all
    loaded = _run(tmp_path, "engine", ROOT / "engine", "load", ",".join(_SMALL))
    assert loaded["misses"] == 0 and loaded["hits"] > 0, loaded


def test_helpers_import_an_installed_extensions_engine_by_its_package_name(tmp_path):
    """Blender imports the installed engine as bl_ext.<repository>.photonmap.engine: the
    helpers import it under that name (parents stubbed; the extension's __init__ needs
    bpy), so the machine code they write is what the caller loads."""
    import shutil
    engine_dir = tmp_path / "extensions" / "user_default" / "photonmap" / "engine"
    shutil.copytree(ROOT / "engine", engine_dir,
                    ignore=shutil.ignore_patterns("__pycache__"))
    package = "bl_ext.user_default.photonmap.engine"
    got = _run(tmp_path, package, engine_dir, "compile", ",".join(_SMALL), "helpers only")
    assert got["helpers"] == 1 and got["here"] == []
    loaded = _run(tmp_path, package, engine_dir, "load", ",".join(_SMALL))
    assert loaded["misses"] == 0 and loaded["hits"] > 0, loaded


def test_a_helper_ends_when_its_callers_pipe_closes():
    """watch_parent: the end of stdin (the caller closed it, or died and the system
    closed it) ends the helper at once, whatever its main thread is doing."""
    code = ("import sys, time\n"
            f"sys.path.insert(0, {str(ROOT)!r})\n"
            "from engine import compilepool\n"
            "compilepool.watch_parent()\n"
            "print('watching', flush=True)\n"
            "time.sleep(120)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "watching"
        assert proc.poll() is None  # an open pipe: the helper works on
        proc.stdin.close()
        assert proc.wait(timeout=10) == compilepool.PARENT_GONE_EXIT
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


_KILLED_PARENT = r"""
import sys
from engine import jit, compilepool
jit._import_kernel_modules()
# Helpers only (join=False): every claim in the compile folder is a helper's.
compilepool.compile_shared(jit._warm_ups, 3, join=False)
"""


def _children(pid):
    """The pids whose parent is pid (Linux /proc)."""
    out = []
    for name in os.listdir("/proc"):
        if name.isdigit():
            try:
                stat = Path("/proc", name, "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(name))
    return out


def _running(pid):
    """pid is a live process (not gone, not a zombie left for its new parent to reap)."""
    try:
        os.kill(pid, 0)
        state = Path("/proc", str(pid), "stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, ProcessLookupError):
        return False
    return state != "Z"


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads /proc (Linux)")
def test_helpers_end_soon_after_their_caller_is_killed(tmp_path):
    """Blender hard-killed (SIGKILL) during the first render's compile: its helpers ran
    on compiling for nobody, up to HELPER_TIMEOUT_S (an hour). They end within seconds."""
    import signal
    import time
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               TMPDIR=str(tmp_path))  # a cold cache: the helpers really compile
    env.pop(compilepool.PROCESSES_ENV, None)
    parent = subprocess.Popen([sys.executable, "-c", _KILLED_PARENT], cwd=ROOT, env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    helpers = []
    try:
        end = time.monotonic() + 120
        # Until a helper has claimed a warm-up (it is compiling), and both are seen.
        while time.monotonic() < end and parent.poll() is None:
            claims = list(tmp_path.glob("photonmap-compile-*/claim-*"))
            helpers = _children(parent.pid)
            if claims and len(helpers) == 2:
                break
            time.sleep(0.1)
        assert parent.poll() is None and len(helpers) == 2 and claims, (
            helpers, parent.stderr.read().decode()[-2000:] if parent.poll() is not None else "")
        assert all(_running(pid) for pid in helpers)
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        end = time.monotonic() + 10
        while time.monotonic() < end and any(_running(pid) for pid in helpers):
            time.sleep(0.1)
        assert not any(_running(pid) for pid in helpers), helpers
    finally:
        for pid in helpers:  # (a failed assertion must not leave them compiling)
            if _running(pid):
                os.kill(pid, signal.SIGKILL)
        if parent.poll() is None:
            parent.kill()
            parent.wait()
