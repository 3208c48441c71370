"""``simlab online``: agents learning while they act on an empirical MDP, MB/MF meta-control.

Every *arm* (a criterion; ``entropy_and_cost`` once per ``kappa``) runs ``seeds``
independent runs of ``decisions`` decisions on the task of
:mod:`simlab.online.task` (start states, goal, one change at ``change_at``), through the
fused loop of :mod:`simlab.online.loop`; jobs run in parallel through
:mod:`simlab.base.parallel`. Seeding: ``SeedSequence(seed).spawn(seeds)[i]``, children 0 and 1, give
run ``i`` its environment and agent streams, the same for every arm (common random
numbers: arms differ by their decisions, not by their luck).

Defaults are the published ones (Dromnelle et al. 2022, sec. 3-4): MF Q-learning alpha
0.6, gamma 0.9, softmax inverse temperature beta 50 (``tau = 0.02`` on simlab's reward of
1; ``--protocol published`` uses the published code's ``1 / (1.9 * 50)``, its beta on
rewards of 1.9: :data:`PUBLISHED_TAU`); MB value iteration
on the learned model, gamma 0.9, beta 50, planning until a sweep changes no Q by more than
1e-4 (at most 100 sweeps); cost filter alpha 0.6; start states 0 and 32, goal 18, change at
decision 1,601 (index 1600): goal -> 34, or passages 20 <-> 21 and 6 <-> 7 closed.
Decisions that follow the authors' published implementation of the method (Dromnelle
et al. 2022, sec. 2; their code "meta-control-decision-making-agent", which the papers'
text leaves implicit):

* **MB's model** is a window of the last ``window`` = 10 outcomes of each pair
  (``sliding-window``), so the model follows a change within a few visits; with the
  count model (``vi-softmax``, all outcomes kept) the old goal's mean reward would fade
  as 1/n and MB would not recover from a goal change.
* **Initial values.** Both experts start every value at 1 while their rewards are scaled
  by 1.9, i.e. at ``1 / 1.9`` of a reward: here ``q_init = 1 / 1.9`` for both experts with
  reward 1. An untried action is then worth a little more than a step away from the
  goal, so both explore, but less than the goal.
* **A reward ends the episode** (``reward_ends``): the rewarded state's values are reset
  to 0 (:mod:`simlab.online.meta`). Without it the goal keeps its initial value forever:
  after the goal moves, the old route still leads to a state worth ``q_init`` and MF's
  distribution along it stays certain, so the entropy criteria never hand control back
  to MB.
* **MB's reward is the arrival state's** (``state_reward``): the reward last seen on
  arriving in a state, so one unrewarded arrival at the old goal forgets it; and **both
  experts plan at a state's first visit** (``plan_both_first``), so both have a
  distribution there (:mod:`simlab.online.meta`).
* **Filtered action distributions** (``prob_alpha`` 0.6): the criterion reads each
  expert's action distribution at ``s`` low-pass filtered over its visits, and weighs the
  cost term by ``exp(-kappa * H_MF)`` with MF's entropy in bits
  (:mod:`simlab.online.meta`).

**Protocol.** ``--protocol`` sets every rule of the run at once: ``simlab`` (default), the
rules above with simlab's own cleaner environment (teleport to a start after a reward, ...),
or ``published``, the authors' simulator and experts as their code runs them (the
environment's rules in :mod:`simlab.online.protocol`, the agent's in
:mod:`simlab.online.meta` ``AGENT_RULES``, the experts' in :data:`EXPERT_RULES`). Each rule
is also an option (``--reset``, ``--change-pays``, ``--passage-choice``, ``--first-state``,
``--restart-after``, ``--phantom-start``, ``--ties``, ``--forget-goal-moves``,
``--learn-from-goal``, ``--reward-links``; ``mb_params`` / ``mf_params`` for the experts):
decision: an option given beside the switch wins over it (it is not refused), and
``summary.json`` records the protocol, every rule as applied and the rules given against it.
The cost the criterion reads stays ``backups`` under ``--protocol published`` (runs stay
bit-identical by seed; the published code measured seconds: ``--cost seconds``).

**Changes.** ``--change goal`` / ``passages`` change the task within the run's model;
``--after MODEL`` makes the world another model from ``--change-at`` on (``--change model``,
or with a goal change or passages closed in it): the published goal change and closed
passages are files of the whole lab after the change. Several ``--after`` models (or
``--passages`` under ``--passage-choice more-used``) are alternatives: the one whose
``--use-states`` state saw the most decisions before the change happens (the first listed
on ties), and the summary records, per run, which one and the counts.

Outputs in ``out`` (one output transaction: all or nothing):

* ``decisions.parquet`` — one row per decision: ``arm``, ``seed`` (run index), ``t``,
  ``s``, ``a``, ``s_next``, ``expert`` (``MF``/``MB``), ``h_mf``, ``h_mb`` (normalised
  entropies), ``c_mf``, ``c_mb`` (filtered costs read by the criterion), ``backups``,
  ``seconds`` (the chosen expert's planning cost, deterministic and wall clock),
  ``reward``, ``phase``;
* ``cumulative_reward.png``, ``cumulative_cost.png``, ``mb_share.png`` (mean over runs,
  change marked);
* ``summary.json`` and ``summary.md`` — per arm: reward (total, before / after the
  change), cost in backups and seconds (absolute and relative to ``mb``), MB share (total
  and per window), recovery after the change, restarts and the alternative chosen by use;
  the protocol and its rules.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base import validation as v
from simlab.base.errors import ConfigError
from simlab.base.options import command, option
from simlab.online.arena import PHYSICS_FILES, ArenaOptions
from simlab.online.meta import AGENT_RULES, CRITERIA, TIES
from simlab.online.protocol import FIRST_STATES, PASSAGE_CHOICES, PROTOCOLS, RESETS, Protocol

__all__ = ["EXPERT_RULES", "MB_DEFAULTS", "MF_DEFAULTS", "OnlineConfig", "OnlineResult",
           "arm_names", "online", "run_arm"]

#: Published settings applied to the MF expert when its preset has the field.
MF_DEFAULTS = {"alpha": 0.6, "gamma": 0.9, "tau": 0.02, "q_init": 1.0 / 1.9}
#: Published settings applied to the MB expert when its preset has the field.
MB_DEFAULTS = {"gamma": 0.9, "tau": 0.02, "q_init": 1.0 / 1.9, "max_sweeps": 100, "tol": 1e-4,
               "plan_every": 0, "window": 10}
#: The published softmax temperature on simlab's reward scale: the published experts draw
#: with ``exp(beta Q)``, beta 50, on values whose rewards are scaled by 1.9 (a reward is
#: worth 1.9, a value starts at 1: ``modelFree.py``, ``modelBased.py``,
#: ``utility.softmax_actions_prob``), i.e. ``exp(Q / tau)`` with ``tau = 1 / (1.9 * 50)`` on
#: values whose reward is 1. simlab's default keeps ``tau = 1 / 50``.
PUBLISHED_TAU = 1.0 / (1.9 * 50.0)
#: The experts' side of each protocol, over the defaults above: the published temperature
#: (:data:`PUBLISHED_TAU`), and the published MB expert changes its values only when it
#: plans (``modelBased.py``: no backup after a transition), so between its plans its
#: distribution at a state is the one of its last plan.
EXPERT_RULES: dict[str, dict[str, dict[str, Any]]] = {
    "simlab": {"mf": {}, "mb": {}},
    "published": {"mf": {"tau": PUBLISHED_TAU},
                  "mb": {"tau": PUBLISHED_TAU, "incremental": False}},
}

CHANGES = ("none", "goal", "passages", "model")
#: The options that override one rule of ``--protocol`` (environment, then agent).
RULE_OPTIONS = ("reset", "change_pays", "passage_choice", "first_state", "restart_after",
                "phantom_start", "ties", "forget_goal_moves", "learn_from_goal", "reward_links")
FILES = ("decisions.parquet", "cumulative_reward.png", "cumulative_cost.png", "mb_share.png",
         "summary.json", "summary.md")
_PLOTS = FILES[1:4]


def _expert_config(name: str, defaults: dict[str, Any], params: Any, key: str) -> Any:
    from simlab.agents.config import config_to_dict
    from simlab.agents.registry import agent_config

    if params is not None and not isinstance(params, dict):
        raise ConfigError(f"expected a table of overrides, got {params!r}", key=key)
    preset = config_to_dict(agent_config(name))
    merged = {k: val for k, val in defaults.items() if k in preset}
    merged.update(params or {})
    try:
        return agent_config(name, merged)
    except ConfigError as exc:
        raise ConfigError(exc.problem, key=f"{key}.{exc.key}" if exc.key else key,
                          fix=exc.fix) from None


@dataclasses.dataclass(frozen=True, kw_only=True)
class OnlineConfig(ArenaOptions):
    """Options of ``simlab online`` / :func:`online` (module docstring; the physics options
    of :class:`~simlab.online.arena.ArenaOptions`)."""

    COMMAND = "online"
    ARGUMENTS = ("mdp",)

    mdp: Any | None = option(None, "mdp.npz written by simlab estimate (Python: or an "
                             "EmpiricalMDP); or --arena to learn in physics", positional=True,
                             parse=Path)
    out: Path | None = option(None, "output directory (required; Python: None writes "
                              "nothing)")
    criteria: tuple[str, ...] = option(
        CRITERIA, f"arbitration criteria to compare, any of {', '.join(CRITERIA)} "
        "(mf / mb: that expert always decides)", metavar="NAME")
    kappas: tuple[float, ...] = option(
        (1.0,), "kappa values of entropy_and_cost (one arm each)",
        metavar="K")
    decisions: int = option(3200, "decisions per run")
    seeds: int = option(10, "independent runs per arm")
    seed: int = option(0, "root seed")
    goal: tuple[int, ...] = option((18,), "goal state(s): reward 1 on arrival, then restart",
                                   metavar="S")
    start_states: tuple[int, ...] = option(
        (0, 32), "start states, drawn uniformly after each reward",
        metavar="S")
    change: str = option("none", "what changes at --change-at: nothing, the goal (to "
                         "--new-goal), passages (--passages close) or the model (the --after "
                         "model)", choices=CHANGES)
    change_at: int = option(1600, "index of the first decision in the changed task "
                            "(0-based: 1600 is decision 1,601)")
    new_goal: tuple[int, ...] = option((34,), "goal state(s) after a goal change",
                                       metavar="S")
    passages: tuple[str, ...] = option(("20-21", "6-7"), "passages U-V closed by a passage "
                                       "change (both directions removed)",
                                       metavar="U-V")
    after: tuple[Any, ...] = option(
        (), "from --change-at the world is this model (an mdp.npz of simlab estimate, from a "
        "dataset or a counts file; the same states and actions): with --change model, goal "
        "or passages; several with --change model: the one whose --use-states state saw the "
        "most decisions (Python: or EmpiricalMDPs)", parse=Path, metavar="MODEL")
    use_states: tuple[int, ...] = option(
        (19, 7), "the counting state of each alternative (each --after model, or each "
        "--passages passage under --passage-choice more-used): the one whose state saw the "
        "most decisions before the change happens, the first on ties (published: 19 towards "
        "20-21, 7 towards 6-7)", metavar="S")
    protocol: str = option("simlab", "the rules of the run (options below override each): "
                           "simlab's own, or the published experiment's (Dromnelle et al. "
                           "2022: a decision in the goal before the restart, the change's "
                           "decision unrewarded, the more used passage closed, first state "
                           "the first start state, a phantom first transition, coin-tossed "
                           "ties, the goal's moves forgotten, MB's goal reward only for the "
                           "moves rewarded into it, MB planning only when it decides, the "
                           "published temperature)",
                           choices=tuple(PROTOCOLS))
    reset: str | None = option(None, "after a reward: teleport to a start state (simlab) or "
                               "one more decision in the goal whose move goes to a start "
                               "state (goal-decision, published)", choices=RESETS)
    change_pays: bool | None = option(None, "the decision at --change-at can be rewarded "
                                      "(simlab); --no-change-pays forces its reward to 0, "
                                      "with or without a change (published)")
    passage_choice: str | None = option(None, "close every --passages passage (all, simlab) "
                                        "or only the more used (more-used, published; "
                                        "counted by --use-states)", choices=PASSAGE_CHOICES)
    first_state: str | None = option(None, "the run's first state: drawn among the start "
                                     "states (drawn, simlab) or the first listed (first, "
                                     "published)", choices=FIRST_STATES)
    restart_after: int | None = option(None, "a run without reward in its first N decisions "
                                       "starts again, the experts keeping what they learned "
                                       "(0: never, simlab and published; 200: the first "
                                       "version of the published simulator)", metavar="N")
    phantom_start: bool | None = option(None, "the experts learn (first state, action 0, "
                                        "reward 0, first state) before the first decision, "
                                        "the published simulator's fictitious previous "
                                        "decision (simlab: no)")
    ties: str | None = option(None, "ties of entropy and entropy_and_cost go to MF (mf, "
                              "simlab) or to a fair coin (random, published)", choices=TIES)
    forget_goal_moves: bool | None = option(None, "MB forgets the moves of a state the first "
                                            "time it pays, so a goal's value stays 0 "
                                            "(published; simlab: kept)")
    learn_from_goal: bool | None = option(None, "learn the transition that starts where a "
                                          "reward was just obtained, the goal-decision "
                                          "reset's move (published: no; simlab: yes, and its "
                                          "teleport makes none)")
    reward_links: bool | None = option(None, "MB's reward of arriving in a goal counts only "
                                       "for the moves once rewarded into it (published); "
                                       "simlab: for every move that reached it")
    mf: str = option("q-softmax", "agent of the MF expert (simlab agent name)")
    mb: str = option("sliding-window", "agent of the MB expert (simlab agent name)")
    mf_params: Any | None = option(None, "overrides of the MF expert {name: value} (over "
                                   "the published alpha 0.6, gamma 0.9, tau 0.02; q_init 1/1.9)",
                                   cli=False)
    mb_params: Any | None = option(None, "overrides of the MB expert {name: value} (over "
                                   "gamma 0.9, tau 0.02, q_init 1/1.9, max_sweeps 100, tol 1e-4, "
                                   "window 10)", cli=False)
    cost: str = option("backups", "cost the criterion reads: backups (deterministic, "
                       "bit-identical seeded runs) or seconds (wall clock, as published)",
                       choices=("backups", "seconds"))
    cost_alpha: float = option(0.6, "rate of the per-state low-pass cost filter, in (0, 1]")
    prob_alpha: float = option(0.6, "rate of the per-state low-pass filter of each expert's "
                               "action distribution, in (0, 1] (1: the last softmax)")
    reward_ends: bool = option(True, "a reward ends the episode: the rewarded state's values "
                               "are reset to 0 (--no-reward-ends keeps them)")
    state_reward: bool = option(True, "MB's reward model is the reward last seen on arriving "
                                "in each state, as published (--no-state-reward: the mean "
                                "reward of each pair's window)")
    plan_both_first: bool = option(True, "both experts plan at a state's first visit, as "
                                   "published (--no-plan-both-first: only the chosen one)")
    window: int = option(200, "decisions per bin of the MB-share curve and of recovery")
    workers: int | None = option(None, "local worker processes (default: the cores; 1: in "
                                 "this process); with --backend ray the cluster's CPUs run "
                                 "the runs and --workers is not used (as in collect)")
    backend: str = option("local", "where runs execute", choices=("local", "ray"))
    plots: bool = option(True, "the PNG figures (--no-plots skips them)")
    overwrite: bool = option(False, "replace outputs a previous simlab online wrote")
    progress: bool = option(True, "progress bar (--no-progress hides it)")

    def validate(self) -> None:
        if (self.mdp is None) == (self.arena is None):
            raise ConfigError("give exactly one world: an MDP file or --arena",
                              key="mdp", fix="simlab online mdp.npz ..., or simlab online "
                              "--arena lab.toml --states states.json ...")
        self.check_arena_options()
        if self.arena is not None and (self.after or self.change == "model"):
            raise ConfigError("a run in physics changes its world itself (a goal change, "
                              "boxes on closed passages), not by a model", key="after",
                              fix="use --change goal or --change passages, or learn on an "
                              "MDP")
        if self.closing != "box" and self.change != "passages":
            raise ConfigError(f"--closing {self.closing} is how --change passages closes a "
                              f"passage; this run's change is {self.change}", key="closing",
                              fix="add --change passages or drop --closing")
        v.whole(self.decisions, "decisions", minimum=1)
        v.whole(self.seeds, "seeds", minimum=1)
        v.whole(self.seed, "seed")
        v.whole(self.window, "window", minimum=1)
        if self.workers is not None:
            v.whole(self.workers, "workers", minimum=1)
        if not self.criteria:
            raise ConfigError("no criterion given", key="criteria")
        for c in self.criteria:
            if c not in CRITERIA:
                raise ConfigError(f"unknown criterion {c!r}", key="criteria",
                                  fix=f"choose among {', '.join(CRITERIA)}")
        if len(set(self.criteria)) != len(self.criteria):
            raise ConfigError(f"criterion listed twice in {list(self.criteria)}",
                              key="criteria")
        if not self.kappas:
            raise ConfigError("no kappa given", key="kappas")
        for k in self.kappas:
            v.positive(k, "kappas", allow_zero=True)
        for key in ("cost_alpha", "prob_alpha"):
            rate = getattr(self, key)
            if not (isinstance(rate, int | float) and 0.0 < rate <= 1.0):
                raise ConfigError(f"expected a rate in (0, 1], got {rate!r}", key=key)
        if self.change != "none" and not 1 <= self.change_at < self.decisions:
            raise ConfigError(f"expected a decision in 1..{self.decisions - 1}, got "
                              f"{self.change_at}", key="change_at",
                              fix="the change must happen during the run")
        if self.after and self.change == "none":
            raise ConfigError("--after gives the world after a change, and there is none",
                              key="after", fix="add --change model (or goal, passages)")
        if self.restart_after is not None:
            v.whole(self.restart_after, "restart_after")
        self.rules()
        self.task()
        self.expert_configs()
        self.arbitration(self.criteria[0], self.kappas[0])

    def _protocol_rule(self, name: str) -> Any:
        """Rule ``name`` of :data:`RULE_OPTIONS` as ``--protocol`` sets it."""
        from simlab.online.meta import Arbitration

        if name in Protocol.__dataclass_fields__:
            return getattr(PROTOCOLS[self.protocol], name)
        return AGENT_RULES[self.protocol].get(name, getattr(Arbitration, name))

    def _rule(self, name: str) -> Any:
        """Rule ``name``: the option when given (it wins over ``--protocol``), else the
        protocol's."""
        given = getattr(self, name)
        return self._protocol_rule(name) if given is None else given

    def rules(self) -> Protocol:
        """The environment's :class:`~simlab.online.protocol.Protocol` of these options: the
        ``--protocol``'s, each rule given explicitly winning over it."""
        return Protocol(**{k: self._rule(k) for k in Protocol.__dataclass_fields__})

    def rules_summary(self) -> dict[str, Any]:
        """The protocol, every rule as applied and those given against it (JSON-ready)."""
        return {"name": self.protocol, "rules": {k: self._rule(k) for k in RULE_OPTIONS},
                "overridden": [k for k in RULE_OPTIONS
                               if self._rule(k) != self._protocol_rule(k)]}

    def task(self, after: tuple[Any, ...] | None = None, names: tuple[str, ...] = ()) -> Any:
        """The :class:`~simlab.online.task.OnlineTask` of these options; ``after`` the
        ``(S, A, S)`` models of ``--after`` once read (default: the option's values, enough
        to check the task)."""
        from simlab.online.task import Change, OnlineTask, parse_passages

        after = self.after if after is None else after
        changes = ()
        by_use = self.use_states if (len(after) > 1 or (
            self.change == "passages" and self.rules().passage_choice == "more-used"
            and len(self.passages) > 1)) else ()
        if self.change == "goal":
            changes = (Change(self.change_at, "goal", goal=self.new_goal, after=after,
                              names=names),)
        elif self.change == "passages":
            changes = (Change(self.change_at, "passages", after=after, names=names,
                              passages=parse_passages(self.passages), use_states=by_use),)
        elif self.change == "model":
            changes = (Change(self.change_at, "model", after=after, names=names,
                              use_states=by_use),)
        return OnlineTask(goal=self.goal, start_states=self.start_states, changes=changes)

    def loop_rules(self) -> Any:
        """The compiled loop's :data:`~simlab.online.protocol.LoopRules` of these options."""
        return self.rules().loop_rules(self.change_at, self.start_states[0])

    def arbitration(self, criterion: str, kappa: float) -> Any:
        """The :class:`~simlab.online.meta.Arbitration` of one arm of these options."""
        from simlab.online.meta import Arbitration

        return Arbitration(criterion=criterion, kappa=float(kappa), cost_alpha=self.cost_alpha,
                           use_time=self.cost == "seconds", prob_alpha=self.prob_alpha,
                           reward_ends=self.reward_ends, state_reward=self.state_reward,
                           plan_both_first=self.plan_both_first, ties=self._rule("ties"),
                           forget_goal_moves=self._rule("forget_goal_moves"),
                           learn_from_goal=self._rule("learn_from_goal"),
                           reward_links=self._rule("reward_links"))

    def expert_configs(self) -> tuple[Any, Any]:
        """The agent configs of the MF and MB experts (published defaults, the protocol's
        :data:`EXPERT_RULES`, then ``mf_params`` / ``mb_params``)."""
        rules = EXPERT_RULES[self.protocol]
        return (_expert_config(self.mf, {**MF_DEFAULTS, **rules["mf"]}, self.mf_params,
                               "mf_params"),
                _expert_config(self.mb, {**MB_DEFAULTS, **rules["mb"]}, self.mb_params,
                               "mb_params"))


def arm_names(criteria: tuple[str, ...], kappas: tuple[float, ...]) -> list[tuple[str, str, float]]:
    """``(arm name, criterion, kappa)`` of every arm: ``entropy_and_cost`` once per kappa,
    named ``entropy_and_cost_k1`` (``k0.5``...)."""
    arms = []
    for c in criteria:
        if c == "entropy_and_cost":
            arms += [(f"entropy_and_cost_k{k:g}", c, float(k)) for k in kappas]
        else:
            arms.append((c, c, 0.0))
    return arms


def run_arm(T: np.ndarray, task: Any, mf_config: Any, mb_config: Any, arbitration: Any,
            valid: np.ndarray | None, decisions: int, seed: np.random.SeedSequence,
            rules: Any = None) -> dict[str, np.ndarray]:
    """One run (module-level: a parallel job): fresh experts arbitrated by
    ``arbitration`` (:class:`~simlab.online.meta.Arbitration`), ``decisions`` decisions on
    the compiled ``task`` of ``T`` (S, A, S) under the loop ``rules``
    (:data:`~simlab.online.protocol.LoopRules`; None: simlab's). Returns the log columns
    and the run's :data:`~simlab.online.loop.RUN_FIELDS` (``restarts`` () int64,
    ``use_counts`` (P,) int64)."""
    from simlab.online.loop import run_online
    from simlab.online.physics import children

    env_seed, agent_seed = children(seed, 2)
    S, A = T.shape[:2]
    agent = arbitration.agent(mf_config, mb_config, S, A, valid=valid)
    log = run_online(agent, task.compile(T), decisions, np.random.default_rng(env_seed),
                     np.random.default_rng(agent_seed), rules)
    return {**log.columns(), "restarts": np.asarray(log.restarts, dtype=np.int64),
            "use_counts": log.use_counts}


def _after_models(cfg: OnlineConfig, m: Any) -> tuple[tuple[np.ndarray, ...], tuple[str, ...]]:
    """The ``(S, A, S)`` models of ``--after`` and their names, each read and checked
    against the run's MDP ``m`` (same states and actions)."""
    from simlab.data.mdp import EmpiricalMDP, load_mdp

    models, names = [], []
    for i, item in enumerate(cfg.after):
        after = item if isinstance(item, EmpiricalMDP) else load_mdp(v.existing_file(
            item, "after", what="MDP file"))
        name = str(after.source) if after.source is not None else f"--after model {i + 1}"
        if (after.n_states, after.n_actions) != (m.n_states, m.n_actions):
            raise ConfigError(f"{after.n_states} states x {after.n_actions} actions, the MDP "
                              f"has {m.n_states} x {m.n_actions}", path=after.source,
                              key="after", fix="give the model of the same lab after the "
                              "change (the same states and actions)")
        models.append(np.asarray(after.T, dtype=np.float64))
        names.append(name)
    return tuple(models), tuple(names)


@dataclasses.dataclass(frozen=True)
class OnlineResult:
    """What :func:`online` did: ``logs[arm]`` (runs,) list of log-column dicts,
    ``summary`` (JSON-ready, see :func:`simlab.online.report.summarize`), ``files`` the
    final paths written (empty without ``out``), ``seconds`` wall time."""

    logs: dict[str, list[dict[str, np.ndarray]]]
    summary: dict[str, Any]
    files: dict[str, Path]
    seconds: float


@dataclasses.dataclass(frozen=True)
class _World:
    """What the arms run on: ``info`` (``source``, ``n_states``, ``n_actions`` of the MDP
    or the physics lab), the ``task``, the ``jobs`` (keyword arguments per run) and the job
    function ``run``; ``lab`` the physics lab (None on an MDP)."""

    info: Any
    task: Any
    jobs: list[dict[str, Any]]
    run: Any
    lab: Any = None
    #: with ``--ensemble``: the member each run index drove, and the ensemble's size
    run_members: tuple[int, ...] | None = None
    ensemble_size: int = 0


def _mdp_world(cfg: OnlineConfig, arms: list[tuple[str, str, float]], seeds: list[Any],
               mf_cfg: Any, mb_cfg: Any) -> _World:
    from simlab.data.mdp import EmpiricalMDP, load_mdp

    m = cfg.mdp if isinstance(cfg.mdp, EmpiricalMDP) else load_mdp(v.existing_file(
        cfg.mdp, "mdp", what="MDP file"))
    after, names = _after_models(cfg, m)
    task = cfg.task(after, names)
    task.compile(m.T, source=m.source)  # state ids checked before any work
    rules = cfg.loop_rules()
    jobs = [dict(T=np.asarray(m.T), task=task, mf_config=mf_cfg, mb_config=mb_cfg,
                 arbitration=cfg.arbitration(crit, kappa), valid=m.valid,
                 decisions=cfg.decisions, seed=seeds[i], rules=rules)
            for _, crit, kappa in arms for i in range(cfg.seeds)]
    return _World(m, task, jobs, run_arm)


def _physics_world(cfg: OnlineConfig, arms: list[tuple[str, str, float]], seeds: list[Any],
                   mf_cfg: Any, mb_cfg: Any) -> _World:
    from types import SimpleNamespace

    from simlab.online.arena import PhysicsJob, physics_lab, physics_task, run_physics_job
    from simlab.physics.primitive_options import ensemble_members

    lab = physics_lab(cfg)
    task = physics_task(cfg, lab)
    rules = cfg.loop_rules()
    members = cfg.primitive_ensemble()
    labs, run_members = [lab] * cfg.seeds, None
    if members is not None:  # run i drives its member in every arm (common random numbers)
        run_members = tuple(ensemble_members(cfg.seed, cfg.seeds, len(members)))
        by_member = [dataclasses.replace(lab, params=m) for m in members]
        labs = [by_member[m] for m in run_members]
    jobs = [dict(job=PhysicsJob(labs[i], task, mf_cfg, mb_cfg, cfg.arbitration(crit, kappa),
                                rules),
                 seed=seeds[i]) for _, crit, kappa in arms for i in range(cfg.seeds)]
    source = cfg.arena if isinstance(cfg.arena, str | Path) else lab.arena.name
    info = SimpleNamespace(source=str(source), n_states=lab.n_states, n_actions=lab.n_actions)
    return _World(info, task, jobs, run_physics_job, lab, run_members,
                  0 if members is None else len(members))


def _run_jobs(cfg: OnlineConfig, world: _World, ex: Any) -> list[Any]:
    if world.lab is None:
        return ex.map(run_arm, world.jobs, desc="online runs", progress=cfg.progress)
    from simlab.online.arena import run_physics_jobs

    return run_physics_jobs(world.jobs, ex, cfg.progress, len(world.jobs) * cfg.decisions)


@command(OnlineConfig, extras=("executor",))
def online(cfg: OnlineConfig, executor: Any = None) -> OnlineResult:
    """Run every arm of ``cfg`` on its MDP, or in physics on its arena, and write the
    outputs (module docstring; :mod:`simlab.online.arena`).

    ``executor`` (Python only): a :mod:`simlab.base.parallel` executor the runs go to (e.g. the
    one of ``simlab reproduce``); default: one of ``backend`` / ``workers``, closed after.
    """
    import contextlib

    from simlab.base.io import output_transaction
    from simlab.base.parallel import make_executor
    from simlab.online.report import owned_by_online

    t0 = time.perf_counter()
    mf_cfg, mb_cfg = cfg.expert_configs()
    arms = arm_names(cfg.criteria, cfg.kappas)
    seeds = np.random.SeedSequence(cfg.seed).spawn(cfg.seeds)
    world = (_physics_world if cfg.in_physics else _mdp_world)(cfg, arms, seeds, mf_cfg,
                                                               mb_cfg)
    m = world.info
    out = cfg.out
    every = FILES + PHYSICS_FILES if world.lab is not None else FILES
    finals: dict[str, Path] = {}
    if out is not None:
        names = every if cfg.plots else tuple(f for f in every if f in FILES
                                              and f not in _PLOTS)
        finals = {n: Path(out) / n for n in names}
        if m.source is not None and any(Path(m.source).resolve() == p.resolve()
                                        for p in finals.values()):
            raise ConfigError("an output would replace an input file", path=m.source,
                              key="out", fix="choose another --out")
        if cfg.overwrite and any(p.exists() for p in finals.values()) \
                and not owned_by_online(Path(out)):
            raise ConfigError("--overwrite replaces only the outputs of an earlier simlab "
                              "online (its summary.json is missing or not ours)", path=out,
                              key="overwrite", fix="choose another --out")
    with contextlib.ExitStack() as stack:
        txn = None
        if out is not None:  # refuses existing outputs and takes the lock before the runs
            txn = stack.enter_context(output_transaction(out, finals.values(),
                                                         overwrite=cfg.overwrite))
            if cfg.overwrite and owned_by_online(Path(out)):
                for name in sorted(set(FILES + PHYSICS_FILES) - set(finals)):
                    txn.retire(Path(out) / name)  # the ones not written again
        if executor is not None:
            results = _run_jobs(cfg, world, executor)
        else:
            # Ray runs on its cluster's CPUs: --workers is for the local pool (as collect)
            workers = None if cfg.backend == "ray" else cfg.workers
            with make_executor(cfg.backend, workers=workers, in_process_single=True) as ex:
                results = _run_jobs(cfg, world, ex)
        logs = {name: results[j * cfg.seeds:(j + 1) * cfg.seeds]
                for j, (name, _, _) in enumerate(arms)}
        from simlab.online.report import summarize, write_outputs

        summary = summarize(logs, cfg, world.task, m, mf_cfg, mb_cfg)
        if world.lab is not None:
            from simlab.online.arena import physics_summary

            at = world.task.changes[0].at if world.task.changes else None
            summary["physics"] = physics_summary(logs, at, world.lab.physics_hz,
                                                 world.run_members, world.ensemble_size)
        summary["seconds"] = round(time.perf_counter() - t0, 3)
        if txn is not None:
            extra: dict[str, Any] = {}
            if world.lab is not None:
                from simlab.online.arena import PHYSICS_RUN_FIELDS
                from simlab.online.physics_plots import physics_figures

                extra = dict(run_fields=PHYSICS_RUN_FIELDS, extra_figures=physics_figures(
                    logs, world.lab, world.task, cfg.window) if cfg.plots else None)
            write_outputs(txn, finals, logs, summary, cfg, **extra)
    return OnlineResult(logs=logs, summary=summary, files=finals,
                        seconds=time.perf_counter() - t0)
