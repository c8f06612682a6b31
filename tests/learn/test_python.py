"""The Python binding (import syndds): Gymnasium's API over the C++ environments.

Run by ctest with PYTHONPATH=<build>/python and Debian's python3."""
import unittest

import numpy as np

import syndds


class SingleEnvironment(unittest.TestCase):
    def test_names(self):
        self.assertIn("double_integrator", syndds.env_names())

    def test_reset_and_step_follow_gymnasium(self):
        env = syndds.make("double_integrator")
        self.assertEqual(env.observation_space.shape, (2,))
        self.assertEqual(env.action_space.shape, (1,))
        self.assertEqual(env.action_space.names, ["force_n"])
        self.assertEqual(env.action_space.explore, [True])
        obs, info = env.reset(seed=3)
        self.assertIsInstance(obs, np.ndarray)
        self.assertEqual(obs.dtype, np.float32)
        self.assertEqual(info, {})
        self.assertTrue(env.observation_space.contains(obs))
        again, _ = env.reset(seed=3)
        np.testing.assert_array_equal(obs, again)
        result = env.step(np.array([1.0], np.float32))
        self.assertEqual(len(result), 5)
        nxt, reward, terminated, truncated, info = result
        self.assertIsInstance(reward, float)
        self.assertIs(terminated, False)
        self.assertIs(truncated, False)
        # x(t) = x0 + v0 t + t^2 / 2 for 1 N on 1 kg over 0.1 s (float32 observations).
        self.assertAlmostEqual(float(nxt[0]), float(obs[0]) + 0.1 * float(obs[1]) + 0.005, places=5)
        self.assertAlmostEqual(reward, -(float(obs[0]) ** 2 + 0.1 * float(obs[1]) ** 2 + 0.01), places=5)

    def test_episode_is_truncated_after_one_hundred_steps(self):
        env = syndds.make("double_integrator")
        env.reset(seed=1)
        ends = [env.step([0.0])[3] for _ in range(100)]
        self.assertEqual(ends.index(True), 99)

    def test_a_wrong_action_is_an_error_naming_it(self):
        env = syndds.make("double_integrator")
        env.reset(seed=1)
        with self.assertRaisesRegex(ValueError, "action"):
            env.step([0.0, 1.0])

    def test_an_unknown_environment_is_an_error_naming_it(self):
        with self.assertRaisesRegex(Exception, "no_such_env"):
            syndds.make("no_such_env")


class VectorEnvironment(unittest.TestCase):
    def run_copies(self, copies, threads, steps=150):
        envs = syndds.make_vector("double_integrator", copies=copies, threads=threads)
        obs, _ = envs.reset(seed=11)
        self.assertEqual(obs.shape, (copies, 2))
        trace = [obs[0].copy()]
        for k in range(steps):
            actions = np.full((copies, 1), 0.3 * np.sin(k), np.float32)
            obs, rewards, terminated, truncated, info = envs.step(actions)
            self.assertEqual(rewards.shape, (copies,))
            if truncated[0]:
                self.assertIsNotNone(info["final_observation"][0])
            trace.append(obs[0].copy())
        return np.array(trace)

    def test_copy_zero_does_not_depend_on_copies_or_threads(self):
        reference = self.run_copies(1, 1)
        np.testing.assert_array_equal(self.run_copies(4, 2), reference)

    def test_actions_of_the_wrong_shape_are_refused(self):
        envs = syndds.make_vector("double_integrator", copies=2)
        envs.reset(seed=1)
        with self.assertRaisesRegex(ValueError, r"actions: expected an array of shape \(2, 1\)"):
            envs.step(np.zeros((3, 1), np.float32))


class CameraFollower(unittest.TestCase):
    """The camera environment of the shipped camera policy: options by keyword, a Dict
    observation of the 45 x 80 x 3 image and the trail's 12 numbers."""

    def test_camera_environment_on_the_trail_observation(self):
        env = syndds.make("convoy_follow", camera=True, observation="trail", reward="track",
                          episodes="mixed", dynamics="full")
        obs, info = env.reset(seed=3)
        self.assertEqual(obs["image"].shape, (45, 80, 3))
        self.assertEqual(obs["image"].dtype, np.uint8)
        self.assertEqual(obs["vector"].shape, (12,))
        self.assertEqual(env.observation_space["vector"].names[0], "cross_track_m")
        obs, reward, terminated, truncated, info = env.step(np.array([0.0, 0.3], np.float32))
        self.assertIn("path_error_m", info)
        self.assertEqual(obs["image"].shape, (45, 80, 3))

    def test_the_memory_observation_has_an_action_not_to_explore(self):
        env = syndds.make("convoy_follow", observation="trail_ff_memory")
        self.assertEqual(env.action_space.names, ["steering", "throttle_brake", "memory"])
        self.assertEqual(env.action_space.explore, [True, True, False])
        obs, _ = env.reset(seed=3)
        self.assertEqual(obs[-1], 0.0)
        obs, *_ = env.step(np.array([0.0, 0.3, 0.25], np.float32))
        self.assertEqual(obs[-1], np.float32(0.25))

    def test_the_teacher_is_there_for_imitation(self):
        env = syndds.make("convoy_follow", observation="trail_ff")
        env.reset(seed=3)
        for _ in range(5):
            teacher = env.expert_action()
            self.assertEqual(teacher.shape, (2,))
            self.assertTrue(env.action_space.contains(teacher))
            env.step(teacher)
        self.assertEqual(syndds.make("double_integrator").expert_action().shape, (0,))
        envs = syndds.make_vector("convoy_follow", copies=2, observation="trail_ff")
        envs.reset(seed=1)
        self.assertEqual(envs.expert_action().shape, (2, 2))

    def test_the_perception_target_is_the_cameras_ranges(self):
        env = syndds.make("convoy_follow", observation="trail_ff", camera=True, episodes="courses")
        env.reset(seed=2000001)
        ranges = env.perception_target()
        self.assertEqual(ranges.shape, (16,))
        self.assertTrue(((ranges >= 0.0) & (ranges <= 1.0)).all())
        self.assertLess(ranges.min(), 1.0)  # a course has obstacles in view at its start
        self.assertEqual(syndds.make("convoy_follow").perception_target().shape, (0,))
        envs = syndds.make_vector("convoy_follow", copies=2, camera=True)
        envs.reset(seed=1)
        self.assertEqual(envs.perception_target().shape, (2, 16))

    def test_an_unknown_observation_is_an_error_naming_it(self):
        with self.assertRaisesRegex(ValueError, "option observation: 'radar' is not one of"):
            syndds.make("convoy_follow", observation="radar")


if __name__ == "__main__":
    unittest.main()
