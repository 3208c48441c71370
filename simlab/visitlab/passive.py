"""The passive model-free learner of the IMOL 2023 poster (thesis Appendix C, Figs. 4-5).

A model-based agent acts and learns; beside it a Q-learner (the *observer*) updates its
own Q table on every transition the actor makes, without choosing anything. After a
fraction of the run (poster: half) the observer takes control: it acts with its own
selection rule and keeps learning, the actor stops (no more planning cost). The
poster's questions: does watching a model-based agent bootstrap the model-free
learner (Fig. 4: learning curves of MB, MF and MF-observing-MB on the navigation and
social tasks), and how does the actor's exploration shape what the observer learns
(Fig. 5: Q maps of MF alone, MF observing MB epsilon-greedy and MF observing R-max, and
their learned values against the optimal values V*(s))?

The loops are the fused ones of :mod:`simlab.visitlab.fused`
(:func:`~simlab.visitlab.fused.with_observer` turns any actor — model-based
epsilon-greedy, value-iteration softmax, R-max — into a watched one), so an observer
run costs what the actor's run costs. The observer is the ``q-learning`` agent of the
variant (thesis: alpha 0.7, epsilon 0.05, Q starting at 0, so that after the take-over
it exploits what it watched instead of trying every action it never saw).

:func:`nav_optimal_q` gives the exact optimal Q* of the goal-conditioned navigation
task (value iteration on the deterministic moves), the x axis of poster Fig. 5 (bottom).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from simlab.base.errors import ConfigError
from simlab.visitlab.fused import loop_agent_config
from simlab.visitlab.grid import Layout
from simlab.visitlab.training import EnvSpec, ObserverSpec, SeedRun, run_seed


def observer_run(task: str, actor: str, trials: int,
                 gens: tuple[np.random.Generator, np.random.Generator], *,
                 takeover_fraction: float = 0.5, variant: str = "thesis",
                 actor_overrides: dict[str, Any] | None = None,
                 observer_overrides: dict[str, Any] | None = None,
                 env_kwargs: dict[str, Any] | None = None) -> SeedRun:
    """One seeded run of ``actor`` (a registry agent name) watched by a Q-learner.

    The observer takes over after ``takeover_fraction`` of the ``trials`` (1.0: it
    only watches). ``returns`` is the reward per trial of whoever acted;
    ``q_observer`` the observer's final Q table, ``q`` the actor's.
    """
    if actor in ("q-learning", "q-softmax", "passive-observer"):
        raise ConfigError(f"the actor must be a model-based agent, got {actor!r}", key="actor",
                          fix="use mb-egreedy, vi-softmax, rmax or sliding-window")
    cfg = loop_agent_config(actor, task, variant, actor_overrides)
    observer = loop_agent_config("q-learning", task, variant, observer_overrides)
    return run_seed(EnvSpec(task, variant, dict(env_kwargs or {})), cfg, trials, gens,
                    observer=ObserverSpec(observer, takeover_fraction))


def nav_optimal_q(layout: Layout, gamma: float = 0.9, tol: float = 1e-10,
                  max_iter: int = 10_000) -> np.ndarray:
    """Optimal Q* of the goal-conditioned navigation task on ``layout``.

    Rows ``cell + label * n_cells`` for every label (non-goal labels too, as if they
    were goals), 25 actions; reward 1 when the move ends in the goal room, discount
    ``gamma``, infinite horizon (the trials' truncation is not termination). Value
    iteration on the deterministic move table until a sweep changes nothing by more
    than ``tol``. Returns float64 ``(n_labels * n_cells, 25)``.
    """
    if not 0.0 <= gamma < 1.0:
        raise ConfigError(f"expected a discount in [0, 1), got {gamma!r}", key="gamma")
    nxt = layout.transition_table()
    labels = layout.cell_labels
    n = layout.n_cells
    out = np.zeros((layout.n_labels * n, nxt.shape[1]), dtype=np.float64)
    for g in range(layout.n_labels):
        r = (labels[nxt] == g).astype(np.float64)
        q = np.zeros_like(r)
        for _ in range(max_iter):
            new = r + gamma * q.max(axis=1)[nxt]
            done = np.abs(new - q).max() <= tol
            q = new
            if done:
                break
        out[g * n:(g + 1) * n] = q
    return out
