"""Render a .blend with the Photon Mapping engine from the command line (bpy wheel).

    python -m addon.batch FILE.blend -o out.png [--samples N] [--photons N]
        [--caustic-photons N] [--resolution-percentage P] [--width W --height H]
        [--no-photon-mapping] [--show-photons] [--seed S] [--frame F]
        [--frames A..B] [--animated-seed] [--dask ADDRESS]

The equivalent of `blender --background FILE.blend -E PHOTONMAP -o out -f 1`: opens the
file, registers the add-on, selects the engine, renders with write_still. The output
format follows the file extension (.png, .exr, .jpg, .tif). Errors are reported in one
line on stderr with a non-zero exit status.

--frames A..B renders every frame from A to B (inclusive) into the output pattern: '#'
in the name becomes the frame number, zero-padded to the count of '#' (out/f_####.png);
without '#', '_####' is added before the extension. --dask renders the progressive passes
of each frame on a Dask cluster (docs/distributed.md).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

FORMATS = {".png": "PNG", ".exr": "OPEN_EXR", ".jpg": "JPEG", ".jpeg": "JPEG",
           ".tif": "TIFF", ".tiff": "TIFF", ".bmp": "BMP"}


class BatchError(Exception):
    pass


def parse_args(argv):
    p = argparse.ArgumentParser(prog="python -m addon.batch",
                                description="Render a .blend with the Photon Mapping engine.")
    p.add_argument("blend", help="the .blend file to render")
    p.add_argument("-o", "--output", required=True, help="output image (.png, .exr, ...)")
    p.add_argument("--samples", type=int, help="camera samples per pixel")
    p.add_argument("--photons", type=int, help="global photons")
    p.add_argument("--caustic-photons", type=int, help="caustic photons")
    p.add_argument("--max-depth", type=int, help="max specular ray depth")
    p.add_argument("--seed", type=int, help="random seed")
    p.add_argument("--threads", type=int, help="threads (0 = all cores)")
    p.add_argument("--resolution-percentage", type=int, help="resolution scale in percent")
    p.add_argument("--width", type=int, help="image width in pixels (before percentage)")
    p.add_argument("--height", type=int, help="image height in pixels (before percentage)")
    p.add_argument("--no-photon-mapping", action="store_true",
                   help="plain ray tracing (direct light only)")
    p.add_argument("--show-photons", action="store_true", help="draw photon hits")
    p.add_argument("--frame", type=int, help="frame to render")
    p.add_argument("--frames", type=_frame_range, metavar="A..B",
                   help="render frames A to B (inclusive) into the output pattern ('#' = "
                        "frame digits)")
    p.add_argument("--animated-seed", action="store_true",
                   help="a different seed on every frame (the add-on's Animated Seed)")
    p.add_argument("--dask", metavar="ADDRESS",
                   help="progressive passes on a Dask cluster: tcp://HOST:8786 or local:W")
    p.add_argument("--quiet", action="store_true", help="less Blender output")
    return p.parse_args(argv)


def _frame_range(text):
    first, sep, last = text.partition("..")
    try:
        a, b = int(first), int(last)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected A..B (e.g. 1..24), got '{text}'") from None
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


def render_file(args) -> str:
    blend = os.path.abspath(args.blend)
    if not os.path.isfile(blend):
        raise BatchError(f"blend file not found: {args.blend}")
    out = os.path.abspath(args.output)
    ext = os.path.splitext(out)[1].lower()
    if ext not in FORMATS:
        raise BatchError(f"unsupported output extension '{ext or '(none)'}' "
                         f"(use one of {', '.join(sorted(FORMATS))})")
    for name in ("samples", "photons", "caustic_photons", "width", "height",
                 "resolution_percentage"):
        _positive(name.replace("_", "-"), getattr(args, name),
                  0 if "photons" in name else 1)
    _positive("max-depth", args.max_depth, 0)
    _positive("seed", args.seed, 0)
    _positive("threads", args.threads, 0)
    os.makedirs(os.path.dirname(out) or ".", exist_ok=True)

    try:
        import bpy
    except ImportError as exc:
        raise BatchError(f"cannot import bpy (Blender as a Python module): {exc}") from None
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if root not in sys.path:
        sys.path.insert(0, root)
    import addon
    from addon.engine import ENGINE_ID
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    try:
        bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
    except RuntimeError as exc:
        raise BatchError(f"cannot open {args.blend}: {str(exc).strip()}") from None
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
        if getattr(args, option) is not None:
            setattr(target, prop, getattr(args, option))
    if args.no_photon_mapping:
        pm.photon_mapping = False
    if args.show_photons:
        pm.show_photons = True
    if args.animated_seed:
        pm.use_animated_seed = True
    if args.dask:
        pm.dask_scheduler = args.dask
    if args.frame is not None:
        scene.frame_set(args.frame)
    r.image_settings.file_format = FORMATS[ext]
    r.use_file_extension = False
    if scene.camera is None:
        raise BatchError(f"{args.blend}: the scene has no active camera")
    if args.frames is None:
        _render_still(bpy, r, out)
        return out
    pattern = frame_pattern(out)
    written = []
    for frame in range(args.frames[0], args.frames[1] + 1):
        scene.frame_set(frame)
        r.filepath = pattern
        path = r.frame_path(frame=frame)  # '#' -> zero-padded frame number
        _render_still(bpy, r, path)
        written.append(path)
    return f"{len(written)} frames: {written[0]} .. {written[-1]}"


def _render_still(bpy, r, path):
    r.filepath = path
    try:
        bpy.ops.render.render(write_still=True)
    except RuntimeError as exc:
        msg = " ".join(str(exc).replace("Error:", "").split())
        raise BatchError(f"render failed: {msg}") from None
    if not os.path.isfile(path):
        raise BatchError(f"render finished but {path} was not written")


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    t0 = time.perf_counter()
    try:
        out = render_file(args)
    except BatchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    print(f"wrote {out} ({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
