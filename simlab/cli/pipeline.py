"""``simlab pipeline``: map -> states -> 10-hour walk -> empirical MDP -> training -> replay."""

from __future__ import annotations

import argparse

HELP = ("the physics half end to end: map, Voronoi states, random-walk dataset, empirical MDP, "
        "training on 9 goals, 3-hour closed-loop replay, report.md")


def add_arguments(p: argparse.ArgumentParser) -> None:
    from simlab.orchestration.stages import PhysicsSettings

    d = PhysicsSettings()
    p.add_argument("--arena", default=d.arena, help="built-in arena name or .toml path")
    p.add_argument("--out", required=True, help="output directory (new or empty, or --resume)")
    p.add_argument("--resume", action="store_true",
                   help="continue a run in --out, reusing every stage whose settings match")
    p.add_argument("--seed", type=int, default=0, help="root seed of every stage (default 0)")
    p.add_argument("--map-minutes", type=float, default=d.map_minutes,
                   help=f"robot minutes of mapping exploration (default {d.map_minutes:g})")
    p.add_argument("--states", type=int, default=d.states,
                   help=f"Voronoi states (default {d.states})")
    p.add_argument("--hours", type=float, default=d.hours,
                   help=f"simulated hours of random walk (default {d.hours:g})")
    p.add_argument("--workers", type=int, default=d.workers,
                   help=f"collection processes (default {d.workers})")
    p.add_argument("--agent", default=d.agent, help=f"agent trained per goal (default {d.agent})")
    p.add_argument("--episodes", type=int, default=d.episodes,
                   help=f"training episodes per goal (default {d.episodes})")
    p.add_argument("--runs", type=int, default=d.runs,
                   help=f"independent training runs per goal (default {d.runs})")
    p.add_argument("--replay-hours", type=float, default=d.replay_hours,
                   help=f"simulated hours of closed-loop replay (default {d.replay_hours:g})")
    p.add_argument("--pose-source", choices=("truth", "odometry", "mcl"), default=d.pose_source,
                   help=f"the replay's pose source (default {d.pose_source})")
    p.add_argument("--no-video", action="store_true", help="skip the replay GIF")
    p.add_argument("--primitives", default="", metavar="FILE.toml",
                   help="[primitives] of the dataset walk, e.g. simlab calibrate's "
                        "primitives.toml (default: built-in; replay uses the dataset's)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    from simlab.orchestration.pipeline import pipeline

    res = pipeline(
        args.arena, args.out, seed=args.seed, resume=args.resume, progress=not args.no_progress,
        map_minutes=args.map_minutes, states=args.states, hours=args.hours, workers=args.workers,
        agent=args.agent, episodes=args.episodes, runs=args.runs,
        replay_hours=args.replay_hours, pose_source=args.pose_source, video=not args.no_video,
        primitives=args.primitives,
    )
    print(f"done in {res.wall_seconds:.0f} s: {res.report}")
    return 0
