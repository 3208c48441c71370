"""``simlab export-minari``: a transition dataset as a Minari dataset.

The options are the fields of :class:`simlab.envs.minari_export.ExportMinariConfig`.
"""

from __future__ import annotations

import argparse

HELP = "export a transition dataset as a Minari dataset (minari extra)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.envs.minari_export import ExportMinariConfig

    ExportMinariConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.envs.minari_export import ExportMinariConfig, export_minari

    result = export_minari(ExportMinariConfig.from_args(args))
    print(f"Minari dataset {result.dataset_id}: {result.episodes} episodes, {result.steps} "
          f"steps in {result.path}")
    return 0
