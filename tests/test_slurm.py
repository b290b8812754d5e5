"""profiles/slurm on a real single-node SLURM (bin/slurm-local), without and with job accounting.

Marker ``slurm`` (CI: `bin/test -m slurm`, as root; the cluster's packages are installed on first use). Each test
starts its own cluster and stops it. The study is config/ci.yaml with two of its methods (Ridge, which has a CV job,
and 1-NN), so that a run takes about a minute. What ran where comes from SLURM's own records (``squeue
--states=all`` without accounting, ``sacct`` with it): every job's comment names its rule and wildcards. A fit job
runs the seeds of its (protocol, source, activity, method, n_train) (config key seeds_per_job, default all), so its
wildcards name no seed.
"""

import base64
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest

from bsrbench import cluster, jobserver

# The cluster tests; the checks of bsrbench.cluster's rules below them run in the ordinary suite.
on_cluster = [
    pytest.mark.slurm,
    pytest.mark.skipif(os.geteuid() != 0, reason="bin/slurm-local runs the SLURM daemons as root"),
]

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))
SLURM_LOCAL = str(ROOT / "bin" / "slurm-local")
STUDY = ("--configfile", "config/ci.yaml", "--config", "run=[Ridge,NN1]")
TARGET = "reports/ci/tables/tableI_hsc.tex"
# The plugin's first status query after 5 s instead of 40 s (the test's jobs take seconds).
SLURM_ARGS = (
    "--workflow-profile",
    "profiles/slurm",
    "--slurm-init-seconds-before-status-checks",
    "5",
)
DAEMONS = ("munged", "mariadbd", "slurmdbd", "slurmctld", "slurmd")


def env(**extra):
    return dict(
        os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}", **extra
    )


# A `sitecustomize` module (Python imports it at start-up from PYTHONPATH, which sbatch passes on to the jobs):
# the fit job that runs GATED_JOB waits until the file GATE exists, so that a test decides when it may finish.
# Ridge's fit job is submitted last (after Ridge's CV), so that the two other jobs (the CV, 1-NN's fit job) can
# finish first on a node of one core.
GATED_JOB = ("Ridge", "1")  # method, seed
GATE_MODULE = """
import json, os, sys, time
if "bsrbench.jobs:fit" in sys.argv:
    job = next(json.loads(a) for a in sys.argv if a.startswith('{{"block"') or a.startswith('{{"input"'))
    seeds = [(s["wildcards"]["method"], str(s["wildcards"]["seed"])) for s in job.get("block", [job])]
    if {job!r} in seeds:
        deadline = time.monotonic() + 900
        while not os.path.exists({gate!r}) and time.monotonic() < deadline:
            time.sleep(0.2)
"""


def gated_env(work):
    """The environment of a run whose fit job GATED_JOB waits for the file ``work/gate``; and that path."""
    folder, gate = work / "sitecustomize", work / "gate"
    folder.mkdir()
    (folder / "sitecustomize.py").write_text(GATE_MODULE.format(job=GATED_JOB, gate=str(gate)))
    return env(PYTHONPATH=str(folder)), gate


def smk(*args, cwd, timeout=900):
    return subprocess.run(
        [SNAKEMAKE, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env()
    )


def copy_tree(work):
    for name in ("Snakefile", "workflow", "profiles", "config"):
        src = ROOT / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    (work / "resources").symlink_to(ROOT / "resources")
    return work


def tables(work):
    return {p.name: p.read_bytes() for p in sorted((work / "reports" / "ci" / "tables").glob("*"))}


@contextmanager
def slurm_cluster(*args):
    """A cluster from bin/slurm-local for the block; afterwards none of its daemons runs."""
    res = subprocess.run([SLURM_LOCAL, "start", *args], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    status = subprocess.run([SLURM_LOCAL, "status"], capture_output=True, text=True)
    pids = [int(p) for p in re.findall(r"running \(pid (\d+)\)", status.stderr)]
    assert len(pids) == (5 if args else 3), status.stderr
    try:
        yield
    finally:
        res = subprocess.run([SLURM_LOCAL, "stop"], capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr
        assert [p for p in pids if Path(f"/proc/{p}").exists()] == []
        assert not Path("/etc/slurm/slurm.conf").exists()


def run_id(log_text):
    m = re.search(r"SLURM run ID: (\S+)", log_text)
    assert m, log_text[-3000:]
    return m.group(1)


def slurm_jobs(name, accounting):
    """SLURM's records of the jobs named ``name`` (a run id): [(job id, rule, wildcards, state)], from the
    comment the plugin gives each job (with accounting: from the recorded sbatch command line, since slurmdbd
    stores the comment itself only when the job ends)."""
    if accounting:
        cmd = ["sacct", "-X", "--noheader", "--parsable2", "--format=JobID,SubmitLine,State"]
        cmd += ["--starttime", "now-1days", "--endtime", "now", "--name", name]
    else:
        cmd = ["squeue", "--states=all", "--noheader", "--format=%i|%k|%T", "--name", name]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    jobs = []
    for line in out.splitlines():
        jobid, comment, state = line.split("|")
        m = re.search(r"(?:^|--comment )'?rule_(\w+?)_wildcards_(\w+)", comment)
        assert m, line
        jobs.append((jobid, m.group(1), m.group(2), state.split()[0]))
    return sorted(jobs, key=lambda j: int(j[0]))


def job_of(path):
    """(rule, wildcards) of the job that writes a fit or CV output path results/ci/<rule>/<protocol>/<source>/
    <activity>/<method>/n<n>/seed<seed>.<ext> (the job of all the seeds of its cell), named as the plugin's
    comments name them; None for other paths."""
    parts = Path(path).parts
    if parts[:2] != ("results", "ci") or parts[2] not in ("fit", "cv") or len(parts) != 9:
        return None
    protocol, source, activity, method, n, _ = parts[3:]
    return parts[2], f"{protocol}_{source}_{activity}_{method}_{n[1:]}"


def job_outputs(work):
    """{(rule, wildcards): its fit and CV result files} of the jobs with results in ``work``."""
    out = {}
    for p in (work / "results" / "ci").glob("*/*/*/*/*/n*/seed*.json"):
        path = p.relative_to(work)
        if job := job_of(path):
            out.setdefault(job, set()).add(path)
    return out


def cluster_jobs(work, outputs):
    """(rule, wildcards) of the jobs whose every result of ``outputs`` (:func:`job_outputs` of a complete run)
    is in ``work``."""
    return {job for job, files in outputs.items() if all((work / f).exists() for f in files)}


def assert_no_job_server(work):
    sock = jobserver.socket_path(cwd=work)
    assert sorted(sock.parent.glob(sock.name + "*")) == []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            args = cmdline.read_bytes().split(b"\0")
        except OSError:
            continue
        assert str(sock).encode() not in args, args  # a server of this working directory


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    """The same study run locally: its tables, its fit and CV jobs and their result files."""
    work = copy_tree(tmp_path_factory.mktemp("local"))
    res = smk(TARGET, "--cores", "2", *STUDY, cwd=work)
    assert res.returncode == 0, res.stderr[-3000:]
    outputs = job_outputs(work)
    jobs = cluster_jobs(work, outputs)
    # 2 methods, each one job of its 2 seeds, and one CV of Ridge's grid (cv mode per_size: one per training size)
    assert {r for r, _ in jobs} == {"fit", "cv"} and len(jobs) == 3, jobs
    assert sorted(len(f) for f in outputs.values()) == [1, 2, 2], outputs
    return tables(work), jobs, outputs


@on_cluster[0]
@on_cluster[1]
def test_sacct_on_a_cluster_without_accounting_stops_before_any_job(tmp_path):
    work = copy_tree(tmp_path)
    with slurm_cluster():
        res = smk(TARGET, *SLURM_ARGS, "--slurm-status-command", "sacct", *STUDY, cwd=work)
        out = res.stdout + res.stderr
        assert res.returncode != 0
        assert "keeps no job accounting (AccountingStorageType = accounting_storage/none)" in out, (
            out
        )
        assert "--slurm-status-command squeue" in out
        listed = subprocess.run(
            ["squeue", "--states=all", "--noheader"], capture_output=True, text=True
        )
        assert listed.stdout.strip() == ""  # nothing was submitted
        # and the check itself, on this cluster
        cluster.check_cluster("squeue", 5)
        with pytest.raises(cluster.ClusterError, match="no job accounting"):
            cluster.check_cluster("sacct", 5)
        with pytest.raises(cluster.ClusterError, match="'gpu' is not a partition"):
            cluster.check_cluster("squeue", 5, ["gpu"])


@on_cluster[0]
@on_cluster[1]
def test_squeue_run_without_accounting_retries_a_cancelled_fit(tmp_path, local_run):
    """Status by squeue; a fit job scancelled while it runs is resubmitted (the profile's retries) and the run
    completes by itself with the local run's tables."""
    local_tables, local_jobs, _ = local_run
    work = copy_tree(tmp_path)
    log = work / "run.log"
    with slurm_cluster():
        with open(log, "w") as fh:
            proc = subprocess.Popen(
                [SNAKEMAKE, TARGET, *SLURM_ARGS, "--slurm-status-command", "squeue", *STUDY],
                cwd=work, stdout=fh, stderr=subprocess.STDOUT, env=env(),
            )  # fmt: skip
        try:
            cancelled = None
            deadline = time.monotonic() + 300
            while cancelled is None and time.monotonic() < deadline and proc.poll() is None:
                time.sleep(0.5)
                if "SLURM run ID" not in log.read_text():
                    continue
                running = [
                    j for j in slurm_jobs(run_id(log.read_text()), False) if j[1:2] == ("fit",)
                ]
                running = [j for j in running if j[3] == "RUNNING"]
                if running:
                    cancelled = running[0]
                    subprocess.run(["scancel", cancelled[0]], check=True)
            assert cancelled, log.read_text()[-3000:]
            assert proc.wait(timeout=600) == 0, log.read_text()[-4000:]
        finally:
            if proc.poll() is None:
                proc.kill()
        jobs = slurm_jobs(run_id(log.read_text()), False)
        print("SLURM jobs (no accounting, squeue):", *jobs, sep="\n  ")
        assert {
            (r, w) for _, r, w, _ in jobs
        } == local_jobs  # the local rules ran here, not in SLURM
        states = {(r, w, s) for _, r, w, s in jobs}
        assert ("fit", cancelled[2], "CANCELLED") in states
        assert ("fit", cancelled[2], "COMPLETED") in states  # its retry
        assert len(jobs) == len(local_jobs) + 1
        assert all(s == "COMPLETED" for j, _, _, s in jobs if j != cancelled[0])
    assert tables(work) == local_tables
    assert_no_job_server(work)


def incomplete_outputs(work):
    """Outputs Snakemake marked as incomplete (.snakemake/incomplete/<urlsafe base64 of the path>)."""
    d = work / ".snakemake" / "incomplete"
    names = [p.name for p in d.iterdir()] if d.is_dir() else []
    return {base64.urlsafe_b64decode(n).decode() for n in names if n != "migration_underway"}


@on_cluster[0]
@on_cluster[1]
def test_sacct_run_with_accounting_killed_then_rerun_submits_only_the_missing_jobs(
    tmp_path, local_run
):
    """Status by sacct (slurmdbd, MariaDB); the main Snakemake process killed with SIGKILL mid-run; after
    `--unlock` the rerun submits exactly the fit and CV jobs whose results are missing or incomplete.

    One fit job (GATED_JOB) cannot finish before the test opens its gate: the kill lands with it unfinished
    and at least two others done, and it is then cancelled, so that it is missing however fast the machine."""
    local_tables, local_jobs, outputs = local_run
    work = copy_tree(tmp_path)
    log = work / "run.log"
    gated_env_, gate = gated_env(work)
    with slurm_cluster("--accounting"):
        with open(log, "w") as fh:
            proc = subprocess.Popen(
                [SNAKEMAKE, TARGET, *SLURM_ARGS, "--slurm-status-command", "sacct", *STUDY],
                cwd=work, stdout=fh, stderr=subprocess.STDOUT, env=gated_env_,
            )  # fmt: skip
        try:
            deadline = time.monotonic() + 300
            while time.monotonic() < deadline and proc.poll() is None:
                time.sleep(0.5)
                if "SLURM run ID" in log.read_text() and len(cluster_jobs(work, outputs)) >= 2:
                    break
            assert proc.poll() is None, log.read_text()[-3000:]
            assert len(cluster_jobs(work, outputs)) >= 2, log.read_text()[-3000:]
            proc.send_signal(signal.SIGKILL)
            proc.wait(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
        first = run_id(log.read_text())
        # The gated job, if submitted, is cancelled (found by squeue: slurmctld's records, which sacct's may
        # lag); the other jobs it had submitted run to their end on their own.
        method, _ = GATED_JOB
        for jobid, rule, wildcards, _ in slurm_jobs(first, False):
            if rule == "fit" and wildcards.endswith(f"_{method}_30"):
                subprocess.run(["scancel", jobid], check=True)
        deadline = time.monotonic() + 300
        while any(s in ("PENDING", "RUNNING") for *_, s in slurm_jobs(first, True)):
            assert time.monotonic() < deadline
            time.sleep(1)
        gate.touch()  # the rerun's jobs pass
        done = cluster_jobs(work, outputs)
        incomplete = incomplete_outputs(work)
        kept = done - {job_of(p) for p in incomplete}
        missing = local_jobs - kept
        assert any(r == "fit" and w.endswith(f"_{method}_30") for r, w in missing), missing
        assert 0 < len(missing) < len(local_jobs), (done, incomplete)

        res = smk(TARGET, *SLURM_ARGS, *STUDY, "--unlock", cwd=work)
        assert res.returncode == 0, res.stderr[-3000:]
        res = smk(TARGET, *SLURM_ARGS, "--slurm-status-command", "sacct", *STUDY, cwd=work)
        assert res.returncode == 0, (res.stdout + res.stderr)[-4000:]
        rerun = slurm_jobs(run_id(res.stdout + res.stderr), True)
        print(
            "SLURM jobs of the killed run (accounting, sacct):",
            *slurm_jobs(first, True),
            sep="\n  ",
        )
        print("SLURM jobs of the rerun:", *rerun, sep="\n  ")
        assert {(r, w) for _, r, w, _ in rerun} == missing
        assert len(rerun) == len(missing) and all(s == "COMPLETED" for *_, s in rerun)
    assert tables(work) == local_tables
    assert_no_job_server(work)


@on_cluster[0]
@on_cluster[1]
def test_a_status_query_that_keeps_failing_ends_the_run(tmp_path):
    """slurmdbd stopped after the jobs are submitted: every sacct query fails, and the run ends by itself
    (bsrbench.cluster.guard_status_queries) with a message naming the jobs, instead of waiting forever."""
    work = copy_tree(tmp_path)
    log = work / "run.log"
    with slurm_cluster("--accounting"):
        with open(log, "w") as fh:
            proc = subprocess.Popen(
                [SNAKEMAKE, TARGET, *SLURM_ARGS, "--slurm-status-command", "sacct", *STUDY],
                cwd=work, stdout=fh, stderr=subprocess.STDOUT, env=env(),
            )  # fmt: skip
        try:
            deadline = time.monotonic() + 120
            while (
                "Job 0 has been submitted" not in log.read_text()
                and "SLURM jobid" not in log.read_text()
            ):
                assert time.monotonic() < deadline and proc.poll() is None, log.read_text()[-3000:]
                time.sleep(0.5)
            dbd = int((Path("/tmp/bsrbench-slurm/run/slurmdbd.pid")).read_text())
            os.kill(dbd, signal.SIGTERM)
            start = time.monotonic()
            rc = proc.wait(timeout=400)
            print(
                f"run ended {time.monotonic() - start:.0f} s after slurmdbd stopped, exit code {rc}"
            )
        finally:
            if proc.poll() is None:
                proc.kill()
        out = log.read_text()
        assert rc != 0
        assert "the SLURM status query (sacct) failed in 3 status checks in a row" in out, out[
            -3000:
        ]
    assert_no_job_server(work)


# ------------------------------------------------------------------ bsrbench.cluster's rules, without a cluster
# `scontrol show config` of slurm-wlm 22.05 (excerpt; a cluster without accounting).
SCONTROL = """Configuration data as of 2026-12-01T21:00:00
AccountingStorageBackupHost = (null)
AccountingStorageType   = accounting_storage/none
MinJobAge               = 300 sec
SLURM_VERSION           = 22.05.8
"""


def test_scontrol_config_is_read():
    config = cluster.parse_config(SCONTROL)
    assert config["AccountingStorageType"] == "accounting_storage/none"
    assert config["MinJobAge"] == "300 sec" and config["SLURM_VERSION"] == "22.05.8"
    assert "Configuration data as of 2026-12-01T21" not in config
    assert [cluster.seconds(v) for v in ("300 sec", "300", "2h", "5 min", "soon")] == [
        300,
        300,
        7200,
        300,
        None,
    ]


@pytest.mark.parametrize(
    "command, storage, age, init, ok",
    [
        (
            "sacct",
            "accounting_storage/slurmdbd",
            "2 sec",
            40,
            True,
        ),  # sacct does not need MinJobAge
        ("sacct", "accounting_storage/none", "300 sec", 40, False),
        ("squeue", "accounting_storage/none", "300 sec", 40, True),
        ("squeue", "accounting_storage/none", "240 sec", 40, True),  # 180 s pause + 60 s margin
        ("squeue", "accounting_storage/none", "239 sec", 40, False),
        # under 3 x 100 s the plugin switches to sacct
        ("squeue", "accounting_storage/slurmdbd", "299 sec", 100, False),
        # nothing to switch to: 3 x 100 = 300
        ("squeue", "accounting_storage/none", "300 sec", 100, True),
        ("qstat", "accounting_storage/slurmdbd", "300 sec", 40, False),
    ],
)
def test_status_command_rules(command, storage, age, init, ok):
    config = {"AccountingStorageType": storage, "MinJobAge": age}
    problem = cluster.status_problem(command, config, init)
    assert (problem is None) == ok, problem


def test_the_messages_say_what_to_set():
    no_accounting = cluster.parse_config(SCONTROL)
    assert "--slurm-status-command squeue" in cluster.status_problem("sacct", no_accounting)
    short = dict(no_accounting, MinJobAge="30 sec")
    assert "raise MinJobAge" in cluster.status_problem("squeue", short)
    short_acct = dict(short, AccountingStorageType="accounting_storage/slurmdbd")
    assert "--slurm-status-command sacct" in cluster.status_problem("squeue", short_acct)
