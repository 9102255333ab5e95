#pragma once
// DisplacedSurface: f(face, u, v) = s + N_s D and its normal, the CPU reference of what the
// renderer draws (Nießner & Loop 2013, §5.1, §5.2, §5.4, §6.2).
//
// Normals, per NormalMode:
//  * Approximate (§5.2, Blinn): f_u = s_u + N_s D_u; no second derivatives of s needed.
//  * Accurate (§5.1): f_u = s_u + N_s,u D + N_s D_u with N_s,u from the Weingarten equations
//    (kernels/normal.h).
//  * Auto: per face, the accurate normal only where a bound on the Weingarten term says the
//    approximate normal is off by more than the caller's tolerance (an angle). The bound is
//    computed once per face, the first time auto normals (or autoFaces()) are asked for: a
//    surface that never uses them never pays the autoSamples^2 evaluations a face (on
//    options().threads threads, the same bounds for every count). At each point of a grid
//    over the face, the angle the
//    Weingarten term turns the approximate normal by (dmWeingartenAngleSine) with |D| widened
//    by half a cell times |grad D| (either sign), largest over the grid, times kAutoMargin for
//    what the grid misses. Between the samples it is an estimate, not a proof; the tests
//    check the promise pointwise on every test mesh, at the finest level. At coarser mips (LOD) D and its gradient change,
//    and with them the angle (it vanishes where grad D = 0, and grows with |D| and |grad D|);
//    the tests measured it only falling there, but the promise is stated for the finest level.
// In end-cap patches at extraordinary corners the normal is interpolated from the patch's
// corners, the limit normal at the extraordinary one (§5.4, dmEndCapNormal): continuous across
// the edges out of the vertex, where each face's own Gregory derivatives are not.
//
// Sharp features: near infinitely sharp creases and corners D fades to 0 (options().sharpBand,
// kernels/sharp.h), so that f is single-valued where the faces' one-sided normals differ.
// displacement() and evaluate() return that faded D; the tiles hold D as fitted.
//
// D comes from the TileSet with the §4.4 clamp always applied (so that tiles of different
// sizes agree along their shared edges) and, for level of detail, at a resolution rho (the
// log2 of the level size to read, §6.2), blending the two nearest levels. rho is in the tile's
// own units: a sub-face of an N-gon (half an edge long) stores no level below s = 2, so where its
// quad neighbour would read s = 1 the two sides of the T-junction differ; callers that pick rho
// per vertex (tessellator.h) floor the resolution of sub-faces accordingly.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "dispmap/core/parallel.h"
#include "dispmap/surface/base_surface.h"
#include "dispmap/kernels/lod.h"
#include "dispmap/kernels/normal.h"
#include "dispmap/kernels/sharp.h"
#include "dispmap/core/tileset.h"

namespace dispmap {

enum class NormalMode { Approximate, Accurate, Auto };
inline const char* toString(NormalMode m) {
    return m == NormalMode::Approximate ? "approximate" : m == NormalMode::Accurate ? "accurate" : "auto";
}

/// The smallest sine of the angle between s_u and s_v above which the first fundamental form
/// is used as it is (kernels/normal.h): where the float error of the Weingarten term, about
/// eps / sin^2, stays near 0.1 (float) and 1e-2 (double).
template <typename real> constexpr real kSinMin = real(1e-3);
template <> inline constexpr double kSinMin<double> = 1e-7;

/// Safety factor of the auto-normal bound over its grid maximum.
inline constexpr double kAutoMargin = 1.25;

/// Resolution that reads the finest level everywhere (still clamped by §4.4).
inline constexpr double kFinest = 64.0;

template <typename real> struct SurfaceSample {
    using vec3 = glm::vec<3, real>;
    vec3 position{0};   ///< f
    vec3 normal{0};     ///< N_f of the mode used (after the §5.4 blend)
    vec3 du{0}, dv{0};  ///< f_u, f_v of the mode used
    vec3 baseNormal{0}; ///< N_s
    vec3 displacement{0}; ///< (D, D_u, D_v)
    bool accurate = false; ///< whether the Weingarten term was included
};

/// A point of the surface's domain: a Ptex face and (u, v) in it.
template <typename real> struct SurfacePoint {
    int face = 0;
    real u = 0, v = 0;
};

struct DisplacedSurfaceOptions {
    /// Width of the band (in base-face edge lengths, (0, 1/2]) over which D fades to 0 towards
    /// infinitely sharp creases and corners, so that the faces on both sides of one meet
    /// (kernels/sharp.h; docs/design.md, "Sharp creases and corners"). 0 turns the rule off:
    /// the one-sided normals then tear the surface open along such features.
    double sharpBand = 0.25;
    /// §5.4: across end-cap patches at extraordinary vertices, normals interpolated from the
    /// patch's corners (kernels/normal.h, dmEndCapNormal), continuous across the edges out of
    /// the vertex. false: the patch's own normal blended towards the limit normal
    /// (dmBlendLimitNormal), which jumps across those edges (the earlier behaviour).
    bool endCapNormals = true;
    /// Auto mode: largest accepted angle (radians) between approximate and accurate normal.
    double autoTolerance = 0.01;
    /// Samples per side of the per-face grid the auto bound is taken over.
    int autoSamples = 17;
    /// Threads of the auto-normal analysis (core/parallel.h: 0 all cores, 1 the calling thread).
    int threads = 0;
};

class DisplacedSurface {
  public:
    /// Throws ArgumentError if the tiles do not belong to the surface's mesh (tile count, or the
    /// topology hash where the tile set has one) or the options are out of range (tolerance not
    /// finite or < 0, samples outside [2, 1024], sharp band outside [0, 1/2]), or if the mesh has
    /// infinitely sharp features, the band is > 0 and the isolation level is 1.
    DisplacedSurface(const BaseSurface& base, const TileSet& tiles, DisplacedSurfaceOptions options = {});
    /// The surface keeps pointers to the base and the tiles: temporaries would dangle.
    DisplacedSurface(BaseSurface&&, const TileSet&, DisplacedSurfaceOptions = {}) = delete;
    DisplacedSurface(const BaseSurface&, TileSet&&, DisplacedSurfaceOptions = {}) = delete;

    const BaseSurface& base() const { return *base_; }
    const TileSet& tiles() const { return *tiles_; }
    const DisplacedSurfaceOptions& options() const { return options_; }
    /// The disc around a corner touched by a sharp feature where D is 0 before it fades in
    /// (kernels/sharp.h): the diagonal of the end caps, sqrt(2) 2^-isolation base-face edges.
    double sharpCapRadius() const { return 1.4142135623730951 * std::ldexp(1.0, -base_->options().isolationLevel); }
    /// The band the fade uses: options().sharpBand, at most 1/2 - sharpCapRadius() (a feature's
    /// ramp must end before it reaches an edge whose other face cannot see that feature: the
    /// spokes of an N-gon's sub-faces are 1/2 from their vertex), so 0.146 at isolation 2.
    double sharpBand() const { return sharpBand_; }

    /// Per Ptex face: whether auto mode evaluates the accurate normal there. These three run the
    /// auto-normal analysis if it has not run yet (once; thread-safe).
    const std::vector<std::uint8_t>& autoFaces() const { return autoAnalysis().accurate; }
    /// How many faces auto mode evaluates accurately, and the bound per face (sine).
    int autoAccurateCount() const { return autoAnalysis().count; }
    double autoBound(int face) const { return autoAnalysis().bound[base_->checkedFace(face)]; }
    /// Whether the auto-normal analysis has run (it runs on the first use of auto normals).
    bool autoAnalysed() const { return auto_->done.load(std::memory_order_acquire); }

    /// (D, D_u, D_v) at (face, u, v) read at resolution rho (kFinest: the finest level the
    /// §4.4 clamp allows). Throws ArgumentError for a face id out of range, (u, v) outside
    /// [0, 1]^2 or not finite, or a NaN rho.
    template <typename real> glm::vec<3, real> displacement(int face, real u, real v, real rho = real(kFinest)) const;

    /// f, N_f and the rest at (face, u, v); throws as BaseSurface::evaluate, and for a NaN rho.
    template <typename real>
    SurfaceSample<real> evaluate(int face, real u, real v, NormalMode mode, real rho = real(kFinest)) const;

    /// evaluate() at many points: out[i] is evaluate(points[i], mode, rho) bit for bit. The points
    /// are visited face by face (a stable counting sort), so that each face's tile and patches
    /// stay in cache while its points are evaluated, on `threads` threads (core/parallel.h).
    /// Every point is checked first: ArgumentError for the first bad one in index order (face
    /// out of range, a hole, (u, v) outside [0, 1]^2 or not finite, a NaN rho), nothing written.
    template <typename real>
    void evaluateBatch(const std::vector<SurfacePoint<real>>& points, NormalMode mode, std::vector<SurfaceSample<real>>& out,
                       int threads = 0, real rho = real(kFinest)) const;

    /// evaluate() on the grid us[i] x vs[j] of one Ptex face (a tessellation's inner grid, or a
    /// line of it: one u or one v): sink(i, j, sample) once per point, line by line along the
    /// longer side (row by row, j outer, unless vs is longer than us: then column by column),
    /// with the resolution rhoAt(i, j). Where approximate normals are used and a regular patch
    /// holds the point, the base surface comes from BaseSurface::Row (each patch collapsed once
    /// per line) and D from TileSet::Row; there the sample is evaluate()'s to rounding, not bit
    /// for bit (tests/test_surface.cpp bounds it). Elsewhere (accurate normals, end caps, a
    /// degenerate s_u x s_v) it is evaluate() itself; where s_u x s_v is nearly degenerate the
    /// two routes' normals may differ by more than rounding (a normal that is undefined there
    /// either way). Every point of a line is checked, in order, before any of it is delivered:
    /// ArgumentError as evaluate() throws it for a face out of range, a NaN rho, a coordinate
    /// outside [0, 1] or not finite, or a hole (the lines before were delivered).
    template <typename real, typename RhoAt, typename Sink>
    void evaluateGrid(int face, std::span<const real> us, std::span<const real> vs, NormalMode mode, RhoAt&& rhoAt, Sink&& sink) const;

  private:
    /// The checks of displacement() (evaluate leaves (u, v) and holes to BaseSurface).
    template <typename real> void check(int face, real u, real v, real rho, bool uv) const;
    /// D of the tiles (levels blended), and with the sharp-feature fade applied.
    template <typename real> glm::vec<3, real> displacementAt(int face, real u, real v, real rho) const;
    template <typename real> glm::vec<3, real> featheredAt(int face, real u, real v, real rho) const;
    /// d1 (D of the tiles at (face, u, v)) with the sharp-feature fade applied.
    template <typename real> glm::vec<3, real> feathered(int face, real u, real v, const glm::vec<3, real>& d1) const;
    /// N_s and the displaced normal (frame du, dv) of the mode at one base sample.
    template <typename real>
    glm::vec<3, real> displacedNormal(const BaseSample<real>& s, glm::vec<2, real> uv, const glm::vec<3, real>& d1, bool accurate,
                                      glm::vec<3, real>& N, glm::vec<3, real>& du, glm::vec<3, real>& dv) const;
    template <typename real>
    glm::vec<3, real> endCapNormal(int face, real u, real v, bool accurate, real rho, const glm::vec<3, real>& own) const;
    /// The auto-normal analysis, computed on first use (copies of the surface share it).
    struct AutoAnalysis {
        std::once_flag once;
        std::atomic<bool> done{false};
        std::vector<std::uint8_t> accurate;
        std::vector<double> bound;
        int count = 0;
    };
    const AutoAnalysis& autoAnalysis() const;
    double autoFaceBound(int face) const;
    const BaseSurface* base_;
    const TileSet* tiles_;
    DisplacedSurfaceOptions options_;
    double sharpBand_ = 0;
    std::shared_ptr<AutoAnalysis> auto_ = std::make_shared<AutoAnalysis>();
};

template <typename real> void DisplacedSurface::check(int face, real u, real v, real rho, bool uv) const {
    if (uv)
        base_->checkPoint(face, u, v);
    else
        base_->checkedFace(face);
    if (std::isnan(rho)) throw ArgumentError("displaced surface: resolution rho is NaN (face " + std::to_string(face) + ")");
}

template <typename real> glm::vec<3, real> DisplacedSurface::displacement(int face, real u, real v, real rho) const {
    check(face, u, v, rho, true);
    return featheredAt(face, u, v, rho);
}

template <typename real> glm::vec<3, real> DisplacedSurface::displacementAt(int face, real u, real v, real rho) const {
    const Tile& t = tiles_->tiles[static_cast<std::size_t>(face)];
    const glm::vec<2, real> uv(u, v);
    auto level = [&](int m) { return tiles_->evaluateD1(face, m, uv); };
    // Finest level with no smaller tile at any corner: dmSelectMips would pick level 0 alone.
    // Said directly, because the selection's latency sits in front of the loads (measured:
    // 18 of 38 ns).
    if (rho >= real(t.k) && (t.sizeDifferences[0] | t.sizeDifferences[1] | t.sizeDifferences[2] | t.sizeDifferences[3]) == 0)
        return level(0);
    const glm::ivec4 diffs(t.sizeDifferences[0], t.sizeDifferences[1], t.sizeDifferences[2], t.sizeDifferences[3]);
    const real maxRes = kern::dmMaxResolution(t.k, diffs, uv);
    int mFine = 0, mCoarse = 0;
    const real w = kern::dmSelectMips(rho, maxRes, t.k, mFine, mCoarse);
    const glm::vec<3, real> coarse = level(mCoarse);
    if (w == real(0)) return coarse;
    return kern::dmBlendMips(coarse, level(mFine), w);
}

template <typename real> glm::vec<3, real> DisplacedSurface::featheredAt(int face, real u, real v, real rho) const {
    return feathered(face, u, v, displacementAt(face, u, v, rho));
}

template <typename real> glm::vec<3, real> DisplacedSurface::feathered(int face, real u, real v, const glm::vec<3, real>& d1) const {
    const int mask = base_->sharpMask(face);
    if (mask == 0) return d1;
    return kern::dmSharpFeather(glm::vec<2, real>(u, v), mask, base_->topology().scale(face), static_cast<real>(sharpBand_),
                                static_cast<real>(sharpCapRadius()), d1);
}

template <typename real>
glm::vec<3, real> DisplacedSurface::displacedNormal(const BaseSample<real>& s, glm::vec<2, real> uv, const glm::vec<3, real>& d1,
                                                    bool accurate, glm::vec<3, real>& N, glm::vec<3, real>& du,
                                                    glm::vec<3, real>& dv) const {
    const glm::vec<3, real> fallback(real(0), real(0), real(1));
    N = kern::dmBaseNormal(s.du, s.dv, s.duu, s.duv, s.dvv, uv, fallback);
    if (accurate) {
        glm::vec<3, real> Nu, Nv;
        kern::dmNormalDerivWeingarten(s.du, s.dv, s.duu, s.duv, s.dvv, N, kSinMin<real>, Nu, Nv);
        return kern::dmDisplacedNormalAccurate(s.du, s.dv, N, Nu, Nv, d1, du, dv);
    }
    return kern::dmDisplacedNormalApprox(s.du, s.dv, N, d1, du, dv);
}

template <typename real>
glm::vec<3, real> DisplacedSurface::endCapNormal(int face, real u, real v, bool accurate, real rho, const glm::vec<3, real>& own) const {
    EndCapCorners<real> ec;
    base_->endCapCorners(face, u, v, ec);
    glm::vec<3, real> n[4];
    int evCorner = 0;
    for (int c = 3; c >= 0; --c) {
        if (base_->isExtraordinaryCorner(face, c) && glm::dvec2(ec.uv[c]) == TileTopology::cornerUV(c)) {
            n[c] = glm::vec<3, real>(base_->cornerNormal(face, c));
            evCorner = c;
        } else {
            glm::vec<3, real> N, du, dv;
            const glm::vec<3, real> d1 = featheredAt(face, ec.uv[c].x, ec.uv[c].y, rho);
            n[c] = displacedNormal(ec.corner[c], ec.uv[c], d1, accurate, N, du, dv);
        }
    }
    return kern::dmEndCapNormal(n[0], n[1], n[2], n[3], ec.local, own, evCorner);
}

template <typename real>
SurfaceSample<real> DisplacedSurface::evaluate(int face, real u, real v, NormalMode mode, real rho) const {
    check(face, u, v, rho, false); // before the auto analysis reads [face]; BaseSurface checks (u, v) and holes
    const bool accurate = mode == NormalMode::Accurate ||
                          (mode == NormalMode::Auto && autoAnalysis().accurate[static_cast<std::size_t>(face)] != 0);
    // Approximate normals need first derivatives only; the second are fetched where s_u x s_v
    // vanishes, for the Taylor fallback of dmBaseNormal.
    BaseSample<real> s = base_->evaluate(face, u, v, accurate);
    if (!accurate) {
        const glm::vec<3, real> n0 = glm::cross(s.du, s.dv);
        if (!(kern::dmDot3(n0, n0) > real(0))) s = base_->evaluate(face, u, v, true);
    }
    SurfaceSample<real> out;
    const glm::vec<3, real> d1 = featheredAt(face, u, v, rho);
    glm::vec<3, real> N;
    const glm::vec<3, real> n = displacedNormal(s, glm::vec<2, real>(u, v), d1, accurate, N, out.du, out.dv);
    out.position = s.p + N * d1.x;
    if (s.endCap && options_.endCapNormals)
        out.normal = endCapNormal(face, u, v, accurate, rho, n);
    else if (s.evWeight > real(0))
        out.normal = kern::dmBlendLimitNormal(n, s.evNormal, s.evWeight);
    else
        out.normal = n;
    out.baseNormal = N;
    out.displacement = d1;
    out.accurate = accurate;
    return out;
}

template <typename real, typename RhoAt, typename Sink>
void DisplacedSurface::evaluateGrid(int face, std::span<const real> us, std::span<const real> vs, NormalMode mode, RhoAt&& rhoAt,
                                    Sink&& sink) const {
    using vec3 = glm::vec<3, real>;
    base_->checkedFace(face);
    const bool accurate = mode == NormalMode::Accurate ||
                          (mode == NormalMode::Auto && autoAnalysis().accurate[static_cast<std::size_t>(face)] != 0);
    // Lines along the longer side: rows (v fixed) unless there are more rows than columns.
    const bool alongV = vs.size() > us.size();
    const std::span<const real> xs = alongV ? vs : us, fixed = alongV ? us : vs;
    // D of the finest level along the line, where displacementAt() reads level 0 alone (rho >=
    // k and no smaller tile at a corner).
    const Tile& tile = tiles_->tiles[static_cast<std::size_t>(face)];
    std::optional<TileSet::Row<real>> dRow;
    if (!accurate && (tile.sizeDifferences[0] | tile.sizeDifferences[1] | tile.sizeDifferences[2] | tile.sizeDifferences[3]) == 0)
        dRow.emplace(*tiles_, face, 0, alongV);
    // A line's points in stages, each a short loop over independent points, so that the square
    // roots and divisions of several points overlap (one point's normal is a chain of two).
    struct Point {
        BaseSample<real> s;
        vec3 d1{0}, N{0}, n{0}, fu{0}, fv{0};
        real rho = 0;
        bool line = false; ///< the line's route; false: evaluate()
    };
    std::vector<Point> line(xs.size());
    for (std::size_t b = 0; b < fixed.size(); ++b) {
        const real f = fixed[b];
        auto ij = [&](std::size_t a) { return alongV ? std::pair(b, a) : std::pair(a, b); };
        // 0. Every point checked as evaluate() checks it (rho, then (u, v), then a hole), before
        // anything of the line is made or delivered.
        bool finest = false; // whether a point reads level 0 alone (rho >= k)
        for (std::size_t a = 0; a < xs.size(); ++a) {
            const auto [i, j] = ij(a);
            line[a].rho = rhoAt(i, j);
            check(face, us[i], vs[j], line[a].rho, false);
            base_->checkPoint(face, us[i], vs[j]);
            finest = finest || line[a].rho >= real(tile.k);
        }
        if (xs.empty()) continue;
        base_->checkNotHole(face);
        std::optional<BaseSurface::Row<real>> baseRow;
        if (!accurate) baseRow.emplace(*base_, face, f, alongV);
        const bool dLine = dRow && finest;
        if (dLine) dRow->setRow(f, xs);
        // 1. s and D. evaluate()'s route for approximate normals in a regular patch (no end-cap
        // or §5.4 data there), unless s_u x s_v vanishes and its fallback needs s_uu.
        for (std::size_t a = 0; a < xs.size(); ++a) {
            Point& p = line[a];
            const auto [i, j] = ij(a);
            const real u = us[i], v = vs[j];
            p.line = baseRow && baseRow->at(xs[a], p.s);
            if (p.line) {
                const vec3 n0 = glm::cross(p.s.du, p.s.dv);
                p.line = kern::dmDot3(n0, n0) > real(0);
            }
            if (p.line) p.d1 = dLine && p.rho >= real(tile.k) ? feathered(face, u, v, dRow->at(xs[a])) : featheredAt(face, u, v, p.rho);
        }
        // 2. N_s, 3. the displaced normal (displacedNormal()'s two steps).
        const vec3 fallback(real(0), real(0), real(1));
        for (std::size_t a = 0; a < xs.size(); ++a)
            if (Point& p = line[a]; p.line) {
                const auto [i, j] = ij(a);
                p.N = kern::dmBaseNormal(p.s.du, p.s.dv, p.s.duu, p.s.duv, p.s.dvv, glm::vec<2, real>(us[i], vs[j]), fallback);
            }
        for (std::size_t a = 0; a < xs.size(); ++a)
            if (Point& p = line[a]; p.line) p.n = kern::dmDisplacedNormalApprox(p.s.du, p.s.dv, p.N, p.d1, p.fu, p.fv);
        // 4. Delivered in order.
        for (std::size_t a = 0; a < xs.size(); ++a) {
            const Point& p = line[a];
            const auto [i, j] = ij(a);
            if (!p.line) {
                sink(i, j, evaluate<real>(face, us[i], vs[j], mode, p.rho));
                continue;
            }
            SurfaceSample<real> out;
            out.position = p.s.p + p.N * p.d1.x;
            out.normal = p.n;
            out.du = p.fu;
            out.dv = p.fv;
            out.baseNormal = p.N;
            out.displacement = p.d1;
            out.accurate = false;
            sink(i, j, out);
        }
    }
}

template <typename real>
void DisplacedSurface::evaluateBatch(const std::vector<SurfacePoint<real>>& points, NormalMode mode, std::vector<SurfaceSample<real>>& out,
                                     int threads, real rho) const {
    checkThreads(threads, "evaluateBatch");
    const int faces = base_->faceCount();
    // Checked in index order before anything is evaluated; then counted per face.
    std::vector<std::size_t> start(static_cast<std::size_t>(faces) + 1, 0);
    for (const SurfacePoint<real>& p : points) {
        check(p.face, p.u, p.v, rho, true);
        if (base_->isHole(p.face)) throw ArgumentError("evaluateBatch: face " + std::to_string(p.face) + " is a hole (no surface to evaluate)");
        ++start[static_cast<std::size_t>(p.face) + 1];
    }
    for (std::size_t f = 0; f < static_cast<std::size_t>(faces); ++f) start[f + 1] += start[f];
    std::vector<std::size_t> order(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) order[start[static_cast<std::size_t>(points[i].face)]++] = i;
    if (mode == NormalMode::Auto) (void)autoAnalysis(); // once, before the loop
    out.resize(points.size());
    Parallel(threads).each(order.size(), 256, [&](std::size_t j) {
        const SurfacePoint<real>& p = points[order[j]];
        out[order[j]] = evaluate<real>(p.face, p.u, p.v, mode, rho);
    });
}

inline DisplacedSurface::DisplacedSurface(const BaseSurface& base, const TileSet& tiles, DisplacedSurfaceOptions options)
    : base_(&base), tiles_(&tiles), options_(options) {
    if (tiles.tileCount() != base.faceCount())
        throw ArgumentError("the tile set has " + std::to_string(tiles.tileCount()) + " tiles but the surface has " +
                            std::to_string(base.faceCount()) + " Ptex faces: it was built for another mesh");
    if (tiles.topologyHash != 0 && tiles.topologyHash != base.topologyHash())
        throw ArgumentError("the tile set was built for another mesh topology than the surface (topology hashes differ)");
    if (!std::isfinite(options.autoTolerance) || options.autoTolerance < 0.0)
        throw ArgumentError("auto-normal tolerance must be a finite angle >= 0 (radians)");
    if (options.autoSamples < 2 || options.autoSamples > 1024)
        throw ArgumentError("auto-normal samples per side must be in [2, 1024]");
    if (!(options.sharpBand >= 0.0 && options.sharpBand <= 0.5))
        throw ArgumentError("sharp-feature band must be in [0, 1/2] base-face edge lengths (0: off)");
    bool sharpFeatures = false;
    for (int f = 0; f < base.faceCount(); ++f) sharpFeatures = sharpFeatures || base.sharpMask(f) != 0;
    if (sharpFeatures && options.sharpBand > 0.0) {
        if (sharpCapRadius() >= 0.5)
            throw ArgumentError("the mesh has infinitely sharp creases or corners, which need isolation level 2 or more (the end "
                                "caps at level 1 cover half a face, so D cannot fade out around them); raise the isolation level, "
                                "or set the sharp-feature band to 0 (the creases then open)");
        sharpBand_ = std::min(options.sharpBand, 0.5 - sharpCapRadius());
    }
    checkThreads(options.threads, "displaced surface");
}

inline double DisplacedSurface::autoFaceBound(int f) const {
    const BaseSurface& base = *base_;
    if (base.isHole(f)) return 0.0;
    double bound = 0;
    const int m = options_.autoSamples;
    const double h = 1.0 / double(m - 1);
    for (int j = 0; j < m && bound < 1.0; ++j)
        for (int i = 0; i < m && bound < 1.0; ++i) {
            const double u = i * h, v = j * h;
            const BaseSample<double> s = base.evaluate(f, u, v, true);
            const glm::dvec3 N = kern::dmBaseNormal(s.du, s.dv, s.duu, s.duv, s.dvv, glm::dvec2(u, v), glm::dvec3(0, 0, 1));
            glm::dvec3 Nu, Nv, au, av;
            kern::dmNormalDerivWeingarten(s.du, s.dv, s.duu, s.duv, s.dvv, N, kSinMin<double>, Nu, Nv);
            const glm::dvec3 d1 = featheredAt(f, u, v, kFinest);
            kern::dmDisplacedNormalApprox(s.du, s.dv, N, d1, au, av);
            // The largest |D| in the cell around the sample, to first order, either sign.
            const double absD = std::abs(d1.x) + 0.5 * h * (std::abs(d1.y) + std::abs(d1.z));
            bound = std::max({bound, kern::dmWeingartenAngleSine(au, av, Nu, Nv, absD),
                              kern::dmWeingartenAngleSine(au, av, Nu, Nv, -absD)});
        }
    return std::min(1.0, kAutoMargin * bound);
}

inline const DisplacedSurface::AutoAnalysis& DisplacedSurface::autoAnalysis() const {
    AutoAnalysis& a = *auto_;
    if (a.done.load(std::memory_order_acquire)) return a;
    std::call_once(a.once, [&] {
        const std::size_t n = static_cast<std::size_t>(base_->faceCount());
        a.accurate.assign(n, 0);
        a.bound.assign(n, 0.0);
        // Faces are independent: each writes its own bound (the same for every thread count).
        Parallel(options_.threads).each(n, 16, [&](std::size_t f) { a.bound[f] = autoFaceBound(static_cast<int>(f)); });
        const double limit = std::sin(std::min(options_.autoTolerance, 1.5707963267948966));
        for (std::size_t f = 0; f < n; ++f)
            if (a.bound[f] > limit) {
                a.accurate[f] = 1;
                ++a.count;
            }
        a.done.store(true, std::memory_order_release);
    });
    return a;
}

} // namespace dispmap
