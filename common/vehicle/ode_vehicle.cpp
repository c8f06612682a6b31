#include "vehicle/ode_vehicle.hpp"

#include <ode/ode.h>
#include <ode/threading_impl.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <mutex>
#include <numbers>
#include <stdexcept>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "vehicle/powertrain.hpp"
#include "vehicle/steering.hpp"
#include "vehicle/tire_model.hpp"

static_assert(sizeof(dReal) == 8, "syndds needs ODE built in double precision (dDOUBLE)");

namespace syndds::vehicle {
namespace {

constexpr double kSettleStepS = 0.002;
constexpr double kSteerGainPerStep = 0.5;    // steering motor closes half the error per step
constexpr double kSteerMaxTorqueNm = 2.0e4;
constexpr double kSteerStopMarginRad = 0.05;
constexpr double kObstacleFriction = 0.5;
constexpr double kObstacleSoftCfm = 1e-7;
constexpr double kObstacleSoftErp = 0.2;
constexpr int kMaxContactsPerPair = 4;
// Vehicle against vehicle (body panels, bumpers, tires): friction and the same soft contact
// as obstacles.
constexpr double kVehicleFriction = 0.5;
constexpr double kRollingResistanceSpeedMps = 0.1;  // smooth sign of the resistance moment
constexpr double kBumpStopFactor = 20.0;     // bump stop rate = factor x spring rate (default)

std::once_flag g_ode_init_once;  // ODE's own process-wide initialisation, done once

void ensure_ode_ready() {
  std::call_once(g_ode_init_once, [] { dInitODE2(0); });
  dAllocateODEDataForThread(dAllocateMaskAll);
}

Vec3 vec(const dReal* v) { return Vec3(v[0], v[1], v[2]); }
Quat body_quat(dBodyID b) {
  const dReal* q = dBodyGetQuaternion(b);
  return Quat(q[0], q[1], q[2], q[3]);
}
void set_body_pose(dBodyID b, const Vec3& p, const Quat& q) {
  dBodySetPosition(b, p.x(), p.y(), p.z());
  const dQuaternion dq = {q.w(), q.x(), q.y(), q.z()};
  dBodySetQuaternion(b, dq);
}
void set_geom_pose(dGeomID g, const Vec3& p, const Quat& q) {
  dGeomSetPosition(g, p.x(), p.y(), p.z());
  const dQuaternion dq = {q.w(), q.x(), q.y(), q.z()};
  dGeomSetQuaternion(g, dq);
}
Vec3 point_velocity(dBodyID b, const Vec3& p) {
  dVector3 v;
  dBodyGetPointVel(b, p.x(), p.y(), p.z(), v);
  return vec(v);
}
void add_force_at(dBodyID b, const Vec3& f, const Vec3& p) {
  dBodyAddForceAtPos(b, f.x(), f.y(), f.z(), p.x(), p.y(), p.z());
}
void add_torque(dBodyID b, const Vec3& t) { dBodyAddTorque(b, t.x(), t.y(), t.z()); }

bool finite(const Vec3& v) { return v.allFinite(); }

/// A body's state as ODE holds it (quaternion in ODE's order w, x, y, z), for checkpoints.
struct BodyState {
  Vec3 position = Vec3::Zero();
  Eigen::Vector4d quaternion = Eigen::Vector4d::Zero();
  Vec3 linear_velocity = Vec3::Zero();
  Vec3 angular_velocity = Vec3::Zero();
};

BodyState get_body_state(dBodyID b) {
  const dReal* q = dBodyGetQuaternion(b);
  return {vec(dBodyGetPosition(b)), Eigen::Vector4d(q[0], q[1], q[2], q[3]),
          vec(dBodyGetLinearVel(b)), vec(dBodyGetAngularVel(b))};
}

/// The setter calls of a restore. dBodySetQuaternion normalises its argument again (and
/// computes the rotation matrix from the result), so the body may end up a last bit away from
/// the raw values it was given: save_state passes its own bodies through this very function
/// with the values it wrote, and both runs continue from set(raw).
void set_body_state(dBodyID b, const BodyState& s) {
  dBodySetPosition(b, s.position.x(), s.position.y(), s.position.z());
  const dQuaternion q = {s.quaternion[0], s.quaternion[1], s.quaternion[2], s.quaternion[3]};
  dBodySetQuaternion(b, q);
  dBodySetLinearVel(b, s.linear_velocity.x(), s.linear_velocity.y(), s.linear_velocity.z());
  dBodySetAngularVel(b, s.angular_velocity.x(), s.angular_velocity.y(), s.angular_velocity.z());
}

/// Every param the full model reads (all but the reduced model's, the name and the file):
/// a state is refused by a vehicle whose params differ in any of them.
std::uint64_t full_params_fingerprint(const VehicleParams& p) {
  Fnv1a64 h;
  auto add = [&h](std::initializer_list<double> values) {
    for (double v : values) h.add(v);
  };
  auto add_vec = [&](const Vec3& v) { add({v.x(), v.y(), v.z()}); };
  auto add_map = [&](const std::vector<std::pair<double, double>>& m) {
    h.add(static_cast<std::int64_t>(m.size()));
    for (const auto& [a, b] : m) add({a, b});
  };
  add({p.chassis.mass_kg, p.chassis.drag_area_m2});
  add_vec(p.chassis.inertia_kgm2);
  add_vec(p.chassis.com_m);
  add_vec(p.chassis.half_extents_m);
  add_vec(p.chassis.box_centre_m);
  add({p.wheels.radius_m, p.wheels.width_m, p.wheels.mass_kg, p.wheels.spin_inertia_kgm2});
  for (const AxleParams* a : {&p.front, &p.rear}) {
    add({a->x_m, a->half_track_m, a->spring_rate_npm, a->damping_nspm, a->travel_m, a->preload_n,
         a->bump_stop_rate_npm, a->brake_torque_nm});
    h.add(std::int64_t{a->steered});
    h.add(std::int64_t{a->driven});
  }
  add({p.steering.max_angle_deg, p.steering.rate_deg_s});
  add_map(p.engine.torque_map_rpm_nm);
  add({p.engine.idle_rpm, p.engine.max_rpm, p.engine.inertia_kgm2, p.engine.motoring_torque_nm});
  const TransmissionParams& t = p.transmission;
  h.add(static_cast<std::int64_t>(t.forward_ratios.size()));
  for (double r : t.forward_ratios) h.add(r);
  add({t.reverse_ratio, t.upshift_rpm, t.downshift_rpm, t.shift_time_s,
       t.ingear_shaft_inertia_kgm2});
  add_map(t.converter_capacity_map);
  add_map(t.converter_torque_ratio_map);
  const DrivelineParams& d = p.driveline;
  add({d.final_drive_ratio, d.front_torque_share, d.driveshaft_inertia_kgm2,
       d.axle_differential_bias, d.centre_differential_bias});
  const TireParams& tp = p.tire;
  add({tp.friction_scale, tp.longitudinal_stiffness, tp.cornering_stiffness, tp.nominal_load_n,
       tp.vertical_stiffness_npm, tp.vertical_damping_nspm, tp.rolling_resistance,
       tp.relaxation_length_m, tp.stiffness_load_exponent});
  return h.value();
}

}  // namespace

namespace {
// One field list of a wheel's diagnostics for saving (D const) and loading.
template <typename Archive, typename D>
void diagnostics_fields(Archive& a, D& d) {
  a.io(d.suspension_compression_m);
  a.io(d.spring_force_n);
  a.io(d.tire_normal_force_n);
  a.io(d.tire_deflection_m);
  a.io(d.slip_ratio);
  a.io(d.slip_angle_rad);
  a.io(d.drive_torque_nm);
  a.io(d.in_contact);
}
}  // namespace

struct OdeVehicleModel::Impl {
  struct ObstacleGeom {
    std::string id;
    dGeomID geom = nullptr;
    Vec3 centre = Vec3::Zero();
    double radius = 0.0;               // bounding sphere
    double last_contact_s = -std::numeric_limits<double>::infinity();
    bool episode_open = false;         // a collision episode with this obstacle is running
  };
  struct PendingContact {
    dContact contact;
    std::size_t obstacle = 0;          // obstacles.size() + k: proxies[k]
    dBodyID body = nullptr;
    dBodyID other = nullptr;           // a proxy's body, or none (static obstacle)
    double relative_speed = 0.0;       // proxies: contact point speeds apart before the step
  };
  /// Another vehicle as a rigid body of its whole mass in this world, rebuilt at every
  /// set_peers from the state the frame contract gives (no gravity, no ground, no engine: it
  /// moves on with its velocities and the reactions of this vehicle's contact forces).
  struct Proxy {
    std::string id;
    dBodyID body = nullptr;
    dGeomID chassis = nullptr;
    std::array<dGeomID, 4> wheels{};
    double radius = 0.0;               // bounding sphere about the body origin
  };
  struct PeerEpisode {
    double last_contact_s = -std::numeric_limits<double>::infinity();
    bool open = false;
  };

  VehicleParams p;
  std::shared_ptr<const terrain::TerrainSurface> terrain;
  std::shared_ptr<terrain::WheelTerrainContact> deformable;
  TireModel tire;
  Powertrain powertrain;

  dWorldID world = nullptr;
  // ODE's default stepping threading implementation is one process-wide object: worlds stepped
  // from several threads at once (single-process runs, in-process tests) corrupt it and abort.
  // Each world gets its own self-threaded implementation.
  dThreadingImplementationID threading = nullptr;
  dJointGroupID contact_group = nullptr;
  dBodyID chassis = nullptr;
  std::array<dBodyID, 4> wheels{};
  std::array<dJointID, 4> joints{};
  dGeomID chassis_geom = nullptr;
  std::array<dGeomID, 4> wheel_geoms{};
  std::vector<ObstacleGeom> obstacles;
  std::vector<Proxy> proxies;                      // sorted by id
  std::map<std::string, PeerEpisode> peer_episodes;
  std::vector<PendingContact> contacts;
  std::vector<dJointFeedback> feedback;
  double vehicle_radius = 0.0;         // bounding sphere about the chassis COM

  std::array<Vec3, 4> wheel_local;     // design wheel centres in the chassis reference frame
  std::array<const AxleParams*, 4> axle{};
  std::array<double, 4> preload{};
  double load_scale = 1.0;               // gravity and preloads (ramped while settling)
  double front_share = 0.0;              // centre differential: front axle's torque share
  std::array<double, 4> drive_share{};   // nominal share of the driveline torque per wheel
  double driveline_inertia = -1.0;       // reflected inertia currently on the wheels
  std::array<TireState, 4> tire_states{};
  std::array<WheelDiagnostics, 4> diag{};

  DriverInputs commanded;
  DriverInputs applied;
  double time = 0.0;
  double last_dt = -1.0;
  Vec3 accel = Vec3::Zero();
  Vec3 angular_accel = Vec3::Zero();
  Vec3 step_v0 = Vec3::Zero();           // begin_step -> end_step only
  Vec3 step_w0 = Vec3::Zero();
  std::vector<CollisionContact> collisions;
  bool owns_world = true;                // false: a second vehicle in another's world (pair)

  // Checked by load_state: the bodies' poses as placed at the start (they fix the hinge-2
  // frames, which ODE keeps relative to the bodies: a vehicle placed elsewhere or on other
  // ground differs from this one in the last bits forever), and the obstacles.
  std::uint64_t placement_fingerprint = 0;
  std::uint64_t obstacles_fingerprint = 0;

  Impl(const VehicleParams& params, std::shared_ptr<const terrain::TerrainSurface> t,
       std::shared_ptr<terrain::WheelTerrainContact> d)
      : p(params),
        terrain(std::move(t)),
        deformable(std::move(d)),
        tire(params.tire, params.wheels),
        powertrain(params) {}

  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  ~Impl() {
    clear_proxies();
    for (auto& o : obstacles) dGeomDestroy(o.geom);
    for (auto g : wheel_geoms) {
      if (g) dGeomDestroy(g);
    }
    if (chassis_geom) dGeomDestroy(chassis_geom);
    if (contact_group) dJointGroupDestroy(contact_group);
    if (world && owns_world) {
      dWorldSetStepThreadingImplementation(world, nullptr, nullptr);
      dWorldDestroy(world);  // bodies and joints with it
    } else if (world) {
      for (dJointID j : joints) {
        if (j) dJointDestroy(j);
      }
      for (dBodyID b : bodies()) {
        if (b) dBodyDestroy(b);
      }
    }
    if (threading) dThreadingFreeImplementation(threading);
  }

  void clear_proxies() {
    for (Proxy& x : proxies) {
      for (dGeomID g : x.wheels) dGeomDestroy(g);
      dGeomDestroy(x.chassis);
      dBodyDestroy(x.body);
    }
    proxies.clear();
  }

  // --- construction ------------------------------------------------------------------------

  void build(const Pose& start, const world::Obstacles& obstacle_list,
             dWorldID shared_world = nullptr) {
    if (shared_world) {
      world = shared_world;
      owns_world = false;
    } else {
      world = dWorldCreate();
      threading = dThreadingAllocateSelfThreadedImplementation();
      dWorldSetStepThreadingImplementation(world, dThreadingImplementationGetFunctions(threading),
                                           threading);
      dWorldSetGravity(world, 0, 0, -kGravity);
      dWorldSetERP(world, 0.2);
      dWorldSetCFM(world, 1e-10);
      dWorldSetAutoDisableFlag(world, 0);
      dWorldSetContactMaxCorrectingVel(world, 1.0);
      dWorldSetContactSurfaceLayer(world, 0.001);
    }
    contact_group = dJointGroupCreate(0);

    const AxleParams* axles[4] = {&p.front, &p.front, &p.rear, &p.rear};
    const double sides[4] = {1.0, -1.0, 1.0, -1.0};
    for (int i = 0; i < 4; ++i) {
      axle[i] = axles[i];
      wheel_local[i] = Vec3(axles[i]->x_m, sides[i] * axles[i]->half_track_m, 0.0);
      const double static_load = p.static_wheel_load_n(i < 2);
      preload[i] = axles[i]->preload_n >= 0 ? axles[i]->preload_n
                                            : static_load - p.wheels.mass_kg * kGravity;
    }

    chassis = dBodyCreate(world);
    dMass m;
    const Vec3& ic = p.chassis.inertia_kgm2;
    dMassSetParameters(&m, p.chassis.mass_kg, 0, 0, 0, ic.x(), ic.y(), ic.z(), 0, 0, 0);
    dBodySetMass(chassis, &m);
    front_share = p.front.driven ? (p.rear.driven ? p.driveline.front_torque_share : 1.0) : 0.0;
    for (int i = 0; i < 4; ++i) {
      drive_share[i] = 0.5 * (i < 2 ? front_share : 1.0 - front_share);
      wheels[i] = dBodyCreate(world);
    }
    set_wheel_inertia();

    place(start);
    Fnv1a64 placed;
    for (dBodyID b : bodies()) {
      const BodyState st = get_body_state(b);
      placed.add_bytes(st.position.data(), sizeof(double) * 3);
      placed.add_bytes(st.quaternion.data(), sizeof(double) * 4);
    }
    placement_fingerprint = placed.value();
    for (int i = 0; i < 4; ++i) make_joint(i);
    make_geoms();
    Fnv1a64 obstacles_hash;
    for (const auto& o : obstacle_list) {
      add_obstacle(o);
      obstacles_hash.add(o.id);
      obstacles_hash.add(static_cast<std::int64_t>(o.shape));
      obstacles_hash.add_bytes(o.size.data(), sizeof(double) * 3);
      obstacles_hash.add_bytes(o.pose.position.data(), sizeof(double) * 3);
      obstacles_hash.add_bytes(o.pose.orientation.coeffs().data(), sizeof(double) * 4);
    }
    obstacles_fingerprint = obstacles_hash.value();
  }

  std::array<dBodyID, 5> bodies() const {
    return {chassis, wheels[0], wheels[1], wheels[2], wheels[3]};
  }

  /// Wheel masses with the driveline inertia of the current gear: the in-gear and drive
  /// shafts turn with the wheels through the differentials. Their inertia J (at the
  /// differentials' input, wheel units) is a rank-one coupling J c c^T of the wheel spins
  /// (c the torque shares); each wheel gets its share c_i J on its spin inertia, which is exact
  /// when the driven wheels accelerate alike (an explicit coupling torque would be unstable:
  /// in first gear J is about 7 times the wheels' own inertia). Re-set on gear changes only.
  void set_wheel_inertia() {
    const double j = powertrain.driveline_inertia_at_wheels();
    if (j == driveline_inertia) return;
    driveline_inertia = j;
    const double r = p.wheels.radius_m;
    const double w = p.wheels.width_m;
    const double i_tilt = p.wheels.mass_kg * (3.0 * r * r + w * w) / 12.0;
    for (int i = 0; i < 4; ++i) {
      dMass m;
      dMassSetParameters(&m, p.wheels.mass_kg, 0, 0, 0, i_tilt,
                         p.wheels.spin_inertia_kgm2 + drive_share[i] * j, i_tilt, 0, 0, 0);
      dBodySetMass(wheels[i], &m);
    }
  }

  /// Puts the chassis at start (x, y, yaw) on the terrain: the chassis plane fits the ground
  /// under the four wheels, each tire at its static deflection, suspension at design height.
  void place(const Pose& start) {
    const double yaw = yaw_of(start.orientation);
    const Quat q_yaw = quat_from_yaw(yaw);
    const Vec3 origin(start.position.x(), start.position.y(), 0.0);
    Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (int i = 0; i < 4; ++i) {
      const Vec3 xy = origin + q_yaw * Vec3(wheel_local[i].x(), wheel_local[i].y(), 0.0);
      const double h = terrain->height(xy.x(), xy.y());
      const Eigen::Vector3d row(1.0, wheel_local[i].x(), wheel_local[i].y());
      a += row * row.transpose();
      b += row * h;
    }
    const Eigen::Vector3d plane = a.ldlt().solve(b);  // h = c0 + gx X + gy Y (vehicle axes)
    const Vec3 normal = (q_yaw * Vec3(-plane[1], -plane[2], 1.0)).normalized();
    const Vec3 forward = q_yaw * Vec3::UnitX();
    const Vec3 x_axis = (forward - forward.dot(normal) * normal).normalized();
    Eigen::Matrix3d rot;
    rot.col(0) = x_axis;
    rot.col(1) = normal.cross(x_axis);
    rot.col(2) = normal;
    const Quat qc(rot);
    const double deflection =
        0.5 * (p.static_wheel_load_n(true) + p.static_wheel_load_n(false)) /
        p.tire.vertical_stiffness_npm;
    const Vec3 ref(origin.x(), origin.y(),
                   plane[0] + (p.wheels.radius_m - deflection) / normal.z());
    set_body_pose(chassis, ref + qc * p.chassis.com_m, qc);
    for (int i = 0; i < 4; ++i) set_body_pose(wheels[i], ref + qc * wheel_local[i], qc);
  }

  void make_joint(int i) {
    dJointID j = dJointCreateHinge2(world, nullptr);
    dJointAttach(j, chassis, wheels[i]);
    const Vec3 c = vec(dBodyGetPosition(wheels[i]));
    dJointSetHinge2Anchor(j, c.x(), c.y(), c.z());
    const Quat qc = body_quat(chassis);
    const Vec3 up = qc * Vec3::UnitZ();
    const Vec3 left = qc * Vec3::UnitY();
    const dReal axis1[3] = {up.x(), up.y(), up.z()};
    const dReal axis2[3] = {left.x(), left.y(), left.z()};
    dJointSetHinge2Axes(j, axis1, axis2);
    if (axle[i]->steered) {
      const double lim = deg_to_rad(p.steering.max_angle_deg) + kSteerStopMarginRad;
      dJointSetHinge2Param(j, dParamLoStop, -lim);
      dJointSetHinge2Param(j, dParamHiStop, lim);
      dJointSetHinge2Param(j, dParamFMax, kSteerMaxTorqueNm);
      dJointSetHinge2Param(j, dParamVel, 0.0);
    } else {
      dJointSetHinge2Param(j, dParamLoStop, 0.0);
      dJointSetHinge2Param(j, dParamHiStop, 0.0);
    }
    dJointSetHinge2Param(j, dParamVel2, 0.0);
    dJointSetHinge2Param(j, dParamFMax2, 0.0);
    joints[i] = j;
  }

  void make_geoms() {
    const Vec3 he = p.chassis.half_extents_m;
    chassis_geom = dCreateBox(nullptr, 2 * he.x(), 2 * he.y(), 2 * he.z());
    dGeomSetBody(chassis_geom, chassis);
    const Vec3 off = p.chassis.box_centre_m - p.chassis.com_m;
    dGeomSetOffsetPosition(chassis_geom, off.x(), off.y(), off.z());
    vehicle_radius = off.norm() + he.norm();
    // Cylinder axis (local z) turned onto the wheel's spin axis (local y).
    const Quat z_to_y(Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitX()));
    const dQuaternion dq = {z_to_y.w(), z_to_y.x(), z_to_y.y(), z_to_y.z()};
    for (int i = 0; i < 4; ++i) {
      wheel_geoms[i] = dCreateCylinder(nullptr, p.wheels.radius_m, p.wheels.width_m);
      dGeomSetBody(wheel_geoms[i], wheels[i]);
      dGeomSetOffsetQuaternion(wheel_geoms[i], dq);
      const double reach = (wheel_local[i] - p.chassis.com_m).norm() + axle[i]->travel_m +
                           std::hypot(p.wheels.radius_m, 0.5 * p.wheels.width_m);
      vehicle_radius = std::max(vehicle_radius, reach);
    }
  }

  void add_obstacle(const world::Obstacle& o) {
    ObstacleGeom g;
    g.id = o.id;
    const Vec3& s = o.size;
    auto positive = [&](double v) {
      if (!(v > 0.0) || !std::isfinite(v)) {
        throw ConfigError("obstacle '" + o.id + "': sizes must be positive and finite");
      }
      return v;
    };
    switch (o.shape) {
      case world::ShapeKind::box:
        g.geom = dCreateBox(nullptr, 2 * positive(s.x()), 2 * positive(s.y()), 2 * positive(s.z()));
        g.radius = s.norm();
        break;
      case world::ShapeKind::sphere:
        g.geom = dCreateSphere(nullptr, positive(s.x()));
        g.radius = s.x();
        break;
      case world::ShapeKind::cylinder:
        g.geom = dCreateCylinder(nullptr, positive(s.x()), 2 * positive(s.z()));
        g.radius = std::hypot(s.x(), s.z());
        break;
    }
    set_geom_pose(g.geom, o.pose.position, o.pose.orientation.normalized());
    g.centre = o.pose.position;
    obstacles.push_back(std::move(g));
  }

  void set_load_scale(double scale) {
    load_scale = scale;
    dWorldSetGravity(world, 0, 0, -kGravity * scale);
  }

  void settle() {
    commanded = DriverInputs{0.0, 0.0, 1.0};
    applied = commanded;
    // Quasi-static: gravity and the suspension preloads ramp up over kSettleRampS, then hold.
    // A vehicle dropped at full weight overshoots its static sinkage, and soil keeps the
    // deepest plastic sinkage it saw: on soft soil the pits came out 12 % deeper than the
    // static (Bekker) equilibrium.
    const int steps = static_cast<int>(std::lround(kSettleTimeS / kSettleStepS));
    for (int n = 0; n < steps; ++n) {
      set_load_scale(std::min(1.0, (n + 1) * kSettleStepS / kSettleRampS));
      step(kSettleStepS, false);
    }
    set_load_scale(1.0);
    for (dBodyID b : {chassis, wheels[0], wheels[1], wheels[2], wheels[3]}) {
      dBodySetLinearVel(b, 0, 0, 0);
      dBodySetAngularVel(b, 0, 0, 0);
    }
    powertrain.reset();
    set_wheel_inertia();
    commanded = DriverInputs{};
    applied = commanded;
    time = 0.0;
    accel.setZero();
    angular_accel.setZero();
    collisions.clear();
    peer_episodes.clear();
    for (auto& o : obstacles) {
      o.last_contact_s = -std::numeric_limits<double>::infinity();
      o.episode_open = false;
    }
  }

  // --- state helpers -----------------------------------------------------------------------

  Vec3 reference_point() const {
    return vec(dBodyGetPosition(chassis)) - body_quat(chassis) * p.chassis.com_m;
  }
  Vec3 spin_axis(int i) const { return body_quat(wheels[i]) * Vec3::UnitY(); }
  /// Wheel spin relative to the chassis about its axle (positive rolls forward).
  double relative_spin(int i) const {
    const Vec3 w = vec(dBodyGetAngularVel(wheels[i])) - vec(dBodyGetAngularVel(chassis));
    return w.dot(spin_axis(i));
  }
  /// Road-wheel angle from the geometry (positive = turned left).
  double steer_angle(int i) const {
    const Vec3 y = body_quat(chassis).conjugate() * spin_axis(i);
    return std::atan2(-y.x(), y.y());
  }

  // --- one step ----------------------------------------------------------------------------

  void set_step_size(double dt) {
    if (dt == last_dt) return;
    for (int i = 0; i < 4; ++i) {
      // Implicit spring-damper of the hinge-2 suspension axis: k = ERP/(h CFM), c = (1-ERP)/CFM.
      const double hk = dt * axle[i]->spring_rate_npm;
      const double denom = hk + axle[i]->damping_nspm;
      dJointSetHinge2Param(joints[i], dParamSuspensionERP, hk / denom);
      dJointSetHinge2Param(joints[i], dParamSuspensionCFM, 1.0 / denom);
    }
    last_dt = dt;
  }

  void apply_steering_and_brakes(double dt) {
    double s = commanded.steering;
    if (p.steering.rate_deg_s > 0.0) {
      const double max_change = p.steering.rate_deg_s / p.steering.max_angle_deg * dt;
      s = applied.steering + clamp(s - applied.steering, -max_change, max_change);
    }
    applied = DriverInputs{s, commanded.throttle, commanded.braking};
    const AckermannAngles angles = ackermann_angles(p, applied.steering);
    for (int i = 0; i < 4; ++i) {
      if (axle[i]->steered) {
        const double target = (i % 2 == 0) ? angles.left_rad : angles.right_rad;
        // ODE's hinge-2 motor drives body 1 relative to body 2: the wheel turns the other way.
        const double rate = kSteerGainPerStep * (target - steer_angle(i)) / dt;
        dJointSetHinge2Param(joints[i], dParamVel, -rate);
      }
      dJointSetHinge2Param(joints[i], dParamFMax2, applied.braking * axle[i]->brake_torque_nm);
    }
  }

  /// A Torsen-type differential (Chrono's simple driveline model): torque splits as `share` :
  /// 1 - share while the two outputs turn alike; as their speeds part by 0.25 to 0.5 rad/s the
  /// slower output's share is weighted by a bias growing linearly from 1 to `max_bias`
  /// (1: an open differential, torque split fixed). Returns (first, second).
  static std::pair<double, double> torsen_split(double torque, double share, double w_first,
                                                double w_second, double max_bias) {
    if (share <= 0.0 || share >= 1.0) return {share * torque, (1.0 - share) * torque};
    const double parted = std::abs(w_first - w_second);
    const double bias = 1.0 + (max_bias - 1.0) * clamp((parted - 0.25) / 0.25, 0.0, 1.0);
    const bool first_slower = std::abs(w_first) < std::abs(w_second);
    const double weight_first = first_slower ? bias * share : share;
    const double weight_second = first_slower ? 1.0 - share : bias * (1.0 - share);
    const double first = torque * weight_first / (weight_first + weight_second);
    return {first, torque - first};
  }

  void apply_drive_torque(double dt) {
    std::array<double, 4> spin{};
    for (int i = 0; i < 4; ++i) spin[i] = relative_spin(i);
    // Differential kinematics: the centre input turns at the torque-weighted mean of the axles.
    const double w_front = 0.5 * (spin[0] + spin[1]);
    const double w_rear = 0.5 * (spin[2] + spin[3]);
    const double w_in = front_share * w_front + (1.0 - front_share) * w_rear;
    const Quat qc = body_quat(chassis);
    const double v_forward = vec(dBodyGetLinearVel(chassis)).dot(qc * Vec3::UnitX());
    const double torque = powertrain.step(applied.throttle, w_in, v_forward, dt);
    set_wheel_inertia();
    std::array<double, 4> wheel_torque{};
    const auto [front_torque, rear_torque] =
        torsen_split(torque, front_share, w_front, w_rear, p.driveline.centre_differential_bias);
    for (int axle_index : {0, 2}) {
      const double axle_torque = axle_index == 0 ? front_torque : rear_torque;
      const auto [left, right] = torsen_split(axle_torque, 0.5, spin[axle_index],
                                              spin[axle_index + 1],
                                              p.driveline.axle_differential_bias);
      wheel_torque[axle_index] = left;
      wheel_torque[axle_index + 1] = right;
    }
    for (int i = 0; i < 4; ++i) {
      const double t = wheel_torque[i];
      diag[i].drive_torque_nm = t;
      if (t == 0.0) continue;
      const Vec3 axis = spin_axis(i);
      add_torque(wheels[i], t * axis);
      add_torque(chassis, -t * axis);
    }
  }

  void apply_tire_forces(double dt) {
    const double r = p.wheels.radius_m;
    for (int i = 0; i < 4; ++i) {
      WheelDiagnostics& d = diag[i];
      d.in_contact = false;
      d.tire_normal_force_n = d.tire_deflection_m = d.slip_ratio = d.slip_angle_rad = 0.0;
      const Vec3 c = vec(dBodyGetPosition(wheels[i]));
      const Vec3 a = spin_axis(i);
      const Vec3 n0 = terrain->normal(c.x(), c.y());
      Vec3 down = -(n0 - n0.dot(a) * a);
      if (down.norm() < 1e-6) {  // wheel lying flat: no rolling contact
        tire_states[i] = TireState{};
        continue;
      }
      down.normalize();
      const Vec3 lowest = c + r * down;
      const double h = terrain->height(lowest.x(), lowest.y());
      const Vec3 n = terrain->normal(lowest.x(), lowest.y());
      const double depth = std::min((h - lowest.z()) * n.z(), 0.9 * r);
      if (depth <= 0.0) {
        tire_states[i] = TireState{};
        continue;
      }
      const Vec3 v = vec(dBodyGetLinearVel(wheels[i]));
      const Vec3 w = vec(dBodyGetAngularVel(wheels[i]));
      const double fz = tire.normal_force(depth, -v.dot(n));
      const Vec3 contact = lowest + depth * n;
      Vec3 ex = a.cross(n);
      if (ex.norm() < 1e-6) {
        tire_states[i] = TireState{};
        continue;
      }
      ex.normalize();
      const Vec3 ey = n.cross(ex);
      // Slip at the effective rolling radius r - deflection/3.
      const Vec3 arm = (contact - c) * ((r - depth / 3.0) / (r - depth));
      const Vec3 vc = v + w.cross(arm);
      TireKinematics k;
      k.normal_force_n = fz;
      k.ground_speed_mps = v.dot(ex);
      k.slip_velocity_x_mps = vc.dot(ex);
      k.slip_velocity_y_mps = vc.dot(ey);
      k.friction = terrain->friction(contact.x(), contact.y()) * p.tire.friction_scale;
      const TireForce f = tire.update(k, dt, tire_states[i]);
      add_force_at(wheels[i], fz * n + f.fx_n * ex + f.fy_n * ey, contact);
      // Rolling resistance: a moment against the spin, smoothed through zero speed.
      const double spin_speed = w.dot(a) * r;
      const double moment = -p.tire.rolling_resistance * fz * (r - depth) *
                            clamp(spin_speed / kRollingResistanceSpeedMps, -1.0, 1.0);
      add_torque(wheels[i], moment * a);
      d.in_contact = fz > 0.0;
      d.tire_normal_force_n = fz;
      d.tire_deflection_m = depth;
      d.slip_ratio = f.slip_ratio;
      d.slip_angle_rad = f.slip_angle_rad;
    }
  }

  void apply_deformable_forces(double dt) {
    std::array<terrain::WheelBodyState, 4> states;
    std::array<terrain::WheelLoad, 4> loads{};
    for (int i = 0; i < 4; ++i) {
      states[i].pose.position = vec(dBodyGetPosition(wheels[i]));
      states[i].pose.orientation = body_quat(wheels[i]);
      states[i].linear_velocity = vec(dBodyGetLinearVel(wheels[i]));
      states[i].angular_velocity = vec(dBodyGetAngularVel(wheels[i]));
      states[i].radius_m = p.wheels.radius_m;
      states[i].width_m = p.wheels.width_m;
    }
    deformable->compute_wheel_loads(states, dt, loads);
    for (int i = 0; i < 4; ++i) {
      const auto& l = loads[i];
      if (!finite(l.force) || !finite(l.torque)) {
        throw std::runtime_error("deformable terrain returned a non-finite wheel load");
      }
      dBodyAddForce(wheels[i], l.force.x(), l.force.y(), l.force.z());
      add_torque(wheels[i], l.torque);
      diag[i].in_contact = l.in_contact;
      diag[i].tire_normal_force_n = l.force.z();
      diag[i].tire_deflection_m = l.sinkage_m;
      diag[i].slip_ratio = diag[i].slip_angle_rad = 0.0;
    }
  }

  void apply_suspension_forces() {
    for (int i = 0; i < 4; ++i) {
      dVector3 a1, a2, ax;
      dJointGetHinge2Anchor(joints[i], a1);
      dJointGetHinge2Anchor2(joints[i], a2);
      dJointGetHinge2Axis1(joints[i], ax);
      const Vec3 p1 = vec(a1), p2 = vec(a2), axis = vec(ax);
      const double s = (p2 - p1).dot(axis);  // compression from design height
      const double s_dot = (point_velocity(wheels[i], p2) - point_velocity(chassis, p1)).dot(axis);
      const AxleParams& ax_p = *axle[i];
      const double half_travel = 0.5 * ax_p.travel_m;
      const double k_stop = ax_p.bump_stop_rate_npm > 0 ? ax_p.bump_stop_rate_npm
                                                        : kBumpStopFactor * ax_p.spring_rate_npm;
      const double c_stop = std::sqrt(k_stop * p.wheels.mass_kg);  // damping ratio 0.5
      double stop = 0.0;
      if (s > half_travel) stop = std::max(0.0, k_stop * (s - half_travel) + c_stop * s_dot);
      if (s < -half_travel) stop = std::min(0.0, k_stop * (s + half_travel) + c_stop * s_dot);
      const double push = load_scale * preload[i] + stop;  // wheel down, chassis up
      dBodyAddForce(wheels[i], -push * axis.x(), -push * axis.y(), -push * axis.z());
      add_force_at(chassis, push * axis, p1);
      diag[i].suspension_compression_m = s;
      diag[i].spring_force_n = push + ax_p.spring_rate_npm * s + ax_p.damping_nspm * s_dot;
    }
  }

  void apply_aero_drag() {
    if (p.chassis.drag_area_m2 <= 0.0) return;
    const Vec3 v = vec(dBodyGetLinearVel(chassis));
    const Vec3 f = -0.5 * kAirDensity * p.chassis.drag_area_m2 * v.norm() * v;
    dBodyAddForce(chassis, f.x(), f.y(), f.z());
  }

  /// A soft contact (the obstacles' ERP and CFM) with friction `mu` between `body` and
  /// `other` (null: the static world), tagged with the obstacle or proxy it belongs to.
  static PendingContact pending_contact(const dContactGeom& geom, double mu, std::size_t tag,
                                        dBodyID body, dBodyID other) {
    PendingContact pc;
    pc.contact = dContact{};
    pc.contact.geom = geom;
    pc.contact.surface.mode = dContactApprox1 | dContactSoftERP | dContactSoftCFM;
    pc.contact.surface.mu = mu;
    pc.contact.surface.soft_erp = kObstacleSoftErp;
    pc.contact.surface.soft_cfm = kObstacleSoftCfm;
    pc.obstacle = tag;
    pc.body = body;
    pc.other = other;
    return pc;
  }

  void find_obstacle_contacts() {
    contacts.clear();
    if (obstacles.empty()) return;
    const Vec3 centre = vec(dBodyGetPosition(chassis));
    const dGeomID geoms[5] = {chassis_geom, wheel_geoms[0], wheel_geoms[1], wheel_geoms[2],
                              wheel_geoms[3]};
    for (std::size_t o = 0; o < obstacles.size(); ++o) {
      auto& ob = obstacles[o];
      if ((ob.centre - centre).norm() > ob.radius + vehicle_radius) {
        // Out of reach: an episode ends once the vehicle has also been free of it for a while.
        if (ob.episode_open && time - ob.last_contact_s > kEpisodeGapS) ob.episode_open = false;
        continue;
      }
      for (dGeomID g : geoms) {
        dContactGeom cg[kMaxContactsPerPair];
        const int n = dCollide(g, ob.geom, kMaxContactsPerPair, cg, sizeof(dContactGeom));
        for (int k = 0; k < n; ++k) {
          contacts.push_back(pending_contact(cg[k], kObstacleFriction, o, dGeomGetBody(g), nullptr));
        }
      }
    }
  }

  /// One contact joint per pending contact (obstacles' and proxies'), with force feedback.
  void create_contact_joints() {
    feedback.assign(contacts.size(), dJointFeedback{});
    for (std::size_t k = 0; k < contacts.size(); ++k) {
      dJointID j = dJointCreateContact(world, contact_group, &contacts[k].contact);
      dJointAttach(j, contacts[k].body, contacts[k].other);
      dJointSetFeedback(j, &feedback[k]);
    }
  }

  std::array<dGeomID, 5> own_geoms() const {
    return {chassis_geom, wheel_geoms[0], wheel_geoms[1], wheel_geoms[2], wheel_geoms[3]};
  }

  /// Contacts between this vehicle's geoms and `other_geoms` (bodies `other`, or static),
  /// tagged `tag`, appended to `out`.
  void collide_with(const std::array<dGeomID, 5>& other_geoms, std::size_t tag,
                    std::vector<PendingContact>& out) const {
    bool first = true;
    // Geom pairs whose bounding boxes do not meet are skipped (dCollide tests no bounds).
    std::array<std::array<dReal, 6>, 5> own_box, other_box;
    const auto own = own_geoms();
    for (std::size_t k = 0; k < 5; ++k) {
      dGeomGetAABB(own[k], own_box[k].data());
      dGeomGetAABB(other_geoms[k], other_box[k].data());
    }
    auto apart = [](const std::array<dReal, 6>& a, const std::array<dReal, 6>& b) {
      return a[1] < b[0] || b[1] < a[0] || a[3] < b[2] || b[3] < a[2] || a[5] < b[4] ||
             b[5] < a[4];
    };
    for (std::size_t gi = 0; gi < 5; ++gi) {
      const dGeomID g = own[gi];
      for (std::size_t hi = 0; hi < 5; ++hi) {
        const dGeomID h = other_geoms[hi];
        if (apart(own_box[gi], other_box[hi])) continue;
        dContactGeom cg[kMaxContactsPerPair];
        const int n = dCollide(g, h, kMaxContactsPerPair, cg, sizeof(dContactGeom));
        for (int k = 0; k < n; ++k) {
          PendingContact pc =
              pending_contact(cg[k], kVehicleFriction, tag, dGeomGetBody(g), dGeomGetBody(h));
          if (first) {
            dVector3 va, vb;
            dBodyGetPointVel(pc.body, cg[k].pos[0], cg[k].pos[1], cg[k].pos[2], va);
            dBodyGetPointVel(pc.other, cg[k].pos[0], cg[k].pos[1], cg[k].pos[2], vb);
            pc.relative_speed = (vec(va) - vec(vb)).norm();
            first = false;
          }
          out.push_back(pc);
        }
      }
    }
  }

  void find_proxy_contacts() {
    if (proxies.empty()) return;
    const Vec3 centre = vec(dBodyGetPosition(chassis));
    for (std::size_t k = 0; k < proxies.size(); ++k) {
      const Proxy& x = proxies[k];
      if ((vec(dBodyGetPosition(x.body)) - centre).norm() > x.radius + vehicle_radius) continue;
      collide_with({x.chassis, x.wheels[0], x.wheels[1], x.wheels[2], x.wheels[3]},
                   obstacles.size() + k, contacts);
    }
  }

  /// Rebuilds the proxies, in id order (so the world holds the same bodies in the same order
  /// whatever came before: a model restored from a checkpoint steps the same numbers).
  void set_peers(const std::vector<PeerVehicle>& peers) {
    clear_proxies();
    const Quat z_to_y(Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitX()));
    for (const PeerVehicle& peer : peers) {
      if (!peer.params) throw std::invalid_argument("peer vehicle '" + peer.id + "' has no params");
      const VehicleParams& q = *peer.params;
      // Rigid body of the whole vehicle: chassis plus wheels at their design positions.
      std::array<Vec3, 4> wheel_design;
      const AxleParams* axles[4] = {&q.front, &q.front, &q.rear, &q.rear};
      const double sides[4] = {1.0, -1.0, 1.0, -1.0};
      const double total = q.total_mass_kg();
      Vec3 com = q.chassis.mass_kg * q.chassis.com_m;
      for (int i = 0; i < 4; ++i) {
        wheel_design[i] = Vec3(axles[i]->x_m, sides[i] * axles[i]->half_track_m, 0.0);
        com += q.wheels.mass_kg * wheel_design[i];
      }
      com /= total;
      Eigen::Matrix3d inertia = q.chassis.inertia_kgm2.asDiagonal();
      auto parallel_axis = [&](double m, const Vec3& d) {
        inertia += m * (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose());
      };
      parallel_axis(q.chassis.mass_kg, q.chassis.com_m - com);
      for (const Vec3& w : wheel_design) parallel_axis(q.wheels.mass_kg, w - com);

      Proxy x;
      x.id = peer.id;
      x.body = dBodyCreate(world);
      dMass m;
      dMassSetParameters(&m, total, 0, 0, 0, inertia(0, 0), inertia(1, 1), inertia(2, 2),
                         inertia(0, 1), inertia(0, 2), inertia(1, 2));
      dBodySetMass(x.body, &m);
      dBodySetGravityMode(x.body, 0);
      const Quat qc = peer.pose.orientation.normalized();
      const Vec3 origin = peer.pose.position + qc * com;
      set_body_pose(x.body, origin, qc);
      const Vec3 v = peer.linear_velocity + peer.angular_velocity.cross(qc * com);
      dBodySetLinearVel(x.body, v.x(), v.y(), v.z());
      dBodySetAngularVel(x.body, peer.angular_velocity.x(), peer.angular_velocity.y(),
                         peer.angular_velocity.z());

      const Vec3 he = q.chassis.half_extents_m;
      x.chassis = dCreateBox(nullptr, 2 * he.x(), 2 * he.y(), 2 * he.z());
      dGeomSetBody(x.chassis, x.body);
      const Vec3 box_off = q.chassis.box_centre_m - com;
      dGeomSetOffsetPosition(x.chassis, box_off.x(), box_off.y(), box_off.z());
      x.radius = box_off.norm() + he.norm();
      const double wheel_reach = std::hypot(q.wheels.radius_m, 0.5 * q.wheels.width_m);
      for (int i = 0; i < 4; ++i) {
        Vec3 local = wheel_design[i] - com;
        Quat turn = Quat::Identity();
        if (peer.wheels.size() == 4) {
          const Pose& w = peer.wheels[static_cast<std::size_t>(i)];
          local = qc.conjugate() * (w.position - origin);
          turn = qc.conjugate() * w.orientation.normalized();
        }
        x.wheels[i] = dCreateCylinder(nullptr, q.wheels.radius_m, q.wheels.width_m);
        dGeomSetBody(x.wheels[i], x.body);
        dGeomSetOffsetPosition(x.wheels[i], local.x(), local.y(), local.z());
        const Quat off = (turn * z_to_y).normalized();
        const dQuaternion dq = {off.w(), off.x(), off.y(), off.z()};
        dGeomSetOffsetQuaternion(x.wheels[i], dq);
        x.radius = std::max(x.radius, local.norm() + wheel_reach);
      }
      proxies.push_back(x);
    }
  }

  void record_collisions(double dt, bool record) {
    // Episodes with vehicles no longer near end like those with obstacles out of reach.
    for (auto& [id, e] : peer_episodes) {
      if (e.open && time - e.last_contact_s > kEpisodeGapS) e.open = false;
    }
    if (contacts.empty()) return;
    // Sum the contact forces on the vehicle per obstacle or vehicle (contacts are grouped).
    std::size_t k = 0;
    while (k < contacts.size()) {
      const std::size_t o = contacts[k].obstacle;
      Vec3 force = Vec3::Zero();
      const Vec3 position = vec(contacts[k].contact.geom.pos);
      const double relative_speed = contacts[k].relative_speed;
      for (; k < contacts.size() && contacts[k].obstacle == o; ++k) force += vec(feedback[k].f1);
      if (o >= obstacles.size()) {
        const std::string& id = proxies[o - obstacles.size()].id;
        PeerEpisode& e = peer_episodes[id];
        if (record && !e.open) {
          CollisionContact c;
          c.impulse_ns = force.norm() * dt;
          c.position = position;
          c.other_vehicle = id;
          c.relative_speed_mps = relative_speed;
          collisions.push_back(std::move(c));
        }
        e.open = record;
        e.last_contact_s = time;
        continue;
      }
      ObstacleGeom& ob = obstacles[o];
      if (record && !ob.episode_open) {
        collisions.push_back(CollisionContact{ob.id, force.norm() * dt, position, {}, 0.0});
      }
      ob.episode_open = record;
      ob.last_contact_s = time;
    }
    dJointGroupEmpty(contact_group);
    contacts.clear();
  }

  void step(double dt, bool record) {
    begin_step(dt);
    // The exact (LCP) solver. Unlike dWorldQuickStep it draws no random numbers from ODE's
    // process-global seed, so interleaved instances cannot disturb each other.
    dWorldStep(world, dt);
    end_step(dt, record);
  }

  /// Everything before the world step: inputs, forces, contact joints.
  void begin_step(double dt) {
    if (!(dt > 0.0) || !std::isfinite(dt)) throw std::invalid_argument("step must be positive");
    ensure_ode_ready();
    set_step_size(dt);
    step_v0 = point_velocity(chassis, reference_point());
    step_w0 = vec(dBodyGetAngularVel(chassis));

    apply_steering_and_brakes(dt);
    apply_drive_torque(dt);
    if (deformable) {
      apply_deformable_forces(dt);
    } else {
      apply_tire_forces(dt);
    }
    apply_suspension_forces();
    apply_aero_drag();
    find_obstacle_contacts();
    find_proxy_contacts();
    create_contact_joints();
  }

  /// Everything after it: time, collision episodes, accelerations.
  void end_step(double dt, bool record) {
    time += dt;
    record_collisions(dt, record);

    const Vec3 v1 = point_velocity(chassis, reference_point());
    const Vec3 w1 = vec(dBodyGetAngularVel(chassis));
    if (!finite(v1) || !finite(w1) || !finite(vec(dBodyGetPosition(chassis)))) {
      throw std::runtime_error("vehicle dynamics diverged at t = " + std::to_string(time) + " s");
    }
    accel = (v1 - step_v0) / dt;
    angular_accel = (w1 - step_w0) / dt;
  }

  // --- checkpoints -------------------------------------------------------------------------
  //
  // Saved: time; the inputs commanded and applied (the applied steering is the rate limiter's
  // state); the last step's accelerations; the five bodies' position, quaternion, linear and
  // angular velocity; the powertrain (gear, engine speed, shift timer, last outputs); the
  // tires' tread deflections; the wheel diagnostics (the snapshot reports the tire loads,
  // set_speed reads the deflections); per obstacle its episode state (last contact time,
  // episode open) and the collisions not taken yet.
  //
  // Not saved, because the constructor rebuilds them identically (checked by the
  // fingerprints) or the next step overwrites them before reading them:
  // - p, terrain, deformable, tire, axle, wheel_local, preload, front_share, drive_share,
  //   vehicle_radius, the obstacles' ids, geoms, centres and radii: from the params, the start
  //   and the obstacle list. A deformable terrain's own state (soil) is saved by its owner.
  // - load_scale: 1 after settling, never changed afterwards.
  // - driveline_inertia and the wheel masses: a function of the gear; load_state sets them
  //   from the restored gear (set_wheel_inertia).
  // - last_dt and the hinge-2 suspension ERP/CFM: a function of the step size, set again by
  //   set_step_size for whatever dt the next step has (restoring last_dt without the joint
  //   params would be wrong, restoring neither is right).
  // - contacts and feedback: filled and emptied within a step (the contact joint group is
  //   empty between steps, so the world's joint list is the four hinge-2 joints in creation
  //   order, as in a new model).
  // ODE: a body's other state is its force and torque accumulators (zeroed by dWorldStep), its
  // rotation matrix (computed from the quaternion by dBodySetQuaternion, as at the end of a
  // step) and its mass (set_wheel_inertia). No auto-disable, damping or finite rotation is in
  // use, so no body keeps averages or counters. The hinge-2 joints keep their anchors, axes and
  // reference angle relative to the bodies from construction (same placement: same numbers),
  // limits and FMax from construction, motor speed (steering) and FMax2 (brakes) set every step
  // before dWorldStep, the limit flags computed by dWorldStep itself. dWorldStep solves each
  // step from scratch (no warm starting) and draws no random numbers. Geoms attached to bodies
  // follow them: the body setters call dGeomMoved, and dCollide recomputes a moved geom's pose
  // from its body. Obstacle geoms are static.

  void save_state(core::StateWriter& w) {
    std::array<BodyState, 5> raw;
    for (std::size_t b = 0; b < 5; ++b) raw[b] = get_body_state(bodies()[b]);

    w.begin("ode_vehicle", 1);
    w.io(p.name);
    w.io(full_params_fingerprint(p));
    w.io(placement_fingerprint);
    w.io(obstacles_fingerprint);
    w.io(static_cast<std::uint32_t>(wheels.size()));
    w.io(deformable != nullptr);
    w.io(time);
    for (const DriverInputs* in : {&commanded, &applied}) {
      w.io(in->steering);
      w.io(in->throttle);
      w.io(in->braking);
    }
    w.io(accel);
    w.io(angular_accel);

    w.begin("ode_bodies", 1);
    for (const BodyState& b : raw) {
      w.io(b.position);
      w.io(b.quaternion);
      w.io(b.linear_velocity);
      w.io(b.angular_velocity);
    }
    w.end();

    powertrain.save_state(w);

    w.begin("tires", 1);
    for (const TireState& t : tire_states) {
      w.io(t.deflection_x_m);
      w.io(t.deflection_y_m);
    }
    w.end();

    w.begin("wheel_diagnostics", 1);
    for (const WheelDiagnostics& d : diag) diagnostics_fields(w, d);
    w.end();

    w.begin("collisions", 2);
    w.io(static_cast<std::uint64_t>(obstacles.size()));
    for (const ObstacleGeom& o : obstacles) {
      w.io(o.id);
      w.io(o.last_contact_s);
      w.io(o.episode_open);
    }
    w.io(static_cast<std::uint64_t>(collisions.size()));
    for (const CollisionContact& c : collisions) {
      w.io(c.obstacle_id);
      w.io(c.impulse_ns);
      w.io(c.position);
      w.io(c.other_vehicle);       // since version 2
      w.io(c.relative_speed_mps);
    }
    // Since version 2: episodes with other vehicles (the proxies themselves are rebuilt from
    // the next frame's inputs, which the member's checkpoint holds).
    w.io(static_cast<std::uint64_t>(peer_episodes.size()));
    for (const auto& [id, e] : peer_episodes) {
      w.io(id);
      w.io(e.last_contact_s);
      w.io(e.open);
    }
    w.end();

    w.end();

    // The bytes hold the raw values; this model now continues from set(raw), exactly as a
    // model restored from them will (see set_body_state).
    for (std::size_t b = 0; b < 5; ++b) set_body_state(bodies()[b], raw[b]);
  }

  void load_state(core::StateReader& r) {
    r.begin("ode_vehicle", 1, 1);
    const auto name = r.get<std::string>();
    const auto params_fp = r.get<std::uint64_t>();
    if (params_fp != full_params_fingerprint(p)) {
      r.fail("the state is of vehicle '" + name + "' with params fingerprint " + hex64(params_fp) +
             "; this model is vehicle '" + p.name + "' with " + hex64(full_params_fingerprint(p)) +
             ": their params differ");
    }
    if (r.get<std::uint64_t>() != placement_fingerprint) {
      r.fail("the state's vehicle was placed at another start or on other terrain than this "
             "model");
    }
    const auto obstacles_fp = r.get<std::uint64_t>();
    const auto wheel_count = r.get<std::uint32_t>();
    if (wheel_count != wheels.size()) {
      r.fail("the state has " + std::to_string(wheel_count) + " wheels, this vehicle " +
             std::to_string(wheels.size()));
    }
    const bool on_deformable = r.get<bool>();
    if (on_deformable != (deformable != nullptr)) {
      r.fail(std::string("the state is of a vehicle on ") +
             (on_deformable ? "deformable" : "rigid") + " ground, this model is on " +
             (deformable ? "deformable" : "rigid") + " ground");
    }
    // Everything is read into these and taken only after the section's end was checked: a
    // state that does not fit leaves the model as it was.
    const auto new_time = r.get<double>();
    DriverInputs new_commanded, new_applied;
    for (DriverInputs* in : {&new_commanded, &new_applied}) {
      r.io(in->steering);
      r.io(in->throttle);
      r.io(in->braking);
    }
    Vec3 new_accel, new_angular_accel;
    r.io(new_accel);
    r.io(new_angular_accel);

    std::array<BodyState, 5> new_bodies;
    r.begin("ode_bodies", 1, 1);
    for (BodyState& b : new_bodies) {
      r.io(b.position);
      r.io(b.quaternion);
      r.io(b.linear_velocity);
      r.io(b.angular_velocity);
    }
    r.end();

    Powertrain new_powertrain = powertrain;
    new_powertrain.load_state(r);

    std::array<TireState, 4> new_tires;
    r.begin("tires", 1, 1);
    for (TireState& t : new_tires) {
      r.io(t.deflection_x_m);
      r.io(t.deflection_y_m);
    }
    r.end();

    std::array<WheelDiagnostics, 4> new_diag;
    r.begin("wheel_diagnostics", 1, 1);
    for (WheelDiagnostics& d : new_diag) diagnostics_fields(r, d);
    r.end();

    const std::uint32_t collisions_version = r.begin("collisions", 2, 1);
    const auto obstacle_count = r.get<std::uint64_t>();
    std::vector<std::string> ids;
    std::vector<std::pair<double, bool>> episodes;
    for (std::uint64_t k = 0; k < obstacle_count && k <= obstacles.size(); ++k) {
      ids.push_back(r.get<std::string>());
      const auto last = r.get<double>();
      episodes.emplace_back(last, r.get<bool>());
    }
    auto list = [](const std::vector<std::string>& names) {
      std::string out;
      for (const auto& n : names) out += (out.empty() ? "'" : ", '") + n + "'";
      return out.empty() ? std::string("none") : out;
    };
    std::vector<std::string> own_ids;
    for (const ObstacleGeom& o : obstacles) own_ids.push_back(o.id);
    if (obstacle_count != obstacles.size() || ids != own_ids) {
      r.fail("the state's obstacles (" + std::to_string(obstacle_count) + ": " + list(ids) +
             (ids.size() < obstacle_count ? ", ..." : "") + ") are not this model's (" +
             std::to_string(obstacles.size()) + ": " + list(own_ids) + ")");
    }
    if (obstacles_fp != obstacles_fingerprint) {
      r.fail("the state's obstacles " + list(ids) +
             " have other shapes, sizes or poses than this model's");
    }
    // One by one: a damaged count runs into the section's end instead of allocating it.
    std::vector<CollisionContact> new_collisions;
    const auto collision_count = r.get<std::uint64_t>();
    for (std::uint64_t k = 0; k < collision_count; ++k) {
      CollisionContact c;
      r.io(c.obstacle_id);
      r.io(c.impulse_ns);
      r.io(c.position);
      if (collisions_version >= 2) {
        r.io(c.other_vehicle);
        r.io(c.relative_speed_mps);
      }
      new_collisions.push_back(std::move(c));
    }
    std::map<std::string, PeerEpisode> new_peer_episodes;
    if (collisions_version >= 2) {
      const auto peer_count = r.get<std::uint64_t>();
      for (std::uint64_t k = 0; k < peer_count; ++k) {
        const auto id = r.get<std::string>();
        PeerEpisode e;
        r.io(e.last_contact_s);
        r.io(e.open);
        new_peer_episodes[id] = e;
      }
    }
    r.end();

    r.end();

    time = new_time;
    commanded = new_commanded;
    applied = new_applied;
    accel = new_accel;
    angular_accel = new_angular_accel;
    for (std::size_t b = 0; b < 5; ++b) set_body_state(bodies()[b], new_bodies[b]);
    powertrain = std::move(new_powertrain);
    set_wheel_inertia();  // masses of the restored gear now (the next step would set them too)
    tire_states = new_tires;
    diag = new_diag;
    for (std::size_t k = 0; k < obstacles.size(); ++k) {
      obstacles[k].last_contact_s = episodes[k].first;
      obstacles[k].episode_open = episodes[k].second;
    }
    collisions = std::move(new_collisions);
    peer_episodes = std::move(new_peer_episodes);
  }
};

OdeVehicleModel::OdeVehicleModel(const VehicleParams& params, const Pose& start,
                                 std::shared_ptr<const terrain::TerrainSurface> terrain,
                                 const world::Obstacles& obstacles,
                                 std::shared_ptr<terrain::WheelTerrainContact> deformable) {
  if (!terrain) throw std::invalid_argument("OdeVehicleModel needs a terrain surface");
  ensure_ode_ready();
  impl_ = std::make_unique<Impl>(params, std::move(terrain), std::move(deformable));
  impl_->build(start, obstacles);
  impl_->settle();
}

OdeVehicleModel::~OdeVehicleModel() = default;

std::unique_ptr<OdeVehicleModel> OdeVehicleModel::in_world_of(
    OdeVehicleModel& host, const VehicleParams& params, const Pose& start,
    std::shared_ptr<const terrain::TerrainSurface> terrain) {
  if (!terrain) throw std::invalid_argument("OdeVehicleModel needs a terrain surface");
  std::unique_ptr<OdeVehicleModel> m(new OdeVehicleModel());
  m->impl_ = std::make_unique<Impl>(params, std::move(terrain), nullptr);
  m->impl_->build(start, {}, host.impl_->world);
  // Settling steps the world: the host is held still meanwhile (disabled bodies are not moved).
  for (dBodyID b : host.impl_->bodies()) dBodyDisable(b);
  m->impl_->settle();
  for (dBodyID b : host.impl_->bodies()) dBodyEnable(b);
  return m;
}

void OdeVehicleModel::step_pair(OdeVehicleModel& a, OdeVehicleModel& b, double dt) {
  Impl& x = *a.impl_;
  Impl& y = *b.impl_;
  if (x.world != y.world) throw std::invalid_argument("step_pair: the vehicles share no world");
  x.begin_step(dt);
  y.begin_step(dt);
  std::vector<Impl::PendingContact> pair;
  x.collide_with(y.own_geoms(), 0, pair);
  for (auto& c : pair) {
    dJointID j = dJointCreateContact(x.world, x.contact_group, &c.contact);
    dJointAttach(j, c.body, c.other);
  }
  dWorldStep(x.world, dt);
  x.end_step(dt, true);
  y.end_step(dt, true);
  dJointGroupEmpty(x.contact_group);  // the pair's joints
}

void OdeVehicleModel::set_peers(std::vector<PeerVehicle> peers) { impl_->set_peers(peers); }

void OdeVehicleModel::set_inputs(const DriverInputs& inputs) {
  if (!std::isfinite(inputs.steering) || !std::isfinite(inputs.throttle) ||
      !std::isfinite(inputs.braking)) {
    throw std::invalid_argument("driver inputs must be finite numbers");
  }
  impl_->commanded = clamp_inputs(inputs);
  if (impl_->p.steering.rate_deg_s <= 0.0) impl_->applied.steering = impl_->commanded.steering;
  impl_->applied.throttle = impl_->commanded.throttle;
  impl_->applied.braking = impl_->commanded.braking;
}

void OdeVehicleModel::advance(double dt) { impl_->step(dt, true); }

void OdeVehicleModel::set_speed(double forward_speed_mps) {
  Impl& m = *impl_;
  const Vec3 v = forward_speed_mps * (body_quat(m.chassis) * Vec3::UnitX());
  dBodySetLinearVel(m.chassis, v.x(), v.y(), v.z());
  dBodySetAngularVel(m.chassis, 0, 0, 0);
  for (int i = 0; i < 4; ++i) {
    dBodySetLinearVel(m.wheels[i], v.x(), v.y(), v.z());
    const double r_eff = m.p.wheels.radius_m - m.diag[i].tire_deflection_m / 3.0;
    const Vec3 w = forward_speed_mps / r_eff * m.spin_axis(i);
    dBodySetAngularVel(m.wheels[i], w.x(), w.y(), w.z());
    m.tire_states[i] = TireState{};
  }
}

VehicleSnapshot OdeVehicleModel::snapshot() const {
  const Impl& m = *impl_;
  VehicleSnapshot s;
  s.time_s = m.time;
  s.pose.position = m.reference_point();
  s.pose.orientation = body_quat(m.chassis);
  s.linear_velocity = point_velocity(m.chassis, s.pose.position);
  s.angular_velocity = vec(dBodyGetAngularVel(m.chassis));
  s.linear_acceleration = m.accel;
  s.angular_acceleration = m.angular_accel;
  s.wheels.resize(4);
  for (int i = 0; i < 4; ++i) {
    WheelSnapshot& w = s.wheels[static_cast<std::size_t>(i)];
    w.pose.position = vec(dBodyGetPosition(m.wheels[i]));
    w.pose.orientation = body_quat(m.wheels[i]);
    w.spin_rad_s = m.relative_spin(i);
    w.steer_angle_rad = m.steer_angle(i);
    w.vertical_load_n = m.diag[i].tire_normal_force_n;
  }
  s.inputs = m.applied;
  s.gear = m.powertrain.gear();
  s.engine_speed_rpm = m.powertrain.engine_rpm();
  return s;
}

void OdeVehicleModel::save_state(core::StateWriter& w) { impl_->save_state(w); }

void OdeVehicleModel::load_state(core::StateReader& r) { impl_->load_state(r); }

std::vector<CollisionContact> OdeVehicleModel::take_collisions() {
  std::vector<CollisionContact> out;
  out.swap(impl_->collisions);
  return out;
}

std::array<OdeVehicleModel::WheelDiagnostics, 4> OdeVehicleModel::wheel_diagnostics() const {
  return impl_->diag;
}

const VehicleParams& OdeVehicleModel::params() const { return impl_->p; }

double OdeVehicleModel::time_s() const { return impl_->time; }

}  // namespace syndds::vehicle
