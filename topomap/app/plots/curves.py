"""A run's curves: the entropies after each split (the paper's Fig. 7) and the quality of the map
learned while exploring.  Each ``plot_*`` draws on the Axes it is given and returns it."""

from __future__ import annotations

import numpy as np

from .style import LEGEND_SIZE, TITLE_SIZE

__all__ = ["plot_entropy", "plot_mapping"]


def plot_entropy(ax, learner):
    """H(u|x), H(x'|x,u) and their sum after phase 1 and after each split; after a refinement
    its values too, as open markers right of a dashed line labelled "refined", at the refined
    map's number of states.  The y-axis spans the split's curves (its range is the data's, not
    0): a refined value beyond it is drawn on the axis' edge, an arrow pointing its way, with
    its value written beside.  The legend sits outside the Axes, so it never covers a curve.
    Returns ``ax``."""
    from matplotlib.ticker import MaxNLocator

    entries = learner.entropies_
    e = [r for r in entries if r.get("stage") != "refined"]
    refined = [r for r in entries if r.get("stage") == "refined"]
    it = [r["n_states"] for r in e]
    hu = np.array([r["H_u"] for r in e])
    hx = np.array([r["H_x"] for r in e])
    curves = (("sum", hu + hx, "^", "k"), ("H(u|x)", hu, "o", "tab:blue"),
              ("H(x'|x,u)", hx, "s", "tab:orange"))
    for label, y, marker, colour in curves:
        ax.plot(it, y, marker=marker, ls="-", ms=3, color=colour, label=label)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("number of states (phase 1, then one more per split)")
    ax.set_ylabel("bits")
    ax.grid(alpha=0.3)
    title = "entropies after each split"
    if refined:
        r = refined[-1]
        lo = min(float(np.min(y)) for _, y, _, _ in curves)
        hi = max(float(np.max(y)) for _, y, _, _ in curves)
        pad = 0.08 * max(hi - lo, 1e-6)
        ax.set_ylim(lo - pad, hi + pad)
        x = max(it) + max(1.0, 0.06 * (max(it) - min(it)))  # right of the split's last point
        ax.axvline((x + max(it)) / 2, color="0.4", ls="--", lw=0.8)
        ax.text((x + max(it)) / 2, hi + pad, " refined", rotation=90, va="top", ha="right",
                fontsize=LEGEND_SIZE, color="0.3")
        values = {"sum": r["H_u"] + r["H_x"], "H(u|x)": r["H_u"], "H(x'|x,u)": r["H_x"]}
        for label, _, marker, colour in curves:
            v = values[label]
            if lo - pad <= v <= hi + pad:
                ax.plot([x], [v], marker=marker, ms=6, mfc="white", mec=colour, ls="none")
            else:
                edge = lo - pad if v < lo else hi + pad
                ax.plot([x], [edge], marker="v" if v < lo else "^", ms=6, color=colour,
                        ls="none", clip_on=False)
                ax.annotate(f"{v:.2f}", (x, edge), xytext=(4, 6 if v < lo else -10),
                            textcoords="offset points", fontsize=LEGEND_SIZE, color=colour)
        ax.plot([], [], marker="o", ms=5, mfc="white", mec="0.3", ls="none",
                label=f"after the refinement ({r['n_states']} states)")
        ax.set_xlim(right=x + 0.5 * (x - max(it)) + 0.5)
        title += ", then after the refinement"
    ax.legend(fontsize=LEGEND_SIZE, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.set_title(title, fontsize=TITLE_SIZE)
    return ax


def plot_mapping(ax, curve, label=""):
    """The online map's ARI against the steps taken (``metrics.json``: ``mapping.curve``)."""
    steps = [c["steps"] for c in curve]
    ax.plot(steps, [c["ari"] for c in curve], marker=".", label=label or None)
    ax.set_xlabel("steps taken")
    ax.set_ylabel("ARI of the map learned so far")
    ax.set_ylim(min(0.0, min(c["ari"] for c in curve)), 1.02)
    ax.set_title("mapping while exploring", fontsize=TITLE_SIZE)
    if label:
        ax.legend(fontsize=LEGEND_SIZE, loc="lower right")
    return ax
