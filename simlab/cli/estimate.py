"""``simlab estimate``: the empirical MDP, its entropy per action and coverage."""

from __future__ import annotations

import argparse

HELP = "estimate T(s,a,s') with entropy and coverage from a dataset or a count table"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", nargs="?", default=None,
                        help="dataset directory written by `simlab collect`")
    parser.add_argument("--out", required=True,
                        help="model file mdp.npz (summary .json and _entropy.png beside it)")
    parser.add_argument("--counts", default=None,
                        help="instead of a dataset: CSV/JSON table with s, a, s_next, count")
    parser.add_argument("--arena", default=None,
                        help="arena whose goals define goal_masks (default: the dataset's)")
    parser.add_argument("--states", default=None,
                        help="states file: S and centres for --counts; checked against a dataset")
    parser.add_argument("--n-states", type=int, default=None,
                        help="number of states for --counts without --states")
    parser.add_argument("--n-actions", type=int, choices=(8, 16), default=None,
                        help="actions of a --counts table: 8 (one speed) or 16 (default 16; "
                             "a dataset records its own)")
    parser.add_argument("--convention", default="simlab",
                        help="direction numbering of --counts: simlab (UP, DOWN, LEFT, RIGHT, "
                             "UL, UR, DL, DR), ccw-east (0 E, 1 NE, ... 7 SE) or 8 numbers "
                             "PERM, the simlab direction of each of yours (default simlab)")
    parser.add_argument("--speed", choices=("slow", "fast"), default="slow",
                        help="which primitive speed an 8-action robot's single speed is "
                             "(default slow; ignored for 16 actions)")
    parser.add_argument("--unvisited", choices=("mask", "self-loop"), default="mask",
                        help="unvisited (s, a): mask = planners never choose them (default); "
                             "self-loop = the old rule, a free stay")
    parser.add_argument("--no-plot", action="store_true", help="skip the entropy bar plot")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")


def run(args: argparse.Namespace) -> int:
    from simlab.actions import parse_action_set
    from simlab.data.estimate import estimate
    from simlab.errors import ConfigError

    action_set = None
    explicit = (args.n_actions is not None or args.convention != "simlab"
                or args.speed != "slow")
    if args.counts is not None:
        n = args.n_actions or 16
        # a 16-action set has both speeds: --speed only describes an 8-action robot
        action_set = parse_action_set(n, args.convention, args.speed if n == 8 else "slow")
    elif explicit:
        raise ConfigError("--n-actions/--convention/--speed describe a --counts table; a "
                          "dataset records its own action set", key="n_actions",
                          fix="drop them, or re-import the data with the right convention")
    result = estimate(
        args.dataset,
        args.out,
        counts=args.counts,
        arena=args.arena,
        states=args.states,
        n_states=args.n_states,
        plot=not args.no_plot,
        overwrite=args.overwrite,
        action_set=action_set,
        unvisited=args.unvisited,
    )
    mdp = result.mdp
    line = (
        f"{mdp.n_states} states x {mdp.n_actions} actions from {int(mdp.counts.sum())} "
        f"transitions; {mdp.coverage:.1%} of (s, a) visited"
    )
    if mdp.n_actions == 16:
        line += (f"; mean entropy slow {mdp.slow_mean_entropy:.3f} bits, "
                 f"fast {mdp.fast_mean_entropy:.3f} bits")
    line += f"; {result.summary['action_set']['n_actions']} actions " \
            f"({result.summary['action_set']['convention']})"
    if result.summary["masked_pairs"]:
        line += (f"; {result.summary['masked_pairs']} untried (s, a) of visited states masked "
                 "for planners (--unvisited self-loop for the old rule)")
    if result.summary["states_without_data"]:
        line += (f"; {result.summary['states_without_data']} states never left in the data "
                 "(all their actions stay allowed)")
    files = [result.npz, result.summary_path] + ([result.plot] if result.plot else [])
    print(line)
    print("wrote " + ", ".join(str(f) for f in files))
    return 0
