"""PM with a fair budget beside the headline PM on the same splits of the paper protocol
(``config/paper-pmfair.yaml``, ``reports/published/paper-pmfair.csv`` beside ``reports/published/paper.csv``).

The fair-budget table is layered over the paper protocol's configuration, so its rows pair seed by seed with the
headline table's PM, 1-NN and the paper's four baselines. Per cell (activity, N): the mean errors of both PMs, the
paper's PM, 1-NN and the best of our four baselines; the split R-hat of the fair PM's test error over its chains;
its CV choice; and whether the fair PM beats the headline PM on these frames (paired t-test over the seeds, Holm
over the cells). :func:`summary` adds, per PM, the cells better, tied or worse than 1-NN and each baseline
(:func:`.reconcile.pm_summary`).
"""

import json

import numpy as np
import pandas as pd

from ..errors import InputError
from . import reconcile

#: The paper protocol's variant (random splits, the files' first 600 rows, tuned methods, wrapped error).
VARIANT = reconcile.BASE


def published_inputs(table, beside, paper):
    """The rows of the fair-budget ``table`` and of the headline table ``beside`` (restricted to the fair table's
    cells), the two studies' configurations merged (methods of both), their data sets and the paper's tables."""
    df, config, datasets, book = reconcile.published_inputs(table, paper)
    base, base_config, base_datasets, _ = reconcile.published_inputs(beside, paper)
    clash = sorted(set(df["method"]) & set(base["method"]))
    if clash:
        raise InputError(
            f"{table} and {beside} both hold method(s) {clash}; expected the fair-budget table to add its own"
        )
    keys = ["protocol", "source", "activity", "n_train"]
    base = base.merge(df[keys].drop_duplicates(), on=keys)
    methods = {**(base_config.get("methods") or {}), **(config.get("methods") or {})}
    sets = {
        s: {**base_datasets.get(s, {}), **datasets.get(s, {})} for s in {*datasets, *base_datasets}
    }
    return pd.concat([base, df], ignore_index=True), {**config, "methods": methods}, sets, book


def _choice(params):
    """The CV's choice of K, j and b_xy from a row's ``params`` JSON."""
    try:
        p = json.loads(params)
    except (TypeError, ValueError):
        return "--"
    return f"K {p.get('n_atoms')}, j {p.get('n_neighbors')}, b {p.get('b_xy'):g}" if p else "--"


def cells(rows, pm_names, paper):
    """One row per cell: the mean errors (degrees), the fair PM's split R-hat (median and largest over the seeds)
    and CV choice, and the paired comparison of the fair and headline PMs (``fair_vs_pm``: better / tied /
    worse, Holm over the cells)."""
    from .comparisons import compare_pair, holm
    from .tables import paper_key

    fair = [n for n in pm_names if n != reconcile.PM]
    if reconcile.PM not in pm_names or len(fair) != 1:
        raise InputError(f"expected the headline PM and one fair-budget PM; found {pm_names}")
    fair = fair[0]
    ref = paper.set_index(["key", "n_train", "method"])["mean_deg"]
    out = []
    for (source, act, pa, n), g in rows.groupby(
        ["source", "activity", "paper_activity", "n_train"], sort=True
    ):
        e = g.pivot_table(index="seed", columns="name", values="error", aggfunc="first")
        if fair not in e.columns or reconcile.PM not in e.columns:
            continue
        own = g[g["name"] == fair]
        base = [b for b in reconcile.BASELINES if b in e.columns]
        best = min(base, key=lambda b: e[b].mean()) if base else None
        both = e[[fair, reconcile.PM]].dropna()
        res = compare_pair(both[fair], both[reconcile.PM], n_train=float(n), n_test=1.0)
        r_hat = own["r_hat_test_error"].dropna() if "r_hat_test_error" in own else pd.Series([])
        first = own.sort_values("seed")["params"].iloc[0] if "params" in own else None
        key = (paper_key(pa), int(n), reconcile.PM)
        out.append(
            {
                "source": source,
                "activity": act,
                "n_train": int(n),
                "pm": float(e[reconcile.PM].mean()),
                "fair": float(e[fair].mean()),
                "fair_train": float(own["train_error"].mean()),
                "paper_pm": float(ref[key]) if key in ref.index else np.nan,
                "nn": float(e[reconcile.NN].mean()) if reconcile.NN in e.columns else np.nan,
                "best": best,
                "best_error": float(e[best].mean()) if best else np.nan,
                "r_hat_median": float(r_hat.median()) if len(r_hat) else np.nan,
                "r_hat_max": float(r_hat.max()) if len(r_hat) else np.nan,
                "converged": int((r_hat <= 1.01).sum()),
                "splits": len(own),
                "choice": _choice(first),
                "diff": res["mean_diff"],
                "p": res["p_paired_t"],
            }
        )
    c = pd.DataFrame(out)
    if c.empty:
        raise InputError("the fair-budget table and the headline table share no cell")
    c["p_holm"] = holm(list(c["p"]))
    c["fair_vs_pm"] = np.where(
        c["p_holm"] < 0.05, np.where(c["diff"] < 0, "better", "worse"), "tied"
    )
    return c


def markdown(c, summaries):
    """The per-cell table, the summary over cells and the legend."""
    lines = [
        "| cell | PM | PM (fair budget) | train | paper's PM | 1-NN | best baseline | split R-hat (median, max) "
        "| CV choice | fair vs PM |",
        "|---|" + "---:|" * 7 + "---|---|",
    ]
    for r in c.itertuples():
        rh = f"{r.r_hat_median:.3f}, {r.r_hat_max:.3f}" if np.isfinite(r.r_hat_median) else "--"
        lines.append(
            f"| {r.activity.replace('_', ' ')} N = {r.n_train} | {r.pm:.2f} | {r.fair:.2f} | {r.fair_train:.2f} "
            f"| {r.paper_pm:.2f} | {r.nn:.2f} | {r.best_error:.2f} ({r.best}) | {rh} | {r.choice} "
            f"| {r.fair_vs_pm} |"
        )
    counts = c["fair_vs_pm"].value_counts()
    lines += [
        "",
        reconcile.pm_markdown(summaries, VARIANT, legend=False),
        "",
        f"Mean errors over the 10 seeds (degrees) on the paper protocol's splits. PM: the headline PM (1 chain, 10 "
        f"prediction sweeps, CV at 300 sweeps); PM (fair budget): 4 chains, 100 prediction sweeps, CV at the "
        f"final 1200 sweeps over K, j and the noise prior's rate b (config/paper-pmfair.yaml); train: its error "
        f"on the training frames. Best baseline: the lowest of our RVM, TGP, SR and DDL. Split R-hat of the fair "
        f"PM's test error across its chains (1.01 or less: the chains agree; "
        f"{int(c['converged'].sum())} of {int(c['splits'].sum())} splits). Fair vs PM: paired t-test over the "
        f"seeds on these frames, Holm over the {len(c)} cells, p < 0.05 "
        f"(better {counts.get('better', 0)}, tied {counts.get('tied', 0)}, worse {counts.get('worse', 0)}). "
        "Summary rows: the cells where each PM is better / tied / worse than 1-NN and each baseline (paired "
        "t-test over the seeds, Holm over the PM's comparisons in the cell). With 4 motions no test across "
        "motions can reach p < 0.05 (the smallest two-sided Wilcoxon p is 0.125): no claim beyond these frames. "
        "Generated by `python -m bsrbench.reporting.published budget reports/published/paper-pmfair.csv`.",
    ]
    return "\n".join(lines)


def published_parts(table, beside, paper):
    """``(cells, summaries)`` of the published fair-budget ``table`` beside the headline table ``beside``:
    :func:`cells` and :func:`.reconcile.pm_summary` (each PM against 1-NN and the baselines)."""
    df, config, datasets, book = published_inputs(table, beside, paper)
    rows, pm = reconcile.pm_rows(df, config, datasets, VARIANT)
    if not len(rows):
        raise InputError(f"{table}: no PM rows on the paper protocol's frames")
    return cells(rows, pm, book), reconcile.pm_summary(rows, pm, book)


def published_markdown(table, beside, paper):
    """:func:`markdown` of the published fair-budget ``table`` beside the headline table ``beside``."""
    return markdown(*published_parts(table, beside, paper))
