"""A run's curves: the entropies after each split (the paper's Fig. 7) and the quality of the map
learned while exploring.  Each ``plot_*`` draws on the Axes it is given and returns it."""

from __future__ import annotations

import numpy as np

from .style import LEGEND_SIZE, TITLE_SIZE

__all__ = ["plot_entropy", "plot_mapping"]


#: the entropies' stages that replace the split's map: drawn apart, right of a dashed line,
#: with their line's label (a continuous log's places replace the split; a refinement refines it)
AFTER_SPLIT = {"refined": "refined", "places": "places"}


def _after_label(learner, stage: str) -> tuple[str, str]:
    """``(legend, title)`` of the map that replaced the split at ``stage``."""
    if stage == "refined":
        return "after the refinement", "then after the refinement"
    chosen = (getattr(learner, "motion_info_", None) or {}).get("chosen")
    what = "the view clusters" if chosen == "views" else "the places (views and motion)"
    return f"{what}, in place of the split", f"then {what}"


def plot_entropy(ax, learner):
    """H(u|x), H(x'|x,u) and their sum after phase 1 and after each split; after a refinement,
    or the places of a continuous log that replace the split's map (:data:`AFTER_SPLIT`), its
    values too, as open markers right of a dashed line labelled with the stage, at that map's
    number of states.  The y-axis spans every value drawn, the split's and the
    refinement's (its range is the data's, not 0, unless an entropy is 0).  The legend sits
    outside the Axes, so it never covers a curve.  Returns ``ax``."""
    from matplotlib.ticker import MaxNLocator

    entries = learner.entropies_
    e = [r for r in entries if r.get("stage") not in AFTER_SPLIT]
    refined = [r for r in entries if r.get("stage") in AFTER_SPLIT]
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
        values = {"sum": r["H_u"] + r["H_x"], "H(u|x)": r["H_u"], "H(x'|x,u)": r["H_x"]}
        drawn = [*(v for _, y, _, _ in curves for v in y), *values.values()]
        lo, hi = min(drawn), max(drawn)
        pad = 0.08 * max(hi - lo, 1e-6)
        ax.set_ylim(lo - pad, hi + pad)
        x = max(it) + max(1.0, 0.06 * (max(it) - min(it)))  # right of the split's last point
        ax.axvline((x + max(it)) / 2, color="0.4", ls="--", lw=0.8)
        legend, then = _after_label(learner, r["stage"])
        ax.text((x + max(it)) / 2, hi + pad, f" {AFTER_SPLIT[r['stage']]}", rotation=90,
                va="top", ha="right", fontsize=LEGEND_SIZE, color="0.3")
        for label, _, marker, colour in curves:  # the sum larger: it shows round a value it meets
            ax.plot([x], [values[label]], marker=marker, ms=9 if label == "sum" else 6,
                    mfc="white", mec=colour, ls="none")
        ax.plot([], [], marker="o", ms=5, mfc="white", mec="0.3", ls="none",
                label=f"{legend} ({r['n_states']} states)")
        ax.set_xlim(right=x + 0.5 * (x - max(it)) + 0.5)
        title += f", {then}"
    ax.legend(fontsize=LEGEND_SIZE, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.set_title(title, fontsize=TITLE_SIZE)
    return ax


def _explorer_name(label: str) -> str:
    """The explorer as the title names it: ``explorer=<component>`` as the run chose it
    (``explorer=active``), else the class name out of its ``repr``."""
    if label.startswith("explorer="):
        return label
    return label.partition("(")[0].strip()


def plot_mapping(ax, curve, label=""):
    """The quality of the map learned while exploring, after every update: its ARI on the
    held-out random walk (``heldout_ari``, the fair judge: :mod:`topomap.worlds.mapping`), and,
    thinner, on the steps taken so far (``ari``, which flatters an explorer that stays in a
    small part of the world); ``label`` names the explorer in the title (``explorer=active``
    as the run chose it; a ``repr``: its class).  The legend sits below the Axes, clear of the curves and the ticks.  Returns ``ax``."""
    steps = [c["steps"] for c in curve]
    lows = [c["ari"] for c in curve]
    if all("heldout_ari" in c for c in curve):
        held = [c["heldout_ari"] for c in curve]
        lows += held
        ax.plot(steps, held, marker="o", ms=3.5, lw=1.6, color="tab:blue",
                label="on a held-out random walk (heldout_ari)")
    ax.plot(steps, [c["ari"] for c in curve], marker=".", lw=0.9, ls="--", color="0.45",
            label="on the steps taken so far (ari)")
    ax.set_xlabel("steps taken")
    ax.set_ylabel("ARI of the map learned so far")
    ax.set_ylim(min(0.0, min(lows)), 1.02)
    ax.grid(alpha=0.3)
    name = _explorer_name(label)
    ax.set_title("mapping while exploring" + (f": {name}" if name else ""), fontsize=TITLE_SIZE)
    ax.legend(fontsize=LEGEND_SIZE, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=1,
              frameon=False)
    return ax
