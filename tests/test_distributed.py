"""Progressive passes on Dask (engine/distributed.py): bitwise the single-machine image,
whatever the workers and the order they finish in; budgets, cancel, a killed worker."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from engine import RenderSettings  # noqa: E402
from engine.api import cornell_box  # noqa: E402
from engine.distributed import missing_packages, parse_address, render_distributed  # noqa: E402
from engine.progressive import Budget, render_progressive  # noqa: E402
from engine.scene import SceneError  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CHEAP = dict(spp=1, photons=3000, caustic_photons=1500, seed=5)
BUFFERS = ("direct", "indirect", "caustic", "specular", "emission", "alpha", "normal", "depth",
           "photon_hits")


def assert_bitwise(a, b):
    for name in BUFFERS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert x.tobytes() == y.tobytes(), f"{name} differs"


@pytest.fixture(scope="module")
def client():
    """One LocalCluster of 2 worker processes (127.0.0.1 only) for the whole module."""
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def small():
    scene = cornell_box(24, 18)
    settings = RenderSettings(**CHEAP)
    return scene, settings, render_progressive(scene, settings, Budget(passes=5))


def test_same_image_as_local(client, small):
    scene, settings, local = small
    film = render_distributed(scene, settings, Budget(passes=5), client=client, worker_threads=1)
    assert_bitwise(film, local)
    assert film.stats["passes"] == 5 and len(film.stats["pass_log"]) == 5
    assert film.stats["error_estimate"] == local.stats["error_estimate"]
    assert film.stats["photons_total"] == local.stats["photons_total"]
    assert film.stats["effects"] == local.stats["effects"]
    assert film.warnings == local.warnings
    # The workers closed their prepared contexts when the render ended.
    idle = client.run(lambda dask_worker: sum(
        len(v) for v in vars(dask_worker).get("_photonmap_contexts", {}).get("idle", {}).values()))
    assert set(idle.values()) == {0}


def test_cryptomatte_as_local(client):
    """The mattes come from pass 1 on a worker as locally (engine/cryptomatte.py)."""
    from dataclasses import replace
    scene = cornell_box(24, 18)
    settings = replace(RenderSettings(**CHEAP), cryptomatte=("object", "material"))
    local = render_progressive(scene, settings, Budget(passes=2))
    film = render_distributed(scene, settings, Budget(passes=2), client=client,
                              worker_threads=1)
    assert set(film.cryptomatte) == {"object", "material"}
    for kind, passes in local.cryptomatte.items():
        for a, b in zip(passes, film.cryptomatte[kind]):
            assert a.tobytes() == b.tobytes(), kind
    assert film.cryptomatte_names == local.cryptomatte_names
    assert_bitwise(film, local)


def test_shadow_catcher_as_local(client):
    """A shadow catcher's sums (engine/shadowcatcher.py: the camera pass' split and the
    catchers-alone pass of each pass) travel with the pass films: the same bits."""
    from engine.shadowcatcher import combined_rgba
    scene = cornell_box(24, 18)
    scene.meshes[0].shadow_catcher = True  # the floor
    settings = RenderSettings(**CHEAP)
    local = render_progressive(scene, settings, Budget(passes=2))
    film = render_distributed(scene, settings, Budget(passes=2), client=client,
                              worker_threads=1)
    assert_bitwise(film, local)
    assert set(film.catcher) == set(local.catcher)
    for key, value in local.catcher.items():
        assert value.tobytes() == film.catcher[key].tobytes(), key
    assert combined_rgba(film, False).tobytes() == combined_rgba(local, False).tobytes()


def test_same_image_one_pass_in_flight_and_other_thread_count(client, small):
    """Passes strictly one after another, and two engine threads per pass instead of one:
    the same bits."""
    scene, settings, local = small
    film = render_distributed(scene, settings, Budget(passes=5), client=client,
                              worker_threads=2, max_in_flight=1)
    assert_bitwise(film, local)


def test_adaptive_sampling_is_off_in_the_passes_and_said_as_locally(client, small):
    """Noise Threshold is the plain render's: on a cluster, as in local progressive
    passes, the passes take all their samples (the same bits) and the user is told."""
    from dataclasses import replace

    from engine.progressive import ADAPTIVE_WARNING
    scene, settings, local = small
    said = []
    film = render_distributed(scene, replace(settings, adaptive_threshold=0.01),
                              Budget(passes=2), client=client, worker_threads=1,
                              on_warning=said.append)
    two = render_progressive(scene, replace(settings, adaptive_threshold=0.01), Budget(passes=2))
    assert_bitwise(film, two)
    assert ADAPTIVE_WARNING in film.warnings and ADAPTIVE_WARNING in two.warnings
    assert said.count(ADAPTIVE_WARNING) == 1


def test_on_pass_sees_the_running_average_in_pass_order(client, small):
    scene, settings, _ = small
    seen_local, seen_dask = [], []
    render_progressive(scene, settings, Budget(passes=3),
                       on_pass=lambda f, i: seen_local.append((i["passes"], f.combined.copy())))
    render_distributed(scene, settings, Budget(passes=3), client=client,
                       on_pass=lambda f, i: seen_dask.append((i["passes"], f.combined.copy())))
    assert [p for p, _ in seen_dask] == [1, 2, 3]
    for (_, a), (_, b) in zip(seen_local, seen_dask):
        assert a.tobytes() == b.tobytes()


def test_out_of_order_completion_is_merged_in_pass_order(monkeypatch):
    """Pass 1 is held back until passes 2 and 3 are done (threads of this process, so the
    patched render_pass is what the workers run); the image is still the local one."""
    import engine.distributed as dist
    scene = cornell_box(16, 12)
    settings = RenderSettings(**CHEAP)
    local = render_progressive(scene, settings, Budget(passes=3))
    first_seed = settings.seed * 1_000_003 + 1
    done = []
    real = dist.render_pass

    def held_back(ctx, region, progress=None, should_cancel=None, **kw):
        if ctx.settings.seed == first_seed:
            t0 = time.perf_counter()
            while len(done) < 2 and time.perf_counter() - t0 < 30:  # poll, no fixed sleep
                time.sleep(0.01)
        film = real(ctx, region, progress, should_cancel, **kw)
        done.append(ctx.settings.seed)
        return film

    monkeypatch.setattr(dist, "render_pass", held_back)
    with distributed.LocalCluster(n_workers=3, threads_per_worker=1, processes=False,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as c:
        film = render_distributed(scene, settings, Budget(passes=3), client=c, worker_threads=1)
    assert done[-1] == first_seed, "pass 1 did not finish last"
    assert_bitwise(film, local)


def _warning_scene(tmp_path):
    """tests/test_cli_output.py's scene that warns (the scene's two, the effect
    analysis' with max_depth 1) with a search radius of 0.01 m (the photon pass')."""
    from test_cli_output import SCENE

    from engine.scenefile import load_scene
    path = tmp_path / "warns.toml"
    path.write_text(SCENE, encoding="utf-8")
    scene, overrides = load_scene(str(path))
    return scene, RenderSettings(**dict(overrides, max_depth=1, radius=0.01, workers=1))


def _until(done, seconds=30.0):
    t0 = time.perf_counter()
    while not done() and time.perf_counter() - t0 < seconds:  # poll, no fixed sleep
        time.sleep(0.01)
    return done()


def test_workers_warnings_reach_on_warning_while_the_pass_runs(monkeypatch, tmp_path):
    """The effect analysis' warning reaches the client's on_warning before pass 1 starts
    its photons, the search radius' before its camera pass (each pass waits for them:
    the workers post them, engine/distributed.py run_pass); each once over 3 passes, all
    before the first progress call; film.warnings as render_progressive lists them."""
    import engine.distributed as dist
    scene, settings = _warning_scene(tmp_path)
    local = render_progressive(scene, settings, Budget(passes=3))
    assert any(w.startswith("Max Ray Depth 1") for w in local.warnings), local.warnings
    assert any(w.startswith("search radius 0.01 m") for w in local.warnings), local.warnings
    events, held = [], {"effects": [], "radius": []}
    real = dist.render_pass

    def told(start):
        return any(kind == "warning" and text.startswith(start) for kind, text in events)

    def waits_for_the_client(ctx, region, progress=None, should_cancel=None, on_warning=None,
                             **kw):
        held["effects"].append(_until(lambda: told("Max Ray Depth 1")))

        def posted(text):  # the radius warning: the camera pass waits until it is told
            on_warning(text)
            held["radius"].append(_until(lambda: told(text[:40])))
        return real(ctx, region, progress, should_cancel, on_warning=posted, **kw)

    monkeypatch.setattr(dist, "render_pass", waits_for_the_client)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as c:
        film = render_distributed(scene, settings, Budget(passes=3), client=c, worker_threads=1,
                                  progress=lambda *a: events.append(("progress", a[2])),
                                  on_warning=lambda text: events.append(("warning", text)))
    # Every pass waited for both, each wait ended by the warning told (none timed out).
    assert held == {"effects": [True] * 3, "radius": [True] * 3}, held
    said = [text for kind, text in events if kind == "warning"]
    assert sorted(said) == sorted(film.warnings) and len(set(said)) == len(said), events
    first = next(i for i, (kind, _) in enumerate(events) if kind == "progress")
    assert all(kind == "progress" for kind, _ in events[first:]), events
    assert film.warnings == local.warnings
    assert_bitwise(film, local)


def test_a_later_pass_told_first_is_still_one_warning(monkeypatch, tmp_path):
    """Two workers; pass 1 starts only once pass 2's search-radius warning was told: the
    client tells it in pass 2's words (its own photon count), film.warnings lists pass 1's,
    the same warning by render.warning_key, by which the front ends print each once
    (engine/cli.py, addon/engine.py)."""
    import engine.distributed as dist
    from engine.render import warning_key
    scene, settings = _warning_scene(tmp_path)
    first_seed = settings.seed * 1_000_003 + 1
    said, waited = [], []
    real = dist.render_pass

    def radius_told():
        return any(text.startswith("search radius 0.01 m") for text in said)

    def pass_2_first(ctx, region, *args, **kw):
        if ctx.settings.seed == first_seed:
            waited.append(_until(radius_told))
        return real(ctx, region, *args, **kw)

    monkeypatch.setattr(dist, "render_pass", pass_2_first)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as c:
        film = render_distributed(scene, settings, Budget(passes=2), client=c, worker_threads=1,
                                  on_warning=said.append)
    assert waited == [True], waited
    radius = [w for w in said if w.startswith("search radius")]
    listed = [w for w in film.warnings if w.startswith("search radius")]
    assert len(radius) == 1 and len(listed) == 1, (said, film.warnings)
    assert warning_key(radius[0]) == warning_key(listed[0])
    assert sorted(map(warning_key, said)) == sorted(map(warning_key, film.warnings))


def test_pass_and_error_budgets_stop_where_local_stops(client):
    scene = cornell_box(16, 12)
    settings = RenderSettings(**CHEAP)
    budget = Budget(target_error=0.05, passes=40)
    local = render_progressive(scene, settings, budget)
    film = render_distributed(scene, settings, budget, client=client)
    assert film.stats["passes"] == local.stats["passes"]
    assert_bitwise(film, local)


def test_time_budget(client):
    scene = cornell_box(16, 12)
    t0 = time.perf_counter()
    film = render_distributed(scene, RenderSettings(**CHEAP), Budget(seconds=2.0), client=client)
    elapsed = time.perf_counter() - t0
    assert film.stats["passes"] >= 1  # the first pass always (as render_progressive)
    first = film.stats["pass_log"][0]["elapsed"]
    # After the first pass the client stops waiting at the deadline (slack: a loaded machine).
    assert elapsed < max(2.0, first) + 3.0
    _wait_until_idle(client)


def _wait_until_idle(client, timeout=30.0):
    """Poll the scheduler until it holds no task (cancelled passes were dropped)."""
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < timeout:
        n = client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks))
        if n == 0:
            return
        time.sleep(0.05)
    raise AssertionError(f"{n} tasks still on the scheduler after {timeout} s")


def test_cancel_drops_pending_passes(client, small):
    scene, settings, _ = small
    state = {"passes": 0}
    film = render_distributed(scene, settings, Budget(passes=40), client=client,
                              should_cancel=lambda: state["passes"] >= 2,
                              on_pass=lambda f, i: state.update(passes=i["passes"]))
    assert film.stats["cancelled"] and 2 <= film.stats["passes"] < 40
    local = render_progressive(scene, settings, Budget(passes=film.stats["passes"]))
    assert_bitwise(film, local)
    _wait_until_idle(client)



def test_engine_under_an_extension_name_is_shipped(client, small, tmp_path, monkeypatch):
    """Inside Blender the engine is bl_ext.<repo>.<id>.engine, a name no worker can import:
    the client uploads the engine (ship_engine_code) and the image is still the local one."""
    import importlib
    package = "bl_ext_t.user_default.photonmap"
    for depth, part in enumerate(package.split(".")):
        d = tmp_path.joinpath(*package.split(".")[:depth + 1])
        d.mkdir()
        (d / "__init__.py").write_text("")
    os.symlink(os.path.join(ROOT, "engine"), tmp_path.joinpath(*package.split("."), "engine"))
    spec = "importlib.util.find_spec('bl_ext_t') is not None"
    assert not any(client.run(eval, spec, {"importlib": importlib}).values())
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        ext = importlib.import_module(package + ".engine")
        dist = importlib.import_module(package + ".engine.distributed")
        scene = importlib.import_module(package + ".engine.api").cornell_box(24, 18)
        film = dist.render_distributed(scene, ext.RenderSettings(**CHEAP), ext.Budget(passes=5),
                                       client=client, worker_threads=1)
        assert type(film).__module__ == package + ".engine.film"
        assert_bitwise(film, small[2])
        assert all(client.run(eval, spec, {"importlib": importlib}).values())  # uploaded
        # The workers share this machine: they import the client's own files (the symlink's
        # target) under the extension's name, so numba loads the kernels compiled here
        # (shippedengine.local_shim) instead of compiling them in each worker.
        jit_file = f"__import__('sys').modules['{package}.engine.jit'].__file__"
        where = set(client.run(eval, jit_file).values())
        assert where == {os.path.join(os.path.realpath(ROOT), "engine", "jit.py")}, where
        client.restart()
        again = dist.render_distributed(scene, ext.RenderSettings(**CHEAP), ext.Budget(passes=5),
                                        client=client, worker_threads=1)
        assert_bitwise(again, small[2])
        assert set(client.run(eval, jit_file).values()) == where
    finally:
        for name in [n for n in sys.modules if n.startswith("bl_ext_t")]:
            del sys.modules[name]


def test_killed_worker_loses_nothing():
    """SIGKILL a worker process while it holds a pass: the scheduler gives the pass to
    the other worker and the image is unchanged. The test has its own cluster: the
    module's would need the nanny's restart of the killed worker (60-70 s on a loaded
    2-core machine, and on CI once never: the nanny was closed while restarting and
    wait_for_workers(2) timed out after 240 s)."""
    # Passes long enough (~0.5 s each) that the scheduler is seen running one, also on a
    # machine where a 32x24 pass ended between two polls.
    scene = cornell_box(64, 48)
    settings = RenderSettings(spp=8, photons=40000, caustic_photons=10000, seed=3)
    budget = Budget(passes=4)
    local = render_progressive(scene, settings, budget)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        killed, film = _render_killing_a_busy_worker(client, scene, settings, budget)
    assert killed, "no pass was ever seen running"
    assert film.stats["passes"] == 4
    assert_bitwise(film, local)


def _render_killing_a_busy_worker(client, scene, settings, budget):
    """render_distributed on client, SIGKILLing the first worker seen running a pass.
    Returns (addresses killed, film)."""
    pids = client.run(os.getpid)  # worker address -> process id
    killed = []

    def kill_a_busy_worker():
        if not killed:
            busy = client.run_on_scheduler(
                lambda dask_scheduler: [ws.address for ws in dask_scheduler.workers.values()
                                        if any(ts.key.startswith("photonmap-")
                                               for ts in ws.executing)])
            if busy and busy[0] in pids:
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(busy[0])
        return False

    film = render_distributed(scene, settings, budget, client=client, worker_threads=1,
                              should_cancel=kill_a_busy_worker)
    return killed, film


def test_lost_scene_is_scattered_again(client, small):
    """Dask's active memory manager keeps one copy of a broadcast scene where no queued task
    needs more, and that copy can die with its worker (CI saw every pass cancelled, "already
    forgotten"). Here the scene's key is force-cancelled on the scheduler once pass 1 is
    merged: the client scatters the scene again, resubmits the cancelled passes, and the
    image is still the local one."""
    scene, settings, local = small
    dropped = []

    def drop_the_scene(film, info):
        if not dropped:
            keys = client.run_on_scheduler(lambda dask_scheduler: [
                k for k in dask_scheduler.tasks if str(k).startswith("PaperScene-")])
            assert len(keys) == 1, keys
            client.cancel([distributed.Future(keys[0], client)], force=True)
            dropped.append(keys[0])

    film = render_distributed(scene, settings, Budget(passes=5), client=client,
                              worker_threads=1, max_in_flight=2, on_pass=drop_the_scene)
    assert dropped and film.stats["passes"] == 5
    assert_bitwise(film, local)
    _wait_until_idle(client)


def test_shipped_engine_unpacks_once_complete_and_private(tmp_path, monkeypatch):
    """shippedengine.unpack: two processes unpacking one zip at once leave one complete
    folder with the zip's modification times; a folder cut short (no marker) is unpacked
    again; a folder other users may write is not trusted (a private one instead).
    shippedengine.local_shim: the client's own folder, unchanged, imported in place."""
    import zipfile
    from engine import shippedengine
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr(shippedengine.tempfile, "tempdir", None)
    src = tmp_path / "engine.zip"
    with zipfile.ZipFile(src, "w") as z:
        info = zipfile.ZipInfo("pkg/engine/jit.py", date_time=(2020, 1, 2, 3, 4, 6))
        z.writestr(info, "X = 1\n")
    data = src.read_bytes()
    code = ("import sys; sys.path.insert(0, %r); from engine import shippedengine; "
            "print(shippedengine.unpack(open(%r, 'rb').read(), 'photonmap_engine_t'))"
            % (ROOT, str(src)))
    env = dict(os.environ, TMPDIR=str(tmp_path))
    runs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                             text=True) for _ in range(2)]
    roots = {r.communicate(timeout=120)[0].strip() for r in runs}
    assert all(r.returncode == 0 for r in runs)
    assert len(roots) == 1
    root = roots.pop()
    jit = os.path.join(root, "pkg", "engine", "jit.py")
    assert open(jit).read() == "X = 1\n"
    assert os.path.getmtime(jit) == time.mktime((2020, 1, 2, 3, 4, 6, 0, 0, -1))
    assert sorted(os.listdir(os.path.dirname(root))) == ["photonmap_engine_t"]  # no scratch
    os.remove(os.path.join(root, shippedengine.COMPLETE))
    os.remove(jit)
    assert shippedengine.unpack(data, "photonmap_engine_t") == root and os.path.isfile(jit)
    # The client's own folder, found unchanged here: a shim imports its files by the
    # package's name; a folder with other contents (another machine's) is not used.
    source = tmp_path / "ext" / "engine"
    source.mkdir(parents=True)
    (source / "__init__.py").write_text("")
    (source / "jit.py").write_text("X = 2\n")
    name = "photonmap_engine_" + shippedengine.engine_digest(str(source), "pkgx.sub.engine")
    shim = shippedengine.local_shim(str(source), "pkgx.sub.engine", name)
    imported = subprocess.run(
        [sys.executable, "-c", "import sys; sys.path.insert(0, %r); import pkgx.sub.engine.jit as j;"
         " print(j.__file__, j.X)" % shim], capture_output=True, text=True, timeout=60)
    assert imported.stdout.split() == [str(source / "jit.py"), "2"], imported.stderr
    assert shippedengine.local_shim(str(source), "pkgx.sub.engine",
                                    "photonmap_engine_" + "0" * 16) is None
    (source / "jit.py").write_text("X = 3\n")  # edited: no longer the shipped engine
    assert shippedengine.local_shim(str(source), "pkgx.sub.engine", name) is None
    if hasattr(os, "getuid"):
        os.chmod(os.path.dirname(root), 0o777)
        other = shippedengine.unpack(data, "photonmap_engine_t")
        assert other != root and not other.startswith(os.path.dirname(root) + os.sep)
        assert os.path.isfile(os.path.join(other, "pkg", "engine", "jit.py"))


def test_cancel_stops_a_running_pass(monkeypatch):
    """Pass 2 runs until its should_cancel turns True (threads of this process, so the
    patched render_pass is what the workers run): cancelling the render after pass 1 must
    reach it through end_render."""
    import engine.distributed as dist
    settings = RenderSettings(**CHEAP)
    second_seed = settings.seed * 1_000_003 + 2
    seen = {}
    real = dist.render_pass

    def endless_second_pass(ctx, region, progress=None, should_cancel=None, **kw):
        if ctx.settings.seed == second_seed:
            t0 = time.perf_counter()
            while not should_cancel() and time.perf_counter() - t0 < 30:
                time.sleep(0.01)
            seen["stopped"] = should_cancel()
        return real(ctx, region, progress, should_cancel, **kw)

    monkeypatch.setattr(dist, "render_pass", endless_second_pass)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as c:
        state = {"passes": 0}
        film = render_distributed(cornell_box(16, 12), settings, Budget(passes=2), client=c,
                                  worker_threads=1,
                                  should_cancel=lambda: state["passes"] >= 1,
                                  on_pass=lambda f, i: state.update(passes=i["passes"]))
        t0 = time.perf_counter()
        while "stopped" not in seen and time.perf_counter() - t0 < 30:
            time.sleep(0.01)
    assert film.stats["cancelled"] and film.stats["passes"] == 1
    assert seen.get("stopped") is True


def test_end_render_stops_running_passes_and_closes_contexts():
    """What Client.run(end_render) does on a worker: the running pass's should_cancel
    turns True and the idle prepared contexts of that render are closed."""
    from types import SimpleNamespace

    import engine.distributed as dist
    from engine.render import prepare_context
    worker = SimpleNamespace()
    cache = dist._cache(worker)
    should_cancel = dist._stop_flag(cache, "render-a")
    other = dist._stop_flag(cache, "render-b")
    cache["key"] = "render-a"
    cache["idle"]["render-a"] = [prepare_context(cornell_box(8, 6), RenderSettings(**CHEAP))]
    assert not should_cancel()
    assert dist.end_render("render-a", dask_worker=worker) == 1
    assert should_cancel() and not other()
    assert cache["idle"] == {} and cache["key"] is None
    assert dist._stop_flag(None, "render-a") is None  # outside a worker: nothing to poll


def test_parse_address():
    assert parse_address("local:3") == ("local", 3)
    assert parse_address(" tcp://127.0.0.1:8786 ") == ("scheduler", "tcp://127.0.0.1:8786")
    for bad in ("local:0", "local:", "local:two", "127.0.0.1:8786", "", "tcp://"):
        with pytest.raises(ValueError, match="dask address"):
            parse_address(bad)


def test_missing_dask_is_named(monkeypatch):
    import importlib.util

    import engine.distributed as dist
    assert missing_packages() == []
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "distributed" else real(name, *a))
    assert dist.missing_packages() == ["distributed"]
    with pytest.raises(ImportError, match="distributed.*pip install"):
        render_distributed(cornell_box(8, 6), address="local:1")


def test_scheduler_without_workers_is_an_error(monkeypatch):
    import engine.distributed as dist
    monkeypatch.setattr(dist, "WORKER_WAIT_SECONDS", 0.5)
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as c:
        with pytest.raises(ValueError, match="has no workers"):
            render_distributed(cornell_box(8, 6), RenderSettings(**CHEAP), client=c)


def test_bad_scene_is_reported_before_shipping(client):
    scene = cornell_box(8, 6)
    scene.camera = None
    with pytest.raises(SceneError):
        render_distributed(scene, RenderSettings(**CHEAP), Budget(passes=1), client=client)


def test_cli_dask_writes_the_local_image(tmp_path):
    """`photonmap render --dask local:1` writes the image render_progressive makes of the
    same file and options."""
    from engine.scenefile import load_scene
    path = os.path.join(ROOT, "scenes", "figure3.toml")
    out = tmp_path / "dask.npy"
    r = subprocess.run([sys.executable, "-m", "engine.cli", "render", path, "--passes", "2",
                        "--spp", "1", "--photons", "2000", "--caustic-photons", "500",
                        "--width", "24", "--height", "18", "--quiet", "--dask", "local:1",
                        "-o", str(out)], cwd=ROOT, env=dict(os.environ, PYTHONPATH=ROOT),
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    scene, overrides = load_scene(path)
    scene.width, scene.height = 24, 18
    overrides.update(spp=1, photons=2000, caustic_photons=500)
    local = render_progressive(scene, RenderSettings(**overrides), Budget(passes=2))
    assert np.load(out).tobytes() == local.combined.tobytes()


def test_cli_bad_address_is_one_line():
    from engine.cli import main
    path = os.path.join(ROOT, "scenes", "figure3.toml")
    assert main(["render", path, "-o", "x.npy", "--quiet", "--dask", "127.0.0.1:8786"]) == 1
