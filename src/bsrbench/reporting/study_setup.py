"""The report's section "Setup": what was run (data, methods, sizes, splits, hyper-parameters) and the table of
the parameters each method ran with, computed from the aggregate table."""

import json
import math

from .latex import escape, general, nobreak, table
from .tables import activity_label


def method_order(df, labels):
    """The methods of ``df`` in the order of ``labels`` (the configuration's ``run``), then any others."""
    have = list(dict.fromkeys(df["method"]))
    return [m for m in labels if m in have] + [m for m in have if m not in labels]


def parameters_used(df, *, defaults, labels=None):
    """Per method, the parameters its fits actually used: ``{method: (set, default)}``.

    ``set``: ``{name: [values]}`` of the parameters given by the configuration or chosen by CV (the aggregate
    table's ``params``, one list entry per distinct value over jobs); ``default``: ``{name: value}`` of the
    estimator's other constructor parameters (``defaults[method]``, e.g. from
    :func:`bsrbench.estimators.estimator_defaults`), i.e. the values it ran with. ``random_state`` is set per job.
    """
    out = {}
    for m in method_order(df, labels or {}):
        seen = {}
        for text in df.loc[df["method"] == m, "params"].astype(str):
            try:
                params = json.loads(text) if text not in ("", "nan") else {}
            except json.JSONDecodeError:
                params = {}
            for k, v in params.items():
                vals = seen.setdefault(k, [])
                if v not in vals:
                    vals.append(v)
        for k in seen:
            try:
                seen[k] = sorted(seen[k])
            except TypeError:
                pass
        default = {k: v for k, v in (defaults.get(m) or {}).items() if k not in seen}
        if "random_state" in default:
            default["random_state"] = "per job"
        out[m] = (seen, default)
    return out


def _lines(rows):
    """About how many printed lines the parameter table's rows take (the widest cell of a row: about 45
    characters a line in the third column, 70 in the fourth)."""
    return sum(max(1, math.ceil(len(r[2]) / 45), math.ceil(len(r[3]) / 70)) for r in rows)


def parameters_table(df, *, labels, defaults):
    """LaTeX table: per method, the estimator, the parameters set by the configuration or CV, and the estimator
    defaults it ran with (see :func:`parameters_used`)."""
    used = parameters_used(df, defaults=defaults, labels=labels)
    est = {}
    if "estimator" in df.columns:
        est = df.drop_duplicates("method").set_index("method")["estimator"].to_dict()

    def cell(pairs):
        # a line may break after each "|" of a CV list (tt text has no other break points)
        items = [
            escape(f"{k}={v}").replace("-", "-{}").replace("|", r"|\allowbreak{}") for k, v in pairs
        ]
        return ", ".join(items) if items else "none"

    rows = []
    for m, (seen, default) in used.items():
        set_pairs = [
            (k, "|".join(general(x, ints=False) for x in vals) + (" (CV)" if len(vals) > 1 else ""))
            for k, vals in seen.items()
        ]
        dflt_pairs = [(k, general(v, ints=False)) for k, v in default.items()]
        name = escape(labels.get(m, m))
        cls = escape(str(est.get(m, "")).split(":")[-1])
        rows.append([name, rf"\texttt{{{cls}}}", cell(set_pairs), cell(dflt_pairs)])
    return table(
        rows,
        width=r"\linewidth",
        # roman type in the parameter columns: long lists of defaults read at the table's size
        spec=r"@{}ll>{\hsize=0.75\hsize\raggedright\arraybackslash}X"
        r">{\hsize=1.25\hsize\raggedright\arraybackslash}X@{}",
        label="tab:parameters",
        head=[r"Method & Class & Set by the configuration or CV & Estimator defaults \\"],
        # a tall table (the quick study's: about 35 lines) floats, so that the findings fill page 1 instead of a
        # blank half page before it; a short one stays here, in the order of the tables
        placement="tbp" if _lines(rows) > 15 else "H",
        caption=r"Parameters each method ran with: those set by the configuration or chosen by cross-validation "
        r"(several values separated by $|$: chosen per activity and $N$), and the estimator's defaults for the "
        r"others.",
    )


def _cv_text(df, cv, how, labels):
    """How the hyper-parameters were chosen; per method when methods had CV modes of their own
    (``methods.<M>.cv``)."""
    if len(cv) <= 1:
        mode = cv[0] if cv else "none"
        return (
            f"{how.get(mode, escape(mode))} (configuration key \\texttt{{cv.mode}}: {escape(mode)})"
        )
    parts = []
    for mode in cv:
        names = [escape(labels.get(m, m)) for m in method_order(df[df["cv"] == mode], labels)]
        parts.append(f"{', '.join(names)}: {how.get(mode, escape(mode))}")
    return "; ".join(parts) + " (configuration keys \\texttt{cv.mode} and \\texttt{methods.*.cv})"


def setup_text(df, *, labels):
    """Sentences describing what was run (computed from the aggregate table)."""
    sources = {}
    pa_col = df["paper_activity"] if "paper_activity" in df.columns else [""] * len(df)
    d = df.assign(paper_activity=pa_col)[["source", "activity", "paper_activity"]].drop_duplicates()
    for src, act, pa in d.itertuples(index=False):
        sources.setdefault(src, []).append(nobreak(activity_label(act, pa)))
    seeds = sorted(df["seed"].unique())
    sizes = sorted(df["n_train"].unique())
    cv = sorted(df["cv"].dropna().unique()) if "cv" in df.columns else []
    splits = "split (seed)" if len(seeds) == 1 else "splits (seeds)"
    methods = [escape(labels.get(m, m)) for m in method_order(df, labels)]
    how = {
        "per_size": "chosen by cross-validation once per activity, method and $N$, on the training frames of "
        f"seed {int(min(seeds))} (the study's first), and used for every seed",
        "per_job": "chosen by cross-validation on the training frames of each split",
        "none": "as configured (no cross-validation)",
    }
    return [
        "Data: " + "; ".join(f"{escape(s)}: {', '.join(a)}" for s, a in sources.items()) + ".",
        f"Methods: {', '.join(methods)}.",
        f"Training sizes $N \\in \\{{{', '.join(str(n) for n in sizes)}\\}}$, {len(seeds)} {splits} per size; "
        f"protocol: {escape(', '.join(sorted(df['protocol'].unique())))}; "
        f"pose transform: {escape(', '.join(sorted(df['pose_transform'].unique())))}.",
        "Hyper-parameters: " + _cv_text(df, cv, how, labels) + ". "
        "Table~\\ref{tab:parameters} lists the parameters each method ran with.",
    ]
