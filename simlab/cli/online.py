"""``simlab online``: agents learning while they act; MB/MF meta-control on an empirical MDP
or in physics on an arena (:mod:`simlab.online.arena`).

The options are the fields of :class:`simlab.online.command.OnlineConfig`.
"""

from __future__ import annotations

import argparse

HELP = ("learn online with MB/MF meta-control (criteria, costs, changes) on an empirical MDP, "
        "or in physics on an arena")
MEMORY_FIX = "fewer --seeds or --decisions, fewer --criteria or --kappas, or --no-plots"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.online.command import OnlineConfig

    OnlineConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.base.errors import ConfigError
    from simlab.online.command import OnlineConfig, online

    cfg = OnlineConfig.from_args(args)
    if cfg.out is None:
        raise ConfigError("no output directory", key="out", fix="add --out DIR")
    res = online(cfg)
    for name, a in res.summary["arms"].items():
        rel = a.get("cost_vs_mb")
        print(f"{name:24s} reward {a['reward']['mean']:7.1f} ± {a['reward']['std']:5.1f}  "
              f"MB share {a['mb_share']:.2f}" + ("" if rel is None else f"  cost vs MB {rel:.2f}"))
    print("wrote " + ", ".join(str(p) for p in res.files.values()))
    return 0
