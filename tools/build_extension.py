"""Download the pinned wheels and build the Blender extension zips (make extension).

    .venv/bin/python tools/build_extension.py [--platforms linux-x64,...] [--output-dir dist]
        [--no-download] [--no-manifest-update]

1. `pip download --only-binary=:all: --no-deps --python-version 3.11 --platform TAG`
   embreex, scipy, numba and llvmlite for every platform into wheels/ (numba and
   llvmlite stop at 0.62.1 / 0.45.1 on macOS x86_64: that platform pins those).
2. Write the manifest's `wheels = [...]` list (all platforms; only when building all).
3. Stage the package (manifest, __init__.py, addon/, engine/, the selected wheels) under
   build/extension/ and build it with Blender's own tool (blender_ext.py from the bpy
   wheel) with --split-platforms: one zip per platform in dist/.
"""
from __future__ import annotations

import argparse
import glob
import os
import re
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MANIFEST = os.path.join(ROOT, "blender_manifest.toml")
WHEELS_DIR = os.path.join(ROOT, "wheels")
PYTHON_VERSION = "3.11"
PINNED = ("embreex==4.4.0.post1", "scipy==1.17.1", "numba==0.68.1", "llvmlite==0.50.0")
# Platforms whose newest wheels are older than PINNED: package name -> pin. numba 0.62.1
# and llvmlite 0.45.1 are the last releases with macOS x86_64 wheels; both accept the
# numpy Blender 4.5 / 5.0 ship (1.26.4).
PLATFORM_PINS = {
    "macos-x64": {"numba": "numba==0.62.1", "llvmlite": "llvmlite==0.45.1"},
}
# Blender platform -> pip --platform tags (pip accepts wheels for these or older).
PLATFORMS = {
    "windows-x64": ["win_amd64"],
    "macos-arm64": ["macosx_13_0_arm64"],
    "macos-x64": ["macosx_13_0_x86_64"],
    "linux-x64": ["manylinux_2_28_x86_64"],
}
# Wheel platform-tag patterns that belong to each Blender platform.
WHEEL_PATTERNS = {
    "windows-x64": re.compile(r"win_amd64"),
    "macos-arm64": re.compile(r"macosx_\d+_\d+_(arm64|universal2)"),
    "macos-x64": re.compile(r"macosx_\d+_\d+_(x86_64|universal2|intel)"),
    "linux-x64": re.compile(r"manylinux\w*_x86_64"),
}
PACKAGE_FILES = ("__init__.py", "blender_manifest.toml")
PACKAGE_DIRS = ("addon", "engine")


def blender_ext_path() -> str:
    import importlib.util
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("error: the bpy wheel is not installed (make venv)")
    base = list(spec.submodule_search_locations)[0]
    hits = glob.glob(os.path.join(base, "*", "scripts", "addons_core", "bl_pkg", "cli",
                                  "blender_ext.py"))
    if not hits:
        raise SystemExit(f"error: blender_ext.py not found inside {base}")
    return sorted(hits)[-1]


def pins_for(platform: str) -> list[str]:
    """The pinned requirements (name==version) for one Blender platform."""
    override = PLATFORM_PINS.get(platform, {})
    return [override.get(pin.split("==")[0], pin) for pin in PINNED]


def download(platforms, dest=WHEELS_DIR):
    os.makedirs(dest, exist_ok=True)
    for plat in platforms:
        cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--only-binary=:all:",
               "--no-deps", "--python-version", PYTHON_VERSION, "--dest", dest]
        for tag in PLATFORMS[plat]:
            cmd += ["--platform", tag]
        cmd += pins_for(plat)
        print(f"downloading wheels for {plat}")
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            raise SystemExit(f"error: pip download for {plat} failed:\n{res.stderr.strip()}")


def wheels_for(platforms, src=WHEELS_DIR) -> list[str]:
    """Wheel file names in src for the pinned packages and the given platforms."""
    chosen = []
    for plat in platforms:
        for pin in pins_for(plat):
            name, version = pin.split("==")
            files = sorted(os.path.basename(p) for p in glob.glob(
                os.path.join(src, f"{name}-{version}-*.whl")))
            match = [f for f in files if WHEEL_PATTERNS[plat].search(f.rsplit("-", 1)[-1])]
            if not match:
                raise SystemExit(f"error: no {name} {version} wheel for {plat} in {src} "
                                 "(run without --no-download)")
            # Prefer the wheel for the oldest OS (most compatible).
            chosen.append(sorted(match)[0])
    return sorted(set(chosen))


def write_manifest(path, wheels, platforms=None):
    text = open(path, encoding="utf-8").read()
    body = "wheels = [\n" + "".join(f'  "./wheels/{w}",\n' for w in wheels) + "]"
    text, n = re.subn(r"(?ms)^wheels\s*=\s*\[.*?^\]", body, text)
    if n == 0:
        text = text.rstrip() + "\n\n" + body + "\n"
    if platforms is not None:
        plist = "platforms = [" + ", ".join(f'"{p}"' for p in platforms) + "]"
        text = re.sub(r"(?m)^platforms\s*=\s*\[.*?\]", plist, text)
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)


def stage(stage_dir, wheels, platforms):
    if os.path.isdir(stage_dir):
        shutil.rmtree(stage_dir)
    os.makedirs(os.path.join(stage_dir, "wheels"))
    for name in PACKAGE_FILES:
        shutil.copy2(os.path.join(ROOT, name), os.path.join(stage_dir, name))
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in PACKAGE_DIRS:
        shutil.copytree(os.path.join(ROOT, name), os.path.join(stage_dir, name), ignore=ignore)
    for w in wheels:
        src = os.path.join(WHEELS_DIR, w)
        dst = os.path.join(stage_dir, "wheels", w)
        try:
            os.link(src, dst)
        except OSError:
            shutil.copy2(src, dst)
    write_manifest(os.path.join(stage_dir, "blender_manifest.toml"), wheels, platforms)


def build(stage_dir, output_dir) -> list[str]:
    os.makedirs(output_dir, exist_ok=True)
    before = set(glob.glob(os.path.join(output_dir, "*.zip")))
    cmd = [sys.executable, blender_ext_path(), "build", "--source-dir", stage_dir,
           "--output-dir", output_dir, "--split-platforms"]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"error: blender_ext.py build failed:\n{res.stdout}{res.stderr}")
    zips = sorted(set(glob.glob(os.path.join(output_dir, "*.zip"))) - before) or \
        sorted(glob.glob(os.path.join(output_dir, "*.zip")))
    return zips


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--platforms", default=",".join(PLATFORMS),
                   help="comma-separated Blender platforms (default: all)")
    p.add_argument("--output-dir", default=os.path.join(ROOT, "dist"))
    p.add_argument("--stage-dir", default=os.path.join(ROOT, "build", "extension"))
    p.add_argument("--no-download", action="store_true", help="use wheels/ as it is")
    p.add_argument("--no-manifest-update", action="store_true",
                   help="do not rewrite the wheels list of blender_manifest.toml")
    args = p.parse_args(argv)
    platforms = [s.strip() for s in args.platforms.split(",") if s.strip()]
    unknown = [s for s in platforms if s not in PLATFORMS]
    if unknown:
        print(f"error: unknown platform(s) {', '.join(unknown)} "
              f"(known: {', '.join(PLATFORMS)})", file=sys.stderr)
        return 2
    if not args.no_download:
        download(platforms)
    wheels = wheels_for(platforms)
    if set(platforms) == set(PLATFORMS) and not args.no_manifest_update:
        write_manifest(MANIFEST, wheels_for(list(PLATFORMS)))
        print(f"updated wheels list in {os.path.relpath(MANIFEST, ROOT)}")
    stage(args.stage_dir, wheels, platforms)
    zips = build(args.stage_dir, args.output_dir)
    for z in zips:
        print(f"built {os.path.relpath(z, ROOT)} ({os.path.getsize(z) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
