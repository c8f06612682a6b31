// The Python binding `syndds._syndds`: the learning environments of common/learn with
// Gymnasium's API (reset -> (observation, info), step -> (observation, reward, terminated,
// truncated, info)), observations and actions as numpy arrays. The package syndds/__init__.py
// adds the space classes and make(). The simulation runs without the GIL.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "learn/env.hpp"
#include "learn/registry.hpp"
#include "learn/vector_env.hpp"

namespace py = pybind11;
using namespace pybind11::literals;
using namespace syndds::learn;

namespace {

py::array_t<float> to_array(const std::vector<float>& v) {
  py::array_t<float> a(static_cast<py::ssize_t>(v.size()));
  if (!v.empty()) std::memcpy(a.mutable_data(), v.data(), v.size() * sizeof(float));
  return a;
}

// A vector-only space gives a 1-D array; with a camera a dict {"image": HxWx3 uint8, "vector"}.
py::object to_python(const Observation& o, const ObservationSpace& space) {
  py::array_t<float> vector = to_array(o.vector);
  if (!space.image) return vector;
  const ImageSpec& s = *space.image;
  py::array_t<std::uint8_t> image({s.height, s.width, s.channels});
  if (o.image.size() != s.bytes()) {
    throw std::runtime_error("environment returned an image of " + std::to_string(o.image.size()) +
                             " bytes, its space says " + std::to_string(s.bytes()));
  }
  std::memcpy(image.mutable_data(), o.image.data(), o.image.size());
  return py::dict("image"_a = image, "vector"_a = vector);
}

py::dict box_dict(const Box& b) {
  std::vector<bool> explore(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) explore[i] = b.explored(i);
  return py::dict("low"_a = to_array(b.low), "high"_a = to_array(b.high), "names"_a = b.names,
                  "explore"_a = explore);
}

py::dict space_dict(const ObservationSpace& s) {
  py::dict d("vector"_a = box_dict(s.vector));
  if (s.image) d["image"] = py::make_tuple(s.image->height, s.image->width, s.image->channels);
  return d;
}

std::vector<float> to_action(const py::handle& action, std::size_t size) {
  const auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(action);
  if (!a || a.ndim() != 1 || static_cast<std::size_t>(a.shape(0)) != size) {
    throw py::value_error("action: expected a sequence of " + std::to_string(size) + " numbers");
  }
  return {a.data(), a.data() + size};
}

py::dict info_dict(const std::map<std::string, double>& info) {
  py::dict d;
  for (const auto& [k, v] : info) d[py::str(k)] = v;
  return d;
}

std::map<std::string, std::string> options_of(const py::dict& kwargs) {
  std::map<std::string, std::string> out;
  for (const auto& [k, v] : kwargs) out[py::str(k)] = py::str(v);
  return out;
}

// One environment, as Python sees it.
class PyEnv {
 public:
  PyEnv(const std::string& name, const py::dict& options)
      : env_(make_env(name, options_of(options))), space_(env_->observation_space()) {}

  py::tuple reset(std::optional<std::uint64_t> seed) {
    if (seed) next_seed_ = *seed;
    Observation o;
    {
      py::gil_scoped_release release;
      o = env_->reset(next_seed_++);
    }
    return py::make_tuple(to_python(o, space_), py::dict());
  }

  py::tuple step(const py::handle& action) {
    const std::vector<float> a = to_action(action, env_->action_space().size());
    StepResult r;
    {
      py::gil_scoped_release release;
      r = env_->step(a);
    }
    return py::make_tuple(to_python(r.observation, space_), r.reward, r.terminated, r.truncated,
                          info_dict(r.info));
  }

  py::dict observation_space() const { return space_dict(space_); }
  py::dict action_space() const { return box_dict(env_->action_space()); }
  py::array_t<float> expert_action() const { return to_array(env_->expert_action()); }
  py::array_t<float> perception_target() const { return to_array(env_->perception_target()); }

 private:
  std::unique_ptr<Env> env_;
  ObservationSpace space_;
  std::uint64_t next_seed_ = 0;  // reset() without a seed: the next one
};

// K copies stepped together (auto-reset; the ended episode's last observation is in
// info["final_observation"][i]).
class PyVectorEnv {
 public:
  PyVectorEnv(const std::string& name, int copies, int threads, const py::dict& options)
      : env_(env_factory(name, options_of(options)), copies, threads),
        space_(env_.observation_space()) {}

  py::tuple reset(std::uint64_t seed) {
    std::vector<Observation> obs;
    {
      py::gil_scoped_release release;
      obs = env_.reset(seed);
    }
    return py::make_tuple(batch(obs), py::dict());
  }

  py::tuple step(const py::handle& actions) {
    const auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(actions);
    const std::size_t n = env_.action_space().size();
    const auto k = static_cast<std::size_t>(env_.size());
    if (!a || a.ndim() != 2 || static_cast<std::size_t>(a.shape(0)) != k ||
        static_cast<std::size_t>(a.shape(1)) != n) {
      throw py::value_error("actions: expected an array of shape (" + std::to_string(k) + ", " +
                            std::to_string(n) + ")");
    }
    std::vector<std::vector<float>> per_copy(k);
    for (std::size_t i = 0; i < k; ++i) per_copy[i].assign(a.data() + i * n, a.data() + (i + 1) * n);
    VectorStepResult r;
    {
      py::gil_scoped_release release;
      r = env_.step(per_copy);
    }
    std::vector<Observation> obs;
    py::array_t<double> reward(static_cast<py::ssize_t>(k));
    py::array_t<bool> terminated(static_cast<py::ssize_t>(k)), truncated(static_cast<py::ssize_t>(k));
    py::list finals, infos;
    for (std::size_t i = 0; i < k; ++i) {
      obs.push_back(r.results[i].observation);
      reward.mutable_at(i) = r.results[i].reward;
      terminated.mutable_at(i) = r.results[i].terminated;
      truncated.mutable_at(i) = r.results[i].truncated;
      finals.append(r.final_observations[i] ? to_python(*r.final_observations[i], space_)
                                            : py::object(py::none()));
      infos.append(info_dict(r.results[i].info));
    }
    return py::make_tuple(batch(obs), reward, terminated, truncated,
                          py::dict("final_observation"_a = finals, "per_copy"_a = infos));
  }

  int size() const { return env_.size(); }
  py::dict observation_space() const { return space_dict(space_); }
  py::dict action_space() const { return box_dict(env_.action_space()); }
  // (K, A) floats, or (K, 0) when the environment has no teacher.
  py::array_t<float> expert_actions() { return rows("expert_action", &Env::expert_action); }
  // (K, R) floats, or (K, 0) when the environment has no perception target.
  py::array_t<float> perception_targets() {
    return rows("perception_target", &Env::perception_target);
  }

 private:
  // One row per copy of what `of` gives.
  py::array_t<float> rows(const char* what, std::vector<float> (Env::*of)() const) {
    const auto k = static_cast<std::size_t>(env_.size());
    std::vector<std::vector<float>> each(k);
    for (std::size_t i = 0; i < k; ++i) each[i] = (env_.copy(static_cast<int>(i)).*of)();
    const std::size_t n = each.empty() ? 0 : each.front().size();
    py::array_t<float> out({k, n});
    for (std::size_t i = 0; i < k; ++i) {
      if (each[i].size() != n) {
        throw py::value_error(std::string(what) + ": copies disagree on its size");
      }
      std::memcpy(out.mutable_data(i), each[i].data(), n * sizeof(float));
    }
    return out;
  }

  // Observations of all copies stacked: (K, n) floats, and (K, H, W, 3) bytes with a camera.
  py::object batch(const std::vector<Observation>& obs) const {
    const std::size_t k = obs.size(), n = space_.vector.size();
    py::array_t<float> vector({k, n});
    for (std::size_t i = 0; i < k; ++i) {
      std::memcpy(vector.mutable_data(i), obs[i].vector.data(), n * sizeof(float));
    }
    if (!space_.image) return vector;
    const ImageSpec& s = *space_.image;
    py::array_t<std::uint8_t> image({static_cast<py::ssize_t>(k), static_cast<py::ssize_t>(s.height),
                                     static_cast<py::ssize_t>(s.width),
                                     static_cast<py::ssize_t>(s.channels)});
    for (std::size_t i = 0; i < k; ++i) {
      std::memcpy(image.mutable_data(i), obs[i].image.data(), s.bytes());
    }
    return py::dict("image"_a = image, "vector"_a = vector);
  }

  VectorEnv env_;
  ObservationSpace space_;
};

}  // namespace

PYBIND11_MODULE(_syndds, m) {
  m.doc() = "syndds learning environments (C++), Gymnasium-style API";
  m.def("env_names", &env_names, "The environments make() knows.");
  py::class_<PyEnv>(m, "Env")
      .def(py::init<const std::string&, const py::dict&>(), "name"_a, "options"_a = py::dict())
      .def("reset", &PyEnv::reset, "seed"_a = py::none())
      .def("step", &PyEnv::step, "action"_a)
      .def("expert_action", &PyEnv::expert_action,
           "The teacher's action for the current state (empty without one)")
      .def("perception_target", &PyEnv::perception_target,
           "What a perception network is fitted to read from the current image (empty without "
           "one)")
      .def_property_readonly("observation_space_dict", &PyEnv::observation_space)
      .def_property_readonly("action_space_dict", &PyEnv::action_space);
  py::class_<PyVectorEnv>(m, "VectorEnv")
      .def(py::init<const std::string&, int, int, const py::dict&>(), "name"_a, "copies"_a,
           "threads"_a = 1, "options"_a = py::dict())
      .def("reset", &PyVectorEnv::reset, "seed"_a)
      .def("step", &PyVectorEnv::step, "actions"_a)
      .def("expert_action", &PyVectorEnv::expert_actions,
           "Each copy's teacher action for its current state: (copies, actions)")
      .def("perception_target", &PyVectorEnv::perception_targets,
           "Each copy's perception target for its current image: (copies, values)")
      .def_property_readonly("num_envs", &PyVectorEnv::size)
      .def_property_readonly("observation_space_dict", &PyVectorEnv::observation_space)
      .def_property_readonly("action_space_dict", &PyVectorEnv::action_space);
}
