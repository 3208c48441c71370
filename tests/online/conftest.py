"""Shared fixtures of the online tests: tiny MDPs and the published expert configs."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.agents.registry import agent_config


def chain(n: int = 5, p: float = 1.0) -> np.ndarray:
    """(n, 2, n) chain: action 1 moves right with probability ``p`` (else stays), action 0
    moves left; the ends bounce."""
    T = np.zeros((n, 2, n))
    for s in range(n):
        T[s, 1, min(s + 1, n - 1)] += p
        T[s, 1, s] += 1 - p
        T[s, 0, max(s - 1, 0)] = 1.0
    return T


@pytest.fixture
def experts():
    mf = agent_config("q-softmax", {"alpha": 0.6, "tau": 0.02, "q_init": 1 / 1.9})
    mb = agent_config("sliding-window", {"tau": 0.02, "q_init": 1 / 1.9, "max_sweeps": 100,
                                         "tol": 1e-4, "plan_every": 0, "window": 10})
    return mf, mb
