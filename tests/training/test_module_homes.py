"""The names of ``simlab train`` stay importable where other packages import them.

The command module (:mod:`simlab.training.train`) re-exports what moved into its options
(:mod:`simlab.training.config`) and its loop (:mod:`simlab.training.loop`): the same
objects, not copies, so an ``isinstance`` or a config built either way agree.
"""

from __future__ import annotations

import pytest

from simlab.training import config, loop, train


@pytest.mark.parametrize("name, home", [
    ("TrainConfig", config), ("TrainTask", config), ("TASK_MODES", config),
    ("param_pair", config), ("GoalSummary", loop),
])
def test_a_moved_name_is_the_same_object_from_the_command_module(name, home) -> None:
    assert getattr(train, name) is getattr(home, name)
    assert name in train.__all__


def test_the_command_takes_the_config_of_its_options_module() -> None:
    cfg = config.TrainConfig(mdp="m.npz", out=None, episodes=5, goal_states="3")
    assert isinstance(cfg.task, train.TrainTask) and cfg.task.goal_states == (3,)
