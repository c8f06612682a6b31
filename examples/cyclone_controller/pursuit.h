/* Path following for the CycloneDDS example controller, free of DDS: pure pursuit on the
 * vehicle's pose for steering, and a proportional speed controller whose one signal becomes
 * throttle (positive) or brake (negative). The target speed tapers so that the vehicle stops
 * at the end of the (open) path. Everything is deterministic: same states in, same commands out.
 */
#ifndef SYNDDS_CYCLONE_PURSUIT_H
#define SYNDDS_CYCLONE_PURSUIT_H

#include <stddef.h>

#define PURSUIT_MAX_POINTS 256

typedef struct pursuit_config {
  double speed_mps;          /* cruise speed */
  double lookahead_min_m;    /* lookahead distance at standstill */
  double lookahead_gain_s;   /* lookahead grows by this many seconds of travel */
  double wheelbase_m;        /* axle to axle */
  double max_steer_rad;      /* road-wheel angle at steering = 1 */
  double speed_gain;         /* throttle (or brake) per m/s of speed error */
  double stop_decel_mps2;    /* deceleration planned for stopping at the path's end */
} pursuit_config;

typedef struct pursuit_path {
  size_t count;
  double x[PURSUIT_MAX_POINTS];
  double y[PURSUIT_MAX_POINTS];
  double s[PURSUIT_MAX_POINTS]; /* arc length at each point */
} pursuit_path;

typedef struct pursuit_state {
  size_t segment;       /* segment the vehicle was last projected on (never goes back) */
  double progress_m;    /* arc length of that projection */
} pursuit_state;

typedef struct pursuit_command {
  double steering;      /* [-1, 1], positive left */
  double throttle;      /* [0, 1] */
  double braking;       /* [0, 1] */
  double target_speed_mps;
  double lateral_error_m;
} pursuit_command;

/* Parses "x,y;x,y;..." (at least two points, consecutive points distinct). On error returns
 * 0 and writes a message (without the option name) to `error`. */
int pursuit_parse_waypoints(const char* text, pursuit_path* path, char* error, size_t error_size);

/* Default gains for an HMMWV-sized vehicle. */
pursuit_config pursuit_default_config(void);

void pursuit_reset(pursuit_state* state);

/* One control update from the chassis position (x, y), yaw (rad, ENU, from +x toward +y) and
 * forward speed (m/s). */
pursuit_command pursuit_update(const pursuit_config* config, const pursuit_path* path,
                               pursuit_state* state, double x, double y, double yaw,
                               double forward_speed);

/* Yaw of a unit quaternion (w, x, y, z) about +z. */
double pursuit_yaw(double w, double x, double y, double z);

#endif
