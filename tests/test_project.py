"""The project as a user meets it: the documents its code cites exist in it; the bin/ scripts refuse a clone
path that Snakemake cannot run from."""

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


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
    proc = subprocess.run(["bash", str(clone / "bin" / script)], capture_output=True, text=True, env=env, timeout=60)
    assert proc.returncode == 1, proc.stderr
    assert re.search(rf"\[{script}\] the path of this clone, '{re.escape(str(clone))}', contains white space; "
                     r"Snakemake would run .* unquoted .*snakemake/snakemake#2645.*Clone or move bsrbench to a path "
                     r"without white space", proc.stderr), proc.stderr
    assert sorted(p.name for p in clone.iterdir()) == ["bin"]  # no .venv, nothing else
