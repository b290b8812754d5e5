"""Convergence of the MCMC methods: the summary table, its LaTeX and the trace figures, from the aggregate table
and the saved fits.

A method run with several chains per split (config key ``methods.<M>.chains``) has, in its rows of the
aggregate, ``n_chains`` and the split R-hat and bulk ESS across chains (ArviZ; Vehtari, Gelman, Simpson,
Carpenter & Buerkner 2021) of the log-likelihood, g_xy, g_s (g_nx, g_ny with separate noise precisions)
and the test error of each retained posterior sample (see :func:`bsrbench.convergence.convergence_summary`).
Rows of one-chain methods have NaN there. The PM ablation that reads these columns is
:mod:`bsrbench.reporting.ablation`.
"""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..convergence import CONVERGENCE_SERIES
from ..io import read_npz
from .latex import escape, fixed, percent, table

#: Columns the aggregate always has (NaN where not computed): chains per split, R-hat and bulk ESS.
CONVERGENCE_COLUMNS = ["n_chains"] + [
    f"{s}_{n}" for n in CONVERGENCE_SERIES for s in ("r_hat", "ess_bulk")
]
#: R-hat below this counts as converged in the goal (the ablation's threshold) ...
RHAT_OK = 1.05
#: ... and below this, the threshold Vehtari et al. (2021) recommend, reported beside it.
RHAT_STRICT = 1.01
#: Per-job columns the aggregate may have (rows written before them have none): tail ESS and the Monte Carlo
#: standard error of each series (ArviZ ``ess(method="tail")``, ``mcse``). Tables show a dash where absent.
EXTRA_CONVERGENCE_COLUMNS = [f"{s}_{n}" for n in CONVERGENCE_SERIES for s in ("ess_tail", "mcse")]
#: Math labels of the per-sweep traces.
#: Math names in titles are set at 10 pt: their sub- and superscripts (0.7 of it) then print at 7 pt.
MATH_TITLE_PT = 10
TRACE_LABELS = {
    "log_likelihood": "log-likelihood",
    "g_xy": r"$\gamma_{xy}$ (noise precision)",
    "g_s": r"$\gamma_s$ (code precision)",
    "g_x": r"$\gamma_x$ (atom precision, $D^x$)",
    "g_y": r"$\gamma_y$ (atom precision, $D^y$)",
    "g_nx": r"$\gamma_{nx}$ (noise precision of $x$)",
    "g_ny": r"$\gamma_{ny}$ (noise precision of $y$)",
    "active_atoms": "active atoms",
    "acceptance": "logit acceptance",
}
_PRECISIONS = ("g_xy", "g_s", "g_x", "g_y", "g_nx", "g_ny")


def with_convergence_columns(df):
    """``df`` with every :data:`CONVERGENCE_COLUMNS` column (NaN where absent), placed after the others."""
    df = df.copy()
    for c in CONVERGENCE_COLUMNS:
        if c not in df.columns:
            df[c] = math.nan
    return df[[c for c in df.columns if c not in CONVERGENCE_COLUMNS] + CONVERGENCE_COLUMNS]


# ------------------------------------------------------------------------------------------------- summaries
def _with_extra_columns(df):
    """``df`` with every :data:`EXTRA_CONVERGENCE_COLUMNS` column, NaN where the rows have none."""
    missing = [c for c in EXTRA_CONVERGENCE_COLUMNS if c not in df.columns]
    return df.assign(**dict.fromkeys(missing, math.nan)) if missing else df


def converged(g, threshold=RHAT_OK):
    """Per row: whether the split R-hat of the log-likelihood and of g_xy are both below ``threshold``."""
    return (g["r_hat_log_likelihood"] < threshold) & (g["r_hat_g_xy"] < threshold)


def convergence_summary_table(df):
    """Per (protocol, source, activity, n_train, method) with several chains: splits, chains, the largest
    R-hat over splits and the smallest bulk and tail ESS over splits of each series, the largest Monte Carlo
    standard error of each series over splits (NaN for rows without tail ESS or MCSE), and the fraction of splits
    whose R-hat of the log-likelihood and of g_xy are both below :data:`RHAT_OK` (``converged``) and below
    :data:`RHAT_STRICT` (``converged_strict``)."""
    df = _with_extra_columns(with_convergence_columns(df))
    d = df[df["n_chains"].fillna(1) > 1]
    keys = ["protocol", "source", "activity", "n_train", "method"]
    if d.empty:
        return pd.DataFrame(columns=keys)
    rows = []
    for key, g in d.groupby(keys, sort=True):
        r = dict(zip(keys, key))
        r["splits"] = len(g)
        r["chains"] = int(g["n_chains"].max())
        for n in CONVERGENCE_SERIES:
            r[f"r_hat_{n}"] = (
                float(g[f"r_hat_{n}"].max()) if g[f"r_hat_{n}"].notna().any() else math.nan
            )
            for stat in ("ess_bulk", "ess_tail"):
                c = g[f"{stat}_{n}"]
                r[f"{stat}_{n}"] = float(c.min()) if c.notna().any() else math.nan
            c = g[f"mcse_{n}"]
            r[f"mcse_{n}"] = float(c.max()) if c.notna().any() else math.nan
        r["converged"] = float(converged(g, RHAT_OK).mean())
        r["converged_strict"] = float(converged(g, RHAT_STRICT).mean())
        rows.append(r)
    return pd.DataFrame(rows)


def convergence_latex(df, *, labels):
    """LaTeX tables of the convergence per method, over the activities, one table per (protocol, N)."""
    df = _with_extra_columns(with_convergence_columns(df))
    d = df[df["n_chains"].fillna(1) > 1]
    if d.empty:
        return (
            r"\noindent No method was run with several chains, so no R-hat was computed "
            r"(set \nolinkurl{methods.<M>.chains} $\geq 2$, e.g.\ \nolinkurl{config/ablation.yaml})."
        )
    out = []
    for (protocol, n_train), dp in d.groupby(["protocol", "n_train"], sort=True):
        acts = ", ".join(sorted(set(dp["activity"])))
        caption = (
            rf"Convergence, protocol ``{escape(protocol)}'', $N={int(n_train)}$ (activities: "
            rf"{escape(acts)}): "
            r"largest split $\hat R$ over splits, smallest bulk and tail ESS over splits (across the chains of each "
            r"split) and largest Monte Carlo standard error (MCSE, degrees) of the test error over splits; "
            r"$\ell$: log-likelihood, err: test error of each retained sample; the last two columns: share of splits "
            rf"with $\hat R < {RHAT_STRICT}$ (Vehtari et al.\ 2021) and $< {RHAT_OK}$ for both $\ell$ and "
            r"$\gamma_{xy}$; --: not recorded (results written before tail ESS and MCSE were)."
        )
        head = [
            r"& & & & \multicolumn{4}{c}{$\hat R$ (largest)} & \multicolumn{2}{c}{bulk ESS} & "
            r"\multicolumn{2}{c}{tail ESS} & MCSE & \multicolumn{2}{c}{$\hat R <$} \\",
            r"\cmidrule(lr){5-8}\cmidrule(lr){9-10}\cmidrule(lr){11-12}\cmidrule(lr){14-15}",
            r"Method & $N$ & splits & chains & $\ell$ & $\gamma_{xy}$ & $\gamma_s$ & "
            rf"err & $\ell$ & err & $\ell$ & err & err & {RHAT_STRICT} & {RHAT_OK} \\",
        ]
        rows = []
        methods = list(dict.fromkeys(dp["method"]))
        for m in methods:
            for n, g in dp[dp["method"] == m].groupby("n_train", sort=True):

                def mx(c, g=g):
                    return float(g[c].max()) if g[c].notna().any() else math.nan

                def mn(c, g=g):
                    return float(g[c].min()) if g[c].notna().any() else math.nan

                rows.append(
                    [
                        escape(labels.get(m, m)),
                        str(int(n)),
                        str(len(g)),
                        str(int(g["n_chains"].max())),
                        fixed(mx("r_hat_log_likelihood")),
                        fixed(mx("r_hat_g_xy")),
                        fixed(mx("r_hat_g_s")),
                        fixed(mx("r_hat_test_error")),
                        fixed(mn("ess_bulk_log_likelihood"), 0),
                        fixed(mn("ess_bulk_test_error"), 0),
                        fixed(mn("ess_tail_log_likelihood"), 0),
                        fixed(mn("ess_tail_test_error"), 0),
                        fixed(mx("mcse_test_error"), 3),
                        percent(converged(g, RHAT_STRICT).mean()),
                        percent(converged(g, RHAT_OK).mean()),
                    ]
                )
        out += [
            table(
                rows,
                spec="@{}lrrrrrrrrrrrrrr@{}",
                head=head,
                caption=caption,
                tabcolsep="3pt",
            ),
            "",
        ]
    return "\n".join(out)


# --------------------------------------------------------------------------------------------------- figures
def chain_traces(arrays):
    """``{name: (chains, sweeps)}`` of a saved fit (``chain_trace_<name>`` of a pooled split, or
    ``trace_<name>`` of a one-chain fit), plus ``draw_error`` (chains, retained samples) if saved."""
    out = {}
    for k, v in arrays.items():
        if k.startswith("chain_trace_"):
            out[k[len("chain_trace_") :]] = np.atleast_2d(np.asarray(v, dtype=float))
    if not out:
        for k, v in arrays.items():
            if k.startswith("trace_") and np.asarray(v).ndim == 1:
                out[k[len("trace_") :]] = np.asarray(v, dtype=float)[None, :]
    if "chain_draw_error" in arrays:
        out["draw_error"] = np.atleast_2d(np.asarray(arrays["chain_draw_error"], dtype=float))
    return out


def _log_axis(ax):
    """A log y axis with plain tick labels (no superscripts, which print below 7 pt) spread over the whole range
    shown (:func:`bsrbench.reporting.plots.label_log_axis`)."""
    from .plots import label_log_axis

    label_log_axis(ax)


def _informative(a):
    """A trace worth a panel: finite values that are not the same constant in every chain."""
    f = a[np.isfinite(a)]
    return f.size > 0 and np.ptp(f) > 0


def plot_chain_traces(arrays, *, title, n_burn_in=None):
    """Per-sweep traces of every chain of a split, overlaid (one colour per chain), burn-in shaded.

    Panels: log-likelihood, the precisions (log axis), active atoms, logit acceptance and the test error of
    each retained sample, each only if it was recorded and is not constant (e.g. elliptical slice sampling
    always moves, so its acceptance is 1 and gets no panel). Returns the figure.
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    tr = chain_traces(arrays)
    if n_burn_in is None and "n_burn_in" in arrays:
        n_burn_in = int(arrays["n_burn_in"])
    order = ["log_likelihood", *_PRECISIONS, "active_atoms", "acceptance", "draw_error"]
    names = [n for n in order if n in tr and _informative(tr[n])]
    names += sorted(n for n in tr if n not in order and _informative(tr[n]))
    n = max(1, len(names))
    ncols = 2 if n > 1 else 1
    nrows = math.ceil(n / ncols)
    from .plots import TEXT_WIDTH

    fig = plt.figure(figsize=(TEXT_WIDTH, 1.75 * nrows + 0.5))
    gs = fig.add_gridspec(nrows, ncols)
    n_chains = max((a.shape[0] for a in tr.values()), default=0)
    for i, name in enumerate(names):
        r, c = divmod(i, ncols)
        span = slice(c, ncols) if (i == n - 1 and n % ncols) else slice(c, c + 1)
        ax = fig.add_subplot(gs[r, span])
        a = tr[name]
        for k in range(a.shape[0]):
            ax.plot(np.arange(a.shape[1]), a[k], lw=0.6, color=f"C{k % 10}", label=f"chain {k}")
        if name == "draw_error":
            ax.set_xlabel("retained sample")
            ax.set_ylabel("degrees", fontsize=7)
            ax.set_title("test error of each retained sample")
        else:
            if n_burn_in:
                ax.axvspan(0, n_burn_in, color="0.9", zorder=0)
                ax.axvline(n_burn_in, color="0.3", ls="--", lw=0.8)
            if name in _PRECISIONS and np.all(a[np.isfinite(a)] > 0):
                _log_axis(ax)
            if name == "active_atoms":  # a count: whole-number ticks only (not 62.5)
                ax.yaxis.set_major_locator(MaxNLocator(integer=True))
            ax.set_xlabel("Gibbs sweep")
            label = TRACE_LABELS.get(name, name.replace("_", " "))
            ax.set_title(label, fontsize=MATH_TITLE_PT if "$" in label else None)
        ax.grid(alpha=0.3)
    if n_chains > 1 and names:
        fig.axes[0].legend(fontsize=7, ncol=min(n_chains, 4), loc="best")
    if not names:
        ax = fig.add_subplot(gs[0, 0])
        ax.text(0.5, 0.5, "the fit saved no trace", ha="center", va="center")
        ax.set_axis_off()
    suffix = f"; {n_chains} chains" if n_chains > 1 else ""
    suffix += "; shaded: burn-in" if n_burn_in else ""
    fig.suptitle(title + suffix)
    fig.tight_layout()
    return fig


def gxy_panel(params, n_train):
    """What one panel of the g_xy figure shows: ``(K, "≥" or "<", prior)`` from a fit's ``params`` (dict) at
    ``n_train`` training pairs; ``prior`` is ``(a_xy, b_xy)`` of a proper Gamma prior on g_xy, or None (the
    paper's improper one)."""
    k = params.get("n_atoms", "?")
    rel = "≥" if isinstance(k, int) and k >= int(n_train) else "<"
    prior = None
    if params.get("a_xy") is not None:
        prior = (float(params["a_xy"]), float(params.get("b_xy", params.get("b0", 1e-6))))
    return k, rel, prior


def gxy_caption(df, methods, *, protocol, n_train, labels):
    """LaTeX caption of the g_xy figure, describing the panels drawn: one per method of ``methods``
    (``report.gxy_methods``), with its K against ``n_train`` and its prior, read from the ``params`` of its rows in
    the aggregate table ``df`` (protocol ``protocol``, ``n_train`` training pairs)."""
    parts = []
    for m in methods:
        rows = df[
            (df["method"] == m) & (df["protocol"] == protocol) & (df["n_train"] == int(n_train))
        ]
        params = (
            json.loads(rows["params"].iloc[0])
            if len(rows) and isinstance(rows["params"].iloc[0], str)
            else {}
        )
        k, rel, prior = gxy_panel(params, n_train)
        text = f"{escape(labels.get(m, m))}: "
        if k == "?":
            text += "$K$ unknown"
        else:
            op = "\\geq" if rel == "≥" else "<"
            text += f"$K = {k} {op} N = {int(n_train)}$"
            if rel == "≥":
                text += " (a code set can interpolate the training pairs)"
        if prior is not None:
            text += f", with a proper Gamma({prior[0]:g}, {prior[1]:g}) prior on $\\gamma_{{xy}}$"
        parts.append(text)
    what = f"the {len(parts)} methods" if len(parts) != 1 else "the method"
    return (
        "The noise precision $\\gamma_{xy}$ per chain (first activity, smallest $N$, first seed; log axis; "
        f"shaded: burn-in) of {what} of \\texttt{{report.gxy\\_methods}}: "
        + "; ".join(parts)
        + ". The panel titles repeat $K$ and $N$."
    )


def plot_gxy(items, *, n_burn_in=None):
    """The g_xy mechanism: g_xy traces (log axis, every chain) side by side, one panel per item.

    ``items``: list of (panel title, arrays of a saved fit). Returns the figure.
    """
    import matplotlib.pyplot as plt

    n = max(1, len(items))
    from .plots import TEXT_WIDTH

    fig, axes = plt.subplots(
        1, n, figsize=(min(TEXT_WIDTH, 2.5 * n + 0.8), 2.6), squeeze=False, sharey=True
    )
    for ax, (title, arrays) in zip(axes[0], items):
        tr = chain_traces(arrays).get("g_xy")
        burn = n_burn_in if n_burn_in is not None else int(arrays.get("n_burn_in", 0))
        if tr is None:
            ax.text(0.5, 0.5, "no g_xy trace", ha="center", va="center", transform=ax.transAxes)
            continue
        for k in range(tr.shape[0]):
            ax.plot(np.arange(tr.shape[1]), tr[k], lw=0.6, color=f"C{k % 10}")
        if burn:
            ax.axvspan(0, burn, color="0.9", zorder=0)
        _log_axis(ax)
        ax.set_title(title, fontsize=8)
        ax.set_xlabel("Gibbs sweep")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(r"$\gamma_{xy}$", fontsize=MATH_TITLE_PT)
    fig.suptitle(
        r"Noise precision $\gamma_{xy}$ per chain (log axis; shaded: burn-in)",
        fontsize=MATH_TITLE_PT,
    )
    fig.tight_layout()
    return fig


def saved_fit(df, path):
    """What the aggregate table ``df`` says of the fit saved at ``path``
    (``.../fit/{protocol}/{source}/{activity}/{method}/n{N}/seed{seed}.npz``): ``(key, params)``, ``key`` a dict of
    protocol, source, activity, method, n_train and seed (from the path), ``params`` the row's params ({} if the
    table has no row of it)."""
    path = Path(path)
    protocol, source, activity, method, n, seed = path.parts[-6:-1] + (path.stem,)
    key = dict(
        protocol=protocol,
        source=source,
        activity=activity,
        method=method,
        n_train=int(n[1:]),
        seed=int(seed[4:]),
    )
    row = df
    for k, v in key.items():
        row = row[row[k] == v]
    return key, (json.loads(row["params"].iloc[0]) if len(row) else {})


def trace_figure(df, path, *, labels):
    """The trace figure (:func:`plot_chain_traces`) of the fit saved at ``path``, titled with its method, data and
    split; the burn-in from the fit, else from its params in ``df``."""
    key, params = saved_fit(df, path)
    arrays = read_npz(path)
    label = labels.get(key["method"], key["method"])
    return plot_chain_traces(
        arrays,
        title=f"{label} on {key['source']}/{key['activity']}, N={key['n_train']}, seed {key['seed']}",
        n_burn_in=int(arrays["n_burn_in"]) if "n_burn_in" in arrays else params.get("n_burn_in"),
    )


def gxy_figure(df, paths, *, labels):
    """The g_xy figure (:func:`plot_gxy`) of the fits saved at ``paths``, one panel each, titled with the method,
    its K against N (:func:`gxy_panel`) and its proper prior if any."""
    items = []
    for path in paths:
        key, params = saved_fit(df, path)
        k, rel, prior = gxy_panel(params, key["n_train"])
        title = f"{labels.get(key['method'], key['method'])}: K={k} {rel} N={key['n_train']}"
        if prior is not None:
            title += f"\nGamma({prior[0]:g}, {prior[1]:g}) prior"
        items.append((title, read_npz(path)))
    return plot_gxy(items)
