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
import json, os, sys
from engine import compilepool, jit
jit._import_kernel_modules()
names = sys.argv[2].split(",")
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
        if not name.startswith("engine") or module is None:
            continue
        for value in vars(module).values():
            if isinstance(value, numba.core.registry.CPUDispatcher) and value.signatures:
                hits += sum(value.stats.cache_hits.values())
                misses += sum(value.stats.cache_misses.values())
    print(json.dumps({"hits": hits, "misses": misses}))
"""

# Small warm-ups (a few CPU seconds together).
_SMALL = ("engine.normalmap._warm_up", "engine.rayoffset._warm_up", "engine.lights.point._warm_up")


def _run(tmp_path, *args):
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    env.pop(compilepool.PROCESSES_ENV, None)
    res = subprocess.run([sys.executable, "-c", _SCRIPT, *args], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("join", ["helpers only", "join"])
def test_a_helper_compiles_what_a_later_process_loads(tmp_path, join):
    """compile_shared in a fresh cache folder (a helper process, and with join the calling
    one too), then a new process runs the same warm-ups: every kernel comes from the
    cache, none is compiled again."""
    got = _run(tmp_path, "compile", ",".join(_SMALL), join)
    assert got["helpers"] == 1
    if join == "join":
        assert set(got["here"]) <= set(got["picked"])
    else:
        assert got["here"] == []  # the helper did them all
    loaded = _run(tmp_path, "load", ",".join(_SMALL))
    assert loaded["misses"] == 0 and loaded["hits"] > 0, loaded
