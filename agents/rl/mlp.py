"""A trained PPO actor as a plain numpy function: inference without torch.

A PPO policy's deterministic action is its actor network's output (the mean of the
Gaussian), clipped to the action space: an MLP of a few small layers. :func:`export`
copies those weights out of a stable-baselines3 model into ``policy.npz`` next to
``model.zip``; :class:`NumpyActor` evaluates them with numpy. A run directory that holds
a ``policy.npz`` is then a controller for every install, including the core one without
torch and stable-baselines3 (the leaderboard's main job), and a step costs a few
microseconds instead of a torch call.

What is exported: the actor's hidden layers (``mlp_extractor.policy_net``: Linear layers
with Tanh or ReLU activations) and its output layer (``action_net``), plus the action
bounds. Observation normalisation and the residual law stay where they are
(``obs_rms.npz``, the manifest; :class:`acc_gym_agents.rl.policy.SB3Policy`). Only PPO's
unsquashed Gaussian policies are supported (SAC and TD3 squash with tanh and keep their
actor elsewhere): exporting anything else is an error, not an approximation.

The numpy forward pass runs in float32 like torch's; the two differ by rounding only
(about 1e-7 on an action, tested against the torch model). An observation's action is the
same to the bit whether it comes alone or in a batch (:func:`_layer`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acc_gym._io import atomic_write

POLICY_FILE = "policy.npz"
ACTIVATIONS = ("tanh", "relu")


def _layer(x: np.ndarray, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``x @ w.T + b`` with each row's sums in an order that does not depend on how many rows
    come with it: numpy's own einsum loop, not BLAS (whose kernels for one row and for many
    differ, so that on some CPUs an observation scored alone and the same observation in a
    batch gave actions 2e-7 apart, and a leaderboard score depended on its batch)."""
    return np.einsum("ij,kj->ik", x, w, optimize=False) + b


def _activate(name: str, x: np.ndarray) -> np.ndarray:
    return np.tanh(x) if name == "tanh" else np.maximum(x, np.float32(0.0))


@dataclass(frozen=True)
class NumpyActor:
    """``action = clip(W_n f(... f(W_1 obs + b_1) ...) + b_n, low, high)`` on normalised observations.

    ``weights[i]`` is ``(out, in)`` as in torch's Linear; ``activations[i]`` follows layer
    ``i`` (one fewer than the layers: the output layer is linear).
    """

    weights: tuple
    biases: tuple
    activations: tuple
    low: np.ndarray
    high: np.ndarray

    def __post_init__(self) -> None:
        if len(self.weights) != len(self.biases) or len(self.activations) != len(self.weights) - 1:
            raise ValueError(f"NumpyActor: {len(self.weights)} weight matrices, {len(self.biases)} bias vectors and "
                             f"{len(self.activations)} activations do not make an MLP")
        for name in self.activations:
            if name not in ACTIVATIONS:
                raise ValueError(f"NumpyActor: unknown activation {name!r}; use one of {ACTIVATIONS}")
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            fan_in = self.weights[i - 1].shape[0] if i else w.shape[1]
            if w.ndim != 2 or b.shape != (w.shape[0],) or w.shape[1] != fan_in:
                raise ValueError(f"NumpyActor: layer {i} has weights {w.shape} and bias {b.shape}")

    @property
    def obs_dim(self) -> int:
        return int(self.weights[0].shape[1])

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        """stable-baselines3's call shape: ``(action, None)``; one observation gives a ``(act_dim,)`` action."""
        if not deterministic:
            raise ValueError("a numpy-exported actor only gives the deterministic action; load the run with "
                             "backend='sb3' to sample")
        x = np.asarray(obs, dtype=np.float32)
        single = x.ndim == 1
        x = np.atleast_2d(x)
        if x.shape[1] != self.obs_dim:
            raise ValueError(f"observation of shape {np.shape(obs)}; this actor takes {self.obs_dim} values")
        for w, b, name in zip(self.weights[:-1], self.biases[:-1], self.activations):
            x = _activate(name, _layer(x, w, b))
        action = np.clip(_layer(x, self.weights[-1], self.biases[-1]), self.low, self.high)
        return (action[0] if single else action), None

    def save(self, path) -> Path:
        """Write the actor to ``path`` (``.npz``) atomically."""
        arrays = {f"w{i}": w for i, w in enumerate(self.weights)} | {f"b{i}": b for i, b in enumerate(self.biases)}
        arrays |= {"activations": np.array(self.activations, dtype=str), "low": self.low, "high": self.high}
        return atomic_write(path, lambda fh: np.savez(fh, **arrays))

    @classmethod
    def load(cls, path) -> NumpyActor:
        """Read an actor written by :meth:`save`; a damaged file is an error naming it."""
        try:
            with np.load(path, allow_pickle=False) as f:
                n = len([k for k in f.files if k.startswith("w")])
                return cls(weights=tuple(f[f"w{i}"].astype(np.float32) for i in range(n)),
                           biases=tuple(f[f"b{i}"].astype(np.float32) for i in range(n)),
                           activations=tuple(str(a) for a in f["activations"]),
                           low=f["low"].astype(np.float32), high=f["high"].astype(np.float32))
        except (OSError, KeyError, ValueError) as exc:
            raise ValueError(f"{path}: not a numpy actor file ({exc})") from None


def from_sb3(model) -> NumpyActor:
    """The actor of a stable-baselines3 PPO model (see the module docstring for what is supported)."""
    from torch import nn
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.torch_layers import FlattenExtractor

    policy = model.policy
    if not isinstance(policy, ActorCriticPolicy) or policy.squash_output or not hasattr(policy, "action_net"):
        raise ValueError(f"only PPO's Gaussian MLP policies export to numpy, not {type(policy).__name__}")
    if not isinstance(policy.pi_features_extractor, FlattenExtractor):
        raise ValueError("only policies on flat observations (FlattenExtractor) export to numpy")
    weights, biases, activations = [], [], []
    for layer in policy.mlp_extractor.policy_net:
        if isinstance(layer, nn.Linear):
            weights.append(layer.weight.detach().cpu().numpy().astype(np.float32))
            biases.append(layer.bias.detach().cpu().numpy().astype(np.float32))
        elif isinstance(layer, (nn.Tanh, nn.ReLU)):
            activations.append("tanh" if isinstance(layer, nn.Tanh) else "relu")
        else:
            raise ValueError(f"cannot export a {type(layer).__name__} layer to numpy")
    if len(activations) != len(weights):
        raise ValueError("the actor's hidden layers must each be a Linear layer followed by an activation")
    weights.append(policy.action_net.weight.detach().cpu().numpy().astype(np.float32))
    biases.append(policy.action_net.bias.detach().cpu().numpy().astype(np.float32))
    space = model.action_space
    return NumpyActor(tuple(weights), tuple(biases), tuple(activations),
                      np.asarray(space.low, np.float32), np.asarray(space.high, np.float32))


def export(run) -> Path:
    """Write ``policy.npz`` into a PPO run directory (``acc-gym train`` output) and return its path."""
    from acc_gym_agents.rl.policy import MODEL_FILE, read_manifest

    run = Path(run)
    algo = read_manifest(run)["algo"]
    if algo != "ppo":
        raise ValueError(f"{run}: only PPO runs export to numpy, this one is {algo!r}")
    import stable_baselines3 as sb3

    return from_sb3(sb3.PPO.load(str(run / MODEL_FILE), device="cpu")).save(run / POLICY_FILE)
