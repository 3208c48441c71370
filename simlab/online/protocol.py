"""The environment's rules of an online run, as one record: simlab's, or the published protocol.

The published navigation experiment (Dromnelle et al. 2022, Int. J. Social Robotics, sec.
4.1) was run by the authors' simulator (their public code "meta-control-decision-making-
agent", ``agentSimulator.py`` and ``manageEnvironment.py``). Its rules, beyond the task
(start states, goal, change), are the fields of :class:`Protocol`; ``PROTOCOLS`` holds
simlab's own choices (``simlab``, the default: each rule the cleaner one) and the published
ones (``published``). The empirical-MDP loop (:mod:`simlab.online.loop`) and the physics
loop read the same record.

The rules (``simlab`` / ``published``):

* ``reset`` — what follows a reward. ``teleport``: the next decision is taken in a start
  state drawn uniformly (the reward ends the episode; the move to the start is no decision).
  ``goal-decision``: the agent takes one more decision in the rewarded state, and that
  decision's move takes it to a start state drawn uniformly, whatever the action (the
  published simulator moves the robot so from the goal; the published model files write
  the same move as the goal's own rows: every action of state 18 leads to 0 or 32). The
  goal's decision is one of the run's decisions, is arbitrated and may plan.
* ``change_pays`` — ``False``: the reward of the decision at the change index is forced
  to 0 (the published simulator does so at decision 1,601 whatever the task, with or
  without a change, because its model file is swapped there).
* ``passage_choice`` — with several passages to close, ``all`` closes them all at once;
  ``more-used`` closes only the one whose counting state saw the most decisions before the
  change (the first listed on ties): the published simulator counts the decisions taken in
  state 19 (towards 20-21) and in state 7 (towards 6-7) and closes 20-21 unless 6-7 was
  used more. Several ``--after`` models are always chosen this way.
* ``first_state`` — ``drawn`` uniformly among the start states, or the ``first`` listed
  (the published run always starts in state 0, the first of its start states 0 and 32).
* ``restart_after`` — when no reward came in the first ``restart_after`` decisions the run
  starts again from its first state with the experts as they are (what they learned is
  kept), the decision counter at 0, the first-visit memory cleared (0: never). The first
  version of the published simulator did so after 200 decisions (``agentSimulator.py``
  1.0, its counter checked after 199 decisions, then 200); the version that reads the
  published after-change files (2.0, with ``loadFiles.py``) has the rule commented out, so
  the published protocol keeps 0 and ``restart_after = 200`` is the early simulator. At
  most :data:`MAX_RESTARTS` times (the simulator would loop forever on a task whose goal
  cannot be reached).
* ``phantom_start`` — the published run begins as if a decision had just been taken in the
  first state: its "previous state" is that state, its "previous action" 0 and its
  "previous reward" 0, so both experts learn the transition ``(s0, 0, 0, s0)`` before the
  first decision, and ``s0`` counts as visited (no first-visit planning there). ``False``:
  nothing is learned before the first decision.

The agent's side of the published rules (ties of the criterion, the goal's moves forgotten
at its first reward, no learning from the rewarded state) lives in
:class:`simlab.online.meta.Arbitration` (``meta.AGENT_RULES``).
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

from simlab.base.errors import ConfigError

__all__ = ["FIRST_STATES", "MAX_RESTARTS", "PASSAGE_CHOICES", "PROTOCOLS", "RESETS",
           "LoopRules", "Protocol"]

RESETS = ("teleport", "goal-decision")
PASSAGE_CHOICES = ("all", "more-used")
FIRST_STATES = ("drawn", "first")

#: Restarts at most (``restart_after``): then the run goes on without reward.
MAX_RESTARTS = 100

#: The protocol as the compiled loop reads it: ``goal_decision`` (bool), ``silent_at``
#: (decision index whose reward is forced to 0, -1 for none), ``first_state`` (-1: drawn),
#: ``restart_after`` (0: never), ``phantom_start`` (bool), ``max_restarts``.
LoopRules = namedtuple("LoopRules", ["goal_decision", "silent_at", "first_state",
                                     "restart_after", "phantom_start", "max_restarts"])


@dataclass(frozen=True)
class Protocol:
    """The environment's rules of an online run (module docstring for each field)."""

    reset: str = "teleport"
    change_pays: bool = True
    passage_choice: str = "all"
    first_state: str = "drawn"
    restart_after: int = 0
    phantom_start: bool = False

    def __post_init__(self) -> None:
        for key, value, allowed in (("reset", self.reset, RESETS),
                                    ("passage_choice", self.passage_choice, PASSAGE_CHOICES),
                                    ("first_state", self.first_state, FIRST_STATES)):
            if value not in allowed:
                raise ConfigError(f"unknown {key} {value!r}", key=key,
                                  fix=f"choose one of {', '.join(allowed)}")
        if not (isinstance(self.restart_after, int) and self.restart_after >= 0):
            raise ConfigError(f"expected a whole number >= 0, got {self.restart_after!r}",
                              key="restart_after")

    def loop_rules(self, change_at: int, first_state: int) -> LoopRules:
        """The :data:`LoopRules` of this protocol for a run whose change (or, without one,
        the index the published simulator swaps its file at) is ``change_at`` and whose
        first listed start state is ``first_state``."""
        return LoopRules(self.reset == "goal-decision",
                         -1 if self.change_pays else int(change_at),
                         int(first_state) if self.first_state == "first" else -1,
                         int(self.restart_after), bool(self.phantom_start), MAX_RESTARTS)

    def as_dict(self) -> dict[str, object]:
        return {"reset": self.reset, "change_pays": self.change_pays,
                "passage_choice": self.passage_choice, "first_state": self.first_state,
                "restart_after": self.restart_after, "phantom_start": self.phantom_start}


#: simlab's rules and the published ones (Dromnelle et al. 2022; module docstring).
PROTOCOLS = {
    "simlab": Protocol(),
    "published": Protocol(reset="goal-decision", change_pays=False, passage_choice="more-used",
                          first_state="first", restart_after=0, phantom_start=True),
}
