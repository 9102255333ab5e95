#pragma once
// DirectionalDistanceMap: Mehra & Kumar's conservative DDM: per voxel and direction cone the
// distance to the nearest solid point reachable from ANY point of the voxel within the cone
// (0 where the solid touches the voxel); the isotropic conservative map is the case of one
// cone holding every direction. Min-filtered coarser levels keep the bound. GLM only.
#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <limits>
#include <vector>

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
// A direction cone as the box test needs it: no angle is computed per box, only products and
// comparisons (as the marcher's dmConeIndex). The azimuth sector runs counter-clockwise from
// the unit vector a0 to a1 (at most half a turn, or the whole circle); the elevation band's
// bounds, widened by the slack, as (cos, sin) pairs, each tested only where it can reject.
struct ConeTest {
    bool allAzimuths = false;
    glm::dvec2 a0{1, 0}, a1{1, 0};
    double la0 = 1, la1 = 1; // |a0| and |a1| as computed (1 up to rounding)
    bool testLo = false, testHi = false;
    glm::dvec2 lo{1, 0}, hi{1, 0}; // (cos, sin) of el[0] - slack and el[1] + slack
    // The sector's edges turned outwards by the slack, when it is less than half a turn even
    // so: the wedge sectorRho cuts a box's footprint to.
    bool clipAzimuth = false;
    glm::dvec2 r0{1, 0}, r1{1, 0};
    int sector = 0; // cones of one sector share r0 and r1
};
inline constexpr double kConeSlack = 1e-6; // radians, > float rounding of dmConeIndex's tests
inline ConeTest coneTest(const ConeSet& cones, int c) {
    constexpr double pi = 3.14159265358979323846;
    double az[2], el[2];
    cones.range(c, az, el);
    ConeTest t;
    t.allAzimuths = az[1] - az[0] >= 2 * pi - kConeSlack;
    t.a0 = {std::cos(az[0]), std::sin(az[0])};
    t.a1 = {std::cos(az[1]), std::sin(az[1])};
    t.la0 = glm::length(t.a0);
    t.la1 = glm::length(t.a1);
    const double e0 = el[0] - kConeSlack, e1 = el[1] + kConeSlack;
    t.testLo = e0 > -pi / 2;
    t.testHi = e1 < pi / 2;
    t.lo = {std::cos(e0), std::sin(e0)};
    t.hi = {std::cos(e1), std::sin(e1)};
    const double b0 = az[0] - kConeSlack, b1 = az[1] + kConeSlack;
    t.clipAzimuth = !t.allAzimuths && b1 - b0 < pi - kConeSlack;
    t.sector = cones.isotropic ? 0 : c % cones.m;
    t.r0 = {std::cos(b0), std::sin(b0)};
    t.r1 = {std::cos(b1), std::sin(b1)};
    return t;
}
inline double cross2(const glm::dvec2& a, const glm::dvec2& b) { return a.x * b.y - a.y * b.x; }
// Whether direction d lies on the counter-clockwise arc from a to b (at most half a turn),
// within kConeSlack radians at either end; la, lb, ld are the vectors' lengths.
inline bool onArc(const glm::dvec2& a, double la, const glm::dvec2& b, double lb, const glm::dvec2& d, double ld) {
    return cross2(a, d) >= -kConeSlack * la * ld && cross2(d, b) >= -kConeSlack * ld * lb;
}
// What the cone test needs of a box D (not containing 0), computed once and then tested
// against every cone: its nearest and farthest horizontal distances, and its azimuth arc
// from its clockwise-most corner p to its counter-clockwise-most q (less than half a turn:
// the box does not contain the axis), with their lengths. The arc is computed when first
// asked for (a box the elevation tests reject never needs it).
struct BoxShape {
    glm::dvec3 lo, hi;
    double rhoMin = 0, rhoMax = 0;
    explicit BoxShape(const Box& D) : lo(D.lo), hi(D.hi) {
        const double cx = std::clamp(0.0, D.lo.x, D.hi.x), cy = std::clamp(0.0, D.lo.y, D.hi.y);
        rhoMin = std::sqrt(cx * cx + cy * cy);
        const double mx = std::max(std::abs(D.lo.x), std::abs(D.hi.x)), my = std::max(std::abs(D.lo.y), std::abs(D.hi.y));
        rhoMax = std::sqrt(mx * mx + my * my);
    }
    struct Arc {
        glm::dvec2 p{0}, q{0};
        double lp = 0, lq = 0;
    };
    // Only for a box off the axis (rhoMin > 0).
    const Arc& arc() const {
        if (!arcKnown_) {
            const glm::dvec2 corner[4] = {{lo.x, lo.y}, {hi.x, lo.y}, {hi.x, hi.y}, {lo.x, hi.y}};
            arc_.p = arc_.q = corner[0];
            for (int i = 1; i < 4; ++i) {
                if (cross2(arc_.p, corner[i]) < 0) arc_.p = corner[i];
                if (cross2(arc_.q, corner[i]) > 0) arc_.q = corner[i];
            }
            arc_.lp = glm::length(arc_.p);
            arc_.lq = glm::length(arc_.q);
            arcKnown_ = true;
        }
        return arc_;
    }

  private:
    mutable Arc arc_;
    mutable bool arcKnown_ = false;
};
// Whether some direction x / |x|, x in the box, can lie in the cone: the box's elevation
// interval (from the nearest and farthest horizontal distances) overlaps the cone's band, and
// the box's azimuth arc overlaps the cone's sector. Conservative: it may say yes for a box
// that misses the cone, never no for one that meets it (the arcs and band are widened by
// kConeSlack). atan2(z, rho) < e is tested as z cos e - rho sin e < 0, which holds for
// rho >= 0 and |e| < pi/2.
inline bool boxMeetsCone(const BoxShape& D, const ConeTest& cone) {
    // (rho, z) = (0, 0) is elevation 0, as atan2(0, 0): a box that touches the axis only at
    // z = 0 (the solid just below or above the voxel) has no direction up or down the axis.
    if (cone.testLo) { // the box's highest elevation below the band?
        const double rho = D.hi.z > 0 ? D.rhoMin : D.hi.z < 0 ? D.rhoMax : 1.0;
        if (D.hi.z * cone.lo.x - rho * cone.lo.y < 0) return false;
    }
    if (cone.testHi) { // the box's lowest elevation above the band?
        const double rho = D.lo.z < 0 ? D.rhoMin : D.lo.z > 0 ? D.rhoMax : 1.0;
        if (D.lo.z * cone.hi.x - rho * cone.hi.y > 0) return false;
    }
    if (D.rhoMin == 0 || cone.allAzimuths) return true;
    // Two arcs of at most half a turn each meet iff one holds the other's start.
    const BoxShape::Arc& a = D.arc();
    return onArc(cone.a0, cone.la0, cone.a1, cone.la1, a.p, a.lp) || onArc(a.p, a.lp, a.q, a.lq, cone.a0, cone.la0);
}
inline bool boxMeetsCone(const Box& D, const ConeTest& cone) { return boxMeetsCone(BoxShape(D), cone); }
inline double boxDistance(const Box& D) {
    const glm::dvec3 c = glm::clamp(glm::dvec3(0.0), D.lo, D.hi);
    return glm::length(c);
}
// Where the ray t r (t >= 0) enters the rectangle [x0, x1] x [y0, y1] (0 if it starts inside),
// or +Inf where it misses it.
inline double rayEntry(const glm::dvec2& r, double x0, double y0, double x1, double y1) {
    double t0 = 0, t1 = std::numeric_limits<double>::infinity();
    const double lo[2] = {x0, y0}, hi[2] = {x1, y1}, dir[2] = {r.x, r.y};
    for (int a = 0; a < 2; ++a) {
        if (dir[a] == 0) {
            if (lo[a] > 0 || hi[a] < 0) return std::numeric_limits<double>::infinity();
            continue;
        }
        double ta = lo[a] / dir[a], tb = hi[a] / dir[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t0 <= t1 ? t0 : std::numeric_limits<double>::infinity();
}
// The distance from the origin to the rectangle [x0, x1] x [y0, y1] of the plane within the
// wedge between the rays of directions r0 and r1 (unit; counter-clockwise from r0 to r1, less
// than half a turn): the rectangle's nearest point where the wedge holds it, else the nearer
// of the points where the wedge's two rays enter the rectangle (the nearest point of a convex
// set cut by a convex wedge lies on the wedge's boundary when the set's own nearest point is
// outside it). +Inf where the wedge misses the rectangle.
inline double wedgeRectDistance(const glm::dvec2& r0, const glm::dvec2& r1, double x0, double y0, double x1, double y1) {
    const glm::dvec2 c(std::clamp(0.0, x0, x1), std::clamp(0.0, y0, y1));
    if (cross2(r0, c) >= 0 && cross2(c, r1) >= 0) return glm::length(c);
    return std::min(rayEntry(r0, x0, y0, x1, y1), rayEntry(r1, x0, y0, x1, y1));
}
// A lower bound on |x| over the points x of box D whose direction lies in the cone (its
// ranges widened by the slack), at least `dist` (the distance to the whole box; 0 for a box
// that touches the voxel), or +Inf where no point of the box is in the cone, in two halves.
// sectorRho: the nearest horizontal distance rho of the box's points in the cone's sector (a
// wedge of less than half a turn; shared by the cones of one sector). bandDistance: their
// (rho, z) then lie in [rho, rhoMax] x [lo.z, hi.z] within the elevation band, a wedge of the
// (rho, z) half-plane, and the distance to that part of the rectangle bounds |x| from below.
// Seen from above a floor g below the voxel, a cone whose band stops 45 degrees below the
// horizon gets sqrt(2) g instead of g.
inline double sectorRho(const BoxShape& D, const ConeTest& cone) {
    if (!cone.clipAzimuth || D.rhoMin == 0) return D.rhoMin;
    const double rho = wedgeRectDistance(cone.r0, cone.r1, D.lo.x, D.lo.y, D.hi.x, D.hi.y);
    return rho <= D.rhoMax ? rho : std::numeric_limits<double>::infinity();
}
// rhoMin: sectorRho's value, finite (bound() stops at +Inf).
inline double bandDistance(const BoxShape& D, const ConeTest& cone, double dist, double rhoMin) {
    // The band's rays in (rho, z); an open end is the vertical half-axis.
    const glm::dvec2 e0 = cone.testLo ? cone.lo : glm::dvec2(0, -1), e1 = cone.testHi ? cone.hi : glm::dvec2(0, 1);
    const double d = wedgeRectDistance(e0, e1, rhoMin, D.lo.z, D.rhoMax, D.hi.z);
    // Rounding of the entry points: a relative 1e-12 below, far under the float the map stores.
    return std::max(dist, d * (1.0 - 1e-12));
}
// One voxel's search for all cones at once (buildDdm, buildSolidDdm): per cone the smallest
// bound (bound(): the distance to the part of the box the cone reaches) over the boxes that
// may meet it. A box is tested only against the cones whose best
// it could still beat, so each cone ends with what a search of its own would find.
struct ConeSearch {
    const std::vector<ConeTest>& tests;
    std::array<double, kMaxCones> best{};
    double worst = 0; // the largest best: boxes at least this far improve no cone

    explicit ConeSearch(const std::vector<ConeTest>& t) : tests(t) {}
    int count() const { return static_cast<int>(tests.size()); }
    void reset(double cap) {
        best.fill(cap);
        from.fill(kNone);
        worst = cap;
    }
    // The cones of `among` (a bit mask; all by default) that the box, at distance `dist`, may
    // still improve. A box holding another may be asked first: what it cannot improve, no box
    // inside it can (its distance, cone test and bound are no larger).
    std::uint32_t open(const Box& box, double dist, std::uint32_t among = ~0u) const {
        std::uint32_t near = 0; // the cones of `among` the box is near enough to improve
        if (dist >= worst) return near;
        for (std::uint32_t m = among & allCones(); m != 0; m &= m - 1)
            if (const int c = std::countr_zero(m); dist < best[static_cast<std::size_t>(c)]) near |= 1u << c;
        if (near == 0) return near;
        const BoxShape shape(box);
        SectorCache rho;
        std::uint32_t mask = 0;
        for (std::uint32_t m = near; m != 0; m &= m - 1)
            if (const int c = std::countr_zero(m); boxMeetsCone(shape, tests[static_cast<std::size_t>(c)]) &&
                                                    bound(shape, c, dist, rho) < best[static_cast<std::size_t>(c)])
                mask |= 1u << c;
        return mask;
    }
    std::uint32_t allCones() const { return count() >= 32 ? ~0u : (1u << count()) - 1u; }
    // Offers a box inside an open one to the cones of `mask`; `id` names the box to the caller:
    // from[c] is the id of the box that set best[c] (kNone while best[c] is the cap).
    static constexpr std::uint64_t kNone = ~std::uint64_t{0};
    std::array<std::uint64_t, kMaxCones> from{};
    void offer(const Box& box, std::uint32_t mask, std::uint64_t id = kNone) {
        const double dist = boxDistance(box);
        std::uint32_t rest = 0; // the cones of `mask` the box is near enough to improve
        for (std::uint32_t m = mask; m != 0; m &= m - 1)
            if (const int c = std::countr_zero(m); dist < best[static_cast<std::size_t>(c)]) rest |= 1u << c;
        if (rest == 0) return;
        const BoxShape shape(box);
        SectorCache rho;
        for (; rest != 0; rest &= rest - 1) {
            const int c = std::countr_zero(rest);
            if (!boxMeetsCone(shape, tests[static_cast<std::size_t>(c)])) continue;
            if (const double b = bound(shape, c, dist, rho); b < best[static_cast<std::size_t>(c)]) {
                best[static_cast<std::size_t>(c)] = b;
                from[static_cast<std::size_t>(c)] = id;
            }
        }
    }
    void settle() { worst = *std::max_element(best.begin(), best.begin() + count()); }
    // The sectors' horizontal distances of one box (sectorRho), each computed on first use.
    struct SectorCache {
        std::array<double, 8> rho;
        std::uint32_t known = 0;
    };
    // Cone c's bound for a box at distance `dist` that meets it: the part of the box the cone
    // reaches (sectorRho, bandDistance) where the cone is narrower than every direction. A
    // column's bound is below those of its sub-boxes, so open() skips the columns no sub-box
    // could improve. A value at or above best[c] may be any such value (it changes nothing).
    double bound(const BoxShape& shape, int c, double dist, SectorCache& cache) const {
        const ConeTest& cone = tests[static_cast<std::size_t>(c)];
        // A box that touches the voxel keeps 0, whatever part of it the cone sees: the marchers
        // test the quadric (or stop) only where the distance is 0.
        if (dist == 0 || !(cone.clipAzimuth || cone.testLo || cone.testHi)) return dist;
        const std::size_t s = static_cast<std::size_t>(cone.sector);
        if (!(cache.known >> s & 1u)) {
            cache.rho[s] = sectorRho(shape, cone);
            cache.known |= 1u << s;
        }
        // |x| >= rho: a sector whose nearest point is already too far (or that misses the box:
        // +Inf; best is finite) needs no band.
        if (cache.rho[s] >= best[static_cast<std::size_t>(c)]) return cache.rho[s];
        return bandDistance(shape, cone, dist, cache.rho[s]);
    }
};
} // namespace detail

/// The largest cap a map accepts (voxels): far beyond any slab's depth, and it keeps the
/// search's column indices in range. The build's time grows with the cap squared where a cone
/// never meets the solid (its search goes out to the cap): keep it near the slab's depth.
inline constexpr float kMaxDdmCap = 65536.0f;

/// Builds the conservative DDM of a height field. The solid of column (i, j) lies inside the
/// boxes of its `subcells` x `subcells` sub-rectangles, each from -Inf up to the largest
/// height of the bilinear patch over it (at one of its corners); for each voxel V and cone C
/// the map stores the smallest, over the difference boxes D = box - V whose directions may lie
/// in C (detail::boxMeetsCone), of a lower bound on |x| over the points x of D in C
/// (detail::ConeSearch::bound; 0 where D holds the origin), found by a search in rings of column
/// blocks that stops when the ring is farther than the best (each block asked first which cones
/// its columns could improve; each voxel starts from the boxes that set its row neighbour's
/// bests). Cap default: `layers` voxels; at most kMaxDdmCap. Rows of
/// voxels on `threads` threads (core/parallel.h; the same map for every count).
inline DirectionalDistanceMap buildDdm(const MesoHeightField& hf, const ConeSet& cones, int subcells = 2, float cap = 0,
                                      int threads = 0) {
    detail::checkMesoSize("directional distance map", hf.width, hf.height, hf.layers);
    checkThreads(threads, "directional distance map");
    cones.validate();
    if (subcells < 1 || subcells > 8) throw ArgumentError("directional distance map: subcells " + std::to_string(subcells) + " not in 1..8");
    if (!(cap >= 0) || !(cap <= kMaxDdmCap))
        throw ArgumentError("directional distance map: cap " + std::to_string(cap) + " not in [0, " + std::to_string(static_cast<int>(kMaxDdmCap)) + "]");
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
    std::array<double, 8> subStart{}; // a / S
    for (int a = 0; a < S; ++a) subStart[static_cast<std::size_t>(a)] = double(a) / S;
    const double subSide = 1.0 / S;
    const int C = cones.count();
    std::vector<detail::ConeTest> tests;
    for (int c = 0; c < C; ++c) tests.push_back(detail::coneTest(cones, c));
    // The columns are searched in a quadtree of blocks: a block's box (its columns' union, up to
    // their highest top) is asked which cones any of its columns could improve; only those
    // cones are asked of its four quarters, and so on down to the columns. tops[l] holds the
    // highest top of the 2^l x 2^l block whose first column is (i, j), wrapped (tops[0] is
    // cellTop).
    constexpr int kLevels = 2, kTop = 1 << kLevels, kHalf = kTop / 2;
    std::vector<std::vector<double>> tops{cellTop};
    for (int l = 0; l < kLevels; ++l) {
        const std::vector<double>& t = tops.back();
        const int e = 1 << l;
        std::vector<double> next(t.size());
        for (int j = 0; j < hf.height; ++j)
            for (int i = 0; i < hf.width; ++i) {
                const int i1 = detail::wrapIndex(i + e, hf.width), j1 = detail::wrapIndex(j + e, hf.height);
                next[static_cast<std::size_t>(j * hf.width + i)] =
                    std::max(std::max(t[static_cast<std::size_t>(j * hf.width + i)], t[static_cast<std::size_t>(j * hf.width + i1)]),
                             std::max(t[static_cast<std::size_t>(j1 * hf.width + i)], t[static_cast<std::size_t>(j1 * hf.width + i1)]));
            }
        tops.push_back(std::move(next));
    }
    // One row of voxels (layer, row) a task: each voxel is independent. All cones of a voxel
    // share one search: the rings go on while any cone's best may still improve, every box's
    // distance and shape are computed once and tested against the cones it could still improve
    // (each of those cones then bounds its own part of the box). Each
    // cone ends with the smallest distance over the boxes that may meet it, as a search of its
    // own would (boxes are only skipped when they cannot beat the cone's best; the order the
    // boxes come in changes no minimum).
    detail::parallelRows(hf.layers * hf.height, threads, [&](int row) {
        const int j = row % hf.height, k = row / hf.height;
        detail::ConeSearch search(tests);
        std::array<std::uint64_t, kMaxCones> warm;
        warm.fill(detail::ConeSearch::kNone);
        for (int i = 0; i < hf.width; ++i) {
            if (k + 1 <= cellMin[static_cast<std::size_t>(j * hf.width + i)]) {
                for (int c = 0; c < C; ++c) m.d[m.index(c, i, j, k)] = 0; // inside the solid
                continue;
            }
            search.reset(m.cap);
            // Sub-box (a, b) of column (ci, cj) (not wrapped) as seen from voxel (i, j, k), and
            // its id for ConeSearch::from.
            const auto subBox = [&](int ci, int cj, std::size_t cell, int a, int b) {
                const double x0 = ci + subStart[static_cast<std::size_t>(a)], y0 = cj + subStart[static_cast<std::size_t>(b)];
                return detail::Box{{x0 - (i + 1.0), y0 - (j + 1.0), bottom - (k + 1.0)},
                                   {x0 + subSide - i, y0 + subSide - j, subTop[cell * static_cast<std::size_t>(S * S) + static_cast<std::size_t>(b * S + a)] - k}};
            };
            constexpr int kBias = 1 << 20; // |ci - i| <= cap + 6 < kBias / 2 (kMaxDdmCap), i < kMaxMesoSize
            const auto subId = [&](int ci, int cj, int a, int b) {
                return static_cast<std::uint64_t>(ci + kBias) << 40 | static_cast<std::uint64_t>(cj + kBias) << 16 | static_cast<std::uint64_t>(b * S + a);
            };
            // Warm start: the boxes that set the previous voxel's bests are offered first (to
            // every cone), so the search skips more of what cannot beat them; the minimum over
            // the same boxes is the same.
            for (int c = 0; c < C; ++c) {
                const std::uint64_t id = warm[static_cast<std::size_t>(c)];
                if (id == detail::ConeSearch::kNone || std::find(warm.begin(), warm.begin() + c, id) != warm.begin() + c) continue;
                const int ci = static_cast<int>(id >> 40) - kBias, cj = static_cast<int>(id >> 16 & 0xFFFFFFu) - kBias;
                const int sub = static_cast<int>(id & 0xFFFFu);
                const std::size_t cell = static_cast<std::size_t>(detail::wrapIndex(cj, hf.height) * hf.width + detail::wrapIndex(ci, hf.width));
                search.offer(subBox(ci, cj, cell, sub % S, sub / S), search.allCones(), id);
            }
            search.settle();
            const auto visit = [&](int di, int dj, std::uint32_t among) {
                const int ci = i + di, cj = j + dj;
                const std::size_t cell = static_cast<std::size_t>(detail::wrapIndex(cj, hf.height) * hf.width + detail::wrapIndex(ci, hf.width));
                const detail::Box cellBox{{ci - (i + 1.0), cj - (j + 1.0), bottom - (k + 1.0)}, {ci + 1.0 - i, cj + 1.0 - j, cellTop[cell] - k}};
                const std::uint32_t open = search.open(cellBox, detail::boxDistance(cellBox), among); // the cones this column may improve
                if (open == 0) return;
                for (int b = 0; b < S; ++b)
                    for (int a = 0; a < S; ++a) search.offer(subBox(ci, cj, cell, a, b), open, subId(ci, cj, a, b));
                search.settle();
            };
            // Block (x0, y0, level l): the columns di = x0 + [0, 2^l), dj = y0 + [0, 2^l).
            const auto block = [&](const auto& self, int x0, int y0, int l, std::uint32_t among) -> void {
                if (l == 0) {
                    visit(x0, y0, among);
                    return;
                }
                const int e = 1 << l;
                const double top = tops[static_cast<std::size_t>(l)][static_cast<std::size_t>(detail::wrapIndex(j + y0, hf.height) * hf.width + detail::wrapIndex(i + x0, hf.width))];
                const detail::Box box{{x0 - 1.0, y0 - 1.0, bottom - (k + 1.0)}, {x0 + double(e), y0 + double(e), top - k}};
                const std::uint32_t open = search.open(box, detail::boxDistance(box), among);
                if (open == 0) return;
                const int h = e / 2;
                self(self, x0, y0, l - 1, open);
                self(self, x0 + h, y0, l - 1, open);
                self(self, x0, y0 + h, l - 1, open);
                self(self, x0 + h, y0 + h, l - 1, open);
            };
            // The top blocks (p, q), x0 = p kTop - kHalf, in rings max(|p|, |q|) = r; ring r is
            // at least r kTop - kHalf - 1 away (horizontally), and no ring that far can improve
            // a cone (the search ends by worst <= cap: the columns beyond the cap's reach are
            // never needed).
            const auto top = [&](int p, int q) { block(block, p * kTop - kHalf, q * kTop - kHalf, kLevels, search.allCones()); };
            for (int r = 0; r * kTop - kHalf - 1 < search.worst; ++r) {
                if (r == 0) {
                    top(0, 0);
                    continue;
                }
                for (int d = -r; d <= r; ++d) {
                    top(d, -r);
                    top(d, r);
                }
                for (int d = -r + 1; d <= r - 1; ++d) {
                    top(-r, d);
                    top(r, d);
                }
            }
            for (int c = 0; c < C; ++c) m.d[m.index(c, i, j, k)] = detail::floatBelow(search.best[static_cast<std::size_t>(c)]);
            warm = search.from;
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
