#pragma once
// Internal to the renderers: 16-ray packets traced either as packets or ray by ray.
#include <embree3/rtcore.h>

namespace syndds::sensors {

// Traces the valid lanes of a packet: 16-wide when rays are coherent, one by one otherwise
// (low-resolution cameras: neighbouring pixels diverge by a degree or more and Embree's
// single-ray traversal is about 20 % faster there; at 720p packets are twice as fast).
inline void intersect(bool packets, const int* valid, RTCScene scene, RTCIntersectContext* ctx,
                      RTCRayHit16& rh) {
  if (packets) {
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
  if (packets) {
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
