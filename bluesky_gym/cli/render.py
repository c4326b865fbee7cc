"""``bluesky-gym render``: fly episodes with a policy and write them to a GIF or MP4 (or a window).

Examples::

    bluesky-gym render HorizontalCREnv-v0 --out horizontal.gif             # random actions
    bluesky-gym render MergeEnv-v0 --policy classical --episodes 2 --out merge.mp4 --seed 7
    bluesky-gym render DescentEnv-v0 --policy runs/descent/model.zip --out descent.gif
    bluesky-gym render SectorCREnv-v0 --grid 4 --out sector_grid.gif     # 4 episodes side by side
    bluesky-gym render VerticalCREnv-v0 --human                          # watch in a window

The policy is ``random`` (uniform actions, seeded by ``--seed``), ``classical`` (the benchmark's
hand-written controller) or the path of a Stable-Baselines3 model ``.zip`` (its algorithm is read
from the file, or given with ``--algo``). ``--seed`` seeds the first episode; the following ones
continue the environment's generator, so the same command always writes the same video.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bluesky_gym.cli.arguments import positive_float, positive_int

Actor = Callable[[dict[str, np.ndarray]], np.ndarray]
NAMED_POLICIES = ("random", "classical")
SB3_ALGORITHMS = {"ppo": "PPO", "sac": "SAC", "td3": "TD3", "ddpg": "DDPG", "a2c": "A2C"}


def _option(text: str) -> tuple[str, Any]:
    key, sep, raw = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        value = ast.literal_eval(raw)
    except (ValueError, SyntaxError):
        value = raw
    return key.strip(), value


def add_parser(subparsers: Any) -> None:
    """Register the ``render`` subcommand."""
    p = subparsers.add_parser(
        "render",
        help="draw episodes of an environment to a GIF/MP4 file or a window",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("env_id", metavar="ID", help="environment id, e.g. HorizontalCREnv-v0")
    p.add_argument("--policy", default="random", help="random, classical, or the path of a Stable-Baselines3 model .zip (default: random)")
    p.add_argument("--algo", choices=sorted(SB3_ALGORITHMS), help="algorithm of the model .zip (default: read from the file)")
    p.add_argument("--stochastic", action="store_true", help="sample the model's actions instead of taking the deterministic ones")
    p.add_argument("--episodes", type=positive_int, default=1, metavar="K", help="episodes to record (default: 1)")
    p.add_argument("--out", type=Path, metavar="FILE", help="output .gif or .mp4 (default: ID.gif; not written with --human)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first episode and of random actions (default: 0)")
    p.add_argument("--max-steps", type=positive_int, metavar="N", help="truncate each episode after N steps (default: the id's limit)")
    p.add_argument("--every", type=positive_int, default=1, metavar="N", help="keep one frame every N steps (default: 1)")
    p.add_argument("--max-frames", type=positive_int, metavar="N", help="stop after N frames")
    p.add_argument("--fps", type=positive_float, default=10.0, help="frames per second of the video (default: 10)")
    p.add_argument("--scale", type=positive_float, default=1.0, help="resize factor of the video frames (default: 1)")
    p.add_argument("--colors", type=int, default=192, metavar="N", help="palette size of GIF frames, 2..256 (default: 192)")
    p.add_argument("--grid", type=positive_int, default=1, metavar="N", help="draw N episodes of a batched environment side by side")
    p.add_argument("--human", action="store_true", help="show the episodes in a window instead of writing a file")
    p.add_argument("--option", type=_option, action="append", default=[], metavar="KEY=VALUE", help="scenario option (repeatable)")
    p.set_defaults(func=run)


def _algo_from_zip(path: Path) -> str:
    """The algorithm of a Stable-Baselines3 model file, from its stored settings."""
    from bluesky_gym.training.evaluation import algorithm_of_zip

    name = algorithm_of_zip(path)
    if name is None:
        raise ValueError(f"cannot tell the algorithm of {path}; pass --algo (one of {', '.join(sorted(SB3_ALGORITHMS))})")
    return name.lower()


def make_actor(policy: str, env_id: str, action_space: Any, seed: int, algo: str | None = None, deterministic: bool = True) -> Actor:
    """A function from a batched observation dict to a batch of actions.

    Args:
        policy: ``random``, ``classical`` or the path of a Stable-Baselines3 model ``.zip``.
        env_id: Environment id (selects the classical controller).
        action_space: Action space of one environment.
        seed: Seed of the random actions.
        algo: Algorithm of the model file (default: read from it).
        deterministic: Deterministic model actions.
    """
    low = np.asarray(action_space.low, dtype=np.float64)
    high = np.asarray(action_space.high, dtype=np.float64)
    if policy == "random":
        rng = np.random.default_rng(seed)
        return lambda obs: rng.uniform(low, high, size=(next(iter(obs.values())).shape[0], *low.shape))
    if policy == "classical":
        from bluesky_gym.training.policies import reference_policy

        controller = reference_policy("classical", env_id, low, high)
        return controller.act
    path = Path(policy)
    if not path.is_file():
        raise ValueError(f"--policy must be one of {', '.join(NAMED_POLICIES)} or an existing model .zip file, got {policy!r}")
    try:
        import stable_baselines3 as sb3
    except ImportError as exc:
        raise ImportError('loading a model needs Stable-Baselines3: pip install "bluesky-gym[train]"') from exc
    name = algo or _algo_from_zip(path)
    model = getattr(sb3, SB3_ALGORITHMS[name]).load(path, device="cpu")

    def act(obs: dict[str, np.ndarray]) -> np.ndarray:
        action, _ = model.predict(obs, deterministic=deterministic)
        return np.asarray(action, dtype=np.float64).reshape(-1, *low.shape)

    return act


def record(
    env_id: str,
    policy: str = "random",
    episodes: int = 1,
    out: Path | None = None,
    seed: int = 0,
    max_steps: int | None = None,
    every: int = 1,
    max_frames: int | None = None,
    fps: float = 10.0,
    scale: float = 1.0,
    colors: int = 192,
    grid: int = 1,
    human: bool = False,
    algo: str | None = None,
    deterministic: bool = True,
    options: dict[str, Any] | None = None,
    log: Callable[[str], None] | None = None,
) -> tuple[Path | None, int]:
    """Fly ``episodes`` episodes of ``env_id`` and write their frames (or show them).

    Returns:
        The file written (None with ``human``) and the number of frames.
    """
    import gymnasium as gym

    import bluesky_gym
    from bluesky_gym.render import VideoWriter

    bluesky_gym.register_envs()
    if env_id not in gym.registry:
        raise ValueError(f"unknown environment {env_id!r}; available: {', '.join(bluesky_gym.available_envs())}")
    mode = "human" if human else "rgb_array"
    kwargs: dict[str, Any] = dict(options or {})
    if max_steps is not None:
        kwargs["max_episode_steps"] = max_steps
    writer = None if human else VideoWriter(out or Path(f"{env_id}.gif"), fps=fps, scale=scale, colors=colors)
    n_frames = 0

    def emit(env: Any) -> bool:
        """Record (or, in a window, count: the environment draws itself) the current frame."""
        nonlocal n_frames
        if writer is not None:
            writer.append(env.render())
        n_frames += 1
        return max_frames is not None and n_frames >= max_frames

    if grid > 1:
        env: Any = gym.make_vec(env_id, num_envs=grid, vectorization_mode="vector_entry_point", render_mode=mode, render_grid=grid, **kwargs)
        actor = make_actor(policy, env_id, env.single_action_space, seed, algo, deterministic)
        obs, _ = env.reset(seed=seed)
        ended = np.zeros(grid, int)
        step = 0
        stop = emit(env)
        while not stop and ended.min() < episodes:
            obs, _, te, tr, _ = env.step(actor(obs))
            ended += np.asarray(te | tr, int)
            step += 1
            if step % every == 0 or ended.min() >= episodes:
                stop = emit(env)
    else:
        if "max_episode_steps" in kwargs:
            env = gym.make(env_id, render_mode=mode, max_episode_steps=kwargs.pop("max_episode_steps"), **kwargs)
        else:
            env = gym.make(env_id, render_mode=mode, **kwargs)
        actor = make_actor(policy, env_id, env.action_space, seed, algo, deterministic)
        stop = False
        for k in range(episodes):
            obs, _ = env.reset(seed=seed if k == 0 else None)
            stop = emit(env)
            step = 0
            done = False
            while not (done or stop):
                action = actor({key: v[None] for key, v in obs.items()})[0]
                obs, reward, te, tr, _ = env.step(action)
                done = te or tr
                step += 1
                if step % every == 0 or done:
                    stop = emit(env)
            if log is not None:
                log(f"episode {k + 1}: {step} steps, return {float(env.unwrapped.task.stats.total_reward[0]):+.2f}")
            if stop:
                break
    env.close()
    path = writer.close() if writer is not None else None
    return path, n_frames


def run(args: argparse.Namespace) -> int:
    """Run the ``render`` subcommand."""
    try:
        path, n = record(
            args.env_id,
            policy=args.policy,
            episodes=args.episodes,
            out=args.out,
            seed=args.seed,
            max_steps=args.max_steps,
            every=args.every,
            max_frames=args.max_frames,
            fps=args.fps,
            scale=args.scale,
            colors=args.colors,
            grid=args.grid,
            human=args.human,
            algo=args.algo,
            deterministic=not args.stochastic,
            options=dict(args.option),
            log=lambda s: print(s, file=sys.stderr),
        )
    except (ValueError, TypeError, ImportError) as exc:  # bad id, option, policy, format or missing package
        print(f"bluesky-gym render: error: {exc}", file=sys.stderr)
        return 2
    if path is not None:
        print(f"wrote {n} frames to {path} ({path.stat().st_size / 1024:.0f} KiB)")
    return 0
