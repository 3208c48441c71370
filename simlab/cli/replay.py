"""``simlab replay``: the learned Q-tables driven in closed loop in physics (thesis Fig. 4.10).

The options are those of :class:`~simlab.replay.config.ReplayConfig` (generated), plus the
primitive flags shared with ``simlab collect`` (they build ``params``) and ``--random``
(kept as the short form of ``--policy random``).
"""

from __future__ import annotations

import argparse

from simlab.cli.collect import add_primitive_arguments, primitive_params_from_args
from simlab.replay.config import ReplayConfig

HELP = ("replay learned Q-tables in physics with goal switching; cumulative reward vs a "
        "random policy and the MDP-predicted rate (optional top-down GIF)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    ReplayConfig.add_arguments(parser)
    parser.add_argument("--random", dest="policy", action="store_const", const="random",
                        default=argparse.SUPPRESS, help="same as --policy random")
    add_primitive_arguments(parser)


def config_from_args(args: argparse.Namespace) -> ReplayConfig:
    """The :class:`ReplayConfig` of the command line (``--states`` and ``--out`` are
    required here, on the command line or in ``--config``, unlike in the Python function);
    the primitive flags become ``params``."""
    from simlab.base.errors import ConfigError

    for name in ("states", "out"):
        if not _given(args, name):
            raise ConfigError(f"missing required option --{name}", key=name)
    cfg = ReplayConfig.from_args(args)
    params = primitive_params_from_args(args)
    return cfg if params is None else cfg.replace(params=params)


def _given(args: argparse.Namespace, name: str) -> bool:
    """Whether option ``name`` is on the command line or in the ``--config`` file."""
    if isinstance(getattr(args, name, None), str):
        return True
    config = getattr(args, "config", None)
    if config is None:
        return False
    from simlab.base.io import read_toml

    return any(k.replace("-", "_") == name for k in read_toml(config))


def run(args: argparse.Namespace) -> int:
    from simlab.replay import replay as replay_module

    result = replay_module.replay(config_from_args(args))
    s = result.summary
    r, c = s.result, s.comparison
    print(f"{s.policy} policy, {s.pose_source} poses: {r.rewards} goals in "
          f"{r.robot_seconds / 3600:.2f} robot-h ({r.transitions} transitions) = "
          f"{r.rate_per_hour:.1f} /h; {r.wall_seconds:.0f} s wall")
    if c.random_rate_per_hour is not None:
        ratio = c.ratio_to_random
        print(f"random policy: {c.random_rate_per_hour:.1f} /h"
              + (f" (learned/random = {ratio:.1f}x)" if ratio else ""))
    if c.predicted_rate_per_hour is not None:
        ratio = c.measured_over_predicted
        print(f"MDP-predicted: {c.predicted_rate_per_hour:.1f} /h"
              + (f" (measured/predicted = {ratio:.2f})" if ratio is not None else
                 " (measured/predicted: undefined, the MDP predicts no reward)"))
    note = (getattr(s, "prediction", None) or {}).get("not_predicted")
    if note:
        print(f"MDP-predicted: none ({note})")
    from simlab.physics.rate import DEFAULT_HZ

    if s.physics["hz"] != DEFAULT_HZ:
        print(f"physics stepped at {s.physics['hz']:g} Hz ({s.physics['source']}; the default "
              f"rate is {DEFAULT_HZ:g} Hz)")
    loc = s.localization.get("mcl")
    if loc:
        a = loc["at_decisions"]
        print(f"MCL error at decisions: mean {100 * a['position_mean_m']:.1f} cm, "
              f"{a['heading_mean_rad']:.3f} rad")
    print(f"wrote {s.files['summary']} and {s.files['plot']}")
    return 0
