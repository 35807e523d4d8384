"""Closure cases compared with Cycles (tests/test_closures_cycles.py, references made by
tools/make_closure_references.py): one surface or ball per case, described without bpy or
the engine so both sides build the same scene from it.

Sun-lit plane: an infinite-looking plane (40 m) at z = 0 lit by a sun of strength SUN_W
W/m^2 from SUN_ZENITH degrees on the +x side (it travels along (-sin, 0, -cos), so its
mirror direction lies on the -x side), seen by a narrow camera (FOV_DEG) at CAM_DIST from the
origin at `view` degrees from the zenith on the -x side: every pixel sees the same
(wo, wi) pair. view = SUN_ZENITH is the mirror direction.
White furnace: a ball of the closure in a uniform white world (strength 1); the mean over
the ball's pixels is its albedo seen from the camera, 1 for a lossless closure.
"""
SUN_W = 3.0
SUN_ZENITH = 45.0
FOV_DEG = 4.0
CAM_DIST = 6.0
SIZE = 8           # pixels per side of the plane renders
FURNACE_SIZE = 24  # pixels per side of the furnace renders

FURNACE_VIEW, FURNACE_DIST, FURNACE_FOV = 60.0, 6.0, 25.0  # ball of radius 1 at the origin

GREY = (0.8, 0.8, 0.8)
COPPER = (0.9, 0.6, 0.3)


def _principled(**kw):
    d = dict(node="principled", base_color=GREY, roughness=0.5, metallic=0.0, ior=1.5,
             specular_ior_level=0.5, specular_tint=(1.0, 1.0, 1.0), coat_weight=0.0,
             coat_roughness=0.03, coat_ior=1.5, coat_tint=(1.0, 1.0, 1.0),
             sheen_weight=0.0, sheen_roughness=0.5, sheen_tint=(1.0, 1.0, 1.0),
             distribution="MULTI_GGX")
    d.update(kw)
    return d


def _glossy(color=(0.9, 0.9, 0.9), roughness=0.4, distribution="GGX"):
    return dict(node="glossy", base_color=color, roughness=roughness,
                distribution=distribution)


def _glass(color=(1.0, 1.0, 1.0), roughness=0.3, ior=1.5, distribution="MULTI_GGX"):
    return dict(node="glass", base_color=color, roughness=roughness, ior=ior,
                distribution=distribution)


def _diffuse(color=GREY):
    return dict(node="diffuse", base_color=color)


VIEWS = (0.0, 45.0, 75.0, 85.0)


def plane_cases():
    cases = {}
    for r in (0.0, 0.25, 0.5, 1.0):
        for v in VIEWS:
            cases[f"dielectric_r{r}_v{v:.0f}"] = (_principled(roughness=r), v)
            cases[f"metal_r{r}_v{v:.0f}"] = (_principled(roughness=r, metallic=1.0,
                                                         base_color=COPPER), v)
    for ior in (1.1, 2.4):
        for v in VIEWS:
            cases[f"dielectric_ior{ior}_v{v:.0f}"] = (_principled(roughness=0.5, ior=ior), v)
    for v in VIEWS:
        cases[f"glossy_ggx_v{v:.0f}"] = (_glossy(), v)
        cases[f"glossy_multi_v{v:.0f}"] = (_glossy(distribution="MULTI_GGX"), v)
        cases[f"coat_v{v:.0f}"] = (_principled(roughness=0.6, base_color=(0.7, 0.2, 0.2),
                                               coat_weight=1.0, coat_roughness=0.2,
                                               coat_tint=(0.8, 0.9, 1.0)), v)
        cases[f"spec_tint_v{v:.0f}"] = (_principled(roughness=0.4,
                                                    specular_tint=(1.0, 0.5, 0.2)), v)
        cases[f"spec_level_v{v:.0f}"] = (_principled(roughness=0.4, specular_ior_level=0.8), v)
        cases[f"metal_f82_v{v:.0f}"] = (_principled(roughness=0.4, metallic=1.0,
                                                    base_color=COPPER,
                                                    specular_tint=(0.5, 0.8, 1.0)), v)
        cases[f"sheen_v{v:.0f}"] = (_principled(roughness=0.7, base_color=(0.1, 0.1, 0.4),
                                                sheen_weight=1.0, sheen_roughness=0.4,
                                                sheen_tint=(1.0, 0.8, 0.6)), v)
    # 85 degrees on a smooth dielectric: a mirror sees nothing of a delta sun; the diffuse
    # base under the Fresnel layer is what is compared.
    return cases


def ball_mask(size):
    """(size, size) bool: pixels well inside the furnace ball's silhouette (a disc of 80 %
    of its radius), away from its faceted edge."""
    import math

    import numpy as np
    half = math.tan(math.radians(FURNACE_FOV) / 2.0)
    r_img = math.tan(math.asin(1.0 / FURNACE_DIST)) / half  # in image half-widths
    y, x = np.mgrid[0:size, 0:size]
    u = (x + 0.5) / size * 2 - 1
    w = (y + 0.5) / size * 2 - 1
    return u * u + w * w < (0.8 * r_img) ** 2


def furnace_cases():
    return {
        "furnace_diffuse": _diffuse((1.0, 1.0, 1.0)),
        "furnace_glossy_multi_r0.5": _glossy((1.0, 1.0, 1.0), 0.5, "MULTI_GGX"),
        "furnace_glossy_multi_r1": _glossy((1.0, 1.0, 1.0), 1.0, "MULTI_GGX"),
        "furnace_glossy_ggx_r1": _glossy((1.0, 1.0, 1.0), 1.0, "GGX"),
        "furnace_metal_r0.5": _principled(roughness=0.5, metallic=1.0, base_color=COPPER),
        "furnace_dielectric_r0.5": _principled(roughness=0.5, base_color=(1.0, 1.0, 1.0)),
        "furnace_dielectric_r1": _principled(roughness=1.0, base_color=(1.0, 1.0, 1.0)),
        "furnace_glass_r0.3": _glass(roughness=0.3),
        "furnace_glass_r0.8_ior2.4": _glass(roughness=0.8, ior=2.4),
        "furnace_coat": _principled(roughness=0.5, base_color=(1.0, 1.0, 1.0),
                                    coat_weight=1.0, coat_roughness=0.3),
        "furnace_sheen": _principled(roughness=0.5, base_color=(1.0, 1.0, 1.0),
                                     sheen_weight=1.0, sheen_roughness=0.3),
    }


def sweep_cases():
    """The corners of issue 14's sweep that plane_cases / furnace_cases leave out
    (tests/test_closures_sweep.py, tests/references/closures_sweep.json): returns
    (planes, furnaces), dicts shaped as plane_cases() and furnace_cases() return.

    Plane: a Principled dielectric at IOR 1.1 / 1.33 / 2.4 and roughness 0 / 0.25 / 1
    (IOR 1.33 also at 0.5), the coat case at coat IOR 1.2 and 2.0, copper at roughness 0.1
    and 0.75, each from the four VIEWS. Furnace: glass at IOR 1.1 / 2.4 x roughness
    0.1 / 0.5 / 1 (and 2.4 at 0.8), a white dielectric at IOR 1.1 / 2.4 x roughness
    0.25 / 1, copper at roughness 0.1 and 1."""
    planes = {}
    for ior in (1.1, 1.33, 2.4):
        for r in (0.0, 0.25, 0.5, 1.0):
            if r == 0.5 and ior != 1.33:  # plane_cases has IOR 1.1 and 2.4 at 0.5
                continue
            for v in VIEWS:
                planes[f"dielectric_ior{ior}_r{r}_v{v:.0f}"] = (
                    _principled(roughness=r, ior=ior), v)
    for coat_ior in (1.2, 2.0):
        for v in VIEWS:
            planes[f"coat_ior{coat_ior}_v{v:.0f}"] = (
                _principled(roughness=0.6, base_color=(0.7, 0.2, 0.2), coat_weight=1.0,
                            coat_roughness=0.2, coat_tint=(0.8, 0.9, 1.0),
                            coat_ior=coat_ior), v)
    for r in (0.1, 0.75):
        for v in VIEWS:
            planes[f"metal_r{r}_v{v:.0f}"] = (
                _principled(roughness=r, metallic=1.0, base_color=COPPER), v)
    furnaces = {}
    for ior in (1.1, 2.4):
        for r in (0.1, 0.5, 1.0):
            furnaces[f"furnace_glass_ior{ior}_r{r}"] = _glass(roughness=r, ior=ior)
        for r in (0.25, 1.0):
            furnaces[f"furnace_dielectric_ior{ior}_r{r}"] = _principled(
                roughness=r, ior=ior, base_color=(1.0, 1.0, 1.0))
    # furnace_glass_r0.8_ior2.4 again, converged (test_closures_sweep.FURNACE_SPP).
    furnaces["furnace_glass_ior2.4_r0.8"] = _glass(roughness=0.8, ior=2.4)
    for r in (0.1, 1.0):
        furnaces[f"furnace_metal_r{r}"] = _principled(roughness=r, metallic=1.0,
                                                      base_color=COPPER)
    return planes, furnaces
