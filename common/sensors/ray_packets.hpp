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

// The widest packet the CPU traces natively: 16 (AVX-512), 8 (AVX2) or 1. Where 16-wide is
// not native, Embree emulates it with 8-wide packets, and that emulation in Debian's Embree
// 3.13.5 aborts on valid rays (its assertion `all(valid, ray.valid())` in
// bvh_intersector_hybrid.cpp fails on AVX2 CPUs): there a 16-ray packet is traced as two native
// 8-wide halves.
inline int native_width(RTCScene scene) {
  static const int width = [scene] {
    RTCDevice device = rtcGetSceneDevice(scene);  // counts a reference
    const int w = rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) ? 16
                  : rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED) ? 8
                                                                                             : 1;
    rtcReleaseDevice(device);
    return w;
  }();
  return width;
}

// Copies lane `from` of ray packet `src` into lane `to` of packet `dst` (any two widths).
template <class Dst, class Src>
inline void copy_ray_lane(Dst& dst, int to, const Src& src, int from) {
  dst.org_x[to] = src.org_x[from];
  dst.org_y[to] = src.org_y[from];
  dst.org_z[to] = src.org_z[from];
  dst.dir_x[to] = src.dir_x[from];
  dst.dir_y[to] = src.dir_y[from];
  dst.dir_z[to] = src.dir_z[from];
  dst.tnear[to] = src.tnear[from];
  dst.tfar[to] = src.tfar[from];
  dst.time[to] = 0.0f;
  dst.mask[to] = src.mask[from];
  dst.id[to] = src.id[from];
  dst.flags[to] = 0;
}
// The hit fields the renderers read back (with the ray's tfar).
template <class Dst, class Src>
inline void copy_hit_lane(Dst& dst, int to, const Src& src, int from) {
  dst.ray.tfar[to] = src.ray.tfar[from];
  dst.hit.geomID[to] = src.hit.geomID[from];
  dst.hit.primID[to] = src.hit.primID[from];
  dst.hit.Ng_x[to] = src.hit.Ng_x[from];
  dst.hit.Ng_y[to] = src.hit.Ng_y[from];
  dst.hit.Ng_z[to] = src.hit.Ng_z[from];
}

// Calls trace(v8, half) for each 8-lane half (half = 0 or 8) of a 16-lane valid mask that has a
// valid lane; v8 is that half's mask, aligned as rtcIntersect8/rtcOccluded8 require.
template <class Trace>
inline void for_each_half(const int* valid, Trace&& trace) {
  for (int half = 0; half < 16; half += 8) {
    alignas(32) int v8[8];
    bool any = false;
    for (int l = 0; l < 8; ++l) any |= (v8[l] = valid[half + l]) != 0;
    if (any) trace(v8, half);
  }
}

// Traces the valid lanes of a packet: as packets when rays are coherent, one by one otherwise
// (low-resolution cameras: neighbouring pixels diverge by a degree or more and Embree's
// single-ray traversal is about 20 % faster there; at 720p packets are twice as fast). Packets
// are 16 wide or two 8-wide halves (native_width); one by one where neither is native.
// intersect_at / occluded_at: the same with packets of `width` lanes (16, 8 or 1; no wider than
// native_width, tests use them to trace one packet every way this CPU can).
inline void intersect_at(int width, const int* valid, RTCScene scene, RTCIntersectContext* ctx,
                         RTCRayHit16& rh) {
  if (width == 16) {
    rtcIntersect16(valid, scene, ctx, &rh);
    return;
  }
  if (width == 8) {
    for_each_half(valid, [&](const int* v8, int half) {
      alignas(32) RTCRayHit8 h;
      for (int l = 0; l < 8; ++l) {
        if (!v8[l]) continue;
        copy_ray_lane(h.ray, l, rh.ray, half + l);
        h.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
        h.hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
      }
      rtcIntersect8(v8, scene, ctx, &h);
      for (int l = 0; l < 8; ++l)
        if (v8[l]) copy_hit_lane(rh, half + l, h, l);
    });
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

inline void occluded_at(int width, const int* valid, RTCScene scene, RTCIntersectContext* ctx,
                        RTCRay16& rays) {
  if (width == 16) {
    rtcOccluded16(valid, scene, ctx, &rays);
    return;
  }
  if (width == 8) {
    for_each_half(valid, [&](const int* v8, int half) {
      alignas(32) RTCRay8 r8;
      for (int l = 0; l < 8; ++l)
        if (v8[l]) copy_ray_lane(r8, l, rays, half + l);
      rtcOccluded8(v8, scene, ctx, &r8);
      for (int l = 0; l < 8; ++l)
        if (v8[l]) rays.tfar[half + l] = r8.tfar[l];
    });
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

inline void intersect(bool packets, const int* valid, RTCScene scene, RTCIntersectContext* ctx,
                      RTCRayHit16& rh) {
  intersect_at(packets ? native_width(scene) : 1, valid, scene, ctx, rh);
}
inline void occluded(bool packets, const int* valid, RTCScene scene, RTCIntersectContext* ctx,
                     RTCRay16& rays) {
  occluded_at(packets ? native_width(scene) : 1, valid, scene, ctx, rays);
}

}  // namespace syndds::sensors
