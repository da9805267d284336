"""PPO in one file, in plain torch (CleanRL style): learn ACC on ``acc_gym/CarFollowing-v1``.

    python examples/cleanrl_ppo.py --total-timesteps 1000000 --seed 0 --out runs/cleanrl_ppo
    python examples/cleanrl_ppo.py --quick                      # a 20-second smoke run

No stable-baselines3: everything the algorithm does is below -- the rollout on acc_gym's
native vector env (``gym.make_vec``, next-step autoreset), running observation
normalisation, generalised advantage estimation, the clipped surrogate, the value loss and
the optimiser loop -- with the same settings as the shipped PPO hyperparameters
(``agents/rl/hyperparams/ppo.yml``): 16 envs x 256 steps a rollout, 10 epochs of minibatches
of 128, learning rate 3e-4 falling linearly to 0, gamma 0.99, lambda 0.95, clip 0.2, no
entropy bonus, tanh MLPs 64-64, an initial action sd of e^-1. The observation and reward
are the environment's own (``-v1``: the safety-margin features and ``MarginReward``).

At the end the deterministic policy (the actor's mean, clipped to [-1, 1], on frozen
normalisation statistics) is scored by :func:`acc_gym.evaluation.runner.evaluate` on
``--eval-episodes`` episodes of a seed never trained on, exactly as any other controller,
and the result is printed as JSON (``--out`` also saves the weights and statistics).

**Next-step autoreset.** The step after an episode ends returns the first observation of
the next episode and ignores its action (Gymnasium's default for vector envs). So the
observation returned *with* ``terminated`` / ``truncated`` is the episode's last one, which
bootstraps a truncated episode's value; the step after it is not a transition and is left
out of the loss (``valid``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
import torch.nn as nn

import acc_gym  # noqa: F401  (registers the ids)


def parse(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--env-id", default="acc_gym/CarFollowing-v1")
    ap.add_argument("--total-timesteps", type=int, default=1_000_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--num-envs", type=int, default=16)
    ap.add_argument("--num-steps", type=int, default=256, help="steps per env per rollout")
    ap.add_argument("--minibatch-size", type=int, default=128)
    ap.add_argument("--update-epochs", type=int, default=10)
    ap.add_argument("--learning-rate", type=float, default=3e-4, help="falls linearly to 0")
    ap.add_argument("--gamma", type=float, default=0.99)
    ap.add_argument("--gae-lambda", type=float, default=0.95)
    ap.add_argument("--clip-coef", type=float, default=0.2)
    ap.add_argument("--ent-coef", type=float, default=0.0)
    ap.add_argument("--vf-coef", type=float, default=0.5)
    ap.add_argument("--max-grad-norm", type=float, default=0.5)
    ap.add_argument("--log-std-init", type=float, default=-1.0)
    ap.add_argument("--eval-episodes", type=int, default=100)
    ap.add_argument("--eval-seed", type=int, default=20261130, help="never a training seed")
    ap.add_argument("--out", default=None, help="save agent.pt and obs_rms.npz here")
    ap.add_argument("--quick", action="store_true", help="a smoke run: 4 envs, 8,192 steps, 3 evaluation episodes")
    args = ap.parse_args(argv)
    if args.quick:
        args.num_envs, args.num_steps, args.total_timesteps, args.eval_episodes = 4, 256, 8192, 3
    batch = args.num_envs * args.num_steps
    if batch % args.minibatch_size:
        ap.error(f"--minibatch-size {args.minibatch_size} must divide num_envs x num_steps = {batch}")
    return args


class RunningMeanStd:
    """Observation statistics over everything seen (Chan et al.'s parallel update)."""

    def __init__(self, shape):
        self.mean, self.var, self.count = np.zeros(shape), np.ones(shape), 1e-4

    def update(self, x: np.ndarray) -> None:
        mean, var, n = x.mean(0), x.var(0), x.shape[0]
        delta, total = mean - self.mean, self.count + n
        self.mean = self.mean + delta * n / total
        self.var = (self.var * self.count + var * n + delta ** 2 * self.count * n / total) / total
        self.count = total

    def normalise(self, x: np.ndarray) -> np.ndarray:
        return np.clip((x - self.mean) / np.sqrt(self.var + 1e-8), -10.0, 10.0).astype(np.float32)


def layer(n_in: int, n_out: int, gain: float) -> nn.Linear:
    lin = nn.Linear(n_in, n_out)
    nn.init.orthogonal_(lin.weight, gain)
    nn.init.zeros_(lin.bias)
    return lin


class Agent(nn.Module):
    def __init__(self, n_obs: int, n_act: int, log_std_init: float):
        super().__init__()
        self.critic = nn.Sequential(layer(n_obs, 64, 2 ** 0.5), nn.Tanh(), layer(64, 64, 2 ** 0.5), nn.Tanh(),
                                    layer(64, 1, 1.0))
        self.actor = nn.Sequential(layer(n_obs, 64, 2 ** 0.5), nn.Tanh(), layer(64, 64, 2 ** 0.5), nn.Tanh(),
                                   layer(64, n_act, 0.01))
        self.log_std = nn.Parameter(torch.full((n_act,), float(log_std_init)))

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x).squeeze(-1)

    def act(self, x: torch.Tensor, action: torch.Tensor | None = None):
        dist = torch.distributions.Normal(self.actor(x), self.log_std.exp())
        if action is None:
            action = dist.sample()
        return action, dist.log_prob(action).sum(-1), dist.entropy().sum(-1), self.value(x)


def advantages(rewards, values, next_value, terminated, done, valid, gamma: float, lam: float) -> torch.Tensor:
    """Generalised advantage estimates ``(T, N)`` under next-step autoreset.

    A step that ends its episode (``done``) bootstraps from the value of the observation it
    returned -- the episode's last, stored at ``t + 1`` -- unless it ``terminated`` (0), and
    cuts the chain; a step that only resets (not ``valid``) gets 0 and is not a transition."""
    T, N = rewards.shape
    adv = torch.zeros((T, N))
    last = torch.zeros(N)
    for t in reversed(range(T)):
        v_next = next_value if t == T - 1 else values[t + 1]
        term_t = torch.as_tensor(terminated[t], dtype=torch.float32)
        done_t = torch.as_tensor(done[t], dtype=torch.float32)
        delta = rewards[t] + gamma * v_next * (1 - term_t) - values[t]
        last = delta + gamma * lam * (1 - done_t) * last
        last = torch.where(torch.as_tensor(valid[t]), last, torch.zeros(N))
        adv[t] = last
    return adv


class Controller:
    """The trained actor as an acc_gym controller: ``predict(obs, deterministic=True)``."""

    def __init__(self, agent: Agent, rms: RunningMeanStd):
        self.agent, self.rms = agent, rms

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        with torch.no_grad():
            mean = self.agent.actor(torch.as_tensor(self.rms.normalise(np.asarray(obs, dtype=np.float64))))
        return np.clip(mean.numpy(), -1.0, 1.0), None


def train(args: argparse.Namespace) -> dict:
    torch.set_num_threads(1)
    torch.manual_seed(args.seed)  # the initial weights, the action noise and the minibatch order
    envs = gym.make_vec(args.env_id, num_envs=args.num_envs, vectorization_mode="vector_entry_point")
    n_obs, n_act = envs.single_observation_space.shape[0], envs.single_action_space.shape[0]
    agent = Agent(n_obs, n_act, args.log_std_init)
    optimiser = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)
    T, N = args.num_steps, args.num_envs
    obs_buf = np.zeros((T, N, n_obs), np.float32)
    act_buf = torch.zeros((T, N, n_act))
    logp_buf, rew_buf, val_buf = torch.zeros((T, N)), np.zeros((T, N)), torch.zeros((T, N))
    term_buf, done_buf, valid_buf = np.zeros((T, N)), np.zeros((T, N)), np.zeros((T, N), bool)
    rms = RunningMeanStd(n_obs)
    raw, _ = envs.reset(seed=args.seed)
    rms.update(raw)
    resetting = np.zeros(N, bool)  # this step only resets (next-step autoreset): not a transition
    updates = max(args.total_timesteps // (T * N), 1)
    t0 = time.time()
    for update in range(updates):
        for group in optimiser.param_groups:
            group["lr"] = args.learning_rate * (1.0 - update / updates)
        for t in range(T):
            obs = rms.normalise(raw)
            with torch.no_grad():
                action, logp, _, value = agent.act(torch.as_tensor(obs))
            raw, reward, term, trunc, info = envs.step(np.clip(action.numpy(), -1.0, 1.0).astype(np.float32))
            rms.update(raw)
            obs_buf[t], act_buf[t], logp_buf[t], val_buf[t] = obs, action, logp, value
            rew_buf[t], term_buf[t], done_buf[t], valid_buf[t] = reward, term, term | trunc, ~resetting
            resetting = term | trunc
        with torch.no_grad():
            next_value = agent.value(torch.as_tensor(rms.normalise(raw)))
        adv = advantages(torch.as_tensor(rew_buf, dtype=torch.float32), val_buf, next_value, term_buf, done_buf,
                         valid_buf, args.gamma, args.gae_lambda)
        ret = adv + val_buf
        keep = torch.as_tensor(valid_buf.reshape(-1))
        b_obs = torch.as_tensor(obs_buf.reshape(T * N, n_obs))[keep]
        b_act, b_logp = act_buf.reshape(T * N, n_act)[keep], logp_buf.reshape(-1)[keep]
        b_adv, b_ret = adv.reshape(-1)[keep], ret.reshape(-1)[keep]
        n = b_obs.shape[0]
        for _ in range(args.update_epochs):
            order = torch.randperm(n)
            for start in range(0, n, args.minibatch_size):
                idx = order[start:start + args.minibatch_size]
                if idx.numel() < 2:
                    continue
                _, logp, entropy, value = agent.act(b_obs[idx], b_act[idx])
                ratio = (logp - b_logp[idx]).exp()
                a = b_adv[idx]
                a = (a - a.mean()) / (a.std() + 1e-8)
                policy_loss = torch.max(-a * ratio, -a * ratio.clamp(1 - args.clip_coef, 1 + args.clip_coef)).mean()
                value_loss = ((value - b_ret[idx]) ** 2).mean()
                loss = policy_loss + args.vf_coef * value_loss - args.ent_coef * entropy.mean()
                optimiser.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
                optimiser.step()
    envs.close()
    wall = time.time() - t0
    from acc_gym.evaluation.runner import evaluate

    summary = evaluate(Controller(agent, rms), args.env_id, episodes=args.eval_episodes, seed=args.eval_seed)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        torch.save(agent.state_dict(), out / "agent.pt")
        np.savez(out / "obs_rms.npz", mean=rms.mean, var=rms.var)
    return {"env_id": args.env_id, "seed": args.seed, "timesteps": updates * T * N, "train_wall_time_s": round(wall, 1),
            "eval_seed": args.eval_seed, "eval_episodes": args.eval_episodes,
            "mean_score": summary["mean_score"], "share_qualified": summary["share_qualified"],
            "collisions": summary["collisions"]}


def main(argv=None) -> int:
    print(json.dumps(train(parse(argv))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
