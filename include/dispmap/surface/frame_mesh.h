#pragma once
// FrameMesh: a tessellated surface with, at every triangle corner, the frame that per-pixel
// mesostructure marches in (kernels/meso_shade.h, dmFrameCoordinates): the position, the
// texture coordinate (s, t) of the mesostructure (one unit a tile), the world derivatives
// pS = dP/ds and pT = dP/dt, and the unit normal n. The mesostructure renderer
// (backend_vulkan MesoRenderer) draws it as the base of its marcher; the rasteriser
// interpolates the frame across each triangle.
//
// The surface is a DisplacedSurface (the Catmull-Clark limit surface with its analytic
// displacement; zero tiles give the limit surface itself), tessellated by the Tessellator. The
// positions are the tessellation's (shared between triangles: watertight); the frame of a
// corner is evaluated in the ptex face of its own triangle (TriangleMesh::triangleUVs), so
// corners on a UV seam or a face edge each carry their own face's chart. Placement:
//  * Uv: (s, t) = the mesh's UV (UvMap, with its interpolation rule) times `repeat`;
//  * Face: (s, t) = the ptex face's (u, v) times `repeat` (every face its own tiles; no UVs
//    needed, seams at face edges where neighbouring faces' parameters disagree).
// Each triangle's (s, t) are moved by whole tiles so that their smallest is in [0, 1) (the
// texture repeats; float voxel coordinates on the GPU stay precise).
// With f_u, f_v the surface's derivatives and M = d(s, t)/d(u, v) the chart's, the frame is
// [pS pT] = [f_u f_v] M^-1. Where M or the frame is singular at a corner (a UV chart
// collapsing to a point, a pole), the corner's frame is taken a step (kFrameNudge) towards
// its face's centre; a frame that stays singular is an ArgumentError naming the face.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/core/error.h"
#include "dispmap/core/parallel.h"
#include "dispmap/core/triangle_mesh.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/uv_map.h"

namespace dispmap {

struct FrameVertex {
    glm::dvec3 position{0.0};
    glm::dvec2 tex{0.0};  ///< (s, t), texture units (one unit: one tile of the mesostructure)
    glm::dvec3 pS{0.0};   ///< dP/ds, world units per texture unit
    glm::dvec3 pT{0.0};   ///< dP/dt
    glm::dvec3 normal{0.0}; ///< unit
    /// The second fundamental form in (s, t): (n . P_ss, n . P_st, n . P_tt), world units per
    /// squared texture unit, negative along a convex direction; w: the most convex principal
    /// curvature, min(k1, k2, 0) (1 / world units). Only with FrameMeshOptions::shape (else 0):
    /// what the renderer's silhouettes read (kern::dmShellExit).
    glm::dvec4 shape{0.0};
};

/// Three corners a triangle, counter-clockwise around the surface's normal.
struct FrameMesh {
    std::vector<FrameVertex> corners;
    /// Per triangle, the ptex face it lies in (TriangleMesh::triangleFaces): what groups the
    /// triangles by the material of their control face (groupFrameMesh).
    std::vector<int> faces;
    /// Triangles per group, in order, when groupFrameMesh has ordered them (group g is the
    /// triangles after the first groups[0] + ... + groups[g - 1]); empty: not grouped.
    std::vector<int> groups;
    /// Whether the corners carry FrameVertex::shape (FrameMeshOptions::shape).
    bool shaped = false;
    int triangleCount() const { return static_cast<int>(corners.size() / 3); }
    /// The world width of a tile, averaged over the corners: the mean of (|pS| + |pT|) / 2
    /// (0 without corners). What a normal map made from heights takes as the tile's width on
    /// this base (scene/meso.h, buildMesoSceneNormals).
    double meanTileWidth() const { return meanTileWidth(0, corners.size() / 3); }
    /// The same over `count` triangles from triangle `first` (one group: groupFrameMesh); 0
    /// for none or a range beyond the mesh.
    double meanTileWidth(std::size_t first, std::size_t count) const {
        if (count == 0 || first > corners.size() / 3 || count > corners.size() / 3 - first) return 0.0;
        double sum = 0;
        for (std::size_t i = 3 * first; i < 3 * (first + count); ++i) sum += 0.5 * (glm::length(corners[i].pS) + glm::length(corners[i].pT));
        return sum / static_cast<double>(3 * count);
    }
};

enum class FramePlacement { Uv, Face };

struct FrameMeshOptions {
    FramePlacement placement = FramePlacement::Uv;
    glm::dvec2 repeat{1.0, 1.0}; ///< tiles per UV unit (Uv) or per ptex face (Face); finite, > 0, <= 1e4
    /// The surface's derivatives and normal: Accurate (the Weingarten term included: pS, pT
    /// are the displaced surface's true derivatives) or Approximate (without it, §5.2: the
    /// frame of the approximate normals). Equal on a surface without displacement.
    NormalMode normals = NormalMode::Accurate;
    /// Per ptex face, its own tiles per unit in place of `repeat` (several mesostructures of
    /// different tile sizes on one base: scene/meso.h); empty: `repeat` on every face.
    std::vector<glm::dvec2> faceRepeat = {};
    /// Also each corner's second fundamental form (FrameVertex::shape), for silhouettes: from
    /// central differences of the surface's normal (in the mode `normals`) a step kShapeStep
    /// to either side in u and v (one-sided at the face's edges), II = -[f_i . n_j]
    /// symmetrised, taken to (s, t) through the chart, M^-T II M^-1. Four more evaluations a
    /// corner, so only when asked.
    bool shape = false;
};

/// Largest frame mesh (corners, three a triangle): the most that fit in the 128 MiB of storage
/// buffer every Vulkan device must bind (maxStorageBufferRange's minimum) at 80 bytes a corner
/// on the GPU, a multiple of three: 1677720 corners, 559240 triangles.
inline constexpr std::size_t kMaxFrameCorners = (std::size_t{1} << 27) / 80 / 3 * 3;

/// How far (in the face's (u, v)) a corner with a singular frame is moved towards its face's
/// centre before its frame is evaluated again.
inline constexpr double kFrameNudge = 1e-3;

/// The step in the face's (u, v) of FrameMeshOptions::shape's differences: their truncation
/// error is about kShapeStep^2 of the curvature's change over a face, their rounding about
/// 1e-16 / kShapeStep of it.
inline constexpr double kShapeStep = 1e-4;

/// Whether a frame's vectors are independent enough to solve in (dmFrameCoordinates): the
/// triple product against the product of the lengths, as a sine (1 orthogonal, 0 dependent).
inline double frameIndependence(const glm::dvec3& pS, const glm::dvec3& pT, const glm::dvec3& n) {
    const double scale = glm::length(pS) * glm::length(pT) * glm::length(n);
    const double triple = glm::dot(glm::cross(pS, pT), n);
    return scale > 0 && std::isfinite(scale) ? std::abs(triple) / scale : 0.0;
}

/// Smallest accepted frameIndependence: 1e-6, a chart sheared to within a thousandth of a
/// degree of flat; below it the solve amplifies float rounding of the view ray by 1e6.
inline constexpr double kMinFrameIndependence = 1e-6;

/// The principal curvatures (k1 <= k2, 1 / world units; negative: convex) of a corner that
/// carries its shape (FrameMeshOptions::shape): the eigenvalues of the shape operator G^-1 II,
/// G the first fundamental form of (pS, pT) and II = FrameVertex::shape's xyz.
inline glm::dvec2 principalCurvatures(const FrameVertex& v) {
    const glm::dmat2 g(glm::dot(v.pS, v.pS), glm::dot(v.pS, v.pT), glm::dot(v.pS, v.pT), glm::dot(v.pT, v.pT));
    const glm::dmat2 so = glm::inverse(g) * glm::dmat2(v.shape.x, v.shape.y, v.shape.y, v.shape.z);
    const double half = 0.5 * (so[0][0] + so[1][1]);
    const double root = std::sqrt(std::max(half * half - glm::determinant(so), 0.0));
    return {half - root, half + root};
}

/// Corners of a shaped frame mesh where the slab of `depth` world units meets itself: the base
/// is concave there with a radius below the depth (k2 > 1 / depth), so the floors of the two
/// sides of the fold overlap. Each side's detail is still marched in its own frame and the
/// depth test keeps the nearer; what is drawn there is not a single offset surface. 0 for a
/// mesh without shape.
inline std::size_t foldedCorners(const FrameMesh& mesh, double depth) {
    if (!mesh.shaped) return 0;
    return static_cast<std::size_t>(
        std::count_if(mesh.corners.begin(), mesh.corners.end(), [&](const FrameVertex& v) { return principalCurvatures(v).y * depth > 1.0; }));
}

namespace detail {
// The frame at face (u, v) = q and the texture coordinate at p (q is p, or p nudged towards the
// face's centre where the frame at p is singular). false where the frame at q is singular.
inline bool frameAt(const DisplacedSurface& surface, const UvMap* uv, const FrameMeshOptions& o, int face, glm::dvec2 p, glm::dvec2 q,
                    FrameVertex& out) {
    const SurfaceSample<double> s = surface.evaluate(face, q.x, q.y, o.normals);
    const glm::dvec2 repeat = o.faceRepeat.empty() ? o.repeat : o.faceRepeat[static_cast<std::size_t>(face)];
    glm::dvec2 ds, dt; // d(s, t)/du, d(s, t)/dv
    if (uv) {
        const UvSample w = uv->evaluate(face, q.x, q.y);
        out.tex = uv->evaluate(face, p.x, p.y).uv * repeat;
        ds = w.du * repeat;
        dt = w.dv * repeat;
    } else {
        out.tex = p * repeat;
        ds = {repeat.x, 0.0};
        dt = {0.0, repeat.y};
    }
    // M = [[s_u, s_v], [t_u, t_v]] (columns ds, dt); [pS pT] = [f_u f_v] M^-1.
    const double det = ds.x * dt.y - dt.x * ds.y;
    if (!(std::abs(det) > kMinFrameIndependence * glm::length(ds) * glm::length(dt))) return false;
    out.pS = (s.du * dt.y - s.dv * ds.y) / det;
    out.pT = (s.dv * ds.x - s.du * dt.x) / det;
    out.normal = s.normal;
    out.shape = glm::dvec4(0.0);
    if (o.shape) {
        // dn/du and dn/dv by differences within [0, 1]^2, then II(u, v) = -[f_i . n_j].
        glm::dvec3 dn[2];
        for (int i = 0; i < 2; ++i) {
            glm::dvec2 lo = q, hi = q;
            lo[i] = std::max(0.0, q[i] - kShapeStep);
            hi[i] = std::min(1.0, q[i] + kShapeStep);
            dn[i] = (surface.evaluate(face, hi.x, hi.y, o.normals).normal - surface.evaluate(face, lo.x, lo.y, o.normals).normal) / (hi[i] - lo[i]);
        }
        const double iuv = -0.5 * (glm::dot(s.du, dn[1]) + glm::dot(s.dv, dn[0]));
        const glm::dmat2 ii(-glm::dot(s.du, dn[0]), iuv, iuv, -glm::dot(s.dv, dn[1]));
        const glm::dmat2 minv = glm::inverse(glm::dmat2(ds, dt)); // M: columns d(s, t)/du, d(s, t)/dv
        const glm::dmat2 st = glm::transpose(minv) * ii * minv;
        out.shape = glm::dvec4(st[0][0], 0.5 * (st[0][1] + st[1][0]), st[1][1], 0.0);
        out.shape.w = std::min(principalCurvatures(out).x, 0.0);
    }
    return frameIndependence(out.pS, out.pT, out.normal) >= kMinFrameIndependence;
}
} // namespace detail

/// The frame mesh of `tess` (the Tessellator's mesh of `surface`), placed by the mesh's UVs
/// (`uv`, required for FramePlacement::Uv; ignored for Face). Throws ArgumentError for options
/// out of range, Uv placement without a UvMap, a UvMap of another mesh, and a corner whose
/// frame stays singular (see the header).
inline FrameMesh buildFrameMesh(const DisplacedSurface& surface, const TriangleMesh& tess, const UvMap* uv, const FrameMeshOptions& o) {
    for (int i = 0; i < 2; ++i)
        if (!(o.repeat[i] > 0 && o.repeat[i] <= 1e4))
            throw ArgumentError("frame mesh: repeat " + std::to_string(o.repeat[i]) + " is not in (0, 1e4] tiles");
    if (!o.faceRepeat.empty() && o.faceRepeat.size() != static_cast<std::size_t>(surface.base().faceCount()))
        throw ArgumentError("frame mesh: " + std::to_string(o.faceRepeat.size()) + " face repeats for " +
                            std::to_string(surface.base().faceCount()) + " ptex faces");
    for (const glm::dvec2& r : o.faceRepeat)
        for (int i = 0; i < 2; ++i)
            if (!(r[i] > 0 && r[i] <= 1e4))
                throw ArgumentError("frame mesh: a face's repeat " + std::to_string(r[i]) + " is not in (0, 1e4] tiles");
    const UvMap* map = o.placement == FramePlacement::Uv ? uv : nullptr;
    if (o.placement == FramePlacement::Uv && !map)
        throw ArgumentError("frame mesh: UV placement needs the mesh's texture coordinates (a mesh without UVs: use face placement)");
    if (map && map->ptexFaceCount() != surface.base().faceCount())
        throw ArgumentError("frame mesh: the UV map has " + std::to_string(map->ptexFaceCount()) + " ptex faces, the surface " +
                            std::to_string(surface.base().faceCount()));
    if (3 * tess.triangles.size() > kMaxFrameCorners)
        throw ArgumentError("frame mesh: " + std::to_string(tess.triangles.size()) + " triangles, more than the " +
                            std::to_string(kMaxFrameCorners / 3) + " a frame mesh may have (a lower tessellation factor)");
    FrameMesh out;
    out.shaped = o.shape;
    out.corners.resize(3 * tess.triangles.size());
    out.faces.assign(tess.triangleFaces.begin(), tess.triangleFaces.end());
    std::vector<char> singular(3 * tess.triangles.size(), 0);
    Parallel().each(tess.triangles.size(), 256, [&](std::size_t t) {
        const int face = tess.triangleFaces[t];
        for (std::size_t c = 0; c < 3; ++c) {
            const glm::dvec2 p = tess.triangleUVs[t][c];
            FrameVertex& v = out.corners[3 * t + c];
            v.position = tess.positions[static_cast<std::size_t>(tess.triangles[t][static_cast<int>(c)])];
            if (!detail::frameAt(surface, map, o, face, p, p, v) &&
                !detail::frameAt(surface, map, o, face, p, p + (glm::dvec2(0.5) - p) * (2.0 * kFrameNudge), v))
                singular[3 * t + c] = 1;
        }
        // The texture repeats every tile: each triangle's coordinates moved by whole tiles to
        // start in [0, 1), so the voxel coordinates the GPU forms in float stay small
        // (a repeat of 1e4 would otherwise leave a quarter voxel of resolution at W = 256).
        const glm::dvec2 shift = glm::floor(glm::min(glm::min(out.corners[3 * t].tex, out.corners[3 * t + 1].tex), out.corners[3 * t + 2].tex));
        for (std::size_t c = 0; c < 3; ++c) out.corners[3 * t + c].tex -= shift;
    });
    for (std::size_t i = 0; i < singular.size(); ++i)
        if (singular[i]) {
            const glm::dvec2 p = tess.triangleUVs[i / 3][i % 3];
            throw ArgumentError("frame mesh: the frame at ptex face " + std::to_string(tess.triangleFaces[i / 3]) + " (u, v) = (" +
                                std::to_string(p.x) + ", " + std::to_string(p.y) + ") is singular (" +
                                (map ? "a degenerate UV chart there" : "the surface's derivatives are dependent") + ")");
        }
    return out;
}

/// Orders the triangles of `mesh` by group, group 0 first, keeping their order within a group
/// (a stable sort: the same mesh whatever else changes), so that each group is one range of
/// corners to draw (the mesostructure renderer draws one mesostructure a range). `groupOfFace`
/// gives each ptex face's group in 0 .. groups - 1. Returns the triangle count of each group
/// (also kept in mesh.groups).
/// ArgumentError for a mesh whose `faces` do not match its corners, a face beyond
/// `groupOfFace`, or a group out of range.
inline std::vector<int> groupFrameMesh(FrameMesh& mesh, const std::vector<int>& groupOfFace, int groups) {
    const std::size_t triangles = mesh.corners.size() / 3;
    if (mesh.faces.size() != triangles || mesh.corners.size() % 3 != 0)
        throw ArgumentError("groupFrameMesh: " + std::to_string(mesh.faces.size()) + " triangle faces for " +
                            std::to_string(mesh.corners.size()) + " corners (three a triangle)");
    if (groups < 1) throw ArgumentError("groupFrameMesh: " + std::to_string(groups) + " groups (at least one)");
    std::vector<int> group(triangles), counts(static_cast<std::size_t>(groups), 0);
    for (std::size_t t = 0; t < triangles; ++t) {
        const int f = mesh.faces[t];
        if (f < 0 || static_cast<std::size_t>(f) >= groupOfFace.size())
            throw ArgumentError("groupFrameMesh: triangle " + std::to_string(t) + " lies in ptex face " + std::to_string(f) + ", beyond the " +
                                std::to_string(groupOfFace.size()) + " faces grouped");
        const int g = groupOfFace[static_cast<std::size_t>(f)];
        if (g < 0 || g >= groups)
            throw ArgumentError("groupFrameMesh: ptex face " + std::to_string(f) + " is in group " + std::to_string(g) + ", not in 0 .. " +
                                std::to_string(groups - 1));
        group[t] = g;
        ++counts[static_cast<std::size_t>(g)];
    }
    // A counting sort: each group's first slot, then the triangles in order.
    std::vector<std::size_t> next(static_cast<std::size_t>(groups), 0);
    for (std::size_t g = 1; g < next.size(); ++g) next[g] = next[g - 1] + static_cast<std::size_t>(counts[g - 1]);
    std::vector<FrameVertex> corners(mesh.corners.size());
    std::vector<int> faces(triangles);
    for (std::size_t t = 0; t < triangles; ++t) {
        const std::size_t to = next[static_cast<std::size_t>(group[t])]++;
        for (std::size_t c = 0; c < 3; ++c) corners[3 * to + c] = mesh.corners[3 * t + c];
        faces[to] = mesh.faces[t];
    }
    mesh.corners = std::move(corners);
    mesh.faces = std::move(faces);
    mesh.groups = counts;
    return counts;
}

} // namespace dispmap
