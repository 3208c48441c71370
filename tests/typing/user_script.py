"""A user's script on simlab's public API, checked by ``mypy --strict`` (tests/typing).

It is type-checked, never run by the tests: each line is what the documentation shows.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import simlab
import simlab.commands
from discretize.voronoi import Discretizer, load_states
from simlab.agents import greedy, load_q_table, make_agent, value_iteration
from simlab.base.actions import SIMLAB16, ActionSet, parse_action_set
from simlab.base.errors import ConfigError, DataError
from simlab.data.dataset import parts_path, read_dataset
from simlab.data.mdp import EmpiricalMDP, load_mdp
from simlab.envs.table_arena import GoalTableArenaEnv
from simlab.localization.likelihood import LikelihoodField
from simlab.localization.maps import arena_map
from simlab.localization.tracker import MCLTracker
from simlab.physics.world import World


def run_policy(q_file: Path, states: Path, goal: str, steps: int) -> float:
    """Total reward of a Q-table's masked greedy policy in physics."""
    policy: NDArray[np.int64] = greedy(q_file)
    env = gym.make("simlab:simlab/TableArenaStates-v0", states=str(states), goal=goal,
                   q_table=str(q_file), max_episode_steps=steps)
    s, _ = env.reset(seed=0)
    total = 0.0
    done = False
    while not done:
        s, r, terminated, truncated, _ = env.step(int(policy[int(s)]))
        total += float(r)
        done = terminated or truncated
    env.close()
    return total


def goal_conditioned() -> tuple[float, ...]:
    env = GoalTableArenaEnv()
    obs, info = env.reset(seed=1)
    reward = env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)
    env.close()
    return tuple(float(x) for x in np.atleast_1d(reward))


def vector_envs() -> gym.vector.AsyncVectorEnv:
    fns = [partial(gym.make, "simlab:simlab/VisitLab-Nav-v0") for _ in range(2)]
    return gym.vector.AsyncVectorEnv(fns, context="spawn")


def plan(mdp_file: Path, goal: int) -> NDArray[np.float64]:
    mdp: EmpiricalMDP = load_mdp(mdp_file)
    R = np.zeros((mdp.n_states, mdp.n_actions))
    Q, V, _n_iter = value_iteration(mdp.T, R, 0.9)
    agent = make_agent("q-learning", mdp.n_states, mdp.n_actions, np.random.default_rng(goal))
    agent.update(0, int(greedy(Q)[0]), 0.0, 1)
    return np.asarray(V, dtype=np.float64)


def datasets(directory: Path) -> int:
    table = read_dataset(directory)
    print(parts_path(directory))
    return int(table.num_rows)


def states_and_actions(path: Path) -> tuple[int, int]:
    disc: Discretizer = load_states(path)
    aset: ActionSet = parse_action_set(8, "ccw-east")
    return disc.n_states, aset.n_actions + SIMLAB16.n_actions


def commands(out: Path) -> None:
    try:
        simlab.commands.pipeline("table", str(out), hours=0.1)
    except (ConfigError, DataError) as exc:
        print(f"simlab: {exc}")
    Q, meta = load_q_table(out / "qtables" / "q_NE.npz")
    print(simlab.__version__, Q.shape, meta.get("goal"))


def localize() -> NDArray[np.float64]:
    """A particle filter fed by the simulated LIDAR."""
    with World("table") as world:
        field = LikelihoodField(arena_map(world.arena, 0.02))
        tracker = MCLTracker(field, np.random.default_rng(0), initial_pose=world.pose())
        tracker.on_scan(world.scan(np.random.default_rng(1)), world.odometry())
        return tracker.pose()
