"""Write engine/lights/sky_hosek_data.py: the coefficients of Hosek and Wilkie's sky model,
CIE XYZ version, the one dataset Cycles uses for the Sky Texture's Hosek / Wilkie type
(scene/shader_nodes.cpp sky_texture_precompute_hosek calls
SKY_arhosek_xyz_skymodelstate_alloc_init, which reads datasetsXYZ / datasetsXYZRad only).

Where the numbers come from: Hosek & Wilkie's reference implementation, version 1.4a
(February 22nd, 2013; http://cgg.mff.cuni.cz/projects/SkylightModelling/), file
ArHosekSkyModelData_CIEXYZ.h, which Blender ships unchanged as
intern/sky/source/sky_hosek_data.h ("Uses Sep 9 pattern / Aug 23 mean dataset"). Six
arrays of doubles:
  datasetXYZ1..3     (channel X, Y, Z): [albedo 0, 1][turbidity 1..10][control point 0..5]
                     [9 sky-dome parameters A..I] = 1080 numbers each
  datasetXYZRad1..3  [albedo 0, 1][turbidity 1..10][control point 0..5] = 120 each
(the control points: a quintic Bezier in (elevation / (pi/2))^(1/3)).

Two ways to read them (both give the same numbers):
    python tools/make_hosek_data.py --header path/to/sky_hosek_data.h
        parses the C header (Blender's or Hosek & Wilkie's ArHosekSkyModelData_CIEXYZ.h);
    python tools/make_hosek_data.py
        reads the arrays out of the installed bpy wheel's binary (bpy/__init__.so: the
        very numbers Cycles 5.0.1 renders with), each found by its first three values,
        which are printed in the header as below; the whole array is checked against
        its known last value.
Every number in the header has 7 significant digits; the script checks that each one
prints back as the same %.6e text (it is the double nearest that decimal), so the data
file reproduces the header's text exactly.

The data and reference code are (c) 2012-2013 Lukas Hosek and Alexander Wilkie, under
the 3-clause BSD licence; the notice is copied into the data file, which keeps it with
the numbers (BSD-3 permits redistribution with the notice; it is compatible with this
project's GPL-3.0-or-later).
"""
from __future__ import annotations

import argparse
import glob
import mmap
import os
import re

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "engine", "lights", "sky_hosek_data.py")

# name -> (length, first three values, last value), as printed in the header
ARRAYS = {
    "datasetXYZ1": (1080, (-1.117001e+000, -1.867262e-001, -1.113505e+001), 6.232887e-001),
    "datasetXYZ2": (1080, (-1.127942e+000, -1.905548e-001, -1.252356e+001), 6.118645e-001),
    "datasetXYZ3": (1080, (-1.310023e+000, -4.407658e-001, -3.640340e+001), 6.791814e-001),
    "datasetXYZRad1": (120, (1.560219e+000, 1.417388e+000, 1.206927e+000), 2.523432e+001),
    "datasetXYZRad2": (120, (1.632341e+000, 1.395230e+000, 1.375634e+000), 2.641780e+001),
    "datasetXYZRad3": (120, (1.168084e+000, 2.156455e+000, -3.980314e+000), 3.110255e+001),
}

NOTICE = '''\
# Copyright (c) 2012-2013 Lukas Hosek and Alexander Wilkie. All rights reserved.
# SPDX-License-Identifier: BSD-3-Clause
#
# Redistribution and use in source and binary forms, with or without modification, are
# permitted provided that the following conditions are met:
#  1. Redistributions of source code must retain the above copyright notice, this list of
#     conditions and the following disclaimer.
#  2. Redistributions in binary form must reproduce the above copyright notice, this list
#     of conditions and the following disclaimer in the documentation and/or other
#     materials provided with the distribution.
#  3. Neither the name of the copyright holders nor the names of its contributors may be
#     used to endorse or promote products derived from this software without specific
#     prior written permission.
#
# THIS SOFTWARE IS PROVIDED BY THE COPYRIGHT HOLDERS AND CONTRIBUTORS "AS IS" AND ANY
# EXPRESS OR IMPLIED WARRANTIES, INCLUDING, BUT NOT LIMITED TO, THE IMPLIED WARRANTIES OF
# MERCHANTABILITY AND FITNESS FOR A PARTICULAR PURPOSE ARE DISCLAIMED. IN NO EVENT SHALL
# THE COPYRIGHT HOLDER OR CONTRIBUTORS BE LIABLE FOR ANY DIRECT, INDIRECT, INCIDENTAL,
# SPECIAL, EXEMPLARY, OR CONSEQUENTIAL DAMAGES (INCLUDING, BUT NOT LIMITED TO, PROCUREMENT
# OF SUBSTITUTE GOODS OR SERVICES; LOSS OF USE, DATA, OR PROFITS; OR BUSINESS
# INTERRUPTION) HOWEVER CAUSED AND ON ANY THEORY OF LIABILITY, WHETHER IN CONTRACT, STRICT
# LIABILITY, OR TORT (INCLUDING NEGLIGENCE OR OTHERWISE) ARISING IN ANY WAY OUT OF THE USE
# OF THIS SOFTWARE, EVEN IF ADVISED OF THE POSSIBILITY OF SUCH DAMAGE.
'''


def from_header(path: str) -> dict:
    """The six arrays parsed from a C header (numbers between `name[] = {` and `};`)."""
    text = open(path, encoding="utf-8", errors="replace").read()
    text = re.sub(r"//[^\n]*", "", text)
    out = {}
    for name in ARRAYS:
        m = re.search(r"\b" + name + r"\s*\[\s*\]\s*=\s*\{(.*?)\}\s*;", text, re.S)
        if m is None:
            raise SystemExit(f"{path}: array {name} not found")
        out[name] = np.array([float(v) for v in m.group(1).replace("\n", " ").split(",")
                              if v.strip()])
    return out


def from_bpy() -> dict:
    """The six arrays read from the installed bpy wheel's binary, each located by its
    first three values."""
    import importlib.util
    # the wheel's binary (before `import bpy`, which puts Blender's Python bpy in its place)
    spec = importlib.util.find_spec("bpy")
    so = glob.glob(os.path.join(os.path.dirname(spec.origin), "__init__*.so")) if spec else []
    if not so:
        raise SystemExit("bpy's binary not found")
    out = {}
    with open(so[0], "rb") as f:
        blob = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        for name, (n, first, _last) in ARRAYS.items():
            pattern = np.array(first, "<f8").tobytes()
            at = blob.find(pattern)
            if at < 0 or blob.find(pattern, at + 1) >= 0:
                raise SystemExit(f"{name}: its first values occur {0 if at < 0 else '> 1'} "
                                 "times in bpy's binary")
            out[name] = np.frombuffer(blob, "<f8", count=n, offset=at).copy()
        blob.close()
    return out


def check(arrays: dict):
    for name, (n, first, last) in ARRAYS.items():
        a = arrays[name]
        assert a.shape == (n,), (name, a.shape)
        assert tuple(a[:3]) == first and a[-1] == last, name
        # 7 significant digits: each value is the double nearest its %.6e text
        assert all(float(f"{v:.6e}") == v for v in a), name


def write(arrays: dict, source: str):
    lines = [NOTICE, '"""Hosek and Wilkie\'s sky model coefficients, CIE XYZ version 1.4a '
             '(ArHosekSkyModelData_CIEXYZ.h,',
             "as Blender's intern/sky/source/sky_hosek_data.h): written by "
             "tools/make_hosek_data.py from",
             f"{source}. Do not edit by hand.",
             "",
             "XYZ[c]: channel c (X, Y, Z), 2 albedos x 10 turbidities x 6 control points x "
             "9 parameters, flat;",
             'XYZ_RAD[c]: 2 x 10 x 6, flat (engine/lights/sky.py reshapes them)."""',
             "", "XYZ = ("]
    for c in (1, 2, 3):
        a = arrays[f"datasetXYZ{c}"].reshape(2, 10, 6, 9)
        lines.append("    (")
        for alb in range(2):
            for t in range(10):
                lines.append(f"        # albedo {alb}, turbidity {t + 1}")
                for k in range(6):
                    lines.append("        " + " ".join(f"{v:.6e}," for v in a[alb, t, k]))
        lines.append("    ),")
    lines += [")", "", "XYZ_RAD = ("]
    for c in (1, 2, 3):
        a = arrays[f"datasetXYZRad{c}"].reshape(2, 10, 6)
        lines.append("    (")
        for alb in range(2):
            for t in range(10):
                lines.append(f"        # albedo {alb}, turbidity {t + 1}")
                lines.append("        " + " ".join(f"{v:.6e}," for v in a[alb, t]))
        lines.append("    ),")
    lines += [")", ""]
    with open(OUT, "w", encoding="utf-8") as f:
        f.write("\n".join(lines))
    print("wrote", OUT)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--header", help="sky_hosek_data.h / ArHosekSkyModelData_CIEXYZ.h")
    args = ap.parse_args()
    if args.header:
        arrays, source = from_header(args.header), os.path.basename(args.header)
    else:
        arrays = from_bpy()
        import bpy
        source = f"the bpy {bpy.app.version_string} wheel's binary"
    check(arrays)
    write(arrays, source)


if __name__ == "__main__":
    main()
