"""Social states in physics vs on the grid, side by side.

Both models live on the same 2560 social states (:func:`simlab.social.walk.decode_social`)
and the 22 physics social actions. The empirical one comes from the physics walk
(:mod:`simlab.social.walk`, or the ``counts`` of ``simlab estimate``'s ``mdp.npz``), the
tabular one from the same uniform random walk in the grid simulation of
:mod:`simlab.visitlab` (:func:`grid_walk`, physics action ``a`` played as the grid action
``GRID_ACTION[a]``, :mod:`simlab.social.actions`).

Decisions:

* **Sparse.** A dense ``2560 x 22 x 2560`` table is 1.2 GB; the comparison works on the
  visited ``(s, a)`` pairs only (:class:`SparseModel`), with the estimator's rules:
  ``P(s' | s, a) = n(s, a, s') / n(s, a)``, entropy in bits, and the most likely ``s'`` the
  smallest index among ties (``np.argmax`` of the dense ``T``).
* **The tabular model is estimated too** (a grid random walk), not read from the grid's
  rules: the grid simulation has no transition matrix, only a simulator.
* **Measures.** Per-state coverage: the fraction of the 22 actions tried in ``s``;
  mean entropy per action over its visited states (NaN if none); agreement: among the
  ``(s, a)`` visited by both models, the fraction whose most likely ``s'`` is the same.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.data.estimate import SparseCountModel, sparse_count_model, sparse_from_dense_counts
from simlab.social.actions import GRID_ACTION, N_SOCIAL_ACTIONS
from simlab.social.walk import N_SOCIAL_STATES


@dataclass(frozen=True)
class SparseModel:
    """A count model on its visited pairs: ``pairs`` (P,) sorted ``s * A + a``; ``n_sa``
    (P,) visits; ``entropy`` (P,) bits of ``P(. | s, a)``; ``mode`` (P,) most likely s'."""

    pairs: NDArray[np.int64]
    n_sa: NDArray[np.int64]
    entropy: NDArray[np.float64]
    mode: NDArray[np.int64]
    n_states: int = N_SOCIAL_STATES
    n_actions: int = N_SOCIAL_ACTIONS

    def coverage_per_state(self) -> NDArray[np.float64]:
        """Fraction of the actions tried in each state, ``(S,)``."""
        s = self.pairs // self.n_actions
        return np.bincount(s, minlength=self.n_states) / float(self.n_actions)

    def mean_entropy_per_action(self) -> NDArray[np.float64]:
        """Mean entropy (bits) over the visited states of each action, ``(A,)`` (NaN: none)."""
        a = self.pairs % self.n_actions
        tot = np.bincount(a, weights=self.entropy, minlength=self.n_actions)
        n = np.bincount(a, minlength=self.n_actions)
        return np.divide(tot, n, out=np.full(self.n_actions, np.nan), where=n > 0)


def sparse_model(s: ArrayLike, a: ArrayLike, s_next: ArrayLike, *,
                 n_states: int = N_SOCIAL_STATES, n_actions: int = N_SOCIAL_ACTIONS
                 ) -> SparseModel:
    """Count transitions ``(s, a, s')`` (int arrays, same length) into a :class:`SparseModel`
    (the estimator's :func:`~simlab.data.estimate.sparse_count_model`, visited pairs only)."""
    return _visited_view(sparse_count_model(s, a, s_next, n_states, n_actions))


def sparse_from_counts(counts: ArrayLike) -> SparseModel:
    """A :class:`SparseModel` from a dense ``(S, A, S)`` count table (``mdp.npz`` counts)."""
    return _visited_view(sparse_from_dense_counts(counts))


def _visited_view(model: SparseCountModel) -> SparseModel:
    """The visited rows of the estimator's CSR model, with each row's most likely ``s'``
    (largest count, smallest ``s'`` among ties)."""
    pairs = np.flatnonzero(model.visited.ravel())
    # rows stay in CSR order, so row r's entries keep positions indptr[r]:indptr[r + 1]
    order = np.lexsort((model.indices, -model.counts, model.rows()))
    mode = model.indices[order[model.indptr[pairs]]]
    return SparseModel(pairs=pairs, n_sa=model.n_sa.ravel()[pairs],
                       entropy=model.entropy.ravel()[pairs], mode=mode,
                       n_states=model.n_states, n_actions=model.n_actions)


def grid_walk(steps: int, seed: int, *, episode_steps: int = 40, human: str = "easy"
              ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """The uniform random walk over the 22 physics actions in the grid's social task
    (``simlab/VisitLab-Social-v0``, thesis variant), restarting every ``episode_steps``;
    returns ``(s, a, s_next)`` (physics action numbers). Same seed -> same arrays."""
    from simlab.visitlab.envs.social import SocialEnv

    act_seq, ep_seq = np.random.SeedSequence(seed).spawn(2)
    act_rng, ep_rng = np.random.default_rng(act_seq), np.random.default_rng(ep_seq)
    env = SocialEnv(human=human, max_steps=None)
    out = np.zeros((3, steps), dtype=np.int64)
    obs = 0
    for k in range(steps):
        if k % episode_steps == 0:
            obs, _ = env.reset(seed=int(ep_rng.integers(0, 2**63 - 1)))
        a = int(act_rng.integers(0, N_SOCIAL_ACTIONS))
        nxt = env.step(int(GRID_ACTION[a]))[0]
        out[:, k] = (obs, a, nxt)
        obs = nxt
    return out[0], out[1], out[2]


@dataclass(frozen=True)
class Comparison:
    """Side-by-side measures: ``coverage`` (2, S) per-state coverage (physics, grid);
    ``entropy`` (2, A) mean entropy per action (bits); ``agreement`` fraction of the pairs
    visited by both with the same most likely s'; ``agreement_per_action`` (A,) (NaN: no
    common pair); ``common_pairs`` and ``visited_pairs`` (physics, grid)."""

    coverage: NDArray[np.float64]
    entropy: NDArray[np.float64]
    agreement: float
    agreement_per_action: NDArray[np.float64]
    common_pairs: int
    visited_pairs: tuple[int, int]


def compare(physics: SparseModel, grid: SparseModel) -> Comparison:
    """Compare the empirical (physics) and tabular (grid) social models (module docstring)."""
    if (physics.n_states, physics.n_actions) != (grid.n_states, grid.n_actions):
        raise ValueError("the two models must have the same states and actions")
    common, i, j = np.intersect1d(physics.pairs, grid.pairs, return_indices=True)
    same = physics.mode[i] == grid.mode[j]
    A = physics.n_actions
    a = common % A
    n = np.bincount(a, minlength=A)
    hits = np.bincount(a, weights=same.astype(float), minlength=A)
    return Comparison(
        coverage=np.stack([physics.coverage_per_state(), grid.coverage_per_state()]),
        entropy=np.stack([physics.mean_entropy_per_action(), grid.mean_entropy_per_action()]),
        agreement=float(same.mean()) if len(common) else float("nan"),
        agreement_per_action=np.divide(hits, n, out=np.full(A, np.nan), where=n > 0),
        common_pairs=len(common),
        visited_pairs=(len(physics.pairs), len(grid.pairs)))


def comparison_figure(result: Comparison) -> Any:
    """The figure "social states vs tabular, side by side" (a matplotlib Figure): per-state
    coverage on the (level x distance, direction x angle) chart for both models, mean
    entropy per action (bits), agreement per action (share of common pairs)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 8), layout="constrained")
    axes = fig.subplots(2, 2)
    for ax, cov, name in zip(axes[0], result.coverage, ("physics (empirical)", "grid (tabular)"),
                             strict=True):
        im = ax.imshow(cov.reshape(40, 64), aspect="auto", vmin=0, vmax=1, cmap="viridis")
        ax.set_title(f"{name}: actions tried per state")
        ax.set_xlabel("required direction x angle (chart column)")
        ax.set_ylabel("level x distance class (chart row)")
        fig.colorbar(im, ax=ax, label="actions tried (share of the actions)")
    x = np.arange(result.entropy.shape[1])
    axes[1, 0].bar(x - 0.2, result.entropy[0], 0.4, label="physics")
    axes[1, 0].bar(x + 0.2, result.entropy[1], 0.4, label="grid")
    axes[1, 0].set_title("mean entropy per action")
    axes[1, 0].set_xlabel("action (index)")
    axes[1, 0].set_ylabel("entropy of T(s, a, .) (bits)")
    axes[1, 0].legend()
    axes[1, 1].bar(x, result.agreement_per_action)
    axes[1, 1].set_ylim(0, 1)
    axes[1, 1].set_title(f"most likely s' agrees: {result.agreement:.0%} of "
                         f"{result.common_pairs} common (s, a)")
    axes[1, 1].set_xlabel("action (index)")
    axes[1, 1].set_ylabel("agreement (share of common states)")
    fig.suptitle("social states vs tabular, side by side")
    return fig


def plot_comparison(result: Comparison, out: str | os.PathLike[str]) -> Path:
    """:func:`comparison_figure` as a PNG at ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    path = Path(out)
    comparison_figure(result).savefig(path, dpi=80)
    return path
