"""Visit the lab: the tabular human-robot interaction simulation (thesis ch. 2).

A robot must get a simulated human's attention and lead them to goal rooms. Layers:

* :mod:`~simlab.visitlab.actions` — actions 0-29 and the one direction table;
* :mod:`~simlab.visitlab.grid` — layouts (gridworld, random lab, the paper's lab)
  and the movement kernel;
* :mod:`~simlab.visitlab.perception` — angle, fields of view, line of sight,
  distance classes;
* :mod:`~simlab.visitlab.humans` — the :class:`Human` parameters and presets;
* :mod:`~simlab.visitlab.dynamics` — the navigation, social and go-to-human step
  kernels (numba), the one source of truth for the dynamics;
* :mod:`~simlab.visitlab.envs` — Gymnasium wrappers (``simlab/VisitLab-*-v0``);
* :mod:`~simlab.visitlab.fused` — the fused numba training loops (env step and agent
  update in one loop) and the agents' thesis / paper settings;
* :mod:`~simlab.visitlab.training` — seeded runs, :func:`~simlab.visitlab.training.train`
  and ``simlab visitlab train`` (options in :mod:`~simlab.visitlab.options`);
* :mod:`~simlab.visitlab.results` — curves files (npz), Fig. 4.1-style plots,
  summaries;
* :mod:`~simlab.visitlab.combined` — the combined architecture (thesis Fig. 3.1):
  required direction from navigation, the social module choosing, action 29 delegated
  to go-to-human, goal rooms reached per trial, episode GIFs;
* :mod:`~simlab.visitlab.adaptability` — continued learning with a new human
  (thesis Fig. 4.7);
* :mod:`~simlab.visitlab.passive` — the passive model-free observer (IMOL poster) and
  the optimal navigation values;
* :mod:`~simlab.visitlab.figures` — the figures of ``simlab reproduce``'s
  Visit-the-lab results;
* :mod:`~simlab.visitlab.reference` — the plain per-step Python loop (benchmark
  baseline and cross-check).

Nothing here knows about PyBullet.
"""

from __future__ import annotations

from simlab.base.lazy import lazy_exports

#: The three Visit-the-lab learning tasks (:func:`simlab.visitlab.training.train`).
TASKS = ("nav", "social", "gotohuman")

# Names re-exported from the submodules, imported on first use: the submodules compile
# numba kernels, and light importers (the CLI parser, experiment specs) only need TASKS.
_names, __getattr__, _dir = lazy_exports(__name__, {
    "Direction": "simlab.base.directions",
    "Action": "simlab.visitlab.actions",
    "move_action": "simlab.visitlab.actions",
    "Layout": "simlab.visitlab.grid",
    "gridworld": "simlab.visitlab.grid",
    "lab_layout": "simlab.visitlab.grid",
    "make_layout": "simlab.visitlab.grid",
    "paper_layout": "simlab.visitlab.grid",
    "PRESETS": "simlab.visitlab.humans",
    "Human": "simlab.visitlab.humans",
    "human": "simlab.visitlab.humans",
    "PAPER_PERCEPTION": "simlab.visitlab.perception",
    "THESIS_PERCEPTION": "simlab.visitlab.perception",
    "Perception": "simlab.visitlab.perception",
})
__all__ = ["TASKS", *_names]


def __dir__() -> list[str]:
    return sorted({*_dir(), *globals()})
