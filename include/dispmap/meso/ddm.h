#pragma once
// DirectionalDistanceMap: Mehra & Kumar's conservative DDM: per voxel and direction cone the
// distance to the nearest solid point reachable from ANY point of the voxel within the cone
// (0 where the solid touches the voxel); the isotropic conservative map is the case of one
// cone holding every direction. Min-filtered coarser levels keep the bound. GLM only.
#include "dispmap/meso/cones.h"
#include "dispmap/meso/height_field.h"

namespace dispmap {

/// Conservative directional distances: d[c][k][j][i] <= the distance along any ray that starts
/// anywhere in voxel (i, j, k) with a direction in cone c to the first solid point it meets;
/// capped at `cap` (the cap is itself a bound). 0 where the solid touches the voxel.
struct DirectionalDistanceMap {
    int width = 0, height = 0, layers = 0;
    ConeSet cones;
    float cap = 0;
    std::vector<float> d;

    std::size_t index(int c, int i, int j, int k) const {
        return ((static_cast<std::size_t>(c) * static_cast<std::size_t>(layers) + static_cast<std::size_t>(k)) *
                    static_cast<std::size_t>(height) +
                static_cast<std::size_t>(detail::wrapIndex(j, height))) *
                   static_cast<std::size_t>(width) +
               static_cast<std::size_t>(detail::wrapIndex(i, width));
    }
    float at(int c, int i, int j, int k) const { return d[index(c, i, j, k)]; }
    std::size_t bytes() const { return d.size() * sizeof(float); }
};

namespace detail {
struct Box {
    glm::dvec3 lo, hi;
};
inline double wrapAngle(double a) {
    constexpr double pi = 3.14159265358979323846;
    while (a <= -pi) a += 2 * pi;
    while (a > pi) a -= 2 * pi;
    return a;
}
// Whether some direction x / |x|, x in the box D (not containing 0), can lie in the cone
// [az] x [el]: the box's elevation and azimuth intervals (bounds of the true sets) overlap
// the cone's. Conservative: it may say yes for a box that misses the cone, never no for one
// that meets it.
inline bool boxMeetsCone(const Box& D, const double az[2], const double el[2]) {
    constexpr double pi = 3.14159265358979323846, slack = 1e-6; // > float rounding of dmConeIndex's tests
    const double cx = std::clamp(0.0, D.lo.x, D.hi.x), cy = std::clamp(0.0, D.lo.y, D.hi.y);
    const double rhoMin = std::sqrt(cx * cx + cy * cy);
    const double mx = std::max(std::abs(D.lo.x), std::abs(D.hi.x)), my = std::max(std::abs(D.lo.y), std::abs(D.hi.y));
    const double rhoMax = std::sqrt(mx * mx + my * my);
    const double elMax = D.hi.z >= 0 ? std::atan2(D.hi.z, rhoMin) : std::atan2(D.hi.z, rhoMax);
    const double elMin = D.lo.z <= 0 ? std::atan2(D.lo.z, rhoMin) : std::atan2(D.lo.z, rhoMax);
    if (elMax < el[0] - slack || elMin > el[1] + slack) return false;
    if (rhoMin == 0 || az[1] - az[0] >= 2 * pi - slack) return true;
    const double centre = std::atan2(0.5 * (D.lo.y + D.hi.y), 0.5 * (D.lo.x + D.hi.x));
    double lo = 0, hi = 0;
    const double xs[2] = {D.lo.x, D.hi.x}, ys[2] = {D.lo.y, D.hi.y};
    for (double x : xs)
        for (double y : ys) {
            const double delta = wrapAngle(std::atan2(y, x) - centre);
            lo = std::min(lo, delta);
            hi = std::max(hi, delta);
        }
    for (double shift : {-2 * pi, 0.0, 2 * pi}) {
        const double a = centre + lo + shift, b = centre + hi + shift;
        if (a <= az[1] + slack && b >= az[0] - slack) return true;
    }
    return false;
}
inline double boxDistance(const Box& D) {
    const glm::dvec3 c = glm::clamp(glm::dvec3(0.0), D.lo, D.hi);
    return glm::length(c);
}
} // namespace detail

/// Builds the conservative DDM of a height field. The solid of column (i, j) lies inside the
/// boxes of its `subcells` x `subcells` sub-rectangles, each from -Inf up to the largest
/// height of the bilinear patch over it (at one of its corners); for each voxel V and cone C
/// the map stores the smallest distance |x| over the difference boxes D = box - V whose
/// directions may lie in C (detail::boxMeetsCone), found by a search in rings of columns
/// that stops when the ring is farther than the best. Cap default: `layers` voxels.
inline DirectionalDistanceMap buildDdm(const MesoHeightField& hf, const ConeSet& cones, int subcells = 2, float cap = 0) {
    detail::checkMesoSize("directional distance map", hf.width, hf.height, hf.layers);
    cones.validate();
    if (subcells < 1 || subcells > 8) throw ArgumentError("directional distance map: subcells " + std::to_string(subcells) + " not in 1..8");
    if (!(cap >= 0) || !std::isfinite(cap)) throw ArgumentError("directional distance map: cap must be finite and >= 0");
    DirectionalDistanceMap m;
    m.width = hf.width;
    m.height = hf.height;
    m.layers = hf.layers;
    m.cones = cones;
    m.cap = cap > 0 ? cap : static_cast<float>(hf.layers);
    m.d.assign(static_cast<std::size_t>(cones.count()) * static_cast<std::size_t>(hf.width) *
                   static_cast<std::size_t>(hf.height) * static_cast<std::size_t>(hf.layers),
               m.cap);
    // Tops of the sub-boxes and of the whole column, per column.
    const int S = subcells;
    std::vector<double> subTop(static_cast<std::size_t>(hf.width * hf.height * S * S)), cellTop(static_cast<std::size_t>(hf.width * hf.height));
    std::vector<double> cellMin(cellTop.size());
    for (int j = 0; j < hf.height; ++j)
        for (int i = 0; i < hf.width; ++i) {
            const glm::dvec4 h = glm::dvec4(hf.cell(i, j));
            const auto H = [&](double x, double y) { return kern::dmBilerp(h, glm::dvec2(x, y)); };
            double top = 0;
            for (int b = 0; b < S; ++b)
                for (int a = 0; a < S; ++a) {
                    const double x0 = double(a) / S, x1 = double(a + 1) / S, y0 = double(b) / S, y1 = double(b + 1) / S;
                    const double t = std::max(std::max(H(x0, y0), H(x1, y0)), std::max(H(x1, y1), H(x0, y1)));
                    subTop[((static_cast<std::size_t>(j) * static_cast<std::size_t>(hf.width) + static_cast<std::size_t>(i)) * static_cast<std::size_t>(S) + static_cast<std::size_t>(b)) * static_cast<std::size_t>(S) + static_cast<std::size_t>(a)] = t;
                    top = std::max(top, t);
                }
            cellTop[static_cast<std::size_t>(j * hf.width + i)] = top;
            cellMin[static_cast<std::size_t>(j * hf.width + i)] = std::min(std::min(h.x, h.y), std::min(h.z, h.w));
        }
    const double bottom = -4.0 * hf.layers - 1.0;
    const int C = cones.count();
    detail::parallelLayers(hf.layers, [&](int k) {
        for (int c = 0; c < C; ++c) {
            double az[2], el[2];
            cones.range(c, az, el);
            for (int j = 0; j < hf.height; ++j)
                for (int i = 0; i < hf.width; ++i) {
                    if (k + 1 <= cellMin[static_cast<std::size_t>(j * hf.width + i)]) {
                        m.d[m.index(c, i, j, k)] = 0; // inside the solid
                        continue;
                    }
                    double best = m.cap;
                    const int maxRing = static_cast<int>(std::ceil(best)) + 1;
                    for (int r = 0; r <= maxRing && r - 1 < best; ++r) {
                        for (int dj = -r; dj <= r; ++dj)
                            for (int di = -r; di <= r; ++di) {
                                if (std::max(std::abs(di), std::abs(dj)) != r) continue;
                                const int ci = i + di, cj = j + dj;
                                const std::size_t cell = static_cast<std::size_t>(detail::wrapIndex(cj, hf.height) * hf.width +
                                                                                  detail::wrapIndex(ci, hf.width));
                                const detail::Box cellBox{{ci - (i + 1.0), cj - (j + 1.0), bottom - (k + 1.0)},
                                                          {ci + 1.0 - i, cj + 1.0 - j, cellTop[cell] - k}};
                                if (detail::boxDistance(cellBox) >= best || !detail::boxMeetsCone(cellBox, az, el)) continue;
                                for (int b = 0; b < S; ++b)
                                    for (int a = 0; a < S; ++a) {
                                        const double x0 = ci + double(a) / S, y0 = cj + double(b) / S;
                                        const detail::Box D{{x0 - (i + 1.0), y0 - (j + 1.0), bottom - (k + 1.0)},
                                                            {x0 + 1.0 / S - i, y0 + 1.0 / S - j,
                                                             subTop[cell * static_cast<std::size_t>(S * S) + static_cast<std::size_t>(b * S + a)] - k}};
                                        const double dist = detail::boxDistance(D);
                                        if (dist < best && detail::boxMeetsCone(D, az, el)) best = dist;
                                    }
                            }
                    }
                    m.d[m.index(c, i, j, k)] = detail::floatBelow(best);
                }
        }
    });
    return m;
}

/// The next coarser level (Mehra & Kumar §3.1, "min filter"): each voxel of the half-size map
/// holds the minimum of its 2 x 2 x 2 children, which is again conservative for the union of
/// their boxes, in the coarse map's own voxels (halved: exact). Needs even sizes.
inline DirectionalDistanceMap minFilter(const DirectionalDistanceMap& fine) {
    if (fine.width % 2 || fine.height % 2 || fine.layers % 2 || fine.width < 4 || fine.height < 4 || fine.layers < 4)
        throw ArgumentError("minFilter: sizes " + std::to_string(fine.width) + " x " + std::to_string(fine.height) + " x " +
                            std::to_string(fine.layers) + " must be even and >= 4");
    DirectionalDistanceMap m;
    m.width = fine.width / 2;
    m.height = fine.height / 2;
    m.layers = fine.layers / 2;
    m.cones = fine.cones;
    m.cap = 0.5f * fine.cap;
    m.d.resize(fine.d.size() / 8);
    for (int c = 0; c < fine.cones.count(); ++c)
        for (int k = 0; k < m.layers; ++k)
            for (int j = 0; j < m.height; ++j)
                for (int i = 0; i < m.width; ++i) {
                    float v = std::numeric_limits<float>::infinity();
                    for (int e = 0; e < 8; ++e) v = std::min(v, fine.at(c, 2 * i + (e & 1), 2 * j + (e >> 1 & 1), 2 * k + (e >> 2)));
                    m.d[m.index(c, i, j, k)] = 0.5f * v;
                }
    return m;
}

} // namespace dispmap
