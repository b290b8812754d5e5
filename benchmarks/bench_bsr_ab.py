"""Interleaved A/B timing of the BayesianSR Gibbs sweep: this checkout's kernels against an older revision's, in
one process, on one core; prints a Markdown table.

Separate runs of benchmarks/bench_bsr.py on a shared machine differ by 20-30% (load, and the drift of g_xy in the
chain being timed), too much to tell a 20% change in one cell from noise. Here both kernels run in the same
process, alternating batch by batch (10 sweeps per batch, 15 batches each, medians of the calling thread's CPU
time per sweep), each on its own copy of the same starting state (a state after 2 sweeps, as in bench_bsr.py) and
its own Generator with the same seed, so load and drift hit both alike.

The old revision's package is extracted with ``git archive <rev> src/bsrbench`` into a temporary folder (or, if
``rev`` is a folder such as another checkout's ``src``, its ``bsrbench`` package is copied there) and imported
under another name, so both numba kernels live side by side (their caches are keyed by file path). As in
``BayesianSR.fit``, glibc keeps freed memory (``keep_freed_memory``), for both kernels alike.
Run from the repository root:
    .venv/bin/python benchmarks/bench_bsr_ab.py main --table --sizes 60x128 200x256   # against main's kernels
    .venv/bin/python benchmarks/bench_bsr_ab.py /work/main/src --table    # another checkout's working tree
    .venv/bin/python benchmarks/bench_bsr_ab.py b54c7e1        # the commit before issue 12's blocked code update
    .venv/bin/python benchmarks/bench_bsr_ab.py b54c7e1 --sizes 30x64 200x256 --w-update ess --atom-update block
    .venv/bin/python benchmarks/bench_bsr_ab.py ef1133b --table   # default, single-site and MH in one table
    .venv/bin/python benchmarks/bench_bsr_ab.py ef1133b --parts --sizes 200x256   # each update alone
"""

import os

for _var in ("NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import importlib
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_bsr as bb

from bsrbench.models import _bsr_kernels as new

DEFAULT_SIZES = ("30x64", "30x128", "60x64", "60x128", "100x196", "200x256")
VARIANT_SIZES = ("30x64", "60x128", "200x256")


def old_kernels(rev, workdir):
    """The ``_bsr_kernels`` module of git revision ``rev`` (or of the package ``rev/bsrbench`` if ``rev`` is a
    folder), imported as ``bsrbench_<rev>.models._bsr_kernels``."""
    name = "bsrbench_" + "".join(c if c.isalnum() else "_" for c in rev)
    if Path(rev).is_dir():
        if not (Path(rev) / "bsrbench" / "models" / "_bsr_kernels.py").is_file():
            raise SystemExit(
                f"{rev}: expected a folder holding bsrbench/models/_bsr_kernels.py (a src folder)"
            )
        shutil.copytree(
            Path(rev) / "bsrbench",
            Path(workdir) / name,
            ignore=shutil.ignore_patterns("__pycache__"),
        )
        sys.path.insert(0, workdir)
        return importlib.import_module(f"{name}.models._bsr_kernels")
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", rev, "src/bsrbench"], capture_output=True
    )
    if archive.returncode != 0:
        raise SystemExit(f"git archive {rev}: {archive.stderr.decode().strip()}")
    subprocess.run(["tar", "-x", "-C", workdir], input=archive.stdout, check=True)
    (Path(workdir) / "src" / "bsrbench").rename(Path(workdir) / name)
    sys.path.insert(0, workdir)
    return importlib.import_module(f"{name}.models._bsr_kernels")


def sweeper(mod, state, data, hyper, w_update, atom_update, seed=5):
    s = mod.BSRState(*[np.array(a, copy=True) for a in state])
    d, h, rng = mod.BSRData(*data), mod.BSRHyper(*hyper), np.random.default_rng(seed)
    return lambda: mod.gibbs_sweep(s, d, h, rng, w_update, atom_update)


def interleaved(fa, fb, batches, per_batch):
    """Median CPU seconds per call of fa and fb, timed in alternating batches after 3 untimed calls each."""
    for f in (fa, fb):
        for _ in range(3):
            f()
    ta, tb = [], []
    for _ in range(batches):
        for f, out in ((fa, ta), (fb, tb)):
            c = time.thread_time()
            for _ in range(per_batch):
                f()
            out.append((time.thread_time() - c) / per_batch)
    return float(np.median(ta)), float(np.median(tb))


def updates(mod, state, data, seed=5):
    """The sweep's updates alone, each a closure on its own copy of ``state`` (module ``mod``'s kernels)."""
    s = mod.BSRState(*[np.array(a, copy=True) for a in state])
    p, r, V, Mx = s.prec, np.random.default_rng(seed), data.V, data.Mx
    return {
        "codes": lambda: mod.update_codes(s.R, s.D, s.norms, s.B, s.S, s.W, p[0], p[1], r),
        "atoms (block)": lambda: mod.update_atoms(
            V, s.R, s.D, s.norms, s.B, s.S, p[1], p[2], p[3], Mx, r
        ),
        "atoms (single-site)": lambda: mod.update_atoms_single(
            s.R, s.D, s.norms, s.B, s.S, p[1], p[2], p[3], Mx, r
        ),
        "logits (ESS)": lambda: mod.update_w_ess(s.W, s.B, data.Lw, r),
        "logits (MH)": lambda: mod.update_w_mh(s.W.copy(), s.B, data.Sigma, data.Lw, r),
    }


def parts_table(old, args):
    """Interleaved A/B of each update alone at the first of ``args.sizes``; prints a Markdown table."""
    N, K = args.sizes[0]
    state, data, _, _, _ = bb.problem(N, K, warmup=2)
    fo, fn = updates(old, state, data), updates(new, state, data)
    print(
        f"updates alone at N = {N}, K = {K}, {args.rev} against this checkout, interleaved: {args.batches} "
        f"batches x {args.per_batch} calls, medians of thread CPU time; load average at the start "
        f"{os.getloadavg()[0]:.1f}\n"
    )
    print(f"| update | {args.rev} ms | this checkout ms | speed-up |\n|---|---:|---:|---:|")
    for name in fo:
        to, tn = interleaved(fo[name], fn[name], args.batches, args.per_batch)
        print(f"| {name} | {1e3 * to:.3f} | {1e3 * tn:.3f} | {to / tn:.2f}x |", flush=True)


def size_cell(text):
    """(N, K) of an ``NxK`` cell such as ``30x64`` (argparse type): ArgumentTypeError otherwise."""
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.isdigit() and int(p) > 0 for p in parts):
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected NxK, e.g. 30x64 (N training frames, K atoms)"
        )
    return int(parts[0]), int(parts[1])


def positive_int(text):
    """A positive integer (argparse type): ArgumentTypeError otherwise."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a positive integer")
    return int(text)


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "rev",
        help="the older git revision (e.g. main, or a commit before a kernel change), or a src folder",
    )
    ap.add_argument(
        "--sizes",
        nargs="+",
        type=size_cell,
        default=[size_cell(c) for c in DEFAULT_SIZES],
        metavar="NxK",
        help=f"cells to time, N training frames x K atoms (default: {' '.join(DEFAULT_SIZES)})",
    )
    ap.add_argument(
        "--w-update",
        default="ess",
        choices=("ess", "mh"),
        help="update of the logits: elliptical slice sampling or Metropolis-Hastings "
        "(default: %(default)s)",
    )
    ap.add_argument(
        "--atom-update",
        default="block",
        choices=("block", "single"),
        help="dictionary update: all atoms jointly or one at a time (default: %(default)s)",
    )
    ap.add_argument(
        "--batches",
        type=positive_int,
        default=15,
        help="alternating batches per kernel; the medians are over them (default: %(default)s)",
    )
    ap.add_argument(
        "--per-batch",
        type=positive_int,
        default=10,
        help="Gibbs sweeps per batch (default: %(default)s)",
    )
    ap.add_argument(
        "--table",
        action="store_true",
        help="one table of the default sweep at --sizes and the single-site and MH variants at "
        f"{' '.join(VARIANT_SIZES)} (ignores --w-update and --atom-update)",
    )
    ap.add_argument(
        "--parts",
        action="store_true",
        help="time each update alone (codes, atoms, logits) at the first of --sizes instead of sweeps",
    )
    args = ap.parse_args(argv)
    new.keep_freed_memory()
    if args.parts:
        with tempfile.TemporaryDirectory() as tmp:
            parts_table(old_kernels(args.rev, tmp), args)
        return
    if args.table:
        runs = [("ess", "block", args.sizes)] + [
            (w, a, [size_cell(c) for c in VARIANT_SIZES])
            for w, a in (("ess", "single"), ("mh", "block"), ("mh", "single"))
        ]
    else:
        runs = [(args.w_update, args.atom_update, args.sizes)]
    with tempfile.TemporaryDirectory() as tmp:
        old = old_kernels(args.rev, tmp)
        print(
            f"{args.rev} against this checkout, interleaved: {args.batches} batches x {args.per_batch} "
            f"sweeps each, medians of thread CPU time; load average at the start "
            f"{os.getloadavg()[0]:.1f}\n"
        )
        print(
            f"| logits | atoms | N | K | {args.rev} ms | this checkout ms | speed-up |\n"
            "|---|---|---:|---:|---:|---:|---:|"
        )
        for w_update, atom_update, sizes in runs:
            for N, K in sizes:
                state, data, hyper, _, _ = bb.problem(N, K, warmup=2)
                fo = sweeper(old, state, data, hyper, w_update, atom_update)
                fn = sweeper(new, state, data, hyper, w_update, atom_update)
                to, tn = interleaved(fo, fn, args.batches, args.per_batch)
                print(
                    f"| {w_update} | {atom_update} | {N} | {K} | {1e3 * to:.3f} | {1e3 * tn:.3f} | "
                    f"{to / tn:.2f}x |",
                    flush=True,
                )
        print(f"\nload average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
