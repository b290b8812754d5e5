"""A method's fit jobs depend on every module they import, derived from the import graph (issue 36, item 1).

In a copy of the project (its own ``src/`` first on PYTHONPATH, so that the code inputs are the copy's files), one
real run of one small split per estimator module, then per module that a fit imports: edit it, ask Snakemake
(dry run) which fit jobs it would rerun, and put it back. The jobs rerun must be exactly those of the methods whose
modules include it.
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bsrbench.methods import configured

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))
FEATURES = ROOT / "results" / "features" / "hsc" / "golf.npz"

#: One method per estimator module of config/config.yaml, each at its cheapest (PM at config/ci.yaml's size).
CONFIG = """
study: deps
study_activities:
  hsc: [golf]
  mocap: []
n_train: [30]
n_seeds: 1
protocols: [random]
cv: {mode: none, folds: 2}
conformal_level: null
job_server: false
run: [RVM, TGP, SR, DDL, PM, NN1, KRR]
methods:
  PM:
    params: {n_atoms: 16, n_neighbors: 3, n_iter: 20, n_burn_in: 10}
    chains: 1
  DDL:
    params: {n_components: 10}
"""


def dry_run_methods(work, env):
    """The methods whose fit jobs a dry run of the study would run."""
    res = subprocess.run(
        [SNAKEMAKE, "-n", "results/deps/aggregate/results.csv", "--cores", "1"]
        + ["--configfile", "config/deps.yaml"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return set(re.findall(r"method=([A-Za-z0-9_]+)", res.stdout))


@pytest.mark.skipif(not FEATURES.is_file(), reason="needs results/features/hsc/golf.npz")
def test_an_edit_of_any_module_a_fit_imports_reruns_exactly_its_methods_fits(tmp_path):
    work = tmp_path
    for name in ("Snakefile", "workflow", "profiles", "config"):
        src = ROOT / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    shutil.copytree(ROOT / "src" / "bsrbench", work / "src" / "bsrbench")
    (work / "resources").symlink_to(ROOT / "resources")
    (work / "results" / "features" / "hsc").mkdir(parents=True)
    shutil.copy(FEATURES, work / "results" / "features" / "hsc" / "golf.npz")
    (work / "config" / "deps.yaml").write_text(CONFIG)
    env = dict(
        os.environ,
        PYTHONPATH=f"{work / 'src'}:{os.environ.get('PYTHONPATH', '')}",
        PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}",
    )
    res = subprocess.run(
        [SNAKEMAKE, "results/deps/aggregate/results.csv", "--cores", "2"]
        + ["--configfile", "config/deps.yaml"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    assert dry_run_methods(work, env) == set()

    # the modules per method, from the import graph (the same derivation as the workflow's code inputs)
    run = ["RVM", "TGP", "SR", "DDL", "PM", "NN1", "KRR"]
    methods = {name: configured()[name] for name in run}
    modules = {name: m.modules() for name, m in methods.items()}
    for name, mods in modules.items():
        print(f"{name} ({methods[name].module}): {' '.join(mods)}")
    files = {}
    for mod in {mod for mods in modules.values() for mod in mods}:
        base = work / "src" / Path(*mod.split("."))
        files[mod] = (
            base.with_suffix(".py") if base.with_suffix(".py").is_file() else base / "__init__.py"
        )
    # Snakemake's own record of each fit job's inputs: every module of the method and no other module
    summary = subprocess.run(
        [SNAKEMAKE, "--detailed-summary", "results/deps/aggregate/results.csv", "--cores", "1"]
        + ["--configfile", "config/deps.yaml"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert summary.returncode == 0, summary.stderr[-3000:]
    inputs = {}
    for line in summary.stdout.splitlines():
        cols = line.split("\t")
        if len(cols) > 4 and cols[2] == "fit" and cols[0].endswith(".json"):
            method = Path(cols[0]).parts[-3]
            inputs[method] = {Path(f).resolve() for f in cols[4].split(",")}
    assert set(inputs) == set(modules)
    for mod, path in files.items():
        expected = {name for name, mods in modules.items() if mod in mods}
        assert {m for m, got in inputs.items() if path.resolve() in got} == expected, mod

    # an edit of a module reruns exactly the fits of the methods that import it: the modules the hand-kept list
    # missed, and modules of one or two methods only
    probes = [
        "bsrbench.convergence",
        "bsrbench.seeds",
        "bsrbench.models.scaling",
        "bsrbench.models.reference",
        "bsrbench.models._bsr_kernels",
        "bsrbench.models.sr",
    ]
    for mod in probes:
        path = files[mod]
        text, stat = path.read_bytes(), path.stat()
        path.write_bytes(text + b"\n# edited\n")
        try:
            expected = {name for name, mods in modules.items() if mod in mods}
            print(f"edit {mod}: reruns the fits of {sorted(expected)}")
            assert dry_run_methods(work, env) == expected, mod
        finally:
            path.write_bytes(text)
            os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
