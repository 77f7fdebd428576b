"""The robots whose generated dynamics are compiled into the engine, and their files."""
from __future__ import annotations

import difflib
from pathlib import Path

from .. import robots
from .files import builtin_sources, registry_source
from .symbolic import structure_of

__all__ = ["builtin_structures", "generate_files", "write_generated", "check_generated"]


def builtin_structures() -> list:
    """Structures of scara1 and scara2, read from coopsim.robots."""
    return [structure_of(robots.scara1(backend="numeric")), structure_of(robots.scara2(backend="numeric"))]


def generate_files(structures=None) -> dict:
    """{file name: text} of every file in cpp/generated, in a fixed order."""
    structures = list(structures) if structures is not None else builtin_structures()
    out = {}
    for s in sorted(structures, key=lambda s: s.name):
        out.update(builtin_sources(s))
    out["registry.cpp"] = registry_source([s.name for s in structures])
    return out


def write_generated(folder, structures=None) -> list:
    """Writes the files into `folder` and removes stale *_dynamics.* files; returns the names written."""
    folder = Path(folder)
    files = generate_files(structures)
    for path in sorted(folder.glob("*_dynamics.*")):
        if path.name not in files:
            path.unlink()
    for name, text in files.items():
        (folder / name).write_text(text, encoding="utf-8", newline="\n")
    return list(files)


def check_generated(folder, structures=None) -> str:
    """Unified diff between `folder` and a fresh generation ('' when byte-identical)."""
    folder = Path(folder)
    files = generate_files(structures)
    chunks = []
    present = {p.name for p in folder.glob("*_dynamics.*")}
    if (folder / "registry.cpp").exists():
        present.add("registry.cpp")
    for name in sorted(set(files) | present):
        path = folder / name
        old = path.read_bytes().decode("utf-8") if path.exists() else ""
        new = files.get(name, "")
        if old != new:
            chunks.extend(difflib.unified_diff(old.splitlines(keepends=True), new.splitlines(keepends=True),
                                               f"committed/{name}", f"generated/{name}", n=1))
            if not chunks or not chunks[-1].endswith("\n"):
                chunks.append("\n")
    return "".join(chunks)

