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
    parser.add_argument("--no-plot", action="store_true", help="skip the entropy bar plot")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")


def run(args: argparse.Namespace) -> int:
    from simlab.data.estimate import estimate

    result = estimate(
        args.dataset,
        args.out,
        counts=args.counts,
        arena=args.arena,
        states=args.states,
        n_states=args.n_states,
        plot=not args.no_plot,
        overwrite=args.overwrite,
    )
    mdp = result.mdp
    line = (
        f"{mdp.n_states} states x {mdp.n_actions} actions from {int(mdp.counts.sum())} "
        f"transitions; {mdp.coverage:.1%} of (s, a) visited"
    )
    if mdp.n_actions == 16:
        line += (f"; mean entropy slow {mdp.slow_mean_entropy:.3f} bits, "
                 f"fast {mdp.fast_mean_entropy:.3f} bits")
    files = [result.npz, result.summary_path] + ([result.plot] if result.plot else [])
    print(line)
    print("wrote " + ", ".join(str(f) for f in files))
    return 0
