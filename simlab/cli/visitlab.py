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

from simlab.visitlab import TASKS

HELP = ("Visit the lab: train the navigation, social and go-to-human modules; show episodes; "
        "run the combined architecture")


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--task", choices=TASKS, default="social",
                   help="module to run (default: social)")
    p.add_argument("--variant", choices=("thesis", "paper"), default="thesis",
                   help="thesis or paper settings (default: thesis)")
    p.add_argument("--human", default=None,
                   help="human preset(s), comma-separated: easy, medium, hard, H1, H2, H3 "
                        "(social default: easy / H1; go-to-human default: a still human)")
    p.add_argument("--layout", default=None,
                   help="gridworld, gridworld-HxW, paper or lab (default: the task's)")
    p.add_argument("--layout-seed", type=int, default=None, help="seed of a random lab layout")
    p.add_argument("--episode", choices=("random", "fixed_positions", "fixed"), default=None,
                   help="go-to-human episode variant (thesis Fig. 4.4; default random)")
    p.add_argument("--start", default=None,
                   help="navigation start: 'random' or a cell index (default: the variant's)")
    p.add_argument("--goal", default=None,
                   help="navigation goal room: 'random' or a label (default: the variant's)")
    p.add_argument("--steps", type=int, default=None,
                   help="steps per trial (default: thesis 50 nav / 40 others, paper 20)")
    p.add_argument("--seed", type=int, default=0, help="root seed (default 0)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="visitlab_command", metavar="ACTION", required=True)
    t = sub.add_parser("train", help="train agents, save curves (npz), a plot and a summary",
                       description="Train one or more agents (and humans) for several seeds; "
                                   "writes curves.npz, curves.png and summary.json into --out.")
    _common(t)
    t.add_argument("--agent", default="mb-egreedy",
                   help="agent name(s), comma-separated: q-learning, q-softmax, mb-egreedy, "
                        "vi-softmax, rmax, sliding-window, passive-observer")
    t.add_argument("--trials", type=int, default=None,
                   help="trials per seed (default: nav 2000, social 40000, gotohuman 2000)")
    t.add_argument("--seeds", type=int, default=10, help="independent runs (default 10)")
    t.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="agent parameter override, repeatable (e.g. --set plan_every=1000, "
                        "--set q_init=none, --set actor.epsilon=0.1)")
    t.add_argument("--workers", type=int, default=1, help="processes for the seeds (default 1)")
    t.add_argument("--out", required=True, help="output directory")
    t.add_argument("--title", default="", help="plot title")
    t.add_argument("--overwrite", action="store_true", help="replace existing output files")
    t.add_argument("--no-progress", action="store_true", help="no progress bar")
    pl = sub.add_parser("plot", help="plot curves of several 'visitlab train' outputs together",
                        description="Draw the curves of one or more curves.npz files on one "
                                    "Fig. 4.1-style plot.")
    pl.add_argument("curves", nargs="+", help="curves.npz files")
    pl.add_argument("--labels", default=None,
                    help="comma-separated legend labels, one per curve in file order")
    pl.add_argument("--title", default="", help="plot title")
    pl.add_argument("--out", required=True, help="PNG to write")
    pl.add_argument("--overwrite", action="store_true", help="replace an existing PNG")
    s = sub.add_parser("show", help="print an episode as text frames",
                       description="Run one episode with a random policy, or greedily with a "
                                   "trained Q table, and print each step as text.")
    _common(s)
    s.add_argument("--q", default=None,
                   help="curves.npz from 'visitlab train': act greedily with its Q")
    s.add_argument("--run", type=int, default=0, help="run index in the curves file")
    s.add_argument("--seed-index", type=int, default=0, help="seeded run whose Q to use")
    s.add_argument("--png", default=None, help="also save the last frame as a PNG")
    s.add_argument("--overwrite", action="store_true", help="replace an existing --png")
    c = sub.add_parser("combined", help="run the combined architecture with trained modules",
                       description="Lead a human to goal rooms with three trained Q tables "
                                   "(thesis Fig. 3.1): prints goal rooms reached per trial, "
                                   "optionally writes an episode GIF.")
    for module, what in (("nav", "goal-conditioned navigation (random start and goal)"),
                         ("social", "social"), ("gotohuman", "go-to-human")):
        c.add_argument(f"--{module}", required=True, metavar="CURVES",
                       help=f"curves.npz of the {what} module ('visitlab train')")
    c.add_argument("--run", type=int, default=0, help="run index in each curves file")
    c.add_argument("--seed-index", type=int, default=0, help="seeded run whose Q tables to use")
    c.add_argument("--human", default=None,
                   help="human preset (default: the social module's training human)")
    c.add_argument("--layout", default="gridworld", help="the world (the navigation module's)")
    c.add_argument("--steps", type=int, default=100, help="steps per trial (default 100)")
    c.add_argument("--weights", default="0.1,0.1,0.8",
                   help="speed coefficients w1,w2,w3 (thesis 0.1,0.1,0.8; paper 1/3 each)")
    c.add_argument("--trials", type=int, default=100, help="trials (default 100)")
    c.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    c.add_argument("--gif", default=None,
                   help="write the first trial with two goals or more (else the best) as a GIF")
    c.add_argument("--overwrite", action="store_true", help="replace an existing GIF")


def _parse_value(text: str):
    low = text.strip().lower()
    if low in ("none", "null"):
        return None
    if low in ("true", "false"):
        return low == "true"
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def _overrides(items: list[str]) -> dict:
    from simlab.errors import ConfigError

    out = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"expected KEY=VALUE, got {item!r}", key="--set")
        key, value = item.split("=", 1)
        out[key.strip()] = _parse_value(value)
    return out


def _env_kwargs(args: argparse.Namespace) -> dict:
    kw: dict = {}
    if args.layout is not None:
        kw["layout"] = args.layout
    if args.layout_seed is not None:
        kw["layout_seed"] = args.layout_seed
    if args.episode is not None:
        if args.task != "gotohuman":
            from simlab.errors import ConfigError

            raise ConfigError("only the gotohuman task has episode variants", key="--episode")
        kw["episode"] = args.episode
    for key in ("start", "goal"):
        value = getattr(args, key)
        if value is None:
            continue
        if args.task != "nav":
            from simlab.errors import ConfigError

            raise ConfigError("only the nav task has a start and a goal", key=f"--{key}")
        kw[key] = value if value == "random" else _parse_value(value)
    if args.steps is not None:
        kw["max_steps"] = args.steps
    return kw


def _humans(args: argparse.Namespace) -> list:
    if args.human is None:
        return [None]
    if args.task == "nav":
        from simlab.errors import ConfigError

        raise ConfigError("the navigation task has no human", key="--human")
    return [h.strip() for h in args.human.split(",") if h.strip()]


def _train(args: argparse.Namespace) -> int:
    from pathlib import Path

    from simlab.io import output_transaction
    from simlab.visitlab.results import FILES, save_results
    from simlab.visitlab.training import train

    out = Path(args.out)
    finals = [out / name for name in FILES]
    overrides = _overrides(args.set)
    # the one output transaction: refused before hours of training (a file in the way, a
    # locked --out), written whole or not at all (a full disk, Ctrl-C)
    with output_transaction(out, finals, overwrite=args.overwrite,
                            what="visitlab output") as txn:
        results = []
        for agent in [a.strip() for a in args.agent.split(",") if a.strip()]:
            for human in _humans(args):
                kw = _env_kwargs(args)
                if human is not None:
                    kw["human"] = human
                res = train(args.task, agent, trials=args.trials, seeds=args.seeds,
                            seed=args.seed, variant=args.variant,
                            progress=not args.no_progress, agent_overrides=overrides,
                            workers=args.workers, **kw)
                results.append(res)
                s = res.summary()
                print(f"{res.label}: plateau {s['plateau']:.2f} +- {s['plateau_std']:.2f} per "
                      f"trial (last 10% of {s['n_trials']} trials, {s['n_seeds']} seeds), 90% "
                      f"of it reached at trial {s['trials_to_90pct']}, "
                      f"{s['wall_time_s']:.1f} s")
        save_results(results, txn.staging, overwrite=True, title=args.title)
    print("wrote " + ", ".join(str(f) for f in finals))
    return 0


def _show(args: argparse.Namespace) -> int:
    import numpy as np

    from simlab.agents.kernels import greedy_action
    from simlab.errors import ConfigError
    from simlab.visitlab.training import make_env

    if args.png:
        from simlab.io import ensure_new

        ensure_new(args.png, overwrite=args.overwrite, what="PNG")  # before the episode
    kw = _env_kwargs(args)
    humans = _humans(args)
    if humans[0] is not None:
        kw["human"] = humans[0]
    env = make_env(args.task, variant=args.variant, render_mode="ansi", **kw)
    q = None
    if args.q is not None:
        from simlab.visitlab.results import load_results

        runs = load_results(args.q)
        if not 0 <= args.run < len(runs):
            raise ConfigError(f"expected a run index in 0..{len(runs) - 1}", key="--run")
        q = runs[args.run].q
        if not 0 <= args.seed_index < q.shape[0]:
            raise ConfigError(f"expected a seed index in 0..{q.shape[0] - 1}", key="--seed-index")
        q = q[args.seed_index]
        if q.shape != (env.observation_space.n, env.action_space.n):
            raise ConfigError(f"Q table of shape {q.shape} does not fit this task's "
                              f"({env.observation_space.n}, {env.action_space.n})", key="--q")
    rng = np.random.default_rng(args.seed)
    obs, _ = env.reset(seed=args.seed)
    env.action_space.seed(args.seed)
    print(env.render())
    total, truncated = 0.0, False
    while not truncated:
        a = int(greedy_action(q[obs], rng)) if q is not None else int(env.action_space.sample())
        obs, reward, _, truncated, _ = env.step(a)
        total += reward
        print(f"action {a}  reward {reward:g}  total {total:g}")
        print(env.render())
    if args.png:
        from simlab.io import atomic_write

        env.render_mode = "rgb_array"
        import imageio.v3 as iio

        with atomic_write(args.png, "wb") as fh:
            fh.write(iio.imwrite("<bytes>", env.render(), extension=".png"))
        print(f"wrote {args.png}")
    return 0


def _plot(args: argparse.Namespace) -> int:
    from simlab.errors import ConfigError
    from simlab.io import ensure_new
    from simlab.visitlab.results import load_results, plot_results, summarize_curve

    ensure_new(args.out, overwrite=args.overwrite, what="plot")
    runs = [r for path in args.curves for r in load_results(path)]
    if args.labels is not None:
        labels = [x.strip() for x in args.labels.split(",")]
        if len(labels) != len(runs):
            raise ConfigError(f"{len(labels)} labels for {len(runs)} curves", key="--labels")
        for r, label in zip(runs, labels, strict=True):
            r.label = label
    plot_results(runs, args.out, title=args.title)
    for r in runs:
        s = summarize_curve(r.returns)
        print(f"{r.label}: plateau {s['plateau']:.2f} +- {s['plateau_std']:.2f}, 90% at trial "
              f"{s['trials_to_90pct']}")
    print(f"wrote {args.out}")
    return 0


def _module_q(path: str, run: int, seed_index: int):
    from simlab.errors import ConfigError
    from simlab.visitlab.results import load_results

    runs = load_results(path)
    if not 0 <= run < len(runs):
        raise ConfigError(f"expected a run index in 0..{len(runs) - 1}", path=path, key="--run")
    q = runs[run].q
    if not 0 <= seed_index < q.shape[0]:
        raise ConfigError(f"expected a seed index in 0..{q.shape[0] - 1}", path=path,
                          key="--seed-index")
    return q[seed_index], runs[run].config


def _combined(args: argparse.Namespace) -> int:
    import numpy as np

    from simlab.errors import ConfigError
    from simlab.io import ensure_new
    from simlab.visitlab.combined import (
        CombinedTask,
        Modules,
        evaluate,
        record_episodes,
        write_episode_gif,
    )
    from simlab.visitlab.humans import Human
    from simlab.visitlab.training import seed_generators

    if args.gif:
        ensure_new(args.gif, overwrite=args.overwrite, what="GIF")
    nav, _ = _module_q(args.nav, args.run, args.seed_index)
    social, social_cfg = _module_q(args.social, args.run, args.seed_index)
    gth, _ = _module_q(args.gotohuman, args.run, args.seed_index)
    human = args.human
    if human is None:
        trained = social_cfg.get("human")
        if not trained:
            raise ConfigError("the social curves file names no human", key="--human",
                              fix="pass --human")
        human = Human(**{**trained, "speed_probs": tuple(trained["speed_probs"])})
    try:
        weights = tuple(float(x) for x in args.weights.split(","))
    except ValueError:
        raise ConfigError(f"expected three numbers, got {args.weights!r}", key="--weights") from None
    task = CombinedTask(layout=args.layout, human=human, speed_weights=weights,
                        max_steps=args.steps)
    modules = Modules(nav, social, gth)
    res = evaluate(task, modules, args.trials, seed_generators(args.seed, 1)[0])
    chance = evaluate(task, modules, args.trials, seed_generators(args.seed, 1)[0], epsilon=1.0)
    print(f"goal rooms per {args.steps}-step trial: {res.goals.mean():.2f} "
          f"(random social actions: {chance.goals.mean():.2f}; {args.trials} trials, human "
          f"'{task.human.name}', weights {task.speed_weights})")
    if args.gif:
        episodes = record_episodes(task, modules, min(args.trials, 50),
                                   seed_generators(args.seed, 1)[0])
        pick = next((e for e in episodes if e.goals >= 2),
                    max(episodes, key=lambda e: e.goals))
        write_episode_gif(task, pick, args.gif, overwrite=args.overwrite)
        print(f"wrote {args.gif} ({pick.goals} goal rooms in {args.steps} steps; "
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
