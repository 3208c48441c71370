"""One decision step in physics: choose -> execute primitive -> pose -> state -> record.

Everything that drives the robot decision by decision (the replay, the dataset walkers,
``simlab drive``, the Gymnasium envs, the mapping run) does the same five things; this
module writes them once. Physics knows nothing of policies, rewards or datasets: the
caller passes

* ``choose(pose, state) -> action`` — the decision (a policy, a random draw, an agent's
  action handed in);
* ``pose_of(result)`` — what the robot believes its pose is after a primitive (the pose
  source: truth, odometry, or a filter fed by ``on_scan``); ``None`` for the result
  means "now, outside a primitive";
* ``state_of(pose) -> int`` — the discretizer's state of a pose (None: no states);
* ``record(step)`` — what to keep of each decision.

The driver holds the current believed pose and state between decisions;
:meth:`DecisionDriver.observe` re-reads them after the robot moved outside a primitive
(e.g. a drive back to the start pose). The order of the random draws is that of the
loops this replaces (``choose`` before the primitive's noise), so seeded runs are
unchanged bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["DecisionDriver", "DecisionStep"]

Pose = NDArray[np.float64]


@dataclass(frozen=True)
class DecisionStep:
    """One decision: ``action`` (index into the driver's ``primitives``), the primitive's
    :class:`~simlab.physics.motion.PrimitiveResult` (``result``: true and odometry poses,
    stepped ``duration`` s, ``blocked``), the true pose before it (3,), the believed poses
    (3,) and states before and after (states None without a ``state_of``)."""

    action: int
    result: Any
    truth_before: Pose
    pose_before: Pose
    pose_after: Pose
    state_before: int | None
    state_after: int | None


class DecisionDriver:
    """Steps one decision at a time in ``world`` (see the module docstring).

    Args:
        world: a :class:`~simlab.physics.world.World`.
        params: :class:`~simlab.physics.motion.PrimitiveParams` of the primitives.
        pose_of: believed pose (3,) after a primitive result, or now for ``None``
            (default: the true pose).
        state_of: state of a believed pose (default: none).
        primitives: simlab primitive executed by each action, ``(A,)`` (default: the
            action is the primitive).
        on_scan / scan_beams: the pose source's scan callback and the beams it reads.
        watch_state: the state function of ``until_state_change`` primitives (they watch
            the true position), passed to :func:`~simlab.physics.motion.execute_primitive`.
    """

    def __init__(self, world: Any, params: Any, *,
                 pose_of: Callable[[Any], Pose] | None = None,
                 state_of: Callable[[Pose], int] | None = None,
                 primitives: NDArray[np.int64] | None = None,
                 on_scan: Callable[..., None] | None = None,
                 scan_beams: NDArray[np.int64] | None = None,
                 watch_state: Callable[[Any], int] | None = None) -> None:
        from simlab.physics.motion import execute_primitive

        self.world = world
        self.params = params
        self._execute = execute_primitive
        self._pose_of = pose_of if pose_of is not None else (lambda _res: world.pose())
        self._state_of = state_of
        self.primitives = primitives
        self.on_scan = on_scan
        self.scan_beams = scan_beams
        self.watch_state = watch_state
        self.pose: Pose = self._pose_of(None)
        self.state: int | None = None if state_of is None else int(state_of(self.pose))

    def observe(self) -> tuple[Pose, int | None]:
        """Re-read the believed pose and state now (after motion outside a primitive)."""
        self.pose = self._pose_of(None)
        self.state = None if self._state_of is None else int(self._state_of(self.pose))
        return self.pose, self.state

    def execute(self, action: int, noise_rng: np.random.Generator) -> DecisionStep:
        """Run ``action``'s primitive with noise from ``noise_rng`` and move the believed
        pose and state on."""
        primitive = int(action if self.primitives is None else self.primitives[action])
        truth_before = self.world.pose()
        res = self._execute(self.world, primitive, noise_rng, self.params, on_scan=self.on_scan,
                            scan_beams=self.scan_beams, state_of=self.watch_state)
        after = self._pose_of(res)
        s_next = None if self._state_of is None else int(self._state_of(after))
        step = DecisionStep(action=int(action), result=res, truth_before=truth_before,
                            pose_before=self.pose, pose_after=after,
                            state_before=self.state, state_after=s_next)
        self.pose, self.state = after, s_next
        return step

    def step(self, choose: Callable[[Pose, int | None], int], noise_rng: np.random.Generator,
             record: Callable[[DecisionStep], None] | None = None) -> DecisionStep:
        """One decision: ``choose`` from the believed pose and state, execute, record."""
        step = self.execute(int(choose(self.pose, self.state)), noise_rng)
        if record is not None:
            record(step)
        return step
