#pragma once
// Internal to the renderers: 16-ray packets filled from a sensor's directions, traced either
// as packets or ray by ray.
#include <embree3/rtcore.h>

#include <cstddef>

#include "core/math.hpp"

namespace syndds::sensors {

/// A sensor's world pose as the packet fill below takes it: rotation row-major, origin.
struct RayFrame {
  float m[9];
  float o[3];
  explicit RayFrame(const Pose& pose) {
    const Eigen::Matrix3d rot = pose.orientation.toRotationMatrix();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) m[3 * i + j] = static_cast<float>(rot(i, j));
      o[i] = static_cast<float>(pose.position[i]);
    }
  }
};

// Fills a packet with rays base, base + 1, ... (lanes at or past `end` invalid): from the
// frame's origin along sensor-frame directions `directions` (xyz per ray) rotated into the
// world (also written to dir[lane]), between tnear and tfar.
inline void fill_packet(RTCRayHit16& rh, int* valid, float (*dir)[3], std::size_t base,
                        std::size_t end, const float* directions, const RayFrame& f, float tnear,
                        float tfar) {
  for (int l = 0; l < 16; ++l) {
    const std::size_t r = base + static_cast<std::size_t>(l);
    valid[l] = r < end ? -1 : 0;
    if (!valid[l]) continue;
    const float* d = &directions[3 * r];
    for (int i = 0; i < 3; ++i)
      dir[l][i] = f.m[3 * i] * d[0] + f.m[3 * i + 1] * d[1] + f.m[3 * i + 2] * d[2];
    rh.ray.org_x[l] = f.o[0];
    rh.ray.org_y[l] = f.o[1];
    rh.ray.org_z[l] = f.o[2];
    rh.ray.dir_x[l] = dir[l][0];
    rh.ray.dir_y[l] = dir[l][1];
    rh.ray.dir_z[l] = dir[l][2];
    rh.ray.tnear[l] = tnear;
    rh.ray.tfar[l] = tfar;
    rh.ray.time[l] = 0.0f;
    rh.ray.mask[l] = 0xFFFFFFFFu;
    rh.ray.id[l] = static_cast<unsigned>(l);
    rh.ray.flags[l] = 0;
    rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
  }
}

// Whether the CPU traces 16-wide packets natively (AVX-512). Elsewhere Embree emulates them
// with 8-wide ones, and that emulation in Debian's Embree 3.13.5 aborts on valid rays (its
// assertion `all(valid, ray.valid())` in bvh_intersector_hybrid.cpp fails on AVX2 CPUs): there
// the packets are traced ray by ray.
inline bool native_packets(RTCScene scene) {
  static const bool native = [scene] {
    RTCDevice device = rtcGetSceneDevice(scene);  // counts a reference
    const bool n = rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) != 0;
    rtcReleaseDevice(device);
    return n;
  }();
  return native;
}

// Traces the valid lanes of a packet: 16-wide when rays are coherent, one by one otherwise
// (low-resolution cameras: neighbouring pixels diverge by a degree or more and Embree's
// single-ray traversal is about 20 % faster there; at 720p packets are twice as fast), and
// one by one on CPUs without native 16-wide packets (native_packets).
inline void intersect(bool packets, const int* valid, RTCScene scene, RTCIntersectContext* ctx,
                      RTCRayHit16& rh) {
  if (packets && native_packets(scene)) {
    rtcIntersect16(valid, scene, ctx, &rh);
    return;
  }
  for (int l = 0; l < 16; ++l) {
    if (!valid[l]) continue;
    RTCRayHit r;
    r.ray.org_x = rh.ray.org_x[l];
    r.ray.org_y = rh.ray.org_y[l];
    r.ray.org_z = rh.ray.org_z[l];
    r.ray.dir_x = rh.ray.dir_x[l];
    r.ray.dir_y = rh.ray.dir_y[l];
    r.ray.dir_z = rh.ray.dir_z[l];
    r.ray.tnear = rh.ray.tnear[l];
    r.ray.tfar = rh.ray.tfar[l];
    r.ray.time = 0.0f;
    r.ray.mask = rh.ray.mask[l];
    r.ray.id = rh.ray.id[l];
    r.ray.flags = 0;
    r.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    r.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, ctx, &r);
    rh.ray.tfar[l] = r.ray.tfar;
    rh.hit.geomID[l] = r.hit.geomID;
    rh.hit.primID[l] = r.hit.primID;
    rh.hit.Ng_x[l] = r.hit.Ng_x;
    rh.hit.Ng_y[l] = r.hit.Ng_y;
    rh.hit.Ng_z[l] = r.hit.Ng_z;
  }
}

inline void occluded(bool packets, const int* valid, RTCScene scene, RTCIntersectContext* ctx,
                     RTCRay16& rays) {
  if (packets && native_packets(scene)) {
    rtcOccluded16(valid, scene, ctx, &rays);
    return;
  }
  for (int l = 0; l < 16; ++l) {
    if (!valid[l]) continue;
    RTCRay r;
    r.org_x = rays.org_x[l];
    r.org_y = rays.org_y[l];
    r.org_z = rays.org_z[l];
    r.dir_x = rays.dir_x[l];
    r.dir_y = rays.dir_y[l];
    r.dir_z = rays.dir_z[l];
    r.tnear = rays.tnear[l];
    r.tfar = rays.tfar[l];
    r.time = 0.0f;
    r.mask = rays.mask[l];
    r.id = rays.id[l];
    r.flags = 0;
    rtcOccluded1(scene, ctx, &r);
    rays.tfar[l] = r.tfar;
  }
}

}  // namespace syndds::sensors
