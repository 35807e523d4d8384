"""Render a .blend with the Photon Mapping engine from the command line (bpy wheel).

    python -m addon.batch FILE.blend -o out.png [--samples N] [--photons N]
        [--caustic-photons N] [--resolution-percentage P] [--width W --height H]
        [--no-photon-mapping] [--show-photons] [--radius R] [--estimator E]
        [--final-gather | --no-final-gather] [--paper] [--seed S] [--frame F]
        [--frames A..B] [--animated-seed] [--dask ADDRESS]
        [--method local|raytrace|photon] [--save-passes] [--strip]
    python -m addon.batch FILE.blend --compare -o grid.png [--preview-size N]
    python -m addon.batch FILE.blend --sweep photons=1000,10000,100000 -o ladder.png
    python -m addon.batch FILE.blend --sweep-preset paper-ladder -o ladder.png

The equivalent of `blender --background FILE.blend -E PHOTONMAP -o out -f 1`: opens the
file, registers the add-on, selects the engine and renders. The output format follows the
file extension (.png, .exr, .jpg, .tif). On stderr: the render's phase and a progress bar
with ETA (the bpy module prints no stats line of its own, so the engine's status is read
from addon.engine.status_listeners), then the effect report, as the CLI shows them. The
warnings are printed on stdout when they arise, each once on a line of its own above the
bar, Python's own (numpy's, numba's) on stderr likewise (engine/console.py).

Output integrity: the output path is checked for writability before the file is opened;
the image is saved only after a complete render, to a temporary file beside the target
that then replaces it (os.replace). A render that fails, or is interrupted (Ctrl-C /
SIGINT, from the command's first moment, also while Blender loads: the render is
cancelled at its next poll, a second Ctrl-C stops at once), writes nothing and leaves an
existing file as it was. SIGTERM (a job's timeout, a render farm's cancel) is handled as
Ctrl-C. Errors are one line on stderr; exit status 1 for errors, 130 when interrupted
(143 for SIGTERM).

--frames A..B renders every frame from A to B (inclusive) into the output pattern: '#'
in the name becomes the frame number, zero-padded to the count of '#' (out/f_####.png);
without '#', '_####' is added before the extension. --dask renders the progressive passes
of each frame on a Dask cluster (docs/distributed.md).

Teaching images (docs/teaching.md, addon/operators.py): --compare renders the three
methods and the photon hits into one labelled grid, --sweep / --sweep-preset a labelled
ladder of one parameter, both at a preview size (--preview-size, the longer side) with
the Preview quality preset unless --samples / --photons / --caustic-photons are given.
--strip writes the effect passes side by side with their sum (name.strip.png) beside a
render, --save-passes each pass as name.direct.png ... (.exr for an .exr output) and the view
layer's data passes (Denoising Data, Diffuse / Glossy / Transmission Color) as
name.denoising_albedo.exr ...
"""
from __future__ import annotations

import os
import signal
import sys

# Ctrl-C from the first moment of a command-line run: while numpy, the engine and Blender
# load (seconds), an interrupt only sets this flag, which main() then acts on as a
# cancel; a second one stops at once. Python's own handler would raise KeyboardInterrupt
# inside those imports: a traceback, or, inside bpy's initialisation, a lost signal or a
# crash.
_early_interrupts: list = []


def _early_interrupt(signum, frame):
    if _early_interrupts:
        _stop_at_once(_early_interrupts[0])
    _early_interrupts.append(signum)


def _stop_at_once(signum=signal.SIGINT):
    """The second Ctrl-C (or SIGTERM): leave now, exit status 128 + the first signal's
    number. The output is only ever replaced whole (a temporary file, then os.replace),
    so it is the old file or the new one; a KeyboardInterrupt raised inside Blender's C
    code could crash it instead."""
    print("\ninterrupt: stopped at once; nothing more is written", file=sys.stderr, flush=True)
    os._exit(128 + int(signum))


if __name__ == "__main__":
    for _signal in (signal.SIGINT, signal.SIGTERM):  # a job's timeout sends SIGTERM
        signal.signal(_signal, _early_interrupt)

import argparse  # noqa: E402
import contextlib  # noqa: E402
import re  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402

from engine.cli import CancelOnInterrupt  # noqa: E402
from engine.console import BarConsole  # noqa: E402
from engine.imageio import check_writable, replacing, say_created  # noqa: E402
from engine.jit import is_compile_text  # noqa: E402

INTERRUPT_MESSAGE = "\ninterrupt: cancelling (Ctrl-C again to stop at once)"

FORMATS = {".png": "PNG", ".exr": "OPEN_EXR", ".jpg": "JPEG", ".jpeg": "JPEG",
           ".tif": "TIFF", ".tiff": "TIFF", ".bmp": "BMP"}


class BatchError(Exception):
    pass


class BatchInterrupted(BatchError):
    pass


# How Blender prints an engine's report (bpy.ops prints the operator's reports on
# sys.stdout when it returns): "Warning: " + the add-on's "Photon Mapping: " + the text.
WARNING_LINE = "Warning: Photon Mapping: {}"
# The add-on's overflow (addon/engine.py, past MAX_REPORTED_WARNINGS): a print each, and
# one report that points at the console, which is this output.
OVERFLOW_LINE = "Photon Mapping warning: {}"
OVERFLOW_REPORT = re.compile(r"Warning: Photon Mapping: \d+ more warnings \(see the system "
                             r"console\)")


class _StatusPrinter:
    """Listener for addon.engine.status_listeners: a tqdm bar on stderr with the phase,
    the fraction of the whole render and the ETA, then the effect report.

    Warnings go to stdout the moment the engine has them (an unsupported shader is said
    before the long render, not after it), each on a line of its own with the bar
    continuing below (write_line, engine/console.py); Blender's own print of the same
    reports, when the render operator returns, is then left out (beside_bar). Blender
    printed them glued to the bar's line where stdout and stderr share a file (`... > log
    2>&1`): the bar had been cleared when the warning came, but Blender prints its reports
    only later, after the bar had redrawn itself (new-user trial, s17). Python's warnings
    raised during the render (numpy's, numba's, ours) go the same way, on stderr."""

    def __init__(self, quiet=False, stream=None, interrupt=None, out=None,
                 previous_effects=None):
        self.quiet = quiet
        # An animation's earlier frame's report: a frame that simulates the same effects
        # says so in one line instead of repeating the report (--frames).
        self.previous_effects = previous_effects
        self.interrupt = interrupt  # its at_once is set while the kernels compile
        self.stream = stream or sys.stderr
        self.out = out  # where warnings go (None: sys.stdout at the time)
        # The bar and every line beside it: one writer, one lock (engine/console.py).
        self.console = BarConsole(self.stream)
        self.status = None  # the engine's "finished" value
        self.film = None  # the engine's Film of the finished render
        self.effects = []
        self.warnings = []
        self.done_line = None  # the engine's closing "Done: ..." in full, printed at close
        self.stage = None  # the engine's stage of the progress to come ("stage" events)
        self._shown = []  # lines printed at a warning event, still to come from Blender

    @property
    def bar(self):
        return self.console.bar

    def _ensure_bar(self):
        if self.console.bar is None and not self.quiet:
            from engine.eta import Eta, progress_bar
            # The time left from the rate after the kernel compile and the first chunk, in
            # the camera pass (engine/eta.py); tqdm's own {remaining} counted the compile in.
            self.eta = Eta(final_stage="render")
            self.console.bar = progress_bar("Starting", "{desc:<46.46}{bar}| "
                                            "{percentage:3.0f}% [{elapsed}<{eta}]",
                                            self.console.bar_file, self.eta)
        return self.console.bar

    def __call__(self, event, value):
        # One writer at a time: the bar, the warnings and Blender's lines (write_line).
        with self.console.lock:
            self._event(event, value)

    def _event(self, event, value):
        if event == "finished":
            self.status = value
        elif event == "film":
            self.film = value
        elif event == "effects":
            self.effects = list(value)
        elif event == "stage":
            self.stage = str(value)
        elif event == "warning":
            self.warnings.append(str(value))
            if not self.quiet:
                self.write_line(WARNING_LINE.format(value))
                self._shown += [WARNING_LINE.format(value), OVERFLOW_LINE.format(value)]
        if event in ("stats", "progress") and self.interrupt is not None:
            # The compile polls nothing for a minute and has nothing to keep: Ctrl-C then
            # stops at once (engine.cli.CancelOnInterrupt.at_once).
            self.interrupt.at_once = event == "stats" and is_compile_text(value)
        if event in ("stats", "progress") and not self.quiet:
            self._ensure_bar()
            with self.console.drawing() as bar:
                if event == "stats":
                    text = str(value)
                    compiling = is_compile_text(text)
                    # The bar's clock moves through steps that report nothing (the
                    # compile, a slow estimator chunk).
                    self.console.keep_alive(True)
                    if compiling:
                        self.eta.restart()
                    if text.startswith("Done: "):
                        # The bar's description column (46 characters) cut this summary
                        # off mid-number ("... 139.0 s (+ 5.4"): the bar says Done, close()
                        # prints it.
                        self.done_line, text = text, "Done"
                    bar.set_description_str(text, refresh=True)
                elif event == "progress":
                    self.eta.update(float(value), self.stage)
                    n = int(round(1000 * min(max(float(value), 0.0), 1.0)))
                    if n > bar.n:
                        bar.update(n - bar.n)

    def write_line(self, line, out=None, end="\n"):
        """Print one line of other output (a warning, Blender's reports) on a line of its
        own, the bar continuing below it (engine/console.py, BarConsole.write_line)."""
        self.console.write_line(line, self.out or out or sys.stdout, end)

    def blender_line(self, line, out, end="\n"):
        """A line Blender (or the add-on) prints on stdout during the render: left out
        when it repeats a warning printed when it came, else printed beside the bar."""
        with self.console.lock:
            if line in self._shown:
                self._shown.remove(line)
                return
            if self.warnings and OVERFLOW_REPORT.fullmatch(line):
                return  # every warning was printed here: "see the system console" is moot
            if (self.status or "").startswith("error: ") and line == "Error: " + self.status[7:]:
                return  # Blender's print of the failure (twice): the run's "render failed" says it
        self.write_line(line, out, end)

    @contextlib.contextmanager
    def beside_bar(self):
        """sys.stdout through blender_line while Blender renders (bpy.ops prints the
        operator's reports there when it returns), and Python's warnings (numpy's,
        numba's, ours, on any thread) through the console onto lines of their own on
        stderr, unless quiet. Entered once, on the main thread, around the render."""
        real = sys.stdout
        sys.stdout = _LineWriter(real, self.blender_line)
        try:
            with (contextlib.nullcontext() if self.quiet else self.console.python_warnings()):
                yield
        finally:
            if isinstance(sys.stdout, _LineWriter):
                sys.stdout.close_pending()
            sys.stdout = real

    def close(self):
        """Close the bar, then print the effect report of a finished render under it (a
        cancelled or failed render simulated nothing worth reporting)."""
        self.console.close()
        # The warnings are not repeated here: they were printed when they came
        # (write_line), or, quiet, by Blender in background mode (self.warnings keeps them).
        if not self.quiet:
            if self.status == "done":
                if self.done_line:
                    print(self.done_line, file=self.stream)
                lines = self.effects
                if self.effects and self.previous_effects:
                    # Only the lines that changed (a moving object changes the photon
                    # counts, seldom the effects): the whole report of about 2 KB a
                    # frame buried a classroom's batch log (newuser42).
                    lines = [x for x in self.effects if x not in self.previous_effects]
                    gone = [x for x in self.previous_effects if x not in self.effects]
                    print("  Effects as the previous frame"
                          + (", except:" if lines or gone else ""), file=self.stream)
                    lines = lines + [f"no longer: {x}" for x in gone]
                for line in lines:
                    print(f"  {line}", file=self.stream)


class _LineWriter:
    """A stand-in for sys.stdout that hands whole lines to line_out(line, out, end) (the
    printer's blender_line) and is the real stream `out` in everything else."""

    def __init__(self, out, line_out):
        self._out = out
        self._line_out = line_out
        self._pending = ""
        self._lock = threading.Lock()

    def write(self, text):
        with self._lock:
            self._pending += text
            lines = self._pending.split("\n")
            self._pending = lines.pop()
        for line in lines:
            self._line_out(line, self._out)
        return len(text)

    def flush(self):
        self._out.flush()

    def close_pending(self):
        """The rest of a line written without its newline, as it was."""
        with self._lock:
            rest, self._pending = self._pending, ""
        if rest:
            self._line_out(rest, self._out, "")

    def __getattr__(self, name):
        return getattr(self._out, name)


def parse_args(argv):
    # No abbreviations (engine/cli.py's reason: '--photon 100' was taken as --photons).
    p = argparse.ArgumentParser(prog="python -m addon.batch",
                                description="Render a .blend with the Photon Mapping engine.",
                                allow_abbrev=False)
    p.add_argument("blend", help="the .blend file to render")
    p.add_argument("-o", "--output", required=True, help="output image (.png, .exr, ...)")
    # The engine CLI's names (--spp, --workers) are accepted as well: one user runs both.
    p.add_argument("--samples", "--spp", type=int, help="camera samples per pixel")
    p.add_argument("--photons", type=int, help="global photons")
    p.add_argument("--caustic-photons", type=int, help="caustic photons")
    p.add_argument("--max-depth", type=int, help="max specular ray depth")
    p.add_argument("--seed", type=int, help="random seed")
    p.add_argument("--threads", "--workers", type=int, help="threads (0 = all cores)")
    p.add_argument("--resolution-percentage", type=int, help="resolution scale in percent")
    p.add_argument("--width", type=int, help="image width in pixels (before percentage)")
    p.add_argument("--height", type=int, help="image height in pixels (before percentage)")
    p.add_argument("--no-photon-mapping", action="store_true",
                   help="plain ray tracing (direct light only)")
    p.add_argument("--show-photons", action="store_true",
                   help="the image is the photon-hit view (dots by photon kind on black)")
    p.add_argument("--radius", type=float,
                   help="max photon search radius in scene units (metres); 0 = automatic")
    p.add_argument("--estimator", choices=("knn_simpson", "knn_cone", "classic", "radius"),
                   help="radiance estimator")
    gather = p.add_mutually_exclusive_group()
    gather.add_argument("--final-gather", dest="final_gather", action="store_true",
                        default=None, help="indirect light by final gathering")
    gather.add_argument("--no-final-gather", dest="final_gather", action="store_false",
                        help="indirect light read from the global photon map directly")
    p.add_argument("--paper", action="store_true",
                   help="the paper's own method: classic estimator, fixed --radius, no final "
                        "gathering (docs/paper_mode.md)")
    p.add_argument("--frame", type=_frame, help="frame to render")
    p.add_argument("--frames", type=_frame_range, metavar="A..B",
                   help="render frames A to B (inclusive) into the output pattern ('#' = "
                        "frame digits)")
    p.add_argument("--animated-seed", action="store_true",
                   help="a different seed on every frame (the add-on's Animated Seed)")
    p.add_argument("--progressive", action="store_true",
                   help="progressive passes (the Progressive panel); implied by --passes / "
                        "--time-limit")
    p.add_argument("--passes", type=int, help="progressive: stop after N passes")
    p.add_argument("--time-limit", type=float, metavar="SECONDS",
                   help="progressive: stop before a pass would end past this time")
    p.add_argument("--dask", metavar="ADDRESS",
                   help="progressive passes on a Dask cluster: tcp://HOST:8786 or local:W")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar or effect report")
    p.add_argument("--method", choices=("local", "raytrace", "photon"),
                   help="local: direct light without shadows, mirrors or glass; raytrace: "
                        "shadows, mirrors and glass (paper Fig. 5b); photon: the full renderer")
    p.add_argument("--save-passes", action="store_true",
                   help="also write each effect pass and the photon-hit view next to the "
                        "output (name.direct.png ... name.photon_hits.png) and the view "
                        "layer's data passes as linear OpenEXR (name.denoising_albedo.exr ...)")
    p.add_argument("--strip", action="store_true",
                   help="also write the effect passes and their sum side by side, labelled "
                        "(name.strip.png)")
    teach = p.add_mutually_exclusive_group()
    teach.add_argument("--compare", action="store_true",
                       help="render local, raytrace and photon and the photon hits into one "
                            "labelled grid (the output) instead of a render")
    teach.add_argument("--sweep", action="append", metavar="NAME=V1,V2,...",
                       help="render one tile per value (photons, radius, k, spp, ray_depth, "
                            "photon_depth) into a labelled ladder; repeat to sweep together")
    teach.add_argument("--sweep-preset", choices=("paper-ladder",),
                       help="the paper's Figure 6 ladder (1k / r 4.0 ... 200k / r 0.4)")
    p.add_argument("--reference", metavar="IMAGE",
                   help="--sweep: measure the errors against this image (EXR for linear "
                        "values, the tiles' size) instead of against the last tile")
    p.add_argument("--preview-size", type=int, default=160,
                   help="--compare / --sweep: longer side of each tile in pixels")
    return p.parse_args(argv)


# Blender's frame numbers (MINAFRAME / MAXFRAME in DNA_scene_types.h).
FRAME_LIMIT = 1048574


def _frame(text):
    try:
        frame = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole frame number, got '{text}'") from None
    if abs(frame) > FRAME_LIMIT:
        raise argparse.ArgumentTypeError(f"Blender's frames run from {-FRAME_LIMIT} to "
                                         f"{FRAME_LIMIT}, got {frame}")
    return frame


def _frame_range(text):
    first, sep, last = text.partition("..")
    try:
        a, b = _frame(first), _frame(last)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"{exc} in '{text}' (expected A..B, e.g. 1..24)") from None
    if not sep or b < a:
        raise argparse.ArgumentTypeError(f"expected A..B with A <= B, got '{text}'")
    return a, b


def frame_pattern(path: str) -> str:
    """The output pattern of a frame range: path itself if it has '#', else '_####'
    inserted before the extension."""
    if "#" in os.path.basename(path):
        return path
    root, ext = os.path.splitext(path)
    return f"{root}_####{ext}"


def _positive(name, value, lo=1):
    if value is not None and value < lo:
        raise BatchError(f"--{name} must be >= {lo}, got {value}")


def _interrupted(interrupt, out, stage):
    """Raise BatchInterrupted when Ctrl-C came in while `stage` (before the render)."""
    if interrupt is not None and interrupt.requested:
        raise BatchInterrupted(f"interrupted while {stage}: nothing rendered; "
                               f"{_untouched(out)}")


def render_file(args, interrupt=None) -> str:
    """Render (or compose the teaching image of) args; returns what was written.
    interrupt: the CancelOnInterrupt whose Ctrl-C cancels the run (main() enters one
    before Blender loads); None: one for each render. Raises BatchError /
    BatchInterrupted with one line."""
    blend = os.path.abspath(args.blend)
    if not os.path.isfile(blend):
        raise BatchError(f"blend file not found: {args.blend}")
    out = os.path.abspath(args.output)
    if os.path.isdir(out):
        raise BatchError(f"--output '{args.output}' is a folder: give an image file, e.g. "
                         f"'{os.path.join(args.output, 'render.png')}'")
    ext = os.path.splitext(out)[1].lower()
    if ext not in FORMATS:
        raise BatchError(f"unsupported output extension '{ext or '(none)'}' "
                         f"(use one of {', '.join(sorted(FORMATS))})")
    for name in ("samples", "photons", "caustic_photons", "width", "height",
                 "resolution_percentage"):
        _positive(name.replace("_", "-"), getattr(args, name),
                  0 if "photons" in name else 1)
    _positive("max-depth", args.max_depth, 0)
    _positive("preview-size", args.preview_size)
    teaching = args.compare or args.sweep or args.sweep_preset
    if teaching and ext not in (".png", ".jpg", ".jpeg"):
        raise BatchError(f"a labelled teaching image is written as .png or .jpg, not "
                         f"'{ext}'")
    if teaching and args.frames is not None:
        raise BatchError("--compare / --sweep render one frame: use --frame, not --frames")
    _positive("seed", args.seed, 0)
    _positive("threads", args.threads, 0)
    _positive("passes", args.passes)
    if args.time_limit is not None and not (args.time_limit > 0 and args.time_limit < float("inf")):
        raise BatchError(f"--time-limit must be a number of seconds > 0, got {args.time_limit}")
    if args.radius is not None and not (args.radius >= 0 and args.radius < float("inf")):
        raise BatchError(f"--radius must be a number >= 0 (0 = automatic), got {args.radius}")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if root not in sys.path:
        sys.path.insert(0, root)
    try:
        check_writable(out, on_create=say_created)  # before the render, not after it
    except OSError as exc:
        raise BatchError(str(exc)) from None

    _interrupted(interrupt, out, "starting")
    try:
        import bpy
    except ImportError as exc:
        raise BatchError(f"cannot import bpy (Blender as a Python module): {exc}") from None
    import addon
    from addon.engine import ENGINE_ID
    _interrupted(interrupt, out, "loading Blender")
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    _interrupted(interrupt, out, "loading the add-on")
    try:
        bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
    except RuntimeError as exc:
        raise BatchError(f"cannot open {args.blend}: {str(exc).strip()}") from None
    _interrupted(interrupt, out, f"reading {args.blend}")
    scene = bpy.context.scene
    r = scene.render
    r.engine = ENGINE_ID
    pm = scene.photonmap
    # (command-line option, object, property) for the options that set a property as given
    for option, target, prop in (("samples", pm, "spp"), ("photons", pm, "photons"),
                                 ("caustic_photons", pm, "caustic_photons"),
                                 ("max_depth", pm, "max_depth"), ("seed", pm, "seed"),
                                 ("threads", pm, "threads"), ("width", r, "resolution_x"),
                                 ("height", r, "resolution_y"),
                                 ("resolution_percentage", r, "resolution_percentage")):
        value = getattr(args, option)
        if value is not None:
            # The property's own range: Blender clamps a value outside it silently (or,
            # beyond a 32-bit int, raises): refuse it naming the option instead.
            rna = target.bl_rna.properties[prop]
            if not rna.hard_min <= value <= rna.hard_max:
                raise BatchError(f"--{option.replace('_', '-')} must be from {rna.hard_min:,} "
                                 f"to {rna.hard_max:,} (Blender's '{rna.name}'), got "
                                 f"{value:,}")
            setattr(target, prop, value)
    if args.no_photon_mapping:
        pm.photon_mapping = False
    if args.show_photons:
        pm.show_photons = True
    if args.radius is not None:
        pm.use_auto_radius = args.radius == 0
        if args.radius > 0:
            pm.radius = args.radius
    if args.estimator is not None:
        pm.estimator = args.estimator
    if args.final_gather is not None:
        pm.final_gather = args.final_gather
    if args.paper:
        pm.paper_mode = True
    if args.animated_seed:
        pm.use_animated_seed = True
    if args.progressive or args.passes is not None or args.time_limit is not None:
        pm.progressive = True
        if args.passes is not None:
            pm.max_passes = args.passes
        if args.time_limit is not None:
            pm.time_limit = args.time_limit
            if args.passes is None:
                pm.max_passes = 0  # as the engine CLI: a time limit alone sets no pass limit
    if args.dask:
        pm.dask_scheduler = args.dask
    if args.method:
        pm.method = args.method
    if args.frame is not None:
        scene.frame_set(args.frame)
    if hasattr(r.image_settings, "media_type"):
        # Blender 5: the media type limits the formats (a .blend saved with OpenEXR
        # MultiLayer output offers that format alone: "PNG" was refused, a traceback).
        r.image_settings.media_type = "IMAGE"
    r.image_settings.file_format = FORMATS[ext]
    r.use_file_extension = False
    if scene.camera is None:
        raise BatchError(f"{args.blend}: the scene has no active camera")
    if teaching:
        return _teaching_image(bpy, scene, args, out, interrupt)
    if args.frames is None:
        film = _render_still(bpy, scene, out, args.quiet, interrupt)
        _extras(bpy, film, out, args)
        return out
    pattern = frame_pattern(out)
    written = []
    effects = None
    for frame in range(args.frames[0], args.frames[1] + 1):
        scene.frame_set(frame)
        r.filepath = pattern
        path = r.frame_path(frame=frame)  # '#' -> zero-padded frame number
        film = _render_still(bpy, scene, path, args.quiet, interrupt, effects)
        effects = list(film.stats.get("effects") or []) if film is not None else None
        _extras(bpy, film, path, args)
        written.append(path)
    return f"{len(written)} frames: {written[0]} .. {written[-1]}"


def _teaching_image(bpy, scene, args, out, interrupt=None) -> str:
    """--compare / --sweep: the labelled image of addon/operators.py, saved to `out`."""
    from addon import operators
    explicit = any(getattr(args, n) is not None for n in ("samples", "photons",
                                                           "caustic_photons"))
    params = {}
    try:
        from addon.core import load_engine
        teaching = load_engine().teaching
        for text in args.sweep or []:
            name, values = teaching.parse_param(text)
            params[name] = values
        kind = "compare" if args.compare else "sweep"
        printer = _StatusPrinter(quiet=args.quiet)

        def progress(stage, fraction, text):
            printer("stats", text)
            printer("progress", fraction)

        # Blender's own SIGINT handler would swallow Ctrl-C: ours turns it into a cancel.
        interrupt = interrupt or CancelOnInterrupt(INTERRUPT_MESSAGE)
        try:
            with interrupt, printer.beside_bar():
                t0 = time.perf_counter()
                tiles, rgb8 = operators.teaching_image(
                    kind, scene, bpy.context.evaluated_depsgraph_get(), args.preview_size,
                    "scene" if explicit else "preview", params, args.sweep_preset or "none",
                    progress, reference=args.reference or "",
                    should_cancel=lambda: interrupt.requested)
                # The grid's renders (its tiles) are the run's rendering time: they do not
                # go through the render engine, so engine.last_render does not hold them.
                _RUN_TIMES["render"] += time.perf_counter() - t0
        finally:
            printer.close()
    except KeyboardInterrupt:
        raise BatchInterrupted(f"interrupted; {_untouched(out)}") from None
    except Exception as exc:  # noqa: BLE001 - one line: ValueError, SceneError, ...
        if type(exc).__name__ == "Cancelled":
            raise BatchInterrupted(f"interrupted: render cancelled; {_untouched(out)}") from None
        raise BatchError(f"{exc}; {_untouched(out)}") from None
    image = operators.store_image(operators.IMAGE_NAMES[kind], rgb8)
    try:
        operators.save_image(image, out)
    except (OSError, RuntimeError) as exc:
        raise BatchError(f"cannot write {out}: {str(exc).strip()}; {_untouched(out)}") from None
    if not args.quiet:
        for t in tiles:
            print("  " + " | ".join(line for line in t.lines if line), file=sys.stderr)
    return out


def _extras(bpy, film, out, args):
    """--save-passes and --strip beside a finished render's output `out`."""
    if not (args.save_passes or args.strip):
        return
    if film is None:
        raise BatchError("the engine returned no image to take the passes from")
    from addon import operators
    from addon.core import load_engine
    pm = load_engine()
    root, ext = os.path.splitext(out)
    if args.save_passes:
        # The effect passes and the photon-hit view (newuser42: a teacher had to render
        # --show-photons apart for it), then the view layer's data passes (Denoising Data,
        # the Color passes) as linear EXR: as the CLI writes them.
        pass_ext = ext if ext in pm.imageio.FORMATS else ".png"
        film.write_passes(root, pass_ext, spp=bpy.context.scene.photonmap.spp)
    if args.strip:
        tiles = pm.teaching.effects_strip(film)
        rgb8 = pm.teaching.compose(tiles, len(tiles), label_mask=operators.blf_label_mask)
        operators.save_image(operators.store_image(operators.IMAGE_NAMES["strip"], rgb8),
                             f"{root}.strip.png")


def _render_still(bpy, scene, out, quiet, interrupt=None, previous_effects=None):
    """Render the current frame and save it to `out` only when the render is complete.
    previous_effects: the effect report of the frame before (an animation), not repeated
    when this frame's is the same. Returns the engine's Film of the render."""
    from addon import engine
    # write_still=True would save whatever the render result holds, also after an error
    # or a cancel (an all-black frame over a good one): save it here, only when complete.
    previous_hook = engine.test_break_hook
    interrupt = interrupt or CancelOnInterrupt(INTERRUPT_MESSAGE)
    printer = _StatusPrinter(quiet=quiet, interrupt=interrupt,
                             previous_effects=previous_effects)
    engine.test_break_hook = lambda: interrupt.requested or bool(previous_hook and previous_hook())
    engine.status_listeners.append(printer)
    try:
        with interrupt, printer.beside_bar():
            bpy.ops.render.render(write_still=False)
    except RuntimeError as exc:
        if interrupt.requested:  # a second SIGINT landed inside Blender's render call
            raise BatchInterrupted(f"interrupted: render cancelled; {_untouched(out)}") from None
        # The engine's own message once (Blender's exception repeats each report).
        msg = engine.last_render.get("error") or " ".join(str(exc).replace("Error:", "").split())
        raise BatchError(f"render failed: {msg}; {_untouched(out)}") from None
    finally:
        engine.status_listeners.remove(printer)
        engine.test_break_hook = previous_hook
        printer.close()
    # Every frame's render and kernel load count in the run's closing time split.
    stats = engine.last_render.get("stats") or {}
    _RUN_TIMES["render"] += float(engine.last_render.get("time", 0.0))
    _RUN_TIMES["compile"] += float(stats.get("time_compile") or 0.0)
    status = printer.status
    if interrupt.requested and status != "done":
        raise BatchInterrupted(f"interrupted: render cancelled; {_untouched(out)}")
    if status is None or status.startswith("error"):
        msg = engine.last_render.get("error") or "the engine did not render the scene"
        raise BatchError(f"render failed: {msg}; {_untouched(out)}")
    if status == "cancelled":
        raise BatchInterrupted(f"render cancelled; {_untouched(out)}")
    try:
        with replacing(out) as tmp:
            bpy.data.images["Render Result"].save_render(filepath=tmp, scene=scene)
    except (OSError, RuntimeError) as exc:
        raise BatchError(f"cannot write {out}: {str(exc).strip()}; "
                         f"{_untouched(out)}") from None
    return printer.film


# Seconds this run spent rendering (the engine's renders, every frame of --frames; the
# teaching grid's tiles) and loading or compiling kernels, for _main's closing time split.
_RUN_TIMES = {"render": 0.0, "compile": 0.0}


def _untouched(out):
    return f"{out} left as it was" if os.path.exists(out) else f"{out} not written"


def main(argv=None) -> int:
    # The command line's Ctrl-C: one handler for the whole run, from before Blender loads
    # (an interrupt that came earlier still, while the modules loaded, counts too).
    interrupt = CancelOnInterrupt(INTERRUPT_MESSAGE)
    interrupt.on_second = lambda: _stop_at_once(interrupt.signum or signal.SIGINT)
    with interrupt:
        if _early_interrupts:
            interrupt.request(_early_interrupts[0])
        return _main(argv, interrupt)


def _main(argv, interrupt) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    t0 = time.perf_counter()
    _RUN_TIMES.update(render=0.0, compile=0.0)
    try:
        out = render_file(args, interrupt)
    except BatchInterrupted as exc:
        print(f"error: {exc}", file=sys.stderr)
        return interrupt.status
    except KeyboardInterrupt:
        print(f"error: interrupted; {_untouched(os.path.abspath(args.output))}",
              file=sys.stderr)
        return interrupt.status
    except BatchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    # The engine's "Done ... s" above is the render alone; this line splits the whole run
    # (a first render's kernel compile would otherwise read as a slow .blend load).
    total = time.perf_counter() - t0
    from addon import engine
    render_s, compile_s = _RUN_TIMES["render"], _RUN_TIMES["compile"]
    words = engine.kernel_words((engine.last_render.get("stats") or {})
                                .get("kernels_compiled", True))
    compiled = f", {words} {compile_s:.1f} s" if compile_s >= 0.5 else ""
    print(f"wrote {out} ({total:.1f} s: rendering {render_s:.1f} s{compiled}, Blender start-up, "
          f"loading the .blend and writing the image "
          f"{max(total - render_s - compile_s, 0.0):.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
