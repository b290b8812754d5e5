"""MCMC convergence diagnostics of the chains of one split, computed with ArviZ.

Rank-normalized split R-hat, bulk and tail effective sample size and the Monte Carlo standard error of the mean
(Vehtari, Gelman, Simpson, Carpenter & Buerkner 2021, as ``arviz.summary(kind="diagnostics")`` computes them).
"""

import math
import warnings

import numpy as np

from .errors import InputError

#: Scalar per-sweep traces a BayesianSR fit records in ``trace_``.
SCALAR_TRACES = ("log_likelihood", "g_xy", "g_s", "g_x", "g_y", "active_atoms", "acceptance")
#: Per-sweep traces whose diagnostics across chains go into the result row of a split (those a method does not
#: record are skipped), plus ``test_error``: the test error of each retained posterior sample (from the
#: estimator's ``predict_draws``, when it has one).
CONVERGENCE_TRACES = ("log_likelihood", "g_xy", "g_s", "g_nx", "g_ny")
CONVERGENCE_SERIES = CONVERGENCE_TRACES + ("test_error",)
#: The result row's columns per series: ``<stat>_<series>``.
CONVERGENCE_STATS = ("r_hat", "ess_bulk", "ess_tail", "mcse")


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
    """ESS (bulk, tail), split R-hat and MCSE of the mean of each scalar trace after burn-in, across chains.

    ``estimators_or_traces``: fitted estimators with ``trace_`` or trace dicts, one per chain (chains are
    cut to the shortest). ``burn_in`` defaults to the estimators' ``n_burn_in`` (0 for plain trace dicts).
    With one chain R-hat is the split R-hat of its two halves. Returns a pandas DataFrame indexed by trace
    name with columns ``mean``, ``sd``, ``ess_bulk``, ``ess_tail``, ``r_hat``, ``mcse``, ``n_chains``,
    ``n_draws``.
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
            warnings.simplefilter("ignore")  # a constant trace gives NaN, on purpose
            s = az.summary(az.convert_to_dataset(x), kind="diagnostics", round_to="none")
        rows[name] = {
            "mean": float(x.mean()),
            "sd": float(x.std()),
            "ess_bulk": float(s.at["x", "ess_bulk"]),
            "ess_tail": float(s.at["x", "ess_tail"]),
            "r_hat": float(s.at["x", "r_hat"]),
            "mcse": float(s.at["x", "mcse_mean"]),
            "n_chains": x.shape[0],
            "n_draws": x.shape[1],
        }
    return pd.DataFrame.from_dict(rows, orient="index")


def convergence_summary(chains):
    """The diagnostics of :data:`CONVERGENCE_STATS` for every series of :data:`CONVERGENCE_SERIES`.

    ``chains``: chain dicts of :func:`bsrbench.runs.run_chain`. The per-sweep traces of
    :data:`CONVERGENCE_TRACES` are used after each chain's burn-in; ``test_error`` is the series of
    per-retained-sample test errors (``draw_error``). Returns ``{"<stat>_<series>": float}``, NaN where the
    series was not recorded, with fewer than 2 chains, or with fewer than 4 draws per chain.
    """
    out = {f"{stat}_{name}": math.nan for name in CONVERGENCE_SERIES for stat in CONVERGENCE_STATS}
    if len(chains) < 2:
        return out
    burn_in = min(int(c.get("n_burn_in", 0)) for c in chains)
    series = {}
    for name in CONVERGENCE_TRACES:
        if all(f"trace_{name}" in c for c in chains):
            arrs = [np.asarray(c[f"trace_{name}"], dtype=float) for c in chains]
            if min(a.size for a in arrs) - burn_in >= 4:
                series[name] = [a[burn_in:] for a in arrs]
    if (
        all("draw_error" in c for c in chains)
        and min(np.size(c["draw_error"]) for c in chains) >= 4
    ):
        series["test_error"] = [np.asarray(c["draw_error"], dtype=float) for c in chains]
    for name, arrs in series.items():
        s = chain_summary([{name: a} for a in arrs], burn_in=0, names=(name,))
        for stat in CONVERGENCE_STATS:
            out[f"{stat}_{name}"] = float(s.at[name, stat])
    return out
