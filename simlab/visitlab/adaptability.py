"""Adaptability to a new human (thesis 4.4.1 and Fig. 4.7; IMOL poster Fig. 6).

The social module is trained with one human (:func:`~simlab.visitlab.training.run_seed`
on the social task), then **continues learning inside the combined architecture**
(:mod:`simlab.visitlab.combined`) with another human, while the navigation and
go-to-human modules stay frozen. The measure is goal rooms reached per trial, over
trials: does the agent recover its performance?

The three humans of Fig. 4.7 (:func:`thesis_humans`):

* **same** — the training human;
* **2x slower** — the same human walking half as fast;
* **pointing need** — the same human with ``P_H = 1`` (COME always leaves it
  waiting for POINTING).

Decision (the thesis does not say which human it trained with): the training human is
the *easy* human walking **2 cells per step** (``s_H = (0, 1, 0)``, every other
parameter 0), so that "two times slower" is a human of the grid — 1 cell per step, the
thesis's easy human exactly. The thesis's explanation of the failure supports it: the
agent "must learn to move slowly ... Among all 25 dynamic actions, only 8 moves at
one-step", i.e. the trained agent used faster moves, which a 1-cell human cannot follow.

Decision (what continues): the continuing agent keeps **its Q table and its model**
(counts and rewards of the social task), ``carry_model=True`` — the same agent goes on
learning, and "a model of one human" (the poster) is what it must revise; its new
experience is added to the old counts, so an agent that saw thousands of transitions
of the old human needs many of the new one to change its mind. ``carry_model=False``
is the thesis's literal procedure ("save the Q(s, a) obtained after a training phase
with one human, and then ... exploit it with another class of human"): the learned Q
is the start, the model is rebuilt from the new human only.

The continuing agent is the training agent's config (thesis: model-based
epsilon-greedy, 50 value-iteration sweeps every 10,000 steps); its planning clock
restarts at 0. It learns from the social module's own reward in the combined task
(level 7 and the human moved in the required direction, now given by navigation).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from simlab.agents.config import QLearningConfig
from simlab.base.errors import ConfigError
from simlab.visitlab import dynamics as dyn
from simlab.visitlab.combined import CombinedRun, CombinedTask, Modules, combined_chunk, new_out
from simlab.visitlab.fused import make_learner, model_from_state, model_state
from simlab.visitlab.humans import Human

#: The training human of the adaptability study (see the module docstring).
BASE_HUMAN = Human((0.0, 1.0, 0.0), 0.0, 0.0, 0.0, 0.0, 0.0, name="easy, 2 cells/step")


def thesis_humans(base: Human = BASE_HUMAN) -> dict[str, Human]:
    """The three humans of Fig. 4.7 for a training human ``base`` walking 2 cells per
    step: ``same``, ``slower`` (1 cell per step) and ``pointing`` (``P_H = 1``)."""
    if tuple(base.speed_probs) != (0.0, 1.0, 0.0):
        raise ConfigError("a 2x slower human needs a training human walking 2 cells per step "
                          f"(speed_probs (0, 1, 0)), got {base.speed_probs}", key="human",
                          fix="give the three humans explicitly")
    return {
        "same": base,
        "slower": base.with_(speed_probs=(1.0, 0.0, 0.0), name=f"{base.name}, 2x slower"),
        "pointing": base.with_(pointing_need=1.0, name=f"{base.name}, pointing need"),
    }


def continue_learning(task: CombinedTask, modules: Modules, agent_cfg: Any, trials: int,
                      gens: tuple[np.random.Generator, np.random.Generator], *,
                      model: Mapping[str, np.ndarray] | None = None) -> CombinedRun:
    """Run ``trials`` combined trials while the social module keeps learning.

    ``agent_cfg`` is the social agent's config (from
    :func:`~simlab.visitlab.fused.loop_agent_config`); its Q starts at
    ``modules.social_q``; ``model`` (from :func:`~simlab.visitlab.fused.model_state`)
    is the model it continues with (None: an empty model). ``gens`` = ``(env_rng,
    agent_rng)``. Returns goals and social rewards per trial, the final Q table and,
    for a model-based agent, the final model.
    """
    task.check_modules(modules)
    if isinstance(trials, bool) or not isinstance(trials, int | np.integer) or trials < 1:
        raise ConfigError(f"expected an integer >= 1, got {trials!r}", key="trials")
    lr = make_learner(agent_cfg, dyn.N_SOCIAL_STATES, 30)
    lr.Q[...] = modules.social_q
    if model is not None:
        if tuple(int(x) for x in model["shape"]) != (dyn.N_SOCIAL_STATES, 30):
            raise ConfigError(f"expected a social model (2560 x 30), got {tuple(model['shape'])}",
                              key="model")
        lr = lr._replace(model=model_from_state(dict(model)))
    out = new_out(trials)
    combined_chunk(task.kernel_args(modules), lr, True, gens[0], gens[1], 0, 0, out)
    final = None if isinstance(agent_cfg, QLearningConfig) else model_state(lr.model)
    return CombinedRun(out.goals, out.rewards, lr.Q, final)
