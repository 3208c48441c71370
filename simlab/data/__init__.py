"""Transition datasets and the empirical MDP (thesis 1.5 eq. 1.13-1.14, 3.2.5 and 4.5).

Layers, one per module:

* :mod:`simlab.data.schema` — column names and types of a dataset part, file names;
* :mod:`simlab.data.manifest` — the JSON manifest (provenance, seeds, checksums);
* :mod:`simlab.data.dataset` — writing parts atomically, reading and validating a
  dataset directory as one :class:`pyarrow.Table`;
* :mod:`simlab.data.walkers` — what runs inside a worker: the physics random walk,
  a physics-free kinematic stand-in, pose sources;
* :mod:`simlab.data.backends` — the dataset parts as jobs of the one parallel layer
  (:mod:`simlab.base.parallel`: in-process, local processes or Ray);
* :mod:`simlab.data.collect` — the ``simlab collect`` driver (budgets, exact resume);
* :mod:`simlab.data.estimate` — counts, T = n(s,a,s')/n(s,a), entropy, coverage,
  ``simlab estimate``;
* :mod:`simlab.data.mdp` — :class:`EmpiricalMDP`, the validated transition matrix with its
  goal areas that training, replay and the env read (``mdp.npz``);
* :mod:`simlab.data.counts` — import of external count tables (real-robot logs);
* :mod:`simlab.data.goals` — which Markov states belong to which goal area;
* :mod:`simlab.data.plots` — the mean-entropy-per-action bar plot (thesis Fig. 4.8);

Importing this package is cheap; the names in ``__all__`` load their module on first
use. The two commands are :func:`simlab.data.collect.collect` and
:func:`simlab.data.estimate.estimate` (also :mod:`simlab.commands`); they are not
re-exported here because their names are those of their modules.
"""

from __future__ import annotations

from simlab.base.lazy import lazy_exports

_LAZY: dict[str, str] = {
    "CollectResult": "simlab.data.collect",
    "EstimateResult": "simlab.data.estimate",
    "EmpiricalMDP": "simlab.data.mdp",
    "load_mdp": "simlab.data.mdp",
    "mdp_from_arrays": "simlab.data.mdp",
    "empirical_mdp": "simlab.data.estimate",
    "read_dataset": "simlab.data.dataset",
    "open_dataset": "simlab.data.dataset",
    "TransitionDataset": "simlab.data.dataset",
    "load_counts": "simlab.data.counts",
    "goal_state_masks": "simlab.data.goals",
}

__all__, __getattr__, __dir__ = lazy_exports(__name__, _LAZY)
