#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <queue>

#include "control/path.hpp"
#include "course/course.hpp"

namespace syndds::course {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kTol = 1e-7;  // geometric tolerance of the tangent graph (m, rad)

double wrap_2pi(double a) {
  a = std::fmod(a, kTwoPi);
  return a < 0.0 ? a + kTwoPi : a;
}

bool point_in_square(const Vec2& p, double size, double tol) {
  return p.x() >= -tol && p.y() >= -tol && p.x() <= size + tol && p.y() <= size + tol;
}

// ---- tangent graph ----

struct Edge {
  int to = 0;
  double length = 0.0;
  int circle = -1;     // -1: straight segment; else an arc of this circle
  double from_angle = 0.0;
  double span = 0.0;   // signed: positive counter-clockwise
};

struct Graph {
  const std::vector<Circle>& circles;
  double size;
  std::vector<Vec2> nodes;
  std::vector<int> node_circle;
  std::vector<std::vector<Edge>> edges;

  bool free_point(const Vec2& p) const {
    if (!point_in_square(p, size, kTol)) return false;
    for (const Circle& c : circles) {
      if ((p - c.centre).norm() < c.radius - kTol) return false;
    }
    return true;
  }
  bool free_segment(const Vec2& a, const Vec2& b) const {
    for (const Circle& c : circles) {
      if (segment_point_distance(a, b, c.centre) < c.radius - kTol) return false;
    }
    return true;  // endpoints are free nodes, the square is convex
  }
  int add_node(const Vec2& p, int circle) {
    if (!free_point(p)) return -1;
    nodes.push_back(p);
    node_circle.push_back(circle);
    edges.emplace_back();
    return static_cast<int>(nodes.size()) - 1;
  }
  void add_segment(int a, int b) {
    if (a < 0 || b < 0 || !free_segment(nodes[a], nodes[b])) return;
    const double l = (nodes[a] - nodes[b]).norm();
    edges[a].push_back({b, l});
    edges[b].push_back({a, l});
  }
  // Whether the counter-clockwise arc of circle i from angle a over span s is free.
  bool free_arc(int i, double a, double s) const {
    const Circle& ci = circles[i];
    for (std::size_t j = 0; j < circles.size(); ++j) {
      if (static_cast<int>(j) == i) continue;
      const Circle& cj = circles[j];
      const Vec2 d = cj.centre - ci.centre;
      const double dist = d.norm();
      if (dist >= ci.radius + cj.radius || dist + cj.radius <= ci.radius) continue;
      if (dist + ci.radius <= cj.radius) return false;  // circle i lies inside j
      const double cos_beta =
          (ci.radius * ci.radius + dist * dist - cj.radius * cj.radius) / (2 * ci.radius * dist);
      const double beta = std::acos(std::clamp(cos_beta, -1.0, 1.0));
      const double b_start = std::atan2(d.y(), d.x()) - beta;
      const double u = wrap_2pi(b_start - a);
      const double v = wrap_2pi(a - b_start);
      if (u < s - kTol || v < 2 * beta - kTol) return false;
    }
    // The arc stays in the square if its end points and its axis extremes inside it do.
    for (int q = 0; q < 4; ++q) {
      const double ang = q * std::numbers::pi / 2;
      if (wrap_2pi(ang - a) <= s) {
        const Vec2 p = ci.centre + ci.radius * Vec2(std::cos(ang), std::sin(ang));
        if (!point_in_square(p, size, kTol)) return false;
      }
    }
    return true;
  }
};

void point_tangents(Graph& g, int point_node, int i) {
  const Circle& c = g.circles[i];
  const Vec2 d = g.nodes[point_node] - c.centre;
  const double dist = d.norm();
  if (dist <= c.radius) return;
  const double theta = std::atan2(d.y(), d.x());
  const double alpha = std::acos(c.radius / dist);
  for (double sign : {-1.0, 1.0}) {
    const double ang = theta + sign * alpha;
    const int n = g.add_node(c.centre + c.radius * Vec2(std::cos(ang), std::sin(ang)), i);
    g.add_segment(point_node, n);
  }
}

void bitangents(Graph& g, int i, int j) {
  const Circle& c1 = g.circles[i];
  const Circle& c2 = g.circles[j];
  const Vec2 d = c2.centre - c1.centre;
  const double dd = d.squaredNorm();
  if (dd < 1e-18) return;
  const Vec2 perp(-d.y(), d.x());
  for (double a1 : {-1.0, 1.0}) {
    for (double a2 : {-1.0, 1.0}) {
      // Line n.p + k = 0 with n.c1 + k = a1 r1 and n.c2 + k = a2 r2, |n| = 1.
      const double r = a2 * c2.radius - a1 * c1.radius;
      if (dd < r * r) continue;
      const double h = std::sqrt(dd - r * r);
      for (double s : {-1.0, 1.0}) {
        const Vec2 n = (r * d + s * h * perp) / dd;
        const Vec2 p1 = c1.centre - a1 * c1.radius * n;
        const Vec2 p2 = c2.centre - a2 * c2.radius * n;
        const int n1 = g.add_node(p1, i);
        if (n1 < 0) continue;
        const int n2 = g.add_node(p2, j);
        g.add_segment(n1, n2);
      }
    }
  }
}

}  // namespace

namespace {

// True when `p` lies farther than `reach` from the bounding box of segment ab, so farther from
// the segment too: the exact distance need not be computed. The 1e-9 m allowance keeps every
// decision the one the exact distance makes, whatever the rounding.
bool beyond_box(const Vec2& a, const Vec2& b, const Vec2& p, double reach) {
  const double r = reach + 1e-9;
  return p.x() < std::min(a.x(), b.x()) - r || p.x() > std::max(a.x(), b.x()) + r ||
         p.y() < std::min(a.y(), b.y()) - r || p.y() > std::max(a.y(), b.y()) + r;
}

}  // namespace

double segment_point_distance(const Vec2& a, const Vec2& b, const Vec2& p) {
  const Vec2 ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 > 0.0 ? std::clamp((p - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

double polyline_length(const std::vector<Vec2>& points) {
  double l = 0.0;
  for (std::size_t i = 1; i < points.size(); ++i) l += (points[i] - points[i - 1]).norm();
  return l;
}

double polyline_clearance(const std::vector<Vec2>& points, const std::vector<Circle>& circles) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < points.size(); ++i) {
    for (const Circle& c : circles) {
      best = std::min(best, segment_point_distance(points[i], points[i + 1], c.centre) - c.radius);
    }
  }
  return best;
}

bool polyline_in_square(const std::vector<Vec2>& points, double size_m, double tol) {
  return std::all_of(points.begin(), points.end(),
                     [&](const Vec2& p) { return point_in_square(p, size_m, tol); });
}

double reference_shortest_path(const Vec2& start, const Vec2& goal,
                               const std::vector<Circle>& circles, double size_m,
                               std::vector<Vec2>* points) {
  Graph g{circles, size_m, {}, {}, {}};
  const int s = g.add_node(start, -1);
  const int t = g.add_node(goal, -1);
  if (s < 0 || t < 0) return std::numeric_limits<double>::infinity();
  g.add_segment(s, t);
  const int nc = static_cast<int>(circles.size());
  for (int i = 0; i < nc; ++i) {
    point_tangents(g, s, i);
    point_tangents(g, t, i);
    for (int j = i + 1; j < nc; ++j) bitangents(g, i, j);
  }
  // Arcs between angularly consecutive nodes of each circle, both ways.
  std::vector<std::vector<std::pair<double, int>>> on_circle(circles.size());
  for (std::size_t n = 0; n < g.nodes.size(); ++n) {
    const int c = g.node_circle[n];
    if (c < 0) continue;
    const Vec2 d = g.nodes[n] - circles[c].centre;
    on_circle[c].push_back({wrap_2pi(std::atan2(d.y(), d.x())), static_cast<int>(n)});
  }
  for (int c = 0; c < nc; ++c) {
    auto& list = on_circle[c];
    std::sort(list.begin(), list.end());
    const std::size_t m = list.size();
    if (m < 2) continue;
    for (std::size_t k = 0; k < m; ++k) {
      const auto& [a, na] = list[k];
      const auto& [b, nb] = list[(k + 1) % m];
      const double span = wrap_2pi(b - a);
      if (!g.free_arc(c, a, span)) continue;
      const double l = circles[c].radius * span;
      g.edges[na].push_back({nb, l, c, a, span});
      g.edges[nb].push_back({na, l, c, b, -span});
    }
  }
  // Dijkstra.
  const std::size_t n = g.nodes.size();
  std::vector<double> dist(n, std::numeric_limits<double>::infinity());
  std::vector<int> prev(n, -1);
  std::vector<Edge> via(n);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  dist[s] = 0.0;
  queue.push({0.0, s});
  while (!queue.empty()) {
    const auto [d, u] = queue.top();
    queue.pop();
    if (d > dist[u]) continue;
    if (u == t) break;
    for (const Edge& e : g.edges[u]) {
      if (d + e.length < dist[e.to]) {
        dist[e.to] = d + e.length;
        prev[e.to] = u;
        via[e.to] = e;
        queue.push({dist[e.to], e.to});
      }
    }
  }
  if (points && std::isfinite(dist[t])) {
    std::vector<Vec2> reversed{g.nodes[t]};
    for (int v = t; prev[v] >= 0; v = prev[v]) {
      const Edge& e = via[v];
      if (e.circle >= 0) {
        const Circle& c = circles[e.circle];
        const int steps =
            std::max(1, static_cast<int>(std::ceil(std::abs(e.span) * c.radius / 0.5)));
        for (int k = steps - 1; k > 0; --k) {
          const double ang = e.from_angle + e.span * k / steps;
          reversed.push_back(c.centre + c.radius * Vec2(std::cos(ang), std::sin(ang)));
        }
      }
      reversed.push_back(g.nodes[prev[v]]);
    }
    points->assign(reversed.rbegin(), reversed.rend());
  }
  return dist[t];
}

// ---- particle swarm ----

namespace {

struct Problem {
  Vec2 start, goal;
  double size = 0.0;
  std::vector<Circle> inflated;  // by clearance + margin
  double margin = 0.0;
  double penalty = 0.0;
  double margin_penalty = 0.0;

  // x holds the K intermediate waypoints as x0, y0, x1, y1, ...
  std::vector<Vec2> polyline(const std::vector<double>& x) const {
    std::vector<Vec2> pts{start};
    for (std::size_t k = 0; k + 1 < x.size(); k += 2) pts.push_back(Vec2(x[k], x[k + 1]));
    pts.push_back(goal);
    return pts;
  }
  double cost(const std::vector<double>& x) const {
    const std::vector<Vec2> pts = polyline(x);
    double c = polyline_length(pts);
    for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
      for (const Circle& o : inflated) {
        if (beyond_box(pts[i], pts[i + 1], o.centre, o.radius)) continue;  // no depth
        // Inside the margin costs a little (narrow gaps stay usable), inside the clearance
        // a lot.
        const double depth = o.radius - segment_point_distance(pts[i], pts[i + 1], o.centre);
        if (depth > 0.0) c += margin_penalty * depth + penalty * std::max(0.0, depth - margin);
      }
    }
    return c;
  }
};

Problem make_problem(const Field& f, const PlannerParams& p) {
  Problem pr;
  pr.start = f.start;
  pr.goal = f.goal;
  pr.size = f.params.size_m;
  for (const Circle& c : f.obstacles) {
    pr.inflated.push_back({c.centre, c.radius + p.clearance_m + p.margin_m});
  }
  pr.margin = p.margin_m;
  pr.penalty = p.penalty_per_m;
  pr.margin_penalty = p.margin_penalty_per_m;
  return pr;
}

// The swarm's seed path: Theta* (any-angle Dijkstra) on the 8-connected 0.5 m grid of the
// square, nodes and edge midpoints outside the circles inflated by the clearance (less half a
// cell), as K
// waypoints. It picks the way round the obstacles; the swarm then shortens it. Empty when the
// grid has no path (the field is then redrawn: a way missed by a 0.5 m grid has hardly any room to spare).
std::vector<double> grid_seed_path(const Problem& pr, int waypoints, double margin) {
  // Half a cell less than the clearance: a gap the grid's nodes just miss stays open (the swarm
  // then finds the exact way through, or the path is refused after the exact check).
  const double slack = margin + 0.25;
  const int n = static_cast<int>(std::lround(2.0 * pr.size)) + 1;  // 0.5 m
  auto free = [&](const Vec2& q) {
    return std::all_of(pr.inflated.begin(), pr.inflated.end(), [&](const Circle& c) {
      return (q - c.centre).norm() >= c.radius - slack;
    });
  };
  auto sees = [&](const Vec2& a, const Vec2& b) {
    return std::all_of(pr.inflated.begin(), pr.inflated.end(), [&](const Circle& c) {
      return beyond_box(a, b, c.centre, c.radius - slack) ||
             segment_point_distance(a, b, c.centre) >= c.radius - slack;
    });
  };
  auto at = [&](int i) { return Vec2(pr.size * (i % n) / (n - 1), pr.size * (i / n) / (n - 1)); };
  const int s = 0;
  const int t = n * n - 1;
  std::vector<char> open(n * n);
  for (int i = 0; i < n * n; ++i) open[i] = free(at(i));
  open[s] = open[t] = 1;
  std::vector<double> dist(n * n, std::numeric_limits<double>::infinity());
  std::vector<int> prev(n * n, -1);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  dist[s] = 0.0;
  queue.push({0.0, s});
  while (!queue.empty()) {
    const auto [d, u] = queue.top();
    queue.pop();
    if (d > dist[u]) continue;
    if (u == t) break;
    const int ux = u % n;
    const int uy = u / n;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int vx = ux + dx;
        const int vy = uy + dy;
        if ((dx == 0 && dy == 0) || vx < 0 || vy < 0 || vx >= n || vy >= n) continue;
        const int v = vy * n + vx;
        if (!open[v] || !free(0.5 * (at(u) + at(v)))) continue;
        // Theta*: straight from u's parent when it sees v, so the path is any-angle and the
        // way round each obstacle is chosen by true lengths, not 8-direction ones.
        const int from = prev[u] >= 0 && sees(at(prev[u]), at(v)) ? prev[u] : u;
        const double nd = dist[from] + (at(from) - at(v)).norm();
        if (nd < dist[v]) {
          dist[v] = nd;
          prev[v] = from;
          queue.push({nd, v});
        }
      }
    }
  }
  if (!std::isfinite(dist[t])) return {};
  std::vector<Vec2> path;
  for (int v = t; v >= 0; v = prev[v]) path.push_back(at(v));
  std::reverse(path.begin(), path.end());
  path.front() = pr.start;
  path.back() = pr.goal;
  // Keep the corners (the way round each obstacle) and split the longest pieces until there
  // are K intermediate points; equal arc lengths if there are more corners than K.
  std::vector<double> x;
  if (path.size() <= static_cast<std::size_t>(waypoints) + 2) {
    while (path.size() < static_cast<std::size_t>(waypoints) + 2) {
      std::size_t longest = 0;
      for (std::size_t i = 1; i + 1 < path.size(); ++i) {
        if ((path[i + 1] - path[i]).norm() > (path[longest + 1] - path[longest]).norm()) {
          longest = i;
        }
      }
      path.insert(path.begin() + static_cast<std::ptrdiff_t>(longest) + 1,
                  0.5 * (path[longest] + path[longest + 1]));
    }
    for (std::size_t i = 1; i + 1 < path.size(); ++i) {
      x.push_back(path[i].x());
      x.push_back(path[i].y());
    }
    return x;
  }
  const double total = polyline_length(path);
  std::size_t seg = 0;
  double acc = 0.0;
  for (int k = 1; k <= waypoints; ++k) {
    const double target = total * k / (waypoints + 1);
    while (seg + 2 < path.size() && acc + (path[seg + 1] - path[seg]).norm() < target) {
      acc += (path[seg + 1] - path[seg]).norm();
      ++seg;
    }
    const double d = (path[seg + 1] - path[seg]).norm();
    const Vec2 q = path[seg] + (target - acc) / d * (path[seg + 1] - path[seg]);
    x.push_back(q.x());
    x.push_back(q.y());
  }
  return x;
}

// One gbest swarm around the seed path; returns the best position found.
std::vector<double> run_swarm(const Problem& pr, const PlannerParams& p,
                              const std::vector<double>& seed_path, int particles,
                              int iterations, Rng& rng) {
  const std::size_t dim = seed_path.size();
  std::vector<std::vector<double>> x(particles, seed_path);
  std::vector<std::vector<double>> v(particles, std::vector<double>(dim));
  for (int i = 1; i < particles; ++i) {  // particle 0 is the seed path itself
    const double spread = 10.0 * i / particles;  // m: from close copies to wide variations
    for (std::size_t k = 0; k < dim; ++k) {
      x[i][k] = std::clamp(seed_path[k] + rng.uniform(-spread, spread), 0.0, pr.size);
      v[i][k] = rng.uniform(-1.0, 1.0);
    }
  }
  std::vector<std::vector<double>> best_x = x;
  std::vector<double> best_c(particles);
  int g = 0;
  for (int i = 0; i < particles; ++i) {
    best_c[i] = pr.cost(x[i]);
    if (best_c[i] < best_c[g]) g = i;
  }
  const double vmax = 5.0;  // m per iteration
  for (int it = 0; it < iterations; ++it) {
    for (int i = 0; i < particles; ++i) {
      for (std::size_t k = 0; k < dim; ++k) {
        v[i][k] = p.inertia * v[i][k] +
                  p.cognitive * rng.uniform() * (best_x[i][k] - x[i][k]) +
                  p.social * rng.uniform() * (best_x[g][k] - x[i][k]);
        v[i][k] = std::clamp(v[i][k], -vmax, vmax);
        x[i][k] = std::clamp(x[i][k] + v[i][k], 0.0, pr.size);
      }
      const double c = pr.cost(x[i]);
      if (c < best_c[i]) {
        best_c[i] = c;
        best_x[i] = x[i];
        if (c < best_c[g]) g = i;
      }
    }
  }
  return best_x[g];
}

std::vector<Vec2> chaikin(const std::vector<Vec2>& pts) {
  std::vector<Vec2> out{pts.front()};
  for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
    out.push_back(0.75 * pts[i] + 0.25 * pts[i + 1]);
    out.push_back(0.25 * pts[i] + 0.75 * pts[i + 1]);
  }
  out.push_back(pts.back());
  return out;
}

// Clearance of the path the leader's controller drives: the Catmull-Rom spline through the
// waypoints (common/control/path.hpp), sampled every 0.2 m.
double spline_clearance(const std::vector<Vec2>& waypoints, const std::vector<Circle>& circles) {
  const control::Path path(waypoints, false);
  return polyline_clearance(path.samples(), circles);
}

}  // namespace

PlannedPath plan_path(const Field& field, std::uint64_t seed, const PlannerParams& p) {
  const Problem pr = make_problem(field, p);
  const double size = field.params.size_m;
  const std::vector<double> seed_path = grid_seed_path(pr, p.waypoints, p.margin_m);
  if (seed_path.empty()) {
    throw CourseError("course path: the field has no way from start to goal keeping " +
                      std::to_string(p.clearance_m) + " m from every obstacle (0.5 m grid)");
  }
  for (int attempt = 0; attempt < p.attempts; ++attempt) {
    const int scale = 1 << attempt;
    std::vector<Vec2> best;
    double best_length = std::numeric_limits<double>::infinity();
    for (int s = 0; s < p.swarms; ++s) {
      // Planner streams start at 2^32, clear of the field draws.
      Rng rng(seed, (std::uint64_t{1} << 32) + static_cast<std::uint64_t>(attempt * 256 + s));
      const std::vector<Vec2> pts =
          pr.polyline(run_swarm(pr, p, seed_path, p.particles * scale, p.iterations * scale, rng));
      const double l = polyline_length(pts);
      if (polyline_clearance(pts, field.obstacles) >= p.clearance_m &&
          polyline_in_square(pts, size) && l < best_length) {
        best = pts;
        best_length = l;
      }
    }
    if (best.empty()) continue;
    for (int passes = p.smoothing_passes; passes >= 0; --passes) {
      std::vector<Vec2> smooth = best;
      for (int k = 0; k < passes; ++k) smooth = chaikin(smooth);
      const double clearance = std::min(polyline_clearance(smooth, field.obstacles),
                                        spline_clearance(smooth, field.obstacles));
      if (clearance >= p.clearance_m && polyline_in_square(smooth, size)) {
        PlannedPath out;
        out.waypoints = smooth;
        out.raw = best;
        out.length_m = polyline_length(smooth);
        out.clearance_m = clearance;
        out.attempt = attempt;
        out.smoothing_passes = passes;
        return out;
      }
    }
  }
  throw CourseError("course path: no path keeping " + std::to_string(p.clearance_m) +
                    " m from every obstacle found in " + std::to_string(p.attempts) +
                    " attempts (seed " + std::to_string(seed) + ")");
}

}  // namespace syndds::course
