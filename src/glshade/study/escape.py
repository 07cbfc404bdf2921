"""Stored text as a Markdown report shows it: one line that reads as the words it holds.

A status reason or a surface's name comes back from a case file or a table, which a hand
(or another program) may have written; in a report it must stay text, never become a
table's column break (``|``), a link (``[...](...)``), code (`` ` ``) or HTML (``<``,
``&``). :func:`markdown_text` makes it so; glshade's own reasons hold none of these
characters and come out as they went in.
"""

from __future__ import annotations

#: Each character that Markdown or HTML would read as markup, and what stands for it
#: (a backslash first, so that an escape can never be undone by one in the text).
_ESCAPES = {
    "\\": "\\\\",
    "|": "\\|",
    "[": "\\[",
    "]": "\\]",
    "`": "\\`",
    "&": "&amp;",
    "<": "&lt;",
    ">": "&gt;",
}
_TABLE = str.maketrans(_ESCAPES)


def markdown_text(text: object) -> str:
    """``text`` as one line of Markdown (in a table cell, a paragraph or bold): every line
    break and other control character a space, the characters of :data:`_ESCAPES`
    escaped."""
    words = "".join(" " if _is_break(c) else c for c in str(text))
    return words.translate(_TABLE)


def _is_break(char: str) -> bool:
    """A control character, or a line or paragraph separator (U+2028, U+2029)."""
    code = ord(char)
    return code < 0x20 or 0x7F <= code < 0xA0 or code in (0x2028, 0x2029)
