"""``simlab drive``: random primitives in an arena, a summary and an optional PNG."""

from __future__ import annotations

import argparse

from simlab.cli.collect import add_primitive_arguments, primitive_params_from_args

HELP = "drive the TurtleBot3 with random motion primitives (headless) and summarize"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--arena", default="table", help="built-in arena name or .toml path")
    p.add_argument("--steps", type=int, default=100, help="number of primitives (default 100)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--gui", action="store_true", help="open the PyBullet GUI (needs a display)")
    p.add_argument("--png", help="write a top-down picture of the trajectory here")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --png file")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--states", default=None,
                   help="states file (JSON of `simlab discretize`); needed by --mode "
                        "until_state_change (default: none)")
    add_primitive_arguments(p)


def run(args: argparse.Namespace) -> int:
    from simlab.physics.drive import drive

    s = drive(args.arena, args.steps, args.seed, gui=args.gui, png=args.png,
              overwrite=args.overwrite, params=primitive_params_from_args(args),
              states=args.states, progress=not args.no_progress)
    print(f"arena {s.arena}: {s.steps} primitives, {s.distance:.2f} m driven, "
          f"{s.blocked} blocked ({s.blocked / max(s.steps, 1):.0%}), "
          f"{s.sim_time:.0f} s simulated ({s.stepped_time:.0f} s stepped) in {s.wall_time:.1f} s "
          f"wall ({s.real_time_factor:.0f}x real time)")
    if s.png:
        print(f"wrote {s.png}")
    return 0
