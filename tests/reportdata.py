"""Small result tables and the paper's rows shared by the reporting tests."""

import io
import re

import pandas as pd

from bsrbench.reporting.convergence import with_convergence_columns
from bsrbench.reporting.tables import (
    aggregate_rows,
    paper_key,
)

PAPER_CSV = """table,activity,n_train,method,mean_deg,std_deg
I,Golf,30,RVM,14.514,2.88
I,Golf,30,PM,8.241,1.13
I,Acrobatics,30,RVM,15.963,2.73
I,Acrobatics,30,PM,12.595,1.24
"""


LABELS = {"RVM": "RVM", "PM": "PM", "NN1": "1-NN"}


def paper_frame():
    df = pd.read_csv(io.StringIO(PAPER_CSV))
    df["key"] = df["activity"].map(paper_key)
    return df


def estimator_of(method):
    """The configured estimator of ``method`` (config/config.yaml, then the ablation's variants), as a result row
    records it; a toy module for a name no configuration knows."""
    from bsrbench.methods import configured

    for study in (None, "ablation"):
        registry = configured(study)
        if method in registry:
            return registry[method].estimator
    return "toy_module:Toy"


def result_rows(errors):
    """errors: {(activity, method): [error per seed]} -> result rows (hsc, random, N=30)."""
    rows = []
    for (act, m), errs in errors.items():
        for seed, e in enumerate(errs):
            rows.append(
                {
                    "protocol": "random",
                    "source": "hsc",
                    "activity": act,
                    "paper_activity": act.capitalize(),
                    "method": m,
                    "estimator": estimator_of(m),
                    "n_train": 30,
                    "seed": seed,
                    "error": e,
                    "params": {"a": 1},
                    "per_angle_rms": [e, e],
                    "cv": "none",
                    "pose_transform": "heading",
                }
            )
    return rows


# ------------------------------------------------------------------------------ paired comparisons in the report
def paired_rows(errors, n_test=570):
    """errors: {(activity, method): [error per seed]} -> aggregate with n_test."""
    rows = result_rows(errors)
    for r in rows:
        r["n_test"] = n_test
    return aggregate_rows(rows)


LATEX_SIZES = ["tiny", "scriptsize", "footnotesize", "small", "normalsize", "large"]


def assert_std_smaller_than_the_table(text):
    """Before: the std was set {\\small ...} inside \\footnotesize tables, so it printed larger than the mean."""
    table = re.search(r"\\(" + "|".join(LATEX_SIZES) + r")\b", text).group(1)
    stds = re.findall(r"\$\\pm\$ \{\\([a-z]+) ", text)
    assert stds and all(LATEX_SIZES.index(s) < LATEX_SIZES.index(table) for s in stds), (
        table,
        set(stds),
    )


# ------------------------------------------------------------------------------------------- reporting
def chained_aggregate():
    """Aggregate of one cell (contiguous, hsc, golf) over N = 30, 100 and two seeds: PM (not converged), PMK16
    (converged, 4 chains), and the one-chain NN1 and SR."""
    rows = []
    for m, err, rhat in (
        ("PM", 9.0, 1.3),
        ("PMK16", 6.0, 1.01),
        ("NN1", 7.0, None),
        ("SR", 5.5, None),
    ):
        for n in (30, 100):
            for seed in (100, 101):
                r = {
                    "protocol": "contiguous",
                    "source": "hsc",
                    "activity": "golf",
                    "paper_activity": "Golf",
                    "method": m,
                    "n_train": n,
                    "seed": seed,
                    "error": err + 0.1 * seed - 10 + (n == 100),
                }
                if rhat is not None:
                    r.update(
                        n_chains=4,
                        r_hat_log_likelihood=rhat,
                        r_hat_g_xy=rhat + 0.05 * (seed - 100),
                        ess_bulk_log_likelihood=100.0 + seed,
                    )
                rows.append(r)
    return with_convergence_columns(pd.DataFrame(rows))


def paper_pm_golf():
    """The paper's PM on Golf at N = 30, 100."""
    return pd.DataFrame(
        {
            "table": "I",
            "activity": "Golf",
            "n_train": [30, 100],
            "method": "PM",
            "mean_deg": [8.24, 3.93],
            "std_deg": [1.0, 1.0],
            "key": "golf",
        }
    )
