"""How much code the pybind11 bindings take beside the engine they bind.

Counts code lines of the bindings (every file in cpp/bindings) and of the
engine (cpp/src/*.cpp, cpp/src/*.hpp, cpp/include/coopsim/*.hpp; the
generated code in cpp/generated is not counted), prints them per file and the
ratio binding / engine.

Counting rule: a line counts when something other than white space is left on
it after removing the comments, // to the end of the line and /* ... */ (also
across lines). String, character and raw string literals (R"d(...)d") are read
as literals, so a "//" inside one is text, not a comment, and the lines of a
multi-line raw string (a docstring) count as code. Blank lines do not count,
inside a raw string neither.

Usage: python3 scripts/binding_ratio.py [repository root]
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
_RAW_START = re.compile(r'R"([^()\\ ]{0,16})\(')


def code_lines(text: str) -> int:
    """Lines of C++ source `text` holding code once comments are removed."""
    counted = 0
    has_code = False  # the current line has code
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c == "\n":
            counted += has_code
            has_code = False
            i += 1
        elif text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            # a comment spanning lines ends the lines it passes without code
            for _ in range(text.count("\n", i, j)):
                counted += has_code
                has_code = False
            i = j
        elif (m := _RAW_START.match(text, i)) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            end = ")" + m.group(1) + '"'
            j = text.find(end, m.end())
            j = n if j < 0 else j + len(end)
            for k in range(i, j):  # the literal's lines count as code, but for blank ones
                if text[k] == "\n":
                    counted += has_code
                    has_code = False
                elif not text[k].isspace():
                    has_code = True
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            has_code = True
            i = j + 1
        else:
            if not c.isspace():
                has_code = True
            i += 1
    return counted + has_code


def binding_files(root: Path = ROOT) -> list[Path]:
    return sorted(p for p in (root / "cpp" / "bindings").iterdir() if p.suffix in (".cpp", ".hpp", ".h"))


def engine_files(root: Path = ROOT) -> list[Path]:
    return sorted([*(root / "cpp" / "src").glob("*.cpp"), *(root / "cpp" / "src").glob("*.hpp"),
                   *(root / "cpp" / "include" / "coopsim").glob("*.hpp")])


def measure(root: Path = ROOT) -> tuple[dict[str, int], dict[str, int]]:
    """(binding, engine): code lines per file, keyed by the path relative to `root`."""
    count = {}
    for group in (binding_files(root), engine_files(root)):
        count[len(count)] = {str(p.relative_to(root)): code_lines(p.read_text(encoding="utf-8")) for p in group}
    return count[0], count[1]


def ratio(root: Path = ROOT) -> float:
    """Binding code lines / engine code lines."""
    binding, engine = measure(root)
    return sum(binding.values()) / sum(engine.values())


def main(argv: list[str]) -> None:
    root = Path(argv[1]) if len(argv) > 1 else ROOT
    binding, engine = measure(root)
    for title, files in (("bindings", binding), ("engine", engine)):
        print(f"{title}:")
        for name, lines in files.items():
            print(f"  {lines:6d}  {name}")
        print(f"  {sum(files.values()):6d}  total")
    b, e = sum(binding.values()), sum(engine.values())
    print(f"ratio bindings / engine: {b} / {e} = {b / e:.3f}")


if __name__ == "__main__":
    main(sys.argv)
