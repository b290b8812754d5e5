"""The report's LaTeX helper (bsrbench.reporting.latex): escaping, number formats and booktabs tables."""

import math
import re
import shutil
import subprocess

import numpy as np
import pytest

from bsrbench.reporting import latex


def test_escape_and_text_helpers():
    assert latex.escape("a_b & 50% {x} #1 $ ~ ^ \\") == (
        r"a\_b \& 50\% \{x\} \#1 \$ \textasciitilde{} \textasciicircum{} \textbackslash{}"
    )
    assert latex.nobreak("Kick_ball") == r"\mbox{Kick\_ball}"
    # two ASCII hyphens stay two hyphens in typewriter type (no en-dash ligature)
    assert latex.tt("--config a_b") == r"\texttt{-{}-{}config a\_b}"
    assert [latex.listing(x) for x in ([], ["a"], ["a", "b"], ["a", "b", "c"])] == [
        "",
        "a",
        "a and b",
        "a, b and c",
    ]


@pytest.mark.parametrize("missing", [None, math.nan, np.nan, math.inf, -np.inf])
def test_a_missing_number_prints_as_the_dash(missing):
    assert latex.fixed(missing) == latex.MISSING == "--"
    assert latex.fixed(missing, 0, missing="") == ""


def test_number_formats():
    assert [latex.fixed(x, d) for x, d in ((1.005, 1), (2.0, 2), (1234.5678, 0), (0.0314, 3))] == [
        "1.0",
        "2.00",
        "1235",
        "0.031",
    ]
    # the math minus, not a hyphen, and the plus sign kept
    assert latex.signed(0.5) == "+0.50" and latex.signed(-1.234) == "$-$1.23"
    assert latex.percent(0.5) == r"50\%" and latex.percent(2 / 3, 1) == r"66.7\%"
    assert latex.general(1e-6) == "1e-06" and latex.general(0.25) == "0.25"
    assert latex.general(10**7) == "1e+07" and latex.general(10**7, ints=False) == "10000000"
    assert latex.general("ess") == "ess"
    # below the limit two decimals; beyond it the mantissa (two decimals) times a power of ten
    assert latex.power_of_ten(9999.994) == "9999.99"
    assert latex.power_of_ten(696966.9) == r"$6.97\times 10^{5}$"
    assert latex.power_of_ten(-12345.0) == r"$-1.23\times 10^{4}$"
    m, e = re.match(r"\$(.+)\\times 10\^\{(-?\d+)\}\$", latex.power_of_ten(3.2e12)).groups()
    assert float(m) * 10 ** int(e) == pytest.approx(3.2e12)


def test_table_layout():
    tex = latex.table(
        [["a", "1"], r"\midrule", ["b", "2"]],
        spec="@{}lr@{}",
        head=[["Name", "$N$"]],
        caption="Cap.",
        label="tab:x",
        tabcolsep="4pt",
    )
    assert tex.splitlines() == [
        r"\begin{table}[H]",
        r"\centering\footnotesize\setlength{\tabcolsep}{4pt}",
        r"\caption{Cap.}",
        r"\label{tab:x}",
        r"\begin{tabular}{@{}lr@{}}",
        r"\toprule",
        r"Name & $N$ \\",
        r"\midrule",
        r"a & 1 \\",
        r"\midrule",
        r"b & 2 \\",
        r"\bottomrule",
        r"\end{tabular}",
        r"\end{table}",
    ]
    wide = latex.table(
        [["x", "y"]], spec="lX", head=["A & B \\\\"], caption="C", width=r"\linewidth"
    )
    assert r"\begin{tabularx}{\linewidth}{lX}" in wide and wide.endswith(
        "\\end{tabularx}\n\\end{table}"
    )
    assert r"\label" not in wide and r"\setlength" not in wide


def test_figure_layout():
    assert latex.figure("f/a.pdf", "Cap.", command=r"\fitgraphics", label="fig:a").splitlines() == [
        r"\begin{figure}[H]",
        r"\centering",
        r"\fitgraphics{f/a.pdf}",
        r"\caption{Cap.}",
        r"\label{fig:a}",
        r"\end{figure}",
    ]
    assert r"\includegraphics[width=\linewidth]{b.pdf}" in latex.figure(
        "b.pdf", "c", options=r"width=\linewidth"
    )


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="needs pdflatex")
def test_a_table_with_every_special_character_compiles(tmp_path):
    text = "a_b & 50% {x} #1 $ ~ ^ \\ --"
    body = [
        [latex.escape(text), latex.fixed(math.nan), latex.signed(-1.0), latex.power_of_ten(1e9)]
    ]
    tex = latex.table(body, spec="llll", head=[["A", "B", "C", "D"]], caption=latex.escape(text))
    doc = "\n".join(
        [
            r"\documentclass{article}",
            r"\usepackage{booktabs,float}",
            r"\begin{document}",
            tex,
            r"\end{document}",
        ]
    )
    (tmp_path / "t.tex").write_text(doc)
    res = subprocess.run(
        ["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "t.tex"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stdout[-2000:]
