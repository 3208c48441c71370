"""Does a policy trained in the twin reach the goal on the real robot? The transfer report.

A simulated twin of a real lab is worth what its policies do on the real robot. This package
scores a twin's policy on the **real** transition model by the expected number of decisions
to reach a goal from the start states, against the best any policy can do on that model:

* :func:`optimal_steps` — minimum expected number of decisions to the goal on a dense
  ``P[s, a, s']`` using allowed actions only: a stochastic shortest path with unit costs
  (Bertsekas & Tsitsiklis 1991, "An analysis of stochastic shortest path problems"), solved
  by policy iteration (exact linear solves, finitely many steps) started from a proper policy;
  ``inf`` where no policy reaches the goal with probability 1 (the almost-sure reachability
  fixed point, Baier & Katoen 2008, "Principles of Model Checking", sec. 10.6.1);
* :func:`policy_steps` — expected steps under a fixed deterministic policy: hitting times of
  the absorbing chain (Kemeny & Snell 1960, "Finite Markov Chains", ch. III), ``inf`` for the
  states from which the policy is not sure to arrive;
* :func:`twin_policy` / :func:`policy_from_q` — the twin's policy: the shortest-path policy
  of a twin model, or the greedy policy of a Q-table written by ``simlab train``;
* :func:`transfer_report` — per goal and per twin (one twin per seed): steps from the start
  states on the real model, the real optimum, their ratio, the share of starts that never
  arrive, per-state disagreement and excess steps; across twins mean, worst, best and spread;
* the report's markdown and figure (:func:`plot_transfer`), and ``simlab transfer``
  (:func:`transfer_command`).

Decisions:

* **Untried real pairs.** On a real count model the robot never tried some ``(s, a)``; no
  data says where it would go, so such a pair is not an action of the real optimum (the
  ``allowed`` mask), and a twin policy that chooses it is scored as **staying put** there
  (the self-loop ``simlab estimate`` also writes for an unvisited row): from any state whose
  walk reaches that state the policy never arrives, ``inf`` steps. The number of such states
  is reported per twin (``untried``). The rule ``untried="mask"`` instead chooses the twin's
  policy among the pairs the real robot tried (a twin that knows the real coverage).
* **Ties.** Among actions whose expected steps are equal within ``1e-9`` (relative), the
  lowest action index; a state with no way to the goal takes its lowest allowed action.
* **Action sets.** Twin and real model must hold the same actions: a twin in another
  numbering of them is read through the columns
  :meth:`simlab.base.actions.ActionSet.primitives` gives (the twin's action doing each real
  action). A twin of another number of
  actions is refused: a twin of simlab's 16 primitives did not walk an 8-action robot's
  actions (its data are spread over moves the robot does not have, at simlab's speeds),
  so it is collected in the robot's action set instead.
* **Untried and stay-only pairs.** The rule ``untried="mask"`` chooses a twin's policy among
  the pairs the real robot tried *and was seen to leave its state in*: a pair tried only in
  place holds the robot for good on the real model (with a few transitions per pair, a
  move that leaves one time in ten often never did in the sample).
* **Starts.** Default: every non-goal state the real robot left at least once. Start states
  from which even the real optimum cannot reach the goal are dropped (reported as
  ``unreachable_starts``): no policy can be scored there. Mean steps over the starts are
  uniform or weighted by the real visits of each start state (``weights``); a mean over
  starts of which one never arrives is ``inf`` ("never" in the reports).
* **A floor for the score.** The optimum of an estimated real model is biased low (its plan
  exploits lucky samples), so even a perfect twin scores above it; :func:`transfer_floor`
  estimates by how much at the real data's sample size, and the reports print it beside the
  twins' scores.
* **Goals** (command): ``--goal-states 18,34`` is one goal made of those states (named
  ``s18+34``, as ``simlab train --goal-states``); without it, the goals recorded in the real
  ``mdp.npz``, else those of the first twin (its Q-tables' goals, or its ``mdp.npz``'s);
  none of them is an error.
"""

from __future__ import annotations

from simlab.calibration.transfer.command import (
    TransferConfig,
    TransferFiles,
    transfer_command,
)
from simlab.calibration.transfer.models import (
    QTable,
    QTableTwin,
    TransferModel,
    load_twin,
    policy_from_q,
    twin_columns,
)
from simlab.calibration.transfer.render import (
    plot_transfer,
    render_transfer_png,
    transfer_markdown,
)
from simlab.calibration.transfer.score import (
    GoalTransfer,
    TransferFloor,
    TransferResult,
    TwinScore,
    transfer_floor,
    transfer_report,
)
from simlab.calibration.transfer.steps import (
    optimal_steps,
    policy_steps,
    real_optimal_actions,
    twin_policy,
)

__all__ = [
    "GoalTransfer",
    "QTable",
    "QTableTwin",
    "TransferConfig",
    "TransferFiles",
    "TransferFloor",
    "TransferModel",
    "TransferResult",
    "TwinScore",
    "load_twin",
    "optimal_steps",
    "plot_transfer",
    "policy_from_q",
    "policy_steps",
    "real_optimal_actions",
    "render_transfer_png",
    "transfer_command",
    "transfer_floor",
    "transfer_markdown",
    "transfer_report",
    "twin_columns",
    "twin_policy",
]
