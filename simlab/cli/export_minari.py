"""``simlab export-minari``: a transition dataset as a Minari dataset."""

from __future__ import annotations

import argparse

HELP = "export a transition dataset as a Minari dataset (minari extra)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", help="dataset directory written by `simlab collect`")
    parser.add_argument("--id", required=True, dest="dataset_id",
                        help="Minari dataset id, e.g. simlab/table-walk-v0")
    parser.add_argument("--episode-length", type=int, default=None,
                        help="transitions per episode (default: the dataset's part size)")
    parser.add_argument("--goal", default=None,
                        help="goal area name: reward 1 when s' is in it (default: rewards 0)")
    parser.add_argument("--arena", default=None,
                        help="arena (built-in name or TOML path) recorded in the env spec for "
                             "recover_environment() (default: the manifest's arena name)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace a local Minari dataset with the same id")


def run(args: argparse.Namespace) -> int:
    from simlab.envs.minari_export import export_minari

    result = export_minari(args.dataset, args.dataset_id, episode_length=args.episode_length,
                           goal=args.goal, overwrite=args.overwrite, arena=args.arena)
    print(f"Minari dataset {result.dataset_id}: {result.episodes} episodes, {result.steps} "
          f"steps in {result.path}")
    return 0
