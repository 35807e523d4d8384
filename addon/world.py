"""Blender world -> the engine's background: a constant colour or an equirectangular
environment map (engine Environment), with a warning naming every node that is not
simulated.

Read as Cycles renders it: Background node's Color x Strength. Color may be a constant,
an RGB node, or an Environment Texture (equirectangular, from its file or packed),
optionally behind a Mapping node (its rotation; Point, Vector, Normal or Texture type) fed
by the Texture Coordinate node's Generated / Object output or nothing (the ray direction
in world shading), or a Sky Texture of any of Blender 5.0's types (Single Scattering, 4.x:
Nishita; Multiple Scattering, 5.0's default; Preetham; Hosek / Wilkie), behind the same
Mapping: the engine computes the sky as Cycles does (engine/lights/sky.py), bakes it into
an environment map and adds its sun disc as a sun light (`sky_sun_lights`). A sky type
the engine does not know warns and uses the world's viewport colour x strength.
Backgrounds (or Emission shaders) joined by Mix Shader and Add Shader nodes are summed, a
Mix factor from Light Path's Is Camera Ray giving camera rays a world of their own
(`export_worlds`; docs/compatibility.md world39). Colours, Mix factors and Strengths
made of nodes of the direction (a gradient sky, a Noise on a factor) are evaluated along
world directions and baked into a map (`WorldDirections`, `_Weight`; worldtex40).
"""
from __future__ import annotations

import bpy
import numpy as np

from .materials import (MaterialConverter, _pixels, _srgb_encoder, cycles_stores_srgb,
                        output_node)


def _from(socket):
    """The node feeding socket (through reroutes), or None."""
    if not socket.is_linked:
        return None
    node = socket.links[0].from_node
    while node.type == "REROUTE" and node.inputs[0].is_linked:
        node = node.inputs[0].links[0].from_node
    return node if node.type != "REROUTE" else None


def world_mist(pm, world) -> tuple:
    """The world's Mist Pass settings as the engine's Scene.mist (start m, depth m,
    falloff exponent), as Cycles' film reads them (blender/sync.cpp); Cycles' film
    defaults without a world."""
    mist = getattr(world, "mist_settings", None)
    if mist is None:
        return pm.Scene.__dataclass_fields__["mist"].default
    return (float(mist.start), float(mist.depth),
            pm.scene.MIST_FALLOFF.get(mist.falloff, 2.0))


def world_medium(pm, world, warnings: list):
    """The engine WorldMedium of the World Output's Volume (Blender manual, World >
    Volume: a homogeneous medium filling all space outside the objects; read as a
    material's medium by MaterialConverter.world_volume), or None without one or when it
    neither absorbs nor scatters. With one, Cycles' world surface and sun lamps light
    nothing (engine/worldmedium.py; the effect report says so)."""
    if world is None:
        return None
    use_nodes = bpy.app.version >= (5, 0, 0) or getattr(world, "use_nodes", True)
    nt = world.node_tree if use_nodes else None
    out = output_node(nt, "OUTPUT_WORLD") if nt is not None else None
    if out is None or "Volume" not in out.inputs or not out.inputs["Volume"].is_linked:
        return None
    sigma_a, sigma_s, g, emit = MaterialConverter(pm).world_volume(
        world, out.inputs["Volume"], warnings)
    if not np.any(sigma_a + sigma_s > 0):
        if np.any(emit > 0):
            # An infinite glowing medium that dims nothing: every escaping ray would
            # collect e x infinity.
            warnings.append(f"world '{world.name}': a World Volume that emits but neither "
                            "absorbs nor scatters (Density 0) is not supported and ignored")
        return None
    return pm.WorldMedium(absorption=sigma_a, scattering=sigma_s, anisotropy=g,
                          emission=emit)


def export_world(pm, world, warnings: list):
    """(background RGB (3,), engine Environment or None) for a Blender world, as the
    scene's light and its reflections see it (export_worlds' first)."""
    return export_worlds(pm, world, warnings)[0]


# Light Path outputs a world's Mix Shader factor may read: each ray kind's value. Cycles'
# camera rays (and those passed on through transparent surfaces) are none of the others;
# the rest of the world's uses (lighting, reflections, refractions, shadow rays) differ
# among themselves, so only Is Camera Ray splits them exactly (world_fac).
LIGHT_PATH_CAMERA = {"Is Camera Ray": 1.0, "Is Shadow Ray": 0.0, "Is Diffuse Ray": 0.0,
                     "Is Glossy Ray": 0.0, "Is Singular Ray": 0.0, "Is Reflection Ray": 0.0,
                     "Is Transmission Ray": 0.0, "Is Volume Scatter Ray": 0.0}


def export_worlds(pm, world, warnings: list, camera_view=None) -> tuple:
    """((background, environment) the scene's light: what every ray but the camera's
    sees, (background, environment) what camera rays see, or None when the same) for a
    Blender world; warnings get one line per unsupported node (each naming the world and
    the node).

    The World Output's Surface is a tree of Background (or Emission) shaders joined by
    Mix Shader and Add Shader nodes, as Cycles sums their closures: each Background's
    Color x Strength weighted by the Mix factors on its way. A Mix factor is a constant or
    a Light Path output (through Math and Invert nodes): Is Camera Ray is 1 for camera
    rays and 0 for the rest, so "light the scene with the HDRI, show a colour behind"
    (Mix by Is Camera Ray) renders as in Cycles. Several environment maps (or a map and a
    colour) in one sum are baked into one map on the first map's texels.

    camera_view: engine shadernodes.CameraView of the render's camera, for the Texture
    Coordinate node's Window and Camera outputs (a screen-mapped backplate): the light
    bakes the image as Cycles projects it through the camera, and camera rays see it
    exactly (engine/worldgraph.py WorldGraph); None (the viewport): those outputs are
    warned and read as the direction."""
    if world is None:
        return (np.zeros(3), None), None
    viewport = np.asarray(tuple(world.color)[:3], dtype=np.float64)
    use_nodes = bpy.app.version >= (5, 0, 0) or getattr(world, "use_nodes", True)
    nt = world.node_tree if use_nodes else None
    if nt is None:
        return (viewport, None), None
    out = output_node(nt, "OUTPUT_WORLD")
    who = f"world '{world.name}'"
    # (the World Output's Volume: world_medium; with one the engine switches the world's
    # light off, as Cycles does)
    if out is None or not out.inputs["Surface"].is_linked:
        return (np.zeros(3), None), None
    node = _from(out.inputs["Surface"])
    memo: dict = {_CAMERA_VIEW: camera_view}
    light = _shader_terms(pm, world, node, "light", warnings, memo)
    camera = _shader_terms(pm, world, node, "camera", [], memo)  # (warned once, above)
    if light is None:
        what = f"'{node.name}' ({node.type})" if node is not None else "(none)"
        warnings.append(f"{who}: surface node {what} is not supported (Background and "
                        "Emission, joined by Mix and Add Shader nodes, are); using the "
                        "world viewport colour as background")
        return (viewport, None), None
    seen_by_camera = _ray_visibility(world, warnings)
    lit = _resolve_terms(pm, light, warnings, who, camera_view)
    if not seen_by_camera:  # World > Settings > Ray Visibility > Camera off: black there
        return lit, (np.zeros(3), None)
    if any(_view_dependent(w, t) for w, t in camera):
        # A screen-mapped backplate: camera rays evaluate the graph at their direction
        # (a baked map would blur the image to its texels).
        return lit, (np.zeros(3), _exact_world(pm, camera, camera_view, world.name))
    if len(camera) == len(light) and all(
            wc == wl and tc is tl for (wc, tc), (wl, tl) in zip(camera, light)):
        return lit, None
    return lit, _resolve_terms(pm, camera, warnings, who, camera_view)


# memo's key for the render's camera view (export_worlds' camera_view), which the colour
# converters read for the Window and Camera coordinates.
_CAMERA_VIEW = ("camera_view",)


def _view_dependent(weight, term) -> bool:
    """A world term reads the camera (Window or Camera coordinates): in its colour graph
    or in a factor of its weight."""
    if isinstance(term, EnvTerm) and term.reads_camera:
        return True
    return isinstance(weight, _Weight) and any(getattr(f, "reads_camera", False)
                                               for f, _ in weight.factors)


def _exact_world(pm, terms, camera_view, name):
    """engine worldgraph.WorldGraph of [(weight, term)] (_shader_terms'): each term's
    colour graph (EnvTerm.graph) or map at strength 1, its weight's constant and
    direction factors, evaluated per ray."""
    out = []
    for w, term in terms:
        const, factors = (w.const, [(f.node, k) for f, k in w.factors]) \
            if isinstance(w, _Weight) else (float(w), [])
        if not factors and const <= 0.0:
            continue
        if isinstance(term, np.ndarray):
            colour = term
        else:
            colour = term.graph if term.graph is not None else term.unit
        out.append((const, factors, colour))
    return pm.worldgraph.WorldGraph(out, camera_view, name=f"{name} (camera rays)")


def _ray_visibility(world, warnings) -> bool:
    """World > Settings > Ray Visibility (Cycles' world visibility flags): whether camera
    rays see the world (off: they see black, as Cycles evaluates no background for them;
    with Film > Transparent nothing). Diffuse, Glossy, Transmission and Volume Scatter off
    are warned (the engine's world lookups do not tell those rays apart); Shadow off
    changes only Cycles' sampling of the world, not the image: nothing to do."""
    vis = getattr(world, "cycles_visibility", None)
    if vis is None:
        return True
    off = [label for attr, label in (("diffuse", "Diffuse"), ("glossy", "Glossy"),
                                     ("transmission", "Transmission"),
                                     ("scatter", "Volume Scatter"))
           if not getattr(vis, attr, True)]
    if off:
        warnings.append(f"world '{world.name}': Ray Visibility {', '.join(off)} off is not "
                        "simulated; those rays see the world")
    return bool(getattr(vis, "camera", True))


def _shader_terms(pm, world, node, ray, warnings, memo):
    """[(weight, term)] of the shader tree at node as ray ("light" or "camera") sees it,
    weight a float or a _Weight (a factor that varies with direction), term an RGB (3,)
    or an EnvTerm; None for a node that is not a Background, Emission, Mix Shader or Add
    Shader (or nothing: [])."""
    if node is None:
        return []
    if node.type in ("BACKGROUND", "EMISSION"):
        strength = world_fac(world, node.inputs["Strength"], ray, warnings,
                             f"the {node.name} Strength", memo=memo, pm=pm)
        weight = (_Weight(1.0, ((strength, "strength"),))
                  if isinstance(strength, _DirectionField) else max(strength, 0.0))
        return [(weight, _background_color(pm, world, node, warnings, memo))]
    if node.type == "ADD_SHADER":
        parts = [_shader_terms(pm, world, _from(sock), ray, warnings, memo)
                 for sock in node.inputs if sock.type == "SHADER"]
        return None if any(p is None for p in parts) else [t for p in parts for t in p]
    if node.type == "MIX_SHADER":
        fac = world_fac(world, node.inputs[0], ray, warnings, memo=memo, pm=pm)
        shaders = [sock for sock in node.inputs if sock.type == "SHADER"]
        first = _shader_terms(pm, world, _from(shaders[0]), ray, warnings, memo)
        second = _shader_terms(pm, world, _from(shaders[1]), ray, warnings, memo)
        if first is None or second is None:
            return None
        if isinstance(fac, _DirectionField):  # Cycles clamps the factor (saturatef)
            return ([(_Weight.of(w).times(fac, "1-fac"), t) for w, t in first]
                    + [(_Weight.of(w).times(fac, "fac"), t) for w, t in second])
        fac = min(max(fac, 0.0), 1.0)
        return ([(_scaled(w, 1.0 - fac), t) for w, t in first if fac < 1.0]
                + [(_scaled(w, fac), t) for w, t in second if fac > 0.0])
    return None


class _DirectionField:
    """A world float socket fed by nodes that vary with direction (a Gradient or Noise
    Texture, Separate XYZ of the Generated coordinates through a Color Ramp ...): node,
    the engine/shadernodes graph, evaluated along world directions (WorldDirections)."""

    def __init__(self, node, reads_camera=False):
        self.node = node
        self.reads_camera = reads_camera  # it reads the Camera or Window coordinates

    def values(self, pm, geo) -> np.ndarray:
        """(n,) the field at geo's n directions (engine worldgraph.direction_values)."""
        return pm.worldgraph.direction_values(self.node, geo)


class _Weight:
    """A world term's weight that varies with direction: const x the product of its
    factors, each (field, kind): "fac" min(max(f, 0), 1) (a Mix Shader's factor, clamped
    as Cycles' svm_node_mix_closure), "1-fac" one minus that, "strength" f itself."""

    def __init__(self, const, factors=()):
        self.const, self.factors = float(const), tuple(factors)

    @staticmethod
    def of(w) -> "_Weight":
        return w if isinstance(w, _Weight) else _Weight(w)

    def times(self, field, kind) -> "_Weight":
        return _Weight(self.const, self.factors + ((field, kind),))

    def __eq__(self, other):
        return (isinstance(other, _Weight) and self.const == other.const
                and len(self.factors) == len(other.factors)
                and all(f is g and k == m for (f, k), (g, m) in
                        zip(self.factors, other.factors)))

    __hash__ = None

    def values(self, pm, geo) -> np.ndarray:
        """(n,) the weight along geo's n directions (engine worldgraph.factor's kinds; a
        negative product is clamped, warned, after the sum)."""
        out = np.full(len(geo.dirs), self.const)
        for field, kind in self.factors:
            out *= pm.worldgraph.factor(field.values(pm, geo), kind)
        return out


def _scaled(w, k: float):
    """Weight w (a float or a _Weight) times the constant k."""
    return w * k if not isinstance(w, _Weight) else _Weight(w.const * k, w.factors)


def world_fac(world, socket, ray, warnings, what="a Mix Shader factor", memo=None,
              pm=None):
    """The value of a world shader's float socket (a Mix Shader's factor, a Background's
    Strength: `what`, for the warning) for ray ("light" or "camera"): its constant, or a
    Light Path output (LIGHT_PATH_CAMERA for camera rays; for the rest Is Camera Ray is 0
    and the other ray kinds are warned and read as 0), through Math (one operand a
    constant) and Invert nodes; other nodes (textures of the direction, Color Ramp,
    Separate XYZ ...: the material converter's nodes) a _DirectionField when pm and memo
    are given (one per socket, shared by both ray kinds), else warned, its constant."""
    who = f"world '{world.name}'"
    if not socket.is_linked:
        return float(socket.default_value)
    link = socket.links[0]
    node, out = link.from_node, link.from_socket.name
    while node.type == "REROUTE" and node.inputs[0].is_linked:
        link = node.inputs[0].links[0]
        node, out = link.from_node, link.from_socket.name
    if node.type == "LIGHT_PATH" and out in LIGHT_PATH_CAMERA:
        if ray == "camera":
            return LIGHT_PATH_CAMERA[out]
        if out != "Is Camera Ray":
            msg = (f"{who}: Light Path '{node.name}' output '{out}' in the world is read "
                   "as 0 for every ray but the camera's (only Is Camera Ray splits them "
                   "as Cycles does)")
            if msg not in warnings:
                warnings.append(msg)
        return 0.0
    if node.type == "MATH":
        values = [world_fac(world, sock, ray, warnings, what, memo, pm)
                  for sock in node.inputs[:2]]
        if not any(isinstance(v, _DirectionField) for v in values):
            result = _math(node.operation, *values)
            if result is not None:
                return min(max(result, 0.0), 1.0) if node.use_clamp else result
    if node.type == "INVERT":
        fac = world_fac(world, node.inputs["Fac"], ray, warnings, what, memo, pm)
        x = world_fac(world, node.inputs["Color"], ray, warnings, what, memo, pm)
        if not (isinstance(fac, _DirectionField) or isinstance(x, _DirectionField)):
            return fac * (1.0 - x) + (1.0 - fac) * x
    if pm is not None and memo is not None:
        return _direction_field(pm, world, socket, warnings, memo)
    value = float(getattr(socket, "default_value", 0.0))
    msg = (f"{who}: node '{node.name}' ({node.type}) driving {what} is not supported (a "
           f"constant, Light Path, Math and Invert are); using {value:g}")
    if msg not in warnings:
        warnings.append(msg)
    return value


def _direction_field(pm, world, socket, warnings, memo):
    """socket's value through the material converter's nodes (_WorldColours): a float
    when it comes out constant, else a _DirectionField; one per socket (memo)."""
    key = ("field", socket.as_pointer())
    if key not in memo:
        colours = _WorldColours(pm, world, warnings, memo.get(_CAMERA_VIEW))
        colours.fallback = np.zeros(3)
        val = colours._input(socket.node, socket, 0)
        warnings.extend(w for w in colours.told() if w not in warnings)
        if hasattr(val, "evaluate"):
            memo[key] = _DirectionField(val, colours.view_dependent)
        else:
            arr = np.asarray(val, np.float64)
            memo[key] = float(arr if arr.ndim == 0 else arr[:3] @ [0.2126, 0.7152, 0.0722])
    return memo[key]


def _math(op, a, b):
    """Cycles' Math node on two floats for the operations a world factor uses; None for
    another operation."""
    ops = {"ADD": lambda: a + b, "SUBTRACT": lambda: a - b, "MULTIPLY": lambda: a * b,
           "DIVIDE": lambda: a / b if b != 0.0 else 0.0, "MINIMUM": lambda: min(a, b),
           "MAXIMUM": lambda: max(a, b), "LESS_THAN": lambda: float(a < b),
           "GREATER_THAN": lambda: float(a > b),
           "POWER": lambda: a ** b if a >= 0.0 else 0.0}
    f = ops.get(op)
    return None if f is None else float(f())


class EnvTerm:
    """An environment map in a world sum: make(strength) -> the engine Environment at that
    strength (an Environment Texture's or Sky Texture's, or a baked colour graph's)."""

    def __init__(self, make, unit=None):
        self.make = make
        self.unit = unit if unit is not None else make(1.0)
        self.graph = None  # a baked colour graph's nodes (shadernodes), for camera rays
        self.reads_camera = False  # the graph reads the Camera or Window coordinates


class _EnvLeaf:
    """An environment map inside a world colour graph (engine/shadernodes nodes evaluated
    along the bake grid's directions): its radiance along the WorldDirections' dirs."""

    def __init__(self, env):
        self.env = env

    def evaluate(self, geo, prim, u, v):
        return self.env.radiance(geo.dirs[np.asarray(prim, np.int64)])


# Nodes that read a surface (its mesh attributes, its neighbourhood by rays, its view)
# or a ray kind: not evaluated along world directions (warned, the socket's value).
_SURFACE_ONLY_NODES = frozenset((
    "AMBIENT_OCCLUSION", "BEVEL", "ATTRIBUTE", "UVMAP", "VERTEX_COLOR", "NORMAL_MAP",
    "BUMP", "TANGENT", "WIREFRAME", "OBJECT_INFO", "PARTICLE_INFO", "HAIR_INFO",
    "POINT_INFO", "LIGHT_PATH", "LAYER_WEIGHT", "FRESNEL", "UVALONGSTROKE",
    "DISPLACEMENT", "VECTOR_DISPLACEMENT", "TEX_POINTDENSITY", "RAYCAST"))


class _WorldColours(MaterialConverter):
    """The material converter's colour nodes (engine/shadernodes) for a world's Background
    colour or a factor: Environment and Sky Textures become _EnvLeaf nodes (made at
    strength 1); Texture Coordinate reads the direction (engine worldgraph.
    WorldDirections), its Camera and Window outputs the camera's projection of it (with
    a camera_view; view_dependent then set), Reflection its opposite (Cycles' sd->wi);
    UV warned, read as Generated. An Image Texture is read at its Vector."""

    def __init__(self, pm, world, warnings, camera_view=None):
        super().__init__(pm)
        self.camera_view = camera_view
        self.view_dependent = False
        self._world, self._world_warnings = world, warnings
        self._mat = type("WorldName", (), {"name": world.name})()
        self._warned, self._warnings = set(), []
        self.leaves = []
        self.fallback = np.zeros(3)  # the Background's own colour (set before a read)

    def _node_output(self, n, out, depth):
        if n.type in ("TEX_ENVIRONMENT", "TEX_SKY"):
            make = (_environment if n.type == "TEX_ENVIRONMENT" else _sky)(
                self.pm, self._world, n, self._world_warnings)
            if make is None:  # (warned) the Background's colour; a sky: the viewport's
                return (self.fallback if n.type == "TEX_ENVIRONMENT" else
                        np.asarray(tuple(self._world.color)[:3], np.float64))
            leaf = _EnvLeaf(make(1.0))
            leaf.make = make
            self.leaves.append(leaf)
            return leaf
        if n.type in _SURFACE_ONLY_NODES:
            return None  # (warned by the converter: not supported, the socket's value)
        oname = getattr(out, "name", out)
        if n.type == "TEX_COORD" and (oname == "Reflection" or (
                oname in ("Window", "Camera") and self.camera_view is not None)):
            self.view_dependent |= oname != "Reflection"
            return self.pm.shadernodes.ViewCoordinates(oname.upper())
        if n.type == "TEX_COORD" and oname not in ("Generated", "Object", "Normal"):
            self._warn(f"material '{self._world.name}': Texture Coordinate '{n.name}' "
                       f"output '{oname}' is not supported in the world (Generated, Object "
                       "and Normal are: the ray direction); using the direction")
            return self.pm.shadernodes.Coordinates("generated")
        if n.type == "TEX_COORD" and oname == "Object" and getattr(n, "object", None):
            self._warn(f"material '{self._world.name}': Texture Coordinate '{n.name}' "
                       f"relative to object '{n.object.name}' is not supported in the "
                       "world; using the direction")
            return self.pm.shadernodes.Coordinates("generated")
        return super()._node_output(n, out, depth)

    def colour(self, node, socket):
        """What feeds the colour socket of node: a constant, an _EnvLeaf, or a colour
        node graph over leaves (MaterialConverter._input)."""
        return self._input(node, socket, 0)

    def told(self) -> list:
        """The converter's warnings, naming the world."""
        prefix = f"material '{self._world.name}'"
        return [w.replace(prefix, f"world '{self._world.name}'", 1) for w in self._warnings]


def _background_color(pm, world, node, warnings, memo):
    """A Background (or Emission) node's Color: RGB (3,) or an EnvTerm (an Environment
    Texture, a Sky Texture, or colour nodes over them: Mix, Hue/Saturation, Bright /
    Contrast, Gamma, Invert, RGB Curves, Math and the rest of the material converter's
    colour nodes, baked on the first map's texels). Each node read once (memo)."""
    if node.name in memo:
        return memo[node.name]
    who = f"world '{world.name}'"
    col_socket = node.inputs["Color"]
    color = np.asarray(tuple(col_socket.default_value)[:3], dtype=np.float64)
    camera_view = memo.get(_CAMERA_VIEW)
    colours = _WorldColours(pm, world, warnings, camera_view)
    colours.fallback = color
    val = colours.colour(node, col_socket)
    term = None
    if isinstance(val, _EnvLeaf):
        term = EnvTerm(val.make, val.env)
    elif hasattr(val, "evaluate"):
        term = _bake_colours(pm, world, val, colours.leaves, warnings, camera_view)
        if term is not None:
            term.graph, term.reads_camera = val, colours.view_dependent
        if term is None:
            src = _from(col_socket)
            warnings.append(f"{who}: node '{src.name}' ({src.type}) plugged into the "
                            "Background colour cannot be evaluated along directions; using "
                            f"the colour {color.round(3).tolist()}")
    else:
        arr = np.asarray(val, np.float64)
        color = np.full(3, float(arr)) if arr.ndim == 0 else arr[:3]
    warnings.extend(w for w in colours.told() if w not in warnings)
    if term is None:
        term = np.clip(color, 0.0, None)
    memo[node.name] = term
    return term


# A baked world map (colour nodes over a map, maps and colours summed) is sampled from its
# sources' own lookups on a grid this many times finer than the first map's texels in
# each direction, as long as it holds at most BAKE_TEXELS texels: the bake's linear
# interpolation then follows the sources' lookups between their texels, where the
# colour nodes' nonlinearity, and an sRGB-stored map's interpolation of encoded values
# (Cycles' and ours), make "interpolate, then the nodes" differ from "the nodes at the
# texels, then interpolate" (newuser39: a 64 x 32 sRGB-tagged map with a 200 sun texel lit
# the floor 1.26-1.35x Cycles when baked at its own texels; an 8-bit JPG panorama is
# sRGB-stored too).
BAKE_UPSAMPLE = (4, 2, 1)
BAKE_TEXELS = 2 ** 21


# A world with no map whose colour or mix factors vary with direction (a gradient sky, a
# Noise on the Strength) is baked on a grid of this size (height, width: 0.35 degrees a
# texel, 2 M texels of float32 RGB = 6 MB).
DIRECTION_BAKE = (512, 1024)


def bake_grid(env, fine=False) -> tuple:
    """(height, width, (height x width, 3) world directions) of the bake grid over env:
    its texel grid refined by the first of BAKE_UPSAMPLE that keeps it within
    BAKE_TEXELS texels (fine: refined further, up to DIRECTION_BAKE's height, for
    weights that vary with direction), the directions at the grid's texel centres (rows
    top first: the zenith; equirectangular, env's rotation). env None: the
    DIRECTION_BAKE grid, no rotation."""
    if env is None:
        height, width = DIRECTION_BAKE
        return height, width, _grid_directions(height, width)
    h0, w0 = env.pixels.shape[:2]
    k = next((k for k in BAKE_UPSAMPLE if h0 * w0 * k * k <= BAKE_TEXELS), 1)
    if fine:
        k = max(k, min(-(-DIRECTION_BAKE[0] // h0), int((BAKE_TEXELS / (h0 * w0)) ** 0.5)))
    height, width = h0 * k, w0 * k
    return height, width, _grid_directions(height, width) @ env.rotation  # (world -> texture)


def _grid_directions(height, width) -> np.ndarray:
    """(height x width, 3) texture-space directions at the texel centres of an
    equirectangular grid (rows top first; Cycles' equirectangular_to_direction)."""
    theta = (np.arange(height) + 0.5)[:, None] / height * np.pi
    u = (np.arange(width) + 0.5)[None, :] / width
    phi = 2.0 * np.pi * (0.5 - u)
    st = np.sin(theta)
    return np.stack(np.broadcast_arrays(st * np.cos(phi), st * np.sin(phi),
                                        np.cos(theta)), -1).reshape(-1, 3)


def _bake_environment(pm, pixels, height, width, first, name, warnings=None, who=""):
    """engine Environment (strength 1) of baked (height x width, 3) radiance texels on
    the bake grid of first (an Environment, or None: the DIRECTION_BAKE grid); negative
    texels (a negative Strength or colour) read 0, with a warning into warnings."""
    if warnings is not None and np.nanmin(pixels) < 0.0:
        msg = (f"{who}: the radiance is negative in some directions (a negative Strength, "
               "factor or colour); those read 0 (Cycles lets them subtract light)")
        if msg not in warnings:
            warnings.append(msg)
    pixels = np.nan_to_num(np.maximum(pixels, 0.0), nan=0.0, posinf=0.0).reshape(
        height, width, 3).astype(np.float32)
    rotation = None if first is None else first.rotation
    interpolation = "Linear" if first is None else first.interpolation
    return pm.Environment(pixels, 1.0, rotation, interpolation,
                          name=name if first is None else first.name)


def _bake_colours(pm, world, val, leaves, warnings, camera_view=None):
    """EnvTerm of a colour graph over environment maps (leaves) or over the direction
    alone (no leaves: a gradient sky): evaluated on the bake grid of the first map
    (bake_grid; every map looked up there) or the DIRECTION_BAKE grid, negatives
    clamped; None when the graph cannot be evaluated without leaves (warned by the
    caller)."""
    first = leaves[0].env if leaves else None
    height, width, dirs = bake_grid(first)
    n = height * width
    try:
        rgb = np.asarray(val.evaluate(pm.worldgraph.WorldDirections(dirs, camera_view),
                                      np.arange(n), np.zeros(n),
                                      np.zeros(n)), np.float64)
    except Exception as exc:  # noqa: BLE001 - a node that needs a surface
        if not leaves:
            return None
        warnings.append(f"world '{world.name}': the Background colour's nodes cannot be "
                        f"evaluated over the environment map ({exc}); using the map alone")
        return EnvTerm(leaves[0].make, first)
    if rgb.ndim == 1:
        rgb = np.repeat(rgb[:, None], 3, axis=1)
    rgb = np.broadcast_to(rgb, (n, 3))
    made = {}

    def make(strength):
        if strength not in made:
            env = _bake_environment(pm, rgb, height, width, first,
                                    f"{world.name} (its colour nodes, baked)",
                                    warnings, f"world '{world.name}'")
            made[strength] = (env if strength == 1.0 else
                              pm.Environment(env.pixels, strength, env.rotation,
                                             env.interpolation, name=env.name))
        return made[strength]
    return EnvTerm(make)


def _resolve_terms(pm, terms, warnings=None, who="the world", camera_view=None) -> tuple:
    """(background RGB (3,), Environment or None) of [(weight, term)], weight a float or
    a _Weight, term an RGB (3,) or an EnvTerm: the colours summed; one map alone at a
    constant weight made at that weight; otherwise (several maps, a map and colours, a
    weight that varies with direction) baked into one map on the first map's bake grid
    (bake_grid: every map looked up there, the colours and weights evaluated along its
    directions; no map: the DIRECTION_BAKE grid), its sky sun disc (sun_light) scaled by
    the sky's weight toward the sun."""
    const = np.zeros(3)
    maps, varying = [], []
    for w, term in terms:
        if isinstance(w, _Weight):
            varying.append((w, term))
            if not isinstance(term, np.ndarray):
                maps.append((w, term))
        elif w <= 0.0:
            continue
        elif isinstance(term, np.ndarray):
            const = const + w * term
        else:
            maps.append((w, term))
    if not maps and not varying:
        return np.clip(const, 0.0, None), None
    if maps and not varying and len(maps) == 1 and not np.any(const > 0):
        first = maps[0][1].make(maps[0][0])
        return first.average(), first
    first = maps[0][1].unit if maps else None
    height, width, dirs = bake_grid(first, fine=bool(varying))
    geo = pm.worldgraph.WorldDirections(dirs, camera_view)
    pixels = np.broadcast_to(const, (height * width, 3)).copy()
    for w, term in terms:
        if not isinstance(w, _Weight) and w <= 0.0:
            continue
        k = w.values(pm, geo)[:, None] if isinstance(w, _Weight) else w
        if isinstance(term, np.ndarray):
            if isinstance(w, _Weight):
                pixels += k * term
        else:
            pixels += k * term.unit.radiance(dirs)
    env = _bake_environment(pm, pixels, height, width, first,
                            f"{maps[0][1].unit.name if maps else 'world'}", warnings, who)
    sun = getattr(first, "sun_light", None) if first is not None else None
    if sun is not None:
        w0 = maps[0][0]
        if isinstance(w0, _Weight):  # the weight toward the sun (travel: -direction)
            toward = -np.asarray(sun["direction"], np.float64).reshape(1, 3)
            w0 = float(w0.values(pm, pm.worldgraph.WorldDirections(
                toward / np.linalg.norm(toward), camera_view))[0])
        env.sun_light = dict(sun, color=np.asarray(sun["color"], np.float64) * w0)
    return env.average(), env


def _environment(pm, world, node, warnings):
    """make(strength) -> the engine Environment of an Environment Texture node (its image
    read once), or None after a warning."""
    who = f"world '{world.name}': Environment Texture '{node.name}'"
    img = node.image
    if img is None:
        warnings.append(f"{who} has no image; the world renders magenta, as in Cycles")
        return _missing_map(pm)
    if node.projection != "EQUIRECTANGULAR":
        warnings.append(f"{who}: projection '{node.projection}' is not supported "
                        "(only Equirectangular); using the Background colour")
        return None
    interpolation = str(node.interpolation)
    if interpolation not in ("Linear", "Closest"):
        warnings.append(f"{who}: interpolation '{interpolation}' is read as Linear")
        interpolation = "Linear"
    rotation = _mapping_rotation(pm, world, node, warnings)
    try:
        rgba = _pixels(img)
    except Exception as exc:  # noqa: BLE001 - any image failure becomes a warning
        warnings.append(f"{who}: image '{img.name}' could not be read ({exc}); the world "
                        "renders magenta, as in Cycles")
        return _missing_map(pm)
    rgb = np.nan_to_num(np.maximum(np.asarray(rgba[:, :, :3], np.float32), 0.0), nan=0.0,
                        posinf=0.0)
    srgb = cycles_stores_srgb(img)
    if srgb and img.is_float:
        # A float file tagged sRGB: Blender decoded it at load, Cycles keeps the file's
        # encoded values (addon/materials.py cycles_stores_srgb); encode back (exact to
        # float rounding). 8-bit texels are the stored encoded values already.
        rgb = _srgb_encoder(pm)(rgb).astype(np.float32)
    def make(strength):
        # srgb: the engine interpolates the encoded texels and decodes after, as Cycles
        # (engine/lights/environment.py).
        return pm.Environment(rgb, strength, rotation, interpolation, name=img.name,
                              srgb=srgb)
    try:
        make(1.0)
    except ValueError as exc:
        warnings.append(f"{who}: {exc}; using the Background colour")
        return None
    return make


def _missing_map(pm):
    """make(strength) of the map Cycles shows for an environment image it cannot load:
    magenta (TEX_IMAGE_MISSING_R/G/B 1, 0, 1) in every direction (a missing HDRI lights
    the scene magenta there too: the user sees it at once)."""
    magenta = np.array([[[1.0, 0.0, 1.0]]], np.float32)
    return lambda strength: pm.Environment(magenta, strength, None, "Closest",
                                           name="missing image")


def _check_coordinates(world, socket, warnings):
    """Warn unless the Texture Coordinate output feeding socket is the world's ray
    direction (Generated, or Object without an object)."""
    link = socket.links[0]
    node, out = link.from_node, link.from_socket.name
    while node.type == "REROUTE" and node.inputs[0].is_linked:
        link = node.inputs[0].links[0]
        node, out = link.from_node, link.from_socket.name
    if out == "Generated" or (out == "Object" and getattr(node, "object", None) is None):
        return
    warnings.append(f"world '{world.name}': Texture Coordinate '{node.name}' output '{out}' "
                    "is not supported for the environment; using the ray direction "
                    "(Generated)")


def _mapping_rotation(pm, world, env_node, warnings):
    """Rotation (world direction -> texture direction) of a Mapping node in front of the
    environment texture, or None."""
    # By iteration: inputs["Vector"] skips a socket flagged unavailable, as a Sky
    # Texture's is until its tree updates after the sky type changed.
    vector = next((s for s in env_node.inputs if s.name == "Vector"), None)
    m = _from(vector) if vector is not None else None
    if m is None:
        return None
    who = f"world '{world.name}'"
    if m.type == "TEX_COORD":
        _check_coordinates(world, vector, warnings)
        return None
    if m.type != "MAPPING":
        warnings.append(f"{who}: node '{m.name}' ({m.type}) in front of '{env_node.name}' "
                        "is not supported; using the ray direction")
        return None
    coord = _from(m.inputs["Vector"])
    if coord is not None and coord.type != "TEX_COORD":
        warnings.append(f"{who}: node '{coord.name}' ({coord.type}) feeding Mapping "
                        f"'{m.name}' is not supported; using the ray direction")
    elif coord is not None:
        _check_coordinates(world, m.inputs["Vector"], warnings)
    for name in ("Location", "Rotation", "Scale"):
        sock = m.inputs.get(name)
        if sock is not None and sock.is_linked:
            warnings.append(f"{who}: a node plugged into Mapping '{m.name}' {name} is not "
                            "supported; using its value")
    R = pm.scene.euler_rotation(m.inputs["Rotation"].default_value)
    scale = np.asarray(tuple(m.inputs["Scale"].default_value), np.float64)
    if not (np.all(scale > 0) and np.allclose(scale, scale[0], rtol=1e-4)):
        warnings.append(f"{who}: Mapping '{m.name}' scale {scale.round(3).tolist()} is not "
                        "supported for the environment (only a uniform positive scale, "
                        "which changes nothing); using its rotation")
    loc = m.inputs.get("Location")
    if (m.vector_type == "POINT" and loc is not None
            and np.any(np.abs(tuple(loc.default_value)) > 1e-9)):
        warnings.append(f"{who}: Mapping '{m.name}' location is ignored for the "
                        "environment (directions only)")
    return R.T if m.vector_type == "TEXTURE" else R


def _sky(pm, world, node, warnings):
    """make(strength) -> the engine Environment baked from a Sky Texture node
    (engine/lights/sky.py), with the sun disc's light parameters as its `sun_light` (None
    without a disc); or None after a warning (a sky type engine/lights/sky.py does not
    know, or a bake that fails)."""
    made = {}

    def make(strength):
        if strength not in made:
            made[strength] = _sky_at(pm, world, node, strength, warnings)
        return made[strength]
    return make if make(1.0) is not None else None


def _sky_at(pm, world, node, strength, warnings):
    """engine Environment of a Sky Texture node at `strength` (_sky), or None after a
    warning."""
    from importlib import import_module
    sky_mod = import_module(pm.__name__ + ".lights.sky")
    who = f"world '{world.name}': Sky Texture '{node.name}'"
    sky_type = sky_mod.SKY_TYPE_ALIASES.get(str(node.sky_type), str(node.sky_type))
    if sky_type not in sky_mod.SUPPORTED_SKY_TYPES:
        warnings.append(f"{who}: sky type {sky_type} is not supported (Single / Multiple "
                        "Scattering, Preetham and Hosek / Wilkie are); using the world "
                        "viewport colour "
                        f"{np.round(tuple(world.color)[:3], 3).tolist()}")
        return None
    rotation = _mapping_rotation(pm, world, node, warnings)
    # Blender 5.0 calls the aerosols' density aerosol_density, 4.x dust_density.
    aerosol = getattr(node, "aerosol_density", None)
    if aerosol is None:
        aerosol = getattr(node, "dust_density", 1.0)
    params = dict(
        sky_type=sky_type, sun_disc=bool(node.sun_disc), sun_size=float(node.sun_size),
        sun_intensity=float(node.sun_intensity), sun_elevation=float(node.sun_elevation),
        sun_rotation=float(node.sun_rotation), altitude=float(node.altitude),
        air_density=float(node.air_density), aerosol_density=float(aerosol),
        ozone_density=float(node.ozone_density),
        sun_vector=tuple(getattr(node, "sun_direction", (0.0, 0.0, 1.0))),
        turbidity=float(getattr(node, "turbidity", 2.2)),
        ground_albedo=float(getattr(node, "ground_albedo", 0.3)), strength=strength,
        rotation=rotation, name=node.name)
    # The bake takes 1-4 s of CPU: a viewport update that leaves the sky as it was (an
    # object moved, a material edited) reuses the last bakes.
    key = repr(sorted((k, v if k != "rotation" or v is None else np.round(v, 12).tolist())
                      for k, v in params.items()))
    env = _SKY_CACHE.get(key)
    if env is None:
        try:
            env = sky_mod.SkyTexture(**params).environment()
        except ValueError as exc:
            warnings.append(f"{who}: {exc}; using the world viewport colour")
            return None
        _SKY_CACHE[key] = env
        while len(_SKY_CACHE) > 2:
            _SKY_CACHE.pop(next(iter(_SKY_CACHE)))
    return env


_SKY_CACHE: dict = {}  # key of the node's settings -> baked Environment (insertion order)


def sky_sun_lights(pm, environment, seen=None) -> list:
    """The engine Light of a baked sky's sun disc ([] for any other environment). seen:
    the (background, environment) camera rays see (export_worlds), None the same: the
    disc shows to the camera only where that world holds the sky too."""
    params = getattr(environment, "sun_light", None)
    if params is None:
        return []
    if seen is not None and getattr(seen[1], "sun_light", None) is None:
        params = dict(params, visible_camera=False)
    return [pm.Light(**params)]
