#pragma once
// Ray and closest-point queries on a triangle mesh, through Embree 3 (its BVH, robust
// watertight mode): what baking needs of a dense mesh (bake/dense_mesh.h) and of a result
// to measure. Queries are const and may run from many threads at once.
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <embree3/rtcore.h>
#include <glm/glm.hpp>

#include "dispmap/core/error.h"

namespace dispmap {

/// The closest point of triangle (a, b, c) to p (Ericson, Real-Time Collision Detection §5.1.5:
/// Voronoi regions of the vertices, then of the edges, then the face). Exact for any triangle,
/// including degenerate ones (the regions then collapse to the segments).
template <typename vec3> vec3 closestPointOnTriangle(const vec3& p, const vec3& a, const vec3& b, const vec3& c) {
    using real = typename vec3::value_type;
    const vec3 ab = b - a, ac = c - a, ap = p - a;
    const real d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return a;
    const vec3 bp = p - b;
    const real d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return b;
    const real vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
    const vec3 cp = p - c;
    const real d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return c;
    const real vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
    const real va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    const real denom = real(1) / (va + vb + vc);
    return a + ab * (vb * denom) + ac * (vc * denom);
}

/// The ray org + t dir, tnear <= t <= tfar, for rtcIntersect1: every mask bit, no hit yet.
inline RTCRayHit embreeRay(const glm::vec3& org, const glm::vec3& dir, float tnear, float tfar) {
    RTCRayHit rh{};
    rh.ray.org_x = org.x;
    rh.ray.org_y = org.y;
    rh.ray.org_z = org.z;
    rh.ray.dir_x = dir.x;
    rh.ray.dir_y = dir.y;
    rh.ray.dir_z = dir.z;
    rh.ray.tnear = tnear;
    rh.ray.tfar = tfar;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    return rh;
}

/// One triangle mesh in an Embree scene.
class RayScene {
  public:
    struct Hit {
        bool hit = false;
        float t = 0;            ///< distance along the (unit) direction
        std::uint32_t prim = 0; ///< triangle index
        glm::vec3 normal{0};    ///< the triangle's unit normal, (b - a) x (c - a) (counter-clockwise front)
    };
    struct Closest {
        bool found = false;
        glm::vec3 point{0};
        float distance = std::numeric_limits<float>::infinity();
        std::uint32_t prim = 0;
    };

    /// Builds the BVH over `positions` and `triangles` (copied). Throws Error when Embree
    /// cannot create a device or build (e.g. out of memory), ArgumentError for an index out
    /// of range or an empty mesh.
    RayScene(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles)
        : positions_(positions), triangles_(triangles) {
        if (triangles_.empty()) throw ArgumentError("ray scene: no triangles");
        for (const glm::uvec3& t : triangles_)
            if (t.x >= positions_.size() || t.y >= positions_.size() || t.z >= positions_.size())
                throw ArgumentError("ray scene: a triangle refers to a vertex out of range");
        device_.reset(rtcNewDevice(nullptr));
        if (!device_) throw Error("Embree: cannot create a device (" + errorName(rtcGetDeviceError(nullptr)) + ")");
        scene_.reset(rtcNewScene(device_.get()));
        rtcSetSceneFlags(scene_.get(), RTC_SCENE_FLAG_ROBUST);
        rtcSetSceneBuildQuality(scene_.get(), RTC_BUILD_QUALITY_HIGH);
        RTCGeometry g = rtcNewGeometry(device_.get(), RTC_GEOMETRY_TYPE_TRIANGLE);
        // (rtcSetNewGeometryBuffer pads the buffer for Embree's 16-byte reads itself.)
        auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                              3 * sizeof(float), positions_.size()));
        auto* ix = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                        3 * sizeof(std::uint32_t), triangles_.size()));
        if (!v || !ix) {
            rtcReleaseGeometry(g);
            throw Error("Embree: cannot allocate the geometry (" + errorName(rtcGetDeviceError(device_.get())) + ")");
        }
        for (std::size_t i = 0; i < positions_.size(); ++i)
            for (int c = 0; c < 3; ++c) v[3 * i + static_cast<std::size_t>(c)] = positions_[i][c];
        for (std::size_t i = 0; i < triangles_.size(); ++i)
            for (int c = 0; c < 3; ++c) ix[3 * i + static_cast<std::size_t>(c)] = triangles_[i][c];
        rtcCommitGeometry(g);
        rtcAttachGeometry(scene_.get(), g);
        rtcReleaseGeometry(g);
        rtcCommitScene(scene_.get());
        const RTCError e = rtcGetDeviceError(device_.get());
        if (e != RTC_ERROR_NONE) throw Error("Embree: cannot build the scene (" + errorName(e) + ")");
    }

    /// The nearest hit of the ray org + t dir (dir of unit length), tnear <= t <= tfar, either side
    /// of a triangle.
    Hit intersect(const glm::vec3& org, const glm::vec3& dir, float tnear, float tfar) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRayHit rh = embreeRay(org, dir, tnear, tfar);
        rtcIntersect1(scene_.get(), &ctx, &rh);
        Hit h;
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return h;
        h.hit = true;
        h.t = rh.ray.tfar;
        h.prim = rh.hit.primID;
        h.normal = triangleNormal(h.prim);
        return h;
    }

    /// The closest point of the mesh to p within `radius` (found = false if none is that close).
    Closest closest(const glm::vec3& p, float radius = std::numeric_limits<float>::infinity()) const {
        Query q;
        q.self = this;
        RTCPointQuery pq{};
        pq.x = p.x;
        pq.y = p.y;
        pq.z = p.z;
        pq.radius = radius;
        pq.time = 0.0f;
        RTCPointQueryContext ctx;
        rtcInitPointQueryContext(&ctx);
        rtcPointQuery(scene_.get(), &pq, &ctx, &RayScene::pointQuery, &q);
        return q.best;
    }

    const std::vector<glm::vec3>& positions() const { return positions_; }
    const std::vector<glm::uvec3>& triangles() const { return triangles_; }
    glm::vec3 triangleNormal(std::uint32_t prim) const {
        const glm::uvec3& t = triangles_[prim];
        const glm::vec3 n = glm::cross(positions_[t.y] - positions_[t.x], positions_[t.z] - positions_[t.x]);
        const float l = glm::length(n);
        return l > 0.0f ? n / l : glm::vec3(0.0f);
    }

  private:
    struct Query {
        const RayScene* self = nullptr;
        Closest best;
    };
    static bool pointQuery(RTCPointQueryFunctionArguments* args) {
        auto* q = static_cast<Query*>(args->userPtr);
        const RayScene& s = *q->self;
        const glm::uvec3& t = s.triangles_[args->primID];
        // In double: Ericson's tests multiply dot products (fourth powers of the coordinates),
        // which overflow float from about 1e10 on; double holds the whole accepted range.
        const glm::dvec3 p(args->query->x, args->query->y, args->query->z);
        const glm::dvec3 c = closestPointOnTriangle(p, glm::dvec3(s.positions_[t.x]), glm::dvec3(s.positions_[t.y]),
                                                    glm::dvec3(s.positions_[t.z]));
        const float d = static_cast<float>(glm::length(c - p));
        // Equal distances go to the lower triangle index, whatever order the BVH visits them in.
        if (d <= args->query->radius && (d < q->best.distance || (d == q->best.distance && args->primID < q->best.prim))) {
            args->query->radius = d;
            q->best.found = true;
            q->best.point = glm::vec3(c);
            q->best.distance = d;
            q->best.prim = args->primID;
            return true; // the radius shrank
        }
        return false;
    }
    static std::string errorName(RTCError e) {
        switch (e) {
        case RTC_ERROR_NONE: return "no error";
        case RTC_ERROR_INVALID_ARGUMENT: return "invalid argument";
        case RTC_ERROR_INVALID_OPERATION: return "invalid operation";
        case RTC_ERROR_OUT_OF_MEMORY: return "out of memory";
        case RTC_ERROR_UNSUPPORTED_CPU: return "unsupported CPU";
        case RTC_ERROR_CANCELLED: return "cancelled";
        default: return "unknown error";
        }
    }
    struct DeviceRelease {
        void operator()(RTCDevice d) const { rtcReleaseDevice(d); }
    };
    struct SceneRelease {
        void operator()(RTCScene s) const { rtcReleaseScene(s); }
    };
    std::vector<glm::vec3> positions_;
    std::vector<glm::uvec3> triangles_;
    std::unique_ptr<RTCDeviceTy, DeviceRelease> device_;
    std::unique_ptr<RTCSceneTy, SceneRelease> scene_;
};

} // namespace dispmap
