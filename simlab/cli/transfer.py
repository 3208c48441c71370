"""``simlab transfer``: score policies of the simulated twin on the real robot's model.

The options are the fields of :class:`simlab.calibration.transfer.TransferConfig`.
"""

from __future__ import annotations

import argparse

#: How to ask transfer for less when it runs out of memory (its own options).
MEMORY_FIX = "a smaller --n-boot, fewer --sim twins or --goal-states"

HELP = ("score twin policies on the real model: expected steps to the goal vs the real "
        "optimum, per-state disagreements on the map")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.calibration.transfer import TransferConfig

    TransferConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.calibration.transfer import TransferConfig, transfer_command

    done = transfer_command(TransferConfig.from_args(args))
    result = done.result
    if len(result.goals) > 1 or any(ln is not None for ln in result.lines):
        print(result.overview_line())
    if len(result.goals) <= 3:
        print(result.summary_line())
    print("wrote " + ", ".join(str(p) for p in done.files.values()))
    return 0
