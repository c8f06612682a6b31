// The convoy-follow environment: its 16 path variants, obstacles beside the path, the reward,
// episode ends, determinism through VectorEnv whatever the number of copies and threads, a
// hand-written follower beating do-nothing and random actions, and the camera variant's images.
#include <gtest/gtest.h>

#include <numeric>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

#include "core/yaml.hpp"
#include "learn/convoy_env.hpp"
#include "learn/vector_env.hpp"
#include "sensors/scene.hpp"

using namespace syndds;
using namespace syndds::learn;

namespace {

ConvoyEnvOptions test_options() {
  ConvoyEnvOptions o;
  o.config_dir = SYNDDS_TEST_CONFIG_DIR;
  return o;
}

// The hand-written follower: the baseline a learned policy has to beat.
std::vector<float> hand_policy(const Observation& o) { return convoy_heuristic_action(o); }

struct EpisodeResult {
  double total = 0.0;
  int steps = 0;
  bool terminated = false;
};

template <typename Policy>
EpisodeResult run_episode(Env& env, std::uint64_t seed, Policy&& policy, int max_steps) {
  EpisodeResult e;
  Observation o = env.reset(seed);
  for (; e.steps < max_steps; ) {
    const StepResult r = env.step(policy(o));
    ++e.steps;
    e.total += r.reward;
    o = r.observation;
    if (r.terminated || r.truncated) {
      e.terminated = r.terminated;
      break;
    }
  }
  return e;
}

}  // namespace

TEST(ConvoyEpisode, SixteenDistinctPathVariantsStayInTheArea) {
  std::vector<std::vector<Vec2>> paths;
  for (int v = 0; v < kConvoyPathVariants; ++v) {
    paths.push_back(convoy_path(v));
    for (const Vec2& p : paths.back()) {
      ASSERT_GE(p.x(), 10.0 - 1e-9);
      ASSERT_LE(p.x(), 80.0 + 1e-9);
      ASSERT_GE(p.y(), 10.0 - 1e-9);
      ASSERT_LE(p.y(), 80.0 + 1e-9);
    }
    ASSERT_GT(paths.back().size(), 100u);
  }
  // Distinct as driven: some point i lies more than 5 m from point i of every other variant
  // (or the lengths differ: S about 114 m, C about 174 m).
  for (int a = 0; a < kConvoyPathVariants; ++a) {
    for (int b = a + 1; b < kConvoyPathVariants; ++b) {
      const auto& pa = paths[static_cast<std::size_t>(a)];
      const auto& pb = paths[static_cast<std::size_t>(b)];
      double worst = 0.0;
      for (std::size_t i = 0; i < std::min(pa.size(), pb.size()); ++i) {
        worst = std::max(worst, (pa[i] - pb[i]).norm());
      }
      EXPECT_TRUE(pa.size() != pb.size() || worst > 5.0) << "variants " << a << " and " << b;
    }
  }
  // C shapes start and end on the same side (within 1 m along one axis), S shapes at
  // opposite corners.
  for (int v = 0; v < kConvoyPathVariants; ++v) {
    const auto& p = paths[static_cast<std::size_t>(v)];
    const Vec2 d = p.back() - p.front();
    if (PathVariant::from_index(v).c_shape) {
      EXPECT_LT(std::min(std::abs(d.x()), std::abs(d.y())), 1.0) << v;
    } else {
      EXPECT_NEAR(std::abs(d.x()), 70.0, 1e-6) << v;
      EXPECT_NEAR(std::abs(d.y()), 70.0, 1e-6) << v;
    }
  }
}

TEST(ConvoyEpisode, ObstaclesKeepThePathClearAndStartsAreOnThePath) {
  std::vector<int> variants_seen(kConvoyPathVariants, 0);
  for (std::uint64_t seed = 0; seed < 200; ++seed) {
    const ConvoyEpisode e = make_convoy_episode(seed);
    ++variants_seen[static_cast<std::size_t>(e.variant)];
    ASSERT_EQ(e.obstacles.size(), 8u);
    for (const auto& ob : e.obstacles) {
      const double to_path = distance_to_path(e.path, ob.centre);
      EXPECT_GE(to_path - ob.radius_m, 2.2) << "seed " << seed << " " << ob.id;
      EXPECT_GE(to_path, 4.0 - 1e-9);
      EXPECT_TRUE(ob.label == "rock" || ob.label == "tree" || ob.label == "bush");
      EXPECT_GE(ob.centre.x() - ob.radius_m, 0.0);
      EXPECT_LE(ob.centre.x() + ob.radius_m, kConvoyAreaM);
      EXPECT_GE(ob.centre.y() - ob.radius_m, 0.0);
      EXPECT_LE(ob.centre.y() + ob.radius_m, kConvoyAreaM);
    }
    EXPECT_LE(e.follower_arc_m, 0.5 * e.path_length_m);
    EXPECT_DOUBLE_EQ(e.leader_arc_m, e.follower_arc_m + 15.0);
    EXPECT_LT(distance_to_path(e.path, e.follower_start), 1e-9);
    EXPECT_LT(distance_to_path(e.path, e.leader_start), 1e-9);
  }
  // Every variant is drawn (200 draws of 16: each expected 12.5 times).
  for (int v = 0; v < kConvoyPathVariants; ++v) EXPECT_GT(variants_seen[static_cast<std::size_t>(v)], 0) << v;
  // The same seed, the same episode.
  const ConvoyEpisode a = make_convoy_episode(77), b = make_convoy_episode(77);
  EXPECT_EQ(convoy_scenario_yaml(a, {}), convoy_scenario_yaml(b, {}));
}

TEST(ConvoyReward, MaximalAtTheOptimalGapInsideTheHeadingWindow) {
  const ConvoyRewardParams p;
  EXPECT_DOUBLE_EQ(convoy_reward(p.optimal_gap_m, 0.0, p), 1.0);
  double previous = 1.0;
  for (double k = 0.5; k <= 30.0; k += 0.5) {
    const double nearer = convoy_reward(p.optimal_gap_m - std::min(k, p.optimal_gap_m), 0.0, p);
    const double farther = convoy_reward(p.optimal_gap_m + k, 0.0, p);
    EXPECT_LT(farther, previous);
    EXPECT_LT(nearer, 1.0);
    EXPECT_GT(farther, 0.0);
    previous = farther;
  }
  // Hyperbolic: one width away gives one half.
  EXPECT_DOUBLE_EQ(convoy_reward(p.optimal_gap_m + p.width_m, 0.3, p), 0.5);
  // Inside the window up to pi/4, outside it the small penalty, whatever the gap.
  EXPECT_DOUBLE_EQ(convoy_reward(p.optimal_gap_m, 0.78, p), 1.0);
  EXPECT_DOUBLE_EQ(convoy_reward(p.optimal_gap_m, -0.79, p), p.outside);
  EXPECT_LT(p.outside, convoy_reward(1000.0, 0.0, p));
}

TEST(ConvoyEnv, CollisionWithAnObstacleEndsTheEpisode) {
  // Obstacles on the path itself: the hand-written follower drives into one.
  ConvoyEnvOptions o = test_options();
  o.episode.obstacle_offset_min_m = 0.0;
  o.episode.obstacle_offset_max_m = 0.0;
  o.episode.clearance_m = -100.0;
  ConvoyEnv env(o);
  Observation obs = env.reset(5);
  StepResult r;
  int steps = 0;
  for (; steps < 500; ++steps) {
    r = env.step(hand_policy(obs));
    obs = r.observation;
    if (r.terminated || r.truncated) break;
  }
  EXPECT_TRUE(r.terminated);
  EXPECT_FALSE(r.truncated);
  EXPECT_EQ(r.info.at("collided"), 1.0);
  EXPECT_EQ(r.reward, o.reward.collision);
  EXPECT_THROW(env.step(hand_policy(obs)), std::logic_error);
}

TEST(ConvoyEnv, RunningIntoTheLeaderIsACollision) {
  // The hand-written follower's steering at full throttle: it catches up with the leader
  // (which ramps up at 0.47 m/s^2) and runs into it; the contact ends the episode.
  ConvoyEnvOptions o = test_options();
  ConvoyEnv env(o);
  Observation obs = env.reset(3);
  StepResult r;
  for (int k = 0; k < 400; ++k) {
    const std::vector<float> full_throttle = {hand_policy(obs)[0], 1.0f};
    r = env.step(full_throttle);
    obs = r.observation;
    if (r.terminated || r.truncated) break;
  }
  EXPECT_TRUE(r.terminated);
  EXPECT_EQ(r.info.at("collided"), 1.0);
  EXPECT_EQ(r.info.at("leader_contact"), 1.0);
  EXPECT_EQ(r.info.at("leader_lost"), 0.0);
  EXPECT_LT(r.info.at("distance_m"), 6.0);
  EXPECT_EQ(r.reward, o.reward.collision);
}

TEST(ConvoyEnv, LeaderLostEndsTheEpisode) {
  ConvoyEnv env(test_options());
  Observation obs = env.reset(11);
  EXPECT_EQ(obs.vector.size(), 4u);
  EXPECT_TRUE(obs.image.empty());
  const std::vector<float> brake = {0.0f, -1.0f};
  StepResult r;
  for (int k = 0; k < 400; ++k) {
    r = env.step(brake);
    if (r.terminated || r.truncated) break;
  }
  EXPECT_TRUE(r.terminated);
  EXPECT_EQ(r.info.at("leader_lost"), 1.0);
  EXPECT_GT(r.info.at("distance_m"), 40.0);
  EXPECT_EQ(r.reward, -10.0);
}

namespace {

// The first `steps` (observation, reward) of copy `copy` through a VectorEnv.
std::vector<std::vector<double>> vector_trace(int copies, int threads, int steps) {
  const ConvoyEnvOptions o = test_options();
  VectorEnv venv([&] { return make_convoy_env(o); }, copies, threads);
  std::vector<std::vector<double>> trace(static_cast<std::size_t>(copies));
  auto record = [&](int i, const Observation& ob, double reward) {
    auto& t = trace[static_cast<std::size_t>(i)];
    t.insert(t.end(), ob.vector.begin(), ob.vector.end());
    t.push_back(reward);
  };
  const auto first = venv.reset(2024);
  for (int i = 0; i < copies; ++i) record(i, first[static_cast<std::size_t>(i)], 0.0);
  for (int k = 0; k < steps; ++k) {
    std::vector<std::vector<float>> actions;
    for (int i = 0; i < copies; ++i) {
      actions.push_back({0.3f * std::sin(0.1f * static_cast<float>(k + i)),
                         k < 15 ? 0.8f : -0.2f});
    }
    const auto r = venv.step(actions);
    for (int i = 0; i < copies; ++i) {
      record(i, r.results[static_cast<std::size_t>(i)].observation,
             r.results[static_cast<std::size_t>(i)].reward);
    }
  }
  return trace;
}

}  // namespace

TEST(ConvoyEnv, SameSeedSameEpisodesWhateverCopiesAndThreads) {
  const int steps = 25;
  const auto one = vector_trace(1, 1, steps);
  const auto four = vector_trace(4, 2, steps);
  const auto eight = vector_trace(8, 2, steps);
  const auto eight_one_thread = vector_trace(8, 1, steps);
  ASSERT_EQ(one[0].size(), static_cast<std::size_t>(5 * (steps + 1)));
  EXPECT_EQ(one[0], four[0]);  // bit for bit
  EXPECT_EQ(one[0], eight[0]);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(four[i], eight[i]) << "copy " << i;
  EXPECT_EQ(eight, eight_one_thread);
  // The copies are different episodes.
  EXPECT_NE(eight[0], eight[1]);
}

TEST(ConvoyEnv, HandWrittenFollowerBeatsDoingNothingAndRandomActions) {
  ConvoyEnv env(test_options());
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  double hand = 0.0, nothing = 0.0, random = 0.0;
  int hand_terminated = 0;
  const std::vector<float> zero = {0.0f, 0.0f};
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    const EpisodeResult h = run_episode(env, seed, hand_policy, 500);
    hand += h.total;
    hand_terminated += h.terminated ? 1 : 0;
    nothing += run_episode(env, seed, [&](const Observation&) { return zero; }, 500).total;
    random += run_episode(env, seed, [&](const Observation&) {
      return std::vector<float>{u(rng), u(rng)};
    }, 500).total;
  }
  std::printf("returns over 3 episodes: hand %.1f, nothing %.1f, random %.1f\n", hand, nothing,
              random);
  EXPECT_EQ(hand_terminated, 0);
  EXPECT_GT(hand, 2.0 * std::max(nothing, random));
  EXPECT_GT(hand - std::max(nothing, random), 100.0);
}

TEST(ConvoyEnv, CameraVariantGivesImagesThatChangeWhenTheLeaderMoves) {
  ConvoyEnvOptions o = test_options();
  o.camera = true;
  ConvoyEnv env(o);
  EXPECT_EQ(env.observation_space().image->bytes(), 80u * 45u * 3u);
  const Observation first = env.reset(3);
  ASSERT_EQ(first.image.size(), 80u * 45u * 3u);
  // The follower stands braked; the leader drives off in view (6 s: 2.8 m/s, 8.5 m on).
  const std::vector<float> brake = {0.0f, -1.0f};
  Observation later;
  for (int k = 0; k < 60; ++k) later = env.step(brake).observation;
  ASSERT_EQ(later.image.size(), first.image.size());
  int changed = 0;
  for (std::size_t i = 0; i < first.image.size(); ++i) {
    changed += std::abs(int(first.image[i]) - int(later.image[i])) > 10 ? 1 : 0;
  }
  EXPECT_GT(changed, 100);
  // Not every pixel: the scene around stands still.
  EXPECT_LT(changed, static_cast<int>(first.image.size()) / 2);
  std::printf("bytes changed by more than 10 levels: %d of %zu\n", changed, first.image.size());
}

TEST(ConvoyEnv, FullDynamicsOnSoftSoilFollows) {
  // The test terrains: full dynamics on the coarse soft-soil patch, the hand-written follower
  // for 8 s (the leader ramps to 3.8 m/s).
  ConvoyEnvOptions o = test_options();
  o.dynamics = ConvoyDynamics::full;
  o.terrain = ConvoyTerrain::scm_soft;
  ConvoyEnv env(o);
  Observation obs = env.reset(4);
  StepResult r;
  double max_speed = 0.0;
  for (int k = 0; k < 80; ++k) {
    r = env.step(hand_policy(obs));
    obs = r.observation;
    max_speed = std::max(max_speed, r.info.at("speed_mps"));
    ASSERT_FALSE(r.terminated || r.truncated) << "step " << k;
  }
  std::printf("full / scm_soft: distance %.2f m, speed %.2f m/s (max %.2f)\n",
              r.info.at("distance_m"), r.info.at("speed_mps"), max_speed);
  EXPECT_GT(max_speed, 1.5);
  EXPECT_GT(r.reward, 0.3);
  EXPECT_EQ(env.follower_state().wheels.size(), 4u);
  std::printf("gear %d, engine %.0f rpm, z %.3f m\n", env.follower_state().gear,
              env.follower_state().engine_speed_rpm, env.follower_state().pose.position.z());
}

// Course episodes: the study's generator on training seeds (never the study's own), the path
// planned 2 m clear of every obstacle, both vehicles on it 15 m apart; `mixed` alternates paper
// (even seeds) and course (odd seeds) episodes.
TEST(ConvoyEpisode, CourseEpisodesUseTheStudysGeneratorOnTrainingSeeds) {
  ConvoyEpisodeOptions o;
  o.kind = ConvoyEpisodeKind::courses;
  for (std::uint64_t seed : {3u, 4u, 515u}) {
    const ConvoyEpisode e = make_convoy_episode(seed, o);
    EXPECT_EQ(e.variant, -1);
    EXPECT_EQ(e.course_seed, kTrainingCourseSeed + seed % kTrainingCourses);
    EXPECT_GT(e.obstacles.size(), 10u);
    EXPECT_GT(e.path_length_m, 120.0);
    for (const auto& ob : e.obstacles) {
      // The planner keeps 2 m from the circles; the path is resampled at 1 m (chords of a
      // smoothed polyline: a few centimetres).
      EXPECT_GE(distance_to_path(e.path, ob.centre) - ob.radius_m, 1.9) << "seed " << seed << " " << ob.id;
    }
    EXPECT_LE(e.follower_arc_m, 0.6 * e.path_length_m);
    EXPECT_DOUBLE_EQ(e.leader_arc_m, e.follower_arc_m + 15.0);
    EXPECT_LT(distance_to_path(e.path, e.follower_start), 1e-9);
    EXPECT_LT(distance_to_path(e.path, e.leader_start), 1e-9);
  }
  // Seed 515 and seed 3 share a course (515 mod 512 = 3), not their starts.
  EXPECT_EQ(make_convoy_episode(3, o).path, make_convoy_episode(515, o).path);
  EXPECT_NE(make_convoy_episode(3, o).follower_arc_m, make_convoy_episode(515, o).follower_arc_m);
  o.kind = ConvoyEpisodeKind::mixed;
  EXPECT_GE(make_convoy_episode(10, o).variant, 0);
  EXPECT_EQ(make_convoy_episode(11, o).variant, -1);
  EXPECT_EQ(make_convoy_episode(10, o).path, make_convoy_episode(10).path);
}

// An option drawn from a stream of its own leaves the episode's other draws as they were:
// the planned path, both starts, the obstacles.
static void expect_same_draws(const ConvoyEpisode& a, const ConvoyEpisode& b) {
  EXPECT_EQ(b.path, a.path);
  EXPECT_EQ(b.leader_start, a.leader_start);
  EXPECT_EQ(b.follower_start, a.follower_start);
  ASSERT_EQ(b.obstacles.size(), a.obstacles.size());
  for (std::size_t i = 0; i < a.obstacles.size(); ++i) {
    EXPECT_EQ(b.obstacles[i].centre, a.obstacles[i].centre);
  }
}

// The wandering leader: every other draw of the episode unchanged, the planned path (the
// reward's reference) unchanged, the leader's path starting where it did and staying within
// the drawn amplitude of the planned one, on both kinds of episode; some amplitudes large.
TEST(ConvoyEpisode, AWobblingLeaderWandersAroundThePlannedPath) {
  double largest = 0.0;
  for (const ConvoyEpisodeKind kind : {ConvoyEpisodeKind::paper, ConvoyEpisodeKind::courses}) {
    ConvoyEpisodeOptions plain;
    plain.kind = kind;
    ConvoyEpisodeOptions wobbly = plain;
    wobbly.leader_wobble_m = 0.5;
    for (std::uint64_t seed = 1; seed <= 12; ++seed) {
      SCOPED_TRACE("seed " + std::to_string(seed));
      const ConvoyEpisode a = make_convoy_episode(seed, plain);
      const ConvoyEpisode b = make_convoy_episode(seed, wobbly);
      EXPECT_EQ(a.leader_wobble_m, 0.0);
      expect_same_draws(a, b);
      EXPECT_EQ(b.leader_path.front(), a.leader_path.front());
      EXPECT_LE(b.leader_wobble_m, 0.5);
      double farthest = 0.0;
      for (const Vec2& p : b.leader_path) farthest = std::max(farthest, distance_to_path(a.path, p));
      EXPECT_LE(farthest, b.leader_wobble_m + 1e-6);
      EXPECT_GE(farthest, 0.5 * b.leader_wobble_m);
      largest = std::max(largest, b.leader_wobble_m);
    }
  }
  EXPECT_GT(largest, 0.25);
}

// Chained episodes: about the asked fraction has a head gap_m ahead of the leader on the
// planned path, every other draw is unchanged, and the scenario makes the leader a classical
// follower of the head (which drives the path from its start).
TEST(ConvoyEpisode, AChainedEpisodeHasTheLeaderFollowAHead) {
  int chained = 0, episodes = 0;
  for (const ConvoyEpisodeKind kind : {ConvoyEpisodeKind::paper, ConvoyEpisodeKind::courses}) {
    ConvoyEpisodeOptions plain;
    plain.kind = kind;
    ConvoyEpisodeOptions chain = plain;
    chain.chain_fraction = 0.5;
    for (std::uint64_t seed = 1; seed <= 20; ++seed) {
      SCOPED_TRACE("seed " + std::to_string(seed));
      const ConvoyEpisode a = make_convoy_episode(seed, plain);
      const ConvoyEpisode b = make_convoy_episode(seed, chain);
      EXPECT_FALSE(a.chained);
      expect_same_draws(a, b);
      ++episodes;
      if (!b.chained) continue;
      ++chained;
      EXPECT_DOUBLE_EQ(b.head_arc_m, b.leader_arc_m + plain.gap_m);
      EXPECT_LE(b.head_arc_m + 20.0, b.path_length_m);
      EXPECT_LT(distance_to_path(b.path, b.head_start), 1e-9);
      EXPECT_EQ(b.head_path.front(), b.head_start);
      const std::string yaml = convoy_scenario_yaml(b, ConvoyScenarioOptions{});
      const auto s = scenario::parse_scenario(YamlNode::load_string(yaml, "chained.yaml"), yaml, {},
                                              SYNDDS_TEST_CONFIG_DIR);
      ASSERT_NE(s.find_vehicle(kConvoyHeadId), nullptr);
      EXPECT_EQ(s.find_vehicle(kConvoyHeadId)->controller.type, "path_follower");
      EXPECT_EQ(s.find_vehicle(kConvoyLeaderId)->controller.type, "follower");
    }
  }
  EXPECT_GT(chained, episodes / 4);
  EXPECT_LT(chained, 3 * episodes / 4);
}

// The classical follower's commands drive a chained episode behind a leader that follows the
// head: no collision, the leader not lost, on the path, and the episode ends when the head
// and the leader have stopped at the path's end.
TEST(ConvoyEnv, AChainedEpisodeRunsToTheEnd) {
  ConvoyEnvOptions o = test_options();
  o.observation = ConvoyObservationKind::trail;
  o.reward_kind = ConvoyRewardKind::track;
  o.episode.chain_fraction = 1.0;
  o.max_steps = 2000;
  ConvoyEnv env(o);
  env.reset(4);
  ASSERT_TRUE(env.episode().chained);
  double error_sum = 0.0;
  int steps = 0;
  StepResult r;
  for (; steps < 2000; ++steps) {
    r = env.step(env.expert_action());
    ASSERT_FALSE(r.terminated) << "collided " << r.info.at("collided") << ", lost "
                               << r.info.at("leader_lost") << " at step " << steps;
    error_sum += r.info.at("path_error_m");
    if (r.truncated) break;
  }
  EXPECT_EQ(r.info.at("leader_done"), 1.0) << "after " << steps << " steps";
  // Not before the head can have driven the rest of its path at the speed cap.
  const double head_drive_s =
      (env.episode().path_length_m - env.episode().head_arc_m) / o.target_speed_mps;
  EXPECT_GT(steps * 0.1, head_drive_s);
  EXPECT_LT(error_sum / steps, 0.4);
}

// The track reward: the gap term times 1 / (1 + e / 0.5 m): 1 at the optimal gap on the path,
// one half 0.5 m off it or a gap width away, a quarter both; no view window.
TEST(ConvoyReward, TrackRewardPaysForDrivingWhereTheLeaderDrove) {
  const ConvoyRewardParams p;
  EXPECT_DOUBLE_EQ(convoy_track_reward(p.optimal_gap_m, 0.0, p), 1.0);
  EXPECT_DOUBLE_EQ(convoy_track_reward(p.optimal_gap_m, 0.5, p), 0.5);
  EXPECT_DOUBLE_EQ(convoy_track_reward(p.optimal_gap_m, -0.5, p), 0.5);
  EXPECT_DOUBLE_EQ(convoy_track_reward(p.optimal_gap_m + p.width_m, 0.0, p), 0.5);
  EXPECT_DOUBLE_EQ(convoy_track_reward(p.optimal_gap_m + p.width_m, 0.5, p), 0.25);
  EXPECT_LT(convoy_track_reward(p.optimal_gap_m, 1.0, p), convoy_track_reward(p.optimal_gap_m, 0.9, p));
}

// The trail observation: 12 named numbers from the classical follower's estimator; at the
// start (both vehicles on a straight stretch of the path, 15 m apart, the follower braked) the
// follower is on the trail, heading along it, the leader about 15 m ahead and 15 m less the two
// half lengths (4.7 m) away bumper to bumper along the trail.
TEST(ConvoyEnv, TrailObservationIsTheEstimatorsViewOfTheTrail) {
  ConvoyEnvOptions o = test_options();
  o.observation = ConvoyObservationKind::trail;
  ConvoyEnv env(o);
  const Box space = env.observation_space().vector;
  ASSERT_EQ(space.size(), 12u);
  EXPECT_EQ(space.names.front(), "cross_track_m");
  EXPECT_EQ(space.names.back(), "leader_left_m");
  // Seed 2: an S path, the follower starting on its straight lead-in (checked below).
  const Observation first = env.reset(2);
  ASSERT_EQ(first.vector.size(), 12u);
  ASSERT_LT(std::abs(wrap_angle(env.episode().leader_yaw_rad - env.episode().follower_yaw_rad)), 0.05)
      << "pick a seed whose start is on a straight";
  EXPECT_LT(std::abs(first.vector[0]), 1.0);         // cross-track (GPS noise 0.5 m)
  EXPECT_GT(first.vector[2], 0.98);                  // cos of the heading error
  EXPECT_NEAR(first.vector[10], 15.0, 1.5);          // leader forward
  EXPECT_LT(std::abs(first.vector[11]), 1.5);        // leader left
  EXPECT_NEAR(first.vector[9], 15.0 - 4.7, 1.5);     // gap along the trail
  // Driving behind the leader with the hand-written follower's pedal: the trail grows, speeds
  // show, and the episode is the same with the same seed.
  Observation obs = first;
  StepResult r;
  for (int k = 0; k < 60; ++k) {
    r = env.step(std::vector<float>{0.0f, 0.3f});
    obs = r.observation;
    if (r.terminated || r.truncated) break;
  }
  EXPECT_GT(obs.vector[6], 1.0);   // own speed
  EXPECT_GT(obs.vector[7], 1.0);   // the leader's
  EXPECT_GT(r.info.at("path_error_m"), -1.0);
  ConvoyEnv again(o);
  EXPECT_EQ(again.reset(2).vector, first.vector);
}

namespace {

// An environment observing `kind` and, beside it, one observing trail on the same options.
struct BesideTrail {
  explicit BesideTrail(ConvoyObservationKind kind)
      : trail(with_observation(ConvoyObservationKind::trail)), env(with_observation(kind)) {}
  static ConvoyEnvOptions with_observation(ConvoyObservationKind kind) {
    ConvoyEnvOptions o = test_options();
    o.observation = kind;
    return o;
  }
  ConvoyEnv trail;
  ConvoyEnv env;
};

// The first 12 numbers of an observation: trail's.
std::vector<float> trail_part(const std::vector<float>& v) { return {v.begin(), v.begin() + 12}; }

}  // namespace

// trail_action: trail's 12 numbers, then the action applied since the previous step, clamped
// as the vehicle gets it (NaN as 0); before the first step the brake the follower holds.
TEST(ConvoyEnv, TrailActionObservationEndsWithThePreviousAction) {
  BesideTrail envs(ConvoyObservationKind::trail_action);
  ConvoyEnv& trail = envs.trail;
  ConvoyEnv& env = envs.env;
  const Box space = env.observation_space().vector;
  ASSERT_EQ(space.size(), 14u);
  EXPECT_EQ(space.names[11], "leader_left_m");
  EXPECT_EQ(space.names[12], "previous_steering");
  EXPECT_EQ(space.names[13], "previous_throttle_brake");
  const Observation first = env.reset(2);
  const Observation first_trail = trail.reset(2);
  ASSERT_EQ(first.vector.size(), 14u);
  EXPECT_EQ(trail_part(first.vector), first_trail.vector);
  EXPECT_EQ(first.vector[12], 0.0f);
  EXPECT_EQ(first.vector[13], -1.0f);
  const std::vector<std::vector<float>> actions = {
      {0.25f, 0.5f}, {-3.0f, 2.0f}, {std::nanf(""), -0.75f}};
  const std::vector<std::vector<float>> applied = {{0.25f, 0.5f}, {-1.0f, 1.0f}, {0.0f, -0.75f}};
  for (std::size_t k = 0; k < actions.size(); ++k) {
    const StepResult r = env.step(actions[k]);
    const StepResult rt = trail.step(actions[k]);
    ASSERT_EQ(r.observation.vector.size(), 14u);
    EXPECT_EQ(trail_part(r.observation.vector), rt.observation.vector) << "step " << k;
    EXPECT_EQ(r.observation.vector[12], applied[k][0]) << "step " << k;
    EXPECT_EQ(r.observation.vector[13], applied[k][1]) << "step " << k;
  }
}

// trail_ff: trail's numbers and the estimator's feed-forward steering, which is most of what the
// classical follower steers (the rest is feedback on the distance and heading to the trail):
// driving with the expert, the two go together.
TEST(ConvoyEnv, TrailFeedForwardObservationEndsWithTheFeedForwardSteering) {
  BesideTrail envs(ConvoyObservationKind::trail_ff);
  ConvoyEnv& trail = envs.trail;
  ConvoyEnv& env = envs.env;
  const Box space = env.observation_space().vector;
  ASSERT_EQ(space.size(), 13u);
  EXPECT_EQ(space.names[12], "feedforward_steering");
  Observation obs = env.reset(2);
  ASSERT_EQ(trail_part(obs.vector), trail.reset(2).vector);
  std::vector<double> ff, steer;
  for (int k = 0; k < 200; ++k) {
    const std::vector<float> expert = env.expert_action();
    ff.push_back(obs.vector[12]);
    steer.push_back(expert[0]);
    EXPECT_GE(obs.vector[12], -1.0f);
    EXPECT_LE(obs.vector[12], 1.0f);
    const StepResult r = env.step(expert);
    const StepResult rt = trail.step(expert);
    ASSERT_EQ(trail_part(r.observation.vector), rt.observation.vector) << "step " << k;
    obs = r.observation;
    if (r.terminated || r.truncated) break;
  }
  ASSERT_GT(ff.size(), 100u);
  const auto n = static_cast<double>(ff.size());
  const double mf = std::accumulate(ff.begin(), ff.end(), 0.0) / n;
  const double ms = std::accumulate(steer.begin(), steer.end(), 0.0) / n;
  double sff = 0.0, sss = 0.0, sfs = 0.0;
  for (std::size_t i = 0; i < ff.size(); ++i) {
    sff += (ff[i] - mf) * (ff[i] - mf);
    sss += (steer[i] - ms) * (steer[i] - ms);
    sfs += (ff[i] - mf) * (steer[i] - ms);
  }
  const double correlation = sfs / std::sqrt(sff * sss);
  std::printf("feed-forward against the expert's steering: correlation %.3f over %zu steps\n",
              correlation, ff.size());
  EXPECT_GT(correlation, 0.4);  // 0.52 here
}

// The expert a trainer may imitate: the classical follower's command from the observation's
// own estimator. Driving the episode with it at the policy's 10 Hz, the follower stays near
// the leader's path and behind it, with no collision; the paper observation has no expert.
TEST(ConvoyEnv, ExpertActionIsTheClassicalFollowersCommand) {
  ConvoyEnvOptions o = test_options();
  ConvoyEnv paper(o);
  paper.reset(2);
  EXPECT_TRUE(paper.expert_action().empty());
  o.observation = ConvoyObservationKind::trail;
  o.reward_kind = ConvoyRewardKind::track;
  for (const std::uint64_t seed : {2u, 5u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    ConvoyEnv env(o);
    env.reset(seed);
    double error_sum = 0.0, distance_min = 1e9;
    int steps = 0;
    for (; steps < 400; ++steps) {
      const std::vector<float> a = env.expert_action();
      ASSERT_EQ(a.size(), 2u);
      EXPECT_LE(std::abs(a[0]), 1.0f);
      EXPECT_LE(std::abs(a[1]), 1.0f);
      const StepResult r = env.step(a);
      ASSERT_FALSE(r.terminated) << "collided " << r.info.at("collided") << ", lost "
                                 << r.info.at("leader_lost") << " at step " << steps;
      error_sum += r.info.at("path_error_m");
      distance_min = std::min(distance_min, r.info.at("distance_m"));
      if (r.truncated) break;
    }
    EXPECT_GT(steps, 150);
    EXPECT_LT(error_sum / steps, 0.4);
    EXPECT_GT(distance_min, 6.0);
  }
}

// The teacher's map (option teacher_keep_clear): the expert steers wider of the episode's
// obstacles, and nothing the policy sees or is paid changes. Two
// environments on the same course episode, both driven by the expert with the map: the
// observations and rewards are the same bit for bit, while the expert without the map would
// command otherwise; and driven by its own expert, the follower passes the obstacles farther
// from their edges with the map than without.
TEST(ConvoyEnv, TheTeachersMapChangesTheExpertNotTheObservation) {
  ConvoyEnvOptions o = test_options();
  o.observation = ConvoyObservationKind::trail_ff;
  o.reward_kind = ConvoyRewardKind::track;
  o.episode.kind = ConvoyEpisodeKind::courses;
  o.max_steps = 300;
  ConvoyEnvOptions mapped = o;
  mapped.teacher_keep_clear_m = 2.5;
  const std::uint64_t seed = 3;
  // The nearest any obstacle's edge comes to the follower's reference point.
  const auto nearest_edge = [](const ConvoyEnv& env) {
    const Vec2 p(env.follower_state().pose.position.x(), env.follower_state().pose.position.y());
    double d = 1e9;
    for (const auto& ob : env.episode().obstacles) d = std::min(d, (p - ob.centre).norm() - ob.radius_m);
    return d;
  };
  {
    ConvoyEnv plain(o), with_map(mapped);
    Observation a = plain.reset(seed), b = with_map.reset(seed);
    int differ = 0;
    for (int k = 0; k < o.max_steps; ++k) {
      ASSERT_EQ(a.vector, b.vector) << "step " << k;
      const std::vector<float> teacher = with_map.expert_action();
      if (teacher != plain.expert_action()) ++differ;
      const StepResult ra = plain.step(teacher), rb = with_map.step(teacher);
      ASSERT_EQ(ra.reward, rb.reward) << "step " << k;
      a = ra.observation;
      b = rb.observation;
      if (ra.terminated || ra.truncated) break;
    }
    EXPECT_GT(differ, 10);
  }
  double nearest[2] = {1e9, 1e9};
  for (int m = 0; m < 2; ++m) {
    ConvoyEnv env(m == 0 ? o : mapped);
    env.reset(seed);
    for (int k = 0; k < o.max_steps; ++k) {
      const StepResult r = env.step(env.expert_action());
      nearest[m] = std::min(nearest[m], nearest_edge(env));
      if (r.terminated || r.truncated) break;
    }
  }
  std::printf("nearest obstacle edge: %.2f m without the map, %.2f m with it\n", nearest[0],
              nearest[1]);
  EXPECT_GT(nearest[1], nearest[0] + 0.3);
}

// teacher_steering_limit: the expert's steering is the classical command without the lock,
// so that a regression onto it reaches the lock where the teacher holds it. Two environments
// on the same episode, one with the limit 1.5, both driven by the plain expert except for a
// second of full opposite lock that throws the follower off the trail: the observations and
// rewards are the same bit for bit; the pedal is the same; where the plain expert steers
// inside the lock the other's steering is equal to it; where the plain expert is at the lock
// the other's has its sign and reaches beyond it, never beyond the limit.
TEST(ConvoyEnv, TheTeachersSteeringBeyondTheLockIsTheCommandWithoutIt) {
  ConvoyEnvOptions o = test_options();
  o.observation = ConvoyObservationKind::trail_ff;
  o.reward_kind = ConvoyRewardKind::track;
  o.max_steps = 200;
  ConvoyEnvOptions beyond_lock = o;
  beyond_lock.teacher_steering_limit = 1.5;
  ConvoyEnv plain(o), beyond(beyond_lock);
  Observation a = plain.reset(4), b = beyond.reset(4);
  int inside = 0, at_lock = 0, beyond_it = 0;
  for (int k = 0; k < o.max_steps; ++k) {
    ASSERT_EQ(a.vector, b.vector) << "step " << k;
    const std::vector<float> p = plain.expert_action(), q = beyond.expert_action();
    ASSERT_EQ(p.size(), 2u);
    ASSERT_EQ(q.size(), 2u);
    EXPECT_EQ(p[1], q[1]) << "step " << k;
    EXPECT_LE(std::abs(q[0]), 1.5f) << "step " << k;
    if (std::abs(p[0]) < 1.0f) {
      EXPECT_EQ(p[0], q[0]) << "step " << k;
      ++inside;
    } else {
      EXPECT_GE(p[0] * q[0], 1.0f) << "step " << k << ": " << p[0] << " against " << q[0];
      ++at_lock;
      if (std::abs(q[0]) > 1.0f) ++beyond_it;
    }
    std::vector<float> act = p;
    if (k >= 60 && k < 70) act[0] = -1.0f;  // a second at the opposite lock
    const StepResult ra = plain.step(act), rb = beyond.step(act);
    ASSERT_EQ(ra.reward, rb.reward) << "step " << k;
    a = ra.observation;
    b = rb.observation;
    if (ra.terminated || ra.truncated) break;
  }
  std::printf("steps inside the lock %d, at it %d, of which beyond it %d\n", inside, at_lock,
              beyond_it);
  EXPECT_GT(inside, 100);
  EXPECT_GE(beyond_it, 3);
}

// trail_ff_memory: a third action, the memory, which comes back clamped in the next
// observation's last number and moves nothing else: two environments driven with the same
// steering and pedal but different memories see the same other numbers and earn the same
// rewards. The teacher's memory is its map's shift over the largest shift (0 without a map),
// and a trainer does not explore in it.
TEST(ConvoyEnv, TheMemoryComesBackInTheNextObservationAndMovesNothing) {
  ConvoyEnvOptions o = test_options();
  o.observation = ConvoyObservationKind::trail_ff_memory;
  o.reward_kind = ConvoyRewardKind::track;
  o.episode.kind = ConvoyEpisodeKind::courses;
  o.teacher_keep_clear_m = 2.5;
  o.max_steps = 200;
  ConvoyEnv a(o), b(o);
  const Box actions = a.action_space();
  ASSERT_EQ(actions.size(), 3u);
  EXPECT_EQ(actions.names[2], "memory");
  EXPECT_TRUE(actions.explored(0));
  EXPECT_TRUE(actions.explored(1));
  EXPECT_FALSE(actions.explored(2));
  const Box space = a.observation_space().vector;
  ASSERT_EQ(space.size(), 14u);
  EXPECT_EQ(space.names[12], "feedforward_steering");
  EXPECT_EQ(space.names[13], "memory");
  Observation oa = a.reset(3), ob = b.reset(3);
  EXPECT_EQ(oa.vector[13], 0.0f);
  const std::vector<float> other = {0.5f, -4.0f, std::nanf("")};  // b's memories, in turn
  const std::vector<float> other_applied = {0.5f, -1.0f, 0.0f};
  int shifted = 0;
  for (int k = 0; k < o.max_steps; ++k) {
    const std::vector<float> teacher = a.expert_action();
    ASSERT_EQ(teacher.size(), 3u);
    EXPECT_LE(std::abs(teacher[2]), 1.0f);
    if (teacher[2] != 0.0f) ++shifted;
    std::vector<float> for_b = teacher;
    for_b[2] = other[static_cast<std::size_t>(k) % other.size()];
    const StepResult ra = a.step(teacher), rb = b.step(for_b);
    ASSERT_EQ(std::vector<float>(ra.observation.vector.begin(), ra.observation.vector.begin() + 13),
              std::vector<float>(rb.observation.vector.begin(), rb.observation.vector.begin() + 13))
        << "step " << k;
    ASSERT_EQ(ra.reward, rb.reward) << "step " << k;
    EXPECT_EQ(ra.observation.vector[13], teacher[2]) << "step " << k;
    EXPECT_EQ(rb.observation.vector[13], other_applied[static_cast<std::size_t>(k) % other.size()])
        << "step " << k;
    if (ra.terminated || ra.truncated) break;
  }
  EXPECT_GT(shifted, 10);  // seed 3's course passes obstacles within the clearance
  // Without a map the teacher remembers nothing.
  o.teacher_keep_clear_m = 0.0;
  ConvoyEnv plain(o);
  plain.reset(3);
  for (int k = 0; k < 50; ++k) {
    const std::vector<float> teacher = plain.expert_action();
    ASSERT_EQ(teacher.size(), 3u);
    EXPECT_EQ(teacher[2], 0.0f);
    plain.step(teacher);
  }
  // A step with the wrong number of actions names both.
  EXPECT_THROW(
      {
        try {
          plain.step(std::vector<float>{0.0f, 0.0f});
        } catch (const std::invalid_argument& e) {
          EXPECT_NE(std::string(e.what()).find("expected 3 action values, got 2"),
                    std::string::npos);
          throw;
        }
      },
      std::invalid_argument);
}

// Random ground colours: each episode's ground has a colour of its own between the rigid
// ground's grey and the soil's brown, drawn from the seed; the image changes (the bottom rows
// look at the ground), the vector observation, the reward and the episode's end do not.
TEST(ConvoyEnv, ARandomGroundColourChangesTheImageNotThePhysics) {
  const auto grey = sensors::terrain_look("rigid").colour;
  const auto brown = sensors::terrain_look("silt").colour;
  int brownish = 0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const auto c = convoy_ground_colour(seed);
    EXPECT_EQ(c, convoy_ground_colour(seed));
    for (double v : c) {
      EXPECT_GE(v, 0.0);
      EXPECT_LE(v, 1.0);
    }
    // Between the two in hue: red's share of the three between grey's and brown's.
    const double b = c[0] + c[1] + c[2];
    EXPECT_GE(c[0] / b, grey.r / (grey.r + grey.g + grey.b) - 1e-9);
    EXPECT_LE(c[0] / b, brown.r / (brown.r + brown.g + brown.b) + 1e-9);
    brownish += c[2] / b < 0.25 ? 1 : 0;
  }
  EXPECT_GT(brownish, 2);
  EXPECT_LT(brownish, 18);
  EXPECT_NE(convoy_ground_colour(1), convoy_ground_colour(2));

  ConvoyEnvOptions o = test_options();
  o.camera = true;
  o.observation = ConvoyObservationKind::trail;
  ConvoyEnvOptions coloured = o;
  coloured.random_ground_colour = true;
  const std::uint64_t seed = 5;
  ConvoyEnv plain(o), env(coloured);
  Observation a = plain.reset(seed), b = env.reset(seed);
  ASSERT_EQ(a.vector, b.vector);
  // The bottom row sees the ground just ahead of the bumper.
  const auto pixel = [](const Observation& ob, int row, int col, int ch) {
    return static_cast<int>(ob.image[(static_cast<std::size_t>(row) * 80 + col) * 3 + ch]);
  };
  const auto c = convoy_ground_colour(seed);
  const int row = 44, col = 40;
  std::printf("ground colour (%.3f, %.3f, %.3f); bottom centre pixel plain (%d, %d, %d), "
              "coloured (%d, %d, %d)\n",
              c[0], c[1], c[2], pixel(a, row, col, 0), pixel(a, row, col, 1), pixel(a, row, col, 2),
              pixel(b, row, col, 0), pixel(b, row, col, 1), pixel(b, row, col, 2));
  // Grey ground: equal channels; the coloured ground's channels in the colour's order.
  EXPECT_EQ(pixel(a, row, col, 0), pixel(a, row, col, 2));
  EXPECT_GT(pixel(b, row, col, 0), pixel(b, row, col, 2) + 10);
  for (int k = 0; k < 40; ++k) {
    const std::vector<float> action = {0.3f * std::sin(0.3f * k), 0.4f};
    const StepResult ra = plain.step(action), rb = env.step(action);
    ASSERT_EQ(ra.observation.vector, rb.observation.vector) << "step " << k;
    ASSERT_EQ(ra.reward, rb.reward) << "step " << k;
    ASSERT_EQ(ra.terminated, rb.terminated);
    ASSERT_EQ(ra.truncated, rb.truncated);
    ASSERT_NE(ra.observation.image, rb.observation.image) << "step " << k;
    if (ra.terminated || ra.truncated) break;
  }
  // The soils keep their own look: refused there.
  ConvoyEnvOptions soft = coloured;
  soft.terrain = ConvoyTerrain::scm_soft;
  EXPECT_THROW(ConvoyEnv{soft}, std::invalid_argument);
}

// Random ground friction: each episode's rigid ground has a friction coefficient of its own in
// [friction_min, 0.8], drawn from the seed and written into the episode's scenario; the same
// actions then drive a different course (the tires' grip changes), while the episode's other
// draws (the paths, the obstacles, the leader's speed) do not.
TEST(ConvoyEnv, ARandomGroundFrictionChangesTheGripNotTheEpisode) {
  double lowest = 1.0, highest = 0.0;
  for (std::uint64_t seed = 1; seed <= 50; ++seed) {
    const double mu = convoy_ground_friction(seed, 0.45);
    EXPECT_EQ(mu, convoy_ground_friction(seed, 0.45));
    EXPECT_GE(mu, 0.45);
    EXPECT_LE(mu, 0.8);
    lowest = std::min(lowest, mu);
    highest = std::max(highest, mu);
  }
  EXPECT_LT(lowest, 0.5);   // 50 uniform draws span the range
  EXPECT_GT(highest, 0.75);

  ConvoyEnvOptions o = test_options();
  o.dynamics = ConvoyDynamics::full;
  ConvoyEnvOptions slippery = o;
  slippery.friction_min = 0.3;
  const std::uint64_t seed = 5;
  const ConvoyScenarioOptions plain_so = convoy_scenario_options(o, seed);
  const ConvoyScenarioOptions slippery_so = convoy_scenario_options(slippery, seed);
  EXPECT_EQ(plain_so.friction, 0.8);
  EXPECT_EQ(slippery_so.friction, convoy_ground_friction(seed, 0.3));
  EXPECT_EQ(plain_so.target_speed_mps, slippery_so.target_speed_mps);
  const ConvoyEpisode e = make_convoy_episode(seed, o.episode);
  const std::string plain_yaml = convoy_scenario_yaml(e, plain_so);
  EXPECT_NE(plain_yaml.find("terrain: {type: rigid, friction: 0.8}"), std::string::npos);
  const std::string slippery_yaml = convoy_scenario_yaml(e, slippery_so);
  EXPECT_EQ(slippery_yaml.find("friction: 0.8}"), std::string::npos);
  EXPECT_NE(slippery_yaml.find("terrain: {type: rigid, friction: 0."), std::string::npos);

  // The same actions (straight, then full lock) drive differently on less grip.
  ConvoyEnv plain(o), env(slippery);
  Observation a = plain.reset(seed), b = env.reset(seed);
  ASSERT_EQ(a.vector.size(), b.vector.size());
  for (std::size_t i = 0; i < a.vector.size(); ++i) {
    EXPECT_NEAR(a.vector[i], b.vector[i], 1e-3) << i;  // the start differs only by settling
  }
  bool differ = false;
  for (int k = 0; k < 60 && !differ; ++k) {
    const std::vector<float> action = {k < 20 ? 0.0f : 1.0f, 0.6f};
    const StepResult ra = plain.step(action), rb = env.step(action);
    for (std::size_t i = 0; i < ra.observation.vector.size(); ++i) {
      differ = differ || std::abs(ra.observation.vector[i] - rb.observation.vector[i]) > 0.05;
    }
    if (ra.terminated || ra.truncated || rb.terminated || rb.truncated) break;
  }
  EXPECT_TRUE(differ);

  ConvoyEnvOptions soft = slippery;
  soft.terrain = ConvoyTerrain::scm_soft;
  EXPECT_THROW(ConvoyEnv{soft}, std::invalid_argument);
  ConvoyEnvOptions too_high = o;
  too_high.friction_min = 0.9;
  EXPECT_THROW(ConvoyEnv{too_high}, std::invalid_argument);
}

// Residual steering: the action is added to the feed-forward steering of the observation the
// policy saw. The expert's action is its command minus that feed-forward, so the expert drives
// the same episode in both forms; a policy of 0 steers by the feed-forward alone.
TEST(ConvoyEnv, ResidualSteeringAddsTheActionToTheFeedforward) {
  ConvoyEnvOptions o = test_options();
  o.observation = ConvoyObservationKind::trail_ff;
  ConvoyEnvOptions r = o;
  r.steering_residual = true;
  ASSERT_EQ(ConvoyObservationBuilder::vector_space(o.observation).names.at(kFeedforwardIndex),
            "feedforward_steering");
  const std::vector<float> seen(13, 0.25f);
  EXPECT_EQ(convoy_steering_command(o, seen, 0.5), 0.5);
  EXPECT_EQ(convoy_steering_command(r, seen, 0.5), 0.75);

  const std::uint64_t seed = 7;
  ConvoyEnv plain(o), residual(r);
  Observation a = plain.reset(seed), b = residual.reset(seed);
  double largest_feedforward = 0.0, largest_gap = 0.0;
  for (int k = 0; k < 150; ++k) {
    const std::vector<float> ea = plain.expert_action(), eb = residual.expert_action();
    for (std::size_t i = 0; i < a.vector.size(); ++i) {
      ASSERT_NEAR(a.vector[i], b.vector[i], 1e-3 * (1.0 + std::abs(a.vector[i])))
          << "step " << k << ", " << i;
    }
    const float ff = b.vector[kFeedforwardIndex];
    largest_feedforward = std::max(largest_feedforward, std::abs(static_cast<double>(ff)));
    EXPECT_NEAR(eb[0], std::clamp(ea[0] - ff, -1.0f, 1.0f), 1e-6) << "step " << k;
    EXPECT_NEAR(eb[1], ea[1], 1e-3);
    // The residual env applies ff + (command - ff), the plain one the command: the same to a
    // float's rounding, which a stable follower does not amplify.
    largest_gap = std::max(largest_gap, std::abs(static_cast<double>(ff) + eb[0] - ea[0]));
    const StepResult ra = plain.step(ea);
    const StepResult rb = residual.step(eb);
    ASSERT_EQ(ra.terminated, rb.terminated);
    a = ra.observation;
    b = rb.observation;
    if (ra.terminated || ra.truncated) break;
  }
  std::printf("largest |feed-forward| %.3f, |ff + residual - command| %.2e\n", largest_feedforward,
              largest_gap);
  EXPECT_GT(largest_feedforward, 0.05);  // the episode has bends

  // A policy of 0 steers by the feed-forward alone (no lag: the applied steering is it).
  ConvoyEnv zero(r);
  Observation z = zero.reset(seed);
  for (int k = 0; k < 30; ++k) {
    const float ff = z.vector[kFeedforwardIndex];
    const StepResult rz = zero.step(std::vector<float>{0.0f, 0.3f});
    EXPECT_EQ(zero.applied_steering(), std::clamp(static_cast<double>(ff), -1.0, 1.0));
    z = rz.observation;
    if (rz.terminated || rz.truncated) break;
  }

  ConvoyEnvOptions no_feedforward = r;
  no_feedforward.observation = ConvoyObservationKind::trail;
  EXPECT_THROW(ConvoyEnv{no_feedforward}, std::invalid_argument);
}

// A start hold: the leader drives off on its path while the follower waits, braked, so the
// first observation has the leader further ahead on a trail it has laid, the follower where
// it started; the expert then closes the gap (at full throttle) without leaving its trail.
TEST(ConvoyEnv, AStartHoldLetsTheLeaderDriveOff) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const double h = convoy_start_hold(seed, 8.0);
    EXPECT_EQ(h, convoy_start_hold(seed, 8.0));
    EXPECT_GE(h, 0.0);
    EXPECT_LE(h, 8.0);
  }
  ConvoyEnvOptions o = test_options();
  o.observation = ConvoyObservationKind::trail_ff;
  o.target_speed_mps = 4.0;
  ConvoyEnvOptions held = o;
  held.start_hold_max_s = 8.0;
  std::uint64_t seed = 1;
  while (convoy_start_hold(seed, 8.0) < 6.0) ++seed;  // a long hold
  ConvoyEnv plain(o), env(held);
  const Observation a = plain.reset(seed), b = env.reset(seed);
  const std::size_t gap = 9;  // gap_m
  ASSERT_EQ(ConvoyObservationBuilder::vector_space(o.observation).names.at(gap), "gap_m");
  std::printf("hold %.2f s: gap %.1f m without, %.1f m with\n", convoy_start_hold(seed, 8.0),
              a.vector[gap], b.vector[gap]);
  EXPECT_GT(b.vector[gap], a.vector[gap] + 10.0);
  EXPECT_LT((plain.follower_state().pose.position - env.follower_state().pose.position).norm(),
            0.05);
  double largest_cross_track = 0.0, largest_throttle = 0.0, last_gap = b.vector[gap];
  for (int k = 0; k < 150; ++k) {
    const std::vector<float> e = env.expert_action();
    largest_throttle = std::max(largest_throttle, static_cast<double>(e[1]));
    const StepResult r = env.step(e);
    ASSERT_FALSE(r.terminated) << "step " << k;
    largest_cross_track = std::max(largest_cross_track, std::abs(static_cast<double>(r.observation.vector[0])));
    last_gap = r.observation.vector[gap];
    if (r.truncated) break;
  }
  std::printf("expert: largest throttle %.2f, largest |cross-track| %.2f m, gap after 15 s %.1f m\n",
              largest_throttle, largest_cross_track, last_gap);
  EXPECT_GT(largest_throttle, 0.9);
  EXPECT_LT(largest_cross_track, 1.0);
  EXPECT_LT(last_gap, b.vector[gap] - 5.0);
}

// The steering lag: none gives the clamped action (NaN as 0); a lag of tau moves the applied
// steering 1 - exp(-T / tau) of the way to the clamped action per period T.
TEST(ConvoyEnv, SteeringLagIsFirstOrderPerAction) {
  EXPECT_EQ(convoy_lagged_steering(0.4, 0.3, 0.0, 0.1), 0.3);
  EXPECT_EQ(convoy_lagged_steering(0.4, 7.0, 0.0, 0.1), 1.0);
  EXPECT_EQ(convoy_lagged_steering(0.4, std::nan(""), 0.0, 0.1), 0.0);
  const double b = 1.0 - std::exp(-0.5);
  EXPECT_DOUBLE_EQ(convoy_lagged_steering(0.0, 1.0, 0.2, 0.1), b);
  EXPECT_DOUBLE_EQ(convoy_lagged_steering(0.5, -3.0, 0.2, 0.1), 0.5 + b * (-1.0 - 0.5));
  // In the environment: the observation's previous steering is the lagged one.
  ConvoyEnvOptions o = test_options();
  o.observation = ConvoyObservationKind::trail_action;
  o.steer_lag_s = 0.2;
  ConvoyEnv env(o);
  env.reset(2);
  double applied = 0.0;
  for (int k = 0; k < 3; ++k) {
    const StepResult r = env.step(std::vector<float>{1.0f, 0.2f});
    applied += b * (1.0 - applied);
    EXPECT_FLOAT_EQ(r.observation.vector[12], static_cast<float>(applied)) << "step " << k;
  }
}

// target_speed_max: each episode's leader cap drawn in [target_speed, target_speed_max] from
// its seed, the same for the same seed, and the episode's other draws unchanged.
TEST(ConvoyEnv, LeaderSpeedCapIsDrawnPerEpisode) {
  ConvoyEnvOptions o = test_options();
  o.target_speed_mps = 3.0;
  o.target_speed_max_mps = 8.0;
  double lo = 1e9, hi = 0.0;
  for (std::uint64_t seed = 1; seed <= 50; ++seed) {
    const double v = convoy_scenario_options(o, seed).target_speed_mps;
    EXPECT_GE(v, 3.0);
    EXPECT_LE(v, 8.0);
    EXPECT_EQ(v, convoy_scenario_options(o, seed).target_speed_mps);
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  EXPECT_LT(lo, 4.0);
  EXPECT_GT(hi, 7.0);
  o.target_speed_max_mps = 0.0;
  EXPECT_EQ(convoy_scenario_options(o, 5).target_speed_mps, 3.0);
}

// Rendering only the camera frames the observations hold (the default) gives the same
// observations, image and vector, bit for bit as rendering every frame (but the image of a
// step cut short by a collision), with one frame per step instead of three (30 Hz camera,
// 10 Hz steps).
TEST(ConvoyEnv, RenderingOnlyTheObservedFramesChangesNoObservation) {
  for (const std::uint64_t seed : {4u, 9u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    ConvoyEnvOptions o = test_options();
    o.camera = true;
    o.observation = ConvoyObservationKind::trail;
    ConvoyEnv lazy(o);
    o.render_only_observed = false;
    ConvoyEnv full(o);
    Observation a = lazy.reset(seed), b = full.reset(seed);
    ASSERT_EQ(a.image, b.image);
    const std::uint64_t lazy_start = lazy.camera_frames(), full_start = full.camera_frames();
    int steps = 0;
    for (; steps < 40; ++steps) {
      // Throttle on, steering in a slow wave: the view changes from step to step.
      const std::vector<float> action = {0.3f * std::sin(0.3f * steps), 0.4f};
      const StepResult ra = lazy.step(action), rb = full.step(action);
      ASSERT_EQ(ra.observation.vector, rb.observation.vector) << "step " << steps;
      ASSERT_EQ(ra.reward, rb.reward);
      ASSERT_EQ(ra.terminated, rb.terminated);
      // A collision stops the step's frames early: its image (never used: no value beyond a
      // terminated step) is the newest rendered, which may be older.
      if (ra.terminated) break;
      ASSERT_EQ(ra.observation.image, rb.observation.image) << "step " << steps;
      if (ra.truncated) break;
    }
    ASSERT_GT(steps, 20);
    const auto lazy_frames = lazy.camera_frames() - lazy_start;
    const auto full_frames = full.camera_frames() - full_start;
    EXPECT_NEAR(static_cast<double>(full_frames) / steps, 3.0, 0.1);
    EXPECT_NEAR(static_cast<double>(lazy_frames) / steps, 1.0, 0.1);
  }
}

// The track reward's smoothness term: a braked follower standing still, steering full left and
// then full right, is paid steer_change x 2^2 less in the second step than one that keeps
// steering left (nothing else differs: it does not move).
TEST(ConvoyReward, TrackRewardChargesSteeringChanges) {
  ConvoyEnvOptions o = test_options();
  o.observation = ConvoyObservationKind::trail;
  o.reward_kind = ConvoyRewardKind::track;
  o.reward.steer_change = 0.1;
  ConvoyEnv a(o), b(o);
  a.reset(6);
  b.reset(6);
  const std::vector<float> left = {1.0f, -1.0f}, right = {-1.0f, -1.0f};
  EXPECT_EQ(a.step(left).reward, b.step(left).reward);
  const StepResult ra = a.step(right), rb = b.step(left);
  ASSERT_EQ(ra.info.at("distance_m"), rb.info.at("distance_m"));
  EXPECT_NEAR(rb.reward - ra.reward, o.reward.steer_change * 4.0, 1e-12);
}

// The perception target's geometry against hand numbers: a ray through an obstacle's centre
// reads the distance to its near edge, a ray beside it reads nothing (1), the nearer of two
// obstacles on a ray hides the farther, obstacles behind the camera or beyond the range are not
// seen, a camera inside a footprint reads 0, and the rays run left to right.
TEST(ConvoyEnv, ObstacleRangesAreTheFirstFootprintEachRayMeets) {
  const double hfov = std::numbers::pi / 2.0;  // two rays: +22.5 and -22.5 degrees
  const double b = std::numbers::pi / 8.0;
  const auto obstacle = [](double x, double y, double r) {
    ConvoyObstacle o;
    o.centre = Vec2(x, y);
    o.radius_m = r;
    return o;
  };
  // On the left ray, 10 m out along it.
  std::vector<ConvoyObstacle> obs = {obstacle(10.0 * std::cos(b), 10.0 * std::sin(b), 1.0)};
  std::vector<float> r = obstacle_ranges(Vec2::Zero(), 0.0, hfov, 2, 20.0, obs);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_NEAR(r[0], 9.0 / 20.0, 1e-6);
  EXPECT_EQ(r[1], 1.0f);
  // Turned by 45 degrees to the left, the same obstacle is on the right ray.
  r = obstacle_ranges(Vec2::Zero(), 2.0 * b, hfov, 2, 20.0, obs);
  EXPECT_EQ(r[0], 1.0f);
  EXPECT_NEAR(r[1], 9.0 / 20.0, 1e-6);
  // A nearer one on the same ray hides it; one behind the camera and one beyond the range
  // change nothing.
  obs.push_back(obstacle(5.0 * std::cos(b), 5.0 * std::sin(b), 0.5));
  obs.push_back(obstacle(-3.0, 0.0, 1.0));
  obs.push_back(obstacle(30.0 * std::cos(b), -30.0 * std::sin(b), 1.0));
  r = obstacle_ranges(Vec2::Zero(), 0.0, hfov, 2, 20.0, obs);
  EXPECT_NEAR(r[0], 4.5 / 20.0, 1e-6);
  EXPECT_EQ(r[1], 1.0f);
  // A ray grazing a footprint: the circle at distance 1 from the ray's line, radius 1.25,
  // centre 8 m along it: the ray enters 8 - sqrt(1.25^2 - 1) = 7.25 m out.
  const Vec2 d(std::cos(-b), std::sin(-b)), n(-d.y(), d.x());
  const Vec2 c = 8.0 * d + 1.0 * n;
  r = obstacle_ranges(Vec2::Zero(), 0.0, hfov, 2, 20.0,
                      std::vector<ConvoyObstacle>{obstacle(c.x(), c.y(), 1.25)});
  EXPECT_NEAR(r[1], 7.25 / 20.0, 1e-6);
  EXPECT_EQ(r[0], 1.0f);
  // From inside a footprint every ray reads 0.
  r = obstacle_ranges(Vec2(0.2, 0.0), 0.0, hfov, 2, 20.0,
                      std::vector<ConvoyObstacle>{obstacle(0.0, 0.0, 1.0)});
  EXPECT_EQ(r, (std::vector<float>{0.0f, 0.0f}));
  EXPECT_THROW(obstacle_ranges(Vec2::Zero(), 0.0, hfov, 0, 20.0, obs), std::invalid_argument);
  EXPECT_THROW(obstacle_ranges(Vec2::Zero(), 0.0, hfov, 2, 0.0, obs), std::invalid_argument);
  EXPECT_THROW(obstacle_ranges(Vec2::Zero(), 0.0, 0.0, 2, 20.0, obs), std::invalid_argument);
}

// The environment's perception target: the ranges of the follower's camera, only with the
// camera; on a course episode driven by the expert the camera sees obstacles at times and
// never from inside one, and the target is what obstacle_ranges reads from the camera's place
// (2.4 m ahead of the reference point), not from the reference point.
TEST(ConvoyEnv, ThePerceptionTargetIsTheCamerasViewOfTheObstacles) {
  ConvoyEnvOptions o = test_options();
  o.observation = ConvoyObservationKind::trail;
  o.episode.kind = ConvoyEpisodeKind::courses;
  ConvoyEnv blind(o);
  blind.reset(2000001);
  EXPECT_TRUE(blind.perception_target().empty());
  o.camera = true;
  ConvoyEnv env(o);
  env.reset(2000001);
  int seeing = 0, steps = 0, from_camera = 0;
  while (steps < 400) {
    const std::vector<float> t = env.perception_target();
    ASSERT_EQ(t.size(), static_cast<std::size_t>(kPerceptionRays));
    const float nearest = *std::min_element(t.begin(), t.end());
    EXPECT_GT(nearest, 0.0f);
    EXPECT_LE(*std::max_element(t.begin(), t.end()), 1.0f);
    seeing += nearest < 1.0f ? 1 : 0;
    const auto& pose = env.follower_state().pose;
    const double yaw = yaw_of(pose.orientation);
    const Vec2 ref(pose.position.x(), pose.position.y());
    const Vec2 camera = ref + 2.4 * Vec2(std::cos(yaw), std::sin(yaw));
    const auto at = [&](const Vec2& p) {
      return obstacle_ranges(p, yaw, std::numbers::pi / 2.0, kPerceptionRays, kPerceptionRangeM,
                             env.episode().obstacles);
    };
    if (nearest < 1.0f) {
      const std::vector<float> expected = at(camera);
      for (std::size_t k = 0; k < t.size(); ++k) EXPECT_NEAR(t[k], expected[k], 1e-5);
      from_camera += at(ref) != t ? 1 : 0;
    }
    const StepResult r = env.step(env.expert_action());
    ++steps;
    if (r.terminated || r.truncated) break;
  }
  std::printf("%d of %d observations see an obstacle\n", seeing, steps);
  EXPECT_GT(seeing, 10);
  EXPECT_GT(from_camera, 0);
}
