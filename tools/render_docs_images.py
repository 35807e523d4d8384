"""Render the README's example images: every example .blend with and without photon
mapping, through the add-on (as `make render` does), into docs/.

    .venv/bin/python tools/render_docs_images.py
"""
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLENDS = ("figure3_sphere", "figure6_box", "figure7_blocker", "figure8_caustic")


def main():
    for name in BLENDS:
        blend = os.path.join(ROOT, "example_blends", f"{name}.blend")
        for suffix, extra in (("", []), ("_raytraced", ["--no-photon-mapping"])):
            out = os.path.join(ROOT, "docs", f"{name}{suffix}.png")
            subprocess.run([sys.executable, "-m", "addon.batch", blend, "-o", out, "--quiet", *extra],
                           cwd=ROOT, check=True)
            print("wrote", os.path.relpath(out, ROOT), flush=True)


if __name__ == "__main__":
    main()
