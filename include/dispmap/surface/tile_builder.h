#pragma once
// Building a TileSet from a control mesh and a displacement source (Nießner & Loop 2013, §4).
//
// What is solved. Per tile of size s the displacement D is sampled at the s x s sub-patch
// centres ((i + 1/2)/s, (j + 1/2)/s), where a uniform biquadratic B-spline takes the value
// sum_ab w_a w_b c_(i+a, j+b) with w = (1, 6, 1)/8. Interpolating all samples of all tiles
// at once is one sparse, strictly diagonally dominant system whose unknowns are the tiles'
// interior coefficients; the overlap ring of each tile is not an unknown, it is a copy of
// the neighbours' coefficients (or the boundary rule). We solve it by block sweeps: with its
// ring fixed, a tile's (T x T) x = rhs system (T = tridiag(1, 6, 1)/8) is solved exactly by two
// passes of the Thomas algorithm. Where every tile's finest level has one resolution and 8 x 8
// texels or more, a sweep is block Gauss-Seidel over colours: the tiles are coloured so that no
// two of a colour share a vertex or an edge, and each colour's tiles get their rings from the
// latest iterate and are solved (in parallel: they read and write nothing of each other's).
// Otherwise (mixed resolutions, whose coarser levels are mips of finer ones; small tiles, where
// visiting the tiles colour by colour costs more memory traffic than the sweeps it saves) a
// sweep is block Gauss-Jacobi: every ring refreshed, then every tile solved. Extrapolated ring
// texels are damped during the sweeps (TileBuild::kDamp). Jacobi's error shrinks about 0.37x a
// sweep, Gauss-Seidel's about 0.15x: on the OpenSubdiv shapes at most 31 sweeps reach double
// precision (k = 1..5 and mixed sizes); the report says how many ran.
// On data that is itself a biquadratic spline over the mesh the fit returns its coefficients.
//
// Rules for the overlap ring (every level, every tile), in this order:
//  * edges: the neighbour's first interior row at the matching resolution, through the
//    rotation between the two tiles' (u, v) frames (TileTopology::Link). Where the neighbour
//    has no level at that resolution (mixed sizes), or at a boundary, the ring is the linear
//    extrapolation 2 c_1 - c_2 of the tile's own rows: D continues with its slope.
//  * corners at a regular interior vertex (4 tiles): the diagonal tile's interior corner;
//  * corners at a boundary vertex with 1 or 2 tiles: extrapolated along the ring of the
//    shared edge, which is what the neighbour's own boundary ring holds there, so D stays C1
//    along the boundary;
//  * extraordinary vertices (interior valence != 4, boundary vertices with 3 or more tiles):
//    the Doo-Sabin corner constraint of §4.2: every incident tile's interior corner is set
//    to their average, and its 2 x 2 corner block to that value, so D_u = D_v = 0 there;
//  * the T-junction where a quad edge meets two sub-faces of an N-gon: the sub-face's ring
//    continues along the quad's row past the edge midpoint; where the quad's coarsest level
//    (s = 2) meets the sub-face, the sub-face provides a virtual s = 1 level (never stored);
//  * mixed sizes at a regular vertex whose diagonal tile lacks the level: every tile that
//    has it uses the parallelogram rule (the two edge neighbours minus the diagonal), so they
//    all agree on the missing quadrant's texel.
//  * creases: D ignores them. It stays C1 across a crease in the face parameters; the
//    displaced surface keeps the base surface's crease through N_s.
// Mixed sizes (§4.4): levels are processed from the finest resolution to the coarsest, so
// that at each resolution every tile's ring copies neighbour data of that same resolution.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "dispmap/core/height_image.h"
#include "dispmap/core/parallel.h"
#include "dispmap/surface/mesh.h"
#include "dispmap/surface/tile_topology.h"
#include "dispmap/core/tileset.h"

namespace dispmap {

/// D(ptexFace, u, v): a displacement defined on the mesh's face parameterisation.
using DisplacementFunction = std::function<double(int ptexFace, double u, double v)>;
/// A procedural source: any callable of (ptexFace, u, v) giving D.
inline DisplacementFunction FunctionSource(DisplacementFunction f) { return f; }

struct BuildOptions {
    MipFilter filter = MipFilter::Haar;
    int maxSweeps = 100;     ///< sweeps of the interpolating fit at most (at most 31 reach the tolerance on the OpenSubdiv shapes)
    double tolerance = 1e-13; ///< stop when no coefficient moves more than this x (1 + max |sample|)
    /// Threads for sampling, fit and mips (core/parallel.h: 0 all cores, 1 the calling thread).
    /// The tiles are the same bit for bit for every count. With more than one thread the
    /// source is called from several threads at once: it must allow that (the library's
    /// sources do: images, functions of (face, u, v), ray casts).
    int threads = 0;
};

struct BuildReport {
    int sweeps = 0;              ///< fit sweeps run
    double lastChange = 0;       ///< largest coefficient change in the last sweep
    double maxResidual = 0;      ///< max |D(sample) - sample| over all samples (double coefficients)
    double maxResidualAwayFromConstraints = 0; ///< same, excluding samples whose stencil reads a constrained corner block
    int constrainedVertices = 0; ///< vertices with the Doo-Sabin corner constraint
    int tJunctions = 0;          ///< quad/sub-face T-junctions
};

/// Per base face: 1 for a quad at either end of an edge that it or another quad shares with a
/// non-quad face. At a T-junction the builder needs such a quad to have the largest size (the
/// sub-faces' k + 1) and no smaller tile at the edge's ends; mixedTileSizes and
/// texelTileSizes keep these quads at k.
inline std::vector<char> quadsPinnedByNonQuads(const ControlMesh& mesh) {
    const Far::TopologyLevel& L = mesh.base();
    std::vector<char> vertex(static_cast<std::size_t>(L.GetNumVertices()), 0);
    for (int e = 0; e < L.GetNumEdges(); ++e) {
        bool quad = false, other = false;
        for (int f : L.GetEdgeFaces(e)) (L.GetFaceVertices(f).size() == 4 ? quad : other) = true;
        if (!(quad && other)) continue;
        for (int v : L.GetEdgeVertices(e)) vertex[static_cast<std::size_t>(v)] = 1;
    }
    std::vector<char> out(static_cast<std::size_t>(L.GetNumFaces()), 0);
    for (int f = 0; f < L.GetNumFaces(); ++f) {
        if (L.GetFaceVertices(f).size() != 4) continue;
        for (int v : L.GetFaceVertices(f)) out[static_cast<std::size_t>(f)] |= vertex[static_cast<std::size_t>(v)];
    }
    return out;
}

/// Tile sizes (log2) for every Ptex face: quads get k, sub-faces of non-quads k - 1, so that
/// texels have the same spacing along every base edge. Throws ArgumentError if k is out of
/// range, or k < 2 on a mesh with non-quad faces.
inline std::vector<int> uniformTileSizes(const ControlMesh& mesh, int k) {
    if (k < kMinTileLog2 || k > kMaxTileLog2)
        throw ArgumentError("tile size 2^" + std::to_string(k) + " out of range: k must be in [" +
                            std::to_string(kMinTileLog2) + ", " + std::to_string(kMaxTileLog2) + "]");
    std::vector<int> out(static_cast<std::size_t>(mesh.ptexFaceCount()), k);
    const Far::TopologyLevel& L = mesh.base();
    for (int f = 0; f < L.GetNumFaces(); ++f) {
        const int n = L.GetFaceVertices(f).size();
        if (n == 4) continue;
        if (k - 1 < kMinTileLog2)
            throw ArgumentError(mesh.description().name + ": face " + std::to_string(f + 1) +
                                " is not a quad; its sub-face tiles need k >= 2");
        for (int j = 0; j < n; ++j) out[static_cast<std::size_t>(mesh.ptex().GetFaceId(f) + j)] = k - 1;
    }
    return out;
}

/// The size one tile needs for its data (§4.4's mixed sizes, chosen by the data): given its
/// 2^kMax x 2^kMax samples at the sub-patch centres (row j = v, `fine`), the smallest k in
/// [max(kMin, 1), kMax] whose samples, the 2^(kMax - k)-square box means of the fine ones (i.e.
/// prefiltered), reproduce every fine sample within `tolerance` when interpolated bilinearly
/// between their centres (clamped at the tile's border). Returns k; `fine` is replaced by the
/// samples at k. Sizes only grow the error monotonically in practice, so the search stops at
/// the first k that fails. Throws ArgumentError if `fine` does not hold 4^kMax samples.
inline int coarsestTileWithin(std::vector<double>& fine, int kMax, double tolerance, int kMin = kMinTileLog2) {
    kMin = std::max(kMin, 1); // two samples a side at least (the interpolation below)
    if (kMax < kMinTileLog2 || kMax > kMaxTileLog2 || fine.size() != std::size_t{1} << (2 * kMax))
        throw ArgumentError("coarsestTileWithin: " + std::to_string(fine.size()) + " samples for a tile of 2^" + std::to_string(kMax) +
                            " x 2^" + std::to_string(kMax));
    const int sf = 1 << kMax;
    int chosen = kMax;
    std::vector<double> best = fine;
    for (int kk = kMax - 1; kk >= kMin; --kk) {
        const int s = 1 << kk, r = sf / s;
        std::vector<double> coarse(static_cast<std::size_t>(s * s), 0.0);
        for (int j = 0; j < sf; ++j)
            for (int i = 0; i < sf; ++i) coarse[static_cast<std::size_t>((j / r) * s + i / r)] += fine[static_cast<std::size_t>(j * sf + i)];
        for (double& c : coarse) c /= static_cast<double>(r * r);
        double err = 0.0;
        for (int j = 0; j < sf && err <= tolerance; ++j)
            for (int i = 0; i < sf; ++i) {
                // the fine centre in coarse sample coordinates
                const double x = std::clamp((i + 0.5) / r - 0.5, 0.0, s - 1.0), y = std::clamp((j + 0.5) / r - 0.5, 0.0, s - 1.0);
                const int x0 = std::min(static_cast<int>(x), s - 2), y0 = std::min(static_cast<int>(y), s - 2); // s >= 2
                const int x1 = x0 + 1, y1 = y0 + 1;
                const double fx = x - x0, fy = y - y0;
                const auto at = [&](int a, int b) { return coarse[static_cast<std::size_t>(b * s + a)]; };
                const double v = (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x1, y0)) + fy * ((1 - fx) * at(x0, y1) + fx * at(x1, y1));
                const double d = std::abs(v - fine[static_cast<std::size_t>(j * sf + i)]);
                if (!(d <= err)) err = d; // a NaN sample makes err NaN
            }
        if (!(err <= tolerance)) break; // NaN samples never pass
        chosen = kk;
        best = std::move(coarse);
    }
    fine = std::move(best);
    return chosen;
}

namespace detail {

/// The working state of a build: every level of every tile in double precision.
///
/// Memory: the sweeps of a large set are bound by memory, not arithmetic (a tile of 4 x 4 has
/// 16 unknowns and reads 20 ring texels of other tiles), so the state is kept compact and in
/// the order the sweeps walk it: one array holds every tile's level 0 (in tile order, or
/// colour by colour where the sweeps are Gauss-Seidel), then every tile's level 1, and so on
/// (levels 0..k-1 and the virtual level k of size 1, see sourceLevelAt); the fit solves
/// straight into level 0's interior, keeping aside only the four corner texels it solved
/// (which the corner constraint overwrites there); the ring plans are flat arrays.
class TileBuild {
  public:
    TileBuild(const TileTopology& topo, std::vector<int> k) : topo_(topo), k_(std::move(k)) {
        const int n = topo.tileCount();
        // Level 0 of tile t is level rank_[t]: tile order, or where the sweeps run in
        // Gauss-Seidel order, colour by colour (greedy colouring in tile order: the smallest
        // colour no earlier tile sharing a vertex or an edge link has). The tiles' levels 1..k
        // follow all the level 0s, in tile order.
        colourOf_.assign(u(n), 0);
        rank_.resize(u(n));
        // Gauss-Seidel where every level 0 has one resolution and 8 x 8 texels or more: it needs
        // about half the sweeps, but visits the tiles colour by colour, which on small tiles
        // costs more in memory traffic than the sweeps it saves (figures.md, "Production-size
        // cages": on the bunny's 4 x 4 tiles 1.2x slower, on 8 x 8 and larger 1.2-1.8x faster).
        seidel_ = true;
        for (int t = 0; t < n; ++t) seidel_ = seidel_ && global(t, 0) == global(0, 0) && k_[u(t)] >= 3;
        std::vector<int> order(u(n));
        for (int t = 0; t < n; ++t) order[u(t)] = t;
        if (seidel_) {
            std::vector<char> used;
            int colours = 0;
            for (int t = 0; t < n; ++t) {
                used.assign(u(colours + 1), 0);
                for (int c = 0; c < 4; ++c) {
                    for (auto [ot, oc] : topo_.incidences(topo_.cornerVertex(t, c)))
                        if (ot < t) used[u(colourOf_[u(ot)])] = 1;
                    for (const TileTopology::Link& l : topo_.links(t, c))
                        if (l.tile < t) used[u(colourOf_[u(l.tile)])] = 1;
                }
                colourOf_[u(t)] = static_cast<int>(std::find(used.begin(), used.end(), 0) - used.begin());
                colours = std::max(colours, colourOf_[u(t)] + 1);
            }
            std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return colourOf_[u(a)] < colourOf_[u(b)]; });
        }
        for (int i = 0; i < n; ++i) rank_[u(order[u(i)])] = u(i);
        std::size_t levels = u(n);
        firstLevel_.resize(u(n));
        for (int t = 0; t < n; ++t) {
            firstLevel_[u(t)] = levels - 1;
            levels += u(k_[u(t)]);
        }
        levelOffset_.resize(levels);
        ringFirst_.resize(levels);
        std::size_t texels = 0, ring = 0;
        for (int m = 0; m <= kMaxTileLog2; ++m)
            for (int i = 0; i < n; ++i) {
                const int t = m == 0 ? order[u(i)] : i;
                if (m > k_[u(t)]) continue;
                levelOffset_[levelIndex(t, m)] = texels;
                texels += levelTexels(size(t, m));
                ringFirst_[levelIndex(t, m)] = ring;
                if (m < k_[u(t)]) ring += u(4 * size(t, m));
            }
        pool_.assign(texels, 0.0);
        ringSource_.assign(ring, nullptr);
        levelPlans_.resize(levels);
        raw_.assign(u(4 * n), 0.0);
        diagonal_.resize(static_cast<std::size_t>(n));
        for (int t = 0; t < n; ++t)
            for (int c = 0; c < 4; ++c) findDiagonal(t, c, diagonal_[u(t)][u(c)][0], diagonal_[u(t)][u(c)][1]);
    }
    // The plans point into pool_: a copy would point into the original.
    TileBuild(const TileBuild&) = delete;
    TileBuild& operator=(const TileBuild&) = delete;

    static std::size_t u(int i) { return static_cast<std::size_t>(i); }
    /// In the sweeps after the first, an extrapolated ring texel (a boundary edge or a missing
    /// level extrapolated from the tile's own rows, a corner extrapolated along an edge) moves
    /// 2/3 of the way to its new value. Taken whole, the lagged self-coupling has an eigenvalue
    /// near or beyond -1 at a mesh corner (a vertex with one tile: the corner sample reads 28/64
    /// of its own coefficient back through three extrapolated ring texels), so the sweeps
    /// oscillated there and ran out: 100 sweeps at a change of ~1e-9 on 132 of 240 builds of
    /// the OpenSubdiv shapes at k = 3..5 (boundaries, mixed sizes), and a divergence to changes
    /// of 1e7 at k = 1 on some boundary meshes. The fixed point is the same (the ring equals the
    /// extrapolation), and the last finalize writes the rule undamped. 2/3 took the fewest
    /// sweeps of 0.4-0.8 over those builds (figures.md, "Production-size cages"). The first
    /// sweep is not damped: the rings start at zero.
    static constexpr double kDamp = 2.0 / 3.0;
    int size(int t, int m) const { return (1 << k_[u(t)]) >> m; }
    /// The global resolution of level m: log2 of its texels per base edge.
    int global(int t, int m) const { return k_[u(t)] - m + topo_.scale(t); }
    /// The level of tile t at global resolution g, or -1; sourceLevelAt also returns the
    /// virtual level m = k of size 1: never stored or evaluated, it is the mip of the coarsest
    /// level and feeds the neighbours' rings where a quad's coarsest level meets a sub-face at
    /// a T-junction (there the sub-face needs size 1), so that every tile that reads that
    /// region of the sub-face reads the same value.
    int sourceLevelAt(int t, int g) const {
        const int m = k_[u(t)] + topo_.scale(t) - g;
        return (m >= 0 && m <= k_[u(t)]) ? m : -1;
    }
    int levelAt(int t, int g) const {
        const int m = sourceLevelAt(t, g);
        return m < k_[u(t)] ? m : -1;
    }
    std::size_t levelIndex(int t, int m) const { return m == 0 ? rank_[u(t)] : firstLevel_[u(t)] + u(m); }
    double* levelData(int t, int m) { return pool_.data() + levelOffset_[levelIndex(t, m)]; }
    const double* levelData(int t, int m) const { return pool_.data() + levelOffset_[levelIndex(t, m)]; }
    double& at(int t, int m, int a, int b) { return levelData(t, m)[u(b * (size(t, m) + 2) + a)]; }
    /// The fit's value at corner c of tile t: what the solve gave there (the level-0 texel
    /// holds the corner constraint's average where the corner is constrained).
    double& fitCorner(int t, int c) { return raw_[4 * rank_[u(t)] + u(c & 3)]; }
    /// The fit's starting point: tile t's samples (row j = v, s x s) as its level-0 interior.
    void setInterior(int t, const std::vector<double>& y) {
        const int s = size(t, 0);
        for (int j = 0; j < s; ++j)
            for (int i = 0; i < s; ++i) at(t, 0, i + 1, j + 1) = y[u(j * s + i)];
        for (int c = 0; c < 4; ++c) fitCorner(t, c) = cornerInterior(t, 0, c);
    }
    /// Texel (t along edge e from corner e, d inward from the ring) of a level of size s.
    static glm::ivec2 edgeTexel(int e, int t, int d, int s) {
        switch (e & 3) {
        case 0: return {t, d};
        case 1: return {s + 1 - d, t};
        case 2: return {s + 1 - t, s + 1 - d};
        default: return {d, s + 1 - t};
        }
    }
    static std::ptrdiff_t texelIndex(glm::ivec2 p, int s) { return static_cast<std::ptrdiff_t>(p.y) * (s + 2) + p.x; }
    double& edgeAt(int t, int m, int e, int along, int d) {
        glm::ivec2 p = edgeTexel(e, along, d, size(t, m));
        return at(t, m, p.x, p.y);
    }
    double& cornerInterior(int t, int m, int c) { return edgeAt(t, m, c, 1, 1); }
    double& cornerRing(int t, int m, int c) { return edgeAt(t, m, c, 0, 0); }

    /// The texel of the neighbour's first interior row that my ring texel `along` of edge e
    /// copies, or nullptr if the neighbour has no level of matching resolution there.
    const double* linkedSource(const TileTopology::Link& l, int t, int m, int along) {
        const int s = size(t, m);
        const long sn = std::lround(static_cast<double>(s) / l.beta);
        const int kn = k_[u(l.tile)];
        int mn = -1;
        for (int j = 0; j <= kn; ++j)
            if (size(l.tile, j) == sn) mn = j;
        if (mn < 0) return nullptr;
        const long tn = std::lround(static_cast<double>(sn) * l.alpha) + 1 - along;
        if (tn < 0 || tn > sn + 1) return nullptr;
        return &edgeAt(l.tile, mn, l.edge, static_cast<int>(tn), 1);
    }
    /// Of the two edges at corner c, one whose ring copies a neighbour at this level (so the
    /// neighbour, extrapolating along the same line, gets the same value); else edge c.
    int matchedEdge(int t, int m, int c) {
        const int prev = (c + 3) & 3;
        if (const TileTopology::Link* l = topo_.linkAt(t, c, 0.0); l && linkedSource(*l, t, m, 1)) return c;
        if (const TileTopology::Link* l = topo_.linkAt(t, prev, 1.0); l && linkedSource(*l, t, m, size(t, m))) return prev;
        return c;
    }

    void filterLevel(int t, int m, MipFilter f) {
        const int s = size(t, m);
        for (int J = 1; J <= s; ++J)
            for (int I = 1; I <= s; ++I) {
                double v = 0.0;
                if (f == MipFilter::Haar) {
                    for (int b = 0; b < 2; ++b)
                        for (int a = 0; a < 2; ++a) v += at(t, m - 1, 2 * I - 1 + a, 2 * J - 1 + b);
                    v *= 0.25;
                } else {
                    static constexpr double w[4] = {-0.25, 0.75, 0.75, -0.25};
                    for (int b = 0; b < 4; ++b)
                        for (int a = 0; a < 4; ++a) v += w[a] * w[b] * at(t, m - 1, 2 * I - 2 + a, 2 * J - 2 + b);
                }
                at(t, m, I, J) = v;
            }
    }

    /// Computes the levels of every tile from the fitted finest interiors: interiors (fit or
    /// mip filter), the corner constraint, then edge and corner rings, resolution by resolution
    /// from the finest. `all` = false stops after the coarsest resolution any tile's level 0 has
    /// (what the fit's sweeps read: a resolution reads only data of its own resolution). With
    /// `damp` (the sweeps after the first) the rings a tile extrapolates move kDamp of the way
    /// (see kDamp); without it the levels computed are those all = true computes. Each phase
    /// runs over tiles (or vertices) in parallel; every task writes only its own tile's level
    /// (or its vertex's corners) and reads what earlier phases wrote, so the result is the same
    /// on any number of threads.
    void finalize(MipFilter filter, const Parallel& par, bool all = true, bool damp = false) {
        prepareSchedule();
        const int gStop = all ? gmin_ : gLevel0Min_;
        for (int g = gmax_; g >= gStop; --g) {
            const Schedule& sch = schedule_[u(gmax_ - g)];
            const std::vector<std::pair<int, int>>& active = sch.active;
            par.each(sch.virtualLevels.size(), 64, [&](std::size_t i) {
                const int t = sch.virtualLevels[i];
                filterLevel(t, k_[u(t)], filter);
            });
            // Level 0's interior is the fit's (solveTile writes it); the levels above are mips.
            par.each(active.size(), 16, [&](std::size_t i) {
                const auto [t, m] = active[i];
                if (m > 0) filterLevel(t, m, filter);
            });
            // Each constrained vertex averages and writes its own incident corners (level 0's
            // from the fit's corner values, not from an earlier average).
            sch.averages.run(par);
            par.each(active.size(), 16, [&](std::size_t i) { fillEdgeRings(active[i].first, active[i].second, g, damp); });
            // Each tile's corners in order (a corner's extrapolation reads ring texels its tile's
            // constrained corners rewrite); the reads across tiles are interior texels only.
            par.each(active.size(), 16, [&](std::size_t i) {
                for (int c = 0; c < 4; ++c) fillCorner(active[i].first, active[i].second, c, g, damp);
            });
        }
    }

    /// Corner constraints made into flat lists: vertex i averages *from[first[i] .. first[i + 1])
    /// (level 0: the fit's corner values; above: the mips' corner texels) into the texels
    /// *to[...], its incident tiles' interior corners (in incidence order).
    struct CornerAverages {
        std::vector<std::size_t> first{0};
        std::vector<const double*> from;
        std::vector<double*> to;
        void add(const double* value, double* texel) {
            from.push_back(value);
            to.push_back(texel);
        }
        void endVertex() { first.push_back(from.size()); }
        /// Each vertex writes only its own corners: in parallel.
        void run(const Parallel& par) const {
            par.each(first.size() - 1, 256, [&](std::size_t i) {
                double sum = 0.0;
                for (std::size_t j = first[i]; j < first[i + 1]; ++j) sum += *from[j];
                const double mean = sum / static_cast<int>(first[i + 1] - first[i]);
                for (std::size_t j = first[i]; j < first[i + 1]; ++j) *to[j] = mean;
            });
        }
    };
    /// Per resolution, the (tile, level) pairs to compute and the tiles whose virtual level
    /// (size 1) lies there; the corner constraints of the constrained vertices with a level
    /// there (in vertex order). Made once: the sizes do not change.
    struct Schedule {
        std::vector<std::pair<int, int>> active;
        std::vector<int> virtualLevels;
        CornerAverages averages;
    };
    void prepareSchedule() {
        if (!schedule_.empty()) return;
        const int n = topo_.tileCount();
        gmax_ = 0;
        gmin_ = 1 << 30;
        gLevel0Min_ = 1 << 30;
        for (int t = 0; t < n; ++t) {
            gmax_ = std::max(gmax_, global(t, 0));
            gmin_ = std::min(gmin_, global(t, k_[u(t)]));
            gLevel0Min_ = std::min(gLevel0Min_, global(t, 0));
        }
        schedule_.resize(u(gmax_ - gmin_ + 1));
        for (int g = gmax_; g >= gmin_; --g) {
            Schedule& sch = schedule_[u(gmax_ - g)];
            for (int t = 0; t < n; ++t) {
                if (int m = levelAt(t, g); m >= 0) sch.active.emplace_back(t, m);
                if (int m = sourceLevelAt(t, g); m == k_[u(t)]) sch.virtualLevels.push_back(t);
            }
        }
        for (int g = gmax_; g >= gmin_; --g) {
            Schedule& sch = schedule_[u(gmax_ - g)];
            for (int v = 0; v < topo_.vertexCount(); ++v) {
                if (topo_.kind(v) != TileTopology::VertexKind::Constrained) continue;
                for (auto [t, c] : topo_.incidences(v))
                    if (int m = levelAt(t, g); m >= 0) sch.averages.add(m == 0 ? &fitCorner(t, c) : &cornerInterior(t, m, c), &cornerInterior(t, m, c));
                if (sch.averages.from.size() > sch.averages.first.back()) sch.averages.endVertex();
            }
        }
    }

    void fillEdgeRings(int t, int m, int g, bool damp = false) {
        const int s = size(t, m);
        // Which neighbour texel each ring texel copies depends on the topology and the sizes
        // only: found on the first call for (t, m), kept for the sweeps after it (the lookups
        // cost more than the copies on small tiles). Each (t, m) is one task's alone.
        LevelPlan& plan = levelPlans_[levelIndex(t, m)];
        const double** const sources = ringSource_.data() + ringFirst_[levelIndex(t, m)];
        if (!plan.ringsPlanned) {
            plan.ringsPlanned = true;
            for (int e = 0; e < 4; ++e) {
                plan.matched[u(e)] = true;
                for (int along = 1; along <= s; ++along) {
                    const TileTopology::Link* l = topo_.linkAt(t, e, (along - 0.5) / s);
                    const double* p = l ? linkedSource(*l, t, m, along) : nullptr;
                    sources[e * s + along - 1] = p;
                    if (!p) plan.matched[u(e)] = false;
                }
            }
        }
        const std::array<bool, 4>& matched = plan.matched;
        double* level = levelData(t, m);
        for (int e = 0; e < 4; ++e) {
            // edgeAt(t, m, e, along, d) is level[base + along * step + d * inward].
            const std::ptrdiff_t base = texelIndex(edgeTexel(e, 0, 0, s), s);
            const std::ptrdiff_t step = texelIndex(edgeTexel(e, 1, 0, s), s) - base, inward = texelIndex(edgeTexel(e, 0, 1, s), s) - base;
            const double* const* source = sources + e * s;
            for (int along = 1; along <= s; ++along) {
                const std::ptrdiff_t i = base + along * step;
                const double* p = source[along - 1];
                if (p) {
                    level[i] = *p;
                } else {
                    const double x = 2.0 * level[i + inward] - level[i + 2 * inward];
                    level[i] = damp ? level[i] + kDamp * (x - level[i]) : x;
                }
            }
        }
        // An unmatched ring entry next to a regular vertex lies in the quadrant of a tile C
        // without this level. The tiles around the vertex that have the level must agree on
        // it: all use the parallelogram rule P = (C's two edge neighbours) - (C's diagonal).
        for (int e = 0; e < 4; ++e) {
            if (matched[u(e)] || topo_.isBoundaryEdge(t, e)) continue;
            for (int end = 0; end < 2; ++end) {
                const int c = end == 0 ? e : (e + 1) & 3; // the corner at this end of edge e
                const int other = end == 0 ? (e + 3) & 3 : (e + 1) & 3;
                if (topo_.kind(topo_.cornerVertex(t, c)) != TileTopology::VertexKind::Regular || !matched[u(other)]) continue;
                int dt = -1, dc = -1;
                diagonal(t, c, dt, dc);
                const int dm = dt >= 0 ? levelAt(dt, g) : -1;
                if (dm < 0) continue;
                const double a = end == 0 ? edgeAt(t, m, other, s, 0) : edgeAt(t, m, other, 1, 0);
                edgeAt(t, m, e, end == 0 ? 1 : s, 0) = cornerInterior(t, m, c) + cornerInterior(dt, dm, dc) - a;
            }
        }
    }

    /// The tile diagonal to tile t across its corner c at a regular vertex (or -1), found once
    /// per corner (the rings and corners of every sweep ask).
    void diagonal(int t, int c, int& dt, int& dc) const {
        const std::array<int, 2>& d = diagonal_[u(t)][u(c & 3)];
        dt = d[0];
        dc = d[1];
    }
    void findDiagonal(int t, int c, int& dt, int& dc) const {
        const TileTopology::Link* next = topo_.linkAt(t, c, 0.0);
        const TileTopology::Link* back = topo_.linkAt(t, (c + 3) & 3, 1.0);
        dt = dc = -1;
        for (auto [ot, oc] : topo_.incidences(topo_.cornerVertex(t, c))) {
            if (ot == t && oc == c) continue;
            if ((next && next->tile == ot) || (back && back->tile == ot)) continue;
            dt = ot;
            dc = oc;
        }
    }

    /// How corner c of level m of tile t gets its ring value: decided by the topology and the
    /// sizes alone, so once (planCorner), then read by every sweep (fillCorner).
    struct CornerPlan {
        enum Mode : std::uint8_t { Unplanned, Constrained, Copy, Parallelogram, Extrapolate };
        Mode mode = Unplanned;
        const double* a = nullptr; ///< Constrained, Copy: the value; Parallelogram: a + b - c; Extrapolate: 2 a - b
        const double* b = nullptr;
        const double* c = nullptr;
    };
    CornerPlan planCorner(int t, int m, int c, int g) {
        const int s = size(t, m);
        const int v = topo_.cornerVertex(t, c);
        const int prev = (c + 3) & 3;
        const TileTopology::Link* next = topo_.linkAt(t, c, 0.0);
        const TileTopology::Link* back = topo_.linkAt(t, prev, 1.0);
        CornerPlan p;
        auto extrapolate = [&](int e) { // from the ring of edge e (c or c - 1)
            p.mode = CornerPlan::Extrapolate;
            p.a = e == c ? &edgeAt(t, m, e, 1, 0) : &edgeAt(t, m, e, s, 0);
            p.b = e == c ? &edgeAt(t, m, e, 2, 0) : &edgeAt(t, m, e, s - 1, 0);
        };
        switch (topo_.kind(v)) {
        case TileTopology::VertexKind::Constrained:
            p.mode = CornerPlan::Constrained;
            p.a = &cornerInterior(t, m, c);
            break;
        case TileTopology::VertexKind::Regular: {
            int dt = -1, dc = -1;
            diagonal(t, c, dt, dc);
            const int dm = dt >= 0 ? sourceLevelAt(dt, g) : -1;
            if (dm >= 0) {
                p.mode = CornerPlan::Copy;
                p.a = &cornerInterior(dt, dm, dc);
            } else if (next && back && linkedSource(*next, t, m, 1) && linkedSource(*back, t, m, s)) {
                p.mode = CornerPlan::Parallelogram;
                p.a = &edgeAt(t, m, c, 1, 0);
                p.b = &edgeAt(t, m, prev, s, 0);
                p.c = &cornerInterior(t, m, c);
            } else {
                extrapolate(matchedEdge(t, m, c));
            }
            break;
        }
        case TileTopology::VertexKind::BoundaryRegular:
            extrapolate(matchedEdge(t, m, c));
            break;
        case TileTopology::VertexKind::TJunction: {
            // The edge on the base edge (not the spoke) links to the quad with beta != 1.
            const double* q = nullptr;
            if (next && next->beta != 1.0) q = linkedSource(*next, t, m, 0);
            if (!q && back && back->beta != 1.0) q = linkedSource(*back, t, m, s + 1);
            if (q) {
                p.mode = CornerPlan::Copy;
                p.a = q;
            } else {
                extrapolate(c);
            }
            break;
        }
        }
        return p;
    }
    void fillCorner(int t, int m, int c, int g, bool damp = false) {
        CornerPlan& p = levelPlans_[levelIndex(t, m)].corner[u(c)];
        if (p.mode == CornerPlan::Unplanned) p = planCorner(t, m, c, g);
        double value = 0.0;
        switch (p.mode) {
        case CornerPlan::Constrained:
            value = *p.a;
            edgeAt(t, m, c, 1, 0) = value;
            edgeAt(t, m, (c + 3) & 3, size(t, m), 0) = value;
            break;
        case CornerPlan::Copy: value = *p.a; break;
        case CornerPlan::Parallelogram: value = *p.a + *p.b - *p.c; break;
        case CornerPlan::Extrapolate:
            value = 2.0 * *p.a - *p.b;
            if (damp) value = cornerRing(t, m, c) + kDamp * (value - cornerRing(t, m, c));
            break;
        case CornerPlan::Unplanned: break;
        }
        cornerRing(t, m, c) = value;
    }

    /// Whether the fit sweeps in Gauss-Seidel order: every tile's finest level has the same
    /// resolution, so a sweep reads and writes level 0 only (no mip feeds a ring), and 8 x 8
    /// texels or more (see the constructor).
    bool seidel() const { return seidel_; }
    /// A Gauss-Seidel sweep's colours over `tiles`: the tiles of each colour (tiles of one colour
    /// share no vertex and no edge, so they neither read each other's texels nor write the same
    /// corner average) and the corner constraints of the constrained vertices they touch. The
    /// colouring is the constructor's (greedy in tile order), restricted to `tiles`.
    struct Colour {
        std::vector<int> tiles;
        CornerAverages averages;
    };
    std::vector<Colour> colours(const std::vector<int>& tiles) {
        prepareSchedule();
        std::vector<Colour> out;
        std::vector<char> in(u(topo_.tileCount()), 0);
        for (int t : tiles) {
            const std::size_t c = u(colourOf_[u(t)]);
            if (out.size() <= c) out.resize(c + 1);
            out[c].tiles.push_back(t);
            in[u(t)] = 1;
        }
        std::vector<int> listed(out.size(), -1);
        for (int v = 0; v < topo_.vertexCount(); ++v) {
            if (topo_.kind(v) != TileTopology::VertexKind::Constrained) continue;
            for (auto [t, c] : topo_.incidences(v)) {
                if (!in[u(t)] || listed[u(colourOf_[u(t)])] == v) continue;
                listed[u(colourOf_[u(t)])] = v; // once per colour (two tiles of a colour never share v)
                CornerAverages& averages = out[u(colourOf_[u(t)])].averages;
                for (auto [vt, vc] : topo_.incidences(v)) averages.add(&fitCorner(vt, vc), &cornerInterior(vt, 0, vc));
                averages.endVertex();
            }
        }
        return out;
    }
    /// One Gauss-Seidel sweep (seidel() only). Per colour: the averages at its constrained
    /// vertices from the latest fit, its tiles' rings (`damp`: see finalize), then its tiles
    /// solved. Returns the largest change.
    double solveSweepColoured(const std::vector<std::vector<double>>& samples, const std::vector<Colour>& colours, const Parallel& par,
                              bool damp) {
        double change = 0.0;
        for (const Colour& colour : colours) {
            colour.averages.run(par);
            par.each(colour.tiles.size(), 16, [&](std::size_t i) {
                const int t = colour.tiles[i];
                fillEdgeRings(t, 0, gmax_, damp);
                for (int c = 0; c < 4; ++c) fillCorner(t, 0, c, gmax_, damp);
            });
            change = std::max(change, solveSweep(samples, colour.tiles, par));
        }
        return change;
    }

    /// One sweep of the fit: each tile of `tiles` has its interior solved exactly with the
    /// current rings (the other tiles stay as they are). Returns the largest change. Tiles are
    /// solved in parallel (each writes only its own level-0 interior and fit corners); the
    /// largest change is taken over per-tile maxima, the same on any number of threads. No
    /// allocation per tile: one scratch buffer per range of tiles, and the Thomas factors of
    /// each size made once.
    double solveSweep(const std::vector<std::vector<double>>& samples, const std::vector<int>& tiles, const Parallel& par) {
        for (int t : tiles) thomas(k_[u(t)]);
        changes_.assign(tiles.size(), 0.0);
        par.ranges(tiles.size(), 8, [&](std::size_t begin, std::size_t end) {
            std::vector<double> rhs, scratch;
            for (std::size_t i = begin; i < end; ++i) changes_[i] = solveTile(samples, tiles[i], rhs, scratch);
        });
        double change = 0.0;
        for (double c : changes_) change = std::max(change, c);
        return change;
    }

    /// Solves tile t's (T x T) x = rhs with T = tridiag(1, 6, 1) (Thomas algorithm, with the
    /// factors of its size), writes the fit interior and returns its largest change.
    double solveTile(const std::vector<std::vector<double>>& samples, int t, std::vector<double>& rhs, std::vector<double>& scratch) {
        const int s = size(t, 0);
        const int w = s + 2;
        const double* d = levelData(t, 0);
        const std::vector<double>& y = samples[u(t)];
        const Thomas& th = thomas_[u(k_[u(t)])];
        rhs.resize(u(s * s));
        auto R = [&](int i, int j) -> double& { return rhs[u((j - 1) * s + (i - 1))]; };
        auto D = [&](int a, int b) { return d[u(b * w + a)]; };
        for (std::size_t i = 0; i < u(s * s); ++i) rhs[i] = 64.0 * y[i];
        // The ring's part of each border sample's 3 x 3 stencil (weights (1, 6, 1) x (1, 6, 1)),
        // moved to the right side: the bottom and top rows take their ring rows' three texels
        // (corners included), the left and right columns the ring texels not on those rows.
        for (int i = 1; i <= s; ++i) {
            R(i, 1) -= D(i - 1, 0) + 6.0 * D(i, 0) + D(i + 1, 0);
            R(i, s) -= D(i - 1, s + 1) + 6.0 * D(i, s + 1) + D(i + 1, s + 1);
        }
        for (int j = 1; j <= s; ++j) {
            double left = 6.0 * D(0, j), right = 6.0 * D(s + 1, j);
            if (j > 1) left += D(0, j - 1), right += D(s + 1, j - 1);
            if (j < s) left += D(0, j + 1), right += D(s + 1, j + 1);
            R(1, j) -= left;
            R(s, j) -= right;
        }
        // Columns (v), then rows (u) after a transpose: each pass eliminates along the slow
        // index with the fast index innermost, so that its s independent lines run side by side
        // (vectorised) instead of one after another.
        tridiagonalLines(rhs.data(), s, th);
        scratch.resize(u(s * s));
        for (int j = 0; j < s; ++j)
            for (int i = 0; i < s; ++i) scratch[u(i * s + j)] = rhs[u(j * s + i)];
        tridiagonalLines(scratch.data(), s, th);
        // Into level 0's interior, whose corner texels get the fit's values back first (the
        // constraint may have overwritten them: the change is against the last fit), and give
        // the new ones to fitCorner.
        for (int c = 0; c < 4; ++c) cornerInterior(t, 0, c) = fitCorner(t, c);
        double change = 0.0;
        for (int j = 0; j < s; ++j)
            for (int i = 0; i < s; ++i) {
                double& x = at(t, 0, i + 1, j + 1);
                const double solved = scratch[u(i * s + j)];
                change = std::max(change, std::abs(solved - x));
                x = solved;
            }
        for (int c = 0; c < 4; ++c) fitCorner(t, c) = cornerInterior(t, 0, c);
        return change;
    }
    /// Solves tridiag(1, 6, 1) along the rows index of an s x s block (row r at a + r s) for
    /// all s columns at once: Thomas algorithm with the precomputed factors of size s.
    struct Thomas;
    static void tridiagonalLines(double* a, int s, const Thomas& th) {
        for (int i = 0; i < s; ++i) a[i] *= th.invBeta[0];
        for (int j = 1; j < s; ++j) {
            double* row = a + static_cast<std::ptrdiff_t>(j) * s;
            const double* prev = row - s;
            const double ib = th.invBeta[u(j)];
            for (int i = 0; i < s; ++i) row[i] = (row[i] - prev[i]) * ib;
        }
        for (int j = s - 1; j-- > 0;) {
            double* row = a + static_cast<std::ptrdiff_t>(j) * s;
            const double* next = row + s;
            const double c = th.c[u(j + 1)];
            for (int i = 0; i < s; ++i) row[i] -= c * next[i];
        }
    }
    /// The Thomas factors of tridiag(1, 6, 1) of size 2^k: c_i = 1 / beta_(i-1) (i >= 1) and
    /// 1 / beta_i, with beta_0 = 6, beta_i = 6 - c_i.
    struct Thomas {
        std::vector<double> c, invBeta;
    };
    void thomas(int k) {
        if (thomas_.size() <= u(k)) thomas_.resize(u(k + 1));
        Thomas& th = thomas_[u(k)];
        if (!th.c.empty()) return;
        const int n = 1 << k;
        th.c.assign(u(n), 0.0);
        th.invBeta.assign(u(n), 0.0);
        double beta = 6.0;
        th.invBeta[0] = 1.0 / beta;
        for (int i = 1; i < n; ++i) {
            th.c[u(i)] = 1.0 / beta;
            beta = 6.0 - th.c[u(i)];
            th.invBeta[u(i)] = 1.0 / beta;
        }
    }

    /// Level m of tile t: (s + 2)^2 texels, row b = v.
    const double* level(int t, int m) const { return levelData(t, m); }

  private:
    const TileTopology& topo_;
    std::vector<int> k_;
    std::vector<double> pool_;              ///< every level of every tile (see the class comment)
    std::vector<std::size_t> firstLevel_;   ///< per tile: its level m > 0 is level firstLevel_ + m
    std::vector<std::size_t> rank_;         ///< per tile: its level 0 is level rank_ (tile order, or colour by colour)
    std::vector<int> colourOf_;             ///< per tile: its colour in the Gauss-Seidel order (0 when not seidel_)
    bool seidel_ = false;                   ///< sweeps in Gauss-Seidel order (seidel())
    std::vector<std::size_t> levelOffset_;  ///< per level (levelIndex): where its texels start in pool_
    std::vector<std::size_t> ringFirst_;    ///< per level: where its 4 s ring sources start in ringSource_
    /// Per level: the neighbour texel each ring texel copies (fillEdgeRings; edge e, texel
    /// along at [e s + along - 1], nullptr where it extrapolates).
    std::vector<const double*> ringSource_;
    std::vector<double> raw_;               ///< per level 0, per corner: the fit's value (fitCorner)
    /// Per level: whether its ring sources are planned, which edges copy a neighbour all
    /// along, and the corners' plans.
    struct LevelPlan {
        bool ringsPlanned = false;
        std::array<bool, 4> matched{};
        std::array<CornerPlan, 4> corner{};
    };
    std::vector<LevelPlan> levelPlans_;
    std::vector<std::array<std::array<int, 2>, 4>> diagonal_; ///< (tile, corner) across each corner, or -1
    std::vector<Schedule> schedule_;
    int gmax_ = 0, gmin_ = 0, gLevel0Min_ = 0;
    std::vector<Thomas> thomas_;
    std::vector<double> changes_;
};

} // namespace detail

/// The fit of a TileSet, kept for edits (Nießner & Loop 2013, §5: after an edit only the
/// modified tiles are updated). The constructor builds the tiles as buildTiles does (which is
/// this class, discarded); refit() re-samples the source on some faces, re-solves their tiles
/// and their neighbours' with every other tile's interior held fixed, and rewrites in tiles()
/// only the tiles whose stored coefficients changed: those re-solved and the next ring, whose
/// overlap rings, corner constraints or mip levels read them. The double-precision state of
/// the fit is kept, so a tile nothing reaches keeps its coefficients bit for bit. The fit the
/// whole set would give differs by the coupling cut at the region's border (the figure of
/// tests/test_tiles.cpp "edits": ~1e-6 of the edit's size).
class TileFitter {
  public:
    /// Throws ArgumentError for sizes out of range or inconsistent at a T-junction, or a
    /// NaN/Inf sample (naming face and (u, v)); MeshError for topology.
    TileFitter(const ControlMesh& mesh, const std::vector<int>& k, const DisplacementFunction& source,
               const BuildOptions& options = {});

    /// The tiles (held on the heap: a DisplacedSurface built on them stays valid when the
    /// fitter moves, and sees refit()'s changes in place). Not on a temporary fitter.
    const TileSet& tiles() const& { return *tiles_; }
    const TileSet& tiles() const&& = delete;
    /// The tiles, moved out (the fitter cannot refit afterwards).
    TileSet takeTiles() && {
        TileSet out = std::move(*tiles_);
        build_.reset(); // refit() refuses from now on
        return out;
    }
    /// The last fit's report (the constructor's, or the last refit's: sweeps over the edited
    /// tiles; the residuals are over every tile).
    const BuildReport& report() const { return report_; }

    /// Re-samples `source` on the given Ptex faces and re-fits the tiles of those whose samples
    /// changed (the other tiles' interiors fixed). Returns the tiles whose coefficients
    /// changed, ascending (empty when no sample changed). Throws ArgumentError for a face id
    /// out of range or a NaN/Inf sample (nothing changes then).
    std::vector<int> refit(const std::vector<int>& faces, const DisplacementFunction& source);

  private:
    /// Samples the finest level of each tile of `faces` into out[i] (in parallel), then throws
    /// for the first non-finite sample in face order (the same error for every thread count).
    void sample(const std::vector<int>& faces, const DisplacementFunction& source, std::vector<std::vector<double>>& out) const;
    void solve(const std::vector<int>& tiles);
    void store(std::vector<int>* changed);

    std::string name_;
    std::vector<int> k_, gmin_;
    BuildOptions options_;
    std::unique_ptr<TileTopology> topo_;      // heap: TileBuild keeps a reference to it
    std::unique_ptr<detail::TileBuild> build_;
    std::vector<std::vector<double>> samples_;
    std::unique_ptr<TileSet> tiles_ = std::make_unique<TileSet>();
    BuildReport report_;
};

inline TileFitter::TileFitter(const ControlMesh& mesh, const std::vector<int>& k, const DisplacementFunction& source,
                              const BuildOptions& options)
    : name_(mesh.description().name), k_(k), options_(options) {
    const std::string& name = name_;
    const int n = mesh.ptexFaceCount();
    if (static_cast<int>(k.size()) != n)
        throw ArgumentError(name + ": " + std::to_string(k.size()) + " tile sizes given for " + std::to_string(n) +
                            " Ptex faces");
    for (int t = 0; t < n; ++t)
        if (k[static_cast<std::size_t>(t)] < kMinTileLog2 || k[static_cast<std::size_t>(t)] > kMaxTileLog2)
            throw ArgumentError(name + ": tile " + std::to_string(t) + " has size 2^" +
                                std::to_string(k[static_cast<std::size_t>(t)]) + "; k must be in [" +
                                std::to_string(kMinTileLog2) + ", " + std::to_string(kMaxTileLog2) + "]");
    if (!source) throw ArgumentError("no displacement source given");
    if (options.maxSweeps < 1 || !(options.tolerance >= 0.0)) throw ArgumentError("invalid build options");
    checkThreads(options.threads, name + ": tile build");
    topo_ = std::make_unique<TileTopology>(mesh);
    const TileTopology& topo = *topo_;
    auto ku = [&](int t) { return k[static_cast<std::size_t>(t)]; };

    // Per-vertex smallest global resolution and the per-corner differences (§4.4).
    std::vector<int>& gmin = gmin_;
    gmin.assign(static_cast<std::size_t>(topo.vertexCount()), 1 << 30);
    for (int v = 0; v < topo.vertexCount(); ++v)
        for (auto [t, c] : topo.incidences(v))
            gmin[static_cast<std::size_t>(v)] = std::min(gmin[static_cast<std::size_t>(v)], ku(t) + topo.scale(t));
    BuildReport& rep = report_;
    for (int v = 0; v < topo.vertexCount(); ++v) {
        if (topo.kind(v) == TileTopology::VertexKind::Constrained) ++rep.constrainedVertices;
        if (topo.kind(v) != TileTopology::VertexKind::TJunction) continue;
        ++rep.tJunctions;
        // The quad's clamp is linear along its whole edge, each sub-face's along its half:
        // they agree only if the edge's two ends and its midpoint allow the same resolution.
        const auto [t, c] = topo.incidences(v).front();
        const TileTopology::Link* l = topo.linkAt(t, c, 0.0);
        if (!l || l->beta == 1.0) l = topo.linkAt(t, (c + 3) & 3, 1.0);
        const int quad = l ? l->tile : -1;
        const int g = gmin[static_cast<std::size_t>(v)];
        bool ok = quad >= 0 && ku(quad) == g;
        for (int qc = 0; ok && quad >= 0 && qc < 4; ++qc)
            for (const TileTopology::Link& ql : topo.links(quad, qc))
                if (ql.tile == t)
                    ok = ok && gmin[static_cast<std::size_t>(topo.cornerVertex(quad, qc))] == g &&
                         gmin[static_cast<std::size_t>(topo.cornerVertex(quad, (qc + 1) & 3))] == g;
        for (auto [st, sc] : topo.incidences(v)) ok = ok && ku(st) + 1 == g;
        if (!ok)
            throw ArgumentError(name + ": tile sizes at the T-junction between face " +
                                std::to_string(topo.baseFace(t) + 1) + " (not a quad) and quad face " +
                                std::to_string(quad >= 0 ? topo.baseFace(quad) + 1 : 0) +
                                " must match: the quad's k must be the sub-faces' k + 1 and equal the smallest k at "
                                "the edge's ends (see uniformTileSizes)");
    }

    // Samples at the sub-patch centres of each tile's finest level.
    std::vector<int> all(static_cast<std::size_t>(n));
    for (int t = 0; t < n; ++t) all[static_cast<std::size_t>(t)] = t;
    sample(all, source, samples_);

    build_ = std::make_unique<detail::TileBuild>(topo, k);
    Parallel(options_.threads).each(static_cast<std::size_t>(n), 64, [&](std::size_t t) { build_->setInterior(static_cast<int>(t), samples_[t]); });
    solve(all);
    tiles_->filter = options.filter;
    tiles_->topologyHash = topologyHash(mesh);
    tiles_->tiles.resize(static_cast<std::size_t>(n));
    store(nullptr);
}

inline void TileFitter::sample(const std::vector<int>& faces, const DisplacementFunction& source,
                               std::vector<std::vector<double>>& out) const {
    out.resize(faces.size());
    // A source may throw (a scene's checks name the face): the exception of the first face in
    // order is the one rethrown, whichever task met its own first.
    std::vector<std::exception_ptr> failed(faces.size());
    Parallel(options_.threads).each(faces.size(), 4, [&](std::size_t f) {
        const int t = faces[f];
        const int s = 1 << k_[static_cast<std::size_t>(t)];
        std::vector<double>& y = out[f];
        y.resize(static_cast<std::size_t>(s * s));
        try {
            for (int j = 0; j < s; ++j)
                for (int i = 0; i < s; ++i) y[static_cast<std::size_t>(j * s + i)] = source(t, (i + 0.5) / s, (j + 0.5) / s);
        } catch (...) {
            failed[f] = std::current_exception();
        }
    });
    for (const std::exception_ptr& e : failed)
        if (e) std::rethrow_exception(e);
    for (std::size_t f = 0; f < faces.size(); ++f) {
        const int t = faces[f];
        const int s = 1 << k_[static_cast<std::size_t>(t)];
        for (int j = 0; j < s; ++j)
            for (int i = 0; i < s; ++i) {
                const double d = out[f][static_cast<std::size_t>(j * s + i)];
                if (std::isfinite(d)) continue;
                const double uu = (i + 0.5) / s, vv = (j + 0.5) / s;
                throw ArgumentError(name_ + ": displacement source gave " + std::to_string(d) + " at Ptex face " + std::to_string(t) +
                                    ", (u, v) = (" + std::to_string(uu) + ", " + std::to_string(vv) + ")");
            }
    }
}

inline void TileFitter::solve(const std::vector<int>& tiles) {
    double maxAbs = 0.0;
    for (const std::vector<double>& y : samples_)
        for (double d : y) maxAbs = std::max(maxAbs, std::abs(d));
    BuildReport& rep = report_;
    const Parallel par(options_.threads);
    std::vector<detail::TileBuild::Colour> colours;
    if (build_->seidel()) colours = build_->colours(tiles);
    for (rep.sweeps = 1; rep.sweeps <= options_.maxSweeps; ++rep.sweeps) {
        if (build_->seidel()) {
            rep.lastChange = build_->solveSweepColoured(samples_, colours, par, rep.sweeps > 1);
        } else {
            build_->finalize(options_.filter, par, false, rep.sweeps > 1);
            rep.lastChange = build_->solveSweep(samples_, tiles, par);
        }
        if (rep.lastChange <= options_.tolerance * (1.0 + maxAbs)) break;
    }
    rep.sweeps = std::min(rep.sweeps, options_.maxSweeps);
    build_->finalize(options_.filter, par);
}

inline void TileFitter::store(std::vector<int>* changed) {
    const TileTopology& topo = *topo_;
    const detail::TileBuild& b = *build_;
    BuildReport& rep = report_;
    const int n = topo.tileCount();
    // Per tile, in parallel: its stored tile, whether it changed, its two residuals.
    std::vector<char> differs(static_cast<std::size_t>(n), 0);
    std::vector<glm::dvec2> residual(static_cast<std::size_t>(n));
    Parallel(options_.threads).each(static_cast<std::size_t>(n), 16, [&](std::size_t tu) {
        const int t = static_cast<int>(tu);
        const int kt = k_[tu];
        Tile tile;
        tile.k = kt;
        for (int c = 0; c < 4; ++c)
            tile.sizeDifferences[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(
                kt + topo.scale(t) - gmin_[static_cast<std::size_t>(topo.cornerVertex(t, c))]);
        tile.coefficients.reserve(Tile::totalTexels(kt));
        for (int m = 0; m < kt; ++m)
            for (std::size_t i = 0, count = levelTexels((1 << kt) >> m); i < count; ++i)
                tile.coefficients.push_back(static_cast<float>(b.level(t, m)[i]));
        Tile& stored = tiles_->tiles[tu];
        if (!changed || stored.coefficients != tile.coefficients) {
            differs[tu] = 1;
            stored = std::move(tile);
        }
        // Interpolation residual at the samples, on the double coefficients.
        const int s = 1 << kt;
        const double* c0 = b.level(t, 0);
        bool constrainedCorner[4];
        for (int c = 0; c < 4; ++c) constrainedCorner[c] = topo.kind(topo.cornerVertex(t, c)) == TileTopology::VertexKind::Constrained;
        glm::dvec2 r2(0.0);
        for (int j = 0; j < s; ++j)
            for (int i = 0; i < s; ++i) {
                double d = 0.0;
                for (int bb = 0; bb < 3; ++bb)
                    for (int a = 0; a < 3; ++a)
                        d += (a == 1 ? 0.75 : 0.125) * (bb == 1 ? 0.75 : 0.125) * c0[static_cast<std::size_t>((j + bb) * (s + 2) + i + a)];
                const double r = std::abs(d - samples_[tu][static_cast<std::size_t>(j * s + i)]);
                r2.x = std::max(r2.x, r);
                bool nearConstraint = false;
                for (int c = 0; c < 4; ++c) {
                    // samples whose 3 x 3 stencil reads the corner's 2 x 2 block
                    const bool ni = (c == 1 || c == 2) ? i >= s - 2 : i <= 1;
                    const bool nj = (c >= 2) ? j >= s - 2 : j <= 1;
                    if (ni && nj && constrainedCorner[c]) nearConstraint = true;
                }
                if (!nearConstraint) r2.y = std::max(r2.y, r);
            }
        residual[tu] = r2;
    });
    rep.maxResidual = 0.0;
    rep.maxResidualAwayFromConstraints = 0.0;
    for (int t = 0; t < n; ++t) {
        const std::size_t tu = static_cast<std::size_t>(t);
        if (changed && differs[tu]) changed->push_back(t);
        rep.maxResidual = std::max(rep.maxResidual, residual[tu].x);
        rep.maxResidualAwayFromConstraints = std::max(rep.maxResidualAwayFromConstraints, residual[tu].y);
    }
}

inline std::vector<int> TileFitter::refit(const std::vector<int>& faces, const DisplacementFunction& source) {
    if (!source) throw ArgumentError("no displacement source given");
    if (!build_) throw ArgumentError("refit: the tiles were taken out of this fitter");
    std::vector<int> edited = faces;
    std::sort(edited.begin(), edited.end());
    edited.erase(std::unique(edited.begin(), edited.end()), edited.end());
    const int n = topo_->tileCount();
    for (int t : edited)
        if (t < 0 || t >= n)
            throw ArgumentError(name_ + ": refit: Ptex face " + std::to_string(t) + " out of range [0, " + std::to_string(n) + ")");
    std::vector<std::vector<double>> fresh;
    sample(edited, source, fresh); // may throw: nothing changed yet
    // Faces whose samples did not change are no edit: their tiles stay as they are.
    std::vector<int> solveTiles;
    for (std::size_t i = 0; i < edited.size(); ++i) {
        std::vector<double>& old = samples_[static_cast<std::size_t>(edited[i])];
        if (old == fresh[i]) continue;
        old = std::move(fresh[i]);
        solveTiles.push_back(edited[i]);
    }
    std::vector<int> changed;
    if (solveTiles.empty()) return changed;
    // The edited tiles and their neighbours (a shared corner or a linked edge) are re-solved:
    // a neighbour's samples near the shared edge read the edited tile through its ring. The
    // interpolation error this leaves at the next ring's samples is the fit's decay across a
    // whole neighbour tile (about 0.17 per texel, so ~1e-6 of the edit for 8-texel tiles).
    std::vector<int> region = solveTiles;
    for (int t : solveTiles) {
        for (int c = 0; c < 4; ++c) {
            for (auto [ot, oc] : topo_->incidences(topo_->cornerVertex(t, c))) region.push_back(ot);
            for (const TileTopology::Link& l : topo_->links(t, c)) region.push_back(l.tile);
        }
    }
    std::sort(region.begin(), region.end());
    region.erase(std::unique(region.begin(), region.end()), region.end());
    solve(region);
    store(&changed);
    return changed;
}

/// Builds the tiles of `mesh` from `source` with tile sizes `k` (one log2 size per Ptex
/// face, see uniformTileSizes). Throws ArgumentError for sizes out of range or inconsistent
/// at a T-junction, or a NaN/Inf sample (naming face and (u, v)); MeshError for topology.
/// (TileFitter keeps the fit for edits.)
inline TileSet buildTiles(const ControlMesh& mesh, const std::vector<int>& k, const DisplacementFunction& source,
                          const BuildOptions& options = {}, BuildReport* report = nullptr) {
    TileFitter fitter(mesh, k, source, options);
    if (report) *report = fitter.report();
    return std::move(fitter).takeTiles();
}

} // namespace dispmap
