"""``simlab train``: learn Q-tables on an empirical MDP, one per goal area."""

from __future__ import annotations

import argparse
import json
from typing import Any

HELP = (
    "train an agent on an empirical MDP (mdp.npz) for each goal; write Q-tables, curves, heat maps"
)

_AGENTS = "q-learning, q-softmax, mb-egreedy, vi-softmax, rmax, sliding-window, passive-observer"


def _param(text: str) -> tuple[str, Any]:
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        parsed = json.loads(value)
    except json.JSONDecodeError:
        parsed = value  # plain strings: --param selection=softmax
    return key.strip(), parsed


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mdp", required=True, help="mdp.npz written by simlab estimate")
    parser.add_argument(
        "--agent", default="vi-softmax", help=f"agent name ({_AGENTS}); default vi-softmax"
    )
    parser.add_argument("--goals", default="all",
                        help="'all' or comma-separated goal names (default all)")
    parser.add_argument(
        "--episodes", type=int, default=2000, help="episodes per run (default 2000)"
    )
    parser.add_argument(
        "--runs", type=int, default=10, help="independent runs per goal (default 10)"
    )
    parser.add_argument("--seed", type=int, default=0, help="root seed (default 0)")
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--horizon", type=int, default=50, help="steps per episode (default 50)")
    parser.add_argument(
        "--start", type=int, default=None, help="fixed start state (default: uniform over states)"
    )
    parser.add_argument(
        "--param",
        type=_param,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override an agent hyper-parameter, e.g. --param tau=0.05 "
        "(repeatable; observer.alpha=0.5 for nested ones)",
    )
    parser.add_argument(
        "--bounds",
        type=float,
        nargs=4,
        metavar=("XMIN", "YMIN", "XMAX", "YMAX"),
        help="heat-map extent in metres (default: from --arena or the centres)",
    )
    parser.add_argument("--arena", default=None, help="arena name or TOML for the heat-map extent")
    parser.add_argument(
        "--map", dest="occupancy_map", default=None, help="map.yaml drawn under the heat maps"
    )
    parser.add_argument(
        "--goal-states", default=None,
        help="train one goal made of these state ids, e.g. 18 or 18,19 (named s18, s18+19); "
        "no arena needed (default: the MDP's named goals)",
    )
    parser.add_argument(
        "--start-states", default=None,
        help="start states drawn uniformly, e.g. 0,32 (default: all states, or --start)",
    )
    parser.add_argument(
        "--task", choices=("per-step", "episodic"), default="per-step",
        help="per-step: +1 per step arriving in the goal, fixed-length episodes (thesis; "
        "default); episodic: +1 on arrival, then restart from the start states (real robot)",
    )
    parser.add_argument(
        "--unvisited", choices=("mask", "self-loop"), default=None,
        help="unvisited (s, a): mask = never chosen, self-loop = the old free stay "
        "(default: the rule stored in the MDP, mask for old files)",
    )
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args: argparse.Namespace) -> int:
    import warnings

    from simlab.commands import train
    from simlab.training.train import TrainTask

    task = TrainTask(mode=args.task, goal_states=args.goal_states,
                     start_states=args.start_states, unvisited=args.unvisited)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        summary = _train(train, args, task)
    for w in caught:  # one line each, after the run (the CLI's showwarning; -q hides them)
        warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    print(
        f"{summary.agent}: {len(summary.goals)} goal(s) x {args.runs} runs x "
        f"{args.episodes} episodes in {summary.seconds:.1f} s -> {summary.out}"
    )
    for g in summary.goals:
        ratio = "n/a" if g.ratio is None else f"{g.ratio:.0%}"
        print(
            f"  {g.goal:>12}: final {g.final_mean_reward:6.2f}  optimal {g.optimal_return:6.2f}"
            f"  ({ratio})  greedy {g.greedy_return:6.2f}"
        )
    return 0


def _train(train: Any, args: argparse.Namespace, task: Any) -> Any:
    return train(
        args.mdp, agent=args.agent, goals=args.goals, episodes=args.episodes, runs=args.runs,
        seed=args.seed, out=args.out, horizon=args.horizon, start=args.start,
        params=dict(args.param), bounds=args.bounds, arena=args.arena,
        occupancy_map=args.occupancy_map, plots=not args.no_plots, overwrite=args.overwrite,
        progress=not args.no_progress, task=task,
    )  # fmt: skip
