"""Speed of the BayesianSR Gibbs sampler and its prediction, on one core.

Times (median over repeats; wall clock and process CPU time, since the machine may be shared):
  1. one full sweep at N=200, K=256, Mx=100, My=57 for each logit update and atom update (block, single),
     with a per-update breakdown;
  2. the plain NumPy reference (tests/naive.py) at the same size, in the same run: the speed-up ratio;
  3. a table over N in {30, 60, 100, 200} x K in {64, 128, 196, 256};
  4. prediction of 400 test points with 50 posterior samples x 10 code sweeps at K=256.
Targets: (1) <= 8 ms per sweep, (2) >= 50x, (4) <= 2 s. Results: benchmarks/results/bsr.csv (git-ignored).

Data: the authors' acrobatics features (resources/paper-features/x4921.mat) when present, else random data
of the same shape. Run from the repository root:  python benchmarks/bench_bsr.py [--quick]
"""

import os

for _var in ("NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import naive  # noqa: E402

from bsrbench.io import atomic_path  # noqa: E402
from bsrbench.models import _bsr_kernels as kern  # noqa: E402
from bsrbench.models.bsr import BayesianSR  # noqa: E402

MX, MY = 100, 57


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


def problem(N, K, seed=0, warmup=5):
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
    hyper = kern.BSRHyper()
    for _ in range(warmup):
        kern.gibbs_sweep(state, data, hyper, rng, "ess")
    return state, data, hyper, rng, (Xrest - X.mean(0)) / sx


def timed(fn, repeats):
    wall, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return float(np.median(wall)), float(np.median(cpu))


def copy_state(s):
    return kern.BSRState(*[np.array(a, copy=True) for a in s])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats and a smaller table")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "bsr.csv"))
    args = ap.parse_args(argv)
    reps = 7 if args.quick else 25
    rows = []
    _, _, _, source = load_data(10)
    print(f"data: {source}; threads: NUMBA={os.environ['NUMBA_NUM_THREADS']} BLAS={os.environ['OPENBLAS_NUM_THREADS']}")

    # 1. one sweep at the paper's largest size, per logit update, and its parts
    N, K = 200, 256
    state, data, hyper, rng, _ = problem(N, K)
    print(f"\n1. sweep at N={N}, K={K}, Mx={MX}, My={MY} (median of {reps}); codes on: {state.B.mean():.2f}")
    for wu, au in (("ess", "block"), ("mh", "block"), ("ess", "single"), ("mh", "single")):
        w, c = timed(lambda: kern.gibbs_sweep(state, data, hyper, rng, wu, au), reps)
        rows.append(dict(section="sweep", N=N, K=K, w_update=wu, atom_update=au, wall_ms=1e3 * w, cpu_ms=1e3 * c))
        print(f"   sweep {wu:4s} {au:6s}: {1e3 * w:7.2f} ms wall, {1e3 * c:7.2f} ms CPU")
    p = state.prec
    parts = {
        "codes": lambda: kern.update_codes(state.R, state.D, state.norms, state.B, state.S, state.W, p[0], p[1], rng),
        "atoms": lambda: kern.update_atoms(data.V, state.R, state.D, state.norms, state.B, state.S, p[1], p[2], p[3],
                                           MX, rng),
        "atoms_single": lambda: kern.update_atoms_single(state.R, state.D, state.norms, state.B, state.S, p[1], p[2],
                                                         p[3], MX, rng),
        "precisions": lambda: kern.update_precisions(state.R, state.D, state.S, p.copy(), MX, 1e-6, 1e-6, rng),
        "w_mh": lambda: kern.update_w_mh(state.W.copy(), state.B, data.Sigma, data.Lw, rng, False),
        "w_ess": lambda: kern.update_w_ess(state.W.copy(), state.B, data.Lw, rng),
    }
    for name, fn in parts.items():
        w, c = timed(fn, reps)
        rows.append(dict(section="part", N=N, K=K, w_update=name, wall_ms=1e3 * w, cpu_ms=1e3 * c))
        print(f"   part {name:10s}: {1e3 * w:7.2f} ms wall, {1e3 * c:7.2f} ms CPU")

    # 2. the NumPy reference at the same size, for each sweep variant
    n_naive = 2 if args.quick else 3
    print("\n2. NumPy reference sweep (tests/naive.py), same state, same run")
    for r in [r for r in rows if r["section"] == "sweep"]:
        wu, au = r["w_update"], r["atom_update"]
        ns = copy_state(state)
        w_ref, c_ref = timed(lambda: naive.gibbs_sweep(ns, data, hyper, np.random.default_rng(1), wu, au), n_naive)
        rows.append(dict(section="naive", N=N, K=K, w_update=wu, atom_update=au, wall_ms=1e3 * w_ref,
                         cpu_ms=1e3 * c_ref))
        print(f"   {wu:4s} {au:6s}: {w_ref:.2f} s wall -> speed-up {1e3 * w_ref / r['wall_ms']:.0f}x wall, "
              f"{1e3 * c_ref / r['cpu_ms']:.0f}x CPU")

    # 3. table over N x K
    Ns = (30, 60, 100, 200)
    Ks = (64, 128, 196, 256)
    print(f"\n3. ms per sweep (ESS / MH, wall) over N x K (median of {max(3, reps // 3)})")
    print("   N \\ K " + "".join(f"{k:>16d}" for k in Ks))
    for n in Ns:
        line = f"   {n:6d}"
        for k in Ks:
            st, dt, hy, rg, _ = problem(n, k, warmup=2)
            cells = []
            for wu in ("ess", "mh"):
                w, c = timed(lambda: kern.gibbs_sweep(st, dt, hy, rg, wu), max(3, reps // 3))
                rows.append(dict(section="grid", N=n, K=k, w_update=wu, wall_ms=1e3 * w, cpu_ms=1e3 * c))
                cells.append(1e3 * w)
            line += f"{cells[0]:8.2f}/{cells[1]:<7.2f}"
        print(line)

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
        kern.predict_kernel(Xt, nbr, Dx, Dy, Ws, gs, gxy, n_sweeps, seeds, np.empty((T, L, MY)), np.empty((T, L)))

    predict()
    w, c = timed(predict, 3)
    rows.append(dict(section="predict", N=N, K=K, w_update="", wall_ms=1e3 * w, cpu_ms=1e3 * c))
    print(f"\n4. prediction of {T} points, {L} samples x {n_sweeps} sweeps, K={K}: {w:.2f} s wall, {c:.2f} s CPU")

    out = Path(args.out)
    with atomic_path(out) as tmp:
        pd.DataFrame(rows).to_csv(tmp, index=False)
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
