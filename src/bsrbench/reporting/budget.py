"""PM with a fair budget beside the headline PM on the same splits of the paper protocol
(``config/paper-pmfair.yaml``, ``reports/published/paper-pmfair.csv`` beside ``reports/published/paper.csv``).

The fair-budget table is layered over the paper protocol's configuration, so its rows pair seed by seed with the
headline table's PM, 1-NN and the paper's four baselines. Per cell (activity, N): the mean errors of both PMs, the
paper's PM, 1-NN and the best of our four baselines; the split R-hat of the fair PM's test error over its chains;
its CV choice; and whether the fair PM beats the headline PM on these frames (paired t-test over the seeds, Holm
over the cells). :func:`summary` adds, per PM, the cells better, tied or worse than 1-NN and each baseline
(:func:`.reconcile.pm_summary`).
"""

import math

import numpy as np
import pandas as pd

from ..errors import DataFileError, InputError
from ..safeload import json_text
from . import reconcile

#: The paper protocol's variant (random splits, the files' first 600 rows, tuned methods, wrapped error).
VARIANT = reconcile.BASE
#: The columns the headline table needs of every row, and the fair-budget table (its PM's R-hat and CV choice).
NEEDED = [*reconcile.NEEDED, "error", "train_error"]
NEEDED_FAIR = [*NEEDED, "r_hat_test_error", "params"]
#: The parameters of the fair PM's CV choice, as :func:`_choice` shows them.
CHOICE = ("n_atoms", "n_neighbors", "b_xy")


def _checked(table, df, needed, datasets):
    """``df`` (the rows of ``table``) with its PM rows' numbers read as numbers; DataFileError naming ``table``
    and the columns of ``needed`` it lacks, InputError naming the line, the column and the value of a row of a
    data set that ``datasets`` (the study's) lacks, or of a PM row whose ``train_error`` or ``r_hat_test_error``
    is not a finite number or whose ``params`` do not hold the CV's choice (:func:`_choice`): a table of other
    rows must not pass as a caption of NaNs or of no converged split."""
    from .tables import paper_names

    missing = [c for c in needed if c not in df.columns]
    if missing:
        raise DataFileError(
            table,
            f"lacks columns {missing}, which the budget table needs; expected rows of today's code (rerun the "
            "study)",
        )
    for i, (s, a) in enumerate(zip(df["source"], df["activity"])):
        if a not in (datasets.get(s) or {}):
            raise InputError(
                f"{table} line {i + 2}: columns 'source', 'activity' are {s!r}, {a!r}; expected a data set of "
                "the study's configuration (the configuration files the table's provenance names)"
            )
    pm = (df["method"].map(paper_names(df)) == reconcile.PM).to_numpy()
    expected = {
        "train_error": "a finite number (degrees)",
        "r_hat_test_error": "a finite number (the split R-hat of the test error over the chains)",
    }
    out = df.copy()
    for col in [c for c in expected if c in needed]:
        v = pd.to_numeric(df[col], errors="coerce")
        bad = np.flatnonzero(pm & ~np.isfinite(v.to_numpy(dtype=float)))
        if len(bad):
            value = df[col].iloc[bad[0]]
            value = value.item() if isinstance(value, np.generic) else value
            raise InputError(
                f"{table} line {bad[0] + 2}: column {col!r} is {value!r}; expected {expected[col]}"
            )
        out[col] = v
    if "params" in needed:
        for i in np.flatnonzero(pm):
            _choice(df["params"].iloc[i], f"{table} line {i + 2}: column 'params'")
    return out


def published_inputs(table, beside, paper):
    """The rows of the fair-budget ``table`` and of the headline table ``beside`` (restricted to the fair table's
    cells), the two studies' configurations merged (methods of both), their data sets and the paper's tables."""
    df, config, datasets, book = reconcile.published_inputs(table, paper)
    df = _checked(table, df, NEEDED_FAIR, datasets)
    base, base_config, base_datasets, _ = reconcile.published_inputs(beside, paper)
    base = _checked(beside, base, NEEDED, base_datasets)
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


def _choice(params, where="column 'params'"):
    """The CV's choice of K, j and b_xy from a row's ``params`` JSON; InputError naming ``where`` (the table's
    line and column), the value and what was expected unless it is a JSON object with a number for each of
    :data:`CHOICE`."""
    p = json_text(params, where) if isinstance(params, str) else None
    shown = repr(params) if len(repr(params)) <= 80 else repr(params)[:77] + "..."
    expected = f"expected a JSON object with a number for each of {list(CHOICE)} (the CV's choice)"
    if not isinstance(p, dict):
        raise InputError(f"{where} is {shown}; {expected}")
    for k in CHOICE:
        v = p.get(k)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            got = "is missing" if k not in p else f"is {v!r}"
            raise InputError(f"{where} is {shown}: {k!r} {got}; {expected}")
    return f"K {p['n_atoms']}, j {p['n_neighbors']}, b {p['b_xy']:g}"


def cells(rows, pm_names, paper, tables=("the fair-budget table", "the headline table")):
    """One row per cell: the mean errors (degrees), the fair PM's split R-hat (median and largest over the seeds)
    and CV choice, and the paired comparison of the fair and headline PMs (``fair_vs_pm``: better / tied /
    worse, Holm over the cells). ``tables``: the fair-budget and the headline table, as messages name them."""
    from .comparisons import compare_pair, holm
    from .tables import paper_key

    fair = [n for n in pm_names if n != reconcile.PM]
    if reconcile.PM not in pm_names or len(fair) != 1:
        raise InputError(
            f"{tables[0]} beside {tables[1]}: found the PMs {pm_names} on the cells of {tables[0]}; expected "
            "the headline PM and one fair-budget PM"
        )
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
        raise InputError(
            f"{tables[0]} and {tables[1]} share no cell (source, activity, N) holding both PMs; expected the "
            "headline table to hold the fair-budget table's cells"
        )
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
    return cells(rows, pm, book, (table, beside)), reconcile.pm_summary(rows, pm, book)


def published_markdown(table, beside, paper):
    """:func:`markdown` of the published fair-budget ``table`` beside the headline table ``beside``."""
    return markdown(*published_parts(table, beside, paper))
