#include "pursuit.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static double clamp(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

pursuit_config pursuit_default_config(void) {
  pursuit_config c;
  c.speed_mps = 5.0;
  c.lookahead_min_m = 3.0;
  c.lookahead_gain_s = 0.6;
  c.wheelbase_m = 3.378;                      /* HMMWV: axles at +-1.689 m */
  c.max_steer_rad = 30.23 * 3.14159265358979323846 / 180.0;
  c.speed_gain = 0.5;
  c.stop_decel_mps2 = 1.5;
  return c;
}

static int parse_number(const char** cursor, double* out) {
  char* end = NULL;
  errno = 0;
  const double v = strtod(*cursor, &end);
  if (end == *cursor || errno == ERANGE || !isfinite(v)) return 0;
  *out = v;
  *cursor = end;
  return 1;
}

static void skip_spaces(const char** cursor) {
  while (**cursor == ' ' || **cursor == '\t') ++*cursor;
}

int pursuit_parse_waypoints(const char* text, pursuit_path* path, char* error,
                            size_t error_size) {
  const char* c = text;
  path->count = 0;
  while (1) {
    double x = 0.0, y = 0.0;
    skip_spaces(&c);
    if (!parse_number(&c, &x)) {
      snprintf(error, error_size, "point %zu: expected a number for x at \"%s\"",
               path->count + 1, c);
      return 0;
    }
    skip_spaces(&c);
    if (*c != ',') {
      snprintf(error, error_size, "point %zu: expected ',' between x and y at \"%s\"",
               path->count + 1, c);
      return 0;
    }
    ++c;
    skip_spaces(&c);
    if (!parse_number(&c, &y)) {
      snprintf(error, error_size, "point %zu: expected a number for y at \"%s\"",
               path->count + 1, c);
      return 0;
    }
    if (path->count == PURSUIT_MAX_POINTS) {
      snprintf(error, error_size, "more than %d points", PURSUIT_MAX_POINTS);
      return 0;
    }
    const size_t i = path->count;
    path->x[i] = x;
    path->y[i] = y;
    if (i == 0) {
      path->s[i] = 0.0;
    } else {
      const double d = hypot(x - path->x[i - 1], y - path->y[i - 1]);
      if (d < 1e-6) {
        snprintf(error, error_size, "point %zu repeats point %zu", i + 1, i);
        return 0;
      }
      path->s[i] = path->s[i - 1] + d;
    }
    path->count = i + 1;
    skip_spaces(&c);
    if (*c == '\0') break;
    if (*c != ';') {
      snprintf(error, error_size, "point %zu: expected ';' before the next point at \"%s\"",
               path->count, c);
      return 0;
    }
    ++c;
  }
  if (path->count < 2) {
    snprintf(error, error_size, "a path needs at least two points, got %zu", path->count);
    return 0;
  }
  return 1;
}

void pursuit_reset(pursuit_state* state) {
  state->segment = 0;
  state->progress_m = 0.0;
}

double pursuit_yaw(double w, double x, double y, double z) {
  return atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z));
}

/* Closest point of segment i to (px, py): its parameter t in [0, 1] and squared distance. */
static double project_on_segment(const pursuit_path* path, size_t i, double px, double py,
                                 double* t_out) {
  const double ax = path->x[i], ay = path->y[i];
  const double dx = path->x[i + 1] - ax, dy = path->y[i + 1] - ay;
  const double len2 = dx * dx + dy * dy;
  const double t = clamp(((px - ax) * dx + (py - ay) * dy) / len2, 0.0, 1.0);
  const double qx = ax + t * dx - px, qy = ay + t * dy - py;
  *t_out = t;
  return qx * qx + qy * qy;
}

/* The point at arc length s; beyond the end it continues along the last segment, so the
 * lookahead point stays ahead of a vehicle that is close to the end. */
static void point_at(const pursuit_path* path, double s, double* x, double* y) {
  size_t i = 0;
  while (i + 2 < path->count && s > path->s[i + 1]) ++i;
  const double len = path->s[i + 1] - path->s[i];
  const double t = (s - path->s[i]) / len;
  *x = path->x[i] + t * (path->x[i + 1] - path->x[i]);
  *y = path->y[i] + t * (path->y[i + 1] - path->y[i]);
}

pursuit_command pursuit_update(const pursuit_config* config, const pursuit_path* path,
                               pursuit_state* state, double x, double y, double yaw,
                               double forward_speed) {
  pursuit_command out = {0.0, 0.0, 0.0, 0.0, 0.0};
  const size_t segments = path->count - 1;

  /* Progress: the closest point on the current or a later segment (a path that crosses
   * itself is followed in order, never from a later part back to an earlier one). Search a
   * few segments ahead only, so a far-away later part of the path is not taken for a shortcut. */
  double best_d2 = INFINITY, best_s = state->progress_m;
  size_t best_i = state->segment;
  for (size_t i = state->segment; i < segments && i < state->segment + 3; ++i) {
    double t = 0.0;
    const double d2 = project_on_segment(path, i, x, y, &t);
    if (d2 < best_d2) {
      best_d2 = d2;
      best_i = i;
      best_s = path->s[i] + t * (path->s[i + 1] - path->s[i]);
    }
  }
  if (best_s < state->progress_m) best_s = state->progress_m;
  state->segment = best_i;
  state->progress_m = best_s;
  out.lateral_error_m = sqrt(best_d2);

  /* Pure pursuit: steer onto the circle through the lookahead point. */
  const double speed = fabs(forward_speed);
  const double lookahead = config->lookahead_min_m + config->lookahead_gain_s * speed;
  double tx = 0.0, ty = 0.0;
  point_at(path, best_s + lookahead, &tx, &ty);
  const double dx = tx - x, dy = ty - y;
  const double local_x = cos(yaw) * dx + sin(yaw) * dy;
  const double local_y = -sin(yaw) * dx + cos(yaw) * dy;
  const double distance = hypot(local_x, local_y);
  double steer = 0.0;
  if (distance > 1e-6) {
    const double alpha = atan2(local_y, local_x);
    steer = atan2(2.0 * config->wheelbase_m * sin(alpha), distance);
  }
  out.steering = clamp(steer / config->max_steer_rad, -1.0, 1.0);

  /* Speed: cruise, then a constant-deceleration taper to a stop at the end of the path. */
  const double remaining = path->s[path->count - 1] - best_s;
  double target = config->speed_mps;
  if (remaining <= 0.3) {
    target = 0.0;
  } else {
    const double stopping = sqrt(2.0 * config->stop_decel_mps2 * remaining);
    if (stopping < target) target = stopping;
  }
  out.target_speed_mps = target;
  const double u = config->speed_gain * (target - forward_speed);
  if (target == 0.0) {
    out.throttle = 0.0;
    out.braking = 1.0;
  } else if (u >= 0.0) {
    out.throttle = clamp(u, 0.0, 1.0);
  } else {
    out.braking = clamp(-u, 0.0, 1.0);
  }
  return out;
}
