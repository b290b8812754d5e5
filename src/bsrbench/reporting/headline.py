"""The README's headline statements, computed from the published tables so that they cannot drift from the numbers.

:func:`verdict_markdown` is the table of the verdict across cells and activities (:mod:`.verdict`);
:func:`findings_markdown` the paragraph under it (the paper's claim, the per-cell tests with the question each
answers, joint positions); :func:`notes_markdown` the notes of ``docs/results.md`` on joint positions and on a mean
NLPD that one split dominates. ``python -m bsrbench.reporting.published readme ... --update`` writes them between
the markers ``<!-- verdict -->``, ``<!-- findings -->`` and ``<!-- notes -->`` of the file.
"""

import os
import re
import stat
from pathlib import Path

import numpy as np

from ..errors import DataFileError
from ..io import atomic_path
from ..paper import PAPER_METHODS
from . import comparisons as cmp
from .tables import paper_names
from .verdict import UNITS, p_text

#: The README's blocks generated here, by marker name.
MARKERS = ("verdict", "findings", "notes")
UNIT_WORDS = {
    "cell": "(source, activity, N) cells",
    "motion": "distinct motions",
}
UNIT_PLURAL = {"cell": "cells", "motion": "motions"}


def _label(labels, m):
    return labels.get(m, m)


def _against(v, unit, scope, pm):
    g = v[(v["unit"] == unit) & (v["scope"] == scope)]
    return g, g[g["versus"] == pm]


def verdict_markdown(v, *, labels, pm="PM", alpha=cmp.ALPHA):
    """Markdown table of the verdict (:func:`.verdict.verdict` of one protocol): per unit and scope, the blocks,
    Friedman's chi2 and p, the Iman-Davenport F and p, PM's mean rank of k with the Nemenyi critical difference,
    and against how many of the other methods PM is worse by the Wilcoxon signed-rank test (Holm, p < ``alpha``),
    two-sided and one-sided, with the largest Holm p; and its legend."""
    head = (
        "| blocks | scope | n | Friedman chi2 (df), p | Iman-Davenport F, p | PM mean rank (CD) "
        "| PM worse than (two-sided) | PM worse than (one-sided) |"
    )
    lines = [head, "|" + "---|" * 8]
    for unit in UNITS:
        for scope in dict.fromkeys(v.loc[v["unit"] == unit, "scope"]):
            g, a = _against(v, unit, scope, pm)
            if g.empty:
                continue
            r = g.iloc[0]
            k = int(r["n_methods"])
            fr = (
                f"{r['friedman_chi2']:.1f} ({k - 1}), {p_text(r['friedman_p'])}"
                if np.isfinite(r["friedman_p"])
                else "no test"
            )
            idf = (
                f"{r['iman_davenport_f']:.1f}, {p_text(r['iman_davenport_p'])}"
                if np.isfinite(r["iman_davenport_p"])
                else "no test"
            )
            pm_row = g[g["method"] == pm]
            rank = (
                f"{float(pm_row['mean_rank'].iloc[0]):.2f} of {k} ({r['nemenyi_cd']:.2f})"
                if len(pm_row) and np.isfinite(r["nemenyi_cd"])
                else (f"{float(pm_row['mean_rank'].iloc[0]):.2f} of {k}" if len(pm_row) else "--")
            )
            sides = []
            for col in ("p_wilcoxon_holm", "p_wilcoxon_worse_holm"):
                tested = a[np.isfinite(a[col])]
                worse = tested[(tested[col] < alpha) & (tested["mean_diff"] > 0)]
                if tested.empty:
                    sides.append("no test")
                    continue
                sides.append(
                    f"{len(worse)} of {len(a)} (largest p {p_text(float(tested[col].max()))})"
                )
            lines.append(
                f"| {UNIT_PLURAL[unit]} | {scope} | {int(r['n_blocks'])} | {fr} | {idf} | {rank} | {sides[0]} | {sides[1]} |"
            )
    lines += [
        "",
        "The blocks are the study's data sets: each (source, activity, N) cell, or each distinct motion with its "
        "cells averaged (the conservative unit: the cells of a motion share its frames, and the authors' "
        "features and ours of the same CMU trials are one motion, key `motion` of config/datasets.yaml). "
        "Friedman test over the methods with the Iman-Davenport F; mean rank 1 is the best, CD the Nemenyi "
        "critical difference of the mean ranks (alpha = 0.05); PM against each other method: Wilcoxon "
        "signed-rank test of the blocks' differences, Holm-adjusted over the comparisons, p < 0.05 (one-sided: "
        "PM worse). With b blocks and m comparisons the smallest Holm-adjusted one-sided p is m 2^-b. Computed "
        "by `bsrbench.reporting.verdict` (reports/published/paper-verdict.csv).",
    ]
    effects = effects_markdown(v, labels=labels, pm=pm, alpha=alpha)
    return "\n".join(lines + ([""] + effects if effects else []))


def effects_markdown(v, *, labels, pm="PM", alpha=cmp.ALPHA):
    """Lines of a markdown table of PM's mean excess error over the distinct motions (all sources) against each
    method, with its bootstrap interval over the motions and the motions where PM is worse, and its legend; []
    without a motion block of PM."""
    from .verdict import smallest_p

    scope = "all" if (v["scope"] == "all").any() else (v["scope"].iloc[0] if len(v) else None)
    g, a = _against(v, "motion", scope, pm)
    if a.empty:
        return []
    b = int(g["n_blocks"].iloc[0])
    lines = [
        f"| {pm} against | mean excess error over the {b} motions (deg) | 95% bootstrap interval | motions where "
        f"{pm} is worse |",
        "|---|---|---|---|",
    ]
    for _, r in a.sort_values("mean_diff").iterrows():
        ci = (
            f"{r['diff_ci_low']:+.2f} to {r['diff_ci_high']:+.2f}"
            if np.isfinite(r["diff_ci_low"])
            else "no interval (fewer than 3 motions)"
        )
        lines.append(
            f"| {_label(labels, r['method'])} | {r['mean_diff']:+.2f} | {ci} | "
            f"{int(r['versus_worse_blocks'])} of {b} |"
        )
    m = len(a)
    floor = smallest_p(b, m)
    reach = (
        f"so no comparison can reach p < {alpha} however large the difference"
        if floor >= alpha
        else f"so a comparison reaches p < {alpha} only when {pm} is worse in nearly every motion"
    )
    lines += [
        "",
        f"Across the {b} distinct motions ({scope}): {pm}'s error minus the method's, averaged over the motions "
        f"(positive: {pm} worse), with a percentile bootstrap interval over the motions (10,000 resamples of the "
        f"{b} motions, seed 0). What {b} motions can show: the smallest Holm-adjusted one-sided Wilcoxon p over "
        f"{m} comparisons is {m} x 2^-{b} = {p_text(floor)}, {reach}; the interval shows the size and its "
        f"uncertainty, under the assumption that these "
        f"motions stand for motions like them (a bootstrap over {b} blocks is itself rough).",
    ]
    return lines


def _cells(df, protocol):
    d = df[df["protocol"] == protocol]
    return d.groupby(["source", "activity", "n_train", "method"])["error"].mean().unstack("method")


def findings_markdown(
    df, comp, v, *, labels, pm="PM", nn="NN1", protocol="random", alpha=cmp.ALPHA
):
    """The README's paragraph of findings, each number computed from the results ``df``, the comparisons ``comp``
    and the verdict ``v`` of ``protocol``."""
    L = lambda m: _label(labels, m)  # noqa: E731
    w = _cells(df, protocol)
    out = []
    # the verdict in one sentence, at the level of cells and of motions
    g, a = _against(v, "cell", "all", pm) if (v["scope"] == "all").any() else (None, None)
    if g is None or g.empty:
        scope = v["scope"].iloc[0] if len(v) else None
        g, a = _against(v, "cell", scope, pm) if scope else (v.iloc[0:0], v.iloc[0:0])
    if len(g) and (not len(a) or not np.isfinite(a["p_wilcoxon_holm"]).any()):
        r = g.iloc[0]
        out.append(
            f"With {int(r['n_blocks'])} complete {UNIT_WORDS['cell']}, no test across the cells is possible "
            f"({r['note'] or 'no comparison with ' + pm})."
        )
    elif len(g):
        r = g.iloc[0]
        pm_rank = float(g.loc[g["method"] == pm, "mean_rank"].iloc[0])
        worse = a[(a["p_wilcoxon_holm"] < alpha) & (a["mean_diff"] > 0)]
        text = (
            f"Across the {int(r['n_blocks'])} {UNIT_WORDS['cell']}, the Friedman test rejects equal "
            f"errors of the {int(r['n_methods'])} methods (chi2 = {r['friedman_chi2']:.1f}, "
            f"p = {p_text(r['friedman_p'])}); {pm}'s mean rank is {pm_rank:.2f} of {int(r['n_methods'])} "
            f"(critical difference {r['nemenyi_cd']:.2f}), and {pm} is worse than {len(worse)} of the "
            f"{len(a)} other methods by the Wilcoxon signed-rank test across the cells (Holm, largest p "
            f"{p_text(float(a['p_wilcoxon_holm'].max()))}"
        )
        hi = a["p_wilcoxon_holm"].idxmax()
        text += f", against {L(a.loc[hi, 'method'])})."
        ga, aa = _against(v, "motion", r["scope"], pm)
        if len(aa):
            from .verdict import smallest_p

            wa = aa[(aa["p_wilcoxon_worse_holm"] < alpha) & (aa["mean_diff"] > 0)]
            b = int(ga["n_blocks"].iloc[0])
            worse_all = int((aa["versus_worse_blocks"] == b).sum())
            text += (
                f" With the {b} {UNIT_WORDS['motion']} as the blocks, {pm} is worse than {len(wa)} of "
                f"{len(aa)} one-sided (Holm, largest p {p_text(float(aa['p_wilcoxon_worse_holm'].max()))}): "
                f"{b} blocks and {len(aa)} comparisons allow no Holm-adjusted p below "
                f"{p_text(smallest_p(b, len(aa)))}; {pm}'s error is higher than the method's in every motion for "
                f"{worse_all} of the {len(aa)} methods (effect sizes below)."
            )
        out.append(text)
    # the paper's claim: PM better than its four baselines
    names = paper_names(df)
    paper_base = sorted(
        (m for m in w.columns if names.get(m) in PAPER_METHODS and names.get(m) != "PM"),
        key=lambda m: PAPER_METHODS.index(names[m]),
    )
    if pm in w.columns and paper_base:
        beats = w[paper_base].gt(w[pm], axis=0)
        all_four = int(beats.all(axis=1).sum())
        some = beats[beats.any(axis=1)]
        text = (
            f"The paper's claim does not hold here: {pm} has a lower mean error than all of "
            f"{', '.join(L(m) for m in paper_base)} at once in {all_four} of the {len(w)} cells"
        )
        if len(some):
            where = [
                f"{s} {act.replace('_', ' ')} N = {int(n)} (than {', '.join(L(m) for m in paper_base if row[m])})"
                for (s, act, n), row in some.iterrows()
            ]
            text += f", and than at least one of them in {len(some)}: " + "; ".join(where)
        if nn in w.columns:
            nn_beat = w[w[pm] < w[nn]]
            ns = sorted({int(n) for _, _, n in nn_beat.index})
            text += f". It beats {L(nn)} in {len(nn_beat)} cells" + (
                f" (N = {', '.join(map(str, ns))})" if ns else ""
            )
        out.append(text + ".")
    # the per-cell tests, each with its question
    t = cmp.pm_counts(comp[comp["protocol"] == protocol], pm=pm, nn=nn)
    parts = []
    for r in t.itertuples(index=False):
        opp = "the cell's best method" if r.versus == "best" else L(r.versus)
        parts.append(
            f"{r.source}: worse than {opp} in {r.worse} of {r.cells} cells on these frames "
            f"({r.worse_corrected} by the corrected test)"
        )
    if parts:
        out.append(
            "Per cell, the paired t-test over the splits asks whether a method is better on the cell's frames "
            "(the splits are independent draws of a training set from them); the corrected resampled t-test of "
            "Nadeau and Bengio asks about a new data set of independent frames, which the frames of one motion "
            "are not, and is reported as a sensitivity: "
            + "; ".join(parts)
            + " (Holm over each cell's comparisons, p < 0.05). Neither generalises beyond the motion; the tests "
            "across the distinct motions above ask about motions like these, and their effect sizes answer it "
            "where the number of motions leaves the tests no power."
        )
    # joint positions
    if "mpjpe_mm" in df.columns:
        d = df[df["protocol"] == protocol]
        mp = d.groupby(["source", "method"])["mpjpe_mm"].mean().dropna()
        bits = []
        for s in dict.fromkeys(d["source"]):
            if (s, pm) not in mp.index:
                continue
            ms = mp.xs(s, level="source").sort_values(ascending=False)
            rank = list(ms.index).index(pm) + 1
            others = ms.drop(pm)
            word = "the highest" if rank == 1 else f"the {_ordinal(rank)} highest"
            bit = f"{word} on {s} ({ms[pm]:.1f} mm; the others {others.min():.1f}-{others.max():.1f} mm"
            if rank > 1:
                above = ", ".join(f"{L(m)} {ms[m]:.1f}" for m in ms.index[: rank - 1])
                bit += f"; above it: {above}"
            bits.append(bit + ")")
        if bits:
            out.append(f"{pm}'s mean joint-position error (MPJPE) is " + " and ".join(bits) + ".")
    return "\n".join(f"- {x}" for x in out)


def _ordinal(n):
    return {2: "second", 3: "third", 4: "fourth"}.get(n, f"{n}th")


def notes_markdown(df, *, labels, protocol="random", share=0.5):
    """Notes for docs/results.md: per source and method with a mean NLPD, the split whose NLPD is more than
    ``share`` of the sum (it then dominates the mean), named with its NLPD and share."""
    L = lambda m: _label(labels, m)  # noqa: E731
    if "nlpd" not in df.columns:
        return ""
    d = df[(df["protocol"] == protocol) & np.isfinite(df["nlpd"])]
    out = []
    for (s, m), g in d.groupby(["source", "method"], sort=True):
        total = float(g["nlpd"].sum())
        top = g.loc[g["nlpd"].idxmax()]
        if total > 0 and float(top["nlpd"]) > share * total and len(g) > 1:
            out.append(
                f"- {L(m)}'s mean NLPD on {s} ({g['nlpd'].mean():.1e}) comes from one split: "
                f"{s} {top['activity'].replace('_', ' ')}, N = {int(top['n_train'])}, seed {int(top['seed'])} "
                f"(NLPD {float(top['nlpd']):.1e}, {100 * float(top['nlpd']) / total:.2f}% of the sum over "
                f"its {len(g)} splits); its median NLPD is {g['nlpd'].median():.2f}."
            )
    return "\n".join(out) if out else "- No mean NLPD is dominated by one split."


def check_update_target(path, what="the update"):
    """Refuse ``path`` as a file that ``--update`` rewrites, before anything is written: DataFileError naming it
    if it is a symbolic link (the atomic rename that writes it would put a regular file in the link's place) or a
    read-only file (the rename would replace it all the same). ``what``: what would replace it, as the message
    says (e.g. "the merge")."""
    path = Path(path)
    if path.is_symlink():
        raise DataFileError(
            path,
            f"is a symbolic link (to {os.readlink(path)!r}); expected a regular file ({what} would replace "
            "the link by a copy): name the file it points to",
        )
    if not path.is_file():
        return  # a missing file or a folder: refused when read
    mode = path.stat().st_mode
    if not os.access(path, os.W_OK) or not mode & stat.S_IWUSR:
        raise DataFileError(
            path,
            f"is read-only (mode {stat.S_IMODE(mode):o}); expected a writable file ({what} would replace "
            "it): make it writable first",
        )


def write_update(path, text):
    """Write ``text`` to the file ``path`` of ``--update`` (:func:`check_update_target`), by atomic rename:
    DataFileError naming ``path`` if it is refused or cannot be written (it is then unchanged)."""
    check_update_target(path)
    try:
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise DataFileError(path, f"cannot write the updated file ({exc.strerror or exc})") from exc


def update_blocks(path, blocks, required=None):
    """Replace the text between ``<!-- name -->`` and ``<!-- /name -->`` for each ``name: text`` of ``blocks``
    present in ``path``; returns the names written. DataFileError naming ``path`` if it is refused
    (:func:`check_update_target`), cannot be read or written, or lacks the markers of a name in ``required``
    (``{name: what the block is}``); the file is then unchanged."""
    path = Path(path)
    check_update_target(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(path, f"cannot read the file to update ({exc})") from exc
    written = []
    for name, block in blocks.items():
        pat = re.compile(rf"(<!-- {re.escape(name)} -->\n).*?(\n<!-- /{re.escape(name)} -->)", re.S)
        if pat.search(text):
            text = pat.sub(lambda m, b=block: m.group(1) + b + m.group(2), text)
            written.append(name)
        elif name in (required or {}):
            raise DataFileError(
                path, f"no markers '<!-- {name} -->' ... '<!-- /{name} -->' for {required[name]}"
            )
    write_update(path, text)
    return written


def blocks(df, comp, v, *, labels, protocol="random"):
    """The generated blocks by marker name (:data:`MARKERS`)."""
    vp = v[v["protocol"] == protocol]
    return {
        "verdict": verdict_markdown(vp, labels=labels),
        "findings": findings_markdown(df, comp, vp, labels=labels, protocol=protocol),
        "notes": notes_markdown(df, labels=labels, protocol=protocol),
    }


__all__ = [
    "MARKERS",
    "blocks",
    "check_update_target",
    "findings_markdown",
    "notes_markdown",
    "p_text",
    "update_blocks",
    "verdict_markdown",
    "write_update",
]
