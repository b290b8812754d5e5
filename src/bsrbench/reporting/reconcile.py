"""The protocol reconciliation: under which variant of the protocol do 1-NN and the paper's baselines land on the
paper's numbers for the authors' features (``config/reconcile.yaml``, ``reports/published/reconcile.csv``)?

A variant is a combination of four factors, each read from the study's configuration rather than from names:

- ``splits``: the row's protocol (random, blocked, ...);
- ``frames``: which frames of the authors' file the data set keeps (its ``first_frame`` and ``frame_step``);
- ``setting``: how the method is set, from its configuration: ``tuned`` (a CV grid), ``defaults`` (no grid, no
  parameters: the class's defaults) or ``no heading transform`` (its own ``pose_transform: none``);
- ``metric``: the error with wrapped angle differences (``error``, the paper's metric as the authors' group's code
  computes it) or the plain difference (``error_unwrapped``).

Per variant, method and cell (paper activity, N) the mean error over the seeds is set beside the paper's number for
that method (for 1-NN, which the paper does not run, the best of the paper's four baselines in that cell): the ratio
ours / paper and whether ours lies within the paper's standard deviation of it. :func:`summary` gives per variant
and method the median ratio over the cells and the cells within the std; :func:`nearest` names the variant whose
methods land nearest the paper (smallest median over methods and cells of |log ratio|).
"""

import numpy as np
import pandas as pd

from ..errors import InputError
from .tables import paper_key, paper_names

#: The paper's baselines, the methods whose numbers are reconciled (with 1-NN against their best).
BASELINES = ("RVM", "TGP", "SR", "DDL")
NN = "1-NN"
PM = "PM"
METRICS = {"wrapped": "error", "unwrapped": "error_unwrapped"}
FACTORS = ["splits", "frames", "setting", "metric"]
#: The study's own protocol, first in every factor's order.
BASE = {"splits": "random", "frames": "rows 0-599", "setting": "tuned", "metric": "wrapped"}


def frames_label(entry):
    """Which rows of its file a data set keeps: ``rows 0-599``, ``rows 100-699``, ``every 2nd row``."""
    first, step, n = (
        int(entry.get("first_frame") or 0),
        int(entry.get("frame_step") or 1),
        entry["n_frames"],
    )
    if step > 1:
        return f"every {step}nd row" if step == 2 else f"every {step}th row"
    return f"rows {first}-{first + int(n) - 1}"


def method_setting(entry):
    """How a configured method is set: ``no heading transform``, ``defaults`` or ``tuned``."""
    if entry.get("pose_transform") == "none":
        return "no heading transform"
    if entry.get("grid", "default") is None and not entry.get("params"):
        return "defaults"
    return "tuned"


#: The columns a reconciliation needs of every row.
NEEDED = [
    "protocol",
    "source",
    "activity",
    "paper_activity",
    "method",
    "estimator",
    "n_train",
    "seed",
]


def _checked(df, datasets):
    """InputError naming the column, or the data set, that the reconciliation cannot do without: a missing column,
    an empty or non-finite error, a data set the study's configuration does not define."""
    missing = [c for c in NEEDED + list(METRICS.values()) if c not in df.columns]
    if missing:
        raise InputError(
            f"the results lack columns {missing}; expected rows of today's code (rerun the study)"
        )
    for c in ("estimator", "paper_activity"):
        if df[c].isna().any():
            raise InputError(f"the results have rows without {c!r}; expected it on every row")
    for c in METRICS.values():
        v = pd.to_numeric(df[c], errors="coerce")
        if not np.isfinite(v).all():
            raise InputError(
                f"the results have rows whose {c!r} is empty or not finite; expected a number"
            )
    for s, a in df[["source", "activity"]].drop_duplicates().itertuples(index=False):
        if a not in (datasets.get(s) or {}):
            raise InputError(
                f"data set {s}/{a} of the results is not in the study's configuration; expected the "
                "configuration files the table's provenance names"
            )


def cells(df, config, datasets, paper):
    """One row per variant, method (its paper name, or 1-NN) and cell (paper activity, N) of the results ``df``:
    our mean and std over the seeds, the paper's mean and std, ratio and ``within`` (|ours - paper| <= the paper's
    std). ``config``: the study's configuration (methods), ``datasets``: {source: {activity: entry}} of the study,
    ``paper``: :func:`.tables.read_paper_tables`. InputError for rows it cannot reconcile (:func:`_checked`)."""
    _checked(df, datasets)
    names = paper_names(df)
    methods = config.get("methods") or {}
    kinds = {}
    for m in df["method"].unique():
        name = names.get(m)
        if name in BASELINES:
            kinds[m] = (name, method_setting(methods.get(m) or {}))
        elif m in methods and "NearestNeighbourRegressor" in methods[m]["estimator"]:
            if (methods[m].get("params") or {}).get("n_neighbors") == 1:
                kinds[m] = (NN, "tuned")
    if not kinds:
        raise InputError(
            "the results hold neither 1-NN nor one of the paper's baselines; nothing to reconcile"
        )
    rows = df[df["method"].isin(kinds)].copy()
    missing = [c for c in METRICS.values() if c not in rows.columns]
    if missing:
        raise InputError(
            f"the results lack columns {missing}; expected rows of today's code (rerun the study)"
        )
    rows["frames"] = [
        frames_label(datasets[s][a]) for s, a in zip(rows["source"], rows["activity"])
    ]
    rows["splits"] = rows["protocol"]
    rows["name"] = rows["method"].map(lambda m: kinds[m][0])
    rows["setting"] = rows["method"].map(lambda m: kinds[m][1])
    rows["key"] = rows["paper_activity"].map(paper_key)
    book = paper.set_index(["key", "n_train", "method"])[["mean_deg", "std_deg"]]
    best = (
        paper[paper["method"].isin(BASELINES)]
        .sort_values("mean_deg")
        .groupby(["key", "n_train"])
        .first()
    )
    out = []
    for metric, col in METRICS.items():
        g = rows.groupby(
            ["splits", "frames", "setting", "name", "key", "paper_activity", "n_train"]
        )[col]
        means = g.agg(["mean", "std", "count"]).reset_index()
        for r in means.itertuples(index=False):
            key = (r.key, int(r.n_train))
            if r.name == NN:
                if key not in best.index:
                    continue
                ref = best.loc[key]
                p_mean, p_std, ref_method = (
                    float(ref["mean_deg"]),
                    float(ref["std_deg"]),
                    ref["method"],
                )
            else:
                if (*key, r.name) not in book.index:
                    continue
                ref = book.loc[(*key, r.name)]
                p_mean, p_std, ref_method = float(ref["mean_deg"]), float(ref["std_deg"]), r.name
            out.append(
                {
                    "splits": r.splits,
                    "frames": r.frames,
                    "setting": r.setting,
                    "metric": metric,
                    "method": r.name,
                    "paper_activity": r.paper_activity,
                    "n_train": int(r.n_train),
                    "seeds": int(r.count),
                    "mean": float(r.mean),
                    "std": float(r.std),
                    "paper_method": ref_method,
                    "paper_mean": p_mean,
                    "paper_std": p_std,
                    "ratio": float(r.mean) / p_mean,
                    "within": bool(abs(float(r.mean) - p_mean) <= p_std),
                }
            )
    out = pd.DataFrame(out)
    # 1-NN has one setting: it is the same fit under every setting of the baselines
    nn = out[out["method"] == NN]
    for setting in sorted(set(out["setting"]) - {"tuned"}):
        out = pd.concat([out, nn.assign(setting=setting)], ignore_index=True)
    return out


def _order(values, first):
    return sorted(set(values), key=lambda v: (v != first, v))


def summary(c):
    """Per variant (:data:`FACTORS`) and method: cells, median ratio over them, cells within the paper's std, and
    the median |log ratio| (the distance to the paper). The study's own protocol first."""
    g = c.groupby([*FACTORS, "method"])
    s = g.agg(
        cells=("ratio", "size"),
        median_ratio=("ratio", "median"),
        within=("within", "sum"),
    ).reset_index()
    s["distance"] = g["ratio"].agg(lambda r: float(np.median(np.abs(np.log(r))))).to_numpy()
    for f in FACTORS:
        s[f] = pd.Categorical(s[f], _order(s[f], BASE[f]))
    methods = [NN, *BASELINES]
    s["method"] = pd.Categorical(s["method"], [m for m in methods if m in set(s["method"])])
    return s.sort_values([*FACTORS, "method"]).reset_index(drop=True)


def nearest(s):
    """The variant whose methods land nearest the paper's numbers: ``(variant dict, distance)``, the smallest mean
    over the methods of their median |log ratio| (every method of the study measured in it)."""
    n_methods = s["method"].nunique()
    d = s.groupby(FACTORS, observed=True).agg(
        distance=("distance", "mean"), methods=("method", "nunique")
    )
    # ties go to the variant nearer the study's own protocol (the factors' order)
    d = d[d["methods"] == n_methods].sort_index().sort_values("distance", kind="mergesort")
    if d.empty:
        raise InputError("no variant has every method measured; nothing to choose")
    best = d.index[0]
    return dict(zip(FACTORS, best)), float(d["distance"].iloc[0])


def pm_rows(df, config, datasets, variant):
    """``(rows, pm)``: the rows of PM's methods (the paper's estimator), 1-NN and the paper's baselines in
    ``variant``'s splits and frames (the :func:`nearest` variant) and setting (and tuned, named ``RVM (tuned)``),
    with ``name`` (PM's methods by their configured label, 1-NN, RVM, ...), and PM's names; no rows when the
    results hold no PM method there."""
    names = paper_names(df)
    methods = config.get("methods") or {}
    label = {}
    for m in df["method"].unique():
        entry = methods.get(m) or {}
        if names.get(m) == PM:
            label[m] = str(entry.get("label") or m)
        elif names.get(m) in BASELINES and method_setting(entry) in (variant["setting"], "tuned"):
            setting = method_setting(entry)
            label[m] = names[m] if setting == variant["setting"] else f"{names[m]} ({setting})"
        elif (
            "NearestNeighbourRegressor" in str(entry.get("estimator", ""))
            and (entry.get("params") or {}).get("n_neighbors") == 1
        ):
            label[m] = NN
    rows = df[df["method"].isin(label) & (df["protocol"] == variant["splits"])].copy()
    rows["frames"] = [
        frames_label(datasets[s][a]) for s, a in zip(rows["source"], rows["activity"])
    ]
    if variant["frames"] is not None:  # None: each data set's configured frames
        rows = rows[rows["frames"] == variant["frames"]]
    rows["name"] = rows["method"].map(label)
    pm = sorted({label[m] for m in label if names.get(m) == PM})
    return rows if set(rows["name"]) & set(pm) else rows.iloc[:0], pm


def pm_summary(rows, pm_names, paper, metric="error"):
    """Per PM method: the cells, its median ratio to the paper's PM and the cells within the paper's std, the
    split R-hat of its chains (median and largest over the splits), and per method compared with (1-NN and the
    baselines) the cells where it is better, tied or worse on these frames (paired t-test over the seeds, Holm over
    the method's comparisons of the cell, p < 0.05). ``metric``: the error column (:data:`METRICS`)."""
    from .comparisons import compare_pair, holm

    book = paper.set_index(["key", "n_train", "method"])[["mean_deg", "std_deg"]]
    present = set(rows["name"])
    others = [m for b in (NN, *BASELINES) for m in (b, f"{b} (tuned)") if m in present]
    out = []
    for name in pm_names:
        own = rows[rows["name"] == name]
        r = {"method": name, "cells": 0, "ratios": [], "within": 0, "r_hat": []}
        r["error"] = float(own[metric].mean())
        r["train_error"] = float(own["train_error"].mean()) if "train_error" in own else np.nan
        counts = {o: [0, 0, 0] for o in others}
        for (_, _, pa, n), g in rows.groupby(["source", "activity", "paper_activity", "n_train"]):
            e = g.pivot_table(index="seed", columns="name", values=metric, aggfunc="first")
            if name not in e.columns:
                continue
            r["cells"] += 1
            key = (paper_key(pa), int(n), PM)
            if key in book.index:
                ours, ref = float(e[name].mean()), book.loc[key]
                r["ratios"].append(ours / float(ref["mean_deg"]))
                r["within"] += abs(ours - float(ref["mean_deg"])) <= float(ref["std_deg"])
            if "r_hat_test_error" in g.columns:
                r["r_hat"] += list(g.loc[g["name"] == name, "r_hat_test_error"].dropna())
            tests = []
            for o in others:
                common = e[[name, o]].dropna() if o in e.columns else e.iloc[:0]
                res = compare_pair(common[name], common[o], n_train=float(n), n_test=1.0)
                tests.append((o, res["mean_diff"], res["p_paired_t"]))
            for (o, diff, _), p in zip(tests, holm([t[2] for t in tests])):
                if np.isfinite(p) and p < 0.05:
                    counts[o][0 if diff < 0 else 2] += 1
                elif np.isfinite(p):
                    counts[o][1] += 1
        r["counts"] = counts
        out.append(r)
    return out


def pm_markdown(summaries, variant, legend=True):
    """The markdown of :func:`pm_summary`, with its legend unless ``legend`` is false."""
    if not summaries:
        return ""
    others = list(summaries[0]["counts"])
    head = "| method | cells | test / train error | ratio to the paper's PM | split R-hat (median, max) | "
    head += " | ".join(f"vs {o}" for o in others)
    lines = [head + " |", "|" + "---|" * (5 + len(others))]
    for r in summaries:
        ratio = (
            f"{np.median(r['ratios']):.2f} ({r['within']}/{len(r['ratios'])})"
            if r["ratios"]
            else "--"
        )
        rh = f"{np.median(r['r_hat']):.3f}, {np.max(r['r_hat']):.3f}" if r["r_hat"] else "--"
        cols = ["{}/{}/{}".format(*r["counts"][o]) for o in others]
        err = f"{r['error']:.2f} / {r['train_error']:.2f}"
        lines.append(
            f"| {r['method']} | {r['cells']} | {err} | {ratio} | {rh} | " + " | ".join(cols) + " |"
        )
    if not legend:
        return "\n".join(lines)
    lines += [
        "",
        f"PM under the nearest variant (splits {variant['splits']}, {variant['frames']}): the median over the "
        "cells of its mean error over the paper's PM (in brackets: cells within the paper's std); its mean error "
        "on the test and on the training frames over the cells and seeds (degrees); the split R-hat "
        "of its test error over its chains (1.01 or less: the chains agree); per method compared with, the cells "
        "where PM's method is better / tied / worse on these frames (paired t-test over the seeds, Holm over the "
        "method's comparisons in the cell, p < 0.05). With 4 motions no test across motions can reach p < 0.05 "
        "(the smallest two-sided Wilcoxon p is 0.125), so no claim beyond these frames is made.",
    ]
    return "\n".join(lines)


def markdown(c, *, study="reconcile"):
    """The markdown table of the reconciliation (one row per variant, per method the median ratio and the cells
    within the paper's std) with its legend and the nearest variant."""
    s = summary(c)
    methods = list(s["method"].cat.categories)
    head = "| splits | frames | setting | metric | " + " | ".join(methods) + " | mean distance |"
    lines = [head, "|" + "---|" * (5 + len(methods))]
    for key, g in s.groupby(FACTORS, observed=True, sort=True):
        g = g.set_index("method", drop=False)
        cols = []
        for m in methods:
            if m in g.index and g.loc[m, "cells"] > 0:
                r = g.loc[m]
                cols.append(f"{r['median_ratio']:.2f} ({int(r['within'])}/{int(r['cells'])})")
            else:
                cols.append("--")
        dist = g["distance"].mean()
        lines.append(
            "| " + " | ".join(map(str, key)) + " | " + " | ".join(cols) + f" | {dist:.2f} |"
        )
    best, dist = nearest(s)
    base = s[(s[FACTORS] == pd.Series(BASE)).all(axis=1)]
    own = f"; the study's own protocol: {base['distance'].mean():.2f}" if len(base) else ""
    b = s.set_index([*FACTORS, "method"])
    key = tuple(best[f] for f in FACTORS)
    per = ", ".join(
        f"{m} {b.loc[(*key, m), 'median_ratio']:.2f} ({int(b.loc[(*key, m), 'within'])} of "
        f"{int(b.loc[(*key, m), 'cells'])} cells within the paper's std)"
        for m in methods
        if (*key, m) in b.index
    )
    lines += [
        "",
        f"Per variant of the protocol and method: the median over the cells (paper activity, N) of our mean error "
        f"over the paper's number for that method and cell, and (in brackets) the cells where our mean lies within "
        f"the paper's standard deviation of it; {NN} against the best of the paper's four baselines in the cell. "
        f"Mean distance: the mean over the methods of the median |log ratio| (0: the paper's numbers). Generated "
        f"by `python -m bsrbench.reporting.published reconcile reports/published/{study}.csv`.",
        "",
        f"Nearest the paper: splits {best['splits']}, {best['frames']}, {best['setting']}, {best['metric']} error "
        f"(mean distance {dist:.2f}{own}): {per}.",
    ]
    return "\n".join(lines)


def published_inputs(table, paper):
    """A published reconciliation table's rows, its study's configuration and data sets (the configuration files its
    provenance names) and the paper's tables (``paper``: their CSV)."""
    from ..methods import study_datasets
    from . import freshness
    from .tables import read_paper_tables, read_results

    files = freshness.configfiles(table)
    return (
        read_results(table),
        freshness.study_config(files),
        study_datasets(files),
        read_paper_tables(paper),
    )


def published_cells(table, paper):
    """:func:`cells` of a published reconciliation table."""
    return cells(*published_inputs(table, paper))
