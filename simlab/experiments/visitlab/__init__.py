"""The Visit-the-lab results of ``simlab reproduce``: thesis Figs. 4.1-4.7, the combined
task, and the IMOL 2023 poster's Figs. 4 and 5.

Runners (the ``visitlab`` group of :mod:`simlab.experiments.registry`), one module each
------------------------------------------------------------------------------------
* ``visitlab.curves`` (``learning_curves``) — learning curves of several training runs
  (Figs. 4.1, 4.2, 4.4, 4.5, 4.6, poster Fig. 4), with per-run metrics (below);
* ``visitlab.nav_heatmaps`` (``heatmaps``) — Fig. 4.3, navigation value maps for the 9
  goal rooms;
* ``visitlab.combined`` (``architecture``) — the combined architecture (goals per trial,
  an episode GIF);
* ``visitlab.adaptability`` (``adaptation``) — Fig. 4.7, continued learning with three humans;
* ``visitlab.passive_qmaps`` (``passive``) — poster Fig. 5, what a passive Q-learner learns from
  watching model-based agents that explore differently.

Shared pieces: :mod:`.runs` (the run tables, seeds and the run cache), :mod:`.metrics`
(curve metrics, greedy success), :mod:`.modules` (the combined architecture's three
trained modules, shared by ``combined`` and ``adaptability``).

Training runs (``[[params.runs]]`` and the module tables)
--------------------------------------------------------
A run is one agent trained on one task for ``seeds`` seeds (``budget.seeds``) of
``trials`` trials, given as a table::

    [[params.runs]]
    label = "mb"               # names its metrics (mb_plateau, ...) and its legend
    agent = "mb-egreedy"       # a registry agent (simlab.agents.registry)
    task = "nav"               # nav | social | gotohuman (default: params.task)
    variant = "thesis"         # thesis | paper (default: params.variant or thesis)
    env = {human = "easy"}     # env settings (simlab.visitlab.envs; a human may be a
                               # preset name or a table of Human fields)
    overrides = {}             # agent settings (loop_agent_config; "actor.x" nested)
    observer = false           # a passive Q-learner watches the agent ...
    takeover = 0.5             # ... and acts from this fraction of the trials on
    legend = "MB eps-greedy"   # optional legend text

``budget.trials`` is a number, or a table by run label or task
(``trials = {nav = 2000, social = 40000}``).

**Runs are shared.** A run is built once per output folder into
``DIR/_cache/visitlab/run-<key>/`` (``runs.npz``: returns ``(seeds, trials)`` and
final Q tables; ``model_<i>.npz`` when a model is kept; ``_stage.json`` written last),
where ``key`` hashes everything that defines it (task, agent, variant, env, overrides,
observer, trials, seeds), the root seed, the simlab version and a fingerprint of the
source the run depends on (:func:`simlab.orchestration.cache.code_fingerprint` of
scope ``visitlab-run``: changed code is never reused). So
Figs. 4.1 and 4.2 share their model-based navigation runs, poster Fig. 4 reuses
Fig. 4.5's social run, Fig. 4.4's random-episode go-to-human run is the combined
architecture's module, and the combined task and Fig. 4.7 share the three trained
modules — as long as their tables agree (the TOMLs say which must stay equal).

Seeds: every run uses the integer seed :func:`visitlab_seed` and its seed ``i`` is
``seed_generators(visitlab_seed(root), seeds)[i]`` — exactly seed ``i`` of
``simlab visitlab train --seed <visitlab_seed(root)> --seeds <seeds>``; all the agents of
a figure start from the same environment streams (common random numbers). The combined
task's evaluation and continued runs use a second stream (spawn key ``(VISL, 1)``).

Curve metrics (for every run ``L``)
-----------------------------------
``L_plateau`` (mean reward per trial over the last 10 % of trials, all seeds),
``L_std`` (the thesis's band: standard deviation of the reward within windows of
``trials / 100`` trials, pooled over seeds, averaged over the last 10 windows),
``L_seed_std`` (standard deviation across seeds of the per-seed plateau),
``L_trials_to_90pct`` (first trial at which the smoothed seed-mean curve reaches 90 % of
the plateau), ``L_trials_to_<x>`` for every ``params.thresholds`` value ``x`` (first trial
at which the smoothed curve reaches ``x``; no value if never), and
``L_<name>`` for every ``params.windows`` entry ``name = [lo, hi]`` (mean reward over the
trials ``[lo * trials, hi * trials)``).

Every runner appends ``params.notes`` (a list of sentences, e.g. why our simulation
differs from the thesis where a check fails) to the notes of ``results.md``.
"""

from __future__ import annotations

# one module per figure; importing them registers their runners
from simlab.experiments.visitlab.adaptation import adapt_job, adaptability
from simlab.experiments.visitlab.architecture import combined
from simlab.experiments.visitlab.heatmaps import nav_heatmaps
from simlab.experiments.visitlab.learning_curves import curves
from simlab.experiments.visitlab.metrics import curve_metrics, greedy_success, pearson
from simlab.experiments.visitlab.modules import direction_matrix, evaluate_job, module_specs
from simlab.experiments.visitlab.passive import passive_qmaps
from simlab.experiments.visitlab.runs import (
    VISITLAB_SPAWN_KEY,
    RunData,
    RunSpec,
    env_kwargs,
    get_runs,
    param_notes,
    parse_run,
    train_job,
    visitlab_seed,
)

__all__ = ["VISITLAB_SPAWN_KEY", "RunData", "RunSpec", "adapt_job", "adaptability", "combined",
           "curve_metrics", "curves", "direction_matrix", "env_kwargs", "evaluate_job",
           "get_runs", "greedy_success", "module_specs", "nav_heatmaps", "param_notes",
           "parse_run", "passive_qmaps", "pearson", "train_job", "visitlab_seed"]
