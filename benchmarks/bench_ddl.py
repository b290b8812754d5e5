"""DDL fit + prediction time: the numba FISTA kernel against the whole-array NumPy FISTA, interleaved in one
process; prints a Markdown table.

At the paper protocol's sizes (N in {30, 60, 100, 200} training pairs, the study's grid: 100 atoms, alpha in
{0.01, 0.03, 0.1}) one job fits DDL on N pairs and codes the test points (here the remaining 600 - N frames of
the authors' acrobatics features, resources/paper-features/x4921.mat, when present, else random data of that
shape). The NumPy variant is the whole-array reference (tests/naive.py ``fista_codes`` and
``coupled_dictionary_learning``, the code before the numba kernels) put in place of ``bsrbench.models.ddl``'s; both variants run alternately (``--repeats`` rounds, medians of the thread's
CPU time, BLAS on one thread). Compared (largest absolute differences): the two fits' dictionaries, their test
codes, and the test codes of both FISTA loops on the same (numba-fitted) dictionary. The test-time Lasso on an
over-complete D_x (100 atoms, 100 features) is not unique and FISTA's 1000 iterations do not converge, so a
rounding-level change of the dictionary can move the test codes far more than itself.
Run from the repository root:  .venv/bin/python benchmarks/bench_ddl.py [--repeats 5]
"""

import os

for _var in ("NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))

import bench_bsr as bb
import naive

import bsrbench.models.ddl as ddl

FAST = ddl._fista_codes, ddl._coupled_dictionary_learning
NUMPY = naive.fista_codes, naive.coupled_dictionary_learning


def job(X, Y, Xt, alpha, routines):
    """Fit DDL on (X, Y) and code Xt with ``routines`` as its FISTA and dictionary learning; returns (CPU s,
    test codes)."""
    ddl._fista_codes, ddl._coupled_dictionary_learning = routines
    try:
        c = time.thread_time()
        m = ddl.DDL(n_components=100, alpha=alpha, random_state=0).fit(X, Y)
        codes = m.sparse_code(Xt)
        return time.thread_time() - c, codes, m
    finally:
        ddl._fista_codes, ddl._coupled_dictionary_learning = FAST


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--repeats", type=int, default=5, help="alternating rounds (default: %(default)s)"
    )
    ap.add_argument("--sizes", type=int, nargs="+", default=[30, 60, 100, 200])
    ap.add_argument("--alphas", type=float, nargs="+", default=[0.01, 0.03, 0.1])
    args = ap.parse_args(argv)
    X0, Y0, _, source = bb.load_data(600)
    print(
        f"DDL fit + coding of 600 - N test points, 100 atoms; data {source}; {args.repeats} alternating "
        f"rounds, medians of thread CPU time; load average at the start {os.getloadavg()[0]:.1f}\n"
    )
    print(
        "| N | alpha | NumPy s | numba s | speed-up | dictionary diff. | test code diff. | "
        "test code diff., same dictionary |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    job(X0[:30], Y0[:30], X0[30:40], 0.1, FAST)  # compile
    tot_old = tot_new = 0.0
    for n in args.sizes:
        X, Y, Xt = X0[:n], Y0[:n], X0[n:]
        for alpha in args.alphas:
            t_old, t_new = [], []
            for _ in range(args.repeats):
                t, c_old, m_old = job(X, Y, Xt, alpha, NUMPY)
                t_old.append(t)
                t, c_new, m_new = job(X, Y, Xt, alpha, FAST)
                t_new.append(t)
            mo, mn = float(np.median(t_old)), float(np.median(t_new))
            tot_old, tot_new = tot_old + mo, tot_new + mn
            d_dict = float(np.max(np.abs(m_old.components_ - m_new.components_)))
            d_fit = float(np.max(np.abs(c_old - c_new)))
            # the NumPy FISTA on the numba fit's dictionary: the coding step alone
            same = naive.fista_codes(m_new._stack_x(Xt), m_new.dictionary_x_, alpha, n_iter=1000)
            d_code = float(np.max(np.abs(same - c_new)))
            print(
                f"| {n} | {alpha:g} | {mo:.3f} | {mn:.3f} | {mo / mn:.1f}x | {d_dict:.0e} | {d_fit:.0e} | "
                f"{d_code:.0e} |",
                flush=True,
            )
    print(f"| all | | {tot_old:.2f} | {tot_new:.2f} | {tot_old / tot_new:.1f}x | | | |")


if __name__ == "__main__":
    main()
