"""``simlab drive``: random primitives in an arena, a summary and an optional PNG.

The options are the fields of :class:`simlab.physics.drive.DriveConfig` (the primitive
options are its :class:`~simlab.physics.primitive_options.PrimitiveOptions` group).
"""

from __future__ import annotations

import argparse

HELP = "drive the TurtleBot3 with random motion primitives (headless) and summarize"


def add_arguments(p: argparse.ArgumentParser) -> None:
    from simlab.physics.drive import DriveConfig

    DriveConfig.add_arguments(p)


def run(args: argparse.Namespace) -> int:
    from simlab.physics.drive import DriveConfig, drive

    s = drive(DriveConfig.from_args(args))
    print(f"arena {s.arena}: {s.steps} primitives, {s.distance:.2f} m driven, "
          f"{s.blocked} blocked ({s.blocked / max(s.steps, 1):.0%}), "
          f"{s.sim_time:.0f} s simulated ({s.stepped_time:.0f} s stepped) in {s.wall_time:.1f} s "
          f"wall ({s.real_time_factor:.0f}x real time)")
    if s.png:
        print(f"wrote {s.png}")
    return 0
