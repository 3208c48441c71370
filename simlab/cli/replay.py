"""``simlab replay``: the learned Q-tables driven in closed loop in physics (thesis Fig. 4.10)."""

from __future__ import annotations

import argparse

from simlab.cli.collect import add_primitive_arguments, primitive_params_from_args

HELP = ("replay learned Q-tables in physics with goal switching; cumulative reward vs a "
        "random policy and the MDP-predicted rate (optional top-down GIF)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--arena", default="table", help="built-in arena name or .toml path")
    parser.add_argument("--states", required=True, metavar="JSON",
                        help="states file written by `simlab discretize`")
    parser.add_argument("--qtables", default=None, metavar="DIR",
                        help="output directory of `simlab train` (q_<goal>.npz per goal)")
    parser.add_argument("--hours", type=float, default=3.0,
                        help="robot time to replay, driving + idle latency (default 3)")
    parser.add_argument("--pose-source", choices=("truth", "odometry", "mcl"), default="truth",
                        help="pose the robot decides from (default truth)")
    parser.add_argument("--map", default=None, metavar="YAML",
                        help="map_server map to localize on and draw (default: the arena's "
                             "own geometry)")
    parser.add_argument("--mdp", default=None, metavar="NPZ",
                        help="mdp.npz for the predicted rate (default: the one the Q-tables "
                             "were trained on)")
    parser.add_argument("--goals", default=None, metavar="NAMES",
                        help="goals to switch between: arena goal names or state-id goals "
                             "as train --goal-states names them (s18, s18+19); default: all "
                             "of the arena's")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--out", required=True, metavar="DIR", help="output directory")
    parser.add_argument("--random", action="store_true",
                        help="replay the uniformly random policy instead of the Q-tables")
    parser.add_argument("--return-to-start", action="store_true",
                        help="drive back to the start pose after each goal (thesis "
                             "go_back_initial_pose)")
    parser.add_argument("--video", action="store_true",
                        help="also write replay.gif (and replay.mp4 with imageio-ffmpeg)")
    parser.add_argument("--baseline-hours", type=float, default=None, metavar="H",
                        help="random-policy baseline replay length (default: --hours; 0: none)")
    parser.add_argument("--epsilon", type=float, default=0.0,
                        help="probability of a random action per decision (default 0)")
    parser.add_argument("--escape-radius", type=float, default=0.03, metavar="M",
                        help="loop watchdog: random action instead of repeating an action "
                             "from within M metres of an earlier decision of the same goal "
                             "episode (default 0.03; 0: off)")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_primitive_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.replay.replay import replay

    result = replay(
        params=primitive_params_from_args(args),
        goals=args.goals,
        arena=args.arena,
        states=args.states,
        qtables=args.qtables,
        hours=args.hours,
        pose_source=args.pose_source,
        seed=args.seed,
        out=args.out,
        policy="random" if args.random else "greedy",
        map=args.map,
        return_to_start=args.return_to_start,
        video=args.video,
        progress=not args.no_progress,
        overwrite=args.overwrite,
        mdp=args.mdp,
        baseline_hours=args.baseline_hours,
        epsilon=args.epsilon,
        escape_radius=args.escape_radius,
    )
    s = result.summary
    r, c = s["result"], s["comparison"]
    print(f"{s['policy']} policy, {s['pose_source']} poses: {r['rewards']} goals in "
          f"{r['robot_seconds'] / 3600:.2f} robot-h ({r['transitions']} transitions) = "
          f"{r['rate_per_hour']:.1f} /h; {r['wall_seconds']:.0f} s wall")
    if "random_rate_per_hour" in c:
        ratio = c.get("ratio_to_random")
        print(f"random policy: {c['random_rate_per_hour']:.1f} /h"
              + (f" (learned/random = {ratio:.1f}x)" if ratio else ""))
    if "predicted_rate_per_hour" in c:
        ratio = c.get("measured_over_predicted")
        print(f"MDP-predicted: {c['predicted_rate_per_hour']:.1f} /h"
              + (f" (measured/predicted = {ratio:.2f})" if ratio is not None else
                 " (measured/predicted: undefined, the MDP predicts no reward)"))
    loc = s["localization"].get("mcl")
    if loc:
        a = loc["at_decisions"]
        print(f"MCL error at decisions: mean {100 * a['position_mean_m']:.1f} cm, "
              f"{a['heading_mean_rad']:.3f} rad")
    print(f"wrote {s['files']['summary']} and {s['files']['plot']}")
    return 0
