"""Shadow catchers as Cycles renders them (Blender's Object > Visibility > Shadow Catcher).

Cycles X (intern/cycles/kernel/integrator/shadow_catcher.h, kernel/film/read.h) splits a
camera path where it first meets a catcher object: the path goes on as usual, its light
from there on kept apart ("with the objects"), and a copy goes on in a scene that holds
only the catcher objects and the lights ("without the objects": the other objects neither
occlude, reflect nor emit for it). Per pixel, over the samples that met a catcher first,

    shadow catcher pass   S = (1 - A) + A * (with / without)        per channel, 1 where
                                                                    `without` is 0
where A is Combined's alpha (coverage with a transparent film). The Combined image is
the matte - everything the camera saw before meeting a catcher: the objects, and the
world without a transparent film - with, by default (the Shadow Catcher pass off: Cycles'
"approximate shadow catcher", film_calculate_shadow_catcher_matte_with_shadow),

    a     = 1 - (share of samples that met the world (transparent film), a holdout or
                 a catcher)                                  the objects' alpha
    alpha = (1 - a) * (1 - clamp(mean(S), 0, 1)) + a
    transparent film: RGBA = (matte, alpha)
    otherwise:        RGB  = matte + background * (1 - alpha), alpha 1

so a catcher is invisible except where it is darker than without the objects; light the
objects add (reflections, colour bleeding) shows only in the pass (S > 1). With the
Shadow Catcher pass on, Combined is the matte alone (alpha a) and the pass carries the
shadow, to be multiplied over the footage in the compositor. Checked on Cycles 5.0's own
output (s37): its Combined alpha is 1 - clamp(mean(pass)) on the catcher, and without a
transparent film its colour the world x clamp(mean(pass)), to 1e-7; ours against it:
tests/blender/test_shadow_catcher_cycles.py, docs/accuracy.md "catcher37".

This engine makes the same two estimates: the camera pass splits its first-bounce rays
that meet a catcher (integrator._split_catcher_paths; their light, count and the world
behind them go into Film.catcher), and a second context renders the scene with only the
catcher objects (alone_scene), whose per-sample mean over its catcher samples is the
"without". Both are the engine's full estimates - direct light by shadow rays, indirect
and caustics from each scene's own photon maps - so the ratio compares like with like;
the second scene costs a photon pass and a camera pass of its own (+49 % on a floor
scene: docs/performance.md "catcher37"). Only first hits split: Cycles also splits a
camera path that reaches a catcher through a transparent surface, which here sees that
catcher as an ordinary surface.
"""
from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np


def catcher_objects(scene) -> np.ndarray | None:
    """(O,) bool over scene.meshes (Geometry.object_id's order): the shadow catchers;
    None when the scene has none."""
    flags = np.array([bool(getattr(m, "shadow_catcher", False)) for m in scene.meshes], bool)
    return flags if flags.any() else None


def behind_transparent_warning(ctx, samples: int) -> str:
    """The warning for `samples` camera samples that met a shadow catcher through a
    transparent surface (an alpha cut-out, a Transparent BSDF card): there the catcher is
    not split and renders as an ordinary surface, opaque in the matte, where Cycles keeps
    it a catcher (newuser37: a card in front of the catcher gave a grey rectangle)."""
    names = [n for n, c in zip(ctx.geo.object_names, ctx.catcher_objects) if c]
    shown = ", ".join(f"'{n}'" for n in names[:3]) + (" ..." if len(names) > 3 else "")
    return (f"shadow catcher {shown}: {samples:,} camera samples meet it through a "
            "transparent surface (alpha or a Transparent BSDF); there it renders as an "
            "ordinary, opaque surface, not as a shadow catcher (Cycles keeps it one): move "
            "the transparent surface out of its view or make the matte without it")


def alone_scene(scene):
    """The scene Cycles' catcher paths see: its shadow catcher meshes only (as ordinary
    surfaces), with its lights, world, camera and materials; no warnings (the whole
    scene's are told once)."""
    meshes = []
    for m in scene.meshes:
        if m.shadow_catcher:
            # (A shallow copy: a placement's faces come from its prototype, which
            # dataclasses.replace would hand back to it as its own; arrays are shared.)
            c = copy.copy(m)
            c.shadow_catcher, c.warnings = False, []
            meshes.append(c)
    return replace(scene, meshes=meshes, warnings=[])


def alone_key(scene, settings) -> str | None:
    """What the catchers-alone context (alone_scene, alone_settings) is built from, as a
    digest: the catcher meshes (geometry, placement, visibility, attributes), the
    materials they use, the material names' order, the lights, the world (colour,
    environment, medium, portals) and the settings the build reads; not the camera and
    image size (a render follows the view: render._render_alone) nor the other objects
    and their materials. Equal digests: the context can be kept (a viewport edit of
    another object, engine/session.py). None when the scene cannot be digested (an
    object that does not pickle): build anew."""
    import hashlib
    import pickle

    alone = alone_scene(scene)
    used = {n for m in alone.meshes for n in m.materials}
    content = (alone.meshes, {n: alone.materials[n] for n in sorted(used)
                              if n in alone.materials},
               list(alone.materials), replace(alone, meshes=[], materials={}, camera=None,
                                              width=0, height=0),
               alone_settings(settings))
    try:
        return hashlib.sha1(pickle.dumps(content, protocol=5)).hexdigest()
    except Exception:  # noqa: BLE001 - any unpicklable member: no key, a rebuild
        return None


def alone_settings(settings):
    """The settings the catcher-only render takes: the film's, with the world not drawn
    (its camera rays that miss add nothing: the "without" is the catchers' light only),
    and none of the extra outputs (Cryptomatte, data passes, photon-hit view)."""
    return replace(settings, film_transparent=True, cryptomatte=(), data_passes=(),
                   show_photons=False)


def add_alone(film, alone) -> None:
    """Record the catcher-only render `alone` (a Film of the same pixels) in
    film.catcher: "alone" (H,W,3) its per-sample mean radiance, "alone_coverage" (H,W)
    the share of its samples that met a catcher."""
    if film.catcher is None:
        h, w = film.height, film.width
        film.catcher = {"light": np.zeros((h, w, 3)), "coverage": np.zeros((h, w)),
                        "background": np.zeros((h, w, 3))}
    from .film import EFFECTS
    film.catcher["alone"] = sum(np.asarray(getattr(alone, n), np.float64) for n in EFFECTS)
    film.catcher["alone_coverage"] = np.asarray(alone.alpha, np.float64)


def _ratio(film) -> np.ndarray:
    """(H,W,3) the catcher's light with the objects over without them, per channel, over
    the samples that met a catcher first (1 where none did or `without` is 0)."""
    c = film.catcher
    with np.errstate(invalid="ignore", divide="ignore"):
        with_objects = c["light"] / c["coverage"][..., None]
        without = c["alone"] / c["alone_coverage"][..., None]
        ratio = with_objects / without
    ok = (c["coverage"][..., None] > 0) & (c["alone_coverage"][..., None] > 0) & (without > 0)
    return np.where(ok & np.isfinite(ratio), ratio, 1.0)


def _alpha(film, transparent: bool) -> np.ndarray:
    """(H,W) Combined's alpha as Cycles' film forms it without catchers: coverage with a
    transparent film, else 1 - the holdout share."""
    return (np.asarray(film.alpha, np.float64) if transparent
            else 1.0 - np.asarray(film.holdout, np.float64))


def shadow_catcher_pass(film, transparent: bool) -> np.ndarray:
    """(H,W,3) float32 Cycles' Shadow Catcher pass (film_calculate_shadow_catcher): the
    with / without ratio over the catcher samples, alpha-over white by Combined's alpha;
    1 where no sample met a catcher. All ones for a film without catchers."""
    if film.catcher is None or "alone" not in film.catcher:
        return np.ones((film.height, film.width, 3), np.float32)
    A = _alpha(film, transparent)[..., None]
    return ((1.0 - A) + A * _ratio(film)).astype(np.float32)


def combined_rgba(film, transparent: bool, approximate: bool = True) -> np.ndarray | None:
    """(H,W,4) float32 Combined with its alpha for a film with shadow catchers (None for
    one without): the matte (the camera's light before it met a catcher) with, when
    approximate (the Shadow Catcher pass off), the shadow as alpha (transparent film) or
    over the world (Cycles' film_calculate_shadow_catcher_matte_with_shadow; module
    docstring)."""
    c = film.catcher
    if c is None or "alone" not in c:
        return None
    from .film import EFFECTS  # (the render's sum, also under the photon-hit view)
    # (>= 0: float32 effects less float64 sums leave -1e-8 where the catcher is alone)
    matte = np.maximum(sum(np.asarray(getattr(film, n), np.float64) for n in EFFECTS)
                       - c["light"], 0.0)
    # Samples that met the world (transparent film), a holdout or a catcher: Cycles'
    # matte transparency; the rest met an object.
    a = np.clip(_alpha(film, transparent) - c["coverage"], 0.0, 1.0)
    if not approximate:
        return np.concatenate([matte, a[..., None]], axis=2).astype(np.float32)
    shadow = np.clip(shadow_catcher_pass(film, transparent).mean(axis=2), 0.0, 1.0)
    alpha = (1.0 - a) * (1.0 - shadow) + a
    if transparent:
        return np.concatenate([matte, alpha[..., None]], axis=2).astype(np.float32)
    rgb = matte + c["background"] * (1.0 - alpha)[..., None]
    return np.concatenate([rgb, np.ones_like(alpha)[..., None]], axis=2).astype(np.float32)
