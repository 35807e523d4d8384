"""The memory estimate (engine/resources.py) against the arrays a render really holds:
an environment map's sampling tables (exact sizes) and the regathers' subset maps of the
bounce limits (GatherMap subsets: an upper bound within GATHER_TOLERANCE), measured as
the nbytes of the real objects after prepare and the map build."""
import os
import tracemalloc

import numpy as np

from helpers import ROOT
from engine import Environment, RenderSettings
from engine.render import prepare_context, shoot_photons
from engine.resources import (ENV_BUILD_BYTES_PER_TEXEL, environment_bytes,
                              estimate_memory, regather_levels)
from engine.scenefile import load_scene

# The regather maps' estimate is an upper bound at most this much above the arrays.
GATHER_TOLERANCE = 1.5


def _built(scene, settings):
    ctx = prepare_context(scene, settings)
    shoot_photons(ctx, {})
    return ctx


def _subset_bytes(ctx):
    gm = ctx.gather_map
    if gm is None:
        return 0
    return sum(v.E.nbytes for v in gm.subset_maps)


def _environment_arrays(env):
    return sum(a.nbytes for part in (env._distribution, env._cosine) if part is not None
               for a in part)


def _hdri(h, w, seed=5):
    """An equirectangular sky with a sun and a dark lower half."""
    rng = np.random.default_rng(seed)
    px = 0.2 + 0.3 * rng.random((h, w, 3))
    px[h // 2:] *= 0.05
    px[h // 8, w // 3] = 5000.0
    return Environment(px)


def test_figure6_regather_maps_within_the_estimate():
    """Figure 6's box under the default bounce limits keeps two regather levels (the
    limits drop 7 / 15 % of its power): the estimate bounds their arrays."""
    scene, _ = load_scene(os.path.join(ROOT, "scenes", "figure6.toml"))
    scene.width, scene.height = 40, 30
    s = RenderSettings(workers=1, photons=100_000, caustic_photons=20_000, spp=1)
    ctx = _built(scene, s)
    measured = _subset_bytes(ctx)
    assert len(ctx.gather_map.subset_maps) == regather_levels(s) == 2
    est = estimate_memory(scene, s).parts["regather maps"]
    assert measured <= est <= GATHER_TOLERANCE * measured, (measured, est)
    # Without limits that can drop photons there are none, and none are counted.
    unlimited = RenderSettings(workers=1, photons=100_000, max_bounces=1024,
                               diffuse_bounces=1024, glossy_bounces=1024,
                               transmission_bounces=1024)
    assert regather_levels(unlimited) == 0
    assert "regather maps" not in estimate_memory(scene, unlimited).parts


def test_environment_tables_are_counted_exactly():
    """An HDRI-lit ground: the estimate's environment part is the nbytes of the sampling
    tables the render built (the shadow rays' cosine-weighted ones, and the map's own
    for the world's photons), and its regather maps bound the arrays."""
    scene, _ = load_scene(os.path.join(ROOT, "scenes", "figure3.toml"))
    scene.width, scene.height = 40, 30
    scene.lights = []
    scene.environment = _hdri(256, 512)
    s = RenderSettings(workers=1, photons=60_000, caustic_photons=0, spp=1)
    ctx = _built(scene, s)
    env = scene.environment
    assert env._distribution is not None and env._cosine is not None
    est = estimate_memory(scene, s)
    kept = _environment_arrays(env)
    assert environment_bytes(env) == kept
    assert est.parts["environment"] == kept + ENV_BUILD_BYTES_PER_TEXEL * 256 * 512
    assert est.parts["regather maps"] >= _subset_bytes(ctx)
    # Without photons only the shadow rays' tables are built.
    assert environment_bytes(env, photons=False) == sum(a.nbytes for a in env._cosine)
    # An 8k x 4k map: ~10.7 MB of cluster tables and three arrays of the map's size.
    big = environment_bytes(type("E", (), {"height": 4096, "width": 8192})())
    assert 675e6 < big < 690e6, big


def test_environment_build_peak_within_the_estimate():
    """The tables' build holds temporaries (the texels as float64 and filtered copies):
    its traced peak stays within the estimate's environment part, and not far below."""
    scene, _ = load_scene(os.path.join(ROOT, "scenes", "figure3.toml"))
    scene.environment = env = _hdri(512, 1024)
    part = estimate_memory(scene, RenderSettings()).parts["environment"]
    tracemalloc.start()
    try:
        env.cosine_distributions
        env.distribution
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= part <= 1.25 * peak, (peak, part)


def test_environment_is_not_counted_without_world_light():
    scene, _ = load_scene(os.path.join(ROOT, "scenes", "figure3.toml"))
    scene.environment = _hdri(32, 64)
    assert "environment" in estimate_memory(scene, RenderSettings()).parts
    scene.background_is_light = False
    assert "environment" not in estimate_memory(scene, RenderSettings()).parts
