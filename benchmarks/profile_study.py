"""Where a study's wall time goes: model compute, job overhead and scheduling, per kind of job.

Reads what a finished run leaves behind, nothing else:
- Snakemake's ``benchmark:`` files (``results/{study}/benchmarks/**.tsv``, ``logs/features``, ``logs/mocap``):
  the wall time ``s`` of every job, from the rule's process start to its end;
- the fit and CV rows (``results/{study}/fit/**.json``, ``results/{study}/cv/**.json``, per-chain ``.npz``):
  the seconds spent inside the estimator (``fit_seconds + predict_seconds``, ``cv_seconds``), timed by the job;
- optionally Snakemake's own log (``--log``): the run's wall time, from its first to its last time stamp.

For each kind of job (PM fit, PM chain, PM chains, PM CV, each baseline's fits and CV, features, the rest) it
prints the number of jobs, the summed job wall time, the summed model time, and their difference (job overhead: starting
the rule's process, handing the job to the job server, loading the features, writing the outputs). With the
run's wall time W and c cores, c W minus the summed job wall time is the time no job was running on a core
(scheduling, waiting on dependencies, the report).

    python benchmarks/profile_study.py results/paper --log snakemake.log --cores 2
"""

import argparse
import csv
import json
import re
from collections import defaultdict
from datetime import datetime
from pathlib import Path

import numpy as np

#: Snakemake's time stamps, e.g. "[Mon Nov 30 12:17:05 2026]".
STAMP = re.compile(r"^\[(\w{3} \w{3} +\d+ \d\d:\d\d:\d\d \d{4})\]")


def job_seconds(tsv):
    """Wall time ``s`` (seconds) of one Snakemake benchmark file; raises ValueError naming the file if unreadable."""
    with open(tsv, newline="") as fh:
        rows = list(csv.DictReader(fh, delimiter="\t"))
    if not rows or "s" not in rows[0]:
        raise ValueError(f"{tsv}: expected a Snakemake benchmark table with a column 's'")
    return float(rows[-1]["s"])


#: The benchmark file of a job that runs a block of seeds (config key seeds_per_job), e.g. seeds0to9.tsv.
BLOCK = re.compile(r"^seeds(\d+)to(\d+)$")


def seed_stems(stem):
    """The result files (without suffix) of the seeds of a job's benchmark file stem: ``seed3`` -> [seed3], a
    block's ``seeds0to9`` -> [seed0, ..., seed9]."""
    m = BLOCK.match(stem.name)
    if not m:
        return [stem]
    return [stem.with_name(f"seed{s}") for s in range(int(m[1]), int(m[2]) + 1)]


def model_seconds(results, rel):
    """Seconds spent in the estimator by the job whose benchmark file is ``rel`` (relative to benchmarks/), summed
    over the seeds of a block job."""
    kind = rel.parts[0]
    stem = results / kind / rel.with_suffix("").relative_to(kind)
    if kind == "cv":
        return sum(
            float(json.loads(s.with_suffix(".json").read_text())["cv_seconds"])
            for s in seed_stems(stem)
        )
    if stem.name.startswith("chain"):
        # a job of one chain (chain3.tsv) or of a split's chains (chains.tsv): the chain files' own timings
        one = stem.name != "chains"
        files = [stem.with_suffix(".npz")] if one else sorted(stem.parent.glob("chain[0-9]*.npz"))
        total = 0.0
        for path in files:
            with np.load(path, allow_pickle=False) as z:
                total += float(z["fit_seconds"]) + float(z["predict_seconds"])
        return total
    rows = [json.loads(s.with_suffix(".json").read_text()) for s in seed_stems(stem)]
    return sum(float(row["fit_seconds"]) + float(row["predict_seconds"]) for row in rows)


def kind_of(rel):
    """('PM fit' | 'PM chain' | 'PM chains' | 'PM CV' | '<method> fit' | ...) for a benchmark file under
    results/{study}/benchmarks: 'chain' for a job of one chain, 'chains' for a job of a split's chains."""
    parts = rel.parts
    if parts[0] in ("cv", "fit"):
        method = parts[4]
        family = "PM" if method.startswith("PM") else method
        if parts[0] == "cv":
            what = "CV"
        elif rel.stem.startswith("chain"):
            what = "chains" if rel.stem == "chains" else "chain"
        else:
            what = "fit"
        return f"{family} {what}"
    return parts[0]


def run_wall_seconds(log):
    """Seconds between the first and the last Snakemake time stamp of ``log``."""
    stamps = [
        datetime.strptime(m.group(1), "%a %b %d %H:%M:%S %Y")
        for line in Path(log).read_text(errors="replace").splitlines()
        if (m := STAMP.match(line))
    ]
    if len(stamps) < 2:
        raise ValueError(
            f"{log}: expected Snakemake's time stamps ('[Mon Nov 30 12:17:05 2026]'), found {len(stamps)}"
        )
    return (max(stamps) - min(stamps)).total_seconds()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=Path, help="results/{study}")
    ap.add_argument("--log", type=Path, help="Snakemake's log of the run (for its wall time)")
    ap.add_argument("--cores", type=int, default=2)
    args = ap.parse_args()
    bench = args.results / "benchmarks"
    if not bench.is_dir():
        raise SystemExit(f"{bench}: no such directory (run the study first)")
    rows = defaultdict(lambda: [0, 0.0, 0.0])
    for tsv in sorted(bench.rglob("*.tsv")):
        rel = tsv.relative_to(bench)
        kind = kind_of(rel)
        acc = rows[kind]
        acc[0] += 1
        acc[1] += job_seconds(tsv)
        if rel.parts[0] in ("cv", "fit"):
            acc[2] += model_seconds(args.results, rel)
    for tsv in sorted(Path("logs/features").rglob("*.benchmark.tsv")) + sorted(
        Path("logs/mocap").rglob("*.benchmark.tsv")
    ):
        acc = rows["features and poses"]
        acc[0] += 1
        acc[1] += job_seconds(tsv)
    total_job = sum(r[1] for r in rows.values())
    print(
        "| jobs of kind | n | job wall s | model s | overhead s | overhead per job s | share of job wall |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for kind, (n, wall, model) in sorted(rows.items(), key=lambda kv: -kv[1][1]):
        over = wall - model if model else float("nan")
        print(
            f"| {kind} | {n} | {wall:.0f} | {model:.0f} | {over:.0f} | {over / n:.2f} | {wall / total_job:.1%} |"
        )
    n_all = sum(r[0] for r in rows.values())
    model_all = sum(r[2] for r in rows.values())
    print(f"| all | {n_all} | {total_job:.0f} | {model_all:.0f} | | | |")
    if args.log:
        wall = run_wall_seconds(args.log)
        idle = args.cores * wall - total_job
        print(
            f"\nrun wall time {wall:.0f} s ({wall / 60:.1f} min) on {args.cores} cores = {args.cores * wall:.0f} core-s; "
            f"jobs occupied {total_job:.0f} core-s ({total_job / (args.cores * wall):.0%}), "
            f"no job running: {idle:.0f} core-s (scheduling, dependencies, jobs without a benchmark file)"
        )


if __name__ == "__main__":
    main()
