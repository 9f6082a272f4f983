"""A static picture of one run (``circsim run --png REPORT.png``), for a page or a paper where the rerun
recording cannot go: the merged map each robot held last, every robot's map in its colour; each robot's
first correct merge of every teammate's map; ν over time of every robot's merge cycles, accepted and
refused, false merges marked.

:class:`RunReport` is a run observer: it keeps, per robot, each cycle's time, mean whole-map ν of its best
hypothesis, verdict and judgement, and the last accepted result's layers; :meth:`RunReport.png` draws the
three panels with matplotlib (Agg) and returns the PNG's bytes (the caller writes them; nothing here does
I/O). The colours are the overlays' (:func:`merger.io.overlay.overlay_rgb`: one palette with the
recording and ``merger merge``'s overlay).
"""

from __future__ import annotations

import io
import math

import numpy as np

from .events import Observer


class RunReport(Observer):
    """Collects what the picture shows while the run goes (see the module's docstring)."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.cycles: dict[str, list[tuple[float, float, bool, bool]]] = {}  # t, ν, accepted, false merge
        self.last: dict[str, object] = {}  # robot -> its last accepted TeamMergeResult
        self.result = None
        self.title = ""

    def on_start(self, sim) -> None:
        self.names = list(sim.robot_names)
        self.cycles = {n: [] for n in self.names}
        self.title = f"{sim.scenario.name}, seed {sim.scenario.seed}"

    def on_merge_cycle(self, cycle) -> None:
        top = cycle.result.top
        nus = [v.nu for v in top.checks.values()]
        nu = float(np.mean(nus)) if nus else math.nan
        self.cycles.setdefault(cycle.robot, []).append((cycle.t, nu, cycle.result.accepted, cycle.false_merge))
        if cycle.result.accepted and cycle.result.layers:
            self.last[cycle.robot] = cycle.result

    def on_end(self, result) -> None:
        self.result = result

    def png(self, dpi: int = 110) -> bytes:
        """The report as PNG bytes: the merged map, the first merges, ν over time."""
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        from merger.io.overlay import PALETTE, overlay_rgb

        colour = {n: tuple(c / 255 for c in PALETTE[i % len(PALETTE)]) for i, n in enumerate(self.names)}
        fig, (ax_map, ax_nu, ax_first) = plt.subplots(1, 3, figsize=(15, 4.8), gridspec_kw={"width_ratios": [1.2, 1.6, 0.9]})
        fig.suptitle(f"circsim run: {self.title}")
        self._draw_map(ax_map, overlay_rgb)
        for n in self.names:
            rows = self.cycles.get(n, [])
            if not rows:
                continue
            t, nu, acc, false = (np.array(v) for v in zip(*rows, strict=True))
            ax_nu.plot(t[acc.astype(bool)], nu[acc.astype(bool)], "o", ms=3, color=colour[n], label=f"{n} accepted")
            ax_nu.plot(t[~acc.astype(bool)], nu[~acc.astype(bool)], ".", ms=2, alpha=0.35, color=colour[n])
            if false.any():
                ax_nu.plot(t[false.astype(bool)], nu[false.astype(bool)], "x", ms=8, mew=2, color="red")
        n_false = self.result.false_merges if self.result is not None else 0
        ax_nu.plot([], [], "x", color="red", mew=2, label=f"false merge ({n_false})")
        ax_nu.set(xlabel="simulated time (s)", ylabel="mean whole-map ν of the best hypothesis", ylim=(0, 1.02),
                  title="ν over time (dots: accepted; faint: refused)")
        ax_nu.legend(fontsize=7, loc="lower right")
        first = {n: (self.result.robots[n].first_merge_s if self.result is not None else None) for n in self.names}
        y = np.arange(len(self.names))
        done = [first[n] if first[n] is not None else 0.0 for n in self.names]
        ax_first.barh(y, done, color=[colour[n] for n in self.names])
        for k, n in enumerate(self.names):
            ax_first.text(done[k], k, f" {first[n]:.1f} s" if first[n] is not None else " never", va="center", fontsize=8)
        ax_first.set(yticks=y, yticklabels=self.names, xlabel="simulated time (s)",
                     title="first correct merge of every map")
        ax_first.invert_yaxis()
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        plt.close(fig)
        return buf.getvalue()

    def _draw_map(self, ax, overlay_rgb) -> None:
        """The merged map of the first robot (in name order) that accepted a merge, in its frame."""
        holder = next((n for n in self.names if n in self.last), None)
        ax.set_axis_off()
        if holder is None:
            ax.set_title("no robot accepted a merge")
            return
        res = self.last[holder]
        names = [n for n in self.names if n in res.layers]
        layers = [res.layers[n] for n in names]
        g0 = layers[0]
        empty = np.zeros(g0.shape, np.uint8)  # a robot not in this merge keeps its colour's place
        rgb = overlay_rgb([res.layers[n].states if n in res.layers else empty for n in self.names], self.names)
        x0, x1, y0, y1 = g0.extent
        ax.imshow(rgb, origin="lower", extent=(x0, x1, y0, y1), interpolation="nearest")
        known = np.nonzero(np.any([g.states > 0 for g in layers], axis=0))
        if known[0].size:
            r0, r1 = known[0].min(), known[0].max() + 1
            c0, c1 = known[1].min(), known[1].max() + 1
            res_m = g0.resolution
            ax.set_xlim(x0 + c0 * res_m, x0 + c1 * res_m)
            ax.set_ylim(y0 + r0 * res_m, y0 + r1 * res_m)
        ax.set_axis_on()
        ax.set(xlabel="x (m)", ylabel="y (m)", aspect="equal",
               title=f"{holder}'s last merged map ({', '.join(names)})")
