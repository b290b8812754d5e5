"""The PDF report: the page-1 header (build date, code, configuration, machine), latexmk on reports/report.tex,
and the check of LaTeX's log."""

import datetime
import os
import platform
import re
import shlex
import shutil
import subprocess
from pathlib import Path

from ..errors import InputError
from ..io import atomic_path
from .latex import escape, row


def config_provenance(configfiles, overrides=()):
    """LaTeX of the configuration a study ran with: the configuration files in the order they apply, then the
    ``--config KEY=VALUE`` overrides of the command line (or of the profile), which apply last, as a shell would
    take them (quoted where needed, in typewriter type with upright quotes and ASCII hyphens, so that the
    command copied from the PDF runs).

    ``configfiles``: paths; ``overrides``: the raw ``KEY=VALUE`` strings (Snakemake's
    ``workflow.config_settings.config_args``).
    """
    files = ", ".join(escape(str(f)) for f in configfiles)
    text = (files + " (in the order they apply)") if configfiles else "none"
    overrides = [str(o) for o in overrides or ()]
    if overrides:
        command = shlex.join(["--config", *overrides])
        typed = escape(command).replace("-", "-{}").replace("'", r"\textquotesingle{}")
        text += r", then \texttt{\frenchspacing " + typed + "}"  # no wider space after a colon
    return text


def build_header(*, configfiles, overrides=(), when=None, root="."):
    """LaTeX for the page-1 header: build date, git commit (and whether the tree has uncommitted changes),
    configuration (files and ``--config`` overrides, :func:`config_provenance`) and machine."""
    when = when or datetime.datetime.now(datetime.UTC)
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=normal"],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        code = f"git commit {commit}" + (
            " with uncommitted changes" if dirty else ", no uncommitted changes"
        )
    except (OSError, subprocess.CalledProcessError):
        code = "not a git checkout (commit unknown)"
    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = " ".join(line.split(":", 1)[1].split())
                break
    except OSError:
        pass
    machine = f"{platform.node()}: {platform.system()} {platform.machine()}, {os.cpu_count()} logical CPUs"
    if cpu:
        machine += f" ({cpu})"
    machine += f", Python {platform.python_version()}"
    rows = [
        ("Built", when.strftime("%Y-%m-%d %H:%M UTC")),
        ("Code", code),
        ("Machine", machine),
    ]
    rows = [(k, escape(v)) for k, v in rows]
    rows.insert(2, ("Configuration", config_provenance(configfiles, overrides)))
    body = "\n".join(row([k, v]) for k, v in rows)
    return (
        "\\begin{center}\\small\n\\begin{tabularx}{0.9\\linewidth}{@{}l>{\\raggedright\\arraybackslash}X@{}}\n"
        + body
        + "\n\\end{tabularx}\n\\end{center}\n"
    )


def build_pdf(tex, pdf, *, root=None, log=None, header=None):
    """Run latexmk (pdflatex) on the template ``tex`` in the folder ``root`` (default: the template's folder),
    output in ``<root>/build``; copy the PDF to ``pdf``.

    TeX looks for the files the template inputs (``tables/*.tex``, ``figures/*.pdf``, ``build/header.tex``) in the
    folder it runs in, so one template serves every study's report folder (``reports/{study}``).
    ``header``: LaTeX written to ``<root>/build/header.tex`` first (the template inputs it; see
    :func:`build_header`). Raises InputError without latexmk, RuntimeError if LaTeX fails (naming its log).
    """
    tex = Path(tex).resolve()
    root = Path(root).resolve() if root is not None else tex.parent
    if shutil.which("latexmk") is None:
        raise InputError(
            "latexmk is not installed (bin/setup installs TeX Live); cannot build the PDF"
        )
    build = root / "build"
    build.mkdir(parents=True, exist_ok=True)
    (build / "header.tex").write_text(header if header is not None else "")
    cmd = [
        "latexmk",
        "-pdf",
        "-interaction=nonstopmode",
        "-halt-on-error",
        f"-outdir={build}",
        str(tex),
    ]
    res = subprocess.run(cmd, cwd=root, capture_output=True, text=True)
    if log is not None:
        Path(log).write_text(res.stdout + res.stderr)
    if res.returncode != 0:
        raise RuntimeError(
            f"latexmk failed on {tex} (exit {res.returncode}); see {build / tex.with_suffix('.log').name}"
        )
    with atomic_path(pdf) as tmp:
        shutil.copyfile(build / tex.with_suffix(".pdf").name, tmp)


def latex_log_problems(text, *, max_overfull_pt=1.0):
    """Problems in a LaTeX log: overfull boxes wider than ``max_overfull_pt``, undefined references and
    citations, and the request to rerun. Returns a list of the offending log lines (empty if none)."""
    out = []
    for line in text.splitlines():
        m = re.match(r"Overfull \\[hv]box \(([\d.]+)pt too (wide|high)\)", line)
        if m and float(m.group(1)) > max_overfull_pt:
            out.append(line)
        elif (
            re.search(r"LaTeX Warning: (Reference|Citation) .* undefined", line)
            or "There were undefined references" in line
            or "Rerun to get cross-references right" in line
        ):
            out.append(line)
    return out
