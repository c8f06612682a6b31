"""syndds learning environments for Python, with Gymnasium's API.

    import numpy as np, syndds
    env = syndds.make("double_integrator")
    obs, info = env.reset(seed=1)
    obs, reward, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))

    envs = syndds.make_vector("convoy_follow", copies=4, threads=2)
    obs, info = envs.reset(seed=1)            # obs: (4, n) floats, or a dict with "image"
    obs, rewards, terminated, truncated, info = envs.step(actions)   # actions: (4, m)

The environments are the C++ ones of common/learn (docs/learning.md): the same seed gives the
same episode, bit for bit, in C++ and in Python. Options are keyword arguments of make(), as
syndds_train's --env-option KEY=VALUE.
"""
import numpy as _np

from ._syndds import Env as _Env
from ._syndds import VectorEnv as _VectorEnv
from ._syndds import env_names

__all__ = ["Box", "Dict", "make", "make_vector", "env_names"]


class Box:
    """A box of numbers (Gymnasium's Box: low, high, shape, dtype, sample, contains)."""

    def __init__(self, low, high, dtype=_np.float32, names=None, explore=None):
        self.low = _np.asarray(low, dtype=dtype)
        self.high = _np.asarray(high, dtype=dtype)
        self.shape = self.low.shape
        self.dtype = _np.dtype(dtype)
        self.names = list(names or [])
        # Actions: the dimensions a learner should explore in; the others (a memory the
        # environment only hands back) are best acted on as the policy's mean.
        self.explore = list(explore) if explore is not None else [True] * self.low.size

    def sample(self, rng=None):
        rng = rng or _np.random.default_rng()
        if _np.issubdtype(self.dtype, _np.integer):
            return rng.integers(self.low, self.high, endpoint=True).astype(self.dtype)
        return rng.uniform(self.low, self.high).astype(self.dtype)

    def contains(self, x):
        x = _np.asarray(x)
        return x.shape == self.shape and bool(_np.all(x >= self.low) and _np.all(x <= self.high))

    def __repr__(self):
        return f"Box({self.low.tolist()}, {self.high.tolist()}, {self.shape}, {self.dtype})"


class Dict:
    """Named sub-spaces (an observation with a camera: "image" and "vector")."""

    def __init__(self, spaces):
        self.spaces = dict(spaces)

    def __getitem__(self, key):
        return self.spaces[key]

    def contains(self, x):
        return all(k in x and s.contains(x[k]) for k, s in self.spaces.items())

    def __repr__(self):
        return f"Dict({self.spaces})"


def _observation_space(d):
    vector = Box(d["vector"]["low"], d["vector"]["high"], names=d["vector"]["names"])
    if "image" not in d:
        return vector
    image = Box(_np.zeros(d["image"], _np.uint8), _np.full(d["image"], 255, _np.uint8), _np.uint8)
    return Dict({"image": image, "vector": vector})


class _Wrapped:
    def __init__(self, env):
        self._env = env
        self.observation_space = _observation_space(env.observation_space_dict)
        a = env.action_space_dict
        self.action_space = Box(a["low"], a["high"], names=a["names"], explore=a["explore"])

    def reset(self, seed=None, options=None):
        return self._env.reset(seed)

    def step(self, action):
        return self._env.step(action)

    def expert_action(self):
        """The environment's teacher for the current state (e.g. the classical convoy follower
        on a trail observation), for imitation; never part of the observation. Empty when
        the environment has none; a vector environment gives one row per copy."""
        return self._env.expert_action()

    def perception_target(self):
        """What a perception network is fitted to read from the current image alone (e.g. the
        obstacles' ranges across the convoy follower's camera view, each over 20 m, 1: none),
        from ground truth; never part of the observation. Empty when the environment has none;
        a vector environment gives one row per copy."""
        return self._env.perception_target()

    def close(self):
        pass


def make(name, **options):
    """One environment by name (env_names() lists them); options as keyword arguments."""
    return _Wrapped(_Env(name, {k: str(v) for k, v in options.items()}))


def make_vector(name, copies, threads=1, **options):
    """`copies` environments stepped together on `threads` threads, reset automatically."""
    env = _Wrapped(_VectorEnv(name, copies, threads, {k: str(v) for k, v in options.items()}))
    env.num_envs = copies
    return env
