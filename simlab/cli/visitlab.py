"""``simlab visitlab``: the tabular Visit-the-lab simulation (train modules, show episodes).

Examples::

    simlab visitlab train --task nav --agent mb-egreedy,q-learning --trials 2000 \\
        --seeds 10 --out runs/nav
    simlab visitlab train --task social --agent mb-egreedy --human easy,medium,hard \\
        --trials 100000 --seeds 10 --workers 2 --out runs/social
    simlab visitlab show --task social --human medium --steps 8
    simlab visitlab combined --nav runs/nav/curves.npz --social runs/social/curves.npz \
        --gotohuman runs/gth/curves.npz --trials 200 --gif episode.gif

For ``combined``, train the navigation module on the combined world with random starts
and goals (``visitlab train --task nav --agent rmax --start random --goal random``; the
thesis's fixed-goal navigation run only knows one room).
"""

from __future__ import annotations

import argparse

HELP = ("Visit the lab: train the navigation, social and go-to-human modules; show episodes; "
        "run the combined architecture")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.visitlab.combined import CombinedConfig
    from simlab.visitlab.options import ShowConfig, VisitlabTrainConfig
    from simlab.visitlab.results import PlotConfig

    sub = parser.add_subparsers(dest="visitlab_command", metavar="ACTION", required=True)
    t = sub.add_parser("train", help="train agents, save curves (npz), a plot and a summary",
                       description="Train one or more agents (and humans) for several seeds; "
                                   "writes curves.npz, curves.png and summary.json into --out.")
    VisitlabTrainConfig.add_arguments(t)
    # repeatable, so not generated: the field is the dict ``agent_overrides``
    t.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="agent parameter override, repeatable (e.g. --set plan_every=1000, "
                        "--set q_init=none, --set actor.epsilon=0.1)")
    pl = sub.add_parser("plot", help="plot curves of several 'visitlab train' outputs together",
                        description="Draw the curves of one or more curves.npz files on one "
                                    "Fig. 4.1-style plot.")
    PlotConfig.add_arguments(pl)
    s = sub.add_parser("show", help="print an episode as text frames",
                       description="Run one episode with a random policy, or greedily with a "
                                   "trained Q table, and print each step as text.")
    ShowConfig.add_arguments(s)
    c = sub.add_parser("combined", help="run the combined architecture with trained modules",
                       description="Lead a human to goal rooms with three trained Q tables "
                                   "(thesis Fig. 3.1): prints goal rooms reached per trial, "
                                   "optionally writes an episode GIF.")
    CombinedConfig.add_arguments(c)


def train_config_from_args(args: argparse.Namespace):  # -> VisitlabTrainConfig
    """The train options of the parsed command line (``--set`` pairs win over a ``set``
    table of ``--config FILE``)."""
    from simlab.visitlab.options import VisitlabTrainConfig, parse_overrides

    cfg = VisitlabTrainConfig.from_args(args)
    if args.set:
        cfg = cfg.replace(agent_overrides={**(cfg.agent_overrides or {}),
                                           **parse_overrides(args.set)})
    return cfg


def _print_run(res) -> None:
    s = res.summary()
    print(f"{res.label}: plateau {s['plateau']:.2f} +- {s['plateau_std']:.2f} per "
          f"trial (last 10% of {s['n_trials']} trials, {s['n_seeds']} seeds), 90% "
          f"of it reached at trial {s['trials_to_90pct']}, "
          f"{s['wall_time_s']:.1f} s")


def _train(args: argparse.Namespace) -> int:
    from simlab.visitlab.training import train_command

    runs = train_command(train_config_from_args(args), on_result=_print_run)
    print("wrote " + ", ".join(str(f) for f in runs.files))
    return 0


def _show(args: argparse.Namespace) -> int:
    import numpy as np

    from simlab.agents.kernels import greedy_action
    from simlab.base.errors import ConfigError
    from simlab.visitlab.options import ShowConfig
    from simlab.visitlab.training import make_env

    cfg = ShowConfig.from_args(args)
    if cfg.png:
        from simlab.base.io import ensure_new

        ensure_new(cfg.png, overwrite=cfg.overwrite, what="PNG")  # before the episode
    env = make_env(cfg.task, variant=cfg.variant, render_mode="ansi",
                   **cfg.env_kwargs(cfg.humans()[0]))
    q = None
    if cfg.q is not None:
        from simlab.visitlab.results import load_results

        runs = load_results(cfg.q)
        if not 0 <= cfg.run < len(runs):
            raise ConfigError(f"expected a run index in 0..{len(runs) - 1}", key="--run")
        q = runs[cfg.run].q
        if not 0 <= cfg.seed_index < q.shape[0]:
            raise ConfigError(f"expected a seed index in 0..{q.shape[0] - 1}", key="--seed-index")
        q = q[cfg.seed_index]
        if q.shape != (env.observation_space.n, env.action_space.n):
            raise ConfigError(f"Q table of shape {q.shape} does not fit this task's "
                              f"({env.observation_space.n}, {env.action_space.n})", key="--q")
    rng = np.random.default_rng(cfg.seed)
    obs, _ = env.reset(seed=cfg.seed)
    env.action_space.seed(cfg.seed)
    print(env.render())
    total, truncated = 0.0, False
    while not truncated:
        a = int(greedy_action(q[obs], rng)) if q is not None else int(env.action_space.sample())
        obs, reward, _, truncated, _ = env.step(a)
        total += reward
        print(f"action {a}  reward {reward:g}  total {total:g}")
        print(env.render())
    if cfg.png:
        from simlab.base.io import atomic_write

        env.render_mode = "rgb_array"
        import imageio.v3 as iio

        with atomic_write(cfg.png, "wb") as fh:
            fh.write(iio.imwrite("<bytes>", env.render(), extension=".png"))
        print(f"wrote {cfg.png}")
    return 0


def _plot(args: argparse.Namespace) -> int:
    from simlab.base.errors import ConfigError
    from simlab.base.io import ensure_new
    from simlab.visitlab.results import PlotConfig, load_results, plot_results, summarize_curve

    cfg = PlotConfig.from_args(args)
    ensure_new(cfg.out, overwrite=cfg.overwrite, what="plot")
    runs = [r for path in cfg.curves for r in load_results(path)]
    labels = cfg.label_list()
    if labels is not None:
        if len(labels) != len(runs):
            raise ConfigError(f"{len(labels)} labels for {len(runs)} curves", key="--labels")
        for r, label in zip(runs, labels, strict=True):
            r.label = label
    plot_results(runs, cfg.out, title=cfg.title)
    for r in runs:
        s = summarize_curve(r.returns)
        print(f"{r.label}: plateau {s['plateau']:.2f} +- {s['plateau_std']:.2f}, 90% at trial "
              f"{s['trials_to_90pct']}")
    print(f"wrote {cfg.out}")
    return 0


def _module_q(path, run: int, seed_index: int, task: str):
    """The Q table of the module of ``task`` (``nav``, ``social``, ``gotohuman``: each is
    also the ``visitlab combined`` option that takes it) from a ``visitlab train`` curves
    file; a file trained on another task (modules given in the wrong order) is refused
    naming the file, the task it holds and the option it goes to."""
    from simlab.base.errors import ConfigError
    from simlab.visitlab import TASKS
    from simlab.visitlab.results import load_results

    runs = load_results(path)
    if not 0 <= run < len(runs):
        raise ConfigError(f"expected a run index in 0..{len(runs) - 1}", path=path, key="--run")
    held = runs[run].config.get("task")
    if held is not None and held != task:
        raise ConfigError(
            f"holds a '{held}' module (visitlab train --task {held}), but --{task} takes "
            f"the '{task}' module", path=path, key=f"--{task}",
            fix=(f"give this file to --{held}, and to --{task} the curves.npz of visitlab "
                 f"train --task {task}") if held in TASKS else
                f"give --{task} the curves.npz of visitlab train --task {task}")
    q = runs[run].q
    if not 0 <= seed_index < q.shape[0]:
        raise ConfigError(f"expected a seed index in 0..{q.shape[0] - 1}", path=path,
                          key="--seed-index")
    return q[seed_index], runs[run].config


def _combined(args: argparse.Namespace) -> int:
    import numpy as np

    from simlab.base.errors import ConfigError
    from simlab.base.io import ensure_new
    from simlab.visitlab.combined import (
        CombinedConfig,
        CombinedTask,
        Modules,
        evaluate,
        record_episodes,
        write_episode_gif,
    )
    from simlab.visitlab.humans import Human
    from simlab.visitlab.training import seed_generators

    cfg = CombinedConfig.from_args(args)
    if cfg.gif:
        ensure_new(cfg.gif, overwrite=cfg.overwrite, what="GIF")
    nav, _ = _module_q(cfg.nav, cfg.run, cfg.seed_index, "nav")
    social, social_cfg = _module_q(cfg.social, cfg.run, cfg.seed_index, "social")
    gth, _ = _module_q(cfg.gotohuman, cfg.run, cfg.seed_index, "gotohuman")
    human = cfg.human
    if human is None:
        trained = social_cfg.get("human")
        if not trained:
            raise ConfigError("the social curves file names no human", key="--human",
                              fix="pass --human")
        human = Human(**{**trained, "speed_probs": tuple(trained["speed_probs"])})
    task = CombinedTask(layout=cfg.layout, human=human, speed_weights=cfg.speed_weights(),
                        max_steps=cfg.steps)
    modules = Modules(nav, social, gth)
    res = evaluate(task, modules, cfg.trials, seed_generators(cfg.seed, 1)[0])
    chance = evaluate(task, modules, cfg.trials, seed_generators(cfg.seed, 1)[0], epsilon=1.0)
    print(f"goal rooms per {cfg.steps}-step trial: {res.goals.mean():.2f} "
          f"(random social actions: {chance.goals.mean():.2f}; {cfg.trials} trials, human "
          f"'{task.human.name}', weights {task.speed_weights})")
    if cfg.gif:
        episodes = record_episodes(task, modules, min(cfg.trials, 50),
                                   seed_generators(cfg.seed, 1)[0])
        pick = next((e for e in episodes if e.goals >= 2),
                    max(episodes, key=lambda e: e.goals))
        write_episode_gif(task, pick, cfg.gif, overwrite=cfg.overwrite)
        print(f"wrote {cfg.gif} ({pick.goals} goal rooms in {cfg.steps} steps; "
              f"goals per trial of those shown: {np.mean([e.goals for e in episodes]):.2f})")
    return 0


def run(args: argparse.Namespace) -> int | None:
    if args.visitlab_command == "train":
        return _train(args)
    if args.visitlab_command == "plot":
        return _plot(args)
    if args.visitlab_command == "combined":
        return _combined(args)
    return _show(args)
