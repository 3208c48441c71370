"""The transfer report as markdown and as a figure (the map of disagreements, the bars
of steps per twin)."""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.calibration.transfer.score import (
    UNTRIED_RULES,
    GoalTransfer,
    TransferResult,
    TwinScore,
    fmt_pct,
    fmt_steps,
)


def transfer_markdown(result: TransferResult, *, figure: bool = True) -> str:
    """The markdown report: per goal, the real optimum and every twin's score; ``figure``:
    link ``transfer.png`` (written beside it)."""
    out = io.StringIO()
    out.write(f"# Transfer of twin policies to {result.real_name}\n\n")
    aset = "unknown action set" if result.action_set is None else result.action_set.describe()
    out.write(f"Real model: `{result.real_name}` ({aset}). Twins: "
              + ", ".join(f"`{n}`" for n in result.twin_names) + ".\n\n"
              "Steps are expected decisions to the goal on the real model; \"never\" = the "
              f"policy is not sure to arrive. Rule `{result.untried}`: "
              f"{UNTRIED_RULES[result.untried]}. A state disagrees when the twin's action is "
              "not one of the real optimal ones; its one-step regret is the extra expected "
              "steps of that action once. Start states are weighted "
              f"`{result.weighting}`.\n")
    if result.reset_states:
        out.write(f"\nReal state(s) {list(result.reset_states)}: their recorded rows are an "
                  "episode reset, not moves; the twins' own rows stand in for them.\n")
    _overview(out, result)
    for g in result.goals:
        s = g.summary()
        out.write(f"\n## Goal {g.name} (states {', '.join(map(str, np.flatnonzero(g.goal)))})"
                  f"\n\n{g.starts.size} start states; real optimum "
                  f"**{fmt_steps(g.optimum_mean)}** steps.")
        if g.unreachable_starts:
            out.write(f" Dropped: start states {list(g.unreachable_starts)}, from which no "
                      "real policy reaches the goal.")
        out.write("\n\n| twin | mean steps | / optimum | starts never arriving | "
                  "states disagreeing | their mean one-step regret (steps) | "
                  "untried real pairs chosen |\n|---|---|---|---|---|---|---|\n")
        for t in g.twins:
            ratio = "never" if math.isinf(t.ratio) else _cell(t.ratio, "{:.3f}")
            r = t.regret[t.disagree]
            regret = "never" if np.isinf(r).any() else (f"{r.mean():.2f}" if r.size else "-")
            out.write(f"| `{t.name}` | {fmt_steps(t.mean_steps)} | {ratio} | "
                      f"{100 * t.never_share:.0f} % | {int(t.disagree.sum())} | {regret} | "
                      f"{int(t.untried.sum())} |\n")
        out.write(f"\nAcross {len(g.twins)} twin(s): mean {fmt_steps(s['mean'])}, worst "
                  f"{fmt_steps(s['worst'])}, best {fmt_steps(s['best'])}, spread (std) "
                  f"{fmt_steps(s['spread'])} steps; mean over the optimum "
                  f"{fmt_pct(s['excess'])}.\n")
        if g.floor is not None and not math.isfinite(g.floor.median):
            out.write(f"\nNo perfect-twin line: {g.floor.phrase().removeprefix('no perfect-twin score: ')}.\n")
        elif g.floor is not None:
            f = g.floor
            out.write(f"\nThe real optimum of an estimated model is biased low, so even a "
                      "perfect twin scores above it. A perfect twin (the real robot's own "
                      "plan) scored on real models re-estimated from the same number of "
                      f"transitions ({f.ratios.size} resamples) is {fmt_pct(f.median - 1.0)} "
                      f"above their optimum (95 %: {fmt_pct(f.low - 1.0)} to "
                      f"{fmt_pct(f.high - 1.0)}). The resamples never hold a transition the "
                      "real data missed, so with few transitions per pair this gap is "
                      "rather a lower bound.\n")
    if figure:
        out.write("\n![transfer](transfer.png)\n")
    return out.getvalue()


def _overview(out: io.StringIO, result: TransferResult) -> None:
    """Every goal at once, per twin: summed steps over the summed real optimum, and the
    perfect twin at the same data (the twin's own visit counts) beside it."""
    ov = result.overview()
    if len(result.goals) < 2 and not any(ln is not None for ln in result.lines):
        return
    out.write(f"\n## Over the {ov['goals']} goal(s)\n\nSteps summed over the goals over the "
              "real optimum summed the same way. A perfect twin (the real model itself, "
              "walked for the twin's own visits, scored the same way, by resampling) shows "
              "what the data alone cost: the gap is the twin's.\n\n| twin | steps / real "
              "optimum | perfect twin, same data | gap |\n|---|---|---|---|\n")
    for t in ov["twins"]:
        r = "never" if t["ratio"] is None else f"{t['ratio']:.3f}"
        line = "n/a" if t["perfect_twin_same_data"] is None else \
            f"{t['perfect_twin_same_data']:.3f}"
        gap = "n/a" if t["gap"] is None else f"{100 * t['gap']:+.1f} %"
        out.write(f"| `{t['twin']}` | {r} | {line} | {gap} |\n")


def _cell(x: float, fmt: str) -> str:
    return fmt.format(x) if math.isfinite(x) else "n/a"


def _panels(g: GoalTransfer) -> list[TwinScore]:
    """The twins drawn on the map: the worst and the best (one when they coincide)."""
    order = sorted(g.twins, key=lambda t: (t.mean_steps, t.never_share))
    return [order[-1]] if len(order) == 1 or order[-1] is order[0] else [order[-1], order[0]]


def _draw_map(ax: Any, g: GoalTransfer, t: TwinScore, centres: NDArray[np.float64] | None,
              vmax: float, grid: Any = None, disc: Any = None, arena: Any = None) -> Any:
    """One map panel: states coloured by excess steps, ``x`` never arrives, a black ring a
    disagreement with the real optimum, a gold star the goal, hollow the non-start states;
    under them the arena (its own frame, as the centres) or else the occupancy ``grid``."""
    from matplotlib import colormaps
    from matplotlib.colors import Normalize

    S = t.steps.size
    if centres is None:
        xy = np.stack([np.arange(S, dtype=float), np.zeros(S)], axis=1)
        ax.set_xlabel("state")
        ax.set_yticks([])
    else:
        xy = np.asarray(centres, dtype=np.float64)
        if arena is not None:
            from simlab.physics.render import draw_arena_on

            draw_arena_on(ax, arena)
        elif grid is not None and disc is not None:
            from discretize.plot import draw_states

            draw_states(ax, grid, disc, numbers=False, robot_radius=None)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal")
    norm = Normalize(0.0, vmax)
    cmap = colormaps["viridis"]
    start = np.zeros(S, dtype=bool)
    start[g.starts] = True
    fin = np.isfinite(t.excess)
    show = start & fin
    ax.scatter(xy[show, 0], xy[show, 1], c=cmap(norm(t.excess[show])), s=90, zorder=3,
               edgecolors=[(0, 0, 0, 1.0 if d else 0.0) for d in t.disagree[show]],
               linewidths=1.8)
    other = ~start & ~g.goal & fin
    ax.scatter(xy[other, 0], xy[other, 1], s=60, facecolors="none",
               edgecolors=cmap(norm(t.excess[other])), zorder=3)
    never = ~g.goal & np.isinf(t.excess)
    if never.any():
        ax.scatter(xy[never, 0], xy[never, 1], marker="X", s=90, color="tab:red", zorder=4,
                   label="never arrives")
    nan = ~g.goal & np.isnan(t.excess)
    if nan.any():
        ax.scatter(xy[nan, 0], xy[nan, 1], marker=".", s=40, color="0.5", zorder=3,
                   label="goal out of real reach")
    untried = t.untried & ~g.goal
    if untried.any():
        ax.scatter(xy[untried, 0], xy[untried, 1], marker="s", s=200, facecolors="none",
                   edgecolors="tab:red", linewidths=1.5, zorder=4,
                   label="action the real robot never tried")
    if t.disagree.any():
        ax.scatter([], [], s=90, facecolors="none", edgecolors="black", linewidths=1.8,
                   label="not a real-optimal action")
    ax.scatter(xy[g.goal, 0], xy[g.goal, 1], marker="*", s=220, color="gold",
               edgecolors="black", zorder=5, label="goal")
    for s in range(S):
        ax.annotate(str(s), xy[s], xytext=(3, 3), textcoords="offset points", fontsize=6)
    score = (f"{fmt_steps(t.mean_steps)} steps" if math.isfinite(t.mean_steps) else
             f"never arrives from {100 * t.never_share:.0f} % of the starts")
    ax.set_title(f"{_short(t.name)}: {score}, {int(t.disagree.sum())} states disagree",
                 fontsize=8)
    from matplotlib.cm import ScalarMappable

    return ScalarMappable(norm=norm, cmap=cmap)


def _draw_bars(ax: Any, g: GoalTransfer) -> None:
    means = g.means
    fin = np.isfinite(means)
    top = max([g.optimum_mean, *means[fin].tolist()]) if math.isfinite(g.optimum_mean) \
        else (float(means[fin].max()) if fin.any() else 1.0)
    top = 1.15 * top if top > 0 else 1.0
    x = np.arange(means.size)
    ax.bar(x[fin], means[fin], color="tab:blue", label="twin policy")
    if not fin.all():
        ax.bar(x[~fin], np.full(int((~fin).sum()), top), color="none", edgecolor="tab:red",
               hatch="//", label="never arrives")
    if math.isfinite(g.optimum_mean):
        ax.axhline(g.optimum_mean, color="k", ls="--", label="real optimum")
        f = g.floor
        if f is not None and math.isfinite(f.low) and math.isfinite(f.high):
            ax.axhspan(g.optimum_mean * f.low, g.optimum_mean * f.high, color="0.85",
                       zorder=0, label="a perfect twin (95 %)")
    ax.set_xticks(x)
    ax.set_xticklabels([_short(t.name) for t in g.twins], rotation=45, ha="right", fontsize=7)
    ax.set_ylabel("expected steps to the goal (real)")
    ax.set_ylim(0, top * 1.05)
    ax.legend(fontsize=7)
    ax.set_title(f"goal {g.name}", fontsize=8)


def _short(name: str) -> str:
    parts = Path(name).parts
    return "/".join(parts[-2:]) if len(parts) > 1 else name


def render_transfer_png(result: TransferResult, *, grid: Any = None, disc: Any = None,
                        arena: Any = None, dpi: int = 110) -> bytes:
    """The figure as PNG bytes: per goal (a row), the worst and best twins' policies on the
    map (states coloured by excess steps over the real optimum, disagreements ringed), then
    a bar per twin seed of its mean steps against the optimum (dashed). Under the states:
    ``arena`` (an :class:`~simlab.physics.arena.ArenaConfig`, drawn in its own frame), else
    the occupancy ``grid`` with ``disc``'s cells."""
    from matplotlib.figure import Figure

    centres = result.centres if disc is None else np.asarray(disc.centres)
    # a long lab (a corridor, or states in a line without centres) gets one map per row
    wide = True
    if centres is not None:
        span = np.ptp(np.asarray(centres), axis=0)
        wide = bool(span[0] > 2.0 * max(span[1], 1e-9))
    n_maps = max(len(_panels(g)) for g in result.goals)
    if wide:
        per_goal = n_maps + 1
        fig = Figure(figsize=(10.0, 3.0 * per_goal * len(result.goals)), layout="constrained")
        grid_axes = fig.subplots(per_goal * len(result.goals), 1, squeeze=False)[:, 0]
        slots = [(list(grid_axes[i * per_goal: i * per_goal + n_maps]),
                  grid_axes[i * per_goal + n_maps]) for i in range(len(result.goals))]
    else:
        fig = Figure(figsize=(4.6 * (n_maps + 1), 4.2 * len(result.goals)),
                     layout="constrained")
        grid_axes = fig.subplots(len(result.goals), n_maps + 1, squeeze=False)
        slots = [(list(row[:n_maps]), row[n_maps]) for row in grid_axes]
    for g, (map_axes, bar_ax) in zip(result.goals, slots, strict=True):
        panels = _panels(g)
        ex = np.concatenate([t.excess[np.isfinite(t.excess)] for t in g.twins])
        vmax = max(1.0, float(ex.max()) if ex.size else 1.0)
        for ax, t in zip(map_axes, panels, strict=False):
            mappable = _draw_map(ax, g, t, centres, vmax, grid, disc, arena)
            cbar = fig.colorbar(mappable, ax=ax, fraction=0.04)
            cbar.set_label("excess steps", fontsize=7)
            ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(0.0, -0.18 if wide
                                                                   else -0.12), ncols=3)
        for ax in map_axes[len(panels):]:
            ax.axis("off")
        _draw_bars(bar_ax, g)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def plot_transfer(result: TransferResult, path: str | os.PathLike[str], *, grid: Any = None,
                  disc: Any = None, arena: Any = None) -> Path:
    """Write :func:`render_transfer_png` to ``path`` atomically."""
    from simlab.base.io import atomic_write_bytes

    atomic_write_bytes(path, render_transfer_png(result, grid=grid, disc=disc, arena=arena))
    return Path(path)
