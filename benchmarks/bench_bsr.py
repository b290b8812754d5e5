"""Speed of the BayesianSR Gibbs sampler and its prediction, on one core; prints Markdown tables.

Everything is timed in one run (median over repeats of the calling thread's CPU time, which on a shared machine
excludes the time other processes hold the core; BLAS runs single-threaded in that thread; wall-clock medians go
to the CSV), the plain NumPy reference (tests/naive.py) included, so that ratios compare like with like
(timings on a shared machine vary 20-30% from run to run):
  1. the sweep over N in {30, 60, 100, 200} x K in {64, 128, 196, 256} (Mx = 100, My = 57), for the default
     sweep (elliptical slice logits, block atoms) and the single-site atom variant, each with the NumPy
     reference's time and the speed-up;
  2. every exact sweep variant at N = 200, K = 256 (logits by ESS or MH; block or single-site atoms; one or
     separate noise precisions) against the reference;
  3. GFLOP/s of each part of the sweep (codes, atoms, precisions, logits) at N = 200, K = 256, from its
     nominal flop count, beside the DGEMM rate of a NumPy matrix product of matching size timed in the same run;
  4. prediction of 400 test points with 50 posterior samples x 10 code sweeps at K = 256.
Targets (issue 12): default sweep <= 4 ms at N = 200, K = 256 and >= 100x the reference; prediction <= 1 s.
Raw rows: benchmarks/results/bsr.csv (git-ignored).

Data: the authors' acrobatics features (resources/paper-features/x4921.mat) when present, else random data
of the same shape. Run from the repository root:  python benchmarks/bench_bsr.py [--quick]
To time another checkout's kernels with this script: PYTHONPATH=<checkout>/src python benchmarks/bench_bsr.py
--naive <checkout>/tests (the script only uses functions whose signatures both have).
"""

import os

for _var in ("NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import importlib
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]

from bsrbench.io import atomic_path
from bsrbench.models import _bsr_kernels as kern
from bsrbench.models.bsr import BayesianSR

MX, MY = 100, 57
M = MX + MY
NS = (30, 60, 100, 200)
KS = (64, 128, 196, 256)


def load_data(n):
    path = ROOT / "resources" / "paper-features" / "x4921.mat"
    if path.exists():
        from scipy.io import loadmat

        d = loadmat(path)
        X, Y = d["X"][:600].astype(float), d["Y"][:600, 3:].astype(float)
        source = "x4921.mat"
    else:
        rng = np.random.default_rng(0)
        X, Y = rng.gamma(2.0, 1.0, (600, MX)), rng.uniform(-180, 180, (600, MY))
        source = "random"
    return X[:n], Y[:n], X[n:], source


def problem(N, K, seed=0, warmup=5, noise="shared"):
    """A sampler state after a few sweeps on standardized data (realistic code density)."""
    X, Y, Xrest, _ = load_data(N)
    sx, sy = X.std(0), Y.std(0)
    sx[sx == 0], sy[sy == 0] = 1, 1
    Xs, Ys = (X - X.mean(0)) / sx, (Y - Y.mean(0)) / sy
    V = np.ascontiguousarray(np.hstack([Xs, Ys]))
    Sigma, eta = kern.logit_prior_cov(Ys)
    Lw, jit = kern.cholesky_with_jitter(Sigma, eta)
    data = kern.BSRData(V=V, Mx=MX, Sigma=np.ascontiguousarray(Sigma + jit * np.eye(N)), Lw=Lw)
    rng = np.random.default_rng(seed)
    state = BayesianSR._initial_state(V, MX, K, rng)
    hyper = kern.BSRHyper(noise=noise)
    for _ in range(warmup):
        kern.gibbs_sweep(state, data, hyper, rng, "ess")
    return state, data, hyper, rng, (Xrest - X.mean(0)) / sx


WALL = {}  # wall-clock medians of the last timing per label, for the CSV


def timed(fn, repeats, label=None):
    """Median CPU time (s) of the calling thread over ``repeats`` calls, after one untimed call (compilation,
    caches); the median wall time is kept in WALL[label]."""
    fn()
    cpu, wall = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.thread_time()
        fn()
        cpu.append(time.thread_time() - c)
        wall.append(time.perf_counter() - t)
    if label is not None:
        WALL[label] = float(np.median(wall))
    return float(np.median(cpu))


def copy_state(s):
    return kern.BSRState(*[np.array(a, copy=True) for a in s])


def sweep_times(N, K, w_update, atom_update, reps, naive_reps, naive, noise="shared"):
    """(kernel s, reference s) per sweep; each timed on its own copy of one state, the reference after a fresh
    copy per repeat (its sweep is exact too, so the state stays realistic)."""
    state, data, hyper, rng, _ = problem(N, K, warmup=2, noise=noise)
    ref_state = copy_state(state)
    t_k = timed(
        lambda: kern.gibbs_sweep(state, data, hyper, rng, w_update, atom_update), reps, "kernel"
    )
    ref_rng = np.random.default_rng(1)
    t_n = timed(
        lambda: naive.gibbs_sweep(ref_state, data, hyper, ref_rng, w_update, atom_update),
        naive_reps,
        "naive",
    )
    return t_k, t_n


def markdown(header, rows):
    out = [
        "| " + " | ".join(header) + " |",
        "|" + "|".join("---:" if i else "---" for i in range(len(header))) + "|",
    ]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def dgemm_rate(m, k, n, reps):
    """GFLOP/s of a NumPy product (m x k) @ (k x n), median of ``reps``."""
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((m, k)), rng.standard_normal((k, n))
    return 2.0 * m * k * n / timed(lambda: a @ b, reps) / 1e9


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    ap.add_argument(
        "--naive", default=str(ROOT / "tests"), help="folder of the NumPy reference naive.py"
    )
    ap.add_argument("--label", default="", help="a name for this run in the printed headings")
    ap.add_argument(
        "--parts-only",
        action="store_true",
        help="only section 3 (GFLOP/s per part) and the DGEMM rates",
    )
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "bsr.csv"))
    args = ap.parse_args(argv)
    sys.path.insert(0, args.naive)
    naive = importlib.import_module("naive")
    reps = 9 if args.quick else 25
    naive_reps = 1 if args.quick else 3
    rows = []
    # as BayesianSR.fit does (older kernels do not have it: timed as their fit ran them)
    kept = kern.keep_freed_memory() if hasattr(kern, "keep_freed_memory") else "n/a"
    _, _, _, source = load_data(10)
    print(
        f"# bench_bsr {args.label}\n\ndata: {source}; kernels: {kern.__file__}; threads: "
        f"NUMBA={os.environ['NUMBA_NUM_THREADS']} BLAS={os.environ['OPENBLAS_NUM_THREADS']}; "
        f"times: the thread's CPU time, kernel sweeps median of {reps}, reference median of {naive_reps}; "
        f"load average at the start: {os.getloadavg()[0]:.2f}; keep_freed_memory: {kept}"
    )

    # 1. the sweep grid, default and single-site
    for atom_update, title in (
        ()
        if args.parts_only
        else (
            ("block", "default sweep (ESS logits, block atoms)"),
            ("single", "single-site atoms (ESS logits)"),
        )
    ):
        table = []
        for n in NS:
            cells = [f"{n}"]
            for k in KS:
                t_k, t_n = sweep_times(n, k, "ess", atom_update, reps, naive_reps, naive)
                rows.append(
                    dict(
                        section="grid",
                        N=n,
                        K=k,
                        w_update="ess",
                        atom_update=atom_update,
                        ms=1e3 * t_k,
                        naive_ms=1e3 * t_n,
                        wall_ms=1e3 * WALL["kernel"],
                        naive_wall_ms=1e3 * WALL["naive"],
                    )
                )
                cells.append(f"{1e3 * t_k:.2f} ms ({t_n / t_k:.0f}x)")
            table.append(cells)
        print(
            f"\n## 1. ms per sweep, {title}: N (rows) x K (columns), speed-up over the NumPy reference\n"
        )
        print(markdown(["N \\ K"] + [str(k) for k in KS], table))

    # 2. every exact variant at paper scale
    N, K = 200, 256
    table = []
    for wu, au, noise in (
        ()
        if args.parts_only
        else (
            ("ess", "block", "shared"),
            ("mh", "block", "shared"),
            ("ess", "single", "shared"),
            ("mh", "single", "shared"),
            ("ess", "block", "separate"),
            ("ess", "single", "separate"),
        )
    ):
        t_k, t_n = sweep_times(N, K, wu, au, reps, naive_reps, naive, noise)
        rows.append(
            dict(
                section="variant",
                N=N,
                K=K,
                w_update=wu,
                atom_update=au,
                noise=noise,
                ms=1e3 * t_k,
                naive_ms=1e3 * t_n,
                wall_ms=1e3 * WALL["kernel"],
                naive_wall_ms=1e3 * WALL["naive"],
            )
        )
        table.append([wu, au, noise, f"{1e3 * t_k:.2f}", f"{1e3 * t_n:.0f}", f"{t_n / t_k:.0f}x"])
    if table:
        print(f"\n## 2. exact sweep variants at N = {N}, K = {K}\n")
        print(markdown(["logits", "atoms", "noise", "ms", "reference ms", "speed-up"], table))

    # 3. GFLOP/s per part at paper scale
    state, data, hyper, rng, _ = problem(N, K)
    p = state.prec
    nnz = int(state.B.sum())
    # nominal flop counts (the algorithms' own, the same for every implementation)
    parts = {
        "codes": (
            lambda: kern.update_codes(
                state.R, state.D, state.norms, state.B, state.S, state.W, p[0], p[1], rng
            ),
            4.0 * N * K * M,
            "4NKM: d_k . r_i and the residual update for every (i, k)",
            (N, M, K),
        ),
        "atoms (block)": (
            lambda: kern.update_atoms(
                data.V, state.R, state.D, state.norms, state.B, state.S, p[1], p[2], p[3], MX, rng
            ),
            *(
                (
                    1.0 * N * N * K + 4.0 * N * K * M + 2.0 * N**3 / 3 + 2.0 * N * N * M,
                    "N x N form: N^2 K (syrk A A^T) + 4NKM (A u, A^T w) + 2 N^3/3 (two "
                    "Cholesky) + 2 N^2 M (solves; the residual from them)",
                    (N, K, M),
                )
                if kern._small_form_cheaper(N, K, M)
                else (
                    1.0 * N * K * K + 4.0 * N * K * M + 2.0 * K**3 / 3 + 2.0 * K * K * M,
                    "NK^2 (syrk A^T A) + 4NKM (A^T V, residual) + 2 K^3/3 (two Cholesky) + "
                    "2K^2 M (solves)",
                    (K, N, K),
                )
            ),
        ),
        "atoms (single-site)": (
            lambda: kern.update_atoms_single(
                state.R, state.D, state.norms, state.B, state.S, p[1], p[2], p[3], MX, rng
            ),
            4.0 * nnz * M,
            f"4 nnz M (nnz = {nnz} active codes)",
            (N, M, K),
        ),
        "precisions": (
            lambda: kern.update_precisions(
                state.R, state.D, state.S, p.copy(), MX, 1e-6, 1e-6, rng
            ),
            2.0 * (N * K + N * M + K * M),
            "2(NK + NM + KM): sums of squares",
            (N, M, K),
        ),
        "logits (ESS)": (
            lambda: kern.update_w_ess(state.W.copy(), state.B, data.Lw, rng),
            1.0 * K * N * N,
            "KN^2: the ellipses L_w eps (trmm)",
            (K, N, N),
        ),
        "logits (MH)": (
            lambda: kern.update_w_mh(state.W.copy(), state.B, data.Sigma, data.Lw, rng),
            5.0 * K * N * N,
            "5KN^2: Sigma Lambda twice, L_w eps (trmm)",
            (K, N, N),
        ),
    }
    table = []
    for name, (fn, flops, formula, shape) in parts.items():
        t = timed(fn, reps, "part")
        peak = dgemm_rate(*shape, reps)
        rows.append(
            dict(
                section="part",
                N=N,
                K=K,
                w_update=name,
                ms=1e3 * t,
                wall_ms=1e3 * WALL["part"],
                gflops=flops / t / 1e9,
                dgemm_gflops=peak,
            )
        )
        table.append(
            [
                name,
                f"{1e3 * t:.3f}",
                f"{flops / 1e6:.1f}",
                f"{flops / t / 1e9:.1f}",
                f"{peak:.1f} ({shape[0]}x{shape[1]} @ {shape[1]}x{shape[2]})",
                f"{flops / t / 1e9 / peak:.0%}",
                formula,
            ]
        )
    big = dgemm_rate(1000, 1000, 1000, 5)
    print(
        f"\n## 3. GFLOP/s per part at N = {N}, K = {K}, M = {M} (codes on: {state.B.mean():.2f}); DGEMM "
        f"1000^3 in this run: {big:.1f} GFLOP/s\n"
    )
    print(
        markdown(
            [
                "part",
                "ms",
                "MFLOP",
                "GFLOP/s",
                "DGEMM GFLOP/s (matching size)",
                "of DGEMM",
                "flop count",
            ],
            table,
        )
    )

    if args.parts_only:
        return
    # 4. prediction: 400 test points, 50 posterior samples x 10 sweeps, K = 256
    L, T, n_sweeps = 50, 400, 10
    Dx, Dy, Ws = np.empty((L, K, MX)), np.empty((L, K, MY)), np.empty((L, N, K))
    gs, gxy = np.empty(L), np.empty(L)
    for l in range(L):
        kern.gibbs_sweep(state, data, hyper, rng, "ess")
        Dx[l], Dy[l], Ws[l] = state.D[:, :MX], state.D[:, MX:], state.W
        gs[l], gxy[l] = state.prec[0], state.prec[1]
    _, _, _, _, Xrest = problem(N, 8, warmup=0)
    Xt = np.ascontiguousarray(np.resize(Xrest, (T, MX)))
    Xtr = np.ascontiguousarray(data.V[:, :MX])

    def predict():
        nbr = kern.nearest_neighbours(Xt, Xtr, 5)
        seeds = kern.point_seeds(Xt.view(np.uint64), np.uint64(3))
        kern.predict_kernel(
            Xt, nbr, Dx, Dy, Ws, gs, gxy, n_sweeps, seeds, np.empty((T, L, MY)), np.empty((T, L))
        )

    t = timed(predict, 3 if args.quick else 7, "predict")
    rows.append(dict(section="predict", N=N, K=K, ms=1e3 * t, wall_ms=1e3 * WALL["predict"]))
    print(
        f"\n## 4. prediction of {T} points, {L} samples x {n_sweeps} code sweeps, K = {K}, N = {N}: "
        f"{t:.2f} s CPU, {WALL['predict']:.2f} s wall (median of {3 if args.quick else 7})"
    )

    out = Path(args.out)
    with atomic_path(out) as tmp:
        pd.DataFrame(rows).to_csv(tmp, index=False)
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
