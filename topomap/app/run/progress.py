"""Progress on a terminal: tqdm bars for the walk, the splits and the core's long loops, and the
learner's log lines (phase 1, every split)."""

from __future__ import annotations

import logging
import sys

log = logging.getLogger("topomap")

__all__ = ["Progress"]


class Progress:
    """Progress bars on a terminal (tqdm) and the learner's log lines."""

    def __init__(self, enabled: bool):
        self.enabled = bool(enabled)
        self._bars = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        for bar in self._bars:
            bar.close()

    def _bar(self, total, desc):
        from tqdm.auto import tqdm

        bar = tqdm(total=total, desc=desc, disable=not self.enabled, leave=False, file=sys.stderr,
                   dynamic_ncols=True)
        self._bars.append(bar)
        return bar

    def ticking(self, explorer, total: int):
        """``explorer``, ticking a "simulating" bar once per chosen action."""
        return _TickingExplorer(explorer, self._bar(total, "simulating"))

    def on_progress(self, stage: str, done: int, total: int | None) -> None:
        """A listener of the core's loops (:mod:`topomap.core.progress`): one bar per running
        loop (BIC, EM, held-out scoring, drawing the figures), closed when the loop ends."""
        bars = self.__dict__.setdefault("_stages", {})
        bar = bars.get(stage)
        if bar is not None and done < bar.n:  # the loop starts again (another EM round)
            bar.close()
            bar = None
        if bar is None:
            bar = bars[stage] = self._bar(total, stage)
        if total is not None and bar.total != total:
            bar.total = total
            bar.refresh()
        bar.update(done - bar.n)
        if total is not None and done >= total:
            bar.close()
            del bars[stage]

    def log_stages(self, stage: str, done: int, total: int | None) -> None:
        """A listener of the core's loops without a terminal: a log line when a loop starts
        and when it ends, with its time (BIC over the cluster counts, an EM fit, ...)."""
        import time

        started = self.__dict__.setdefault("_started", {})
        if stage not in started:
            started[stage] = time.perf_counter()
            log.info("%s: started", stage)
        if total is not None and done >= total:
            log.info("%s: done (%d steps, %.1f s)", stage, done,
                     time.perf_counter() - started.pop(stage))

    def on_event(self, event, info) -> None:
        """A learner callback: log phase 1, tick a "splitting" bar per split."""
        if event == "phase1":
            n = info["learner"].n_clusters_
            e = info["entropies"]
            log.info("phase 1: %d symbols + %d GDS states, H(o|x)=%.3f bits (differential entropy "
                     "of continuous observations: may be negative), H(u|x)=%.3f, "
                     "H(x'|x,u)=%.3f bits", n, info["map"].n_states - n, e["H_o"], e["H_u"], e["H_x"])
            self.splitting = self._bar(None, "splitting")
        elif event == "split":
            self.splitting.update(1)
            r = info["record"]
            log.debug("split %d: state %d -> %d (gain %.4f)", r["iteration"], r["state"],
                      r["new_state"], r["gain"])
        elif event == "done" and getattr(self, "splitting", None) is not None:
            self.splitting.close()


class _TickingExplorer:
    def __init__(self, explorer, bar):
        self.explorer, self.bar = explorer, bar

    def __getattr__(self, name):  # see / update / update_every of the explorer, when it has them
        return getattr(self.explorer, name)

    def choose(self, executable, rng):
        self.bar.update(1)
        return self.explorer.choose(executable, rng)
