"""Teaching images: methods side by side, parameter sweeps and effect strips, labelled.

The paper's long-term goal (Yu, Lowther & Shene 2005, §7) is a tool in which students
render one scene "with local illumination, ray tracing and photon mapping" and learn what
each method and each parameter adds. This module renders those series and composes them
into one labelled image; the CLI (engine/cli.py), the batch command (addon/batch.py) and
the Blender operators (addon/operators.py) all call it. docs/teaching.md is the lesson.

    tiles = compare_methods(scene, settings)          # local, raytrace, photon, photon hits
    tiles = sweep(scene, settings, "photons", [1000, 10000, 100000])
    tiles = effects_strip(film)                       # direct ... emission and their sum
    rgb8 = compose(tiles)                             # (H, W, 3) uint8, labels burned in

Labels are drawn by a `label_mask(lines, width, size)` function: Pillow's own font here
(pillow_label_mask), Blender's BLF font inside Blender (addon/operators.py). Images are
linear radiance until compose() encodes them as sRGB, like the CLI's PNG output.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from .film import EFFECTS
from .imageio import to_8bit
from .progressive import relmse
from .sampling import luminance
from .settings import METHODS, RenderSettings

PREVIEW_LONG_SIDE = 160  # pixels along the longer image side of a preview tile
METHOD_TITLES = {"local": "Local illumination", "raytrace": "Ray tracing",
                 "photon": "Photon mapping"}

# Sweepable parameters: name on the command line -> RenderSettings field, value type.
SWEEP_PARAMS = {
    "photons": ("photons", int),
    "radius": ("radius", float),
    "k": ("k_nearest", int),
    "spp": ("spp", int),
    "ray_depth": ("max_depth", int),
    "photon_depth": ("max_photon_depth", int),
}
SWEEP_ALIASES = {"k_nearest": "k", "samples": "spp", "max_depth": "ray_depth",
                 "max_photon_depth": "photon_depth", "MaxRayPerLightSrc": "photons",
                 "MaxPhotonSearchRadius": "radius", "MaxRayTraceDepth": "ray_depth",
                 "MaxPhotonTraceDepth": "photon_depth"}

# The paper's Figure 6 ladder: (photons, search radius in the paper's scene units). The
# paper's room is about 20 of its units wide; our 4 m box reads one paper unit as 0.2 m
# (bench/bench_accuracy.py), so r 4.0 ... 0.4 becomes 0.8 m ... 0.08 m. The rungs use
# the paper's own estimate: the classic estimator without final gathering.
PAPER_LADDER = ((1_000, 4.0), (10_000, 2.0), (100_000, 1.0), (200_000, 0.4))
PAPER_RADIUS_UNIT = 0.2  # metres per paper radius unit
SWEEP_PRESETS = {
    "paper-ladder": dict(
        params={"photons": [p for p, _ in PAPER_LADDER],
                "radius": [r * PAPER_RADIUS_UNIT for _, r in PAPER_LADDER]},
        settings=dict(estimator="classic", final_gather=False)),
}


@dataclass
class Tile:
    """One labelled image of a series: `image` (H, W, 3) linear radiance, `lines` the
    label text (first line the title), `seconds` the render's wall time (None if it is
    not a render of its own), `error` its error against the series' reference."""
    image: np.ndarray
    lines: list
    seconds: float | None = None
    error: float | None = None
    stats: dict = field(default_factory=dict)


# --- rendering series ---------------------------------------------------------------------

def preview_scene(scene, long_side: int = PREVIEW_LONG_SIDE):
    """A shallow copy of `scene` whose image is at most long_side pixels on its longer
    side (aspect kept); the scene itself unchanged. Raises ValueError for long_side < 1."""
    import copy
    if int(long_side) < 1:
        raise ValueError(f"preview size must be >= 1 pixel, got {long_side}")
    out = copy.copy(scene)
    w, h = scene.width, scene.height
    scale = min(1.0, long_side / max(w, h))
    out.width, out.height = max(1, round(w * scale)), max(1, round(h * scale))
    return out


def effects_sum(film) -> np.ndarray:
    """(H, W, 3) the sum of the effect passes: the rendered image without any photon-hit
    dots drawn over it."""
    return sum(getattr(film, name) for name in EFFECTS).astype(np.float32)


def mean_brightness(img: np.ndarray) -> float:
    """Mean luminance (Rec. 709 weights) of a linear (H, W, 3) image."""
    return float(np.mean(luminance(np.asarray(img, np.float64).reshape(-1, 3))))


def displayed_brightness(img: np.ndarray) -> float:
    """Mean luminance of a linear (H, W, 3) image with each channel clipped to [0, 1]
    (the PNG's range; no view transform), so that a lamp or a glint seen in a mirror
    counts as a white pixel, not as its radiance."""
    return mean_brightness(np.clip(np.asarray(img, np.float64), 0.0, 1.0))


def brightness_difference(img: np.ndarray, ref: np.ndarray) -> float:
    """Relative difference of the displayed brightness (displayed_brightness), (img -
    ref) / ref; nan when ref is black. Of the linear means, one glint pixel of radiance
    4,600 (a lamp seen in a polished ring) set a label to -33 % between tiles that look
    alike (newuser42)."""
    m = displayed_brightness(ref)
    return (displayed_brightness(img) - m) / m if m > 0 else float("nan")


def _photons_emitted(stats) -> int:
    """The photons a render's photon pass traced over all its shots (the glow shot
    included: render._photon_pass's photons_emitted_all)."""
    if "photons_emitted_all" in stats:
        return int(stats["photons_emitted_all"])
    return int(stats.get("photons_emitted", 0) or 0) + int(
        stats.get("caustic_photons_emitted", 0) or 0)


def _photons_stored(stats) -> int:
    """The photons a render's maps store: global, caustic and, where the glow shot makes
    a map of its own (render.GLOW_MAP_APART), glow (before, held in the caustic map)."""
    return sum(int(stats.get(name, 0) or 0)
               for name in ("global_photons", "caustic_photons", "glow_photons"))


def _render_timed(scene, settings, progress, should_cancel, prefix, part=(0, 1)):
    """Render; the time without the kernel compile. part = (index, count) of this render
    in its series: progress reports the fraction of the whole series (each render's
    stages placed within its share by engine/stagespans.py: a stage's own fraction read
    as the render's sent the bar back at every stage, polish38)."""
    from .parallel import Cancelled
    from .render import render
    from .stagespans import StageSpans
    spans = StageSpans(settings.uses_photon_maps, settings.photons + settings.caustic_photons,
                       max(scene.width * scene.height, 1) * settings.spp)

    def step(stage, fraction, text):
        if progress is not None:
            whole = spans.whole(stage, fraction)  # None: the kernel compile, before it
            progress(stage, (part[0] + (whole or 0.0)) / part[1], f"{prefix}: {text}")

    t0 = time.perf_counter()
    film = render(scene, settings, progress=step, should_cancel=should_cancel,
                  on_plan=spans.plan)
    # Without the one-off kernel compile of a machine's first render (engine/jit.py).
    seconds = time.perf_counter() - t0 - float(film.stats.get("time_compile") or 0.0)
    if film.stats.get("cancelled"):
        raise Cancelled()
    return film, seconds


def compare_methods(scene, settings: RenderSettings, progress=None,
                    should_cancel=None) -> list[Tile]:
    """Render `scene` with each method (local, raytrace, photon) and add the photon-hit
    view of the photon render: four tiles, each labelled with the method, its render time,
    its photons and its mean brightness difference to the photon-mapped image.
    progress(stage, fraction, text) as engine.render's; raises engine.parallel.Cancelled
    when should_cancel() turns true."""
    films = {}
    for method in METHODS:
        s = replace(settings, method=method, photon_mapping=True,
                    show_photons=(method == "photon"))
        films[method] = _render_timed(scene, s, progress, should_cancel, METHOD_TITLES[method],
                                      (METHODS.index(method), len(METHODS)))
    ref = effects_sum(films["photon"][0])
    tiles = []
    for method in METHODS:
        film, seconds = films[method]
        img = effects_sum(film)
        emitted = _photons_emitted(film.stats)
        if method == "photon":
            diff = "brightness: the reference"
        else:
            d = brightness_difference(img, ref)
            diff = ("brightness: photon image black" if d != d
                    else f"brightness {100 * d:+.0f} % vs photon")
        tiles.append(Tile(img, [METHOD_TITLES[method], f"{seconds:.1f} s, {emitted:,} photons",
                                diff], seconds, stats=dict(film.stats)))
    film, _ = films["photon"]
    tiles.append(Tile(np.asarray(film.photon_hits, np.float32),
                      ["Photon hits", f"{_photons_stored(film.stats):,} hits stored",
                       f"from {_photons_emitted(film.stats):,} photons"], stats=dict(film.stats)))
    return tiles


def parse_param(text: str):
    """'photons=1000,10000' -> ('photons', [1000, 10000]). Names: SWEEP_PARAMS and their
    aliases (the paper's names too). Raises ValueError naming the bad part."""
    name, sep, values = str(text).partition("=")
    name = name.strip()
    name = SWEEP_ALIASES.get(name, name)
    if not sep or name not in SWEEP_PARAMS:
        raise ValueError(f"sweep parameter '{text}': expected NAME=V1,V2,... with NAME one of "
                         f"{', '.join(SWEEP_PARAMS)}")
    kind = SWEEP_PARAMS[name][1]
    out = []
    for part in values.split(","):
        part = part.strip()
        try:
            v = float(part) if kind is float else int(float(part))
            if kind is int and float(part) != int(float(part)):
                raise ValueError
        except ValueError:
            raise ValueError(f"sweep parameter '{text}': '{part}' is not a "
                             f"{'number' if kind is float else 'whole number'}") from None
        if not math.isfinite(v):
            raise ValueError(f"sweep parameter '{text}': '{part}' is not finite")
        out.append(v)
    if not out:
        raise ValueError(f"sweep parameter '{text}': no values")
    return name, out


def _param_text(name, value) -> str:
    if name == "radius":
        return f"r {value:.3g} m"
    if name == "photons":
        return f"{value:,} photons"
    if name == "k":
        return f"k {value}"
    if name == "spp":
        return f"{value} spp"
    return f"{name.replace('_', ' ')} {value}"


def sweep(scene, settings: RenderSettings, params: dict, reference: np.ndarray | None = None,
          progress=None, should_cancel=None) -> list[Tile]:
    """Render one tile per value of the swept parameter(s) and label each with its value,
    render time and relMSE (docs/design.md's formula) against `reference` (H, W, 3)
    linear, or, without one, against the last tile (the finest: list values from coarse
    to fine). params: {name: [values]} with names of SWEEP_PARAMS; several names sweep
    together (same number of values each), as the paper's ladder sweeps photons and
    radius. A photons sweep scales the caustic photons with the global ones (their ratio
    in `settings`). Raises ValueError for unknown names, unequal lengths, values out of
    range (RenderSettings names the setting) or a reference of another size."""
    if not params:
        raise ValueError("sweep: no parameter to sweep (--param NAME=V1,V2,...)")
    lengths = {len(v) for v in params.values()}
    if len(lengths) != 1:
        raise ValueError("sweep: parameters swept together need the same number of values, "
                         "got " + ", ".join(f"{n}: {len(v)}" for n, v in params.items()))
    for name in params:
        if name not in SWEEP_PARAMS:
            raise ValueError(f"sweep: unknown parameter '{name}' (one of "
                             f"{', '.join(SWEEP_PARAMS)})")
    if reference is not None:
        reference = np.asarray(reference, np.float32)
        if reference.shape[:2] != (scene.height, scene.width):
            raise ValueError(f"reference image is {reference.shape[1]}x{reference.shape[0]}, "
                             f"the sweep renders {scene.width}x{scene.height}")
    count = lengths.pop()
    rungs = []
    for i in range(count):
        changes = {}
        for name, values in params.items():
            field_name = SWEEP_PARAMS[name][0]
            changes[field_name] = values[i]
            if name == "photons":
                ratio = settings.caustic_photons / settings.photons if settings.photons else 0.5
                changes["caustic_photons"] = int(round(values[i] * ratio))
        s = replace(settings, **changes)  # __post_init__ checks the ranges
        title = ", ".join(_param_text(n, v[i]) for n, v in params.items())
        film, seconds = _render_timed(scene, s, progress, should_cancel,
                                      f"{i + 1}/{count} {title}", (i, count))
        rungs.append((title, effects_sum(film), seconds, film.stats))
    ref = reference if reference is not None else rungs[-1][1]
    tiles = []
    for i, (title, img, seconds, stats) in enumerate(rungs):
        is_ref = reference is None and i == count - 1
        err = None if is_ref else relmse(img, ref)
        tiles.append(Tile(img, [title, f"{seconds:.1f} s",
                                "reference (finest)" if is_ref else f"relMSE {err:.4f}"],
                          seconds, err, dict(stats)))
    return tiles


def effects_strip(film) -> list[Tile]:
    """The effect passes (direct, indirect, caustic, specular, emission) and their sum,
    each labelled with its share of the sum's mean brightness."""
    total = effects_sum(film)
    whole = mean_brightness(total)
    tiles = []
    for name in EFFECTS:
        img = np.asarray(getattr(film, name), np.float32)
        share = mean_brightness(img) / whole if whole > 0 else 0.0
        tiles.append(Tile(img, [name.capitalize(), f"{100 * share:.0f} % of the image"]))
    seconds = film.stats.get("time_total")
    tiles.append(Tile(total, ["Sum (the image)", f"{seconds:.1f} s" if seconds else ""],
                      seconds))
    return tiles


# --- composing --------------------------------------------------------------------------

def label_font_size(tile_width: int) -> int:
    """Label text height in pixels for tiles of this width (about 14 characters fit)."""
    return int(max(9, min(16, tile_width // 13)))


LABEL_PAD = 3  # pixels between a label's text and the sides of its band


def fit_label(lines, width: int, size: int, measure):
    """Fit a label's text to a tile `width` pixels wide, never clipping it: the font
    shrinks from `size` (down to MIN_FONT) until the longest line fits; lines still too
    wide are wrapped at spaces (the band grows a line); a word wider than the tile even
    then widens the label. measure(text, size) -> its width in pixels (the font's).
    Returns (lines, size, label width >= width)."""
    lines = [str(x) for x in lines]
    room = int(width) - 2 * LABEL_PAD

    def widest(texts, sz):
        return max((measure(t, sz) for t in texts if t), default=0)

    while size > MIN_FONT and widest(lines, size) > room:
        size -= 1  # narrower, so that the longest line fits the tile
    if widest(lines, size) > room:
        wrapped = []
        for line in lines:
            words = []
            for word in line.split(" "):
                if word == "%" and words:  # "-35 %" stays on one line
                    words[-1] += " %"
                else:
                    words.append(word)
            current = words[0]
            for word in words[1:]:
                if measure(f"{current} {word}", size) <= room:
                    current = f"{current} {word}"
                else:
                    wrapped.append(current)
                    current = word
            wrapped.append(current)
        lines = wrapped
    need = int(math.ceil(widest(lines, size))) + 2 * LABEL_PAD
    return lines, size, max(int(width), need)


def pillow_label_mask(lines, width: int, size: int) -> np.ndarray:
    """Text coverage (h, w) float32 in [0, 1] of `lines` in Pillow's default font at
    `size` pixels, one line below the other, fitted to `width` by fit_label (smaller,
    then wrapped; w > width only for a word wider than the tile): never clipped."""
    from PIL import Image, ImageDraw, ImageFont
    fonts = {}

    def font(sz):
        if sz not in fonts:
            fonts[sz] = ImageFont.load_default(size=sz)
        return fonts[sz]

    lines, size, width = fit_label(lines, width, size, lambda t, sz: font(sz).getlength(t))
    step = size + max(2, size // 4)
    height = step * len(lines) + 4
    img = Image.new("L", (int(width), int(height)), 0)
    draw = ImageDraw.Draw(img)
    for i, line in enumerate(lines):
        draw.text((LABEL_PAD, 2 + i * step), line, fill=255, font=font(size))
    return np.asarray(img, np.float32) / 255.0


GAP = 2  # pixels between tiles
MIN_FONT = 8  # smallest label text, pixels
GAP_GREY = 48
TEXT_RGB = (255, 255, 255)


def compose(tiles: list[Tile], columns: int | None = None, exposure: float = 0.0,
            label_mask=None, font_size: int | None = None) -> np.ndarray:
    """Tiles on a grid (`columns` per row; default all in one row up to 4, then 4 per
    row), each image sRGB-encoded (engine.imageio.to_8bit) with its label as white text
    on a black band below it. Returns (H, W, 3) uint8 with H = rows * (tile height +
    band + GAP) - GAP and W = columns * (cell width + GAP) - GAP; the cell width is the
    tile width, or the widest label's where a word is wider than a small tile (the image
    centred in its cell): label text is never clipped. All tiles must have the same size
    (ValueError otherwise). label_mask(lines, width, size) -> (h, w >= width) coverage:
    pillow_label_mask by default."""
    if not tiles:
        raise ValueError("compose: no tiles")
    h, w = tiles[0].image.shape[:2]
    for t in tiles:
        if t.image.shape[:2] != (h, w):
            raise ValueError(f"compose: tiles differ in size ({t.image.shape[1]}x"
                             f"{t.image.shape[0]} and {w}x{h})")
    columns = int(columns or min(len(tiles), 4))
    if columns < 1:
        raise ValueError(f"compose: columns must be >= 1, got {columns}")
    label_mask = label_mask or pillow_label_mask
    size = font_size or label_font_size(w)
    masks = [np.asarray(label_mask(t.lines, w, size), np.float32) for t in tiles]
    band = max(m.shape[0] for m in masks)
    cell_w = max([w] + [m.shape[1] for m in masks])
    rows = -(-len(tiles) // columns)
    cell_h = h + band
    out = np.full((rows * (cell_h + GAP) - GAP, columns * (cell_w + GAP) - GAP, 3), GAP_GREY,
                  np.uint8)
    boxes = tile_boxes((h, w), len(tiles), columns, band, cell_w)
    for t, m, (x, y, _, _) in zip(tiles, masks, boxes):
        out[y:y + h, x:x + w] = to_8bit(np.nan_to_num(t.image), exposure)
        x0 = x - (cell_w - w) // 2  # the cell's left edge
        label = np.zeros((band, cell_w, 3), np.float32)
        label[:m.shape[0], :m.shape[1], :] = m[:, :cell_w, None] * np.asarray(TEXT_RGB,
                                                                              np.float32)
        out[y + h:y + cell_h, x0:x0 + cell_w] = np.round(label).astype(np.uint8)
    return out


def tile_boxes(tiles_shape: tuple, count: int, columns: int, band: int,
               cell_width: int | None = None):
    """(x, y, w, h) of each tile's image inside a compose() result; tiles_shape = (h, w)
    of one tile, band the label band's height, cell_width the cells' width (default the
    tile's; wider cells centre the image). For tests and image maps."""
    h, w = tiles_shape
    cell_w = max(w, int(cell_width or w))
    return [((i % columns) * (cell_w + GAP) + (cell_w - w) // 2,
             (i // columns) * (h + band + GAP), w, h) for i in range(count)]
