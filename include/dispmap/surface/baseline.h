#pragma once
// The traditional baseline the renderer compares with (Nießner & Loop 2013, Fig. 7): a height
// texture plus a tangent-space normal map, baked from a DisplacedSurface into an atlas of one
// square chart per Ptex face.
//
// Layout. With n = texelsPerFace, face f's chart is (n + 1) x (n + 1) texels; texel (i, j) of
// the chart lies exactly at face (u, v) = (i / n, j / n), so the chart's outer texels lie on
// the face's edges and both faces of an edge hold texels evaluated at the same surface points
// (equal-size faces: the same points; a quad edge against two half-length sub-face edges: the
// quad's texels are every other one of the sub-faces', see below). Charts are packed row by
// row into a near-square grid of ceil(sqrt(F)) columns; texel (x, y) is element y * width + x
// (row 0 first; in Vulkan that is texture coordinate y = 0). A shader reads face (u, v) at
// kern::dmBaselineAtlasUV(origin, (u, v), n, (width, height)) = (origin + 0.5 + (u, v) n) / size
// with linear filtering: it interpolates the chart's texels around (u, v) and never reads a
// neighbouring chart, so no gutters are needed.
//
// Heights: D at the texel's (face, u, v) at the finest level (rho = kFinest), as float. Where a
// sub-face edge meets a quad edge (a T-junction, TileTopology link with beta = 1/2) the
// sub-face's edge texels are replaced by what the quad's linear filter reads at their points:
// the quad's texel at every other one, the mean of the two around it in between. Both sides
// then give the same piecewise-linear D along the edge (for any n), so a displaced
// tessellation does not crack there. The normal map is left as evaluated: the two sides
// decode in different tangent frames anyway.
//
// Normals: the accurate displaced normal (NormalMode::Accurate, with the §5.4 blend near
// extraordinary vertices) in the tangent frame of kernels/baseline.h: N the base normal, T
// from s_u. Stored as an engine-typical RGBA8 normal map: byte = round(255 (n_ts / 2 + 1/2))
// per channel, alpha 255. Read back through a UNORM view and dmUnpackUnormNormal, each
// component is within 1 / 255 of n_ts, so the decoded normal is within
// asin(sqrt(3) / 255) ~ 0.39 degrees of the stored one (tests/test_baseline.cpp).
//
// Holes (faces tagged as holes): height 0, normal (0, 0, 1) in tangent space.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/surface/displaced_surface.h"
#include "dispmap/core/error.h"
#include "dispmap/kernels/baseline.h"

namespace dispmap {

/// Largest texels per face edge, and largest atlas side, of a baseline atlas.
inline constexpr int kMaxBaselineTexelsPerFace = 1024;
inline constexpr int kMaxBaselineAtlasSize = 16384;

struct BaselineAtlas {
    int texelsPerFace = 0; ///< n: each chart is (n + 1) x (n + 1) texels, texel (i, j) at (u, v) = (i, j) / n
    int width = 0, height = 0; ///< atlas size in texels
    std::vector<float> heights;         ///< width * height: D at each texel (0 outside charts and in holes)
    std::vector<std::uint8_t> normals;  ///< width * height * 4 (RGBA8): n_ts / 2 + 1/2, a = 255
    std::vector<glm::uvec2> chartOrigins; ///< per Ptex face: texel (x0, y0) of its (u, v) = (0, 0)

    /// Bytes of the two textures as stored: 4 (float height) + 4 (RGBA8) per texel.
    std::size_t bytes() const { return heights.size() * sizeof(float) + normals.size(); }
    /// Index of texel (x, y) in heights (times 4 in normals).
    std::size_t index(int x, int y) const {
        return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
    }
    /// Index of chart texel (i, j) of `face` (no range checks).
    std::size_t chartIndex(int face, int i, int j) const {
        const glm::uvec2 o = chartOrigins[static_cast<std::size_t>(face)];
        return index(static_cast<int>(o.x) + i, static_cast<int>(o.y) + j);
    }
};

namespace detail {
inline std::uint8_t unormByte(double x) {
    return static_cast<std::uint8_t>(std::clamp(std::lround(x * 255.0), 0l, 255l));
}
} // namespace detail

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
    int cols = 1;
    while (cols * cols < faces) ++cols;
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

/// D at face (u, v) as a linearly filtered read of the atlas gives it (bilinear between the
/// chart's texels around (u, v)): the CPU reference of the baseline's height lookup. Throws
/// ArgumentError for a face id out of range or (u, v) outside [0, 1]^2.
inline double sampleBaselineHeight(const BaselineAtlas& a, int face, double u, double v) {
    if (face < 0 || static_cast<std::size_t>(face) >= a.chartOrigins.size())
        throw ArgumentError("sampleBaselineHeight: face id " + std::to_string(face) + " out of range");
    if (!(u >= 0.0 && u <= 1.0 && v >= 0.0 && v <= 1.0))
        throw ArgumentError("sampleBaselineHeight: (u, v) = (" + std::to_string(u) + ", " + std::to_string(v) +
                            ") is not in [0, 1]^2");
    const int n = a.texelsPerFace;
    const double x = u * n, y = v * n;
    const int i = std::min(static_cast<int>(x), n - 1), j = std::min(static_cast<int>(y), n - 1);
    const double fx = x - i, fy = y - j;
    const auto h = [&](int di, int dj) { return static_cast<double>(a.heights[a.chartIndex(face, i + di, j + dj)]); };
    return (1 - fy) * ((1 - fx) * h(0, 0) + fx * h(1, 0)) + fy * ((1 - fx) * h(0, 1) + fx * h(1, 1));
}

} // namespace dispmap
