"""Text that goes into generated files: safe by construction.

Every name a user wrote reaches generated code (Promela, SMV, dot) only as an identifier
made by a namer, or as text through one of these functions:

* ``comment_text``: inside a comment (Promela ``/* */``, SMV ``--``, anything line-based);
* ``dot_string``: a Graphviz double-quoted string.
"""
from __future__ import annotations

__all__ = ["comment_text", "dot_string"]


def comment_text(text: object) -> str:
    """``text`` made safe inside a generated comment: printable ASCII on one line (other
    characters as ``\\xNN`` / ``\\uNNNN`` escapes) with no comment delimiter (``/*`` and
    ``*/`` are broken apart).

    >>> comment_text('x */ c_code { system("touch X") } /* y\\nz')
    'x * / c_code { system("touch X") } / * y\\\\x0az'
    """
    t = str(text).encode("ascii", "backslashreplace").decode("ascii")
    t = "".join(c if c.isprintable() else f"\\x{ord(c):02x}" for c in t)
    while "/*" in t or "*/" in t:
        t = t.replace("/*", "/ *").replace("*/", "* /")
    return t


def dot_string(text: object) -> str:
    """A dot double-quoted string: backslashes and quotes escaped, newlines (``\\r\\n`` too)
    as ``\\n`` line breaks, other non-printable characters (controls, lone surrogates) as
    ``\\uXXXX`` text.

    >>> print(dot_string('a"b\\\\c\\nd\\x00'))
    "a\\"b\\\\c\\nd\\\\u0000"
    """
    out = []
    for c in str(text).replace("\r\n", "\n"):
        if c == "\\":
            out.append("\\\\")
        elif c == '"':
            out.append('\\"')
        elif c == "\n":
            out.append("\\n")
        elif not c.isprintable():
            out.append(f"\\\\u{ord(c):04x}")
        else:
            out.append(c)
    return '"' + "".join(out) + '"'
