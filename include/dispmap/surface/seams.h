#pragma once
// Seams of a displaced surface: f and its normal evaluated independently from both faces of
// every edge, at the same points, and compared (docs/figures.md, "Seams"). A renderer or a
// tessellator that evaluates a shared edge once, from one side, cannot show a crack the
// surface has; this check can. Used by the tests and by `dispmap bench`; a tool writer can run
// it on an asset before shipping it.
//
// Points per tile edge: the dyadic parameters j / 16, `randomPoints` uniform ones, and near
// an end at an extraordinary corner, inside the end-cap ring (the first 2^-isolation of the
// edge), the fractions 1/8, 1/4, 1/2, 3/4 and 1 of it plus `randomPoints` more. Each point is
// classified by what the edge is there:
//  * sharp: the edge lies on an infinitely sharp crease, or the point lies within the cap
//    around a vertex on a sharp feature (DisplacedSurface::sharpCapRadius), where D is 0 and
//    the normal is the base surface's: positions only, the normal is meant to jump at the
//    feature, and Far's end caps at such vertices are not G1 across their smooth edges;
//  * endCap: within the end-cap ring of an extraordinary vertex (§5.4);
//  * other: everything else (regular edges, boundaries of N-gon sub-faces, T-junctions).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "dispmap/surface/displaced_surface.h"

namespace dispmap {

struct SeamOptions {
    NormalMode normals = NormalMode::Approximate;
    /// Resolution D is read at on both sides, in a quad's units: a sub-face of an N-gon (half as
    /// long) reads rho - 1, as the tessellator's per-vertex resolutions do.
    double rho = kFinest;
    int randomPoints = 4; ///< per edge, and again per end-cap ring
    std::uint32_t seed = 1;
};

/// The largest difference between the two sides of an edge, over one class of points.
struct SeamClass {
    int points = 0;
    double positionGap = 0; ///< |f_a - f_b| / the control mesh's bounding-box diagonal
    double normalJump = 0;  ///< angle between the two normals, radians
    int worstFace = -1;     ///< the face (and edge parameter) of the largest normal jump
    double worstY = 0;
};

struct SeamReport {
    SeamClass sharp, endCap, other;
    /// Inside faces: the outer edges of the end caps at extraordinary corners, where the end
    /// cap's normal meets the regular patches' (evaluated 1e-9 to either side of the edge).
    SeamClass endCapBoundary;
    double size = 0; ///< the bounding-box diagonal the gaps are relative to
};

namespace detail {
inline double angleBetween(const glm::dvec3& a, const glm::dvec3& b) {
    return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}
/// The bounding-box diagonal of the control points (at least the smallest normal double): the
/// scale seam gaps are measured in.
inline double controlDiagonal(const BaseSurface& base) {
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (int v = 0; v < base.controlPointCount(); ++v) {
        lo = glm::min(lo, base.points()[static_cast<std::size_t>(v)]);
        hi = glm::max(hi, base.points()[static_cast<std::size_t>(v)]);
    }
    return std::max(glm::length(hi - lo), std::numeric_limits<double>::min());
}
} // namespace detail

/// Both sides of every edge between two faces that are not holes, evaluated in `real`
/// precision (float or double). Throws as DisplacedSurface::evaluate (it should not: every
/// point is inside [0, 1]^2).
template <typename real> SeamReport measureSeams(const DisplacedSurface& surface, const SeamOptions& options = {}) {
    const BaseSurface& base = surface.base();
    const TileTopology& topo = base.topology();
    SeamReport report;
    report.size = detail::controlDiagonal(base);
    std::mt19937 rng(options.seed);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    const double ring = std::ldexp(1.0, -base.options().isolationLevel);
    // The same classes whether the fade is on or off (before/after tables compare like points).
    const double cap = surface.sharpCapRadius();
    auto rhoOf = [&](int face) { return static_cast<real>(options.rho - topo.scale(face)); };
    auto pointOn = [](int e, double y) {
        const glm::dvec2 a = TileTopology::cornerUV(e), b = TileTopology::cornerUV(e + 1);
        return a + y * (b - a);
    };
    for (int t = 0; t < base.faceCount(); ++t) {
        if (base.isHole(t)) continue;
        const double unit = topo.scale(t) ? 2.0 : 1.0; // a sub-face edge is half a base edge
        for (int e = 0; e < 4; ++e) {
            const bool sharpEdge = (base.sharpMask(t) >> e) & 1;
            const bool ev0 = base.isExtraordinaryCorner(t, e), ev1 = base.isExtraordinaryCorner(t, (e + 1) & 3);
            const double r = ring * unit; // the end-cap ring in this edge's parameter
            const bool touched0 = (base.sharpMask(t) >> (4 + e)) & 1, touched1 = (base.sharpMask(t) >> (4 + ((e + 1) & 3))) & 1;
            std::vector<double> ys;
            for (int j = 0; j <= 16; ++j) ys.push_back(j / 16.0);
            for (int j = 0; j < options.randomPoints; ++j) ys.push_back(uniform(rng));
            for (int end = 0; end < 2; ++end) {
                if (!(end == 0 ? ev0 : ev1)) continue;
                std::vector<double> near = {0.125, 0.25, 0.5, 0.75, 1.0};
                for (int j = 0; j < options.randomPoints; ++j) near.push_back(uniform(rng));
                for (double x : near) ys.push_back(end == 0 ? x * r : 1.0 - x * r);
            }
            for (double y : ys) {
                const TileTopology::Link* l = topo.linkAt(t, e, y);
                if (!l || base.isHole(l->tile) || l->tile < t) continue; // each pair once
                const double z = l->alpha - l->beta * y;
                const glm::dvec2 a = pointOn(e, y), b = pointOn(l->edge, std::clamp(z, 0.0, 1.0));
                const SurfaceSample<real> sa = surface.evaluate<real>(t, real(a.x), real(a.y), options.normals, rhoOf(t));
                const SurfaceSample<real> sb =
                    surface.evaluate<real>(l->tile, real(b.x), real(b.y), options.normals, rhoOf(l->tile));
                const bool inRing = (ev0 && y <= r) || (ev1 && y >= 1.0 - r);
                // Within the cap around a vertex on a sharp feature D is 0 and the normal is
                // the base surface's, one-sided at the vertex itself.
                const bool nearTouched = (touched0 && y <= cap * unit) || (touched1 && y >= 1.0 - cap * unit);
                const bool sharp = sharpEdge || nearTouched;
                SeamClass& c = sharp ? report.sharp : inRing ? report.endCap : report.other;
                ++c.points;
                c.positionGap = std::max(c.positionGap, glm::length(glm::dvec3(sa.position) - glm::dvec3(sb.position)) / report.size);
                if (sharp) continue;
                const double jump = detail::angleBetween(glm::dvec3(sa.normal), glm::dvec3(sb.normal));
                if (jump > c.normalJump) {
                    c.normalJump = jump;
                    c.worstFace = t;
                    c.worstY = y;
                }
            }
        }
    }
    // The end caps' outer edges inside each face (both neighbours of the end cap there are
    // patches of the same face).
    const double eps = 1e-9;
    for (int t = 0; t < base.faceCount(); ++t) {
        if (base.isHole(t)) continue;
        const double h = ring * (topo.scale(t) ? 2.0 : 1.0);
        for (int c = 0; c < 4; ++c) {
            if (!base.isExtraordinaryCorner(t, c) || base.sharpMask(t) != 0) continue;
            const glm::dvec2 corner = TileTopology::cornerUV(c), inward(corner.x == 0.0 ? 1.0 : -1.0, corner.y == 0.0 ? 1.0 : -1.0);
            for (double y : {0.0, 0.25, 0.5, 0.75, uniform(rng), uniform(rng)})
                for (int side = 0; side < 2; ++side) {
                    // side 0: the edge a = h (across the first parameter), side 1: b = h.
                    const glm::dvec2 along = side == 0 ? glm::dvec2(h, y * h) : glm::dvec2(y * h, h);
                    const glm::dvec2 across = side == 0 ? glm::dvec2(eps, 0.0) : glm::dvec2(0.0, eps);
                    const glm::dvec2 in = corner + inward * (along - across), out = corner + inward * (along + across);
                    const SurfaceSample<real> sa = surface.evaluate<real>(t, real(in.x), real(in.y), options.normals, rhoOf(t));
                    const SurfaceSample<real> sb = surface.evaluate<real>(t, real(out.x), real(out.y), options.normals, rhoOf(t));
                    SeamClass& k = report.endCapBoundary;
                    ++k.points;
                    const double jump = detail::angleBetween(glm::dvec3(sa.normal), glm::dvec3(sb.normal));
                    if (jump > k.normalJump) {
                        k.normalJump = jump;
                        k.worstFace = t;
                        k.worstY = y;
                    }
                }
        }
    }
    return report;
}

} // namespace dispmap
