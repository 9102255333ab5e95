#pragma once
// The mesostructure marchers on the CPU, in float or double. kernels/meso.h has the voxel
// space and every step rule and kernels/meso_march.h the marchers' loops, written once for the
// CPU and the GPU; this file supplies the loops' memory (kern::DmMesoMapsT and its fetch
// functions, as shaders/meso/march.glsl does on the GPU), checks the inputs and keeps the exact
// reference, so that both sides give the same hits and counts.
//
// A ray is (o, d) in voxel space, d of unit length, usually o on the top plane z = L where
// the base surface is; MesoHit::t is the parameter of the hit o + t d. `iterations` counts
// the loop's rounds: one map fetch each (a distance sample set, a DDM value plus a quadric
// where it is 0, or a height cell).
#include <cmath>
#include <limits>

#include "dispmap/meso/albedo.h"
#include "dispmap/meso/compression.h"
#include "dispmap/meso/ddm.h"
#include "dispmap/meso/distance_map.h"
#include "dispmap/meso/height_field.h"
#include "dispmap/meso/quadrics.h"
#include "dispmap/meso/solid.h"
#include "dispmap/kernels/meso_march.h"
#include "dispmap/kernels/meso_shade.h"

namespace dispmap {

struct MesoHit {
    bool hit = false; ///< false: the ray left through the top (view: a miss; shadow: lit)
    double t = 0;
    int iterations = 0;
    glm::dvec3 point(const glm::dvec3& o, const glm::dvec3& d) const { return o + t * d; }
};

/// The tolerance of the root solver's tangent band (kernels/meso.h, dmQuadraticRoots).
template <class real> constexpr real mesoRootTolerance() { return real(16) * std::numeric_limits<real>::epsilon(); }

namespace detail {
template <class real> using v3 = glm::vec<3, real, glm::defaultp>;
template <class real> using v4 = glm::vec<4, real, glm::defaultp>;
inline void checkRay(const glm::dvec3& o, const glm::dvec3& d, const char* what) {
    const double l = glm::length(d);
    if (!std::isfinite(o.x + o.y + o.z) || !std::isfinite(l) || std::abs(l - 1.0) > 1e-6)
        throw ArgumentError(std::string(what) + ": the ray needs a finite origin and a unit direction");
}
} // namespace detail

} // namespace dispmap

namespace dispmap::kern {
/// The maps the loops of kernels/meso_march.h read on the CPU (any may be null when the
/// marcher at hand does not read it; the dense DDM is read when it is set, else the compressed
/// one). The fetch functions below are the CPU's side of the loops' memory.
template <typename real> struct DmMesoMapsT {
    int layers = 0;
    int width = 0, height = 0; ///< the tile's voxels (read by the solid's march)
    const MesoHeightField* field = nullptr;
    const DistanceMap* distance = nullptr;
    const DirectionalDistanceMap* dense = nullptr;
    const CompressedDdm* compressed = nullptr;
    const ColumnQuadrics* quadrics = nullptr;
    const MesoAlbedo* image = nullptr; ///< the one image sampled (its words from 0 on)
    const MesoSolid* solid = nullptr;  ///< a solid's triangle lists (meso/solid.h)
};
template <typename real> float dmMesoFetchDistance(const DmMesoMapsT<real>& m, int i, int j, int k) { return m.distance->at(i, j, k); }
template <typename real> float dmMesoFetchDdm(const DmMesoMapsT<real>& m, int c, int i, int j, int k) {
    return m.dense ? m.dense->at(c, i, j, k) : m.compressed->lookup(c, i, j, k);
}
template <typename real> glm::vec4 dmMesoFetchCell(const DmMesoMapsT<real>& m, int i, int j) { return m.field->cell(i, j); }
template <typename real> glm::vec4 dmMesoFetchQuadric(const DmMesoMapsT<real>& m, int i, int j, int part) {
    const ColumnQuadrics& q = *m.quadrics;
    return q.q[3 * (static_cast<std::size_t>(dispmap::detail::wrapIndex(j, q.height)) * static_cast<std::size_t>(q.width) +
                    static_cast<std::size_t>(dispmap::detail::wrapIndex(i, q.width))) +
               static_cast<std::size_t>(part)];
}
template <typename real> std::uint32_t dmMesoFetchImage(const DmMesoMapsT<real>& m, int i) { return m.image->words[static_cast<std::size_t>(i)]; }
// The solid's side of kernels/meso_march.h's memory (march.glsl reads packSolid's buffers):
// voxel (i, j, k)'s entries (i and j wrapped), an entry's word and a triangle's rows in `real`.
template <typename real> ivec2 dmMesoFetchSolidRange(const DmMesoMapsT<real>& m, int i, int j, int k) {
    const std::size_t v = m.solid->voxelIndex(i, j, k);
    return ivec2(static_cast<int>(m.solid->entryStart[v]), static_cast<int>(m.solid->entryStart[v + 1]));
}
template <typename real> std::uint32_t dmMesoFetchSolidEntry(const DmMesoMapsT<real>& m, int e) {
    return m.solid->entryWord(static_cast<std::size_t>(e));
}
template <typename real> glm::vec<4, real> dmMesoFetchSolidTriangle(const DmMesoMapsT<real>& m, int t, int part) {
    return glm::vec<4, real>(m.solid->triangleRow(static_cast<std::size_t>(t), part));
}
} // namespace dispmap::kern

namespace dispmap {

/// The image (an albedo or a normal map) at texture coordinate uv (tiles) and mip level lod
/// (kern::dmMesoImage, as the renderer's fragment shader samples it), RGBA in [0, 1].
/// ArgumentError for an empty image, words that do not hold one (mesoAlbedoProblem), or a
/// coordinate or level that is not finite.
template <class real> glm::vec<4, real> sampleMesoAlbedo(const MesoAlbedo& a, const glm::dvec2& uv, double lod) {
    if (a.words.empty()) throw ArgumentError("sampleMesoAlbedo: the albedo is empty");
    if (const std::string why = mesoAlbedoProblem(a); !why.empty()) throw ArgumentError("sampleMesoAlbedo: the image's words are not an image: " + why);
    if (!std::isfinite(uv.x + uv.y + lod)) throw ArgumentError("sampleMesoAlbedo: texture coordinate or level not finite");
    kern::DmMesoMapsT<real> m;
    m.image = &a;
    return kern::dmMesoImage<real>(m, 0, glm::vec<2, real>(uv), real(lod));
}

/// The tangent-space unit normal a normal map holds at texture coordinate uv and level lod
/// (kern::dmNormalMapTangent of its trilinear sample, as the renderer reads it): scale
/// multiplies x and y (glTF's normalTexture.scale), greenT is -1 for green up (OpenGL, glTF,
/// normalMapFromHeights) and +1 for green down (DirectX). ArgumentError as sampleMesoAlbedo,
/// and for a scale that is not finite or a greenT other than +-1.
template <class real> glm::vec<3, real> sampleMesoNormal(const MesoAlbedo& map, const glm::dvec2& uv, double lod, double scale, double greenT) {
    if (!std::isfinite(scale) || (greenT != 1.0 && greenT != -1.0))
        throw ArgumentError("sampleMesoNormal: the scale must be finite and greenT +1 or -1");
    return kern::dmNormalMapTangent<real>(sampleMesoAlbedo<real>(map, uv, lod), real(scale), real(greenT));
}

/// The exact reference: the ray against the bilinear height field column by column (2D DDA),
/// with the exact root of each column's quadratic (dmRayHeightCell), in `real`. Stops as a miss
/// when the ray rises through the top or has crossed maxColumns columns.
template <class real>
MesoHit marchReference(const MesoHeightField& hf, const glm::dvec3& o0, const glm::dvec3& d0, int maxColumns = 1 << 20) {
    detail::checkRay(o0, d0, "marchReference");
    using V3 = detail::v3<real>;
    const V3 o(o0), d(d0);
    const real L = static_cast<real>(hf.layers);
    MesoHit r;
    real t = 0;
    if (o.z > L) { // come down to the top plane first
        if (!(d.z < 0)) return r;
        t = kern::dmPlaneHit(o, d, L);
    }
    const V3 dxy(d.x, d.y, real(0));
    glm::ivec3 c = kern::dmVoxelAt(V3(o + d * t), d);
    for (int n = 0; n < maxColumns; ++n) {
        ++r.iterations;
        int axis;
        const real tExit = kern::dmVoxelExit(V3(o.x, o.y, 0), dxy, glm::ivec3(c.x, c.y, 0), axis);
        const V3 local = (o + d * t) - V3(static_cast<real>(c.x), static_cast<real>(c.y), real(0));
        real s;
        const real len = std::max(tExit - t, real(0));
        if (kern::dmRayHeightCell(local, d, detail::v4<real>(hf.cell(c.x, c.y)), len, mesoRootTolerance<real>(), s)) {
            r.hit = true;
            r.t = static_cast<double>(t + s);
            return r;
        }
        if (d.z >= 0 && o.z + d.z * tExit >= L) return r; // rose through the top
        t = std::max(tExit, t);
        c = kern::dmVoxelStep(c, d, axis);
    }
    return r;
}

namespace detail {
// A distance map the marchers can read (`who` names the caller).
inline void checkDistanceMap(const DistanceMap& m, const char* who) {
    if (m.width <= 0 || m.height <= 0 || m.layers <= 0 || m.d.empty())
        throw ArgumentError(std::string(who) + ": the distance map was not built (MesoMapOptions::distance, or a technique that reads it)");
}
} // namespace detail

/// Donnelly's sphere tracing: `iterations` steps of the trilinearly read distance, or fewer
/// when it falls to eps or below (eps < 0: the fixed count, as the chapter's shader, except
/// that a signed distance at or below eps, deep inside the solid, still stops it).
/// The hit is where the last step ends; a ray that rose through the top is a miss.
/// ArgumentError for a map that was not built.
template <class real> MesoHit marchDistanceMap(const DistanceMap& m, const glm::dvec3& o0, const glm::dvec3& d0, int iterations, double eps) {
    detail::checkRay(o0, d0, "marchDistanceMap");
    detail::checkDistanceMap(m, "marchDistanceMap");
    kern::DmMesoMapsT<real> maps;
    maps.layers = m.layers;
    maps.distance = &m;
    MesoHit r;
    real t = 0;
    r.hit = kern::dmMesoMarchDistance(maps, detail::v3<real>(o0), detail::v3<real>(d0), iterations, static_cast<real>(eps), t,
                                      r.iterations);
    r.t = static_cast<double>(t);
    return r;
}

/// How a curved base bends a view ray in the slab (kern::dmBentPoint): `bend` the coefficient of
/// t^2 of the shell's quadric along the ray (kern::dmShellBend at the entry) and `curve` the
/// base's most convex principal curvature in voxels (kern::dmShellVoxels(shape, vpu).w, <= 0),
/// which maps the quadric's level to the depth below the top (exactly on a ball or a cylinder).
/// curve 0: the depth is the quadric's level, the ray a parabola. A plain double converts to
/// a bend with curve 0.
struct MesoBend {
    double bend = 0, curve = 0;
    MesoBend(double b = 0, double c = 0) : bend(b), curve(c) {}
};

namespace detail {
// A bent view ray the bent marchers take (`who` names the caller), in a slab `layers` deep: it
// enters at the top going down, with a finite bend and a curve in range.
inline void checkBentRay(const glm::dvec3& o, const glm::dvec3& d, const MesoBend& b, int layers, const char* who) {
    if (!(o.z == layers) || !(d.z < 0) || !std::isfinite(b.bend))
        throw ArgumentError(std::string(who) + ": the ray must enter at the top (z = layers) going down, with a finite bend");
    if (!(b.curve <= 0 && b.curve * layers > -1))
        throw ArgumentError(std::string(who) + ": the bend's curve must be <= 0 and above -1 / layers (kern::dmShellLimit keeps it above -1/2)");
}
} // namespace detail

/// marchDistanceMap along the ray bent by a curved base (kern::dmMesoMarchDistanceBent: each
/// step moves the point along the curve no farther than the distance read; `bend` (MesoBend) at
/// the entry o0, a view ray from the top: o0.z = layers, d0 going down). The hit's t is the
/// straight ray's; `slabPoint` (if given) gets the hit in the slab's coordinates, where the
/// detail is read. ArgumentError for an entry off the top, an upward ray or a bend that is not
/// finite (or a curve out of range).
template <class real>
MesoHit marchDistanceMapBent(const DistanceMap& m, const glm::dvec3& o0, const glm::dvec3& d0, MesoBend bend, int iterations, double eps,
                             glm::dvec3* slabPoint = nullptr) {
    detail::checkRay(o0, d0, "marchDistanceMapBent");
    detail::checkDistanceMap(m, "marchDistanceMapBent");
    detail::checkBentRay(o0, d0, bend, m.layers, "marchDistanceMapBent");
    kern::DmMesoMapsT<real> maps;
    maps.layers = m.layers;
    maps.distance = &m;
    MesoHit r;
    real t = 0;
    glm::vec<3, real> p;
    r.hit = kern::dmMesoMarchDistanceBent(maps, detail::v3<real>(o0), detail::v3<real>(d0), static_cast<real>(bend.bend),
                                          static_cast<real>(bend.curve), iterations, static_cast<real>(eps), t, p, r.iterations);
    r.t = static_cast<double>(t);
    if (slabPoint) *slabPoint = glm::dvec3(p);
    return r;
}

/// Options of the conservative (directional) marcher.
struct DdmMarch {
    int maxIterations = 256;
    bool quadrics = true; ///< intersect the quadric in voxels whose distance is 0 (else stop there)
    int exitRule = 1;     ///< 1: step exit(v) + d; 0: the paper's t + d
};

namespace detail {
// The kernels' view of a DDM (dense or compressed), its layers and quadrics, after the checks
// both DDM marchers make (`who` names the caller).
template <class real, class Map>
kern::DmMesoMapsT<real> ddmMaps(const Map& map, int layers, const ColumnQuadrics* quadrics, const glm::dvec3& o0, const glm::dvec3& d0,
                                const DdmMarch& opt, const char* who) {
    checkRay(o0, d0, who);
    if (opt.quadrics && !quadrics) throw ArgumentError(std::string(who) + ": quadric intersection needs the column quadrics");
    kern::DmMesoMapsT<real> maps;
    maps.layers = layers;
    maps.quadrics = quadrics;
    map.bind(maps);
    return maps;
}
} // namespace detail

/// Algorithm 3.1 (sphere tracing a conservative DDM, quadric intersection 3.2, voxel walls
/// 3.3; the loop is kern::dmMesoMarchDdm) over DenseDdmView or CompressedDdmView; quadrics may be
/// null only when options.quadrics is false. A ray that runs out of iterations counts as a hit
/// at its last point (short of the surface: conservative), so a shadow ray never leaks light
/// and a view ray never shows the sky through the surface. ArgumentError for an upward ray on
/// a map without shadow cones.
template <class real, class Map>
MesoHit marchDdm(const Map& map, const ConeSet& cones, int layers, const ColumnQuadrics* quadrics, const glm::dvec3& o0,
                 const glm::dvec3& d0, const DdmMarch& opt) {
    if (d0.z > 0 && !cones.isotropic && !cones.shadow) throw ArgumentError("marchDdm: an upward (shadow) ray needs shadow cones");
    const kern::DmMesoMapsT<real> maps = detail::ddmMaps<real>(map, layers, quadrics, o0, d0, opt, "marchDdm");
    MesoHit r;
    real t = 0;
    r.hit = kern::dmMesoMarchDdm(maps, detail::v3<real>(o0), detail::v3<real>(d0), cones.kernelM(), cones.n, opt.maxIterations,
                                 opt.quadrics, opt.exitRule, mesoRootTolerance<real>(), real(3.0e38), t, r.iterations);
    r.t = static_cast<double>(t);
    return r;
}

/// How far (voxels) each chord of a bent ray may lie from its curve (kern::dmMesoMarchDdmBent).
inline constexpr double kMesoChordError = 0.05;
/// The most convex curvature times the slab's depth that the renderer's silhouettes and bent
/// rays take from a base (kern::dmShellLimit): where the base is tighter, half the depth is the
/// radius they see (so that a thick slab on a thin part does not show holes).
inline constexpr double kShellCurvatureLimit = 0.5;

/// marchDdm along the ray bent by a curved base (kern::dmMesoMarchDdmBent; `bend` (MesoBend) at
/// the entry o0, a view ray from the top: o0.z = layers, d0 going down).
/// The hit's t is the straight ray's; `slabPoint` (if given) gets the hit in the slab's
/// coordinates, where the detail is read. ArgumentError as marchDdm, and for an entry off the
/// top, an upward ray or a bend that is not finite.
template <class real, class Map>
MesoHit marchDdmBent(const Map& map, const ConeSet& cones, int layers, const ColumnQuadrics* quadrics, const glm::dvec3& o0,
                     const glm::dvec3& d0, MesoBend bend, const DdmMarch& opt, glm::dvec3* slabPoint = nullptr) {
    if (!cones.isotropic && !cones.shadow)
        throw ArgumentError("marchDdmBent: a ray bent back up marches upward chords: the map needs shadow cones (or to be isotropic)");
    const kern::DmMesoMapsT<real> maps = detail::ddmMaps<real>(map, layers, quadrics, o0, d0, opt, "marchDdmBent");
    detail::checkBentRay(o0, d0, bend, layers, "marchDdmBent");
    MesoHit r;
    real t = 0;
    glm::vec<3, real> p;
    int triangle;
    glm::vec<2, real> uv;
    r.hit = kern::dmMesoMarchDdmBent(maps, detail::v3<real>(o0), detail::v3<real>(d0), static_cast<real>(bend.bend),
                                     static_cast<real>(bend.curve), cones.kernelM(), cones.n, opt.maxIterations, opt.quadrics, false, opt.exitRule, mesoRootTolerance<real>(), real(kMesoChordError), t,
                                     p, r.iterations, triangle, uv);
    r.t = static_cast<double>(t);
    if (slabPoint) *slabPoint = glm::dvec3(p);
    return r;
}

/// The dense map, read directly.
struct DenseDdmView {
    const DirectionalDistanceMap* m;
    float distance(int c, int i, int j, int k) const { return m->at(c, i, j, k); }
    template <class real> void bind(kern::DmMesoMapsT<real>& maps) const { maps.dense = m; }
};
/// The compressed map, read through its grid and atlas (Appendix A.2).
struct CompressedDdmView {
    const CompressedDdm* m;
    float distance(int c, int i, int j, int k) const { return m->lookup(c, i, j, k); }
    template <class real> void bind(kern::DmMesoMapsT<real>& maps) const { maps.compressed = m; }
};

/// Most linear steps of relief mapping and POM (4 per voxel layer at the most layers, 256): the
/// renderer and the CPU marchers refuse more (a bent ray takes up to 4 times as many).
inline constexpr int kMaxMesoLinearSteps = 1024;

namespace detail {
// What relief mapping and POM take: a finite view ray going down, 1 .. kMaxMesoLinearSteps steps.
inline void checkHeightSearch(const glm::dvec3& o, const glm::dvec3& d, int linear, const char* what) {
    checkRay(o, d, what);
    if (!(d.z < 0)) throw ArgumentError("relief mapping / POM: view rays go down (d.z < 0)");
    if (linear < 1 || linear > kMaxMesoLinearSteps)
        throw ArgumentError("relief mapping / POM: " + std::to_string(linear) + " linear steps, not in [1, " + std::to_string(kMaxMesoLinearSteps) + "]");
}
} // namespace detail

/// Relief mapping (Policarpo et al. 2005): `linear` equal steps from the top to the bottom
/// plane until a sample is at or below the surface, then `binary` bisections; the hit is the
/// final bracket's midpoint. View rays only (d.z < 0).
/// Parallax occlusion mapping (Tatarchuk 2006) with binary < 0: the same linear search, then
/// the crossing of the segment between the last two samples.
template <class real> MesoHit marchHeightSearch(const MesoHeightField& hf, const glm::dvec3& o0, const glm::dvec3& d0, int linear, int binary) {
    detail::checkHeightSearch(o0, d0, linear, "marchHeightSearch");
    kern::DmMesoMapsT<real> maps;
    maps.layers = hf.layers;
    maps.field = &hf;
    MesoHit r;
    real t = 0;
    r.hit = kern::dmMesoMarchHeight(maps, detail::v3<real>(o0), detail::v3<real>(d0), linear, binary, t, r.iterations);
    r.t = static_cast<double>(t);
    return r;
}

/// marchHeightSearch along the ray bent by a curved base (kern::dmMesoMarchHeightBent; `bend`
/// (MesoBend) at the entry o0, a view ray from the top: o0.z = layers, d0 going down). The hit's t is the straight ray's; `slabPoint` (if given) gets the hit in the slab's
/// coordinates, where the detail is read. A ray a convex base bends back up to the top without
/// meeting the surface misses. ArgumentError as marchHeightSearch, and for an entry off the top
/// or a bend that is not finite.
template <class real>
MesoHit marchHeightSearchBent(const MesoHeightField& hf, const glm::dvec3& o0, const glm::dvec3& d0, MesoBend bend, int linear, int binary,
                              glm::dvec3* slabPoint = nullptr) {
    detail::checkHeightSearch(o0, d0, linear, "marchHeightSearchBent");
    detail::checkBentRay(o0, d0, bend, hf.layers, "marchHeightSearchBent");
    kern::DmMesoMapsT<real> maps;
    maps.layers = hf.layers;
    maps.field = &hf;
    MesoHit r;
    real t = 0;
    glm::vec<3, real> p;
    r.hit = kern::dmMesoMarchHeightBent(maps, detail::v3<real>(o0), detail::v3<real>(d0), static_cast<real>(bend.bend),
                                        static_cast<real>(bend.curve), linear, binary, t, p, r.iterations);
    r.t = static_cast<double>(t);
    if (slabPoint) *slabPoint = glm::dvec3(p);
    return r;
}

/// The exact first hit of o + t d, t in [t0, t1], on the triangles listed for voxel v (every
/// copy of each across the periodic seam next to v: the reference does not trust the copy its
/// entry names), Moller-Trumbore in double with the mesh's own vertices.
inline bool raySolidVoxel(const MesoSolid& s, const glm::ivec3& v, const glm::dvec3& o, const glm::dvec3& d, double t0, double t1, double& t) {
    const glm::dvec3 shift(std::floor(static_cast<double>(v.x) / s.width) * s.width, std::floor(static_cast<double>(v.y) / s.height) * s.height, 0);
    bool hit = false;
    t = t1;
    const std::size_t vi = s.voxelIndex(v.x, v.y, v.z);
    for (std::uint32_t e = s.entryStart[vi]; e < s.entryStart[vi + 1]; ++e) {
        const auto& tri = s.triangles[static_cast<std::size_t>(s.entries[e].triangle)];
        const glm::dvec3 a = s.vertices[static_cast<std::size_t>(tri[0])] + shift;
        const glm::dvec3 e1 = s.vertices[static_cast<std::size_t>(tri[1])] + shift - a, e2 = s.vertices[static_cast<std::size_t>(tri[2])] + shift - a;
        // The triangle may lie up to kMaxSolidTileReach tiles beyond the one v is in: try every
        // shift along each axis that may put it near v.
        const int R = static_cast<int>(kMaxSolidTileReach) + 1;
        for (int sy = -R; sy <= R; ++sy)
            for (int sx = -R; sx <= R; ++sx) {
                const glm::dvec3 q = a + glm::dvec3(sx * s.width, sy * s.height, 0);
                const glm::dvec3 p = glm::cross(d, e2);
                const double det = glm::dot(e1, p);
                if (std::abs(det) < 1e-300) continue;
                const glm::dvec3 w = o - q;
                const double u = glm::dot(w, p) / det;
                if (u < 0 || u > 1) continue;
                const glm::dvec3 qq = glm::cross(w, e1);
                const double vv = glm::dot(d, qq) / det;
                if (vv < 0 || u + vv > 1) continue;
                const double tt = glm::dot(e2, qq) / det;
                if (tt >= t0 && tt <= t) {
                    t = tt;
                    hit = true;
                }
            }
    }
    return hit;
}

/// A hit of the solid marchers: MesoHit, and the triangle hit (-1: the floor or no triangle)
/// with the barycentric (u, v) on it.
struct MesoSolidHit : MesoHit {
    int triangle = -1;
    glm::dvec2 uv{0};
};

namespace detail {
// The kernels' view of a solid's DDM after the checks both solid marchers make (`who`).
template <class real, class Map>
kern::DmMesoMapsT<real> solidMaps(const Map& map, const ConeSet& cones, const MesoSolid& s, const glm::dvec3& o, const glm::dvec3& d,
                                  bool rises, const char* who) {
    checkRay(o, d, who);
    if (rises && !cones.isotropic && !cones.shadow)
        throw ArgumentError(std::string(who) + (d.z > 0 ? ": an upward (shadow) ray needs shadow cones"
                                                        : ": a ray bent back up marches upward chords: the map needs shadow cones (or to be isotropic)"));
    if (map.m->width != s.width || map.m->height != s.height || map.m->layers != s.layers || s.entryStart.size() != s.voxelSolid.size() + 1)
        throw ArgumentError(std::string(who) + ": the map and the solid differ in size (buildMesoSolidMaps builds both)");
    kern::DmMesoMapsT<real> maps;
    maps.layers = s.layers;
    maps.width = s.width;
    maps.height = s.height;
    maps.solid = &s;
    map.bind(maps);
    return maps;
}
} // namespace detail

/// Algorithm 3.1 over the solid's (dense or compressed) DDM with exact triangle tests in the
/// voxels whose distance is 0 (kern::dmMesoMarchDdmSolid, the loop the GPU runs), in `real`;
/// the floor z = 0 is a hit. ArgumentError for an upward ray on a map without shadow cones.
template <class real = double, class Map>
MesoSolidHit marchDdmSolid(const Map& map, const ConeSet& cones, const MesoSolid& s, const glm::dvec3& o, const glm::dvec3& d,
                           int maxIterations = 1024, int exitRule = 1) {
    const kern::DmMesoMapsT<real> maps = detail::solidMaps<real>(map, cones, s, o, d, d.z > 0, "marchDdmSolid");
    MesoSolidHit r;
    real t = 0;
    glm::vec<2, real> uv(0);
    r.hit = kern::dmMesoMarchDdmSolid(maps, detail::v3<real>(o), detail::v3<real>(d), cones.kernelM(), cones.n, maxIterations, exitRule,
                                      mesoRootTolerance<real>(), real(3.0e38), t, r.iterations, r.triangle, uv);
    r.t = static_cast<double>(t);
    r.uv = glm::dvec2(uv);
    return r;
}

/// marchDdmSolid along the ray bent by a curved base (kern::dmMesoMarchDdmBent with `solid`:
/// chords within kMesoChordError voxels of the curve, each marched with the solid's exact
/// triangle tests; `bend` (MesoBend) at the entry o, a view ray from the top: o.z = layers, d
/// going down). The hit's t is the straight ray's; `slabPoint` (if given) gets
/// the hit in the slab's coordinates, where the triangle is. ArgumentError as marchDdmSolid,
/// for a map without shadow cones (a convex base bends rays back up), an entry off the top, an
/// upward ray or a bend that is not finite.
template <class real = double, class Map>
MesoSolidHit marchDdmSolidBent(const Map& map, const ConeSet& cones, const MesoSolid& s, const glm::dvec3& o, const glm::dvec3& d, MesoBend bend,
                               int maxIterations = 1024, int exitRule = 1, glm::dvec3* slabPoint = nullptr) {
    const kern::DmMesoMapsT<real> maps = detail::solidMaps<real>(map, cones, s, o, d, true, "marchDdmSolidBent");
    detail::checkBentRay(o, d, bend, s.layers, "marchDdmSolidBent");
    MesoSolidHit r;
    real t = 0;
    glm::vec<3, real> p;
    glm::vec<2, real> uv(0);
    r.hit = kern::dmMesoMarchDdmBent(maps, detail::v3<real>(o), detail::v3<real>(d), static_cast<real>(bend.bend),
                                     static_cast<real>(bend.curve), cones.kernelM(), cones.n, maxIterations, false, true, exitRule, mesoRootTolerance<real>(), real(kMesoChordError), t, p, r.iterations,
                                     r.triangle, uv);
    r.t = static_cast<double>(t);
    r.uv = glm::dvec2(uv);
    if (slabPoint) *slabPoint = glm::dvec3(p);
    return r;
}

/// The exact reference for the solid: every voxel along the ray (3D DDA), its triangles, the
/// floor. tMax: the walk stops, as a miss with t > tMax, once it has passed tMax (a segment,
/// e.g. a chord of a bent ray); a crossing found beyond it in the voxel where it stops is
/// returned as it is.
inline MesoHit marchSolidReference(const MesoSolid& s, const glm::dvec3& o, const glm::dvec3& d, int maxVoxels = 1 << 20,
                                   double tMax = std::numeric_limits<double>::infinity()) {
    detail::checkRay(o, d, "marchSolidReference");
    MesoHit r;
    double t = 0;
    glm::ivec3 v = kern::dmVoxelAt(o, d);
    for (int i = 0; i < maxVoxels; ++i) {
        if (kern::dmDdmLeftSlab(v, s.layers, o, d, t, r.hit)) break;
        if (t > tMax) {
            r.hit = false;
            break;
        }
        ++r.iterations;
        int axis;
        const double tExit = kern::dmVoxelExit(o, d, v, axis);
        double th;
        if (raySolidVoxel(s, v, o, d, t, std::max(tExit, t), th)) {
            r.hit = true;
            t = th;
            break;
        }
        t = std::max(t, tExit);
        v = kern::dmVoxelStep(v, d, axis);
    }
    r.t = t;
    return r;
}

/// Every map the marchers read, built from one height field (what `dispmap meso` builds and
/// the GPU renderer uploads). A map a scene does not need is not built: its sizes are set and
/// its data left empty (the flags below; mesoMapOptionsFor picks them from a technique).
struct MesoMapOptions {
    ConeSet cones{4, 1, true, false}; ///< view and shadow cones of the DDM
    int block = 4;                    ///< compression block size (must divide the sizes)
    /// Free-space blocks whose values spread by more than this (voxels) are stored whole
    /// (compressDdm; +Inf: the paper's rule, least memory, more iterations).
    float compressionSpread = kDefaultCompressionSpread;
    int distanceSubsamples = 4;       ///< Donnelly's map: column-model samples per texel
    bool distance = true, ddm = true, quadrics = true;
    int threads = 0; ///< threads of the map builders (core/parallel.h; the same maps for every count)
};
struct MesoMaps {
    MesoHeightField field; ///< a solid's: its sizes, no heights
    DistanceMap distance;
    CompressedDdm ddm;
    ColumnQuadrics quadrics;
    std::size_t denseDdmBytes = 0;
    MesoSolid solid; ///< non-height-field detail (buildMesoSolidMaps), else empty
    bool isSolid() const { return solid.width > 0; }
};
inline MesoMaps buildMesoMaps(const MesoHeightField& field, const MesoMapOptions& options = {}) {
    MesoMaps m;
    m.field = field;
    if (options.distance) {
        m.distance = buildDistanceMap(field, options.distanceSubsamples, options.threads);
    } else {
        m.distance.width = field.width;
        m.distance.height = field.height;
        m.distance.layers = field.layers;
    }
    if (options.ddm) {
        const DirectionalDistanceMap dense = buildDdm(field, options.cones, 2, 0, options.threads);
        m.denseDdmBytes = dense.bytes();
        m.ddm = compressDdm(dense, options.block, options.compressionSpread);
    } else {
        options.cones.validate();
        CompressedDdm& c = m.ddm;
        c.width = field.width;
        c.height = field.height;
        c.layers = field.layers;
        c.block = options.block;
        c.cones = options.cones;
    }
    if (options.quadrics) {
        m.quadrics = buildColumnQuadrics(field);
    } else {
        m.quadrics.width = field.width;
        m.quadrics.height = field.height;
    }
    return m;
}

/// The maps of a non-height-field solid (meso/solid.h): its DDM (options.cones, compressed
/// as buildMesoMaps compresses) and, when options.distance, Donnelly's map of it; no quadrics
/// (the DDM march tests the triangles of its 0 voxels), the field holds only the sizes. The
/// marchers that read heights (relief mapping, POM) do not apply.
inline MesoMaps buildMesoSolidMaps(MesoSolid solid, const MesoMapOptions& options = {}) {
    if (solid.width <= 0 || solid.entryStart.empty()) throw ArgumentError("solid mesostructure maps: the solid is empty (mesoSolidFromMesh builds one)");
    MesoMaps m;
    m.field.width = solid.width;
    m.field.height = solid.height;
    m.field.layers = solid.layers;
    if (options.distance) {
        m.distance = buildSolidDistanceMap(solid);
    } else {
        m.distance.width = solid.width;
        m.distance.height = solid.height;
        m.distance.layers = solid.layers;
    }
    const DirectionalDistanceMap dense = buildSolidDdm(solid, options.cones, 0, options.threads);
    m.denseDdmBytes = dense.bytes();
    m.ddm = compressDdm(dense, options.block, options.compressionSpread);
    m.quadrics.width = solid.width;
    m.quadrics.height = solid.height;
    m.solid = std::move(solid);
    return m;
}

/// A marcher and its knobs.
enum class MesoMethod { DistanceMap, Ddm, Relief, Pom };
struct MesoTechnique {
    MesoMethod method = MesoMethod::Ddm;
    int iterations = 64; ///< DistanceMap: the step count (eps < 0) or cap; Ddm: the cap
    double eps = -1;     ///< DistanceMap: stop when the distance is <= eps (< 0: fixed count)
    bool quadrics = true; ///< Ddm: quadric intersection in 0 voxels
    int exitRule = 1;     ///< Ddm: 1 exit(v) + d, 0 the paper's t + d
    int linear = 32;      ///< Relief / POM: linear steps
    int binary = 6;       ///< Relief: bisections (POM ignores it)
};

/// The maps `technique` reads (and the shadow rays' DDM with shadow cones and quadrics when
/// `shadows`), nothing else.
inline MesoMapOptions mesoMapOptionsFor(const MesoTechnique& technique, bool shadows, ConeSet cones = {4, 1, false, false}) {
    MesoMapOptions o;
    cones.shadow = shadows;
    o.cones = cones;
    o.distance = technique.method == MesoMethod::DistanceMap;
    o.ddm = technique.method == MesoMethod::Ddm || shadows;
    o.quadrics = (technique.method == MesoMethod::Ddm && technique.quadrics) || shadows;
    return o;
}

/// One view ray through `maps` by `technique` along the ray bent by a curved base (`bend`:
/// MesoBend at the entry): the distance map (marchDistanceMapBent), the DDM
/// (marchDdmBent; marchDdmSolidBent over a solid), relief mapping or POM
/// (marchHeightSearchBent). `slabPoint`: the hit in the slab's coordinates.
template <class real>
MesoHit marchMesoBent(const MesoMaps& maps, const MesoTechnique& tq, const glm::dvec3& o, const glm::dvec3& d, MesoBend bend,
                      glm::dvec3* slabPoint = nullptr) {
    switch (tq.method) {
    case MesoMethod::DistanceMap:
        return marchDistanceMapBent<real>(maps.distance, o, d, bend, tq.iterations, tq.eps, slabPoint);
    case MesoMethod::Ddm: {
        if (maps.isSolid())
            return marchDdmSolidBent<real>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, maps.solid, o, d, bend, tq.iterations, tq.exitRule, slabPoint);
        DdmMarch opt;
        opt.maxIterations = tq.iterations;
        opt.quadrics = tq.quadrics;
        opt.exitRule = tq.exitRule;
        return marchDdmBent<real>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, maps.field.layers, &maps.quadrics, o, d, bend, opt, slabPoint);
    }
    case MesoMethod::Relief:
    case MesoMethod::Pom:
        if (maps.isSolid()) throw ArgumentError("marchMesoBent: relief mapping and POM march height fields, not a solid");
        return marchHeightSearchBent<real>(maps.field, o, d, bend, tq.linear, tq.method == MesoMethod::Pom ? -1 : tq.binary, slabPoint);
    }
    throw ArgumentError("marchMesoBent: unknown method");
}

/// One ray through `maps` by `technique`, in `real`.
template <class real> MesoHit marchMeso(const MesoMaps& maps, const MesoTechnique& tq, const glm::dvec3& o, const glm::dvec3& d) {
    switch (tq.method) {
    case MesoMethod::DistanceMap:
        return marchDistanceMap<real>(maps.distance, o, d, tq.iterations, tq.eps);
    case MesoMethod::Ddm: {
        DdmMarch opt;
        opt.maxIterations = tq.iterations;
        opt.quadrics = tq.quadrics;
        opt.exitRule = tq.exitRule;
        if (maps.isSolid()) return marchDdmSolid<real>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, maps.solid, o, d, tq.iterations, tq.exitRule);
        return marchDdm<real>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, maps.field.layers, &maps.quadrics, o, d, opt);
    }
    case MesoMethod::Relief:
    case MesoMethod::Pom:
        if (maps.isSolid()) throw ArgumentError("marchMeso: relief mapping and POM march height fields, not a solid");
        return marchHeightSearch<real>(maps.field, o, d, tq.linear, tq.method == MesoMethod::Pom ? -1 : tq.binary);
    }
    throw ArgumentError("marchMeso: unknown method");
}

} // namespace dispmap
