"""The social random walk: an empirical social MDP's data, as a simlab dataset (thesis 3.2.5).

:func:`social_walk` drives :class:`~simlab.social.task.SocialTable` with actions drawn
by a behaviour policy over the 22 social actions (uniform, or least-tried: below) and
records every decision: the observed social
state ``s`` (0-2559, the grid's index of interaction level, distance class, required
direction and angle; :func:`decode_social`), the action, ``s'``, the social reward, the
start time and duration (simulated s), the robot's and the human's poses before and after,
and whether a primitive was blocked. :func:`write_social_dataset` writes it through the
public writer :func:`simlab.data.writer.write_dataset`, so ``simlab estimate``, the entropy
and the coverage read it like any navigation dataset.

Decisions:

* **Episodes.** The walk restarts (new random robot and human poses, new required
  direction) every ``episode_steps`` decisions (default 40, the grid's social trial
  length), so that the data covers the table rather than one corner of it; transitions
  never cross a restart, the clock runs on.
* **Seeds and segments.** ``workers`` is the number of independent walk *segments*
  (``steps`` decisions each). Segment ``w`` draws from ``SeedSequence(seed).spawn(workers)[w]``:
  one stream for the actions, one for the episodes' seeds of :meth:`SocialTable.reset`. A
  segment depends only on ``(seed, w, steps, episode_steps, policy, social)``: segment ``w``
  is the same whatever the number of segments, and the first ``k`` segments of a longer
  collection are a smaller one (nested budgets). Same seed, segments and budget -> the
  same dataset (content).
* **Parallel segments**: :func:`social_walk` ``processes=N`` runs the
  segments as jobs of a :mod:`simlab.base.parallel` executor (the ``local`` process pool of
  ``simlab collect``, or ``ray``), each job on its own PyBullet world; results come back
  in segment order, so the data do not depend on ``processes`` (a test checks 1 vs 2).
  With ``processes=1`` the segments run one after the other on one world in this process.
  A caller that already has an executor (``simlab reproduce``'s) passes it as ``executor``:
  the same jobs run there, no second pool is started.
* **Behaviour policy** (``policy``, decision): ``"uniform"`` draws each action uniformly
  from the 22 (the first version; one draw of the action stream per decision).
  ``"least-tried"`` seeks coverage: at each decision it picks uniformly among the actions
  tried least often so far *in this segment* at the current observation pooled over the
  required direction (level, distance class, angle: the pooled states of
  :func:`simlab.social.empirical.pooled_model`; one draw per decision). So at a pooled
  observation the counts of the 22 actions never differ by more than one. Any behaviour
  policy is valid for estimating ``P(s' | s, a)``: the count estimate conditions on the
  action taken, and the task's dynamics do not depend on why it was taken (the walk has
  no memory the task can see); the policy changes only *which* pairs get data. The
  measured rewards ``R(s, a)`` are likewise per pair.
* **Columns.** The dataset schema is the navigation one: ``x, y, yaw`` are the robot's
  poses (true pose, ``pose_source="truth"``); ``s, s_next`` are the social states. The
  human's poses and the rewards do not fit the schema; they stay in the returned
  :class:`SocialWalk` (and the dataset's provenance records the total reward).
* **States record.** The dataset's discretizer is :class:`SocialStates`: 2560 states whose
  ``centres`` are chart coordinates, not metres (x = level * 5 + distance class,
  y = required direction * 8 + angle), and which has no poses -> states mapping.
* **Actions.** 22 actions are not an :class:`~simlab.base.actions.ActionSet` (8 or 16
  primitives): the manifest records ``action_set: null`` and ``parameters.action_names``
  (:data:`ACTION_NAMES`), the writer's ``DatasetInfo.action_names``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.physics.motion import N_ACTIONS
from simlab.social.actions import N_SOCIAL_ACTIONS, SocialAction
from simlab.social.perception import SOCIAL_DIMS
from simlab.social.task import SocialConfig, SocialTable

#: Number of social states (levels 8 x distance classes 5 x directions 8 x angles 8).
N_SOCIAL_STATES = int(np.prod(SOCIAL_DIMS))

#: Number of observations pooled over the required direction (level x distance x angle).
N_POOLED_STATES = N_SOCIAL_STATES // SOCIAL_DIMS[2]

#: Behaviour policies of the walk (:attr:`WalkConfig.policy`, module docstring).
WALK_POLICIES = ("uniform", "least-tried")

_DIRS = ("up", "down", "left", "right", "up-left", "up-right", "down-left", "down-right")
#: Name of every social action, index order (the manifest's ``parameters.action_names``).
ACTION_NAMES: tuple[str, ...] = tuple(
    f"{'slow' if a < 8 else 'fast'}-{_DIRS[a % 8]}" for a in range(N_ACTIONS)
) + tuple(a.name for a in SocialAction)


def decode_social(s: NDArray[np.int64] | int) -> NDArray[np.int64]:
    """Social state index -> ``(..., 4)`` ``(level, distance class, required direction,
    angle)``; raises ValueError outside 0..2559."""
    arr = np.asarray(s, dtype=np.int64)
    if arr.size and (arr.min() < 0 or arr.max() >= N_SOCIAL_STATES):
        raise ValueError(f"social states are 0..{N_SOCIAL_STATES - 1}, got {arr.min()}.."
                         f"{arr.max()}")
    return np.stack(np.unravel_index(arr, SOCIAL_DIMS), axis=-1).astype(np.int64)


class SocialStates:
    """The 2560 social states as a dataset discretizer (module docstring, "States record")."""

    n_states = N_SOCIAL_STATES

    @property
    def centres(self) -> NDArray[np.float64]:
        """Chart coordinates ``(2560, 2)``: (level * 5 + distance, direction * 8 + angle)."""
        d = decode_social(np.arange(N_SOCIAL_STATES))
        return np.stack([d[:, 0] * 5 + d[:, 1], d[:, 2] * 8 + d[:, 3]], axis=1).astype(float)

    def state_of(self, xy: NDArray[np.float64]) -> NDArray[np.int64]:
        raise ValueError("social states do not follow from poses; give s and s_next")

    def content_hash(self) -> str:
        """Fixed fingerprint of the social index (its dimensions and order)."""
        return hashlib.sha256(f"simlab-social-states{SOCIAL_DIMS}".encode()).hexdigest()


@dataclass(frozen=True)
class WalkConfig:
    """A social random walk: ``steps`` decisions per segment, restarts every
    ``episode_steps``, ``workers`` independent segments (module docstring), the behaviour
    ``policy`` (:data:`WALK_POLICIES`), the task's ``social`` settings."""

    steps: int = 1000
    episode_steps: int = 40
    workers: int = 1
    seed: int = 0
    social: SocialConfig = field(default_factory=SocialConfig)
    policy: str = "uniform"

    def __post_init__(self) -> None:
        validation.whole(self.steps, "WalkConfig.steps", minimum=1)
        validation.whole(self.episode_steps, "WalkConfig.episode_steps", minimum=1)
        validation.whole(self.workers, "WalkConfig.workers", minimum=1)
        validation.whole(self.seed, "WalkConfig.seed", minimum=0)
        validation.choice(self.policy, WALK_POLICIES, "WalkConfig.policy")


@dataclass(frozen=True)
class SocialWalk:
    """One worker's transitions, ``N`` rows: ``s, a, s_next`` int64; ``reward``, ``t``
    (start, s), ``duration`` (s) float64; ``blocked`` bool; ``robot``, ``robot_next``,
    ``human``, ``human_next`` ``(N, 3)`` poses (m, m, rad); ``episode`` int64."""

    s: NDArray[np.int64]
    a: NDArray[np.int64]
    s_next: NDArray[np.int64]
    reward: NDArray[np.float64]
    t: NDArray[np.float64]
    duration: NDArray[np.float64]
    blocked: NDArray[np.bool_]
    robot: NDArray[np.float64]
    robot_next: NDArray[np.float64]
    human: NDArray[np.float64]
    human_next: NDArray[np.float64]
    episode: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.s)

    @property
    def simulated_hours(self) -> float:
        """Simulated time of the walk (h)."""
        return float(self.duration.sum()) / 3600.0


def _walk_one(table: SocialTable, cfg: WalkConfig, seq: np.random.SeedSequence) -> SocialWalk:
    """One worker's walk on ``table`` (see the module docstring)."""
    act_seq, ep_seq = seq.spawn(2)
    act_rng, ep_rng = np.random.default_rng(act_seq), np.random.default_rng(ep_seq)
    rows: dict[str, list] = {k: [] for k in SocialWalk.__dataclass_fields__}
    tried = np.zeros((N_POOLED_STATES, N_SOCIAL_ACTIONS), dtype=np.int64)
    clock, episode, obs = 0.0, -1, 0
    for k in range(cfg.steps):
        if k % cfg.episode_steps == 0:
            episode += 1
            obs = table.reset(int(ep_rng.integers(0, 2**63 - 1)))
        if cfg.policy == "least-tried":
            row = tried[pooled_state(obs)]
            least = np.flatnonzero(row == row.min())
            a = int(least[int(act_rng.integers(0, least.size))])
            row[a] += 1
        else:
            a = int(act_rng.integers(0, N_SOCIAL_ACTIONS))
        robot, human = table.world.pose(), table.human_pose.copy()
        nxt, reward, info = table.step(a)
        for key, value in (("s", obs), ("a", a), ("s_next", nxt), ("reward", reward),
                           ("t", clock), ("duration", info.duration),
                           ("blocked", info.blocked), ("robot", robot),
                           ("robot_next", info.robot_pose), ("human", human),
                           ("human_next", info.human_pose), ("episode", episode)):
            rows[key].append(value)
        clock += info.duration
        obs = nxt
    dtypes = {"s": np.int64, "a": np.int64, "s_next": np.int64, "episode": np.int64,
              "blocked": bool}
    return SocialWalk(**{k: np.asarray(v, dtype=dtypes.get(k, np.float64)).reshape(
        (cfg.steps, 3) if k in ("robot", "robot_next", "human", "human_next") else (cfg.steps,))
        for k, v in rows.items()})


def pooled_state(s: NDArray[np.int64] | int) -> NDArray[np.int64] | int:
    """Social state(s) -> the observation pooled over the required direction,
    ``(level * 5 + distance class) * 8 + angle`` (0-319)."""
    d = decode_social(s)
    out = (d[..., 0] * SOCIAL_DIMS[1] + d[..., 1]) * SOCIAL_DIMS[3] + d[..., 3]
    return int(out) if np.ndim(out) == 0 else out


def walk_segment(cfg: WalkConfig, index: int) -> SocialWalk:
    """Segment ``index`` of the walk ``cfg`` on a world of its own (a parallel job)."""
    seq = np.random.SeedSequence(cfg.seed).spawn(cfg.workers)[index]
    with SocialTable(cfg.social) as table:
        return _walk_one(table, cfg, seq)


def social_walk(cfg: WalkConfig, *, processes: int = 1, backend: str = "local",
                address: str | None = None, executor: Any | None = None) -> list[SocialWalk]:
    """Run the walk: one :class:`SocialWalk` per segment, in segment order (module
    docstring). ``processes`` > 1 (or ``backend="ray"``) runs the segments as jobs of a
    :func:`simlab.base.parallel.make_executor` executor; ``executor`` (a :mod:`simlab.base.parallel`
    executor the caller owns and closes, e.g. the one of ``simlab reproduce``) runs them
    on it instead (``processes`` and ``backend`` must then keep their defaults). The
    result does not depend on where the segments ran."""
    validation.whole(processes, "processes", minimum=1)
    jobs = [{"cfg": cfg, "index": i} for i in range(cfg.workers)]
    if executor is not None:
        if processes != 1 or backend != "local" or address is not None:
            raise ConfigError("give either an executor or processes/backend/address",
                              key="executor")
        return executor.map(walk_segment, jobs, desc="social walk")
    seqs = np.random.SeedSequence(cfg.seed).spawn(cfg.workers)
    if backend == "local" and (processes == 1 or cfg.workers == 1):
        with SocialTable(cfg.social) as table:
            return [_walk_one(table, cfg, seq) for seq in seqs]
    from simlab.base.parallel import make_executor

    workers = None if backend == "ray" else min(processes, cfg.workers)
    with make_executor(backend, workers=workers, address=address) as ex:
        return ex.map(walk_segment, jobs)


def write_social_dataset(out: str | os.PathLike[str], cfg: WalkConfig, *,
                         overwrite: bool = False, part_size: int = 10_000,
                         processes: int = 1) -> tuple[object, list[SocialWalk]]:
    """Walk (``processes`` as :func:`social_walk`) and write the simlab dataset into
    ``out``, one segment after the other (the writer's parts, ``out/parts/``); returns
    (the writer's :class:`~simlab.data.writer.WriteResult`, the walks)."""
    from simlab.data.writer import DatasetInfo, TransitionArrays, write_dataset

    walks = social_walk(cfg, processes=processes)
    arrays = [TransitionArrays(t=w.t, a=w.a, pose=w.robot, pose_next=w.robot_next,
                               blocked=w.blocked, duration=w.duration, s=w.s, s_next=w.s_next)
              for w in walks]
    social = cfg.social
    human = social.human
    info = DatasetInfo(
        discretizer=SocialStates(), pose_source="truth", action_names=ACTION_NAMES,
        arena={"name": str(social.arena), "kind": "social"}, simulator="physics",
        robot={"model": "turtlebot3_burger"}, seed=cfg.seed,
        parameters={"state_space": "social", "social_dims": list(SOCIAL_DIMS),
                    "steps": cfg.steps, "episode_steps": cfg.episode_steps,
                    "segments": cfg.workers, "policy": cfg.policy,
                    "human": dataclasses.asdict(human),
                    "redraw_p": social.redraw_p, "signal_time": social.signal_time},
        provenance={"walk": f"simlab.social.walk.social_walk ({cfg.policy} over 22 actions)",
                    "reward_total": float(sum(w.reward.sum() for w in walks)),
                    "simulated_hours": sum(w.simulated_hours for w in walks)})
    result = write_dataset(out, arrays, info, overwrite=overwrite, part_size=part_size)
    return result, walks
