"""The photon maps' build (render._build_maps) on the workers: its two chains (the gather
chain; the other maps, which wait for the gather chain's shot spacing before the caustic
map) and the gather guide's blocks of points give the same maps, bit for bit, on one
thread and on two, and a chain's error reaches the caller without leaving the other
chain waiting (docs/performance.md "workers54")."""
import importlib
import threading

import numpy as np
import pytest

from engine import RenderSettings, guiding
from engine.api import cornell_box

render = importlib.import_module("engine.render")


def _settings(workers):
    return RenderSettings(workers=workers, photons=30_000, caustic_photons=20_000, spp=1,
                          gather_guiding="on")


def _maps(workers):
    """The arrays and radii the photon pass leaves in the context, by name."""
    ctx = render.prepare_context(cornell_box(40, 30), _settings(workers))
    try:
        render.shoot_photons(ctx, {})
        out = {name: getattr(ctx, name) for name in ("caustic_radius", "global_radius",
                                                     "gather_short")}
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
