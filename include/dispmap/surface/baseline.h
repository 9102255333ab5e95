#pragma once
// The traditional baseline the renderer compares with (Nießner & Loop 2013, Fig. 7): a height
// texture plus a tangent-space normal map, baked from a DisplacedSurface, in one of two
// layouts (BaselineLayout):
//  * Faces: an atlas of one square chart per Ptex face, seam-free by construction (below).
//    It shows what the traditional method costs where nothing but filtering goes wrong.
//  * MeshUv: the mesh's own UV layout, as an engine ships it: one UV-space image, each face
//    reading it at its corner UVs interpolated bilinearly (kern::dmFaceUv; the linear rule of
//    uv_map.h), normals in the tangent frame of per-vertex tangents (below). Along UV seams
//    the two faces of an edge read different texels, so D and the normal differ there: the
//    cracks and shading seams of the paper's Figure 7 (measureUvSeams counts them).
//
// Faces layout. With n = texelsPerFace, face f's chart is (n + 1) x (n + 1) texels; texel
// (i, j) of the chart lies exactly at face (u, v) = (i / n, j / n), so the chart's outer texels lie on
// the face's edges and both faces of an edge hold texels evaluated at the same surface points
// (equal-size faces: the same points; a quad edge against two half-length sub-face edges: the
// quad's texels are every other one of the sub-faces', see below). Charts are packed row by
// row into a near-square grid of ceil(sqrt(F)) columns; texel (x, y) is element y * width + x
// (row 0 first; in Vulkan that is texture coordinate y = 0). A shader reads face (u, v) at
// kern::dmBaselineAtlasUV(origin, (u, v), n, (width, height)) = (origin + 0.5 + (u, v) n) / size
// with linear filtering: it interpolates the chart's texels around (u, v) and never reads a
// neighbouring chart, so no gutters are needed.
//
// MeshUv layout. A width x height image of the unit UV square, row 0 at t = 1 (image files'
// top row; texture coordinate kern::dmUvTexcoord). Every texel centre a face covers holds D
// and the normal at the face's (u, v) there (map_source.h's rasterizeUvs, Newton steps on the
// bilinear UVs); texels outside every chart are filled by `gutter` rounds of dilation (each
// empty texel next to filled ones takes their mean), as baking tools pad charts so that
// linear filtering at a chart's border does not read the empty background. The image
// repeats (the shader's sampler uses repeat addressing, as engines do): a face's centre must
// lie in [0, 1]^2, its corners may reach past it (UDIM sets are refused). Where charts overlap
// (mirrored or stacked shells, or a face reaching past the square onto another chart) the face
// rasterised last owns the texel, as in any baked map; BaselineAtlas::sharedTexels counts them.
//
// Heights: D at the texel's (face, u, v) at the finest level (rho = kFinest), as float. Where a
// sub-face edge meets a quad edge (a T-junction, TileTopology link with beta = 1/2) the
// sub-face's edge texels of the Faces layout are replaced by what the quad's linear filter
// reads at their points:
// the quad's texel at every other one, the mean of the two around it in between. Both sides
// then give the same piecewise-linear D along the edge (for any n), so a displaced
// tessellation does not crack there. The normal map is left as evaluated: the two sides
// decode in different tangent frames anyway.
//
// Normals: the accurate displaced normal (NormalMode::Accurate, with the §5.4 blend near
// extraordinary vertices) in the tangent frame of kernels/baseline.h: N the base normal, T
// from s_u (Faces) or, in the MeshUv layout, the conventional per-vertex tangents (Lengyel):
// at each face corner the UV layout's s direction (kern::dmUvTangent), averaged over the faces
// that share the corner's vertex and UV (split at UV seams), interpolated over the face and
// made perpendicular to N (kern::dmFaceTangent); at the edge midpoints of a non-quad's
// sub-faces the mean of the edge's two end tangents (what a quad across it interpolates).
// Bake and shader use the same frame, as MikkTSpace guarantees an engine, so inside a chart
// the normal map decodes to what was baked; at a UV seam the two sides' frames and texels
// differ. Stored as an engine-typical RGBA8 normal map: byte = round(255 (n_ts / 2 + 1/2))
// per channel, alpha 255. Read back through a UNORM view and dmUnpackUnormNormal, each
// component is within 1 / 255 of n_ts, so the decoded normal is within
// asin(sqrt(3) / 255) ~ 0.39 degrees of the stored one (tests/test_baseline.cpp).
//
// Holes (faces tagged as holes): height 0, normal (0, 0, 1) in tangent space (Faces); not
// rasterised (MeshUv).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/map_source.h"
#include "dispmap/surface/seams.h"
#include "dispmap/surface/uv_map.h"
#include "dispmap/core/error.h"
#include "dispmap/kernels/baseline.h"

namespace dispmap {

/// Largest texels per face edge, and largest atlas side, of a baseline atlas.
inline constexpr int kMaxBaselineTexelsPerFace = 1024;
inline constexpr int kMaxBaselineAtlasSize = 16384;
/// Largest gutter (dilation rounds) of a mesh-UV baseline.
inline constexpr int kMaxBaselineGutter = 64;

/// Where the baseline's textures are laid out (see the top of this file).
enum class BaselineLayout { Faces, MeshUv };
inline const char* toString(BaselineLayout l) { return l == BaselineLayout::Faces ? "faces" : "uv"; }
inline std::optional<BaselineLayout> parseBaselineLayout(std::string_view name) {
    if (name == "faces") return BaselineLayout::Faces;
    if (name == "uv") return BaselineLayout::MeshUv;
    return std::nullopt;
}

struct BaselineAtlas {
    BaselineLayout layout = BaselineLayout::Faces;
    int texelsPerFace = 0; ///< Faces: n, each chart (n + 1) x (n + 1) texels, texel (i, j) at (u, v) = (i, j) / n
    int width = 0, height = 0; ///< atlas size in texels
    std::vector<float> heights;         ///< width * height: D at each texel (0 outside charts and in holes)
    std::vector<std::uint8_t> normals;  ///< width * height * 4 (RGBA8): n_ts / 2 + 1/2, a = 255
    std::vector<glm::uvec2> chartOrigins; ///< Faces: per Ptex face, texel (x0, y0) of its (u, v) = (0, 0)
    /// MeshUv: per Ptex face two entries, its corner UVs (c0, c1) and (c2, c3) at (u, v) =
    /// (0, 0), (1, 0), (1, 1), (0, 1), as the shader reads them (float).
    std::vector<glm::vec4> faceUvs;
    /// MeshUv: per Ptex face four entries, the per-vertex tangents at its corners (xyz, w = 0).
    std::vector<glm::vec4> cornerTangents;
    int gutter = 0; ///< MeshUv: dilation rounds around the charts
    std::size_t sharedTexels = 0; ///< MeshUv: texels more than one face covers (the last one's values)

    /// Bytes of the two textures as stored: 4 (float height) + 4 (RGBA8) per texel.
    std::size_t bytes() const { return heights.size() * sizeof(float) + normals.size(); }
    /// Index of texel (x, y) in heights (times 4 in normals).
    std::size_t index(int x, int y) const {
        return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
    }
    int faceCount() const {
        return static_cast<int>(layout == BaselineLayout::Faces ? chartOrigins.size() : faceUvs.size() / 2);
    }
    /// Index of chart texel (i, j) of `face` (Faces layout; no range checks).
    std::size_t chartIndex(int face, int i, int j) const {
        const glm::uvec2 o = chartOrigins[static_cast<std::size_t>(face)];
        return index(static_cast<int>(o.x) + i, static_cast<int>(o.y) + j);
    }
};

namespace detail {
inline std::uint8_t unormByte(double x) {
    return static_cast<std::uint8_t>(std::clamp(std::lround(x * 255.0), 0l, 255l));
}
/// Charts per row of a Faces atlas: ceil(sqrt(faces)).
inline int baselineColumns(int faces) {
    int cols = 1;
    while (cols * cols < faces) ++cols;
    return cols;
}
} // namespace detail

/// The side of a square mesh-UV image with as many texels as a Faces atlas of `faces` charts
/// at `texelsPerFace` (equal memory), at most kMaxBaselineAtlasSize.
inline int baselineUvSide(int faces, int texelsPerFace) {
    const int cols = detail::baselineColumns(std::max(faces, 1));
    const double texels = static_cast<double>(cols) * (texelsPerFace + 1) * ((std::max(faces, 1) + cols - 1) / cols) * (texelsPerFace + 1);
    return static_cast<int>(std::min<double>(std::ceil(std::sqrt(texels)), kMaxBaselineAtlasSize));
}

/// Bakes the baseline's textures from `surface` with n = texelsPerFace (see the top of this
/// file). Throws ArgumentError for n outside [1, kMaxBaselineTexelsPerFace] or an atlas wider
/// or taller than kMaxBaselineAtlasSize texels; propagates what the surface throws.
inline BaselineAtlas bakeBaseline(const DisplacedSurface& surface, int texelsPerFace) {
    const int n = texelsPerFace;
    if (n < 1 || n > kMaxBaselineTexelsPerFace)
        throw ArgumentError("bakeBaseline: texels per face " + std::to_string(n) + " out of range [1, " +
                            std::to_string(kMaxBaselineTexelsPerFace) + "]");
    const BaseSurface& base = surface.base();
    const int faces = base.faceCount();
    const int cols = detail::baselineColumns(faces);
    const int rows = (faces + cols - 1) / cols;
    const long long w = static_cast<long long>(cols) * (n + 1), h = static_cast<long long>(rows) * (n + 1);
    if (w > kMaxBaselineAtlasSize || h > kMaxBaselineAtlasSize)
        throw ArgumentError("bakeBaseline: an atlas of " + std::to_string(faces) + " charts of " + std::to_string(n + 1) +
                            "^2 texels would be " + std::to_string(w) + " x " + std::to_string(h) + " texels; at most " +
                            std::to_string(kMaxBaselineAtlasSize) + " per side");
    BaselineAtlas a;
    a.texelsPerFace = n;
    a.width = static_cast<int>(w);
    a.height = static_cast<int>(h);
    const std::size_t texels = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
    a.heights.assign(texels, 0.0f);
    a.normals.assign(4 * texels, 0);
    a.chartOrigins.resize(static_cast<std::size_t>(faces));
    for (int f = 0; f < faces; ++f)
        a.chartOrigins[static_cast<std::size_t>(f)] =
            glm::uvec2(static_cast<unsigned>((f % cols) * (n + 1)), static_cast<unsigned>((f / cols) * (n + 1)));

    const auto store = [&a](std::size_t at, float d, const glm::dvec3& nts) {
        a.heights[at] = d;
        for (int c = 0; c < 3; ++c) a.normals[4 * at + static_cast<std::size_t>(c)] = detail::unormByte(0.5 * nts[c] + 0.5);
        a.normals[4 * at + 3] = 255;
    };
    for (int f = 0; f < faces; ++f) {
        const bool hole = base.isHole(f);
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i) {
                const std::size_t at = a.chartIndex(f, i, j);
                if (hole) {
                    store(at, 0.0f, glm::dvec3(0, 0, 1));
                    continue;
                }
                const double u = double(i) / n, v = double(j) / n;
                const SurfaceSample<double> s = surface.evaluate<double>(f, u, v, NormalMode::Accurate);
                const BaseSample<double> b = base.evaluate<double>(f, u, v, false);
                const glm::dvec3 T = kern::dmTangentFromDerivative(b.du, s.baseNormal);
                store(at, static_cast<float>(s.displacement.x), kern::dmTangentSpaceEncode(s.normal, T, s.baseNormal));
            }
    }

    // T-junctions: the texels of a sub-face edge that covers half of a quad's edge become what
    // the quad's linear filter reads there: the quad's texel where one lies at the same point
    // (every other texel), else the mean of the two around it.
    const TileTopology& topo = base.topology();
    const auto edgeTexel = [&a, n](int face, int edge, int m) { // texel m (0..n) along tile edge `edge`
        const int i = edge == 0 ? m : edge == 1 ? n : edge == 2 ? n - m : 0;
        const int j = edge == 0 ? 0 : edge == 1 ? m : edge == 2 ? n : n - m;
        return a.chartIndex(face, i, j);
    };
    for (int t = 0; t < faces; ++t) {
        if (base.isHole(t)) continue;
        for (int e = 0; e < 4; ++e)
            for (const TileTopology::Link& l : topo.links(t, e)) {
                if (!(l.beta == 0.5) || base.isHole(l.tile)) continue; // only the half-length side
                // My edge parameter y = m / n is the quad's z = alpha - y / 2, i.e. 2 n alpha - m
                // half-texels along the quad's edge.
                const double twoNAlpha = 2.0 * n * l.alpha;
                const long q0 = std::lround(twoNAlpha);
                if (std::abs(twoNAlpha - static_cast<double>(q0)) > 1e-9) continue; // not a half-edge link
                for (int m = 0; m <= n; ++m) {
                    const long q = q0 - m;
                    if (q < 0 || q > 2L * n) continue;
                    const float lo = a.heights[edgeTexel(l.tile, l.edge, static_cast<int>(q / 2))];
                    const float hi = a.heights[edgeTexel(l.tile, l.edge, static_cast<int>((q + 1) / 2))];
                    a.heights[edgeTexel(t, e, m)] = q % 2 == 0 ? lo : 0.5f * (lo + hi);
                }
            }
    }
    return a;
}

/// The mesh UV of face (u, v) in a MeshUv atlas (bilinear between the face's stored corner
/// UVs, kern::dmFaceUv) with its derivatives along u and v. No range checks.
inline glm::dvec2 baselineFaceUv(const BaselineAtlas& a, int face, double u, double v, glm::dvec2& du, glm::dvec2& dv) {
    const std::size_t f = 2 * static_cast<std::size_t>(face);
    return kern::dmFaceUv(glm::dvec4(a.faceUvs[f]), glm::dvec4(a.faceUvs[f + 1]), glm::dvec2(u, v), du, dv);
}

/// The tangent T of the frame the normal map is stored in at face (u, v), from the base
/// surface's s_u and unit normal N there (Faces) or the face's corner tangents (MeshUv). No
/// range checks.
inline glm::dvec3 baselineTangent(const BaselineAtlas& a, int face, double u, double v, const glm::dvec3& su, const glm::dvec3& N) {
    if (a.layout == BaselineLayout::Faces) return kern::dmTangentFromDerivative(su, N);
    const auto t = [&a, face](int c) { return glm::dvec3(a.cornerTangents[4 * static_cast<std::size_t>(face) + static_cast<std::size_t>(c)]); };
    return kern::dmFaceTangent(t(0), t(1), t(2), t(3), glm::dvec2(u, v), N);
}

/// The normalised texture coordinate a shader reads face (u, v) at: in its chart (Faces) or
/// at its mesh UV (MeshUv). No range checks.
inline glm::dvec2 baselineTexcoord(const BaselineAtlas& a, int face, double u, double v) {
    if (a.layout == BaselineLayout::Faces)
        return kern::dmBaselineAtlasUV(glm::dvec2(a.chartOrigins[static_cast<std::size_t>(face)]), glm::dvec2(u, v),
                                       static_cast<double>(a.texelsPerFace), glm::dvec2(a.width, a.height));
    glm::dvec2 du, dv;
    return kern::dmUvTexcoord(baselineFaceUv(a, face, u, v, du, dv));
}

/// Bakes the baseline's textures in the mesh's UV layout (see the top of this file): a
/// width x height image of the unit UV square, `gutter` rounds of dilation. `uvs` must
/// interpolate linearly (UvInterpolation::Linear: what the shader does over each face).
/// Throws ArgumentError for smooth UVs, a UV map of another mesh, sizes out of [1,
/// kMaxBaselineAtlasSize], a gutter out of [0, kMaxBaselineGutter], a UV that is not finite, or
/// a face whose centre lies outside the UV square (naming it); propagates what the surface
/// throws.
inline BaselineAtlas bakeBaselineUv(const DisplacedSurface& surface, const UvMap& uvs, int width, int height, int gutter = 4) {
    const BaseSurface& base = surface.base();
    if (uvs.smooth())
        throw ArgumentError("bakeBaselineUv: the UVs must interpolate linearly (an engine interpolates a patch's corner UVs); "
                            "give a UvMap with the linear rule");
    if (uvs.ptexFaceCount() != base.faceCount())
        throw ArgumentError("bakeBaselineUv: a UV map of " + std::to_string(uvs.ptexFaceCount()) + " ptex faces for a surface of " +
                            std::to_string(base.faceCount()));
    if (width < 1 || height < 1 || width > kMaxBaselineAtlasSize || height > kMaxBaselineAtlasSize)
        throw ArgumentError("bakeBaselineUv: size " + std::to_string(width) + " x " + std::to_string(height) + " out of range [1, " +
                            std::to_string(kMaxBaselineAtlasSize) + "]");
    if (gutter < 0 || gutter > kMaxBaselineGutter)
        throw ArgumentError("bakeBaselineUv: gutter " + std::to_string(gutter) + " out of range [0, " +
                            std::to_string(kMaxBaselineGutter) + "]");
    const int faces = base.faceCount();
    BaselineAtlas a;
    a.layout = BaselineLayout::MeshUv;
    a.width = width;
    a.height = height;
    a.gutter = gutter;
    a.faceUvs.resize(2 * static_cast<std::size_t>(faces));
    std::vector<int> faceTiles(static_cast<std::size_t>(faces), 0);
    for (int f = 0; f < faces; ++f) {
        const std::array<glm::dvec2, 4>& c = uvs.linearCorners(f);
        a.faceUvs[2 * static_cast<std::size_t>(f)] = glm::vec4(glm::vec2(c[0]), glm::vec2(c[1]));
        a.faceUvs[2 * static_cast<std::size_t>(f) + 1] = glm::vec4(glm::vec2(c[2]), glm::vec2(c[3]));
        for (const glm::dvec2& uv : c)
            if (!(std::isfinite(uv.x) && std::isfinite(uv.y)))
                throw ArgumentError("bakeBaselineUv: ptex face " + std::to_string(f) + " has a UV that is not finite");
        if (base.isHole(f)) {
            faceTiles[static_cast<std::size_t>(f)] = -1;
            continue;
        }
        const glm::dvec2 centre = 0.25 * (c[0] + c[1] + c[2] + c[3]);
        if (!(centre.x >= 0.0 && centre.x <= 1.0 && centre.y >= 0.0 && centre.y <= 1.0))
            throw ArgumentError("bakeBaselineUv: ptex face " + std::to_string(f) + " lies outside the UV square (its centre is at (" +
                                std::to_string(centre.x) + ", " + std::to_string(centre.y) +
                                ")); the mesh-UV baseline is one repeating UV tile (no UDIM sets)");
    }
    // Per-vertex tangents: each face corner's UV tangent, summed over the corners that share a
    // vertex and a UV, normalised.
    a.cornerTangents.assign(4 * static_cast<std::size_t>(faces), glm::vec4(0.0f));
    {
        const TileTopology& topo = base.topology();
        std::map<std::tuple<int, float, float>, glm::dvec3> sums;
        std::vector<std::tuple<int, float, float>> keys(4 * static_cast<std::size_t>(faces));
        std::vector<glm::dvec3> own(keys.size());
        for (int f = 0; f < faces; ++f) {
            if (base.isHole(f)) continue;
            for (int c = 0; c < 4; ++c) {
                const glm::dvec2 uv = TileTopology::cornerUV(c);
                const SurfaceSample<double> s = surface.evaluate<double>(f, uv.x, uv.y, NormalMode::Approximate);
                const BaseSample<double> b = base.evaluate<double>(f, uv.x, uv.y, false);
                glm::dvec2 du, dv;
                baselineFaceUv(a, f, uv.x, uv.y, du, dv);
                const std::size_t i = 4 * static_cast<std::size_t>(f) + static_cast<std::size_t>(c);
                const glm::vec2 st = glm::vec2(a.faceUvs[2 * static_cast<std::size_t>(f) + static_cast<std::size_t>(c / 2)][2 * (c % 2)],
                                               a.faceUvs[2 * static_cast<std::size_t>(f) + static_cast<std::size_t>(c / 2)][2 * (c % 2) + 1]);
                keys[i] = {topo.cornerVertex(f, c), st.x, st.y};
                own[i] = kern::dmUvTangent(b.du, b.dv, du, dv, s.baseNormal);
                sums[keys[i]] += own[i];
            }
        }
        std::vector<glm::dvec3> averaged(keys.size());
        for (std::size_t i = 0; i < keys.size(); ++i) {
            const glm::dvec3 sum = sums[keys[i]];
            averaged[i] = glm::dot(sum, sum) > 1e-12 ? glm::normalize(sum) : own[i];
        }
        // A sub-face of a non-quad (ptex faces first .. first + n - 1 of one base face, corner 0
        // at the face's vertex k, corners 1 and 3 at the midpoints of its edges to vertices k + 1
        // and k - 1): the midpoint tangents are the mean of the edge's end tangents, what a quad
        // across the edge interpolates there, so both sides agree along the whole edge.
        for (int f = 0; f < faces;) {
            int end = f + 1;
            while (end < faces && uvs.baseFace(end) == uvs.baseFace(f)) ++end;
            const int count = end - f;
            for (int j = 0; count > 1 && j < count; ++j) {
                const auto vertexTangent = [&](int sub) { return averaged[4 * static_cast<std::size_t>(f + (sub + count) % count)]; };
                const std::size_t at = 4 * static_cast<std::size_t>(f + j);
                averaged[at + 1] = 0.5 * (vertexTangent(j) + vertexTangent(j + 1));
                averaged[at + 3] = 0.5 * (vertexTangent(j - 1) + vertexTangent(j));
            }
            f = end;
        }
        for (int f = 0; f < faces; ++f)
            if (!base.isHole(f))
                for (std::size_t i = 4 * static_cast<std::size_t>(f); i < 4 * static_cast<std::size_t>(f) + 4; ++i)
                    a.cornerTangents[i] = glm::vec4(glm::vec3(averaged[i]), 0.0f);
    }
    const std::size_t texels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    a.heights.assign(texels, 0.0f);
    a.normals.assign(4 * texels, 0);
    for (std::size_t i = 0; i < texels; ++i) {
        a.normals[4 * i + 0] = a.normals[4 * i + 1] = 128;
        a.normals[4 * i + 2] = a.normals[4 * i + 3] = 255;
    }
    std::vector<std::uint8_t> covered(texels, 0);
    std::vector<int> owner(texels, -1);
    // The unit square and its 8 neighbours: the parts of faces outside [0, 1]^2 land where the
    // repeating lookup reads them.
    const auto bakeTexel = [&](int x, int y, int t, double u, double v) {
        const std::size_t at = a.index(x, y);
        if (owner[at] >= 0 && owner[at] != t && covered[at] == 1) {
            ++a.sharedTexels;
            covered[at] = 2; // counted once
        }
        owner[at] = t;
        const SurfaceSample<double> s = surface.evaluate<double>(t, u, v, NormalMode::Accurate);
        const glm::dvec3 T = baselineTangent(a, t, u, v, glm::dvec3(0.0), s.baseNormal);
        const glm::dvec3 nts = kern::dmTangentSpaceEncode(s.normal, T, s.baseNormal);
        a.heights[at] = static_cast<float>(s.displacement.x);
        for (int c = 0; c < 3; ++c) a.normals[4 * at + static_cast<std::size_t>(c)] = detail::unormByte(0.5 * nts[c] + 0.5);
        if (!covered[at]) covered[at] = 1;
    };
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) rasterizeUvs(uvs, faceTiles, 0, width, height, 4, 0.0, 3, bakeTexel, glm::dvec2(dx, dy));
    // Gutters: each round, an empty texel with filled 8-neighbours takes their mean.
    std::vector<std::uint8_t> next = covered;
    for (int round = 0; round < gutter; ++round) {
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                const std::size_t at = a.index(x, y);
                if (covered[at]) continue;
                double h = 0.0, n[4] = {0, 0, 0, 0};
                int count = 0;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const std::size_t o = a.index((x + dx + width) % width, (y + dy + height) % height); // repeating
                        if (!covered[o]) continue;
                        h += static_cast<double>(a.heights[o]);
                        for (std::size_t c = 0; c < 4; ++c) n[c] += a.normals[4 * o + c];
                        ++count;
                    }
                if (count == 0) continue;
                a.heights[at] = static_cast<float>(h / count);
                for (std::size_t c = 0; c < 4; ++c) a.normals[4 * at + c] = detail::unormByte(n[c] / (255.0 * count));
                next[at] = 1;
            }
        covered = next;
    }
    return a;
}

namespace detail {
inline void checkBaselineLookup(const BaselineAtlas& a, int face, double u, double v, const char* what) {
    if (face < 0 || face >= a.faceCount())
        throw ArgumentError(std::string(what) + ": face id " + std::to_string(face) + " out of range");
    if (!(u >= 0.0 && u <= 1.0 && v >= 0.0 && v <= 1.0))
        throw ArgumentError(std::string(what) + ": (u, v) = (" + std::to_string(u) + ", " + std::to_string(v) +
                            ") is not in [0, 1]^2");
}

/// A linearly filtered read at normalised texture coordinate tc, as a Vulkan sampler with
/// repeat addressing does it (exact weights; hardware rounds them to its sub-texel
/// precision): fetch(index) is one texel's value.
template <typename Fetch> auto filterLinear(const BaselineAtlas& a, glm::dvec2 tc, Fetch fetch) {
    if (!(std::isfinite(tc.x) && std::isfinite(tc.y))) throw ArgumentError("baseline lookup: the texture coordinate is not finite");
    const double x = tc.x * a.width - 0.5, y = tc.y * a.height - 0.5;
    const double fx0 = std::floor(x), fy0 = std::floor(y);
    const double fx = x - fx0, fy = y - fy0;
    const auto wrap = [](double i, int n) {
        const double m = std::fmod(i, static_cast<double>(n));
        return static_cast<int>(m < 0.0 ? m + n : m);
    };
    const int x0 = wrap(fx0, a.width), x1 = wrap(fx0 + 1, a.width);
    const int y0 = wrap(fy0, a.height), y1 = wrap(fy0 + 1, a.height);
    return (1 - fy) * ((1 - fx) * fetch(a.index(x0, y0)) + fx * fetch(a.index(x1, y0))) +
           fy * ((1 - fx) * fetch(a.index(x0, y1)) + fx * fetch(a.index(x1, y1)));
}
} // namespace detail

/// D at face (u, v) as a linearly filtered read of the atlas gives it: the CPU reference of
/// the baseline's height lookup (the Faces layout reads only the face's chart). Throws
/// ArgumentError for a face id out of range or (u, v) outside [0, 1]^2.
inline double sampleBaselineHeight(const BaselineAtlas& a, int face, double u, double v) {
    detail::checkBaselineLookup(a, face, u, v, "sampleBaselineHeight");
    return detail::filterLinear(a, baselineTexcoord(a, face, u, v),
                                [&a](std::size_t i) { return static_cast<double>(a.heights[i]); });
}

/// The world normal the baseline shades face (u, v) with: the normal map read with linear
/// filtering, unpacked and decoded in the layout's tangent frame (baselineTangent) from the
/// base surface's s_u and unit normal N there. Throws as sampleBaselineHeight.
inline glm::dvec3 sampleBaselineNormal(const BaselineAtlas& a, int face, double u, double v, const glm::dvec3& su,
                                       const glm::dvec3& N) {
    detail::checkBaselineLookup(a, face, u, v, "sampleBaselineNormal");
    const glm::dvec3 c = detail::filterLinear(a, baselineTexcoord(a, face, u, v), [&a](std::size_t i) {
        return glm::dvec3(a.normals[4 * i], a.normals[4 * i + 1], a.normals[4 * i + 2]) / 255.0;
    });
    return kern::dmTangentSpaceDecode(kern::dmUnpackUnormNormal(c), baselineTangent(a, face, u, v, su, N), N);
}

/// The two sides of the edges of one kind (UV seams, or edges inside a UV chart).
struct UvSeamClass {
    int points = 0;
    double maxGap = 0, meanGap = 0;   ///< |f_a - f_b| / the control mesh's bounding-box diagonal
    double maxJump = 0, meanJump = 0; ///< angle between the two sides' shading normals, radians
    int worstFace = -1;               ///< the face and (u, v) of the widest gap
    glm::dvec2 worstUv{0.0};
};
struct UvSeamReport {
    UvSeamClass seams;  ///< edges whose two faces read different UVs (by more than 1e-6)
    UvSeamClass inside; ///< edges inside a chart
    double size = 0;    ///< the bounding-box diagonal the gaps are relative to
};

/// What a renderer shows on both sides of every edge between two faces (not holes, not on
/// an infinitely sharp crease, where the normal is meant to jump), at the parameters j / 16
/// of each edge: with `atlas` the baseline's displaced position p + N D and shading normal
/// (sampleBaselineHeight, sampleBaselineNormal), without it the displaced surface's (f and
/// its normal of mode `normals`, at the finest level). Edges are sorted by whether the faces'
/// linear UVs (`uvs`) agree there: the crack widths and shading jumps of the paper's
/// Figure 7. Throws as the lookups.
inline UvSeamReport measureUvSeams(const DisplacedSurface& surface, const UvMap& uvs, const BaselineAtlas* atlas,
                                   NormalMode normals = NormalMode::Accurate) {
    const BaseSurface& base = surface.base();
    const TileTopology& topo = base.topology();
    if (uvs.ptexFaceCount() != base.faceCount() || (atlas && atlas->faceCount() != base.faceCount()))
        throw ArgumentError("measureUvSeams: the UV map, atlas and surface have different face counts");
    UvSeamReport report;
    report.size = detail::controlDiagonal(base);
    const auto side = [&](int face, glm::dvec2 uv, glm::dvec3& position, glm::dvec3& normal) {
        const SurfaceSample<double> s = surface.evaluate<double>(face, uv.x, uv.y, normals);
        if (!atlas) {
            position = s.position;
            normal = s.normal;
            return;
        }
        const BaseSample<double> b = base.evaluate<double>(face, uv.x, uv.y, false);
        position = b.p + s.baseNormal * sampleBaselineHeight(*atlas, face, uv.x, uv.y);
        normal = sampleBaselineNormal(*atlas, face, uv.x, uv.y, b.du, s.baseNormal);
    };
    const auto pointOn = [](int e, double y) {
        const glm::dvec2 a = TileTopology::cornerUV(e), b = TileTopology::cornerUV(e + 1);
        return a + y * (b - a);
    };
    for (int t = 0; t < base.faceCount(); ++t) {
        if (base.isHole(t)) continue;
        for (int e = 0; e < 4; ++e) {
            if ((base.sharpMask(t) >> e) & 1) continue;
            for (int j = 0; j <= 16; ++j) {
                const double y = j / 16.0;
                const TileTopology::Link* l = topo.linkAt(t, e, y);
                if (!l || base.isHole(l->tile) || l->tile < t) continue; // each pair once
                const glm::dvec2 a = pointOn(e, y), b = pointOn(l->edge, std::clamp(l->alpha - l->beta * y, 0.0, 1.0));
                const bool seam = glm::length(uvs(t, a.x, a.y) - uvs(l->tile, b.x, b.y)) > 1e-6;
                glm::dvec3 pa, na, pb, nb;
                side(t, a, pa, na);
                side(l->tile, b, pb, nb);
                UvSeamClass& c = seam ? report.seams : report.inside;
                const double gap = glm::length(pa - pb) / report.size, jump = detail::angleBetween(na, nb);
                ++c.points;
                if (gap > c.maxGap || c.worstFace < 0) {
                    c.worstFace = t;
                    c.worstUv = a;
                }
                c.maxGap = std::max(c.maxGap, gap);
                c.meanGap += gap;
                c.maxJump = std::max(c.maxJump, jump);
                c.meanJump += jump;
            }
        }
    }
    for (UvSeamClass* c : {&report.seams, &report.inside})
        if (c->points) {
            c->meanGap /= c->points;
            c->meanJump /= c->points;
        }
    return report;
}

} // namespace dispmap
