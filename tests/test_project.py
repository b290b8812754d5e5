"""The project as a user meets it: the documents its code cites exist in it; the bin/ scripts refuse a clone
path that Snakemake cannot run from."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCANNED = (
    "README.md",
    "Snakefile",
    "bin",
    "config",
    "docs",
    "profiles",
    "src",
    "tests",
    "workflow",
    "benchmarks",
)
SUFFIXES = {".py", ".smk", ".md", ".yaml", ".yml", ".txt", ".tex", ""}
# a document of the project cited from its text, optionally with a section: docs/model.md, section "Error metric"
DOC_CITE = re.compile(
    r'docs/([A-Za-z0-9_.-]+\.md)(?:[,\s(]+section\s+"([^"]+)")?'
)  # may wrap over lines
MD_LINK = re.compile(r"\]\(([^()\s#]+\.md)?(?:#([^()\s]+))?\)")


def _project_text_files():
    """(path, text) of the project's own text files: sources, tests, configuration, documents, scripts."""
    for top in SCANNED:
        base = ROOT / top
        paths = [base] if base.is_file() else sorted(p for p in base.rglob("*") if p.is_file())
        for path in paths:
            rel = path.relative_to(ROOT).parts
            if path.suffix not in SUFFIXES or any(
                p.startswith(".") or p == "__pycache__" or p.endswith(".egg-info") for p in rel
            ):
                continue
            try:
                yield path, path.read_text(encoding="utf-8")
            except UnicodeDecodeError:
                continue


def _headings(md_path):
    """The section titles of a Markdown file, without their numbers ("3.1 Atoms" -> "Atoms")."""
    titles = []
    for line in md_path.read_text(encoding="utf-8").splitlines():
        m = re.match(r"#+\s+(?:[0-9.]+\s+)?(.*?)\s*$", line)
        if m:
            titles.append(m.group(1))
    return titles


def _slug(heading):
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.lower()).replace(" ", "-")


def test_documents_cited_by_the_project_exist_in_it():
    """The code cited "MODEL.md" and "shared MODEL.md", a document outside the repository (../shared), which a
    fresh clone does not have. Every document the project's text cites must be in the project: no MODEL.md or
    ../shared reference; every docs/<name>.md exists and has the section named after it; every relative link of a
    Markdown file points to an existing file and heading."""
    problems = []
    this = Path(__file__).resolve()
    for path, text in _project_text_files():
        if path.resolve() == this:
            continue
        rel = path.relative_to(ROOT)
        for m in DOC_CITE.finditer(text):
            name, section = m.group(1), " ".join((m.group(2) or "").split())
            n = text.count("\n", 0, m.start()) + 1
            doc = ROOT / "docs" / name
            if not doc.is_file():
                problems.append(f"{rel}:{n}: docs/{name} does not exist")
            elif section and section not in _headings(doc):
                problems.append(f"{rel}:{n}: docs/{name} has no section {section!r}")
        for n, line in enumerate(text.splitlines(), 1):
            if "MODEL.md" in line or re.search(r"\.\./shared/|/work/shared/", line):
                problems.append(f"{rel}:{n}: cites a document outside the project: {line.strip()}")
            if path.suffix == ".md":
                for target, anchor in MD_LINK.findall(line):
                    if not target and not anchor:
                        continue
                    doc = (path.parent / target).resolve() if target else path
                    if not doc.is_file():
                        problems.append(f"{rel}:{n}: link to {target}, which does not exist")
                    elif anchor and anchor not in {_slug(h) for h in _headings(doc)}:
                        problems.append(f"{rel}:{n}: link to {target}#{anchor}: no such heading")
    assert not problems, "\n".join(problems)


def test_the_model_document_cites_the_code_it_describes():
    """docs/model.md names the kernels and estimator options it documents; each must exist in the code (so that
    renaming one without updating the document fails here)."""
    from bsrbench.models import _bsr_kernels as kern
    from bsrbench.models.bsr import PREDICTIONS

    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    for name in re.findall(r"`((?:update|predict|logit|cholesky|_initial)_[a-z_]+)`", text):
        if name != "_initial_state":
            assert hasattr(kern, name), name
    for option in re.findall(r'`"([a-z-]+)"`', text):
        assert option in {
            *kern.W_UPDATES,
            *kern.ATOM_UPDATES,
            *kern.NOISE_MODELS,
            *PREDICTIONS,
            "uniform",
            "likelihood",
            "pooled",
        }, option


@pytest.mark.parametrize("script", ["setup", "study"])
def test_bin_scripts_stop_early_in_a_clone_path_with_white_space(tmp_path, script):
    """Snakemake (9.x) runs a `script:` rule as ``{sys.executable} script.py`` with the interpreter's path unquoted
    (snakemake/snakemake#2645), and .venv/bin/python lies inside the clone: from "/tmp/with space/bsrbench" the
    first script rule failed with "/usr/bin/bash: line 1: /tmp/with: No such file or directory". The scripts now
    stop before doing anything, naming the path and the reason."""
    clone = tmp_path / "my clone"
    (clone / "bin").mkdir(parents=True)
    for name in ("setup", "study"):
        shutil.copy2(ROOT / "bin" / name, clone / "bin" / name)
    env = dict(os.environ, BSRBENCH_NO_APT="1")
    proc = subprocess.run(
        ["bash", str(clone / "bin" / script)], capture_output=True, text=True, env=env, timeout=60
    )
    assert proc.returncode == 1, proc.stderr
    assert re.search(
        rf"\[{script}\] the path of this clone, '{re.escape(str(clone))}', contains white space; "
        r"Snakemake would run .* unquoted .*snakemake/snakemake#2645.*Clone or move bsrbench to a path "
        r"without white space",
        proc.stderr,
    ), proc.stderr
    assert sorted(p.name for p in clone.iterdir()) == ["bin"]  # no .venv, nothing else


@pytest.mark.parametrize(
    "args, dry",
    [
        (["-n"], True),
        (["--dry-run"], True),
        (["--dryrun"], True),
        (["-np"], True),
        (["-pn"], True),
        (["--configfile", "config/paper.yaml", "-n"], True),
        (["--cores", "2", "-Fn"], True),
        ([], False),
        (["-p"], False),
        (["--configfile", "config/paper.yaml"], False),
        (["--notemp"], False),
        (["--nolock", "--config", "n_train=[30]"], False),
        (["-j2"], False),
    ],
)
def test_bin_study_dry_run_writes_no_report(args, dry):
    """`bin/study -n` ran Snakemake's dry run and then `snakemake --summary` and `--report` for real. bin/study now
    stops after the dry run when its arguments ask for one (-n, --dry-run, --dryrun, -n in combined short flags);
    BSRBENCH_STUDY_PLAN=1 makes it print that decision (made by the same shell function) and exit."""
    env = dict(os.environ, BSRBENCH_STUDY_PLAN="1")
    proc = subprocess.run(
        ["bash", str(ROOT / "bin" / "study"), *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("dry run:" if dry else "run:"), proc.stdout
    assert ("no reports" in proc.stdout) == dry


def test_bench_bsr_ab_help_and_a_malformed_size():
    """benchmarks/bench_bsr_ab.py showed only its docstring's first line in --help, options without help, and
    `--sizes 30-64` ended in a ValueError traceback; now --help shows the whole docstring and every option's
    default, and a malformed cell is argparse's one-line error."""
    script = ROOT / "benchmarks" / "bench_bsr_ab.py"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    help_ = subprocess.run(
        [sys.executable, str(script), "--help"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert help_.returncode == 0, help_.stderr
    assert (
        "its own Generator with the same seed" in help_.stdout
    )  # a line from the middle of the docstring
    for option, default in [
        ("--sizes", "30x64 30x128"),
        ("--w-update", "ess"),
        ("--atom-update", "block"),
        ("--batches", "15"),
        ("--per-batch", "10"),
    ]:
        assert re.search(rf"{option}.*?\(default:\s+{default}", help_.stdout, re.S), (
            option,
            help_.stdout,
        )
    bad = subprocess.run(
        [sys.executable, str(script), "HEAD", "--sizes", "30-64"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert bad.returncode == 2 and "Traceback" not in bad.stderr, bad.stderr
    assert "error: argument --sizes: '30-64': expected NxK, e.g. 30x64" in bad.stderr, bad.stderr


def _as_at_a_terminal():
    """SIGINT as a shell at a terminal has it: handled by default and not blocked. A test process may have it
    ignored or blocked (inherited from whatever started it), and a child inherits that through exec."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def test_bin_study_interrupted_says_how_to_resume(tmp_path):
    """Ctrl-C (SIGINT to the terminal's process group) during `bin/study`: the finished jobs' files are kept, the
    last line says the run was interrupted and how to resume it, and the exit code is 130."""
    import signal
    import threading

    work = tmp_path / "study"
    work.mkdir()
    for name in ("Snakefile", "workflow", "profiles", "config", "bin"):
        src = ROOT / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    for name in ("requirements.lock", "pyproject.toml"):
        shutil.copy(ROOT / name, work / name)
    (work / "reports").mkdir()
    shutil.copy(ROOT / "reports" / "report.tex", work / "reports" / "report.tex")
    for name in ("resources", ".venv"):
        (work / name).symlink_to(ROOT / name)
    proc = subprocess.Popen(
        ["bin/study", "--configfile", "config/ci.yaml"],
        cwd=work,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
        env=dict(os.environ, BSRBENCH_NO_APT="1"),
        preexec_fn=_as_at_a_terminal,
    )
    # interrupt when Snakemake reports its first finished job (read as it comes, so the pipe never fills)
    lines, finished = [], threading.Event()

    def read():
        for line in proc.stdout:
            lines.append(line)
            if line.startswith("Finished jobid"):
                finished.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    assert finished.wait(timeout=300), "no job finished within 300 s: " + "".join(lines)[-3000:]
    done = [p for p in (work / "results").rglob("*.npz") if p.is_file()]
    os.killpg(proc.pid, signal.SIGINT)
    proc.wait(timeout=300)
    reader.join(timeout=60)
    out = "".join(lines)
    assert proc.returncode == 130, out[-3000:]
    last = out.strip().splitlines()[-1]
    assert last == (
        "[study] interrupted: the finished jobs are kept; rerun the same command to resume: "
        "bin/study --configfile config/ci.yaml"
    ), out[-3000:]
    assert done and all(
        p.is_file() for p in done
    )  # the first jobs (features, poses) write .npz files
