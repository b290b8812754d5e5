"""Text layer shared by the motion-capture readers: one place that reads a file into lines and splits tokens.

* Encoding: UTF-8, with or without a byte-order mark (Windows tools write one); bytes that are not UTF-8 (an
  8-bit name in a comment) become U+FFFD instead of failing, and then fail only where a keyword or number is
  expected.
* Line ends: LF, CRLF and a lone CR. Only these end a line (``str.splitlines`` also splits at form feeds and
  other separators, which would shift the line numbers of the error messages).
* Tokens: runs of characters between white space (spaces, tabs); for ASF/AMC (Acclaim 1.10), commas are white
  space too.
* Numbers: decimal numbers with an optional exponent only; ``float`` also takes ``nan``, ``inf`` and ``1_000``,
  which no motion-capture format writes.
"""

import re
from pathlib import Path

from ..errors import DataFileError

_LINE_END = re.compile(r"\r\n|\r|\n")
#: A decimal number (ASCII digits only: ``float`` also reads other scripts' digits).
NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_WHOLE = re.compile(r"[0-9]+")


def read_lines(path, what):
    """Lines of the text file ``path`` (BOM stripped, any line end). ``what`` names the expected file in the
    error raised when it is missing."""
    path = Path(path)
    if not path.is_file():
        raise DataFileError(path, f"file not found (expected {what})")
    text = path.read_bytes().decode("utf-8-sig", errors="replace")
    lines = _LINE_END.split(text)
    if lines and lines[-1] == "":
        lines.pop()  # the final line end
    return lines


def tokens(line, commas=False):
    """White-space separated tokens of ``line``; with ``commas``, commas separate tokens too (ASF/AMC)."""
    return (line.replace(",", " ") if commas else line).split()


def is_number(token):
    """A decimal number whose value is finite (``1e999`` is not)."""
    return NUMBER.fullmatch(token) is not None and abs(float(token)) < float("inf")


def is_whole(token):
    """A whole number written with ASCII digits (``str.isdigit`` also takes superscripts, which ``int`` rejects)."""
    return _WHOLE.fullmatch(token) is not None


def first_bad_number(tokens_):
    """Index of the first token that is not a decimal number, or None."""
    return next((k for k, x in enumerate(tokens_) if not is_number(x)), None)
