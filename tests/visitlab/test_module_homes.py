"""Names that moved out of :mod:`simlab.visitlab.training` (the fused loops, the options)
stay importable from it as the same objects, and :func:`~simlab.visitlab.training.train`
takes its env as the :class:`~simlab.visitlab.training.EnvSpec` record or spelled out."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.visitlab import fused, options, training


@pytest.mark.parametrize("home", [fused, options])
def test_every_moved_name_is_the_same_object_from_training(home) -> None:
    for name in home.__all__:
        assert getattr(training, name) is getattr(home, name), name
        assert name in training.__all__


def test_an_env_spec_and_its_spelled_out_fields_train_the_same_run() -> None:
    spec = training.EnvSpec("nav", "paper", {"max_steps": 12})
    a = training.train(spec, "q-learning", trials=20, seeds=2, seed=5, progress=False)
    b = training.train("nav", "q-learning", trials=20, seeds=2, seed=5, progress=False,
                       variant="paper", max_steps=12)
    np.testing.assert_array_equal(a.returns, b.returns)
    np.testing.assert_array_equal(a.q, b.q)
    assert a.config == b.config and a.config["variant"] == "paper"
    assert a.config["env_kwargs"] == {"max_steps": 12}


def test_env_arguments_beside_a_record_are_refused() -> None:
    with pytest.raises(ConfigError, match="EnvSpec"):
        training.train(training.EnvSpec("nav"), "q-learning", trials=2, seeds=1,
                       progress=False, max_steps=5)
