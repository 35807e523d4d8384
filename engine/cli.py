"""Command line: `photonmap render SCENE.toml -o out.png [options]`, and the teaching
images (engine/teaching.py, docs/teaching.md): `photonmap compare SCENE.toml -o grid.png`
(the three methods and the photon hits) and `photonmap sweep SCENE.toml --param
photons=1000,10000 -o ladder.png` (or `--preset paper-ladder`).

Errors are one line naming the argument or file, with a non-zero exit status. The output
path is checked before the render starts, and the image replaces the target only once it
is completely written (engine/imageio.py). Ctrl-C (or SIGTERM: a job's timeout, a render
farm's cancel) cancels the render: the target is left untouched (exit status 130; 143 for
SIGTERM), or with --keep-partial the finished part is written, marked partial in its
metadata. A second one stops at once, as does the first during the kernel compile.

Warnings are printed on stderr when they arise ("photonmap: warning: ..."), each once on a
line of its own above the progress bar, also where stdout and stderr share a file; Python's
own warnings raised during the render (numpy's, numba's, any thread's) likewise
(engine/console.py, shared with addon/batch.py)."""
from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import threading

import numpy as np

from . import shadowcatcher
from .eta import Eta
from .settings import ESTIMATORS, METHODS, RenderSettings
from .teaching import SWEEP_PRESETS

_DEFAULTS = RenderSettings()


def _whole_number(text, least):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got '{text}'") from None
    if v < least:
        raise argparse.ArgumentTypeError(f"must be >= {least}, got {v}")
    return v


def _nonnegative_int(text):
    return _whole_number(text, 0)


def _positive_int(text):
    return _whole_number(text, 1)


def _finite_float(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got '{text}'") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return v


EXPOSURE_RANGE = (-32.0, 32.0)  # stops, Blender's (View Transform > Exposure)


def _exposure(text):
    v = _finite_float(text)
    lo, hi = EXPOSURE_RANGE
    if not lo <= v <= hi:
        raise argparse.ArgumentTypeError(f"must be from {lo:g} to {hi:g} stops (as "
                                         f"Blender's), got {text}")
    return v


def _positive_float(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got '{text}'") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
    return v


def _noise_threshold(text):
    from .settings import ADAPTIVE_THRESHOLD_MAX
    v = _finite_float(text)
    if not 0.0 <= v <= ADAPTIVE_THRESHOLD_MAX:
        raise argparse.ArgumentTypeError(f"must be from 0 (off) to {ADAPTIVE_THRESHOLD_MAX:g} "
                                         f"(as Cycles' Noise Threshold), got {text}")
    return v


def _clamp(text):
    from .settings import CLAMP_MAX
    v = _finite_float(text)
    if not 0.0 <= v <= CLAMP_MAX:
        raise argparse.ArgumentTypeError(f"must be from 0 (off) to {CLAMP_MAX:g} (as Cycles' "
                                         f"Clamping), got {text}")
    return v


QUALITY_PRESETS = ("preview", "medium", "high", "reference")


def _kinds(text: str, valid) -> tuple:
    """A comma-separated list of `valid` words (--data-passes, --cryptomatte)."""
    kinds = tuple(k.strip() for k in text.split(",") if k.strip())
    if not kinds or any(k not in valid for k in kinds):
        raise argparse.ArgumentTypeError(f"takes {', '.join(valid)} (comma-separated), "
                                         f"got {text!r}")
    return kinds


def _data_passes(text: str) -> tuple:
    """--data-passes' value: comma-separated kinds of RenderSettings.DATA_PASSES."""
    from .settings import DATA_PASSES
    return _kinds(text, DATA_PASSES)


def _cryptomatte(text: str) -> tuple:
    """--cryptomatte's value: comma-separated kinds of RenderSettings.CRYPTOMATTE_KINDS."""
    from .settings import CRYPTOMATTE_KINDS
    return _kinds(text, CRYPTOMATTE_KINDS)


def _setting_options(r, method=True, sweeps=False):
    """Options that set RenderSettings or the image size, shared by the subcommands."""
    if sweeps:
        r.add_argument("--preset", choices=QUALITY_PRESETS + tuple(SWEEP_PRESETS),
                       help="quality preset (docs/accuracy_time.md), or a predefined sweep: "
                            "paper-ladder = the paper's Figure 6 rungs 1k / r 4.0 ... 200k / "
                            "r 0.4 (paper units, x0.2 m) with the classic estimator and no "
                            "final gather; other options override it")
    else:
        r.add_argument("--preset", choices=QUALITY_PRESETS,
                       help="quality preset (docs/accuracy_time.md has its measured time and "
                            "error); other options override it")
    r.add_argument("--photons", type=_nonnegative_int, help="global photons to emit")
    r.add_argument("--caustic-photons", type=_nonnegative_int,
                   help="caustic photons to emit (default: with --photons, scaled with them "
                        "in the scene file's ratio, else half as many)")
    r.add_argument("--radius", type=_positive_float,
                   help="max photon search radius in scene units, metres (the paper's "
                        "MaxPhotonSearchRadius; default: auto from the photon spacing)")
    r.add_argument("--min-photons", type=_nonnegative_int, help="fewer photons found -> no estimate")
    r.add_argument("--k", dest="k_nearest", type=_positive_int, help="photons per k-NN estimate")
    r.add_argument("--estimator", choices=ESTIMATORS, help="radiance estimator")
    r.add_argument("--spp", type=_positive_int, help="camera samples per pixel (adaptive "
                   "sampling: the most a pixel takes)")
    # Cycles' Sampling > Noise Threshold / Min Samples (engine/adaptive.py)
    r.add_argument("--noise-threshold", dest="adaptive_threshold", type=_noise_threshold,
                   help="adaptive sampling: a pixel stops once its noise is below this (as "
                        "Cycles' Noise Threshold, e.g. 0.01; default 0: off, every pixel "
                        "takes --spp)")
    r.add_argument("--min-samples", dest="adaptive_min_samples", type=_nonnegative_int,
                   help="adaptive sampling: samples every pixel takes first (Cycles' Min "
                        "Samples; default 0: auto from the threshold)")
    # Cycles' Light Paths > Clamping (engine/sampleclamp.py)
    r.add_argument("--clamp-direct", dest="clamp_direct", type=_clamp,
                   help="each camera sample's direct light at most this per channel on "
                        "average (Cycles' Clamping > Direct Light; default 0: off)")
    r.add_argument("--clamp-indirect", dest="clamp_indirect", type=_clamp,
                   help="each camera sample's indirect light at most this per channel on "
                        "average (Cycles' Clamping > Indirect Light, 10 in Blender; default "
                        "0: off)")
    r.add_argument("--max-depth", type=_nonnegative_int,
                   help="an extra cap on the mirror / glass bounces of camera rays (default "
                        "1024: none, the bounce limits below stop them, as in Cycles)")
    r.add_argument("--max-photon-depth", type=_nonnegative_int, help="max photon bounces")
    # Cycles' Light Paths > Max Bounces (engine/settings.py, same defaults 12 / 4 / 4 / 12)
    r.add_argument("--max-bounces", type=_nonnegative_int,
                   help="most bounces of a light path in all (Cycles' Total, default 12)")
    r.add_argument("--diffuse-bounces", type=_nonnegative_int,
                   help="most diffuse bounces of a light path (default 4; 0: direct light only)")
    r.add_argument("--glossy-bounces", type=_nonnegative_int,
                   help="most glossy / mirror bounces of a light path (default 4)")
    r.add_argument("--transmission-bounces", type=_nonnegative_int,
                   help="most refractions of a light path (default 12)")
    r.add_argument("--light-samples", type=_positive_int, help="shadow rays per area light")
    r.add_argument("--seed", type=_nonnegative_int, help="random seed (same seed, same image)")
    r.add_argument("--workers", type=_nonnegative_int, help="threads (0 = all cores)")
    r.add_argument("--width", type=_positive_int, help="image width (overrides the file)")
    r.add_argument("--height", type=_positive_int, help="image height (overrides the file)")
    if method:
        r.add_argument("--method", choices=METHODS,
                       help="local: direct light without shadows, mirrors or glass; raytrace: "
                            "shadows, mirrors and glass (paper Fig. 5b); photon: the full "
                            "renderer (default; docs/teaching.md)")
    r.add_argument("--no-photon-mapping", action="store_true",
                   help="plain ray tracing: direct light and mirrors only (paper Fig. 5b)")
    r.add_argument("--no-caustics", action="store_true", help="skip the caustic map")
    for name in ("caustics", "indirect", "specular", "soft-shadows"):
        r.add_argument(f"--{name}", choices=("auto", "on", "off"),
                       help=f"force {name.replace('-', ' ')} on or off (default: auto, decided "
                            "from the scene)")
    r.add_argument("--no-final-gather", action="store_true",
                   help="show the global photon map directly (faster, blotchier)")
    r.add_argument("--paper", action="store_true",
                   help="the paper's own method: classic estimator (cosine-weighted, fixed "
                        "--radius in scene units, metres), no final gathering "
                        "(docs/paper_mode.md)")
    r.add_argument("--exposure", type=_exposure, default=0.0,
                   help="exposure in stops for PNG/PPM, -32 to 32")
    r.add_argument("--quiet", action="store_true", help="no progress bar")


def _teaching_options(r):
    """Output and size of the labelled teaching images (engine/teaching.py)."""
    r.add_argument("-o", "--output", required=True, help="output image: .png or .jpg")
    r.add_argument("--preview-size", type=_positive_int, default=None,
                   help="longer image side of each tile in pixels when --width / --height "
                        "are not given (default 160)")
    r.add_argument("--columns", type=_positive_int, help="tiles per row of the grid")


def build_parser() -> argparse.ArgumentParser:
    # No abbreviations: a misspelt '--photon 100' was taken as --photons 100 without a word
    # (new-user trial, s22); a wrong option name is refused with the usage instead.
    p = argparse.ArgumentParser(prog="photonmap", description="Photon mapping renderer",
                                allow_abbrev=False)
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render a TOML scene file to an image", allow_abbrev=False)
    r.add_argument("scene", help="scene file (.toml, see docs/scene_format.md)")
    r.add_argument("-o", "--output", required=True,
                   help="output image: .png (sRGB), .exr (linear float), .ppm, .npy")
    r.add_argument("--progressive", action="store_true",
                   help="render passes of fresh photons with a shrinking search area until "
                        "a budget (--passes / --time-limit / --target-error) is reached")
    r.add_argument("--passes", type=_nonnegative_int, help="progressive: stop after N passes")
    r.add_argument("--time-limit", type=_positive_float, help="progressive: stop within T seconds")
    r.add_argument("--target-error", type=_positive_float,
                   help="progressive: stop when the estimated relMSE is below this")
    r.add_argument("--dask", metavar="ADDRESS",
                   help="progressive passes on a Dask cluster: local:W (W worker processes "
                        "here) or tcp://HOST:8786 (a running scheduler); same image as without "
                        "(docs/distributed.md)")
    _setting_options(r)
    r.add_argument("--show-photons", action="store_true",
                   help="write the photon-hit view (dots by photon kind on black, paper Fig. "
                        "6, left) as the image; --save-passes writes it beside any render")
    r.add_argument("--save-passes", action="store_true",
                   help="also write each effect pass next to the output (name.direct.png ...) "
                        "and any --data-passes as linear OpenEXR (name.denoising_albedo.exr ...)")
    r.add_argument("--cryptomatte", type=_cryptomatte, metavar="KINDS",
                   help="Cryptomatte ID mattes to make, comma-separated: object, material, "
                        "asset; written with --save-passes as name.cryptomatte.exr (the "
                        "spec's channels and manifest, for Blender, Nuke or Fusion)")
    r.add_argument("--cryptomatte-levels", type=int, metavar="N",
                   help="Cryptomatte ranks a pixel, 1-16 (default 6)")
    r.add_argument("--data-passes", type=_data_passes, metavar="KINDS",
                   help="Cycles' data passes to make, comma-separated: denoising (Denoising "
                        "Normal / Albedo / Depth), color (Diffuse / Glossy / Transmission "
                        "Color), light (Cycles' Diffuse / Glossy / Transmission Direct and "
                        "Indirect, Emission, Environment; brings color), object_index, "
                        "material_index, position, uv, mist, ao (Ambient Occlusion, rays of "
                        "--ao-distance); written with --save-passes")
    r.add_argument("--light-groups", type=lambda t: tuple(x.strip() for x in t.split(",")
                                                          if x.strip()),
                   metavar="NAMES",
                   help="Light Group passes to make, comma-separated group names (the "
                        "scene file's lightgroup = \"NAME\" on lights, objects and "
                        "world_lightgroup): each the image of its emitters alone, written "
                        "with --save-passes as name.lightgroup_NAME.exr")
    r.add_argument("--ao-distance", type=float, metavar="M",
                   help="the Ambient Occlusion pass' ray length in metres (Blender's World > "
                        "Ambient Occlusion > Distance; default 10)")
    r.add_argument("--strip", action="store_true",
                   help="also write the effect passes and their sum side by side, labelled, "
                        "as name.strip.png (docs/teaching.md)")
    r.add_argument("--keep-partial", action="store_true",
                   help="on Ctrl-C, write the part of the image finished so far (marked "
                        "partial in its metadata) instead of leaving the output untouched")

    c = sub.add_parser("compare", help="render a scene with each method (local, raytrace, "
                                       "photon) and the photon hits into one labelled grid",
                       allow_abbrev=False)
    c.add_argument("scene", help="scene file (.toml, see docs/scene_format.md)")
    _teaching_options(c)
    _setting_options(c, method=False)

    w = sub.add_parser("sweep", help="render a scene for each value of a parameter into one "
                                     "labelled ladder with times and errors", allow_abbrev=False)
    w.add_argument("scene", help="scene file (.toml, see docs/scene_format.md)")
    _teaching_options(w)
    w.add_argument("--param", action="append", default=[], metavar="NAME=V1,V2,...",
                   help="parameter and its values, coarse to fine: photons, radius (metres), "
                        "k, spp, ray_depth, photon_depth; repeat to sweep several together")
    w.add_argument("--reference", metavar="IMAGE",
                   help="error against this image (.exr / .npy linear, same size as the tiles) "
                        "instead of against the last tile")
    _setting_options(w, sweeps=True)
    p.commands = {"render": r, "compare": c, "sweep": w}  # main(): errors in their words
    return p


class CancelOnInterrupt:
    """While active, the first Ctrl-C (SIGINT) or SIGTERM (a job's timeout or a render
    farm's cancel) only sets `requested`, which the render polls as its should_cancel,
    and prints `message` to `stream` if one is given; a second one calls on_second()
    (default: raises KeyboardInterrupt at once). `status` is the exit status of the
    interrupted command: 128 + the signal's number (130 for Ctrl-C, 143 for SIGTERM).
    Used by this CLI and by addon/batch.py."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self, message=None, stream=None, on_second=None):
        self.requested = False
        self.signum = None
        self.message = message
        self.stream = stream or sys.stderr
        self.on_second = on_second
        # True while a step runs that polls nothing and has nothing to keep (the kernel
        # compile, a minute): the first Ctrl-C stops at once, as a second one.
        self.at_once = False
        self._previous = {}
        self._depth = 0

    @property
    def status(self) -> int:
        return 128 + int(self.signum or signal.SIGINT)

    def request(self, signum=signal.SIGINT) -> None:
        """As if the signal had come now (the batch's interrupts before Blender loaded)."""
        self.requested = True
        self.signum = self.signum or signum
        if self.message:
            print(self.message, file=self.stream, flush=True)

    def _handler(self, signum, frame):
        if self.requested or self.at_once:
            self.signum = self.signum or signum
            if self.on_second is not None:
                self.on_second()
            raise KeyboardInterrupt
        self.request(signum)

    def __enter__(self):
        # Re-entrant: the batch command holds one for its whole run and each render
        # enters it again; the handlers before the outermost entry come back at its exit.
        self._depth += 1
        if self._depth == 1 and threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:  # signals: main thread only
                self._previous[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc):
        self._depth -= 1
        if self._depth == 0:
            for sig, previous in self._previous.items():
                signal.signal(sig, previous if previous is not None else signal.SIG_DFL)
            self._previous = {}
        return False


def main(argv=None) -> int:
    from . import _interrupted_while_loading
    if signal.getsignal(signal.SIGINT) is _interrupted_while_loading:
        # Loaded: Ctrl-C is a KeyboardInterrupt again (a cancel inside the render, a clean
        # stop elsewhere); engine/__init__ stopped at once only while the imports ran.
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        # Said by the subcommand's parser: its usage lists the options it takes (the
        # top-level usage named only the subcommands).
        parser.commands[args.command].error(f"unrecognized arguments: {' '.join(unknown)}")
    try:
        return {"render": _render, "compare": _compare, "sweep": _sweep}[args.command](args)
    except KeyboardInterrupt:
        print("photonmap: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError, ImportError) as e:  # ImportError: --dask without dask
        print(f"photonmap: error: {e}", file=sys.stderr)
        return 1


def _scene_and_overrides(args, preset_overrides=None, preview=False):
    """The scene file with the size options applied, and the RenderSettings keywords:
    quality preset, then the file's [render] table, then the options. preview: without
    --width / --height the image is scaled to --preview-size (engine/teaching.py)."""
    from . import presets
    from .scenefile import load_scene
    scene, file_overrides = load_scene(args.scene)
    # The teaching images default to the preview quality: they render several images.
    quality = args.preset if args.preset in presets.PRESETS else ("preview" if preview else None)
    overrides = presets.apply(quality) if quality else {}
    overrides.update(file_overrides)
    overrides.update(preset_overrides or {})
    # The counts before the options: --photons alone scales the caustic photons in this
    # ratio (below).
    counts = ((int(overrides.get("photons", _DEFAULTS.photons)),
               int(overrides["caustic_photons"])) if "caustic_photons" in overrides
              else (_DEFAULTS.photons, _DEFAULTS.caustic_photons))
    if preview and args.width is None and args.height is None:
        from .teaching import PREVIEW_LONG_SIDE, preview_scene
        scene = preview_scene(scene, args.preview_size or PREVIEW_LONG_SIDE)
    if args.width is not None:
        scene.width = args.width
    if args.height is not None:
        scene.height = args.height
    for name in ("photons", "caustic_photons", "radius", "min_photons", "k_nearest", "estimator",
                 "spp", "max_depth", "max_photon_depth", "light_samples", "seed", "workers",
                 "method", "max_bounces", "diffuse_bounces", "glossy_bounces",
                 "transmission_bounces", "adaptive_threshold", "adaptive_min_samples",
                 "clamp_direct", "clamp_indirect",
                 "data_passes", "ao_distance", "light_groups", "cryptomatte",
                 "cryptomatte_levels"):
        v = getattr(args, name, None)
        if v is not None:
            overrides[name] = v
    if args.photons is not None and args.caustic_photons is None:
        # --photons alone scales the caustic photons too, in the ratio the preset or
        # the scene file set with its caustic count (else the defaults'; 0 stays 0): a
        # quick 5,000-photon render should not trace 200,000 caustic photons. The scene
        # file's own count stood before (newuser42:
        # paper mode's "--photons 1000" on figure6.toml kept its 100,000 caustic photons
        # and took 35 minutes instead of 3).
        base, caustic = counts
        from .settings import LIMITS
        overrides["caustic_photons"] = min(args.photons * caustic // base if base > 0
                                           else caustic, LIMITS["caustic_photons"])
    if args.no_photon_mapping:
        overrides["photon_mapping"] = False
    for name in ("caustics", "indirect", "specular", "soft_shadows"):
        if getattr(args, name) is not None:
            overrides[name] = getattr(args, name)
    if args.no_caustics:
        overrides["caustics"] = "off"
    if args.no_final_gather:
        overrides["final_gather"] = False
    if args.paper:
        overrides["paper_mode"] = True
    return scene, overrides


TEACHING_FORMATS = (".png", ".jpg", ".jpeg")


def _not_a_folder(path, ext):
    """An existing folder as the output: say so (rather than 'unsupported format')."""
    if os.path.isdir(path):
        raise ValueError(f"--output '{path}' is a folder: give an image file, e.g. "
                         f"'{os.path.join(path, 'render' + ext)}'")


def _check_teaching_output(path):
    from .imageio import check_writable, say_created
    _not_a_folder(path, ".png")
    ext = os.path.splitext(path)[1].lower()
    if ext not in TEACHING_FORMATS:
        raise ValueError(f"--output '{path}': unsupported format '{ext or '(none)'}' for a "
                         f"labelled image (use {', '.join(TEACHING_FORMATS)})")
    check_writable(path, on_create=say_created)


def save_composed(rgb8, path):
    """Write a composed uint8 image (engine/teaching.py) to `path` atomically (Pillow)."""
    from PIL import Image

    from .imageio import replacing
    ext = os.path.splitext(path)[1].lower()
    with replacing(path) as tmp:
        Image.fromarray(rgb8).save(tmp, format="JPEG" if ext in (".jpg", ".jpeg") else "PNG",
                                   optimize=True)


def _teaching_run(args, make_tiles, what):
    """Progress bar, Ctrl-C and output of compare / sweep: make_tiles(progress,
    should_cancel) -> tiles, composed and written to args.output."""
    from .console import BarConsole
    from .parallel import Cancelled
    from .teaching import compose
    console = BarConsole(sys.stderr)
    if not args.quiet:
        from tqdm import tqdm
        console.bar = tqdm(total=1000, desc="Preparing", unit="",
                           bar_format="{desc:<44.44}{bar}| {elapsed}", file=console.bar_file)

    interrupt = CancelOnInterrupt()

    def progress(stage, fraction, text):
        interrupt.at_once = stage == "compile"  # polls nothing for a minute
        with console.drawing() as bar:
            if bar is not None:
                bar.set_description_str(text)
                bar.n = int(1000 * fraction)
                bar.refresh()

    try:
        with interrupt, _python_warnings(console, args.quiet):
            tiles = make_tiles(progress, lambda: interrupt.requested)
    except (Cancelled, KeyboardInterrupt):
        console.close()
        print(f"photonmap: interrupted: '{args.output}' left untouched", file=sys.stderr)
        return interrupt.status
    finally:
        console.close()
    save_composed(compose(tiles, args.columns, args.exposure), args.output)
    if not args.quiet:
        for t in tiles:
            print("  " + " | ".join(line for line in t.lines if line), file=sys.stderr)
        print(f"wrote {args.output} ({what}, {len(tiles)} tiles of "
              f"{tiles[0].image.shape[1]}x{tiles[0].image.shape[0]})", file=sys.stderr)
    return 0


def _compare(args) -> int:
    from .resources import check_resources
    from .teaching import compare_methods
    _check_teaching_output(args.output)
    scene, overrides = _scene_and_overrides(args, preview=True)
    settings = RenderSettings(**overrides)
    scene.validate()
    check_resources(scene, settings)
    return _teaching_run(args, lambda progress, cancel: compare_methods(
        scene, settings, progress, cancel), "methods compared")


def _sweep(args) -> int:
    from .imageio import read_image
    from .resources import check_resources
    from .teaching import SWEEP_PRESETS, parse_param, sweep
    _check_teaching_output(args.output)
    params, preset_settings = {}, {}
    if args.preset in SWEEP_PRESETS:
        params.update(SWEEP_PRESETS[args.preset]["params"])
        preset_settings = SWEEP_PRESETS[args.preset]["settings"]
    for text in args.param:
        name, values = parse_param(text)
        params[name] = values
    if not params:
        raise ValueError("sweep: give --param NAME=V1,V2,... or --preset paper-ladder")
    scene, overrides = _scene_and_overrides(args, preset_settings, preview=True)
    settings = RenderSettings(**overrides)
    reference = None
    if args.reference:
        if not os.path.isfile(args.reference):
            raise ValueError(f"--reference '{args.reference}': file not found")
        reference = read_image(args.reference)
    scene.validate()
    # The largest value of each swept setting bounds the memory (engine/resources.py).
    from dataclasses import replace

    from .teaching import SWEEP_PARAMS
    check_resources(scene, replace(settings, **{SWEEP_PARAMS[n][0]: max(v)
                                                for n, v in params.items() if n != "radius"}))
    return _teaching_run(args, lambda progress, cancel: sweep(
        scene, settings, params, reference, progress, cancel), "sweep")


def _python_warnings(console, quiet):
    """Python's warnings through the console while its bar is shown (engine/console.py);
    quiet: no bar to keep whole, Python prints them as usual."""
    import contextlib
    return contextlib.nullcontext() if quiet else console.python_warnings()


def _render(args) -> int:
    from .imageio import FORMATS, write_image
    from .progressive import Budget, render_progressive
    from .render import render

    _not_a_folder(args.output, ".png")
    ext = os.path.splitext(args.output)[1].lower()
    if ext not in FORMATS:
        raise ValueError(f"--output '{args.output}': unsupported format '{ext or '(none)'}' "
                         f"(use {', '.join(FORMATS)})")
    scene, overrides = _scene_and_overrides(args)
    if args.show_photons:
        overrides["show_photons"] = True
    settings = RenderSettings(**overrides)
    progressive = args.progressive or bool(args.dask) or any(
        v is not None for v in (args.passes, args.time_limit, args.target_error))
    from .resources import check_resources
    scene.validate()
    check_resources(scene, settings, progressive=progressive)  # before the progress bar
    from .imageio import check_writable, say_created
    # After the scene file and the settings are accepted (a refused render leaves no new
    # folder behind), before the render.
    check_writable(args.output, on_create=say_created)

    from .console import BarConsole
    console = BarConsole(sys.stderr)  # the bar and every line beside it (engine/console.py)
    # Warnings are said when they arise, each on a line of its own with the bar below,
    # once each, as the batch command does (addon/batch.py): the scene's (what its file
    # asks that cannot render as asked, broken meshes) now, before the long render; the
    # effect analysis' when the render has it (on_warning), before the photons; a
    # hand-set search radius' once the photon maps are built, before the camera pass;
    # with --dask each as a worker finds it (engine/distributed.py).
    # Once each by render.warning_key: a cluster's passes may tell a search radius'
    # warning in a later pass' words (the first to arrive) than film.warnings lists.
    from .render import warning_key
    said = set()

    def say_one(warning):
        if warning_key(warning) not in said:
            said.add(warning_key(warning))
            console.write_line(f"photonmap: warning: {warning}", sys.stderr)

    def say(warnings):
        for w in warnings:
            say_one(w)

    say(scene.all_warnings())
    interrupt = CancelOnInterrupt()
    where = {"stage": "preparing", "fraction": 0.0, "passes": 0}
    # The stages' shares of the bar by their work (engine/stagespans.py), re-sized by the
    # render's photon plan (render's on_plan; a progressive pass keeps the settings').
    from .stagespans import StageSpans
    spans = StageSpans(settings.uses_photon_maps, settings.photons + settings.caustic_photons,
                       scene.width * scene.height * settings.spp)
    # The bar shows the fraction of the whole render and the time left (engine/eta.py:
    # measured after the kernel compile and the first chunk, not from the start, and in
    # one render from the camera pass' own rate: each pass of a progressive one has every
    # stage, its rate over passes).
    passes = args.passes if progressive and not args.dask else None
    eta = (_TimeLeft(args.time_limit) if progressive and args.time_limit and not passes
           else Eta(final_stage="render"))
    if not args.quiet:
        from .eta import progress_bar
        console.bar = progress_bar("Preparing", "{desc:<42.42}{bar}| {percentage:3.0f}% "
                                   "[{elapsed}<{eta}]", console.bar_file, eta)

    def progress(stage, fraction, text):
        where["stage"], where["fraction"] = stage, fraction
        interrupt.at_once = stage == "compile"  # polls nothing for a minute
        console.keep_alive(True)  # the bar's clock moves through steps that report nothing
        if stage == "compile":
            eta.restart()
        whole = spans.whole(stage, fraction)
        if whole is not None and args.dask:
            whole = fraction  # the cluster reports the fraction of the budget
        elif whole is not None and progressive:
            whole = (where["passes"] + whole) / passes if passes else None
        if whole is not None:
            eta.update(whole, None if progressive or args.dask else stage)
        with console.drawing() as bar:
            if bar is None:
                return
            bar.set_description_str(text, refresh=False)
            if whole is None:  # no share of the whole known (--target-error): the stage's
                bar.n = int(1000 * min(max(fraction, 0.0), 1.0))
            elif int(1000 * whole) > bar.n:
                bar.n = int(1000 * whole)
            bar.refresh()

    def should_cancel():
        # The engine's first poll ends the start, see below.
        interrupt.at_once = where["stage"] == "compile"
        return interrupt.requested

    # Until the engine first polls should_cancel it loads (or compiles) its kernels:
    # seconds to minutes of work that polls nothing and has nothing to keep, so a Ctrl-C
    # stops at once (newuser42: 20 s on a loaded machine). Not on a cluster, whose start
    # owns processes to stop.
    interrupt.at_once = not args.dask
    try:
        if progressive:
            budget = Budget(args.passes or None, args.time_limit, args.target_error)

            def on_pass(film, info):
                where["passes"] = info["passes"]
                if not args.quiet:
                    error = info["error_estimate"]  # two passes are needed to estimate it
                    error = f"{error:.4f}" if math.isfinite(error) else "after pass 2"
                    console.write_line(f"pass {info['passes']}: {info['photons']:,} photons, "
                                       f"{info['elapsed']:.1f} s, estimated relMSE {error}")
            with interrupt, _python_warnings(console, args.quiet):
                if args.dask:
                    from .distributed import render_distributed
                    film = render_distributed(scene, settings, budget, address=args.dask,
                                              progress=progress, on_pass=on_pass,
                                              should_cancel=should_cancel,
                                              on_warning=say_one)
                else:
                    film = render_progressive(scene, settings, budget, progress=progress,
                                              on_pass=on_pass, should_cancel=should_cancel,
                                              on_warning=say_one)
        else:
            with interrupt, _python_warnings(console, args.quiet):
                film = render(scene, settings, progress=progress, should_cancel=should_cancel,
                              on_warning=say_one, on_plan=spans.plan)
        say(film.warnings)  # each was said when it arose (on_warning): none is left
    except KeyboardInterrupt:  # a second Ctrl-C, or the first during the kernel compile
        console.close()
        again = " (the next run compiles them again)" if where["stage"] == "compile" else ""
        print(f"photonmap: interrupted while {_stage_text(where)}: '{args.output}' left "
              f"untouched{again}", file=sys.stderr)
        return interrupt.status
    finally:
        console.close()
    partial = None
    # A Ctrl-C that came after the last poll left a complete image: write it as usual.
    if film.stats.get("cancelled"):
        partial = _finished_part(film, progressive, where)
        if not args.keep_partial or partial is None:
            kept = ("nothing was finished to keep; " if args.keep_partial else "")
            print(f"photonmap: interrupted while {_stage_text(where)}: {kept}"
                  f"'{args.output}' left untouched"
                  + ("" if args.keep_partial else " (--keep-partial writes the finished part)"),
                  file=sys.stderr)
            return interrupt.status
    if not args.quiet:
        for line in film.stats.get("effects", []):
            print(f"  {line}", file=sys.stderr)
    meta = {"photonmap:effects": "\n".join(film.stats.get("effects", [])),
            "photonmap:settings": repr(settings)}
    if partial is not None:
        meta["photonmap:partial"] = f"interrupted: {partial}"
    # RGBA where the image has transparency to carry (a transparent film, holdouts), as
    # Blender writes it; .ppm has no alpha channel.
    alpha = film.alpha if (settings.film_transparent or bool(np.any(film.holdout > 0))) else None
    rgb = film.combined
    caught = None if film.show_photons else shadowcatcher.combined_rgba(
        film, settings.film_transparent)
    if caught is not None:  # shadow catchers: Cycles' approximate shadow catcher
        rgb = caught[..., :3]
        alpha = caught[..., 3] if settings.film_transparent else None
    write_image(rgb, args.output, args.exposure, metadata=meta, alpha=alpha)
    if partial is not None:
        print(f"photonmap: interrupted: wrote the partial image to '{args.output}' ({partial}; "
              "marked 'photonmap:partial' in its metadata)", file=sys.stderr)
        return interrupt.status
    if args.save_passes:
        root, ext = os.path.splitext(args.output)
        film.write_passes(root, ext, args.exposure, settings.spp)
        if film.catcher is not None:  # Cycles' Shadow Catcher pass: data, linear EXR
            write_image(shadowcatcher.shadow_catcher_pass(film, settings.film_transparent),
                         f"{root}.shadow_catcher.exr")
        if film.cryptomatte:
            from .imageio import write_cryptomatte
            write_cryptomatte(film.cryptomatte, film.cryptomatte_names,
                              f"{root}.cryptomatte.exr")
    if args.strip:
        from .teaching import compose, effects_strip
        save_composed(compose(effects_strip(film), columns=6, exposure=args.exposure),
                      f"{os.path.splitext(args.output)[0]}.strip.png")
    st = film.stats
    if not args.quiet:
        # A progressive render's pixels took spp samples in each of its passes (adaptive
        # sampling is off in progressive passes).
        passes = st.get("passes") if st.get("progressive") else None
        if passes is not None:
            samples = f"{passes} passes x {settings.spp} spp"
        elif "adaptive_mean_spp" in st:
            samples = f"adaptive: {st['adaptive_mean_spp']:.1f} of {settings.spp} spp a pixel"
        else:
            samples = f"{settings.spp} spp"
        print(f"wrote {args.output} ({scene.width}x{scene.height}, {samples}, "
              f"{st.get('time_total', 0):.1f} s)", file=sys.stderr)
    return 0


class _TimeLeft:
    """The time left of a progressive render with only a --time-limit: the limit minus
    the time since the render started, as its budget counts it (Eta's interface)."""

    def __init__(self, limit: float):
        import time
        self.limit, self.clock = float(limit), time.monotonic
        self.start = self.clock()

    def restart(self):
        pass

    def update(self, fraction):
        pass

    def text(self) -> str:
        from .eta import format_seconds
        return format_seconds(max(0.0, self.limit - (self.clock() - self.start)))


def _stage_text(where) -> str:
    names = {"photons": "tracing photons", "photon_map": "building the photon map",
             "render": "rendering", "compile": "compiling the render kernels"}
    if where["stage"] in ("compile", "preparing"):
        return names.get(where["stage"], where["stage"])
    return f"{names.get(where['stage'], where['stage'])} ({100 * where['fraction']:.0f} %)"


def _finished_part(film, progressive: bool, where) -> str | None:
    """What of a cancelled render is finished, in words, or None if nothing is. Camera
    samples run pixel by pixel from the top row (engine/integrator.py), so a camera pass
    cancelled at fraction f has the top f of the image's pixels finished."""
    if progressive:
        passes = int(film.stats.get("passes", 0))
        return f"{passes} complete pass(es)" if passes > 0 else None
    if where["stage"] != "render" or where["fraction"] <= 0:
        return None
    rows = math.floor(where["fraction"] * film.height)
    return (f"{100 * where['fraction']:.0f} % of the camera samples: the top {rows} of "
            f"{film.height} rows")


if __name__ == "__main__":
    sys.exit(main())
