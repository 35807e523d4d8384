"""Progressive passes of one frame on a Dask cluster (Dask distributed).

Every progressive pass is an independent render (its own seed, its own k_i:
engine/progressive.py), so each pass is one Dask task. The scene is scattered to the
workers once; a worker prepares it (BVH, lights, effect plan) once per render and keeps
that context for the following passes. Each task returns its pass film; the client merges
the films strictly in pass order with the same PassMerger as the single-machine loop, so
the image is bitwise the same as render_progressive with the same seed and pass count,
whatever the number of workers or the order in which they finish.

A worker that dies mid-pass loses nothing: the scheduler hands its task to another worker.
The scene is broadcast, but Dask's active memory manager (on by default) drops the
replicas no queued task needs, so the one copy left can die with its worker; the
scheduler then cancels every pass that needs it, and the client scatters the scene
again and resubmits those passes (MAX_SCENE_LOSSES times a render). Budgets (passes, seconds, target
error) and cancel stop the render; pending tasks are cancelled and running ones are told
to stop (a flag on each worker that the pass polls).

dask and distributed are optional (`pip install photonmap[distributed]`); they are
imported only when a render asks for a cluster. docs/distributed.md has the set-up.
"""
from __future__ import annotations

import importlib.util
import os
import threading
import time
import uuid
import warnings
from collections import deque
from contextlib import contextmanager
from dataclasses import replace

from .effects import shot_words
from .film import Film
from .progressive import (ADAPTIVE_WARNING, Budget, PassMerger, add_shot_counts, budget_spent,
                          max_passes_of, overrun_warning, pass_settings)
from .render import (_check_region, close_context, prepare_context, render_cryptomatte,
                     render_pass, warning_key, warning_teller)
from .scene import Scene
from .settings import RenderSettings

REQUIRED = ("dask", "distributed")
INSTALL_HINT = "pip install 'dask[distributed]'"
SCHEMES = ("tcp://", "tls://", "ws://", "wss://")
LOCAL_PREFIX = "local:"
POLL_SECONDS = 0.1       # how often the client asks should_cancel while passes run
STOPPED_KEPT = 64          # render keys a worker remembers as ended (for passes still running)
WORKER_WAIT_SECONDS = 30.0  # a scheduler without workers: wait this long for one
MAX_SCENE_LOSSES = 8        # scene copies a render may lose with dying workers (resubmits)


def missing_packages() -> list[str]:
    """Names of the packages distributed rendering needs that are not installed
    (found without importing them, so the add-on can say what is missing cheaply)."""
    return [name for name in REQUIRED if importlib.util.find_spec(name) is None]


def _import_distributed():
    missing = missing_packages()
    if missing:
        raise ImportError(f"distributed rendering needs the Python package(s) "
                          f"{', '.join(missing)}: install them with {INSTALL_HINT}")
    import distributed
    return distributed


def parse_address(address: str) -> tuple[str, object]:
    """'local:W' -> ('local', W): a LocalCluster of W worker processes on this machine;
    'tcp://HOST:PORT' (or tls://, ws://, wss://) -> ('scheduler', address): an existing
    Dask scheduler. Raises ValueError naming the bad address."""
    text = str(address or "").strip()
    if text.lower().startswith(LOCAL_PREFIX):
        count = text[len(LOCAL_PREFIX):]
        if not count.isdigit() or int(count) < 1:
            raise ValueError(f"dask address '{address}': 'local:W' needs a worker count "
                             f"W >= 1, e.g. local:2")
        return "local", int(count)
    if text.lower().startswith(SCHEMES) and len(text) > text.index("://") + 3:
        return "scheduler", text
    raise ValueError(f"dask address '{address}': expected local:W (W worker processes on "
                     f"this machine) or a scheduler address such as tcp://HOST:8786")


@contextmanager
def connect(address: str):
    """Yield (client, worker_threads) for an address of parse_address. A 'local:W'
    cluster is started here and shut down on exit, with one task thread per worker
    process and cores / W engine threads per pass (the image does not depend on it)."""
    kind, value = parse_address(address)
    distributed = _import_distributed()
    if kind == "local":
        cluster = distributed.LocalCluster(n_workers=value, threads_per_worker=1,
                                           processes=True, host="127.0.0.1",
                                           dashboard_address=None)
        try:
            with distributed.Client(cluster) as client:
                yield client, max(1, (os.cpu_count() or 1) // value)
        finally:
            cluster.close()
    else:
        try:
            client = distributed.Client(value, timeout=10)
        except OSError as exc:
            raise ValueError(f"dask address '{address}': cannot reach the scheduler "
                             f"({exc})") from None
        with client:
            yield client, None


# --- worker side ------------------------------------------------------------------------

def _cache(worker=None):
    """This worker's state: {'lock', 'key': current render, 'idle': {key: [prepared
    contexts]}, 'stopped': keys of ended renders}, kept on the Dask Worker object, which
    outlives a re-import of the engine (ship_engine_code). None outside a worker."""
    if worker is None:
        try:
            from distributed import get_worker
            worker = get_worker()
        except (ImportError, ValueError):
            return None
    return vars(worker).setdefault("_photonmap_contexts",
                                   {"lock": threading.Lock(), "key": None, "idle": {},
                                    "stopped": deque(maxlen=STOPPED_KEPT)})


def _take_context(cache, key, scene, settings):
    if cache is None:
        return prepare_context(scene, settings)
    with cache["lock"]:
        if key != cache["key"]:  # a new render: drop the idle contexts of older ones
            for old in [k for k in cache["idle"] if k != key]:
                for ctx in cache["idle"].pop(old):
                    close_context(ctx)
            cache["key"] = key
        idle = cache["idle"].setdefault(key, [])
        if idle:
            return idle.pop()
    return prepare_context(scene, settings)  # outside the lock: other threads may prepare too


def _give_back(cache, key, ctx):
    if cache is not None:
        with cache["lock"]:
            if key == cache["key"]:
                cache["idle"].setdefault(key, []).append(ctx)
                return
    close_context(ctx)


def end_render(key: str, dask_worker=None) -> int:
    """Run on every worker (Client.run, which passes dask_worker) when render `key` ends:
    passes of it still running stop at their next check, and the prepared contexts are
    closed, so a long-lived cluster does not keep the last scene's BVH (a running pass
    closes its own when done). Returns how many contexts were closed."""
    cache = _cache(dask_worker)
    if cache is None:
        return 0
    with cache["lock"]:
        cache["stopped"].append(key)
        idle = cache["idle"].pop(key, [])
        if cache["key"] == key:
            cache["key"] = None
    for ctx in idle:
        close_context(ctx)
    return len(idle)


def _stop_flag(cache, key):
    """should_cancel for a running pass: True once end_render(key) ran on this worker."""
    if cache is None:
        return None
    stopped = cache["stopped"]
    return lambda: key in stopped


def _threads_here():
    try:
        from distributed import get_worker
        per_task = get_worker().state.nthreads
    except (ImportError, ValueError):
        per_task = 1
    return max(1, (os.cpu_count() or 1) // max(1, per_task))


def warning_topic(key: str) -> str:
    """The Dask event topic on which the passes of render `key` post their warnings."""
    return f"{key}-warnings"


def _warning_poster(key: str):
    """post(warnings): log a list of warning texts as an event on warning_topic(key)
    (Worker.log_event, through the scheduler to the client that subscribed), so the
    client says each when the worker knows it, not when the pass returns. A no-op
    outside a Dask worker; best effort (the pass' film carries its warnings too)."""
    try:
        from distributed import get_worker
        worker = get_worker()
    except (ImportError, ValueError):
        return lambda warnings: None
    topic = warning_topic(key)

    def post(warnings):
        if warnings:
            try:
                worker.log_event(topic, [str(w) for w in warnings])
            except Exception:  # noqa: BLE001 - a lost event only delays the warning
                pass
    return post


def run_pass(scene: Scene, settings: RenderSettings, i: int, region, key: str,
             worker_threads: int | None = None) -> Film:
    """The Dask task: render pass i (1-based) of `settings` on this worker and return its
    film (with its photon-hit pass, like every pass). The prepared context is
    cached per render key. Engine threads: worker_threads, else settings.workers, else the
    cores divided among this worker's task threads; the image does not depend on it.
    film.warnings: the scene's, the effect analysis' and the pass' own (a hand-set search
    radius), each also posted to the client when known (_warning_poster): the first two
    once the context is prepared, the pass' once its photon maps are built."""
    threads = int(worker_threads or settings.workers or _threads_here())
    base = settings if threads == settings.workers else replace(settings, workers=threads)
    cache = _cache()
    post = _warning_poster(key)
    ctx = _take_context(cache, key, scene, base)
    try:
        known = ctx.scene.all_warnings() + ctx.plan.warnings
        post(known)
        ctx.settings = pass_settings(base, i)
        t0 = time.perf_counter()
        film = render_pass(ctx, region, None, _stop_flag(cache, key),
                           on_warning=lambda w: post([w]))
        if i == 1 and settings.cryptomatte and not film.stats.get("cancelled"):
            render_cryptomatte(ctx, region, film, _stop_flag(cache, key))  # as progressive
        film.stats["pass_seconds"] = time.perf_counter() - t0
        film.stats["effects"] = ctx.plan.report()
        film.warnings = known + film.stats.get("warnings", [])
    finally:
        _give_back(cache, key, ctx)
    return film


# --- client side ------------------------------------------------------------------------

def _engine_package() -> str:
    """'engine' from a checkout or pip install; 'bl_ext.<repo>.<id>.engine' inside a
    Blender extension, a name no Dask worker can import."""
    return __name__.rpartition(".")[0]


def engine_zip(directory: str) -> str:
    """Write the engine's files into a zip importable under the engine's own package name
    (parent packages as empty __init__.py files) and return its path. The name carries
    shippedengine.engine_digest (the files and the package name), so an edited engine is a
    new upload (and a new folder on the workers: shippedengine.unpack)."""
    import zipfile

    from .shippedengine import engine_digest, engine_files
    here = os.path.dirname(os.path.abspath(__file__))
    package = _engine_package()
    path = os.path.join(directory, f"photonmap_engine_{engine_digest(here, package)}.zip")
    parts = package.split(".")
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for depth in range(1, len(parts)):
            z.writestr("/".join(parts[:depth]) + "/__init__.py", "")
        prefix = "/".join(parts)
        for f in engine_files(here):
            z.write(f, prefix + "/" + os.path.relpath(f, here).replace(os.sep, "/"))
    return path


def ship_engine_code(client) -> None:
    """Ship the engine (engine_zip) to the scheduler and every worker, also to workers
    that join or restart later, so they import it under the client's module name. Inside
    a Blender extension that name is bl_ext.<repo>.<id>.engine, which no worker could
    import otherwise; workers need only the engine's dependencies. The scheduler gets
    Client.upload_file's copy (it unpickles the passes' tasks); each worker unpacks the
    zip once per machine into a folder named by its contents (shippedengine.UnpackEngine),
    so numba's kernel cache serves every render after the first on that machine; a worker
    on the client's machine (a local cluster) imports the client's own files instead and
    loads the kernels the client compiled (shippedengine.local_shim)."""
    import tempfile

    import cloudpickle
    from distributed.diagnostics.plugin import SchedulerUploadFile

    from . import shippedengine
    with tempfile.TemporaryDirectory() as tmp:
        path = engine_zip(tmp)
        with open(path, "rb") as f:
            data = f.read()
        name = os.path.splitext(os.path.basename(path))[0]
        # One plugin name per package: a later render (or an edited engine) replaces the
        # last one instead of piling zips on the scheduler that a restart would replay.
        plugin = f"photonmap-engine-{_engine_package()}"
        with warnings.catch_warnings():  # replacing the last render's: expected
            warnings.filterwarnings("ignore", message="Scheduler already contains a plugin")
            client.register_plugin(SchedulerUploadFile(path, load=True),
                                   name=f"{plugin}-scheduler")
    # The workers cannot import the plugin's module by its name: send it by value.
    cloudpickle.register_pickle_by_value(shippedengine)
    source = os.path.realpath(os.path.dirname(os.path.abspath(__file__)))
    client.register_plugin(shippedengine.UnpackEngine(data, name, _engine_package(), source),
                           name=f"{plugin}-workers")


def render_distributed(scene: Scene, settings: RenderSettings | None = None,
                       budget: Budget | None = None, client=None, address: str | None = None,
                       progress=None, should_cancel=None, on_pass=None, region=None,
                       worker_threads: int | None = None, max_in_flight: int | None = None,
                       ship_code: bool | None = None, on_warning=None) -> Film:
    """render_progressive on a Dask cluster: bitwise the same Film for the same seed and
    pass count.

    client: a distributed.Client, or address: 'local:W' / 'tcp://HOST:PORT' (a cluster is
    connected, and for local:W started, for this render only). progress(stage, fraction,
    text) after each finished pass, on_pass(film, info) after each merged pass (the
    running average, in pass order), should_cancel() polled every POLL_SECONDS.
    worker_threads: engine threads per pass on a worker (default: see run_pass).
    max_in_flight: passes submitted but not merged (default 2 x the cluster's task
    threads), bounding memory and the work thrown away when a budget ends the render.
    ship_code: upload the engine to the cluster first (ship_engine_code); default: when
    the engine is not the top-level package 'engine' (a Blender extension). Otherwise
    the workers import the installed engine, which must be the client's version.
    on_warning(text): each of film.warnings once, on the calling thread, when the client
    learns it: the scene's before any pass is sent; the effect analysis' and each pass'
    own (a hand-set search radius) as a worker posts them (run_pass; at the latest when
    that pass returns, before its progress call), however many workers and passes find
    them (render.warning_key).
    Raises ValueError for a bad address, ImportError when dask is missing, SceneError for
    a bad scene (checked here, before anything is shipped)."""
    if client is None:
        if address is None:
            raise ValueError("render_distributed needs a client or an address (local:W or "
                             "tcp://HOST:PORT)")
        with connect(address) as (own_client, threads):
            return render_distributed(scene, settings, budget, own_client, None, progress,
                                      should_cancel, on_pass, region,
                                      worker_threads or threads, max_in_flight, ship_code,
                                      on_warning)
    distributed = _import_distributed()
    settings = settings or RenderSettings()
    budget = budget or Budget()
    region = _check_region(region, scene.width, scene.height)
    scene.validate()
    tell = warning_teller(on_warning)
    tell(scene.all_warnings())  # the client's copy: known before anything is sent
    if settings.adaptive_threshold > 0:
        tell([ADAPTIVE_WARNING])
    t_start = time.perf_counter()
    max_passes = max_passes_of(budget)
    key = f"photonmap-{uuid.uuid4().hex}"
    w, h = region[2] - region[0], region[3] - region[1]
    merger = PassMerger(w, h, settings.show_photons)
    if not client.nthreads():
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT_SECONDS)
        except TimeoutError:
            raise ValueError(f"the Dask scheduler {client.scheduler.address} has no workers "
                             f"(none joined within {WORKER_WAIT_SECONDS:g} s)") from None
    nthreads = sum(client.nthreads().values())
    window = max_in_flight or max(2, 2 * nthreads)
    if ship_code if ship_code is not None else _engine_package() != "engine":
        ship_engine_code(client)
    # The workers' warnings as they post them (run_pass), queued by the client's event
    # thread and told from this one (tell_posted), between its waits.
    posted = deque()
    topic = warning_topic(key)
    client.subscribe_topic(topic, posted.append)

    def tell_posted():
        while posted:
            _, texts = posted.popleft()
            tell(texts)

    scene_future = client.scatter(scene, broadcast=True, hash=False)
    scene_losses = 0

    def submit(i):
        # Earlier passes first (higher Dask priority): they are merged first. A pass
        # resubmitted after the scene was lost gets a key of its own (the old one is
        # forgotten by the scheduler).
        return client.submit(run_pass, scene_future, settings, i, region, key, worker_threads,
                             key=f"{key}-pass-{i}" + (f"-r{scene_losses}" if scene_losses else ""),
                             priority=-i, pure=False)

    cancelled_error = getattr(distributed.client, "FuturesCancelledError", TimeoutError)
    pending: dict = {}   # pass -> future
    finished: dict = {}  # pass -> Film, waiting for the passes before it
    log, effects, warnings, keys = [], [], [], set()
    shots = {}  # the caustic shots' counts over the passes (progressive.add_shot_counts)
    cancelled = False
    next_pass = 1
    try:
        while True:
            while (len(pending) + len(finished) < window
                   and (max_passes is None or next_pass <= max_passes)):
                pending[next_pass] = submit(next_pass)
                next_pass += 1
            if not pending and not finished:
                break
            if should_cancel is not None and should_cancel():
                cancelled = True
                break
            timeout = POLL_SECONDS
            if budget.seconds is not None and merger.passes:
                # As on one machine the first pass is always finished; after it the client
                # stops waiting at the deadline: what is merged is the image.
                left = budget.seconds - (time.perf_counter() - t_start)
                if left <= 0:
                    break
                timeout = min(timeout, left)
            try:
                distributed.wait(list(pending.values()), timeout=timeout,
                                 return_when="FIRST_COMPLETED")
            except (TimeoutError, cancelled_error):
                pass  # cancelled passes: their scene copy died with a worker (below)
            tell_posted()
            lost = [i for i in sorted(pending) if pending[i].cancelled()]
            if lost:
                scene_losses += 1
                if scene_losses > MAX_SCENE_LOSSES:
                    raise RuntimeError(
                        f"the Dask cluster lost the scene {scene_losses} times (workers "
                        f"died while holding it); {merger.passes} passes were merged")
                scene_future.release()
                scene_future = client.scatter(scene, broadcast=True, hash=False)
                for i in lost:
                    pending.pop(i).release()
                    pending[i] = submit(i)
                continue
            for i in sorted(pending):
                if pending[i].done():
                    try:
                        film = pending[i].result()  # re-raises the task's error here
                    except Exception:
                        if pending[i].cancelled():
                            continue  # cancelled since the check above: resubmitted next round
                        raise
                    future = pending.pop(i)
                    # Released now, not when garbage collected: the waits' tracebacks
                    # form reference cycles that kept finished passes on the workers.
                    future.release()
                    finished[i] = film
                    # Its warnings whose events have not come (yet): before its progress.
                    tell(film.warnings)
                    if progress is not None:
                        progress("render", _fraction(budget, max_passes, len(finished) + merger.passes,
                                                     time.perf_counter() - t_start),
                                 f"Pass {i} done ({merger.passes} merged, {len(pending)} running)")
            stop = False
            while merger.passes + 1 in finished:
                one = finished.pop(merger.passes + 1)
                if not effects:
                    effects = one.stats.get("effects", [])
                # film.warnings as render_progressive lists them, the same from any
                # cluster: the first pass' (the scene's, the effect analysis', its
                # own), then what a later pass finds anew (warning_key), in pass order.
                for w in one.warnings:
                    if merger.passes == 0 or warning_key(w) not in keys:
                        warnings.append(w)
                keys.update(warning_key(w) for w in warnings)
                merger.add(one)
                add_shot_counts(shots, one.stats)
                elapsed = time.perf_counter() - t_start
                info = dict(passes=merger.passes, photons=merger.photons, elapsed=elapsed,
                            error_estimate=merger.error,
                            k_nearest=pass_settings(settings, merger.passes).k_nearest,
                            pass_seconds=one.stats.get("pass_seconds", float("nan")))
                log.append(info)
                if merger.passes == 1 and (
                        overrun := overrun_warning(budget, settings, info["pass_seconds"])):
                    warnings.append(overrun)
                    tell([overrun])
                if on_pass is not None:
                    on_pass(merger.film, info)
                if budget_spent(budget, merger.passes, merger.error, elapsed):
                    stop = True
                    break
            if stop:
                break
    finally:
        # Budget reached, cancel or an error: nothing more is merged. Stop running passes
        # at their next check and drop the ones not started.
        try:
            client.cancel(list(pending.values()))
            for future in pending.values():
                future.release()
            scene_future.release()
            client.run(end_render, key, on_error="ignore")
            client.unsubscribe_topic(topic)
        except Exception:  # noqa: BLE001 - the cluster may be gone; the error before matters
            pass
    film = merger.film
    film.stats.update(progressive=True, passes=merger.passes, error_estimate=merger.error,
                      photons_total=merger.photons, pass_log=log, cancelled=cancelled,
                      effects=shot_words(effects, shots), time_total=time.perf_counter() - t_start,
                      distributed=dict(workers=len(client.nthreads()), threads=nthreads))
    film.warnings = list(warnings or scene.all_warnings())
    if settings.adaptive_threshold > 0:  # the passes take all their samples (pass_settings)
        film.warnings.append(ADAPTIVE_WARNING)
    tell(film.warnings)
    return film


def _fraction(budget: Budget, max_passes, passes, elapsed) -> float:
    parts = []
    if max_passes:
        parts.append(passes / max_passes)
    if budget.seconds:
        parts.append(elapsed / budget.seconds)
    return min(1.0, max(parts)) if parts else 0.0
