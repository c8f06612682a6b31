#!/usr/bin/python3
"""Evaluates two follower policies on the convoy-follow environment through the Python binding:
a hand-written one (steer toward the leader, pedal by the gap) and random actions.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/evaluate_follower.py [EPISODES]

Observation (docs/learning.md): [leader north m, leader east m, compass heading rad (clockwise
from north), closing speed m/s]; action: [steering (+ left), throttle (+) / brake (-)].
"""
import math
import sys

import numpy as np

import syndds


def hand_written(obs):
    north, east, heading, closing = (float(v) for v in obs)
    bearing = math.atan2(east, north)  # clockwise from north, like the compass
    off = (bearing - heading + math.pi) % (2 * math.pi) - math.pi  # + : leader to the right
    gap = math.hypot(north, east)
    steering = max(-1.0, min(1.0, -2.0 * off))
    pedal = max(-1.0, min(1.0, 0.15 * (gap - 15.0) - 0.3 * closing))
    return np.array([steering, pedal], np.float32)


def evaluate(env, policy, episodes, rng):
    returns = []
    for seed in range(1, episodes + 1):
        obs, _ = env.reset(seed=seed)
        total, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, _ = env.step(policy(obs, rng))
            total += reward
            done = terminated or truncated
        returns.append(total)
    return returns


def main():
    episodes = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    env = syndds.make("convoy_follow", terrain="rigid")
    rng = np.random.default_rng(0)
    for name, policy in [("hand-written", lambda obs, _: hand_written(obs)),
                         ("random", lambda _, r: env.action_space.sample(r))]:
        returns = evaluate(env, policy, episodes, rng)
        print(f"{name:>12}: mean return {np.mean(returns):8.1f} over {episodes} episodes "
              f"({', '.join(f'{r:.1f}' for r in returns)})")


if __name__ == "__main__":
    main()
