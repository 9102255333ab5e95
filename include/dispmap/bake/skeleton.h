#pragma once
// The skeleton-guided initial control mesh (ICM) of Huang & Feng, "Efficient Skeleton-guided
// Displaced Subdivision Surfaces", §3.1.2: a user places joints inside a dense mesh and joins
// them by segments; the ICM is built from
//  * cuts: at every joint of valence 1 or 2, the mesh's cross-section in the plane through the
//    joint across the skeleton, approximated by an n-gon (n from the cross-section's perimeter
//    relative to the mesh's size, its points chosen by farthest-point insertion);
//  * caps: the cut of a valence-1 joint is also a face, closing the tube there;
//  * hinges: at every joint of valence 3 to 6, a box around the joint oriented so that each
//    segment leaves through its own face; the faces no segment leaves through stay in the ICM;
//  * pipes: along every segment, a band of quads (triangles where the two ends have different
//    numbers of vertices) joining its two ends (cut or hinge face).
// The result is a closed polygon mesh, oriented as the dense mesh is (outward for a dense mesh
// whose triangles face out), that ControlMesh accepts; it is the
// start of a fit (the paper subdivides it once into the all-quad initial base mesh).
//
// Skeleton file: JSON {"joints": [[x, y, z], ...], "segments": [[a, b], ...]} with 0-based
// joint indices; comments (// and /* */) are allowed, other keys are not (a misspelt key would
// otherwise be ignored silently).
//
// Every way a skeleton can fail is an ArgumentError "skeleton NAME: ..." naming the joint or
// segment and saying what to change: no joints or segments, an index out of range, a segment
// from a joint to itself, a repeated or zero-length segment, a NaN/Inf coordinate, an unused
// joint, a skeleton in several pieces, a joint of more than 6 segments, a joint outside the
// mesh, segments a box cannot separate, two segments folding back at a joint, and a segment
// too short for the cuts or hinges at its ends (they would cross). The mesh built is checked
// once more (its orientation and ControlMesh's topology checks) before it is returned.
#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "dispmap/bake/dense_mesh.h"
#include "dispmap/bake/ray_scene.h"
#include "dispmap/core/error.h"
#include "dispmap/core/file_io.h"
#include "dispmap/surface/mesh.h"

namespace dispmap {

struct Skeleton {
    std::string name;                         ///< file name, for messages
    std::vector<glm::dvec3> joints;
    std::vector<std::array<int, 2>> segments; ///< 0-based joint indices
};

/// A skeleton file is a few kilobytes; anything far larger is a wrong path.
inline constexpr std::uint64_t kMaxSkeletonFileBytes = std::uint64_t{16} << 20;
/// More joints than a hand-placed skeleton has; bounds the work (each cut casts 360 rays).
inline constexpr int kMaxSkeletonJoints = 100000;
/// Most sides a cut may have (SkeletonOptions::maxSides).
inline constexpr int kMaxCutSides = 64;
/// Rays cast in a cut's plane to find the cross-section around the joint (one per degree).
inline constexpr int kSkeletonCutRays = 360;

struct SkeletonOptions {
    /// n of a cut = round(sidesPerDiagonal * perimeter / bbox diagonal), clamped to [minSides, maxSides].
    double sidesPerDiagonal = 8.0;
    int minSides = 4, maxSides = 16;
    /// Hinge half-size = hingeScale * distance from the joint to the dense surface (then
    /// shrunk, if needed, so that every corner of the box stays inside the mesh).
    double hingeScale = 0.6;
};

struct SkeletonReport {
    int cuts = 0, hinges = 0, caps = 0;
    std::vector<int> cutSides; ///< sides of each cut, in joint order
};

namespace detail {

inline std::string skeletonNumber(double x) {
    char b[40];
    std::snprintf(b, sizeof b, "%.6g", x);
    return b;
}
inline std::string skeletonPoint(const glm::dvec3& p) {
    // Appended piecewise: GCC 12 at -O3 reports a false -Wrestrict for "(" + string.
    std::string r(1, '(');
    r += skeletonNumber(p.x);
    r += ", ";
    r += skeletonNumber(p.y);
    r += ", ";
    r += skeletonNumber(p.z);
    r += ')';
    return r;
}
[[noreturn]] inline void skeletonFail(const std::string& name, const std::string& why) {
    throw ArgumentError("skeleton " + name + ": " + why);
}
inline std::string skeletonJoint(const Skeleton& s, int j) {
    return "joint " + std::to_string(j) + " " + skeletonPoint(s.joints[static_cast<std::size_t>(j)]);
}
inline std::string skeletonSegment(const Skeleton& s, int k) {
    const std::array<int, 2>& g = s.segments[static_cast<std::size_t>(k)];
    return "segment " + std::to_string(k) + " [" + std::to_string(g[0]) + ", " + std::to_string(g[1]) + "]";
}

/// The checks that need no mesh: see the top of this file. Called by parseSkeleton and by
/// skeletonControlMesh (a Skeleton may be built in code).
inline void checkSkeleton(const Skeleton& s) {
    const std::string& n = s.name;
    if (s.joints.empty()) skeletonFail(n, "has no joints");
    if (s.joints.size() > static_cast<std::size_t>(kMaxSkeletonJoints))
        skeletonFail(n, "has " + std::to_string(s.joints.size()) + " joints, more than " + std::to_string(kMaxSkeletonJoints));
    for (std::size_t j = 0; j < s.joints.size(); ++j)
        for (int c = 0; c < 3; ++c) {
            const double x = s.joints[j][c];
            if (!std::isfinite(x))
                skeletonFail(n, "joint " + std::to_string(j) + " has coordinate " + skeletonNumber(x) + ", not a finite number");
            if (std::abs(x) > kMaxDenseCoordinate)
                skeletonFail(n, "joint " + std::to_string(j) + " has coordinate " + skeletonNumber(x) + " beyond the limit of 1e18");
        }
    const int nj = static_cast<int>(s.joints.size());
    if (s.segments.empty())
        skeletonFail(n, nj == 1 ? "has one joint and no segment: a control mesh needs at least one segment (two joints)"
                                : "has no segments");
    std::map<std::pair<int, int>, int> seen;
    std::vector<int> valence(s.joints.size(), 0);
    for (std::size_t k = 0; k < s.segments.size(); ++k) {
        const int ki = static_cast<int>(k);
        const auto [a, b] = s.segments[k];
        for (int v : {a, b})
            if (v < 0 || v >= nj)
                skeletonFail(n, skeletonSegment(s, ki) + " refers to joint " + std::to_string(v) + ", but the " +
                                    std::to_string(nj) + " joints are numbered 0 to " + std::to_string(nj - 1));
        if (a == b) skeletonFail(n, skeletonSegment(s, ki) + " joins joint " + std::to_string(a) + " to itself");
        const auto key = std::make_pair(std::min(a, b), std::max(a, b));
        if (const auto it = seen.find(key); it != seen.end())
            skeletonFail(n, skeletonSegment(s, ki) + " repeats " + skeletonSegment(s, it->second));
        seen.emplace(key, ki);
        if (s.joints[static_cast<std::size_t>(a)] == s.joints[static_cast<std::size_t>(b)])
            skeletonFail(n, skeletonSegment(s, ki) + " has zero length: joints " + std::to_string(a) + " and " +
                                std::to_string(b) + " are both at " + skeletonPoint(s.joints[static_cast<std::size_t>(a)]));
        ++valence[static_cast<std::size_t>(a)];
        ++valence[static_cast<std::size_t>(b)];
    }
    for (int j = 0; j < nj; ++j) {
        const int v = valence[static_cast<std::size_t>(j)];
        if (v == 0) skeletonFail(n, skeletonJoint(s, j) + " is not used by any segment");
        if (v > 6)
            skeletonFail(n, skeletonJoint(s, j) + " joins " + std::to_string(v) +
                                " segments; its hinge is a box of 6 faces, one per segment: split the joint into two joined ones");
    }
    // Connected: one ICM per skeleton, and a piece the others cannot reach would be a second mesh.
    std::vector<std::vector<int>> adjacent(s.joints.size());
    for (const auto& [a, b] : s.segments) {
        adjacent[static_cast<std::size_t>(a)].push_back(b);
        adjacent[static_cast<std::size_t>(b)].push_back(a);
    }
    std::vector<char> reached(s.joints.size(), 0);
    std::vector<int> stack{0};
    while (!stack.empty()) {
        const std::size_t j = static_cast<std::size_t>(stack.back());
        stack.pop_back();
        if (reached[j]) continue;
        reached[j] = 1;
        for (int o : adjacent[j])
            if (!reached[static_cast<std::size_t>(o)]) stack.push_back(o);
    }
    for (int j = 0; j < nj; ++j)
        if (!reached[static_cast<std::size_t>(j)])
            skeletonFail(n, "is not connected: " + skeletonJoint(s, j) +
                                " cannot be reached from joint 0 along segments (one skeleton makes one mesh)");
}

inline void checkSkeletonOptions(const SkeletonOptions& o, const std::string& name) {
    if (!(std::isfinite(o.sidesPerDiagonal) && o.sidesPerDiagonal > 0.0 && o.sidesPerDiagonal <= 1e6))
        skeletonFail(name, "option sidesPerDiagonal " + skeletonNumber(o.sidesPerDiagonal) + " must be above 0 and at most 1e6");
    if (o.minSides < 3 || o.maxSides > kMaxCutSides || o.minSides > o.maxSides)
        skeletonFail(name, "options minSides " + std::to_string(o.minSides) + " and maxSides " + std::to_string(o.maxSides) +
                               " must satisfy 3 <= minSides <= maxSides <= " + std::to_string(kMaxCutSides));
    if (!(std::isfinite(o.hingeScale) && o.hingeScale > 0.0 && o.hingeScale <= 1.0))
        skeletonFail(name, "option hingeScale " + skeletonNumber(o.hingeScale) + " must be above 0 and at most 1");
}

/// +1 if the dense mesh's triangles face outward (positive signed volume), -1 if inward. A
/// ray from inside leaves through a triangle whose outward normal points along the ray; this
/// sign says which of the stored normals is outward. Coordinates are taken relative to the
/// box centre so that the sum does not lose its digits far from the origin.
inline double denseOrientation(const DenseMesh& m) {
    const glm::dvec3 c = 0.5 * (m.lo + m.hi);
    double v = 0.0;
    for (const glm::uvec3& t : m.triangles) {
        const glm::dvec3 a = glm::dvec3(m.positions[t.x]) - c, b = glm::dvec3(m.positions[t.y]) - c,
                         d = glm::dvec3(m.positions[t.z]) - c;
        v += glm::dot(a, glm::cross(b, d));
    }
    return v < 0.0 ? -1.0 : 1.0;
}

/// A unit vector perpendicular to the unit vector n.
inline glm::dvec3 skeletonPerpendicular(const glm::dvec3& n) {
    const glm::dvec3 other = std::abs(n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    return glm::normalize(glm::cross(n, other));
}

/// Where the ray from p along unit d leaves the mesh from inside (the nearest crossing, if the
/// surface there faces along d); returns the distance, or -1 if it misses or enters instead.
inline double skeletonExit(const RayScene& scene, double orient, const glm::dvec3& p, const glm::dvec3& d) {
    const glm::vec3 df = glm::normalize(glm::vec3(d));
    const RayScene::Hit h = scene.intersect(glm::vec3(p), df, 0.0f, std::numeric_limits<float>::infinity());
    if (!h.hit || !(orient * static_cast<double>(glm::dot(h.normal, df)) > 0.0)) return -1.0;
    return static_cast<double>(h.t);
}

struct SkeletonCut {
    int joint = -1;
    glm::dvec3 normal{0};             ///< unit; the points run counter-clockwise around it
    std::vector<glm::dvec3> points;   ///< the n-gon, on the dense surface
    double perimeter = 0.0;           ///< of the cross-section (the polygon of all ray hits)
    int firstVertex = 0;              ///< index of points[0] in the ICM
};

/// The cut at joint j, in the plane through it with unit normal n. The cross-section around the
/// joint is found by rays in the plane: the nearest crossing along each is exactly where the
/// plane's section of the surface is first met, and a ray that leaves through a surface facing
/// along it proves the joint inside. Departing from a cross-section built from all triangles
/// straddling the plane, this keeps only the part the joint sees, which is the part that
/// belongs to its limb (a plane through a leg also cuts the other leg).
inline SkeletonCut skeletonCut(const RayScene& scene, double orient, const Skeleton& s, int j, const glm::dvec3& n,
                               double diagonal, const SkeletonOptions& o) {
    SkeletonCut cut;
    cut.joint = j;
    cut.normal = n;
    const glm::dvec3 p = s.joints[static_cast<std::size_t>(j)];
    const glm::dvec3 e1 = skeletonPerpendicular(n), e2 = glm::cross(n, e1); // e1 x e2 = n
    std::vector<glm::dvec3> hits;
    hits.reserve(kSkeletonCutRays);
    int misses = 0, entries = 0;
    for (int r = 0; r < kSkeletonCutRays; ++r) {
        const double a = 2.0 * 3.14159265358979323846 * r / kSkeletonCutRays;
        const glm::dvec3 d = std::cos(a) * e1 + std::sin(a) * e2;
        const glm::vec3 df = glm::normalize(glm::vec3(d));
        const RayScene::Hit h = scene.intersect(glm::vec3(p), df, 0.0f, std::numeric_limits<float>::infinity());
        if (!h.hit) {
            ++misses;
            continue;
        }
        if (!(orient * static_cast<double>(glm::dot(h.normal, df)) > 0.0)) { // entered: p is outside there
            ++entries;
            continue;
        }
        hits.push_back(glm::dvec3(glm::vec3(p)) + static_cast<double>(h.t) * glm::dvec3(df));
    }
    // From inside a closed mesh every ray leaves; a tenth is allowed to fail for holes in a scan
    // and rays that graze an edge.
    const int need = (9 * kSkeletonCutRays + 9) / 10;
    if (static_cast<int>(hits.size()) < need)
        skeletonFail(s.name, skeletonJoint(s, j) + " is not inside the mesh: only " + std::to_string(hits.size()) + " of " +
                                 std::to_string(kSkeletonCutRays) + " rays in its cut plane leave the surface from inside (" +
                                 std::to_string(misses) + " miss it, " + std::to_string(entries) +
                                 " meet it from outside); move the joint inside");
    for (std::size_t i = 0; i < hits.size(); ++i) cut.perimeter += glm::length(hits[(i + 1) % hits.size()] - hits[i]);
    const long wanted = std::lround(o.sidesPerDiagonal * cut.perimeter / diagonal);
    const std::size_t sides = static_cast<std::size_t>(std::clamp<long>(wanted, o.minSides, o.maxSides));
    // Farthest-point insertion (the paper, after [13]): the farthest pair first, then always the
    // point farthest from those chosen. It keeps the extremes of the section (the tips of an
    // elongated one), which a uniform spacing in angle would cut off.
    const std::size_t m = hits.size();
    std::size_t i0 = 0, i1 = 1;
    double far = -1.0;
    for (std::size_t a = 0; a < m; ++a)
        for (std::size_t b = a + 1; b < m; ++b) {
            const glm::dvec3 d = hits[a] - hits[b];
            const double d2 = glm::dot(d, d);
            if (d2 > far) {
                far = d2;
                i0 = a;
                i1 = b;
            }
        }
    std::vector<std::size_t> chosen{i0, i1};
    std::vector<double> nearest(m);
    for (std::size_t a = 0; a < m; ++a) {
        const glm::dvec3 d0 = hits[a] - hits[i0], d1 = hits[a] - hits[i1];
        nearest[a] = std::min(glm::dot(d0, d0), glm::dot(d1, d1));
    }
    while (chosen.size() < sides) {
        const std::size_t k = static_cast<std::size_t>(std::max_element(nearest.begin(), nearest.end()) - nearest.begin());
        if (!(nearest[k] > 0.0)) break; // every hit is already chosen (or coincides with one)
        chosen.push_back(k);
        for (std::size_t a = 0; a < m; ++a) {
            const glm::dvec3 d = hits[a] - hits[k];
            nearest[a] = std::min(nearest[a], glm::dot(d, d));
        }
    }
    if (chosen.size() < 3 || !(far > 0.0))
        skeletonFail(s.name, "the cross-section at " + skeletonJoint(s, j) + " is degenerate (its points coincide)");
    // Hits are stored in ray order, which is counter-clockwise around n.
    std::sort(chosen.begin(), chosen.end());
    for (std::size_t k : chosen) cut.points.push_back(hits[k]);
    return cut;
}

/// A box face: f = 2 * axis + (1 if it faces the negative axis).
inline glm::dvec3 hingeFaceNormal(const std::array<glm::dvec3, 3>& axes, int f) {
    return (f % 2 ? -1.0 : 1.0) * axes[static_cast<std::size_t>(f / 2)];
}

struct SkeletonHinge {
    int joint = -1;
    std::array<glm::dvec3, 3> axes{};   ///< right-handed orthonormal frame
    double half = 0.0;                  ///< half the box's edge
    std::vector<int> branchFace;        ///< per segment of the joint (adjacency order): its face
    int firstVertex = 0;                ///< index of corner 0 in the ICM
};

/// The orientation of the hinge box at joint j: each segment (unit directions `dirs`) must
/// leave the box through its own face, i.e. the face its direction points to most (the paper:
/// "each face of the hinge intersects with at most one skeleton segment"). Candidate frames
/// come from pairs of segments: one segment on an axis and the other in that axis' plane
/// (Gram-Schmidt), and the pair placed symmetrically about the bisector of two axes (which
/// suits two segments at any angle); among those that separate the segments, the one whose
/// worst segment is best aligned with its face wins.
inline SkeletonHinge skeletonHingeFrame(const Skeleton& s, int j, const std::vector<glm::dvec3>& dirs,
                                        const std::vector<int>& segs) {
    SkeletonHinge best;
    best.joint = j;
    double bestScore = -2.0;
    const auto consider = [&](const glm::dvec3& x, const glm::dvec3& y) {
        const std::array<glm::dvec3, 3> axes{x, y, glm::cross(x, y)};
        std::vector<int> face(dirs.size());
        std::array<bool, 6> used{};
        double score = 2.0;
        for (std::size_t b = 0; b < dirs.size(); ++b) {
            int f = 0;
            double c = -2.0;
            for (int k = 0; k < 6; ++k)
                if (const double ck = glm::dot(dirs[b], hingeFaceNormal(axes, k)); ck > c) {
                    c = ck;
                    f = k;
                }
            if (used[static_cast<std::size_t>(f)]) return; // two segments through one face
            used[static_cast<std::size_t>(f)] = true;
            face[b] = f;
            score = std::min(score, c);
        }
        if (score > bestScore) {
            bestScore = score;
            best.axes = axes;
            best.branchFace = face;
        }
    };
    for (std::size_t a = 0; a < dirs.size(); ++a)
        for (std::size_t b = 0; b < dirs.size(); ++b) {
            if (a == b) continue;
            const glm::dvec3 y = dirs[b] - glm::dot(dirs[b], dirs[a]) * dirs[a];
            if (glm::length(y) < 1e-9) continue; // parallel: no plane
            consider(dirs[a], glm::normalize(y));
            const glm::dvec3 sum = dirs[a] + dirs[b], diff = dirs[a] - dirs[b];
            if (glm::length(sum) < 1e-9 || glm::length(diff) < 1e-9) continue;
            const glm::dvec3 m = glm::normalize(sum), d = glm::normalize(diff);
            consider(glm::normalize(m + d), glm::normalize(m - d));
        }
    if (bestScore < -1.0) {
        // No frame separates them: name the two segments closest in direction.
        std::size_t ca = 0, cb = 1;
        double closest = -2.0;
        for (std::size_t a = 0; a < dirs.size(); ++a)
            for (std::size_t b = a + 1; b < dirs.size(); ++b)
                if (const double c = glm::dot(dirs[a], dirs[b]); c > closest) {
                    closest = c;
                    ca = a;
                    cb = b;
                }
        const double degrees = std::acos(std::clamp(closest, -1.0, 1.0)) * 180.0 / 3.14159265358979323846;
        skeletonFail(s.name, "no orientation of the hinge box at " + skeletonJoint(s, j) + " gives each of its " +
                                 std::to_string(dirs.size()) + " segments a face of its own (" +
                                 skeletonSegment(s, segs[ca]) + " and " + skeletonSegment(s, segs[cb]) + " leave it " +
                                 skeletonNumber(degrees) + " degrees apart): move a joint to spread the segments");
    }
    return best;
}

/// One end of a pipe: a cut, or the face of a hinge a segment leaves through.
struct SkeletonPipeEnd {
    glm::dvec3 centre{0};
    glm::dvec3 axis{0};   ///< unit, pointing into the pipe (towards the other end)
    std::vector<int> ring; ///< ICM vertices, counter-clockwise around `axis`
    std::string what;     ///< for messages
};

/// The angles of ring vertices around unit axis a (basis b1, b2, b1 x b2 = a), about centre c,
/// unwrapped to increase from the first; false unless they make exactly one turn (the ring,
/// seen along the pipe, winds once counter-clockwise around its centre).
inline bool skeletonRingAngles(const std::vector<glm::dvec3>& pos, const std::vector<int>& ring, std::size_t start,
                               const glm::dvec3& c, const glm::dvec3& b1, const glm::dvec3& b2, std::vector<double>& out) {
    constexpr double twoPi = 2.0 * 3.14159265358979323846;
    const std::size_t n = ring.size();
    out.assign(n + 1, 0.0);
    const auto angle = [&](std::size_t k) {
        const glm::dvec3 q = pos[static_cast<std::size_t>(ring[(start + k) % n])] - c;
        return std::atan2(glm::dot(q, b2), glm::dot(q, b1));
    };
    out[0] = angle(0);
    for (std::size_t k = 1; k <= n; ++k) {
        double step = std::fmod(angle(k) - angle(k - 1), twoPi);
        if (step < 0.0) step += twoPi;
        out[k] = out[k - 1] + step;
    }
    return std::abs(out[n] - out[0] - twoPi) < 1e-6;
}

/// Appends the band of faces joining ring0 (end0) and ring1 (end1) for segment k.
inline void skeletonBand(MeshDescription& d, const Skeleton& s, int k, const SkeletonPipeEnd& end0,
                         const SkeletonPipeEnd& end1, double diagonal) {
    const std::vector<glm::dvec3>& P = d.positions;
    const auto at = [&](int v) { return P[static_cast<std::size_t>(v)]; };
    // The ends must face each other: each lies wholly on the far side of the other's plane.
    // Otherwise the cuts (or a cut and a hinge face) cross inside the mesh and the pipe between
    // them would fold through itself.
    const double eps = 1e-9 * diagonal;
    const auto beyond = [&](const SkeletonPipeEnd& from, const SkeletonPipeEnd& to) {
        for (int v : to.ring)
            if (!(glm::dot(at(v) - from.centre, from.axis) > eps)) return false;
        return true;
    };
    if (!beyond(end0, end1) || !beyond(end1, end0))
        skeletonFail(s.name, skeletonSegment(s, k) + ": " + end0.what + " and " + end1.what +
                                 " cross each other inside the mesh (the segment is too short for the mesh's thickness "
                                 "there, or bends too sharply): move a joint, or lower hingeScale");
    glm::dvec3 a = end1.centre - end0.centre;
    a /= glm::length(a); // nonzero: end1's centre lies beyond end0's plane
    const glm::dvec3 b1 = skeletonPerpendicular(a), b2 = glm::cross(a, b1);
    // Both rings counter-clockwise around a: end1's ring runs counter-clockwise around its own
    // axis, which points back along the pipe.
    const std::vector<int>& r0 = end0.ring;
    const std::vector<int> r1(end1.ring.rbegin(), end1.ring.rend());
    const std::size_t n0 = r0.size(), n1 = r1.size();
    std::vector<double> A, B;
    std::size_t j0 = 0;
    bool wound = skeletonRingAngles(P, r0, 0, end0.centre, b1, b2, A);
    if (wound) {
        // Start ring1 at its vertex nearest in angle to ring0's first.
        constexpr double pi = 3.14159265358979323846;
        double bestGap = 10.0;
        for (std::size_t j = 0; j < n1; ++j) {
            const glm::dvec3 q = at(r1[j]) - end1.centre;
            double gap = std::fmod(std::atan2(glm::dot(q, b2), glm::dot(q, b1)) - A[0], 2.0 * pi);
            if (gap > pi) gap -= 2.0 * pi;
            if (gap < -pi) gap += 2.0 * pi;
            if (std::abs(gap) < std::abs(bestGap)) {
                bestGap = gap;
                j0 = j;
            }
        }
        wound = skeletonRingAngles(P, r1, j0, end1.centre, b1, b2, B);
        const double shift = A[0] + bestGap - B[0];
        for (double& x : B) x += shift;
    }
    if (!wound)
        skeletonFail(s.name, skeletonSegment(s, k) + ": " + end0.what + " and " + end1.what +
                                 " are too oblique to the segment to be joined (seen along it, one does not wind once "
                                 "around it): move a joint");
    const auto face = [&](std::initializer_list<int> vs) {
        d.faceSizes.push_back(static_cast<int>(vs.size()));
        d.faceVertices.insert(d.faceVertices.end(), vs.begin(), vs.end());
    };
    // Quad (r0[i], r0[i+1], r1[j+1], r1[j]) faces outward: along a ring is counter-clockwise
    // around the pipe, across goes along it, and (counter-clockwise) x (along) points out.
    if (n0 == n1) {
        // Equal counts: quads, with the offset that makes the connecting edges shortest.
        std::size_t bestOffset = 0;
        double bestLength = std::numeric_limits<double>::infinity();
        for (std::size_t off = 0; off < n1; ++off) {
            double sum = 0.0;
            for (std::size_t i = 0; i < n0; ++i) sum += glm::length(at(r0[i]) - at(r1[(i + off) % n1]));
            if (sum < bestLength) {
                bestLength = sum;
                bestOffset = off;
            }
        }
        for (std::size_t i = 0; i < n0; ++i)
            face({r0[i], r0[(i + 1) % n0], r1[(i + 1 + bestOffset) % n1], r1[(i + bestOffset) % n1]});
        return;
    }
    // Different counts: walk both rings by angle around the pipe, always advancing the one whose
    // next vertex comes first (a triangle); where both next vertices come at nearly the same
    // angle, advance both (a quad).
    std::size_t i = 0, j = 0;
    const auto v0 = [&](std::size_t x) { return r0[x % n0]; };
    const auto v1 = [&](std::size_t x) { return r1[(j0 + x) % n1]; };
    while (i < n0 || j < n1) {
        if (i < n0 && j < n1) {
            const double da = A[i + 1] - A[i], db = B[j + 1] - B[j];
            if (std::abs(A[i + 1] - B[j + 1]) < 0.25 * std::min(da, db)) {
                face({v0(i), v0(i + 1), v1(j + 1), v1(j)});
                ++i;
                ++j;
                continue;
            }
        }
        if (j == n1 || (i < n0 && A[i + 1] <= B[j + 1])) {
            face({v0(i), v0(i + 1), v1(j)});
            ++i;
        } else {
            face({v0(i), v1(j + 1), v1(j)});
            ++j;
        }
    }
}

} // namespace detail

/// Parses a skeleton file's JSON (see the top of this file) and checks it (detail::checkSkeleton).
/// Throws ArgumentError "skeleton NAME: ...".
inline Skeleton parseSkeleton(const std::string& text, const std::string& name) {
    using Json = nlohmann::json;
    using detail::skeletonFail;
    if (const std::size_t at = detail::jsonTooDeepAt(text, 16); at != std::string_view::npos)
        skeletonFail(name, "invalid JSON: arrays and objects nest deeper than 16 levels (at byte " + std::to_string(at) + ")");
    Json j;
    try {
        j = Json::parse(text, nullptr, true, /*ignore_comments=*/true);
    } catch (const Json::exception& e) {
        skeletonFail(name, "invalid JSON: " + detail::excerpt(e.what(), 300));
    }
    const std::string shape = "a skeleton file is {\"joints\": [[x, y, z], ...], \"segments\": [[a, b], ...]}";
    if (!j.is_object()) skeletonFail(name, "the file is not a JSON object: " + shape);
    for (const auto& [key, value] : j.items()) {
        (void)value;
        if (key != "joints" && key != "segments")
            skeletonFail(name, "unknown key '" + detail::excerpt(key) + "': " + shape);
    }
    if (!j.contains("joints") || !j["joints"].is_array()) skeletonFail(name, "'joints' is missing or not an array: " + shape);
    if (!j.contains("segments") || !j["segments"].is_array())
        skeletonFail(name, "'segments' is missing or not an array: " + shape);
    const Json& joints = j["joints"];
    const Json& segments = j["segments"];
    if (joints.size() > static_cast<std::size_t>(kMaxSkeletonJoints))
        skeletonFail(name, "has " + std::to_string(joints.size()) + " joints, more than " + std::to_string(kMaxSkeletonJoints));
    if (segments.size() > 3 * static_cast<std::size_t>(kMaxSkeletonJoints))
        skeletonFail(name, "has " + std::to_string(segments.size()) + " segments, more than " +
                               std::to_string(3 * kMaxSkeletonJoints));
    Skeleton s;
    s.name = name;
    for (std::size_t i = 0; i < joints.size(); ++i) {
        const Json& p = joints[i];
        if (!p.is_array() || p.size() != 3 || !p[0].is_number() || !p[1].is_number() || !p[2].is_number())
            skeletonFail(name, "joint " + std::to_string(i) + " is not [x, y, z] (three numbers)");
        s.joints.emplace_back(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
    }
    for (std::size_t i = 0; i < segments.size(); ++i) {
        const Json& g = segments[i];
        if (!g.is_array() || g.size() != 2 || !g[0].is_number_integer() || !g[1].is_number_integer())
            skeletonFail(name, "segment " + std::to_string(i) + " is not [a, b] (two joint indices, integers)");
        std::array<int, 2> seg{};
        for (std::size_t e = 0; e < 2; ++e) {
            // An index beyond int is refused here; the others are checked in checkSkeleton.
            const bool big = g[e].is_number_unsigned() ? g[e].get<std::uint64_t>() > static_cast<std::uint64_t>(INT_MAX)
                                                       : g[e].get<std::int64_t>() < INT_MIN;
            if (big)
                skeletonFail(name, "segment " + std::to_string(i) + " refers to joint " + g[e].dump() + ", out of range");
            seg[e] = static_cast<int>(g[e].get<std::int64_t>());
        }
        s.segments.push_back(seg);
    }
    detail::checkSkeleton(s);
    return s;
}

/// Reads and checks a skeleton file: a regular file of at most kMaxSkeletonFileBytes. Throws
/// FileError if it cannot be read, ArgumentError for its content.
inline Skeleton readSkeleton(const std::string& path) {
    const std::vector<unsigned char> bytes = detail::readFileBytes(path, "skeleton file", kMaxSkeletonFileBytes);
    return parseSkeleton(std::string(bytes.begin(), bytes.end()), path);
}

/// The ICM of `dense` (whose ray scene is `scene`) along `skeleton`: see the top of this file.
/// A closed polygon mesh, faces counter-clockwise seen from outside; vertices are the cut points
/// (on the dense surface, cut by cut in joint order) and then the hinge corners (8 per hinge,
/// inside the mesh). Throws ArgumentError "skeleton NAME: ..." for a skeleton that cannot make
/// one (see the top of this file).
inline MeshDescription skeletonControlMesh(const DenseMesh& dense, const RayScene& scene, const Skeleton& skeleton,
                                           const SkeletonOptions& options = {}, SkeletonReport* report = nullptr) {
    using namespace detail;
    const Skeleton& s = skeleton;
    checkSkeleton(s);
    checkSkeletonOptions(options, s.name);
    const double diagonal = dense.diagonal();
    const double orient = denseOrientation(dense);
    const std::size_t nj = s.joints.size();
    const auto J = [&](int j) { return s.joints[static_cast<std::size_t>(j)]; };
    // Per joint, its segments and the unit directions along them, in segment order.
    std::vector<std::vector<int>> segs(nj);
    std::vector<std::vector<glm::dvec3>> dirs(nj);
    for (std::size_t k = 0; k < s.segments.size(); ++k) {
        const auto [a, b] = s.segments[k];
        // Far shorter than any limb: its direction would be noise (or, below 1e-154, NaN).
        const double length = glm::length(J(b) - J(a));
        if (!(length > 1e-6 * diagonal))
            skeletonFail(s.name, skeletonSegment(s, static_cast<int>(k)) + " is " + skeletonNumber(length) +
                                     " long, less than a millionth of the mesh's size (" + skeletonNumber(diagonal) +
                                     "): merge its joints");
        const glm::dvec3 d = (J(b) - J(a)) / length;
        segs[static_cast<std::size_t>(a)].push_back(static_cast<int>(k));
        dirs[static_cast<std::size_t>(a)].push_back(d);
        segs[static_cast<std::size_t>(b)].push_back(static_cast<int>(k));
        dirs[static_cast<std::size_t>(b)].push_back(-d);
    }

    // Hinge frames first: they depend on the skeleton alone, so a skeleton whose segments no
    // box can separate is refused before any ray is cast.
    std::vector<int> hingeOf(nj, -1), cutOf(nj, -1);
    std::vector<SkeletonHinge> hinges;
    for (std::size_t j = 0; j < nj; ++j)
        if (segs[j].size() >= 3) {
            hingeOf[j] = static_cast<int>(hinges.size());
            hinges.push_back(skeletonHingeFrame(s, static_cast<int>(j), dirs[j], segs[j]));
        }

    MeshDescription d;
    d.name = s.name + " (skeleton ICM)";
    // Cuts.
    std::vector<SkeletonCut> cuts;
    for (std::size_t j = 0; j < nj; ++j) {
        if (segs[j].size() > 2) continue;
        const int ji = static_cast<int>(j);
        glm::dvec3 n = dirs[j][0];
        if (segs[j].size() == 2) {
            // The cut plane is across the path through the joint: its normal is the mean of the
            // direction arriving along the first segment and the one leaving along the second.
            const glm::dvec3 sum = dirs[j][1] - dirs[j][0];
            // |sum| = 2 sin(angle / 2): below 20 degrees between the segments they fold back
            // onto each other, and both pipes would leave the cut on one side.
            if (glm::length(sum) < 2.0 * std::sin(10.0 * 3.14159265358979323846 / 180.0))
                skeletonFail(s.name, "the two segments at " + skeletonJoint(s, ji) + " (" + skeletonSegment(s, segs[j][0]) +
                                         " and " + skeletonSegment(s, segs[j][1]) +
                                         ") fold back onto each other (less than 20 degrees apart): move a joint");
            n = glm::normalize(sum);
        }
        cutOf[j] = static_cast<int>(cuts.size());
        cuts.push_back(skeletonCut(scene, orient, s, ji, n, diagonal, options));
        SkeletonCut& c = cuts.back();
        c.firstVertex = static_cast<int>(d.positions.size());
        d.positions.insert(d.positions.end(), c.points.begin(), c.points.end());
    }
    // Hinge sizes and corners.
    for (SkeletonHinge& h : hinges) {
        const glm::dvec3 c = J(h.joint);
        int exits = 0, rays = 0;
        for (int x = -1; x <= 1; ++x)
            for (int y = -1; y <= 1; ++y)
                for (int z = -1; z <= 1; ++z) {
                    if (x == 0 && y == 0 && z == 0) continue;
                    ++rays;
                    if (skeletonExit(scene, orient, c, glm::normalize(glm::dvec3(x, y, z))) >= 0.0) ++exits;
                }
        const RayScene::Closest near = scene.closest(glm::vec3(c));
        if (10 * exits < 9 * rays || !near.found || !(near.distance > 0.0f))
            skeletonFail(s.name, skeletonJoint(s, h.joint) + " is not inside the mesh: only " + std::to_string(exits) + " of " +
                                     std::to_string(rays) + " rays from it leave the surface from inside; move the joint inside");
        h.half = options.hingeScale * static_cast<double>(near.distance);
        // A box of half-size h reaches h * sqrt(3) towards its corners, beyond the nearest
        // surface distance when that lies towards a corner: shrink it to keep the corners inside.
        for (int corner = 0; corner < 8; ++corner) {
            const glm::dvec3 dir = glm::normalize((corner & 1 ? 1.0 : -1.0) * h.axes[0] + (corner & 2 ? 1.0 : -1.0) * h.axes[1] +
                                                  (corner & 4 ? 1.0 : -1.0) * h.axes[2]);
            const glm::vec3 df = glm::normalize(glm::vec3(dir));
            const RayScene::Hit hit = scene.intersect(glm::vec3(c), df, 0.0f, std::numeric_limits<float>::infinity());
            if (hit.hit) h.half = std::min(h.half, 0.9 * static_cast<double>(hit.t) / std::sqrt(3.0));
        }
        h.firstVertex = static_cast<int>(d.positions.size());
        for (int corner = 0; corner < 8; ++corner)
            d.positions.push_back(c + h.half * ((corner & 1 ? 1.0 : -1.0) * h.axes[0] + (corner & 2 ? 1.0 : -1.0) * h.axes[1] +
                                                (corner & 4 ? 1.0 : -1.0) * h.axes[2]));
    }
    // The four corners of box face f, counter-clockwise seen from outside.
    const auto hingeFace = [](const SkeletonHinge& h, int f) {
        const int axis = f / 2, sign = f % 2 ? -1 : 1;
        const int u = (axis + 1) % 3, v = (axis + 2) % 3; // e_u x e_v = e_axis
        std::vector<int> ring;
        // (-u -v), (+u -v), (+u +v), (-u +v): counter-clockwise around e_axis.
        for (const auto& [su, sv] : {std::pair{-1, -1}, std::pair{1, -1}, std::pair{1, 1}, std::pair{-1, 1}}) {
            int corner = 0;
            if (sign > 0) corner |= 1 << axis;
            if (su > 0) corner |= 1 << u;
            if (sv > 0) corner |= 1 << v;
            ring.push_back(h.firstVertex + corner);
        }
        if (sign < 0) std::reverse(ring.begin(), ring.end());
        return ring;
    };
    const auto addFace = [&](const std::vector<int>& ring) {
        d.faceSizes.push_back(static_cast<int>(ring.size()));
        d.faceVertices.insert(d.faceVertices.end(), ring.begin(), ring.end());
    };
    // Caps: a valence-1 joint's cut closes its tube; its normal points into the tube.
    int caps = 0;
    for (const SkeletonCut& c : cuts)
        if (segs[static_cast<std::size_t>(c.joint)].size() == 1) {
            std::vector<int> ring;
            for (int i = static_cast<int>(c.points.size()) - 1; i >= 0; --i) ring.push_back(c.firstVertex + i);
            addFace(ring);
            ++caps;
        }
    // The hinge faces no segment leaves through.
    for (const SkeletonHinge& h : hinges)
        for (int f = 0; f < 6; ++f)
            if (std::find(h.branchFace.begin(), h.branchFace.end(), f) == h.branchFace.end()) addFace(hingeFace(h, f));
    // Pipes.
    const auto endAt = [&](int j, int k) {
        SkeletonPipeEnd e;
        const std::size_t ju = static_cast<std::size_t>(j);
        const std::size_t slot = static_cast<std::size_t>(std::find(segs[ju].begin(), segs[ju].end(), k) - segs[ju].begin());
        if (cutOf[ju] >= 0) {
            const SkeletonCut& c = cuts[static_cast<std::size_t>(cutOf[ju])];
            e.centre = J(j);
            const bool along = glm::dot(c.normal, dirs[ju][slot]) > 0.0;
            e.axis = along ? c.normal : -c.normal;
            for (std::size_t i = 0; i < c.points.size(); ++i) e.ring.push_back(c.firstVertex + static_cast<int>(i));
            if (!along) std::reverse(e.ring.begin(), e.ring.end());
            e.what = "the cut at " + skeletonJoint(s, j);
        } else {
            const SkeletonHinge& h = hinges[static_cast<std::size_t>(hingeOf[ju])];
            const int f = h.branchFace[slot];
            e.axis = hingeFaceNormal(h.axes, f);
            e.centre = J(j) + h.half * e.axis;
            e.ring = hingeFace(h, f);
            e.what = "the hinge box at " + skeletonJoint(s, j);
        }
        return e;
    };
    for (std::size_t k = 0; k < s.segments.size(); ++k)
        skeletonBand(d, s, static_cast<int>(k), endAt(s.segments[k][0], static_cast<int>(k)),
                     endAt(s.segments[k][1], static_cast<int>(k)), diagonal);

    // Last checks. Every face is oriented by construction; a negative volume means pipes
    // turned inside out between badly placed joints, which the checks above did not catch.
    double volume = 0.0;
    for (std::size_t f = 0, o = 0; f < d.faceSizes.size(); o += static_cast<std::size_t>(d.faceSizes[f]), ++f) {
        const glm::dvec3 p0 = d.positions[static_cast<std::size_t>(d.faceVertices[o])];
        for (std::size_t i = 1; i + 1 < static_cast<std::size_t>(d.faceSizes[f]); ++i)
            volume += glm::dot(p0, glm::cross(d.positions[static_cast<std::size_t>(d.faceVertices[o + i])],
                                              d.positions[static_cast<std::size_t>(d.faceVertices[o + i + 1])]));
    }
    if (!(volume > 0.0))
        skeletonFail(s.name, "the control mesh built along it is inside out (its signed volume is not positive): check "
                             "that the joints lie along the middle of the mesh's limbs");
    // A dense mesh stored inward-facing gets an inward-facing control mesh: the fit and the rays
    // compare the base surface's normals with the dense triangles' own.
    if (orient < 0.0)
        for (std::size_t f = 0, o = 0; f < d.faceSizes.size(); o += static_cast<std::size_t>(d.faceSizes[f]), ++f)
            std::reverse(d.faceVertices.begin() + static_cast<std::ptrdiff_t>(o),
                         d.faceVertices.begin() + static_cast<std::ptrdiff_t>(o + static_cast<std::size_t>(d.faceSizes[f])));
    try {
        ControlMesh check(d);
    } catch (const MeshError& e) {
        skeletonFail(s.name, std::string("the control mesh built along it is not valid: ") + e.what());
    }
    if (report) {
        report->cuts = static_cast<int>(cuts.size());
        report->hinges = static_cast<int>(hinges.size());
        report->caps = caps;
        report->cutSides.clear();
        for (const SkeletonCut& c : cuts) report->cutSides.push_back(static_cast<int>(c.points.size()));
    }
    return d;
}

} // namespace dispmap
