"""The figures of ``simlab online`` read on their own: axes in units, a colour bar where
colour is a number, a legend for the markers, nothing drawn past the run's end."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

from simlab.online.physics_plots import physics_figure, visits_figure
from simlab.online.report import online_figures, window_centres
from simlab.physics.arena import load_arena

N, WINDOW = 21, 10  # the last window holds one decision
UNIT = re.compile(r"\((?:[^()]*\b(?:m|s|h|bits|count|share|backups|index|rewards)\b[^()]*)\)")


def _logs(rng: np.random.Generator) -> dict[str, list[dict[str, np.ndarray]]]:
    def run() -> dict[str, np.ndarray]:
        return {"blocked": rng.random(N) < 0.2, "duration": rng.uniform(1, 3, N),
                "reward": (rng.random(N) < 0.1).astype(float), "backups": rng.integers(0, 9, N),
                "expert": rng.random(N) < 0.5, "x": rng.uniform(-0.5, 0.5, N),
                "y": rng.uniform(-0.5, 0.5, N), "boxes": np.array([[0.2, 0.1, 0.1, 0.2, 0.3]])}

    return {"mf": [run(), run()], "mb": [run(), run()]}


def _task(change: str = "goal") -> SimpleNamespace:
    return SimpleNamespace(start_states=(0,), goal=(4,), changes=[
        SimpleNamespace(at=12, kind=change, goal=(2,))])


def _plotted_axes(fig) -> list:
    return [ax for ax in fig.axes if ax.lines or ax.collections or ax.patches]


def test_windows_are_drawn_inside_the_run() -> None:
    np.testing.assert_allclose(window_centres(N, WINDOW), [5.0, 15.0, 20.5])
    np.testing.assert_allclose(window_centres(20, WINDOW), [5.0, 15.0])


def test_physics_figure_stops_at_the_runs_end_with_units() -> None:
    fig = physics_figure(_logs(np.random.default_rng(0)), _task(), WINDOW)
    axes = _plotted_axes(fig)
    assert len(axes) == 2
    for ax in axes:
        assert ax.get_xlim()[1] <= N
        assert max(np.max(np.asarray(ln.get_xdata(), float)) for ln in ax.lines) <= N
        assert UNIT.search(ax.get_ylabel()), ax.get_ylabel()
    assert UNIT.search(axes[1].get_xlabel())
    assert "(s)" in axes[1].get_ylabel()
    labels = [t.get_text() for t in axes[0].get_legend().get_texts()]
    assert labels == ["mf", "mb", "change"]


def test_visits_figure_has_a_colour_bar_metres_and_a_legend() -> None:
    arena = load_arena("table")
    lab = SimpleNamespace(arena=arena, discretizer=SimpleNamespace(
        centres=np.array([[-0.5, -0.5], [0.0, -0.5], [0.5, -0.5], [0.0, 0.0], [0.5, 0.5]])))
    fig = visits_figure(_logs(np.random.default_rng(1)), lab, _task())
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert len(panels) == 2
    for ax in panels:
        assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
    bars = [ax for ax in fig.axes if ax not in panels]
    assert len(bars) == 1 and "positions per bin" in bars[0].get_ylabel()
    labels = [t.get_text() for t in panels[0].get_legend().get_texts()]
    assert labels == ["start states", "goal states", "goal after the change",
                      "box added by the change"]


@pytest.mark.parametrize("name", ["cumulative_reward.png", "cumulative_cost.png", "mb_share.png"])
def test_online_figures_stop_at_the_runs_end_with_units(name: str) -> None:
    summary = {"task": {"changes": [{"at": 12}]}}
    fig = online_figures(_logs(np.random.default_rng(2)), summary, WINDOW)[name]
    (ax,) = _plotted_axes(fig)
    assert ax.get_xlim() == (0.0, float(N))
    assert max(np.max(np.asarray(ln.get_xdata(), float)) for ln in ax.lines) <= N
    assert UNIT.search(ax.get_xlabel()) and UNIT.search(ax.get_ylabel()), ax.get_ylabel()
    assert ax.get_legend() is not None
