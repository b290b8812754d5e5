"""Checks that a SLURM cluster can run the study through profiles/slurm, made before any job is submitted.

snakemake-executor-plugin-slurm learns that a job ended only from its status command: ``sacct`` (job accounting,
slurmdbd) or ``squeue`` (slurmctld's memory of recent jobs). When that command cannot see the jobs, the plugin
drops them from its list without reporting them, and Snakemake waits for them forever. Two such clusters:

- ``sacct`` on a cluster without accounting (``AccountingStorageType = accounting_storage/none``): every query
  fails ("Slurm accounting storage is disabled").
- ``squeue`` on a cluster whose ``MinJobAge`` is short: a finished job leaves slurmctld's memory before the next
  query. The plugin waits up to ``MAX_STATUS_INTERVAL`` seconds between queries, and it silently switches to
  ``sacct`` when ``MinJobAge`` is under three times its first interval (``--slurm-init-seconds-before-status-checks``).

:func:`check_cluster` runs SLURM's own commands and raises :class:`ClusterError`, saying what to set, when the
configured status command cannot work. The Snakefile calls it from ``onstart`` (docs/cluster.md).
"""

import re
import shlex
import subprocess

#: The plugin's longest pause between two status queries (snakemake-executor-plugin-slurm 2.8.0, seconds).
MAX_STATUS_INTERVAL = 180
#: Time a finished job must stay visible beyond that pause (a query's own duration, slurmctld's purge timing).
MARGIN = 60
#: Seconds a SLURM command may take before the check gives up on it.
TIMEOUT = 30

_SET_SQUEUE = (
    "Set `slurm-status-command: squeue` in profiles/slurm/config.yaml or add `--slurm-status-command squeue` "
    "to the snakemake command"
)
_SET_SACCT = (
    "Set `slurm-status-command: sacct` in profiles/slurm/config.yaml or add `--slurm-status-command sacct` "
    "to the snakemake command"
)


class ClusterError(RuntimeError):
    """The cluster cannot run the workflow with the given settings; the message says what to change."""


def parse_config(text):
    """``scontrol show config`` output as a dict (``Key = value`` lines; the values are stripped strings)."""
    out = {}
    for line in text.splitlines():
        key, sep, value = line.partition("=")
        if sep and key.strip() and " " not in key.strip():
            out[key.strip()] = value.strip()
    return out


def seconds(value):
    """A SLURM duration such as ``300 sec``, ``300`` or ``1h`` in seconds; None if it is not one."""
    m = re.fullmatch(r"(\d+)\s*([a-zA-Z]*)", value.strip())
    if not m:
        return None
    unit = m.group(2).lower()
    factor = {
        "": 1,
        "s": 1,
        "sec": 1,
        "secs": 1,
        "m": 60,
        "min": 60,
        "h": 3600,
        "hour": 3600,
        "hours": 3600,
    }
    return int(m.group(1)) * factor[unit] if unit in factor else None


def has_accounting(config):
    """Whether the cluster (its ``scontrol show config`` dict) stores job accounting for ``sacct``."""
    storage = config.get("AccountingStorageType", "")
    return bool(storage) and not storage.endswith("/none") and storage != "(null)"


def min_job_age_needed(init_seconds):
    """The shortest ``MinJobAge`` with which ``squeue`` sees every finished job (see the module docstring)."""
    return max(3 * init_seconds, MAX_STATUS_INTERVAL + MARGIN)


def status_problem(status_command, config, init_seconds=40):
    """Why ``status_command`` cannot follow jobs on the cluster of ``config`` (``scontrol show config`` as a
    dict), with what to set; None when it can."""
    if status_command not in ("sacct", "squeue"):
        return (
            f"slurm-status-command is {status_command!r}; expected 'sacct' (clusters with job accounting) "
            "or 'squeue'."
        )
    if status_command == "sacct":
        if has_accounting(config):
            return None
        storage = config.get("AccountingStorageType", "not set")
        return (
            "the SLURM status command is 'sacct', but this cluster keeps no job accounting "
            f"(AccountingStorageType = {storage}): sacct cannot see the jobs and the run would wait for them "
            f"forever. {_SET_SQUEUE}."
        )
    age = seconds(config.get("MinJobAge", ""))
    needed = min_job_age_needed(init_seconds)
    if age is not None and age >= needed:
        return None
    found = f"MinJobAge = {config['MinJobAge']}" if "MinJobAge" in config else "MinJobAge unknown"
    fix = (
        f"{_SET_SACCT} (this cluster has job accounting)"
        if has_accounting(config)
        else "Ask the cluster's administrator to raise MinJobAge (SLURM's default is 300 s)"
    )
    return (
        f"the SLURM status command is 'squeue', which needs finished jobs kept for at least {needed} s "
        f"(MinJobAge in slurm.conf; this cluster: {found}): it would miss finished jobs and the run would wait "
        f"for them forever. {fix}."
    )


def _run(cmd):
    try:
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
    except FileNotFoundError:
        raise ClusterError(
            f"`{cmd[0]}` is not installed on this host: the SLURM profile submits jobs from a host with the "
            "SLURM client commands (sbatch, squeue, sacct, scontrol, sinfo)."
        ) from None
    except subprocess.TimeoutExpired:
        raise ClusterError(f"`{shlex.join(cmd)}` did not answer within {TIMEOUT} s.") from None
    return res


def status_query(status_command):
    """The plugin's own status query for ``status_command``, for a job name no job has (it must succeed)."""
    from snakemake_executor_plugin_slurm import job_status_query as q

    build = q.query_job_status_sacct if status_command == "sacct" else q.query_job_status_squeue
    return shlex.split(build("bsrbench-cluster-check"))


def check_cluster(status_command, init_seconds=40, partitions=()):
    """Raise :class:`ClusterError` unless jobs can be submitted to this host's SLURM and followed with
    ``status_command``; ``partitions`` are the ``slurm_partition`` resources of the jobs to submit (None or
    empty: the cluster's default partition)."""
    res = _run(["scontrol", "show", "config"])
    if res.returncode != 0:
        raise ClusterError(
            f"`scontrol show config` failed, so no job can be submitted: {res.stderr.strip()} "
            "(is slurmctld running, and SLURM_CONF set if slurm.conf is not in /etc/slurm?)"
        )
    config = parse_config(res.stdout)
    problem = status_problem(status_command, config, init_seconds)
    if problem:
        raise ClusterError(problem)
    query = status_query(status_command)
    res = _run(query)
    if res.returncode != 0:
        raise ClusterError(
            f"the SLURM status query fails on this cluster, and the run would wait forever for its jobs: "
            f"`{shlex.join(query)}` says {res.stderr.strip()!r}."
        )
    res = _run(["sinfo", "--noheader", "--format=%P"])
    listed = res.stdout.split() if res.returncode == 0 else []
    names = {p.rstrip("*") for p in listed}
    for p in sorted({str(p) for p in partitions if p}):
        if p not in names:
            raise ClusterError(
                f"slurm_partition {p!r} is not a partition of this cluster (sinfo lists: "
                f"{', '.join(sorted(names)) or 'none'}); set one of them with --default-resources "
                "slurm_partition=<name>."
            )
    if (not partitions or not all(partitions)) and not any(p.endswith("*") for p in listed):
        raise ClusterError(
            "this cluster has no default partition and no slurm_partition is set; set one with "
            f"--default-resources slurm_partition=<name> (sinfo lists: {', '.join(sorted(names)) or 'none'})."
        )


#: Status checks in a row whose every query failed, after which the run stops (see guard_status_queries).
MAX_FAILED_CHECKS = 3


def guard_status_queries(executor_class, max_failed=MAX_FAILED_CHECKS):
    """Make ``executor_class`` (snakemake-executor-plugin-slurm 2.8.0's Executor) stop the run when its status
    query keeps failing, instead of waiting forever.

    When every attempt of a status check fails, the plugin reports none of the active jobs and yields none of
    them back, so Snakemake forgets them and waits. The wrapped check yields them back (the next check tries
    again) and, after ``max_failed`` such checks in a row, raises :class:`ClusterError`, which ends the run
    (Snakemake's scheduler raises an executor's error). The failures are read from the plugin's own counters
    of successful and failed queries."""
    original = executor_class.check_active_jobs
    if getattr(original, "guarded", False):
        return

    async def check_active_jobs(self, active_jobs):
        calls, failures = self._status_query_calls, self._status_query_failures
        async for job in original(self, active_jobs):
            yield job
        if (
            not active_jobs
            or self._status_query_calls > calls
            or self._status_query_failures == failures
        ):
            self._failed_status_checks = 0
            return
        self._failed_status_checks = getattr(self, "_failed_status_checks", 0) + 1
        if self._failed_status_checks >= max_failed:
            ids = ", ".join(sorted(str(j.external_jobid) for j in active_jobs))
            raise ClusterError(
                f"the SLURM status query ({self.get_status_command()}) failed in {max_failed} status checks in "
                f"a row, so the run stops instead of waiting for jobs it cannot see (run with --verbose for "
                f"SLURM's message). Jobs still submitted: {ids}; scancel them or let them end, then rerun "
                "(after `snakemake --unlock` if needed)."
            )
        for job in active_jobs:
            yield job

    check_active_jobs.guarded = True
    executor_class.check_active_jobs = check_active_jobs
