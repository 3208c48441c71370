"""The one decision-step driver: choose -> execute primitive -> pose -> state -> record."""

from __future__ import annotations

import math

import numpy as np

from simlab.physics.driver import DecisionDriver, DecisionStep
from simlab.physics.motion import PrimitiveParams, execute_primitive
from simlab.physics.world import World


def _quadrant(pose: np.ndarray) -> int:
    """A toy state function: the quadrant of (x, y)."""
    return int(pose[0] >= 0) + 2 * int(pose[1] >= 0)


def test_driver_steps_like_the_bare_primitives_and_chains_its_poses() -> None:
    params = PrimitiveParams()
    primitives = np.array([8, 11, 0, 3])  # action a runs primitive primitives[a]
    actions = [0, 1, 3, 2, 1]
    steps: list[DecisionStep] = []
    chosen = iter(actions)
    with World("table") as world:
        driver = DecisionDriver(world, params, state_of=_quadrant, primitives=primitives)
        assert driver.state == _quadrant(world.pose())
        for _ in actions:
            driver.step(lambda pose, state: next(chosen), np.random.default_rng(7),
                        record=steps.append)
    with World("table") as world:  # the same primitives without the driver
        bare = [execute_primitive(world, int(primitives[a]), np.random.default_rng(7), params)
                for a in actions]
    assert [s.action for s in steps] == actions
    for i, (step, res) in enumerate(zip(steps, bare, strict=True)):
        np.testing.assert_array_equal(step.result.pose_after, res.pose_after)
        assert step.result.blocked == res.blocked and step.result.duration == res.duration
        np.testing.assert_array_equal(step.pose_after, res.pose_after)  # default: truth
        assert step.state_after == _quadrant(step.pose_after)
        if i:
            np.testing.assert_array_equal(step.pose_before, steps[i - 1].pose_after)
            np.testing.assert_array_equal(step.truth_before, steps[i - 1].result.pose_after)
            assert step.state_before == steps[i - 1].state_after


def test_pose_source_callback_and_observe() -> None:
    """The believed pose comes from ``pose_of`` (here the odometry); ``observe`` re-reads
    it after the robot moved outside a primitive."""
    with World("table") as world:
        def odometry(res):
            return world.odometry() if res is None else np.asarray(res.odom_after)

        driver = DecisionDriver(world, PrimitiveParams(), pose_of=odometry, state_of=_quadrant)
        step = driver.step(lambda pose, state: 0, np.random.default_rng(0))
        np.testing.assert_array_equal(step.pose_after, step.result.odom_after)
        np.testing.assert_array_equal(driver.pose, step.result.odom_after)
        world.reset((0.3, -0.3, math.pi))
        pose, state = driver.observe()
        np.testing.assert_allclose(pose, world.odometry())
        assert state == _quadrant(pose) == driver.state
