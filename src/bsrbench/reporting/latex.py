"""LaTeX for every section of the report: escaping, number formatting and booktabs tables.

The sections (:mod:`.findings`, :mod:`.study_setup`, :mod:`.ablation`, :mod:`.convergence`, :mod:`.mechanisms`,
:mod:`.today`) write their tables with :func:`table` and their numbers with the formatters here, so that a
missing value, a negative sign or a percentage reads the same in every table.
"""

import numpy as np

# escaping, a mean +- std cell and the bold of the best are those of the paper's Tables I-II (tables.py), so that
# every table prints them alike; the sections take them from here
from .tables import best_mask, format_cell, latex_escape

__all__ = [
    "MISSING",
    "best_mask",
    "bold",
    "escape",
    "figure",
    "finite",
    "fixed",
    "format_cell",
    "general",
    "listing",
    "nobreak",
    "percent",
    "power_of_ten",
    "row",
    "signed",
    "table",
    "tt",
]

#: What a table cell shows for a value that is missing (None, NaN or infinite).
MISSING = "--"

escape = latex_escape


# ------------------------------------------------------------------------------------------------------ text
def nobreak(text):
    """LaTeX for ``text`` (escaped) that is never hyphenated or broken across lines (activity names)."""
    return r"\mbox{" + escape(text) + "}"


def tt(text):
    """``text`` in typewriter type, exactly as typed: "--" stays two ASCII hyphens (no en-dash ligature), so a
    command copied from the PDF runs."""
    return r"\texttt{" + escape(text).replace("-", "-{}") + "}"


def listing(items):
    """``a``, ``a and b``, ``a, b and c``."""
    items = list(items)
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


def bold(text):
    return rf"\textbf{{{text}}}"


# --------------------------------------------------------------------------------------------------- numbers
def finite(x):
    """Whether ``x`` is a number to print (not None, NaN or infinite)."""
    return x is not None and bool(np.isfinite(x))


def fixed(x, digits=2, *, missing=MISSING):
    """``x`` with ``digits`` decimals; ``missing`` for None, NaN or an infinite value."""
    return f"{x:.{digits}f}" if finite(x) else missing


def signed(x, digits=2):
    """``x`` with its sign and ``digits`` decimals, the minus as a math minus (``+0.50``, ``$-$0.50``)."""
    return f"{x:+.{digits}f}".replace("-", "$-$")


def percent(share, digits=0):
    """A share in [0, 1] as a LaTeX percentage: ``0.5`` -> ``50\\%``."""
    return f"{100 * share:.{digits}f}\\%"


def general(x, *, ints=True):
    """``x`` in Python's shortest general format (``0.001``, ``1e-06``) if it is a float (or, with ``ints``, an
    int); anything else as ``str``."""
    kinds = (int, float) if ints else (float,)
    return f"{x:g}" if isinstance(x, kinds) else str(x)


def power_of_ten(x, digits=2, *, limit=1e4):
    """``x`` with ``digits`` decimals below ``limit`` in magnitude, beyond it as $m\\times 10^{e}$ (an
    over-confident method's mean NLPD)."""
    if abs(x) < limit:
        return f"{x:.{digits}f}"
    m, e = f"{x:.{digits}e}".split("e")
    return rf"${m}\times 10^{{{int(e)}}}$"


# ---------------------------------------------------------------------------------------------------- tables
def row(cells):
    """One table row: the cells joined by ``&``, ended by ``\\\\``."""
    return " & ".join(cells) + r" \\"


def _lines(items):
    # a string is a line of LaTeX as it stands (a rule, a prepared row); a sequence is a row's cells
    return [x if isinstance(x, str) else row(x) for x in items]


def table(
    body,
    *,
    spec,
    head,
    caption,
    label=None,
    size=r"\footnotesize",
    tabcolsep=None,
    width=None,
    midrule=True,
    placement="H",
):
    """A booktabs table in a ``table`` float placed here (``placement`` ``H``; ``tbp``: where LaTeX finds room,
    for a table too tall to follow its text on the page), centred, as one string of lines.

    ``head`` and ``body``: items each a row's cells (a sequence, joined by :func:`row`) or a line of LaTeX as it
    stands (a string: ``\\midrule``, ``\\cmidrule``, a prepared row). ``spec``: the column specification;
    ``width``: the width of a ``tabularx`` (default: a plain ``tabular``); ``size``: the font size command;
    ``tabcolsep``: the column separation (e.g. ``"4pt"``); ``midrule``: a ``\\midrule`` between head and body.
    """
    env = "tabularx" if width else "tabular"
    setup = r"\centering" + size
    if tabcolsep is not None:
        setup += rf"\setlength{{\tabcolsep}}{{{tabcolsep}}}"
    lines = [rf"\begin{{table}}[{placement}]", setup, rf"\caption{{{caption}}}"]
    if label is not None:
        lines.append(rf"\label{{{label}}}")
    lines.append(rf"\begin{{{env}}}" + (f"{{{width}}}" if width else "") + f"{{{spec}}}")
    lines += [r"\toprule", *_lines(head)]
    if midrule:
        lines.append(r"\midrule")
    lines += [*_lines(body), r"\bottomrule", rf"\end{{{env}}}", r"\end{table}"]
    return "\n".join(lines)


def figure(path, caption, *, command=r"\includegraphics", options=None, label=None):
    """A figure float placed here (``[H]``), centred: ``command[options]{path}`` with its caption and label."""
    graphics = command + (f"[{options}]" if options else "") + f"{{{path}}}"
    lines = [r"\begin{figure}[H]", r"\centering", graphics, rf"\caption{{{caption}}}"]
    if label is not None:
        lines.append(rf"\label{{{label}}}")
    return "\n".join(lines + [r"\end{figure}"])
