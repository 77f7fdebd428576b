"""The shape of the code base itself: properties the project keeps as it grows."""
from __future__ import annotations

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))

from binding_ratio import code_lines, measure  # noqa: E402


def test_code_lines_count_code_not_comments():
    # the counting rule of scripts/binding_ratio.py on a known text: comments and blank lines out, the lines
    # of a raw string literal (but for blank ones) and a "//" inside a string in
    text = ('// a comment\n'
            'int a = 1;  // trailing\n'
            '\n'
            '/* a block\n'
            '   comment */\n'
            'const char* u = "http://x";\n'
            'const char* d = R"doc(one\n'
            '\n'
            'two // not a comment)doc";\n'
            'int b; /* c */ int c;\n'
            '   /* only a comment */   \n')
    assert code_lines(text) == 5


def test_the_bindings_are_at_most_a_third_of_the_engine():
    # the bindings declare (types, argument names, docstrings, GIL release) and convert Python objects;
    # every check and default lives in the engine, which the bindings call
    binding, engine = measure()
    b, e = sum(binding.values()), sum(engine.values())
    assert b / e <= 0.33, f"bindings {b} code lines / engine {e} = {b / e:.3f} > 0.33: {binding}"
