"""The photon maps' build (render._build_maps) on the workers: its two chains (the gather
chain; the other maps, which wait for the gather chain's shot spacing before the caustic
map) and the gather guide's blocks of points give the same maps, bit for bit, on one
thread and on two, and a chain's error reaches the caller without leaving the other
chain waiting (docs/performance.md "workers54"); the gather chain's steps side by side
and the secondary share measured in the other chain give what the calling thread's
steps gave (docs/performance.md "workers55")."""
import importlib
import threading

import numpy as np
import pytest

from engine import RenderSettings, guiding, visualimportance
from engine.api import cornell_box

render = importlib.import_module("engine.render")


def _settings(workers):
    return RenderSettings(workers=workers, photons=30_000, caustic_photons=20_000, spp=1,
                          gather_guiding="on")


def _maps(workers):
    """The arrays and radii the photon pass leaves in the context, by name."""
    ctx = render.prepare_context(cornell_box(40, 30), _settings(workers))
    try:
        stats = {}
        shot = render.shoot_photons(ctx, stats)[0]
        out = {name: getattr(ctx, name) for name in ("caustic_radius", "global_radius",
                                                     "gather_short")}
        # The shares the map build measures beside its chains, and the calling thread's
        # own call for the secondary share (smooth_counts' value before workers55).
        out["indirect_share"] = np.float64(stats["indirect_share"])
        out["secondary_share"] = np.float64(stats["secondary_share"])
        out["secondary_share_alone"] = np.float64(visualimportance.secondary_share(
            ctx, shot, ctx.settings.radius or ctx.global_radius))
        out["gather_rays_used"] = np.int64(ctx.gather_rays)
        for name in ("caustic_map", "secondary_map"):
            ph = getattr(ctx, name).photons
            for field in ("position", "power", "direction", "normal", "kind"):
                out[f"{name}.{field}"] = np.asarray(getattr(ph, field))
        gm = ctx.gather_map
        for field in ("position", "normal", "E", "boundary"):
            out[f"gather_map.{field}"] = np.asarray(getattr(gm, field))
        out["guide.row_prob"] = gm.guide.row_prob
        out["guide.col_prob"] = gm.guide.col_prob
        for name, value in vars(ctx.gather_counts).items():
            if isinstance(value, np.ndarray):
                out[f"gather_counts.{name}"] = value
        return out
    finally:
        render.close_context(ctx)


def test_maps_are_the_same_on_one_thread_and_two(monkeypatch):
    one = _maps(1)
    assert one["caustic_map.position"].shape[0] > 0
    assert one["guide.row_prob"].shape[0] > 1
    two = _maps(2)
    # the guide's blocks as small as they go: its numbers do not depend on them
    monkeypatch.setattr(guiding, "GRID_ROWS", 1)
    monkeypatch.setattr(guiding, "GRID_BLOCKS", 1 << 30)
    tiny = _maps(2)
    assert one.keys() == two.keys() == tiny.keys()
    assert 0.0 < one["secondary_share"] < 1.0
    assert one["secondary_share"] == one["secondary_share_alone"]
    for key, value in one.items():
        np.testing.assert_array_equal(two[key], value, err_msg=key)
        np.testing.assert_array_equal(tiny[key], value, err_msg=key)


def test_a_gather_chain_error_reaches_the_caller_and_no_chain_waits(monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("broken radius")

    monkeypatch.setattr(render, "KthTree", broken)
    monkeypatch.setattr(render, "global_search_radius", broken)
    got = {}

    def run():
        ctx = render.prepare_context(cornell_box(40, 30), _settings(2))
        try:
            render.shoot_photons(ctx, {})
        except RuntimeError as e:
            got["error"] = str(e)
        finally:
            render.close_context(ctx)

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(120)
    assert not t.is_alive(), "the map build hung"
    assert got.get("error") == "broken radius"


def test_handover_waits_for_its_value_and_stops_on_close_or_cancel():
    h = render._Handover()
    threading.Timer(0.05, h.set, (1.5,)).start()
    assert h.wait(lambda: False) == 1.5
    closed = render._Handover()
    closed.close()
    with pytest.raises(render.Cancelled):
        closed.wait(lambda: False)
    with pytest.raises(render.Cancelled):
        render._Handover().wait(lambda: True)


def test_once_makes_its_value_once_and_a_second_caller_waits_for_it():
    calls, started = [], threading.Event()

    def make():
        started.set()
        calls.append(threading.get_ident())
        threading.Event().wait(0.05)  # the other thread asks meanwhile
        return np.arange(3)

    once = render._Once(make)
    got = {}
    t = threading.Thread(target=lambda: got.setdefault("first", once()))
    t.start()
    started.wait(5)
    second = once()
    t.join(5)
    assert len(calls) == 1
    assert second is got["first"]

    def broken():
        raise RuntimeError("no masks")

    failed = render._Once(broken)
    for _ in range(2):  # every caller sees the error
        with pytest.raises(RuntimeError, match="no masks"):
            failed()
