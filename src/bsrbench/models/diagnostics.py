"""MCMC diagnostics for :class:`bsrbench.models.bsr.BayesianSR` fits.

Each fit records one value per sweep of the scalar traces in ``trace_`` (log-likelihood, g_xy, g_s, g_x, g_y,
active atoms, acceptance). :func:`chain_summary` gives the bulk/tail effective sample size and the rank-normalized
split R-hat (Vehtari, Gelman, Simpson, Carpenter & Buerkner 2021, as implemented by ArviZ) over one or several
chains (fits of the same data with different seeds); :func:`plot_traces` draws them.
"""

import warnings

import numpy as np

from ..errors import InputError
from ..io import atomic_path

SCALAR_TRACES = ("log_likelihood", "g_xy", "g_s", "g_x", "g_y", "active_atoms", "acceptance")


def _as_traces(obj):
    """A list of trace dicts from an estimator, a trace dict, or a list of either."""
    items = obj if isinstance(obj, (list, tuple)) else [obj]
    out = []
    for i, item in enumerate(items):
        tr = getattr(item, "trace_", item)
        if not isinstance(tr, dict) or not tr:
            raise InputError(
                f"chain {i}: expected a fitted BayesianSR or a dict of per-sweep traces; got {type(item)}"
            )
        out.append(tr)
    return out


def _stack(traces, name, burn_in):
    arrs = [np.asarray(tr[name], dtype=float) for tr in traces]
    n = min(a.shape[0] for a in arrs)
    if n - burn_in < 4:
        raise InputError(
            f"trace {name!r}: need at least 4 sweeps after burn_in={burn_in}; got {n - burn_in}"
        )
    return np.stack([a[burn_in:n] for a in arrs])  # (chain, draw)


def chain_summary(estimators_or_traces, burn_in=None, names=SCALAR_TRACES):
    """ESS (bulk, tail) and split R-hat of each scalar trace after burn-in, across chains.

    ``burn_in`` defaults to the estimators' ``n_burn_in`` (0 for plain trace dicts). With one chain R-hat is the
    split R-hat of its two halves. Returns a pandas DataFrame indexed by trace name with columns ``mean``, ``sd``,
    ``ess_bulk``, ``ess_tail``, ``r_hat``, ``n_chains``, ``n_draws``.
    """
    import arviz as az
    import pandas as pd

    items = (
        estimators_or_traces
        if isinstance(estimators_or_traces, (list, tuple))
        else [estimators_or_traces]
    )
    traces = _as_traces(items)
    if burn_in is None:
        burn_in = min(int(getattr(it, "n_burn_in", 0)) for it in items)
    rows = {}
    for name in names:
        if not all(name in tr for tr in traces):
            continue
        x = _stack(traces, name, int(burn_in))
        with warnings.catch_warnings():
            warnings.simplefilter(
                "ignore"
            )  # constant traces (e.g. ESS acceptance = 1) give NaN, on purpose
            ds = az.convert_to_dataset(x)  # (chain, draw) -> variable "x"
            ess_b = float(az.ess(ds, method="bulk")["x"].values)
            ess_t = float(az.ess(ds, method="tail")["x"].values)
            rhat = float(az.rhat(ds)["x"].values)
        rows[name] = {
            "mean": float(x.mean()),
            "sd": float(x.std()),
            "ess_bulk": ess_b,
            "ess_tail": ess_t,
            "r_hat": rhat,
            "n_chains": x.shape[0],
            "n_draws": x.shape[1],
        }
    return pd.DataFrame.from_dict(rows, orient="index")


def plot_traces(estimators_or_traces, path_or_ax=None, names=SCALAR_TRACES, burn_in=None):
    """Plot each scalar trace against the sweep number, one panel per trace, one line per chain.

    ``path_or_ax``: a file path (written atomically; the figure is closed), an array of matplotlib axes (one per
    trace), or None (returns the figure). A dashed line marks ``burn_in`` (default: the estimators' n_burn_in).
    """
    import matplotlib

    items = (
        estimators_or_traces
        if isinstance(estimators_or_traces, (list, tuple))
        else [estimators_or_traces]
    )
    traces = _as_traces(items)
    names = [n for n in names if all(n in tr for tr in traces)]
    if burn_in is None:
        burn_in = min(int(getattr(it, "n_burn_in", 0)) for it in items)
    fig = None
    if (
        path_or_ax is None
        or isinstance(path_or_ax, (str, bytes))
        or hasattr(path_or_ax, "__fspath__")
    ):
        if path_or_ax is not None:
            matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(
            len(names), 1, figsize=(7, 1.6 * len(names)), sharex=True, squeeze=False
        )
        axes = axes[:, 0]
    else:
        axes = np.ravel(path_or_ax)
        if axes.size < len(names):
            raise InputError(f"path_or_ax: need {len(names)} axes, one per trace; got {axes.size}")
    for ax, name in zip(axes, names):
        for c, tr in enumerate(traces):
            ax.plot(np.asarray(tr[name]), lw=0.7, label=f"chain {c}")
        if burn_in:
            ax.axvline(burn_in, color="k", ls="--", lw=0.7)
        ax.set_ylabel(name.replace("_", " "), fontsize=8)
    axes[len(names) - 1].set_xlabel("sweep")
    if len(traces) > 1:
        axes[0].legend(fontsize=7, ncol=min(len(traces), 4))
    if fig is not None and path_or_ax is not None:
        import matplotlib.pyplot as plt

        fig.tight_layout()
        with atomic_path(path_or_ax) as tmp:
            fig.savefig(tmp)
        plt.close(fig)
        return None
    return fig
