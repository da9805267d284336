"""Record one episode of an acc_gym environment as a video with Gymnasium's ``RecordVideo``.

The environment is made with ``render_mode="rgb_array"`` (the top view with its HUD,
:mod:`acc_gym.rendering`), wrapped in :class:`gymnasium.wrappers.RecordVideo` and driven for
one episode by a controller loaded by name (:func:`acc_gym.controllers.make_controller`,
default ``acc``, the linear ACC law). ``RecordVideo`` writes an mp4 through moviepy
(``pip install moviepy``; it brings its own ffmpeg, no network needed) into a scratch
folder inside ``--out``; the file is then moved to ``OUT/NAME.mp4`` in one step. With
``--gif`` the same frames (every ``--gif-every``-th) are also written as ``OUT/NAME.gif``
(Pillow, a matplotlib dependency).

    python examples/record_video.py                   # docs/rendering.mp4: SingleLane-v1, a cut-in
    python examples/record_video.py --gif             # and docs/rendering.gif
    python examples/record_video.py --quick --out /tmp/video   # 25 steps, for a check

Exit code 0 when the video is written, 1 when moviepy is missing or the controller name is
unknown, 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
from pathlib import Path

import gymnasium
import numpy as np

import acc_gym  # noqa: F401  (registers the environments)
from acc_gym.controllers import make_controller, registered_controllers

ROOT = Path(__file__).resolve().parents[1]


def record(env_id: str, scenario: str | None, seed: int, controller: str, out: Path, name: str,
           max_steps: int | None = None, gif_every: int = 0) -> dict:
    """Record one episode; returns the paths written, the steps and the episode's score (None if cut)."""
    from gymnasium.wrappers import RecordVideo

    policy = make_controller(controller)
    if policy is None:
        raise LookupError(f"unknown controller {controller!r}; registered: {', '.join(registered_controllers())}")
    out.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=f".{name}-", dir=out))  # same filesystem: the move is one rename
    frames = []
    try:
        env = RecordVideo(gymnasium.make(env_id, render_mode="rgb_array"), str(scratch / "video"), name_prefix=name,
                          episode_trigger=lambda episode: episode == 0)
        options = {"scenario": scenario} if scenario else None
        obs, _ = env.reset(seed=seed, options=options)
        if hasattr(policy, "reset"):
            policy.reset()
        steps, info, done = 0, {}, False
        if gif_every:
            frames.append(env.unwrapped.render())
        while not done and (max_steps is None or steps < max_steps):
            action, _ = policy.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(np.asarray(action, dtype=np.float32).reshape(1))
            steps += 1
            done = terminated or truncated
            if gif_every and steps % gif_every == 0:
                frames.append(env.unwrapped.render())
        env.close()  # writes the mp4 (an episode cut by --max-steps too)
        written = sorted((scratch / "video").glob("*.mp4"))
        if len(written) != 1:
            raise RuntimeError(f"RecordVideo wrote {len(written)} videos into {scratch}, expected one")
        mp4 = out / f"{name}.mp4"
        os.replace(written[0], mp4)
        paths = [mp4]
        if gif_every:
            from PIL import Image

            images = [Image.fromarray(f).quantize(colors=64, method=Image.Quantize.MEDIANCUT) for f in frames]
            tmp = scratch / f"{name}.gif"
            images[0].save(tmp, save_all=True, append_images=images[1:], duration=int(1000 * gif_every /
                           env.metadata["render_fps"]), loop=0, optimize=True)
            os.replace(tmp, out / f"{name}.gif")
            paths.append(out / f"{name}.gif")
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return {"paths": paths, "steps": steps, "score": info.get("score"), "scenario": info.get("scenario")}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="acc_gym/SingleLane-v1", help="environment id")
    ap.add_argument("--scenario", default="singlelane/2/cut-in",
                    help="scenario id to reset into ('' for the environment's own draw)")
    ap.add_argument("--seed", type=int, default=1, help="reset seed")
    ap.add_argument("--controller", default="acc", help="a registered controller name")
    ap.add_argument("--out", type=Path, default=ROOT / "docs", help="output folder")
    ap.add_argument("--name", default="rendering", help="file name without extension")
    ap.add_argument("--gif", action="store_true", help="also write NAME.gif")
    ap.add_argument("--gif-every", type=int, default=2, help="GIF: every k-th frame")
    ap.add_argument("--max-steps", type=int, default=None, help="stop the episode after this many steps")
    ap.add_argument("--quick", action="store_true", help="25 steps (a check that it works)")
    args = ap.parse_args(argv)
    if args.gif_every < 1:
        ap.error(f"--gif-every must be >= 1, got {args.gif_every}")
    if args.max_steps is not None and args.max_steps < 1:
        ap.error(f"--max-steps must be >= 1, got {args.max_steps}")
    if not args.name or os.sep in args.name:
        ap.error(f"--name must be a file name without a folder, got {args.name!r}")
    try:
        import moviepy  # noqa: F401
    except ImportError:
        print("record_video: RecordVideo needs moviepy: pip install moviepy", file=sys.stderr)
        return 1
    try:
        result = record(args.env, args.scenario or None, args.seed, args.controller, args.out, args.name,
                        25 if args.quick else args.max_steps, args.gif_every if args.gif else 0)
    except LookupError as exc:
        print(f"record_video: {exc}", file=sys.stderr)
        return 1
    score = "cut before its end" if result["score"] is None else f"score {result['score']:.1f}"
    print(f"{result['scenario']}: {result['steps']} steps, {score}")
    for path in result["paths"]:
        print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
