"""``simlab estimate``: the empirical MDP, its entropy per action and coverage.

The options are the fields of :class:`simlab.data.estimate.EstimateConfig`.
"""

from __future__ import annotations

import argparse

HELP = "estimate T(s,a,s') with entropy and coverage from a dataset or a count table"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.data.estimate import EstimateConfig

    EstimateConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.data.estimate import EstimateConfig, estimate

    result = estimate(EstimateConfig.from_args(args))
    mdp = result.mdp
    line = (
        f"{mdp.n_states} states x {mdp.n_actions} actions from {int(mdp.counts.sum())} "
        f"transitions; {mdp.coverage:.1%} of (s, a) visited"
    )
    if mdp.n_actions == 16 and int(mdp.counts.sum()):
        line += (f"; mean entropy slow {mdp.slow_mean_entropy:.3f} bits, "
                 f"fast {mdp.fast_mean_entropy:.3f} bits")
    aset = result.summary["action_set"]
    line += (f"; {aset['n_actions']} actions ({aset['convention']})" if aset is not None
             else "; named actions, not motion primitives")
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
