#pragma once
// PackedSurface: the base surface as the GPU reads it: the Far::PatchTable of a BaseSurface
// flattened into std430-ready arrays (control points, patch records, a per-face quadtree that
// locates the patch of a (face, u, v) like Far::PatchMap), and evaluate(), the CPU twin of the
// shader evaluation with the kernels of kernels/patch.h (docs/design.md, Conventions, "The base
// surface on the GPU").
//
// The quadtree: faceRoots[face] is kLeaf | patch when one patch covers the whole Ptex face,
// kEmpty for a hole, else the index of a node; nodes[n][q] is the child in quadrant q (the
// value dmQuadTreeStep returns: bit 0 u >= 1/2, bit 1 v >= 1/2), again kLeaf | patch, a node
// index or kEmpty. It is built from the patches' PatchParams (face, depth, NonQuadRoot, U, V)
// the way Far::PatchMap builds its own, and walked with the same rule at u, v = 1/2 and 1, so
// it finds the patch PatchMap finds. The walk, exact in floating point: node = faceRoots[face];
// while it is not a leaf, node = nodes[node][dmQuadTreeStep(uv)].
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/surface/base_surface.h"
#include "dispmap/core/error.h"
#include "dispmap/kernels/patch.h"

namespace dispmap {

/// The base surface as the GPU reads it (std430-ready arrays), built from a BaseSurface.
struct PackedSurface {
    static constexpr std::uint32_t kLeaf = 0x80000000u;  ///< child/root value: leaf, low 31 bits = patch index
    static constexpr std::uint32_t kEmpty = 0xFFFFFFFFu; ///< no patch (hole faces)

    /// xyz = BaseSurface::points() rounded to float, w = 0 (refined vertices, then local points).
    std::vector<glm::vec4> points;
    /// Control-point indices (into points) of all patches, concatenated in patch order.
    std::vector<std::uint32_t> patchIndices;
    /// Per patch (Far's global patch index): x = first entry in patchIndices, y = count (16 or
    /// 20), z = PatchParam field0, w = field1.
    std::vector<glm::uvec4> patches;
    /// Quadtree nodes: child c (quadrant as dmQuadTreeStep returns) = kLeaf | patch, a node
    /// index, or kEmpty.
    std::vector<glm::uvec4> nodes;
    /// Per Ptex face: kLeaf | patch (one patch covers the face), a node index, or kEmpty (hole).
    std::vector<std::uint32_t> faceRoots;
    /// Per Ptex face and corner (index face * 4 + c): xyz = BaseSurface::cornerNormal (float),
    /// w = 1 if BaseSurface::isExtraordinaryCorner, else 0.
    std::vector<glm::vec4> cornerNormals;

    /// Flattens base's patch table. Throws MeshError if the table holds a patch type other than
    /// 16-point B-spline or 20-point Gregory-basis patches, or patches that overlap.
    explicit PackedSurface(const BaseSurface& base);

    int faceCount() const { return static_cast<int>(faceRoots.size()); }
    /// Total bytes of the six arrays above (what the GPU uploads).
    std::size_t bytes() const {
        return points.size() * sizeof(glm::vec4) + patchIndices.size() * sizeof(std::uint32_t) +
               patches.size() * sizeof(glm::uvec4) + nodes.size() * sizeof(glm::uvec4) +
               faceRoots.size() * sizeof(std::uint32_t) + cornerNormals.size() * sizeof(glm::vec4);
    }
    /// The patch holding (face, u, v), walking faceRoots/nodes with dmQuadTreeStep. Throws
    /// ArgumentError for a face id out of range, (u, v) outside [0, 1]^2 or not finite, or a hole.
    template <typename real> std::uint32_t findPatch(int face, real u, real v) const;

    /// The CPU twin of the shader: the patch of (face, u, v) (findPatch), its weights from
    /// dmPatchBasis1/2, sum_i w_i P_i in index order i = 0..count-1 for p, du, dv (and, if
    /// `second`, duu, duv, dvv); evNormal/evWeight from dmEndCapCornerWeights and the
    /// extraordinary corners' normals. float reads `points` and `cornerNormals`; double reads
    /// the unrounded BaseSurface points and corner normals (kept privately, not uploaded), so
    /// that it equals BaseSurface::evaluate<double> to rounding. Throws like findPatch.
    template <typename real> BaseSample<real> evaluate(int face, real u, real v, bool second = true) const;

  private:
    template <typename real> glm::vec<3, real> point(std::uint32_t i) const;
    template <typename real> glm::vec<3, real> cornerNormal(std::size_t i) const;
    std::vector<glm::dvec3> pointsD_;
    std::vector<glm::dvec3> cornerNormalsD_;
};

template <> inline glm::vec<3, float> PackedSurface::point<float>(std::uint32_t i) const {
    const glm::vec4& p = points[i];
    return glm::vec3(p.x, p.y, p.z);
}
template <> inline glm::vec<3, double> PackedSurface::point<double>(std::uint32_t i) const { return pointsD_[i]; }
template <> inline glm::vec<3, float> PackedSurface::cornerNormal<float>(std::size_t i) const {
    const glm::vec4& n = cornerNormals[i];
    return glm::vec3(n.x, n.y, n.z);
}
template <> inline glm::vec<3, double> PackedSurface::cornerNormal<double>(std::size_t i) const { return cornerNormalsD_[i]; }

inline PackedSurface::PackedSurface(const BaseSurface& base) {
    const Far::PatchTable& table = base.patchTable();
    const int faces = base.faceCount();

    pointsD_ = base.points();
    points.reserve(pointsD_.size());
    for (const glm::dvec3& p : pointsD_) points.emplace_back(glm::vec3(p), 0.0f);

    // Patches in Far's global order (array by array), the order of PatchMap's handles.
    std::vector<Far::PatchParam> params;
    for (int a = 0; a < table.GetNumPatchArrays(); ++a) {
        const Far::PatchDescriptor desc = table.GetPatchArrayDescriptor(a);
        const int n = desc.GetNumControlVertices();
        if (!((desc.GetType() == Far::PatchDescriptor::REGULAR && n == 16) ||
              (desc.GetType() == Far::PatchDescriptor::GREGORY_BASIS && n == 20)))
            throw MeshError("PackedSurface: patch type " + std::to_string(static_cast<int>(desc.GetType())) + " with " +
                            std::to_string(n) + " control points is not supported (16-point B-spline, 20-point Gregory basis)");
        for (int i = 0; i < table.GetNumPatches(a); ++i) {
            const Far::ConstIndexArray cv = table.GetPatchVertices(a, i);
            const Far::PatchParam param = table.GetPatchParam(a, i);
            patches.emplace_back(static_cast<std::uint32_t>(patchIndices.size()), static_cast<std::uint32_t>(n),
                                 param.field0, param.field1);
            for (int k = 0; k < cv.size(); ++k) {
                if (cv[k] < 0 || static_cast<std::size_t>(cv[k]) >= points.size())
                    throw MeshError("PackedSurface: a patch control point index is out of range");
                patchIndices.push_back(static_cast<std::uint32_t>(cv[k]));
            }
            params.push_back(param);
        }
    }

    // The quadtree, from each patch's PatchParam as Far::PatchMap builds it: a patch at depth d
    // (root depth r = NonQuadRoot) descends d - r levels, quadrant bits taken from U and V,
    // most significant first; a patch at the root depth covers its whole face.
    faceRoots.assign(static_cast<std::size_t>(faces), kEmpty);
    const auto conflict = [](int face) {
        return MeshError("PackedSurface: patches overlap in Ptex face " + std::to_string(face));
    };
    for (std::size_t h = 0; h < params.size(); ++h) {
        const Far::PatchParam& param = params[h];
        const int face = param.GetFaceId();
        if (face < 0 || face >= faces) throw MeshError("PackedSurface: patch with Ptex face id " + std::to_string(face) + " out of range");
        const std::uint32_t leaf = kLeaf | static_cast<std::uint32_t>(h);
        std::uint32_t& root = faceRoots[static_cast<std::size_t>(face)];
        const int depth = param.GetDepth(), rootDepth = param.NonQuadRoot() ? 1 : 0;
        if (depth == rootDepth) {
            if (root != kEmpty) throw conflict(face);
            root = leaf;
            continue;
        }
        if (root == kEmpty) {
            root = static_cast<std::uint32_t>(nodes.size());
            nodes.emplace_back(kEmpty);
        } else if (root & kLeaf) {
            throw conflict(face);
        }
        std::uint32_t node = root;
        const int u = param.GetU(), v = param.GetV();
        for (int j = rootDepth + 1; j <= depth; ++j) {
            const int q = (((v >> (depth - j)) & 1) << 1) | ((u >> (depth - j)) & 1);
            const std::uint32_t child = nodes[node][q];
            if (j == depth) {
                if (child != kEmpty) throw conflict(face);
                nodes[node][q] = leaf;
            } else if (child == kEmpty) {
                const auto fresh = static_cast<std::uint32_t>(nodes.size());
                nodes.emplace_back(kEmpty);
                nodes[node][q] = fresh;
                node = fresh;
            } else if (child & kLeaf) {
                throw conflict(face);
            } else {
                node = child;
            }
        }
    }

    // §5.4 corner data.
    cornerNormals.resize(static_cast<std::size_t>(faces) * 4);
    cornerNormalsD_.resize(cornerNormals.size());
    for (int f = 0; f < faces; ++f)
        for (int c = 0; c < 4; ++c) {
            const std::size_t i = static_cast<std::size_t>(f) * 4 + static_cast<std::size_t>(c);
            cornerNormalsD_[i] = base.cornerNormal(f, c);
            cornerNormals[i] = glm::vec4(glm::vec3(cornerNormalsD_[i]), base.isExtraordinaryCorner(f, c) ? 1.0f : 0.0f);
        }
}

template <typename real> std::uint32_t PackedSurface::findPatch(int face, real u, real v) const {
    if (face < 0 || face >= faceCount())
        throw ArgumentError("PackedSurface: face id " + std::to_string(face) + " out of range [0, " + std::to_string(faceCount()) + ")");
    if (!(u >= real(0) && u <= real(1) && v >= real(0) && v <= real(1)))
        throw ArgumentError("PackedSurface: (u, v) = (" + std::to_string(static_cast<double>(u)) + ", " +
                            std::to_string(static_cast<double>(v)) + ") of face " + std::to_string(face) + " is not in [0, 1]^2");
    std::uint32_t node = faceRoots[static_cast<std::size_t>(face)];
    glm::vec<2, real> uv(u, v);
    while (node != kEmpty && !(node & kLeaf)) node = nodes[node][kern::dmQuadTreeStep(uv)];
    if (node == kEmpty) throw ArgumentError("PackedSurface: face " + std::to_string(face) + " is a hole (no surface to evaluate)");
    return node & ~kLeaf;
}

template <typename real> BaseSample<real> PackedSurface::evaluate(int face, real u, real v, bool second) const {
    using vec3 = glm::vec<3, real>;
    const std::uint32_t patch = findPatch(face, u, v);
    const glm::uvec4& rec = patches[patch];
    const glm::uvec2 param(rec.z, rec.w);
    const glm::vec<2, real> uv(u, v);
    const int count = static_cast<int>(rec.y);
    real w[20], wu[20], wv[20], wuu[20], wuv[20], wvv[20];
    if (second)
        kern::dmPatchBasis2(param, count, uv, w, wu, wv, wuu, wuv, wvv);
    else
        kern::dmPatchBasis1(param, count, uv, w, wu, wv);
    BaseSample<real> s;
    for (int i = 0; i < count; ++i) {
        const vec3 x = point<real>(patchIndices[rec.x + static_cast<std::uint32_t>(i)]);
        s.p += w[i] * x;
        s.du += wu[i] * x;
        s.dv += wv[i] * x;
        if (second) {
            s.duu += wuu[i] * x;
            s.duv += wuv[i] * x;
            s.dvv += wvv[i] * x;
        }
    }
    const glm::vec<4, real> cw = kern::dmEndCapCornerWeights(param, uv);
    for (int c = 0; c < 4; ++c) {
        const std::size_t i = static_cast<std::size_t>(face) * 4 + static_cast<std::size_t>(c);
        if (cornerNormals[i].w != 0.0f && cw[c] != real(0)) {
            s.evWeight += cw[c];
            s.evNormal += cw[c] * cornerNormal<real>(i);
        }
    }
    return s;
}

} // namespace dispmap
