"""The shipped files cite only documents that ship: docs/design.md (with a section that
exists), never the team's design notes outside the repository (issue 12, item 8)."""
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHIPPED_DIRS = ("engine", "addon", "docs", "tests", "bench", "tools", "example_blends")
SHIPPED_FILES = ("README.md", "Makefile", "__init__.py", "blender_manifest.toml",
                 "pyproject.toml")
TEXT_EXT = (".py", ".md", ".toml", ".txt", ".json", ".cfg", ".csv")
# Built from parts so this file does not match itself.
OUTSIDE_NOTES = re.compile("DESIGN" + r"(\.md)?\s*(§|section\s*\d)", re.IGNORECASE)
OUTSIDE_NAME = "DESIGN" + ".md"
CITATION = re.compile(r"docs/design\.md,\s+")


def shipped_text_files():
    for d in SHIPPED_DIRS:
        for base, _, names in os.walk(os.path.join(ROOT, d)):
            if "__pycache__" in base:
                continue
            for n in names:
                if n.endswith(TEXT_EXT):
                    yield os.path.join(base, n)
    for n in SHIPPED_FILES:
        p = os.path.join(ROOT, n)
        if os.path.isfile(p):
            yield p


def _headings():
    with open(os.path.join(ROOT, "docs", "design.md"), encoding="utf-8") as f:
        return {line[3:].strip() for line in f if line.startswith("## ")}


def test_no_shipped_file_cites_the_outside_design_notes():
    offenders = []
    for path in shipped_text_files():
        with open(path, encoding="utf-8", errors="replace") as f:
            for i, line in enumerate(f, 1):
                if OUTSIDE_NOTES.search(line) or OUTSIDE_NAME in line:
                    offenders.append(f"{os.path.relpath(path, ROOT)}:{i}: {line.strip()}")
    assert not offenders, "cite docs/design.md, <section name> instead:\n" + "\n".join(offenders)


def test_design_md_citations_name_existing_sections():
    headings = _headings()
    assert {"Architecture and data flow", "Units (Cycles)", "Embree (embreex) facts",
            "kd-tree (scipy) facts", "numba facts", "Measuring accuracy"} <= headings
    cited, unknown = 0, []
    for path in shipped_text_files():
        with open(path, encoding="utf-8", errors="replace") as f:
            # Join wrapped lines (comments, concatenated string literals): a section
            # name may continue on the next line.
            text = re.sub(r'\s*"?\n\s*(#\s*|")?\s*', " ", f.read())
        for m in CITATION.finditer(text):
            after = text[m.end():m.end() + 60]
            if after.startswith("<section name>"):
                continue  # the citation form itself, as documented
            cited += 1
            if not any(after.startswith(h) for h in headings):
                unknown.append(f"{os.path.relpath(path, ROOT)}: '{after[:30]}...'")
    assert cited >= 10  # the engine's design citations are found by the pattern
    assert not unknown, "citations of missing docs/design.md sections:\n" + "\n".join(unknown)


# The team's machine: the folder that holds its checkouts, worktrees and notes. Built from
# parts so this file does not match itself.
TEAM_PATH = re.compile(r"(?<![\w~.$])" + "/wo" + r"rk/")
# A script under /tmp/ exists only where someone wrote it; /tmp/ as a scratch folder that a
# command writes (outputs, caches, TMPDIR) is fine. Such a script may be named only where
# the text says it was a one-off (its paragraph), or in a file whose reading note says so.
TMP_SCRIPT = re.compile(r"/tmp/[\w./{},-]*\.(?:py|sh|tar\.gz)\b")
ONE_OFF = re.compile(r"one-off", re.IGNORECASE)
# ... or where the same paragraph writes it (`git show COMMIT:FILE > /tmp/x.py`).
WRITTEN = re.compile(r">\s*(/tmp/[\w./{},-]*\.(?:py|sh|tar\.gz))\b")
READING_NOTE = "a script named under /tmp/ was a one-off script, not kept"


def _paragraphs(text):
    """(first line number, paragraph) for each block of lines between blank lines."""
    start, lines = 1, []
    for i, line in enumerate(text.splitlines() + [""], 1):
        if line.strip():
            if not lines:
                start = i
            lines.append(line)
        elif lines:
            yield start, "\n".join(lines)
            lines = []


def test_no_shipped_file_names_the_team_machines_paths():
    """A reader has a clone and nothing else: commands run from the repository root, a base
    checkout is a placeholder the text defines (BASE), and scripts that were not kept are
    said to be one-off (docs/performance.md, "Reading the commands")."""
    offenders = []
    for path in shipped_text_files():
        rel = os.path.relpath(path, ROOT)
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read()
        noted = READING_NOTE in " ".join(text.split()).lower()
        for start, para in _paragraphs(text):
            for k, line in enumerate(para.splitlines()):
                if TEAM_PATH.search(line):
                    offenders.append(f"{rel}:{start + k}: {line.strip()}")
                elif (not noted and not ONE_OFF.search(para)
                      and set(TMP_SCRIPT.findall(line)) - set(WRITTEN.findall(para))):
                    offenders.append(f"{rel}:{start + k}: {line.strip()}")
    assert not offenders, ("paths that exist only on the team's machine (write the repository "
                           "root, BASE, or say 'a one-off script, not kept'):\n"
                           + "\n".join(offenders))
