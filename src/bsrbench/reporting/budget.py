"""PM with a fair budget beside the headline PM on the same splits of the paper protocol
(``config/paper-pmfair.yaml``, ``reports/published/paper-pmfair.csv`` beside ``reports/published/paper.csv``).

The fair-budget table is layered over the paper protocol's configuration, so its rows pair seed by seed with the
headline table's PM, 1-NN and the paper's four baselines. Per cell (activity, N): the mean errors of both PMs, the
paper's PM, 1-NN and the best of our four baselines; the split R-hat of the fair PM's test error over its chains;
its CV choice; and whether the fair PM beats the headline PM on these frames (paired t-test over the seeds, Holm
over the cells). Per data source, :func:`.reconcile.pm_summary` adds, per PM, the cells better, tied or worse than
1-NN and each baseline; :func:`across_motions` asks the question across the distinct motions
(:mod:`.verdict`, the motion as the unit).
"""

import math

import numpy as np
import pandas as pd

from ..errors import DataFileError, InputError
from ..safeload import json_text
from . import reconcile

#: The paper protocol (random splits, tuned methods, wrapped error) on each data set's frames as configured: the
#: fair-budget study is layered over config/paper.yaml, so its frames are the headline table's.
VARIANT = {**reconcile.BASE, "frames": None}
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


#: The methods the headline table must hold in every cell of the fair-budget table, as :mod:`.reconcile` names
#: them: its PM, 1-NN and the paper's four baselines (the columns and the summary rows compare them).
BESIDE = (reconcile.PM, reconcile.NN, *reconcile.BASELINES)


def _cell_text(source, activity, n):
    return f"(source {source!r}, activity {activity!r}, N {int(n)})"


def check_beside(rows, pm_names, tables=("the fair-budget table", "the headline table")):
    """Refuse a fair-budget table whose cells the headline table cannot be set beside: InputError naming the
    headline table, the cell (source, activity, N) and the methods of :data:`BESIDE` it lacks there, or both
    tables, the cell and both seed lists when the fair PM's seeds differ from the headline PM's (means and pairs
    over other seeds are no comparison). ``rows``: :func:`.reconcile.pm_rows` of both tables; ``tables``: the
    fair-budget and the headline table, as messages name them. A headline table without any PM is left to
    :func:`cells`, which names the PMs found."""
    fair = [n for n in pm_names if n != reconcile.PM]
    if reconcile.PM not in pm_names or len(fair) != 1:
        return
    (fair,) = fair
    keys = ["source", "activity", "n_train"]
    for (source, act, n), g in rows.groupby(keys, sort=True):
        if not (g["name"] == fair).any():
            continue
        missing = [m for m in BESIDE if m not in set(g["name"])]
        if missing:
            raise InputError(
                f"{tables[1]}: the cell {_cell_text(source, act, n)} of {tables[0]} lacks method(s) "
                f"{missing}; expected the headline table to hold {', '.join(BESIDE)} in every cell of the "
                "fair-budget table"
            )
        seeds = [
            sorted(int(s) for s in set(g.loc[g["name"] == m, "seed"])) for m in (fair, reconcile.PM)
        ]
        if seeds[0] != seeds[1]:
            raise InputError(
                f"{tables[0]} beside {tables[1]}: the cell {_cell_text(source, act, n)} has the seeds "
                f"{seeds[0]} of {fair} in {tables[0]} and {seeds[1]} of {reconcile.PM} in {tables[1]}; "
                "expected the same seeds (the means and the paired test are over the cell's seeds)"
            )


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
                "seeds": int(own["seed"].nunique()),
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


def across_motions(rows, fair, motions):
    """The fair-budget PM ``fair`` against each other method of ``rows`` with the distinct motions as the unit
    (:func:`.verdict.verdict`: the mean of each motion's cells, both sources together when there are two):
    per method the mean difference (fair PM minus it) with its bootstrap interval over the motions, the motions
    where the fair PM is worse, and the two-sided Wilcoxon p, Holm-adjusted over the methods. ``motions``:
    {(source, activity): motion} (:func:`bsrbench.datasets.motion_map`)."""
    from .verdict import ALL, verdict

    v = verdict(rows.assign(method=rows["name"]), motions=motions, pm=fair)
    v = v[v["unit"] == "motion"]
    scope = ALL if ALL in set(v["scope"]) else v["scope"].iloc[0]
    return v[(v["scope"] == scope) & (v["versus"] == fair)].set_index("method")


def _motions_markdown(v, fair):
    """The table of :func:`across_motions` and what its motions can show."""
    from .verdict import p_text, smallest_p

    b = int(v["n_blocks"].iloc[0])
    floor = smallest_p(b, len(v), one_sided=False)
    lines = [
        f"Across the {b} distinct motions (each the mean of its cells; {fair} minus each method):",
        "",
        "| method | mean difference [95% bootstrap interval] | motions where the fair PM is worse | Wilcoxon p "
        "(Holm) |",
        "|---|---:|---:|---:|",
    ]
    for m, r in v.sort_values("mean_diff").iterrows():
        ci = (
            f" [{r['diff_ci_low']:+.2f}, {r['diff_ci_high']:+.2f}]"
            if np.isfinite(r["diff_ci_low"])
            else ""
        )
        lines.append(
            f"| {m} | {r['mean_diff']:+.2f}{ci} | {int(r['versus_worse_blocks'])} of {b} "
            f"| {p_text(r['p_wilcoxon_holm'])} |"
        )
    reach = (
        f"With {b} motions and Holm over {len(v)} methods the smallest possible p is {floor:.3g}: no test across "
        "motions can reach p < 0.05, and no claim beyond these frames is made; the intervals say what the "
        "motions can."
        if floor >= 0.05
        else f"With {b} motions and Holm over {len(v)} methods the smallest possible p is {floor:.3g}."
    )
    return lines, reach


def markdown(c, summaries, motions=None):
    """The per-cell table, the summary over cells per data source (``summaries``: {source: pm_summary}, or one
    summary list), the comparison across motions (``motions``: :func:`across_motions`, or None) and the legend."""
    lines = [
        "| cell | PM | PM (fair budget) | train | paper's PM | 1-NN | best baseline | split R-hat (median, max) "
        "| CV choice | fair vs PM |",
        "|---|" + "---:|" * 7 + "---|---|",
    ]
    for r in c.itertuples():
        rh = f"{r.r_hat_median:.3f}, {r.r_hat_max:.3f}" if np.isfinite(r.r_hat_median) else "--"
        lines.append(
            f"| {r.source} {r.activity.replace('_', ' ')} N = {r.n_train} | {r.pm:.2f} | {r.fair:.2f} | {r.fair_train:.2f} "
            f"| {r.paper_pm:.2f} | {r.nn:.2f} | {r.best_error:.2f} ({r.best}) | {rh} | {r.choice} "
            f"| {r.fair_vs_pm} |"
        )
    counts = c["fair_vs_pm"].value_counts()
    if not isinstance(summaries, dict):
        summaries = {"": summaries}
    for source, summary in summaries.items():
        lines += [""] + ([f"{source}:", ""] if len(summaries) > 1 else [])
        lines += [reconcile.pm_markdown(summary, VARIANT, legend=False)]
    reach = ""
    if motions is not None and len(motions):
        fair = str(motions["versus"].iloc[0])
        table, reach = _motions_markdown(motions, fair)
        lines += [""] + table
    seeds = sorted(set(c["seeds"])) if "seeds" in c else []
    over = (
        f"the {seeds[0]} seeds"
        if len(seeds) == 1
        else f"the seeds ({seeds[0]} to {seeds[-1]} per cell)"
        if seeds
        else "the seeds"
    )
    lines += [
        "",
        f"Mean errors over {over} (degrees) on the paper protocol's splits. PM: the headline PM (1 chain, 10 "
        f"prediction sweeps, CV at 300 sweeps); PM (fair budget): 4 chains, 100 prediction sweeps, CV at the "
        f"final 1200 sweeps over K, j and the noise prior's rate b (config/paper-pmfair.yaml); train: its error "
        f"on the training frames. Best baseline: the lowest of our RVM, TGP, SR and DDL. Split R-hat of the fair "
        f"PM's test error across its chains (1.01 or less: the chains agree; "
        f"{int(c['converged'].sum())} of {int(c['splits'].sum())} splits). Fair vs PM: paired t-test over the "
        f"seeds on these frames, Holm over the {len(c)} cells, p < 0.05 "
        f"(better {counts.get('better', 0)}, tied {counts.get('tied', 0)}, worse {counts.get('worse', 0)}). "
        "Summary rows: the cells where each PM is better / tied / worse than 1-NN and each baseline (paired "
        f"t-test over the seeds, Holm over the PM's comparisons in the cell), per data source. {reach} "
        "Generated by `python -m bsrbench.reporting.published budget reports/published/paper-pmfair.csv`.",
    ]
    return "\n".join(lines)


def published_parts(table, beside, paper):
    """``(cells, summaries, motions)`` of the published fair-budget ``table`` beside the headline table
    ``beside``: :func:`cells`, {source: :func:`.reconcile.pm_summary`} (each PM against 1-NN and the baselines on
    the cells of the source) and :func:`across_motions`."""
    from ..datasets import motion_map

    df, config, datasets, book = published_inputs(table, beside, paper)
    rows, pm = reconcile.pm_rows(df, config, datasets, VARIANT)
    if not len(rows):
        raise InputError(f"{table}: no PM rows on the paper protocol's splits")
    check_beside(rows, pm, (table, beside))
    c = cells(rows, pm, book, (table, beside))
    rows = rows.merge(c[["source", "activity", "n_train"]], on=["source", "activity", "n_train"])
    summaries = {s: reconcile.pm_summary(g, pm, book) for s, g in rows.groupby("source", sort=True)}
    (fair,) = [n for n in pm if n != reconcile.PM]
    return c, summaries, across_motions(rows, fair, motion_map(datasets))


def published_markdown(table, beside, paper):
    """:func:`markdown` of the published fair-budget ``table`` beside the headline table ``beside``."""
    return markdown(*published_parts(table, beside, paper))
