"""``simlab calibrate``: fit the primitive parameters so the simulated T matches a real one.

The options are the fields of :class:`simlab.calibration.command.CalibrateConfig`.
"""

from __future__ import annotations

import argparse

HELP = "calibrate primitive parameters against a real transition count table"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.calibration.command import CalibrateConfig

    CalibrateConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.calibration.command import CalibrateConfig, calibrate_command

    done = calibrate_command(CalibrateConfig.from_args(args))
    r = done.result
    values = ", ".join(f"{n}={getattr(r.params, n):.4g}" for n in r.space.names)
    print(f"best of {len(r.candidates)} candidates: {values}")
    print(f"TV distance {r.final.distance:.3f} (floor {r.floor.median:.3f}, matched "
          f"{r.matched_floor.median:.3f}); argmax agreement {r.agreement:.0%}")
    print("wrote " + ", ".join(str(p) for p in done.files.values()))
    return 0
