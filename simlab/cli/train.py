"""``simlab train``: learn Q-tables on an empirical MDP, one per goal area.

The options are the fields of :class:`simlab.training.config.TrainConfig`.
"""

from __future__ import annotations

import argparse
from typing import Any

HELP = (
    "train an agent on an empirical MDP (mdp.npz) for each goal; write Q-tables, curves, heat maps"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.training.config import TrainConfig, param_pair

    TrainConfig.add_arguments(parser)
    # repeatable, so not generated: the field is the dict ``params``
    parser.add_argument(
        "--param",
        type=param_pair,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override an agent hyper-parameter, e.g. --param tau=0.05 "
        "(repeatable; observer.alpha=0.5 for nested ones; default: the agent's preset)",
    )


def config_from_args(args: argparse.Namespace) -> Any:
    """The :class:`~simlab.training.config.TrainConfig` of the parsed command line
    (``--param`` pairs win over a ``params`` table of ``--config FILE``)."""
    from simlab.base.errors import ConfigError
    from simlab.training.config import TrainConfig

    cfg = TrainConfig.from_args(args)
    if cfg.out is None:
        raise ConfigError("an output directory is required", key="out", fix="--out DIR")
    if args.param:
        cfg = cfg.replace(params={**(cfg.params or {}), **dict(args.param)},
                          task=cfg.task.mode)
    return cfg


def run(args: argparse.Namespace) -> int:
    import warnings

    from simlab.commands import train

    cfg = config_from_args(args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        summary = train(cfg)
    for w in caught:  # one line each, after the run (the CLI's showwarning; -q hides them)
        warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    print(
        f"{summary.agent}: {len(summary.goals)} goal(s) x {cfg.runs} runs x "
        f"{cfg.episodes} episodes in {summary.seconds:.1f} s -> {summary.out}"
    )
    for g in summary.goals:
        ratio = "n/a" if g.ratio is None else f"{g.ratio:.0%}"
        print(
            f"  {g.goal:>12}: final {g.final_mean_reward:6.2f}  optimal {g.optimal_return:6.2f}"
            f"  ({ratio})  greedy {g.greedy_return:6.2f}"
        )
    return 0
