"""Writes the bindings' docstrings from the engine's headers: cpp/bindings/generated/docstrings.hpp.

    python3 scripts/header_docs.py            # rewrites cpp/bindings/generated/docstrings.hpp
    python3 scripts/header_docs.py --check    # writes nothing; exits 1 (printing a diff) if it differs

As pybind11_mkdoc and Drake do, every public declaration of cpp/include/coopsim/*.hpp that has a
comment becomes one constant, ``doc_<Class>_<member>`` (``doc_<name>`` at namespace scope):

- the ``//`` lines right above a declaration (no blank line between) are its comment;
- a comment after a declaration on its own line(s) (``double dt = 2e-4;  // s, > 0``) is added to it;
- a declaration of several names (``double squeeze = 0.0, twist = 0.0;  // N, N m``) gives each name
  the trailing comment's matching comma-separated part when the counts agree, else the whole comment;
- overloads share one constant (the first comment found);
- private and protected members, bodies of inline functions and comments starting with ``----``
  (section rulers) are left out.

The bindings use the constants in their ``.def(...)`` and ``def_property_readonly(...)`` instead of
literals; tests/test_house.py fails when the committed file differs from what this writes. The output
depends on the headers only (files in name order, declarations in their order): byte-identical on
regeneration.
"""
from __future__ import annotations

import argparse
import difflib
import os
import re
import sys
from typing import Dict, List, Optional, Tuple

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HEADERS = os.path.join(ROOT, "cpp", "include", "coopsim")
TARGET = os.path.join(ROOT, "cpp", "bindings", "generated", "docstrings.hpp")
COMMAND = "python3 scripts/header_docs.py"

_SKIP_WORDS = {"if", "for", "while", "switch", "return", "sizeof", "static_assert", "decltype", "operator",
               "template", "alignas", "noexcept", "explicit", "const", "constexpr"}
_SCOPE_RE = re.compile(r"^\s*(?:template\s*<[^>]*>\s*)?(struct|class|enum\s+class|enum)\s+(\w+)[^;]*$")


def _strip_comment(line: str) -> Tuple[str, str]:
    """(code, trailing comment) of one line (a '//' outside string literals)."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            if ch == quote and line[i - 1] != "\\":
                quote = None
        elif ch in "\"'":
            quote = ch
        elif line.startswith("//", i):
            return line[:i], line[i + 2:].strip()
    return line, ""


def _names(decl: str) -> List[str]:
    """The names a declaration (without its comments, up to ';' or '{') declares."""
    text = re.sub(r"\s+", " ", decl).strip()
    if not text or text.startswith("#") or text.startswith("using ") or text.startswith("friend "):
        return []
    if text.startswith("typedef "):
        m = re.search(r"(\w+)\s*;?$", text)
        return [m.group(1)] if m else []
    depth = 0
    flat = []  # the text at template and parenthesis depth 0 (parameter lists and initialisers dropped)
    for ch in text:
        if ch in "(<[{":
            if depth == 0 and ch == "(":
                flat.append("(")
            depth += 1
        elif ch in ")>]}":
            depth -= 1
        elif depth == 0:
            flat.append(ch)
    flat_text = "".join(flat)
    eq = flat_text.find("=")
    if eq >= 0 and ("(" not in flat_text or eq < flat_text.index("(")):
        flat_text = ",".join(part.split("=")[0] for part in flat_text.split(","))  # a variable with initialisers
    if "(" in flat_text and "=" not in text.split("(")[0]:  # a function: the identifier before its parameter list
        m = re.search(r"(~?\w+)\s*\($", flat_text[:flat_text.index("(") + 1])
        if not m or m.group(1) in _SKIP_WORDS or m.group(1).startswith("~") or "operator" in flat_text:
            return []
        return [m.group(1)]
    names = []
    for part in flat_text.rstrip(";{ ").split(","):
        part = part.split("=")[0].strip()
        m = re.search(r"(\w+)\s*$", part)
        if m and m.group(1) not in _SKIP_WORDS:
            names.append(m.group(1))
    return names


def _split_units(comment: str, names: List[str]) -> List[str]:
    """Each name's part of one trailing comment: 'N, N m, N' split when every part is a short unit,
    'grasp: ...' to that name alone, else the whole comment to each."""
    count = len(names)
    parts = [p.strip() for p in comment.split(",")]
    if count > 1 and len(parts) == count and all(0 < len(p) <= 6 for p in parts):
        return parts
    m = re.match(r"^(\w+):", comment)
    if count > 1 and m and m.group(1) in names:
        return [comment if n == m.group(1) else "" for n in names]
    return [comment] * count


def parse(path: str) -> List[Tuple[str, str]]:
    """[(constant name, docstring)] of one header, in declaration order."""
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    out: List[Tuple[str, str]] = []
    scopes: List[Tuple[str, int, bool]] = []  # (name or '' for a skipped body, brace depth inside it, public)
    depth = 0
    pending: List[str] = []
    i = 0
    while i < len(lines):
        raw = lines[i]
        code, trailing = _strip_comment(raw)
        stripped = code.strip()
        if not stripped:
            if raw.strip().startswith("//"):
                text = raw.strip()[2:]
                if text.strip().startswith("----"):
                    pending = []
                else:
                    pending.append(text[1:] if text.startswith(" ") else text)
            else:
                pending = []
            i += 1
            continue
        if stripped.startswith("#"):
            pending = []
            i += 1
            continue
        skipping = any(not s[0] or not s[2] for s in scopes)
        access = re.match(r"^(public|private|protected)\s*:", stripped)
        if access and scopes:
            name, d, _ = scopes[-1]
            scopes[-1] = (name, d, access.group(1) == "public")
            pending = []
            i += 1
            continue
        # a declaration: up to ';' or '{' at parenthesis depth 0 (several lines for a long one)
        decl, comments, j = "", [trailing] if trailing else [], i
        while True:
            decl += " " + _strip_comment(lines[j])[0]
            if j > i:
                c = _strip_comment(lines[j])[1]
                if c:
                    comments.append(c)
            paren = decl.count("(") - decl.count(")")
            if paren <= 0 and re.search(r"[;{}]\s*$", decl.strip() + " ") or paren <= 0 and ("{" in decl or ";" in decl):
                break
            j += 1
            if j >= len(lines):
                break
        scope_match = _SCOPE_RE.match(decl.strip()) if "{" in decl else None
        opens = decl.count("{") - decl.count("}")
        names = [] if skipping else _names(decl.split("{")[0] if "{" in decl else decl)
        namespace = decl.strip().startswith("namespace")
        if scope_match and not namespace:
            names = [scope_match.group(2)]
        prefix = "_".join(s[0] for s in scopes if s[0])
        if not skipping and names and not namespace:
            doc_lines = [p.rstrip() for p in pending]
            trail = " ".join(comments)
            pieces = _split_units(trail, names) if trail else [""] * len(names)
            for name, piece in zip(names, pieces):
                text = "\n".join(doc_lines + ([piece] if piece else [])).strip("\n")
                if text:
                    out.append(((prefix + "_" if prefix else "") + name, text))
        pending = []
        # braces: a struct or class opens a named scope; a namespace none; anything else a skipped body
        if opens > 0:
            if namespace:
                depth += opens
            elif scope_match:
                kind = scope_match.group(1)
                depth += opens
                scopes.append((scope_match.group(2), depth, kind != "class"))
                if kind.startswith("enum") or decl.strip().endswith("};"):
                    pass
            else:
                depth += opens
                scopes.append(("", depth, False))
        elif opens < 0:
            for _ in range(-opens):
                if scopes and scopes[-1][1] == depth:
                    scopes.pop()
                depth -= 1
        i = j + 1
    return out


def generate() -> str:
    docs: Dict[str, str] = {}
    order: List[str] = []
    for name in sorted(os.listdir(HEADERS)):
        if not name.endswith(".hpp"):
            continue
        for key, text in parse(os.path.join(HEADERS, name)):
            if key not in docs:
                docs[key] = text
                order.append(key)
    body = [f"// Generated by {COMMAND} from cpp/include/coopsim/*.hpp (the comment above each public",
            "// declaration) - do not edit: change the header's comment and run the command again.",
            "#pragma once", "", "namespace coopsim::docs {", ""]
    for key in order:
        body.append(f"constexpr const char* doc_{key} = {_c_string(docs[key])};")
    body += ["", "}  // namespace coopsim::docs", ""]
    return "\n".join(body)


def _c_string(text: str) -> str:
    out = []
    for line in text.split("\n"):
        esc = line.replace("\\", "\\\\").replace('"', '\\"')
        out.append(esc)
    return '"' + "\\n\"\n    \"".join(out) + '"'


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 if the file differs")
    parser.add_argument("--out", default=TARGET, help="the file to write (default: %(default)s)")
    args = parser.parse_args(argv)
    text = generate()
    if args.check:
        try:
            with open(args.out, encoding="utf-8") as f:
                old = f.read()
        except FileNotFoundError:
            old = ""
        if old != text:
            sys.stdout.writelines(difflib.unified_diff(old.splitlines(True), text.splitlines(True),
                                                       args.out, "regenerated"))
            return 1
        return 0
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    tmp = args.out + ".tmp"
    with open(tmp, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)
    os.replace(tmp, args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
