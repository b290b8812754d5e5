"""Where a trivial job's time goes, and an A/B of it: a 1-NN fit job of the study, this checkout against an older
revision.

A 1-NN job computes for milliseconds, so its wall time is the floor that every job of the study pays besides its
model. Two measurements, each interleaving the two revisions round by round (medians of ``--repeats`` rounds):

1. **The job command**, as the rule ``fit`` runs it: ``python -m bsrbench.jobserver job bsrbench.jobs:fit JOB
   --settings SETTINGS`` (interpreter start, the client, the warm job server's fork, then the job body: load the
   features, split, fit, predict the test and the training frames, score, write the row and the arrays). Each
   revision gets its own warm server (own socket, ``bsrbench.jobs`` preloaded, as the first job of a run starts
   it). Beside it: the same command for a job whose body does nothing (:func:`bsrbench.jobserver.ping`), and a
   bare ``python -c pass``. Snakemake's own per-job work (its scheduling, the benchmark file, the shell) is in
   neither; ``benchmarks/profile_study.py`` gives a finished study's totals.
2. **The job body's phases**, in this process with this checkout's code (``time.perf_counter``).

The older revision's package comes from ``git archive <rev> src/bsrbench``. Both rows must be equal but for their
timings (checked and printed).

    .venv/bin/python benchmarks/bench_job_floor.py 8e7ce46 --activity golf --n-train 200 --repeats 21

``--method PM --method RVM ...`` adds the fit job of each named method (its ``params`` in ``config/config.yaml``
read over by ``--study``'s file, e.g. ``--study paper``; no split-conformal refit) to the A/B, in the same rounds.
"""

import argparse
import io as _io
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

ROOT = Path(__file__).resolve().parents[1]
ESTIMATOR = "bsrbench.models.reference:NearestNeighbourRegressor"
TIMING_FIELDS = {"fit_seconds", "predict_seconds"}


def old_package(rev, workdir):
    """``src`` folder holding revision ``rev``'s ``bsrbench`` package."""
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", rev, "src/bsrbench"], capture_output=True
    )
    if archive.returncode:
        raise SystemExit(f"git archive {rev}: {archive.stderr.decode().strip()}")
    with tarfile.open(fileobj=_io.BytesIO(archive.stdout)) as tar:
        tar.extractall(workdir, filter="data")
    return Path(workdir) / "src"


class Revision:
    """One revision's warm job server and its job commands."""

    def __init__(self, name, src, tmp, features, n_train, activity, methods=()):
        self.name, self.dir = name, Path(tmp) / name.replace(" ", "_")
        self.dir.mkdir()
        self.env = dict(
            os.environ, PYTHONPATH=str(src), BSRBENCH_JOBSERVER_SOCKET=str(self.dir / "s.sock")
        )
        wildcards = dict(
            protocol="random",
            source="hsc",
            activity=activity,
            method="NN1",
            n_train=n_train,
            seed=0,
        )
        out = {"row": str(self.dir / "row.json"), "predictions": str(self.dir / "pred.npz")}
        job = json.dumps(
            {"input": {"features": str(features)}, "output": out, "wildcards": wildcards}
        )
        settings = dict(
            estimator=ESTIMATOR,
            fixed={"n_neighbors": 1},
            cv_mode="none",
            paper_activity="",
            pose_transform="heading",
            conformal=None,
            min_test=100,
            gap=30,
        )
        base = [sys.executable, "-m", "bsrbench.jobserver", "job"]
        log = ["--log", str(self.dir / "job.log")]
        ping = json.dumps(
            {"input": {}, "output": {"path": str(self.dir / "ping")}, "wildcards": {}}
        )
        self.commands = {
            "1-NN fit job": base
            + ["bsrbench.jobs:fit", job, "--settings", json.dumps(settings)]
            + log,
            "no-op job": base + ["bsrbench.jobserver:ping", ping] + log,
        }
        for method, (estimator, params) in methods.items():
            out_m = {k: v.replace(".", f"_{method}.", 1) for k, v in out.items()}
            job_m = json.dumps(
                {
                    "input": {"features": str(features)},
                    "output": out_m,
                    "wildcards": {**wildcards, "method": method},
                }
            )
            settings_m = dict(settings, estimator=estimator, fixed=params)
            self.commands[f"{method} fit job"] = (
                base + ["bsrbench.jobs:fit", job_m, "--settings", json.dumps(settings_m)] + log
            )
        self.server = subprocess.Popen(
            [sys.executable, "-m", "bsrbench.jobserver", str(self.dir / "s.sock"), "bsrbench.jobs"],
            env=self.env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )

    def wait_listening(self, timeout=600):
        deadline = time.monotonic() + timeout
        while not (self.dir / "s.sock").exists():
            if time.monotonic() > deadline or self.server.poll() is not None:
                raise SystemExit(f"{self.name}: job server did not start")
            time.sleep(0.1)

    def time(self, what):
        t0 = time.perf_counter()
        done = subprocess.run(self.commands[what], env=self.env, capture_output=True)
        if done.returncode:
            raise SystemExit(f"{self.name}: {what} failed: {done.stderr.decode()[-2000:]}")
        return time.perf_counter() - t0

    def row(self):
        return json.loads((self.dir / "row.json").read_text())

    def stop(self):
        subprocess.run(
            [
                sys.executable,
                "-c",
                f"from bsrbench import jobserver; jobserver.shutdown({str(self.dir / 's.sock')!r})",
            ],
            env=self.env,
        )
        self.server.wait(timeout=60)


def phases(features, activity, n_train, repeats):
    """Medians (s) of the job body's phases with this checkout's code, in this process."""
    sys.path.insert(0, str(ROOT / "src"))
    from bsrbench import io, metrics, runs
    from bsrbench.splits import JobSpec

    spec = JobSpec(
        source="hsc",
        activity=activity,
        method="NN1",
        n_train=n_train,
        seed=0,
        protocol="random",
        pose_transform="heading",
        min_test=100,
        gap=30,
    )
    names = (
        "load features",
        "split + fit",
        "predict test and train",
        "angle errors",
        "MPJPE + PA-MPJPE",
        "row + arrays (rest of scoring)",
        "write",
    )
    out = {name: [] for name in names}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeats + 1):
            t = [time.perf_counter()]
            feats = io.load_features(features)
            t.append(time.perf_counter())
            split = runs.prepare_split(spec, feats)
            est, fit_s = split.fit(ESTIMATOR, {"n_neighbors": 1}, spec.method_seed)
            t.append(time.perf_counter())
            Z = est.predict(split.X[split.test])
            train_error = runs._train_error(split, est.predict(split.X[split.train]))
            t.append(time.perf_counter())
            Y_true, Y_pred = split.Y[split.test], split.transform.inverse(Z)
            metrics.mean_angle_error(Y_true, Y_pred)
            t.append(time.perf_counter())
            runs.extra_scores(Y_true, Y_pred, source="NN1", skeleton=split.skeleton)
            t.append(time.perf_counter())
            row, arrays = runs._score(
                spec,
                split,
                estimator=ESTIMATOR,
                params={"n_neighbors": 1},
                cv_mode="none",
                cv_seconds=None,
                Z_mean=Z,
                Z_std=None,
                fit_seconds=fit_s,
                predict_seconds=0.0,
                train_error=train_error,
            )
            t.append(time.perf_counter())
            io.write_arrays(Path(tmp) / "p.npz", arrays)
            io.write_json(Path(tmp) / "r.json", row)
            t.append(time.perf_counter())
            if i:  # the first round warms the caches
                for name, a, b in zip(names, t, t[1:]):
                    out[name].append(b - a)
    med = {name: statistics.median(v) for name, v in out.items()}
    # _score repeats the angle errors and the joint-position scores: what is left is the row and arrays
    med[names[5]] -= med[names[3]] + med[names[4]]
    return med


def method_settings(names, study):
    """{name: (estimator, params)} of the methods ``names`` in config/config.yaml read over by config/STUDY.yaml."""
    import yaml

    merged = {}
    for path in [ROOT / "config" / "config.yaml", ROOT / "config" / f"{study}.yaml"][
        : 2 if study else 1
    ]:
        for name, entry in (yaml.safe_load(path.read_text()).get("methods") or {}).items():
            merged[name] = {**merged.get(name, {}), **(entry or {})}
    return {n: (merged[n]["estimator"], merged[n].get("params") or {}) for n in names}


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "rev", help="the older git revision to compare with (e.g. the commit before a change)"
    )
    ap.add_argument(
        "--features", default=None, help="features file (default results/features/hsc/ACTIVITY.npz)"
    )
    ap.add_argument("--activity", default="golf")
    ap.add_argument("--n-train", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=21)
    ap.add_argument("--method", action="append", default=[], help="also time this method's fit job")
    ap.add_argument("--study", default=None, help="read config/STUDY.yaml over config/config.yaml")
    args = ap.parse_args(argv)
    methods = method_settings(args.method, args.study)
    features = Path(
        args.features or ROOT / "results" / "features" / "hsc" / f"{args.activity}.npz"
    ).resolve()
    if not features.is_file():
        ap.error(
            f"{features}: no such features file (build it: snakemake --cores 2 --until features_mat)"
        )
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        revs = [
            Revision(
                args.rev,
                old_package(args.rev, Path(tmp) / "old"),
                tmp,
                features,
                args.n_train,
                args.activity,
                methods,
            ),
            Revision(
                "this checkout", ROOT / "src", tmp, features, args.n_train, args.activity, methods
            ),
        ]
        times = {(r.name, what): [] for r in revs for what in ("python -c pass", *r.commands)}
        try:
            for r in revs:
                r.wait_listening()
                for what in r.commands:  # warm-up round: the server's first fork, the OS caches
                    r.time(what)
            for _ in range(args.repeats):
                for r in revs:
                    t0 = time.perf_counter()
                    subprocess.run([sys.executable, "-c", "pass"], check=True)
                    times[(r.name, "python -c pass")].append(time.perf_counter() - t0)
                    for what in r.commands:
                        times[(r.name, what)].append(r.time(what))
            rows = [r.row() for r in revs]
        finally:
            for r in revs:
                r.stop()
    differ = sorted(k for k in rows[0] if k not in TIMING_FIELDS and rows[0][k] != rows[1].get(k))
    print(
        f"1-NN fit job ({features.name}, N = {args.n_train}, {rows[0]['n_test']} test frames): wall time of the "
        f"rule's command, {args.rev} against this checkout, interleaved; medians of {args.repeats} rounds; load "
        f"average {load0:.1f} at the start, {os.getloadavg()[0]:.1f} at the end\n"
    )
    print(f"| command | {args.rev} ms | this checkout ms | ratio |\n|---|---:|---:|---:|")
    for what in ("1-NN fit job", *(f"{m} fit job" for m in methods), "no-op job", "python -c pass"):
        old, new = (statistics.median(times[(r.name, what)]) * 1e3 for r in revs)
        print(f"| {what} | {old:.1f} | {new:.1f} | {old / new:.2f}x |")
    pa = abs(rows[0]["pa_mpjpe_mm"] - rows[1]["pa_mpjpe_mm"])
    print(
        f"\nRows equal but for timings and {differ or 'nothing'}; PA-MPJPE differs by {pa:.1e} mm.\n"
    )
    print(
        f"Job body, this checkout, in-process (medians of {args.repeats}):\n\n| phase | ms |\n|---|---:|"
    )
    for name, sec in phases(features, args.activity, args.n_train, args.repeats).items():
        print(f"| {name} | {sec * 1e3:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
