"""Packaging metadata (pyproject.toml): the current forms, so `pip install -e .` and the
wheel build give no deprecation warning (issue 16's fresh-user review)."""
import os
import re
import tomllib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _toml(name):
    with open(os.path.join(ROOT, name), "rb") as f:
        return tomllib.load(f)


def test_license_is_an_spdx_string_as_in_the_blender_manifest():
    """PEP 639: `project.license` is an SPDX expression string; the table form
    ({text = ...}) is deprecated by setuptools (BuildBackendWarning, removal 2027). The
    expression is the one the Blender extension declares."""
    py = _toml("pyproject.toml")
    license_ = py["project"]["license"]
    assert isinstance(license_, str), f"project.license must be an SPDX string, got {license_!r}"
    manifest = _toml("blender_manifest.toml")["license"]
    assert [f"SPDX:{license_}"] == manifest


def test_build_backend_reads_the_spdx_license():
    """setuptools reads the string form from 77.0 on: the build requirement says so (an
    older setuptools in the build environment would refuse the string)."""
    requires = _toml("pyproject.toml")["build-system"]["requires"]
    found = [re.fullmatch(r"setuptools>=(\d+)(\.\d+)*", r.replace(" ", "")) for r in requires]
    versions = [int(m.group(1)) for m in found if m]
    assert versions and versions[0] >= 77, requires
