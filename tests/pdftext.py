"""Printed sizes of the text in a PDF's embedded figures (pypdf content streams), for the report checks.

pdflatex places an included PDF figure as a form XObject: ``q a b c d e f cm /Fm Do Q`` on the page. The
printed size of a glyph is its font size (``Tf``) scaled by the text matrix (``Tm``), the form's ``/Matrix``
and every ``cm`` on the way; this walks the page and form content streams with that state (PDF 32000-1,
sections 8.3-8.4 and 9.3-9.4) and reports, per form, the smallest printed size of any text it shows.
"""

import math

from pypdf import PdfReader
from pypdf.generic import ContentStream

_SHOW = {b"Tj", b"TJ", b"'", b'"'}


def _mul(a, b):
    """Product of two PDF matrices [a b c d e f] (row vector convention: a then b)."""
    return [
        a[0] * b[0] + a[1] * b[2],
        a[0] * b[1] + a[1] * b[3],
        a[2] * b[0] + a[3] * b[2],
        a[2] * b[1] + a[3] * b[3],
        a[4] * b[0] + a[5] * b[2] + b[4],
        a[4] * b[1] + a[5] * b[3] + b[5],
    ]


def _walk(reader, stream, resources, ctm, out, form):
    resources = resources.get_object() if resources is not None else {}
    ops = ContentStream(stream, reader).operations
    stack, tm, size = [], [1, 0, 0, 1, 0, 0], None
    for operands, op in ops:
        if op == b"q":
            stack.append(ctm)
        elif op == b"Q":
            ctm = stack.pop() if stack else ctm
        elif op == b"cm":
            ctm = _mul([float(x) for x in operands], ctm)
        elif op == b"BT":
            tm = [1, 0, 0, 1, 0, 0]
        elif op == b"Tf":
            size = float(operands[1])
        elif op == b"Tm":
            tm = [float(x) for x in operands]
        elif op in _SHOW and form is not None and size is not None:
            m = _mul(tm, ctm)
            # printed height of a glyph: the font size times the length of the transformed y unit vector
            out.setdefault(form, []).append(abs(size) * math.hypot(m[2], m[3]))
        elif op == b"Do":
            xobjects = resources.get("/XObject")
            xo = xobjects.get_object().get(operands[0]) if xobjects is not None else None
            if xo is None:
                continue
            xo = xo.get_object()
            if xo.get("/Subtype") != "/Form":
                continue
            matrix = [float(x) for x in xo.get("/Matrix", [1, 0, 0, 1, 0, 0])]
            if form is None:
                placed = sum(1 for k in out if k.split("#")[0] == operands[0])
                name = f"{operands[0]}#{placed + 1}"
            else:
                name = form
            _walk(reader, xo, xo.get("/Resources", resources), _mul(matrix, ctm), out, name)


def figure_text_sizes(path):
    """``{(page, "form name#k"): [printed text sizes in pt]}`` for every placement of a form XObject (figure)
    that shows text (``k``: the k-th placement of that form on the page)."""
    reader = PdfReader(str(path))
    sizes = {}
    for i, page in enumerate(reader.pages, start=1):
        out = {}
        contents = page.get_contents()
        if contents is None:
            continue
        _walk(reader, contents, page.get("/Resources"), [1, 0, 0, 1, 0, 0], out, None)
        for name, v in out.items():
            sizes[(i, name)] = v
    return sizes
