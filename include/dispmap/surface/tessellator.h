#pragma once
// Tessellator: the CPU reference tessellation of a DisplacedSurface into a watertight triangle
// mesh, as the hardware tessellator and the evaluation shader would produce it (Nießner & Loop
// 2013, §6.1 factors, §6.2 mip selection; the texel-ratio rule on swimming).
//
// Factors (§6.1). A factor is given per TileTopology vertex id, in segments per base edge:
// base vertices carry the caller's values (uniform, distance-based, ...); an edge midpoint gets
// the mean of its edge's two vertices and an N-gon centre the mean of its face's vertices (the
// bilinear subdivision of the factors to sub-patch corners). A tile's corner factors are its
// vertices' factors times 2^-scale (a sub-face of an N-gon spans half a base edge, so it takes
// half the segments: the same density as its quad neighbours, and the same texel spacing as
// its k - 1 tile), clamped to [1, maxFactor]; edge factors are the max of the two corners
// (kern::dmEdgeTessFactors), inner factors the max of opposite edges (kern::dmInnerTessFactors).
//
// Spacing. Integer: ceil(T) equal segments. FractionalEven (hardware fractional_even_spacing):
// for T in (2m, 2m + 2], 2m + 2 segments: m of length 1/T from each end and two equal shorter
// ones meeting at 1/2, of length (1 - 2m/T)/2 each. Every point moves continuously with T:
// when T crosses an even integer the two new points are born at the midpoint, and the point
// with index i from either end sits at i/T. Factors below 2 give two segments.
//
// Watertight by construction. A tile edge lies on a segment between two TileTopology vertices
// (a base edge between quads, half a base edge or a spoke of an N-gon). A segment's points
// depend only on its two vertex ids (factor max(F_a, F_b) times 1/2 for N-gon segments,
// clamped), are parameterised from its lower vertex id, and their vertices are created once,
// by the first tile that needs them, and reused by every other tile on the segment; corners
// are created once per vertex id. T-junction rule: where a quad edge meets two sub-faces of an
// N-gon, the quad's edge points are the union of the two half-segments' points (so the
// midpoint is always a vertex); the quad's own edge factor still enters its inner factors.
//
// Interior. The inner factors give grids xu, xv (the spacing above, at least 2 segments each;
// only a face whose four edges and inner factors are all 1 under Integer spacing is two
// triangles). The grid points strictly inside the face form the inner region (triangulated cell
// by cell); the ring between it and each tile edge is a monotone zipper: walking both
// polylines in the edge's direction, it advances the one whose next point comes first (ties to
// the edge), so no triangle spans points out of order. Triangles are counter-clockwise in the
// face's (u, v) domain, i.e. around s_u x s_v: seen from outside for counter-clockwise faces.
//
// Vertices. f and N_f in the chosen NormalMode, with the ptex face and (u, v) they were
// evaluated at (one of the faces that share the vertex) and the resolution rho read: a tile's
// inner grid through DisplacedSurface::evaluateGrid (each patch and tile row collapsed once per
// grid row: evaluate() to rounding where approximate normals meet a regular patch, evaluate()
// itself elsewhere), and so are the points of each edge segment (a line u or v = const), the
// corners and T-junction midpoints through DisplacedSurface::evaluate. A shared vertex is
// evaluated once, so the mesh stays watertight. Mip selection:
//  * Off: rho = kFinest (the finest level the §4.4 clamp allows).
//  * TessFactor (§6.2): rho = log2 of the bilinearly interpolated per-vertex factor (dmBilerp of
//    the tile's four corner values, in base-edge units), minus the tile's scale.
//  * TexelRatio: the texel-ratio level M = log2(L / T) + 1 as a per-vertex resolution
//    (kern::dmVertexResolutionTexelRatio with kMin = the smallest k + scale of the tiles around
//    the base vertex), interpolated the same way; midpoints and centres take the mean of the
//    resolutions of their base vertices.
// Factors enter both rules clamped to [1, maxFactor] (in base-edge units, per vertex).
// Both rules are per-vertex values interpolated bilinearly, so both faces of a shared edge
// read the same rho there, including across a T-junction (the midpoint is the mean, so the
// quad's linear interpolation and the sub-faces' agree). The vertices of non-quad faces read no
// coarser than base resolution 2 (mip factor at least 4): a sub-face's coarsest level (s = 2 on
// half an edge) is base resolution 2, and below it the quad across a T-junction would read a
// level the sub-face has not.
//
// Output: a TriangleMesh (hole faces, BaseSurface::isHole, produce no triangles: their edges
// are boundary edges). TriangleLocator gives the piecewise-linear position at any
// (face, u, v); io/mesh_writers.h writes it as OBJ or PLY.
//
// Errors: ArgumentError for factors that are NaN, infinite or <= 0 (naming the vertex), a
// factor set of another mesh, maxFactor outside [1, 1024] or not finite, a distance constant
// c that is not finite and > 0, and a tessellation whose estimated memory (Tessellator::
// estimate, from the factors alone) exceeds TessellateOptions::maxBytes (kMaxTessellationBytes).
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/surface/base_surface.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/core/error.h"
#include "dispmap/core/memory.h"
#include "dispmap/core/parallel.h"
#include "dispmap/core/triangle_mesh.h"
#include "dispmap/kernels/lod.h"
#include "dispmap/kernels/tile.h"

namespace dispmap {

enum class Spacing { Integer, FractionalEven };
inline const char* toString(Spacing s) { return s == Spacing::Integer ? "integer" : "fractional_even"; }

enum class MipSelection {
    Off,        ///< rho = kFinest
    TessFactor, ///< §6.2: rho = log2 of the interpolated factor
    TexelRatio,    ///< the texel-ratio rule: M = log2(L / T) + 1 per vertex, interpolated
};
inline const char* toString(MipSelection m) {
    return m == MipSelection::Off ? "off" : m == MipSelection::TessFactor ? "log2 TF (6.2)" : "texel ratio";
}

/// Tessellation factors per TileTopology vertex id (base vertices [0, nv), edge midpoints
/// nv + edge, N-gon centres nv + ne + face), in segments per base edge.
struct TessFactors {
    std::vector<double> values;
};

/// Largest peak memory of one tessellation (TessellateOptions::maxBytes by default). Memory
/// grows with the square of the factors: the 45 Ptex faces of catmark_nonquads at factor 1000
/// are 33 million triangles and ~5.5 GB. 4 GiB (~26 million triangles) is more than a renderer
/// draws per frame and fits the machines dispmap runs on, with room for writing the mesh out.
inline constexpr std::uint64_t kMaxTessellationBytes = std::uint64_t{4} << 30;

struct TessellateOptions {
    NormalMode normals = NormalMode::Approximate;
    Spacing spacing = Spacing::FractionalEven;
    double maxFactor = 64; ///< clamp of tile factors, [1, 1024] (64 is the hardware's limit)
    MipSelection mips = MipSelection::Off;
    /// tessellate() refuses (ArgumentError) when Tessellator::estimate()'s bytes exceed this.
    std::uint64_t maxBytes = kMaxTessellationBytes;
    /// Threads evaluating the vertices (core/parallel.h: 0 all cores, 1 the calling thread).
    /// The connectivity is made in tile order on one thread, so the mesh is the same bit for
    /// bit for every count.
    int threads = 0;
    /// New output arrays get the transparent-huge-page hint (core/memory.h, which says where it
    /// does nothing or costs; Linux only). Off leaves them to malloc and the system's THP
    /// setting. The mesh is the same either way; `dispmap bench --only embree` prints what the
    /// hint saves.
    bool hugePages = true;
};

/// The size of a tessellation, from its factors alone (Tessellator::estimate).
struct TessellationSize {
    std::uint64_t triangles = 0; ///< exact
    std::uint64_t vertices = 0;  ///< an upper bound (edge points counted by both tiles of an edge)
    std::uint64_t bytes = 0;     ///< peak memory of tessellate() for these counts (triangle arrays at twice their size)
};

/// The points of one edge parameterised over [0, 1] for factor T (>= 1): increasing, first 0,
/// last 1 (see the header for the two rules). Throws ArgumentError for T not finite or outside
/// [1, 1e6].
inline std::vector<double> edgeSpacing(double T, Spacing spacing) {
    if (!std::isfinite(T) || T < 1.0 || T > 1e6)
        throw ArgumentError("edge factor " + std::to_string(T) + " out of range [1, 1e6]");
    std::vector<double> x;
    if (spacing == Spacing::Integer) {
        const int n = static_cast<int>(std::ceil(T));
        x.resize(static_cast<std::size_t>(n + 1));
        for (int i = 0; i <= n; ++i) x[static_cast<std::size_t>(i)] = double(i) / double(n);
        return x;
    }
    const int m = std::max(0, static_cast<int>(std::ceil(T / 2.0)) - 1);
    const int n = 2 * m + 2;
    x.resize(static_cast<std::size_t>(n + 1));
    const double h = 1.0 / T;
    for (int i = 0; i <= m; ++i) {
        x[static_cast<std::size_t>(i)] = double(i) * h;
        x[static_cast<std::size_t>(n - i)] = 1.0 - double(i) * h;
    }
    x[static_cast<std::size_t>(m + 1)] = 0.5;
    return x;
}

namespace detail {
inline bool validFactor(double f) { return std::isfinite(f) && f > 0.0; }
inline void checkFactor(double f, const std::string& what) {
    if (!validFactor(f))
        throw ArgumentError("tessellation factor " + std::to_string(f) + " of " + what +
                            " is invalid: factors must be finite and > 0");
}
inline const Far::TopologyLevel& baseLevel(const BaseSurface& base) { return base.refiner().GetLevel(0); }
// The number of segments edgeSpacing(T, spacing) makes (T in [1, 1e6]), without making them.
inline std::uint64_t spacingSegments(double T, Spacing spacing) {
    if (spacing == Spacing::Integer) return static_cast<std::uint64_t>(std::ceil(T));
    return 2 * static_cast<std::uint64_t>(std::max(0.0, std::ceil(T / 2.0) - 1.0)) + 2;
}
} // namespace detail

namespace detail {
/// Per TileTopology vertex id from per base vertex values: edge midpoints take the mean of
/// their edge's two vertices, N-gon centres the mean of the face's vertices (§6.1's bilinear
/// subdivision). Written as 0.5 a + 0.5 b and a sum of x / n so that finite input stays finite.
inline std::vector<double> spreadToTileVertices(const Far::TopologyLevel& L, const std::vector<double>& perBaseVertex) {
    const int nv = L.GetNumVertices(), ne = L.GetNumEdges(), nf = L.GetNumFaces();
    std::vector<double> out(static_cast<std::size_t>(nv + ne + nf), 0.0);
    std::copy(perBaseVertex.begin(), perBaseVertex.begin() + nv, out.begin());
    for (int e = 0; e < ne; ++e) {
        auto ev = L.GetEdgeVertices(e);
        out[static_cast<std::size_t>(nv + e)] =
            0.5 * perBaseVertex[static_cast<std::size_t>(ev[0])] + 0.5 * perBaseVertex[static_cast<std::size_t>(ev[1])];
    }
    for (int f = 0; f < nf; ++f) {
        auto fv = L.GetFaceVertices(f);
        double sum = 0;
        for (int i = 0; i < fv.size(); ++i) sum += perBaseVertex[static_cast<std::size_t>(fv[i])] / double(fv.size());
        out[static_cast<std::size_t>(nv + ne + f)] = sum;
    }
    return out;
}
} // namespace detail

/// Factors for every TileTopology vertex id from one factor per base vertex: midpoints and
/// centres get the means (see the header). Throws ArgumentError for a wrong count or a
/// factor that is not finite and > 0.
inline TessFactors tessFactorsFromBaseVertices(const BaseSurface& base, const std::vector<double>& perBaseVertex) {
    const Far::TopologyLevel& L = detail::baseLevel(base);
    const int nv = L.GetNumVertices();
    if (static_cast<int>(perBaseVertex.size()) != nv)
        throw ArgumentError(std::to_string(perBaseVertex.size()) + " tessellation factors given for " +
                            std::to_string(nv) + " base vertices");
    TessFactors out;
    for (int v = 0; v < nv; ++v) // the name is made only for the message
        if (const double f = perBaseVertex[static_cast<std::size_t>(v)]; !detail::validFactor(f))
            detail::checkFactor(f, "base vertex " + std::to_string(v));
    out.values = detail::spreadToTileVertices(L, perBaseVertex);
    return out;
}

/// The same factor T at every vertex. Throws ArgumentError for T not finite or <= 0.
inline TessFactors uniformTessFactors(const BaseSurface& base, double T) {
    detail::checkFactor(T, "the uniform factor");
    return tessFactorsFromBaseVertices(base, std::vector<double>(static_cast<std::size_t>(detail::baseLevel(base).GetNumVertices()), T));
}

/// The limit position s of every base vertex: s at a Ptex corner of the vertex that is not in
/// a hole, else the control point.
inline std::vector<glm::dvec3> baseVertexLimitPositions(const BaseSurface& base) {
    const int nv = detail::baseLevel(base).GetNumVertices();
    std::vector<glm::dvec3> p(static_cast<std::size_t>(nv));
    for (int v = 0; v < nv; ++v) {
        p[static_cast<std::size_t>(v)] = base.points()[static_cast<std::size_t>(v)];
        for (const auto& [t, c] : base.topology().incidences(v))
            if (!base.isHole(t)) {
                const glm::dvec2 uv = TileTopology::cornerUV(c);
                p[static_cast<std::size_t>(v)] = base.evaluate<double>(t, uv.x, uv.y, false).p;
                break;
            }
    }
    return p;
}

/// Distance-based factors (§6.1, kern::dmTessFactorDistance): c / |eye - s(v)| at the limit
/// position of every base vertex. Throws ArgumentError for c not finite and > 0 or an eye
/// that is not finite.
inline TessFactors distanceTessFactors(const BaseSurface& base, const glm::dvec3& eye, double c) {
    if (!std::isfinite(c) || !(c > 0.0))
        throw ArgumentError("distance factor constant c = " + std::to_string(c) + " must be finite and > 0");
    if (!std::isfinite(eye.x) || !std::isfinite(eye.y) || !std::isfinite(eye.z))
        throw ArgumentError("eye position is not finite");
    const std::vector<glm::dvec3> p = baseVertexLimitPositions(base);
    std::vector<double> f(p.size());
    for (std::size_t v = 0; v < p.size(); ++v) f[v] = kern::dmTessFactorDistance(eye, p[v], c);
    return tessFactorsFromBaseVertices(base, f);
}

/// What limits the mip choice at each base vertex (the Tessellator's rules; the GPU renderer
/// uploads the same): floorRes, the coarsest base resolution read there (2 at vertices of
/// non-quad faces, see the header, else 1), and kMin, the smallest k + scale of the tiles
/// around it (the texel-ratio rule's texel count; 1 << 20 where no tile touches the vertex).
struct VertexMipLimits {
    std::vector<double> floorRes;
    std::vector<int> kMin;
};
inline VertexMipLimits vertexMipLimits(const DisplacedSurface& surface) {
    const TileTopology& topo = surface.base().topology();
    const int nv = detail::baseLevel(surface.base()).GetNumVertices();
    VertexMipLimits m{std::vector<double>(static_cast<std::size_t>(nv), 1.0), std::vector<int>(static_cast<std::size_t>(nv), 1 << 20)};
    for (int v = 0; v < nv; ++v)
        for (const auto& [t, c] : topo.incidences(v)) {
            (void)c;
            if (topo.scale(t) > 0) m.floorRes[static_cast<std::size_t>(v)] = 2.0;
            m.kMin[static_cast<std::size_t>(v)] =
                std::min(m.kMin[static_cast<std::size_t>(v)], surface.tiles().tiles[static_cast<std::size_t>(t)].k + topo.scale(t));
        }
    return m;
}

/// Per-tile factors and the mip rule of one DisplacedSurface, and the tessellation itself.
class Tessellator {
  public:
    /// Keeps a reference to `surface` (which keeps its base and tiles): they must outlive it.
    /// Throws ArgumentError for factors of another mesh, invalid factors, or options out of
    /// range (see the header).
    Tessellator(const DisplacedSurface& surface, TessFactors factors, TessellateOptions options = {});
    /// The tessellator keeps a pointer to the surface: a temporary would dangle.
    Tessellator(DisplacedSurface&&, TessFactors, TessellateOptions = {}) = delete;

    const TessellateOptions& options() const { return options_; }
    /// A tile's corner factors (scaled and clamped), edge factors and inner factors. Throws
    /// ArgumentError for a face out of range.
    glm::dvec4 cornerFactors(int face) const;
    glm::dvec4 edgeFactors(int face) const { return kern::dmEdgeTessFactors(cornerFactors(face)); }
    glm::dvec2 innerFactors(int face) const { return kern::dmInnerTessFactors(edgeFactors(face)); }
    /// The resolution rho a vertex at (face, u, v) reads (kFinest with mips off), in the
    /// tile's own units (a sub-face's is one less than its quad neighbour's at the same texel
    /// spacing). Throws ArgumentError for a face out of range.
    double resolution(int face, double u, double v) const;
    /// The triangle and vertex counts and the memory tessellate() will take, counted tile by
    /// tile from the factors (no vertex is evaluated: microseconds per face).
    TessellationSize estimate() const;
    /// The whole surface (hole faces skipped). Throws ArgumentError, before anything is made,
    /// when estimate().bytes exceeds options().maxBytes.
    TriangleMesh tessellate() const;
    /// The same mesh, bit for bit, made in `out`'s arrays: they keep their capacity, so a
    /// tessellation again (new factors, a moved cage) into the same mesh reallocates none of the
    /// mesh's arrays while it fits, and its pages are already touched (an application
    /// tessellating again as its factors change; `dispmap bench --only embree` times both; the
    /// call's own working arrays, a few bytes a tile and vertex id, are still allocated). On a
    /// throw `out` is left empty (capacity kept).
    void tessellate(TriangleMesh& out) const;

  private:
    /// The vertex (TileTopology id) in the middle of tile t's edge e where a quad edge meets two
    /// sub-faces of an N-gon, or -1.
    int tJunctionMidpoint(int t, int e) const;
    struct Point {
        int id;
        glm::dvec2 uv; ///< in the tile being built
        double along;  ///< coordinate along the strip's direction
    };
    struct Build;
    double segmentFactor(int a, int b) const;
    /// What tile t makes: the segments of each edge (two halves at a T-junction), whether it is
    /// two triangles between its corners, its inner grid's segments, its triangles.
    struct TileCounts {
        std::array<std::uint64_t, 4> edgeSegments{};
        bool allOne = false;
        std::uint64_t nu = 0, nv = 0, triangles = 0;
    };
    TileCounts tileCounts(int t) const;
    /// The canonical points (0..n) of the segment between vertex ids lo < hi.
    std::vector<double> segmentSpacing(int lo, int hi) const { return edgeSpacing(segmentFactor(lo, hi), options_.spacing); }
    /// Serial, in tile order: gives tile t its vertex ids (corners and T-junction midpoints it
    /// is the first to touch, the interior points of the segments it is the first to reach, its
    /// inner grid) and the first index of its triangles; writes the (face, uv) of corners and
    /// midpoints. The ids are those of one pass over the tiles making every vertex as it
    /// meets it, whatever the thread count of emit().
    void plan(Build& b, int t) const;
    /// Parallel over tiles: tile t's segment and grid points (those it owns) and its triangles,
    /// at the places plan() gave them.
    void emit(Build& b, int t) const;

    const DisplacedSurface* surface_;
    TessFactors factors_;
    TessellateOptions options_;
    int nv_ = 0;
    std::vector<double> mipValue_; ///< per vertex id: mip factor (TessFactor) or resolution (TexelRatio)
};

struct Tessellator::Build {
    /// The output. plan() and emit() write each vertex's (face, uv) into mesh.faces and
    /// mesh.uvs, the vertex loop evaluates there.
    TriangleMesh& mesh;
    explicit Build(TriangleMesh& out) : mesh(out) {}
    std::vector<int> corner; // vertex id -> index
    /// A segment's interior points: n - 1 indices from `first` in canonical order, made by
    /// tile `owner` (in its frame).
    struct Segment {
        int first = 0, n = 0, owner = -1;
    };
    std::unordered_map<std::uint64_t, Segment> segments; // (lo, hi) -> its points
    struct TilePlan {
        int grid = 0;          ///< first index of the inner grid's points
        std::size_t triangles = 0; ///< first index of the tile's triangles
        bool allOne = false;   ///< two triangles between the corners, no grid
        int nu = 0, nv = 0;    ///< inner grid segments
    };
    std::vector<TilePlan> tiles;
    int count = 0; // indices given so far
    std::size_t triangleCount = 0;
    int add(int face, glm::dvec2 uv) {
        mesh.faces.push_back(face);
        mesh.uvs.push_back(uv);
        return count++;
    }
    int reserve(int n) {
        const int first = count;
        count += n;
        mesh.faces.resize(static_cast<std::size_t>(count));
        mesh.uvs.resize(static_cast<std::size_t>(count));
        return first;
    }
    void set(int i, int face, glm::dvec2 uv) {
        mesh.faces[static_cast<std::size_t>(i)] = face;
        mesh.uvs[static_cast<std::size_t>(i)] = uv;
    }
    static std::uint64_t key(int lo, int hi) { return static_cast<std::uint64_t>(lo) << 32 | static_cast<std::uint32_t>(hi); }
};

inline Tessellator::Tessellator(const DisplacedSurface& surface, TessFactors factors, TessellateOptions options)
    : surface_(&surface), factors_(std::move(factors)), options_(options) {
    const BaseSurface& base = surface.base();
    const TileTopology& topo = base.topology();
    const Far::TopologyLevel& L = detail::baseLevel(base);
    nv_ = L.GetNumVertices();
    if (static_cast<int>(factors_.values.size()) != topo.vertexCount())
        throw ArgumentError(std::to_string(factors_.values.size()) + " tessellation factors given, but the surface has " +
                            std::to_string(topo.vertexCount()) + " tile vertices: they were made for another mesh");
    for (int v = 0; v < topo.vertexCount(); ++v)
        if (const double f = factors_.values[static_cast<std::size_t>(v)]; !detail::validFactor(f))
            detail::checkFactor(f, "tile vertex " + std::to_string(v));
    if (!std::isfinite(options.maxFactor) || options.maxFactor < 1.0 || options.maxFactor > 1024.0)
        throw ArgumentError("maximum tessellation factor " + std::to_string(options.maxFactor) +
                            " out of range [1, 1024]");
    checkThreads(options.threads, "tessellation");
    if (options.mips == MipSelection::Off) return;

    // Per base vertex: the mip value, with the floor at vertices of non-quad faces.
    const VertexMipLimits limits = vertexMipLimits(surface);
    const std::vector<double>& floorRes = limits.floorRes;
    const std::vector<int>& kMin = limits.kMin;
    std::vector<double> perVertex(static_cast<std::size_t>(nv_));
    for (int v = 0; v < nv_; ++v) {
        const std::size_t i = static_cast<std::size_t>(v);
        const double F = std::min(factors_.values[i], options.maxFactor);
        if (options.mips == MipSelection::TessFactor)
            perVertex[i] = std::max(F, std::exp2(floorRes[i]));
        else if (kMin[i] > kMaxTileLog2 + 1) // no tile at this vertex: the value is never read
            perVertex[i] = floorRes[i];
        else
            perVertex[i] = std::max(kern::dmVertexResolutionTexelRatio(kMin[i], std::max(F, 1.0)), floorRes[i]);
    }
    mipValue_ = detail::spreadToTileVertices(L, perVertex);
}

inline glm::dvec4 Tessellator::cornerFactors(int face) const {
    const TileTopology& topo = surface_->base().topology();
    if (face < 0 || face >= topo.tileCount())
        throw ArgumentError("Ptex face " + std::to_string(face) + " out of range [0, " + std::to_string(topo.tileCount()) + ")");
    const double scale = topo.scale(face) > 0 ? 0.5 : 1.0;
    glm::dvec4 c;
    for (int i = 0; i < 4; ++i)
        c[i] = kern::dmClampTessFactor(factors_.values[static_cast<std::size_t>(topo.cornerVertex(face, i))] * scale,
                                       options_.maxFactor);
    return c;
}

// Factor of the segment between vertex ids a and b: the edge factor every tile on it computes
// (max of the two scaled, clamped corners; N-gon segments have an endpoint id >= nv).
inline double Tessellator::segmentFactor(int a, int b) const {
    const double scale = std::max(a, b) >= nv_ ? 0.5 : 1.0;
    const double f = std::max(factors_.values[static_cast<std::size_t>(a)], factors_.values[static_cast<std::size_t>(b)]);
    return kern::dmClampTessFactor(f * scale, options_.maxFactor);
}

inline double Tessellator::resolution(int face, double u, double v) const {
    const TileTopology& topo = surface_->base().topology();
    if (face < 0 || face >= topo.tileCount())
        throw ArgumentError("Ptex face " + std::to_string(face) + " out of range [0, " + std::to_string(topo.tileCount()) + ")");
    if (options_.mips == MipSelection::Off) return kFinest;
    glm::dvec4 c;
    for (int i = 0; i < 4; ++i) c[i] = mipValue_[static_cast<std::size_t>(topo.cornerVertex(face, i))];
    const double x = kern::dmBilerp(c, glm::dvec2(u, v));
    const double r = options_.mips == MipSelection::TessFactor ? kern::dmResolutionFromTessFactor(x) : x;
    return r - double(topo.scale(face));
}

inline int Tessellator::tJunctionMidpoint(int t, int e) const {
    const TileTopology& topo = surface_->base().topology();
    const std::vector<TileTopology::Link>& links = topo.links(t, e);
    if (!(topo.scale(t) == 0 && links.size() == 2 && links[0].beta != 1.0)) return -1;
    // The end of the sub-face edge covering [0, 1/2] that is not this edge's first corner.
    const TileTopology::Link& l = links[0].y0 == 0.0 ? links[0] : links[1];
    const int s0 = topo.cornerVertex(l.tile, l.edge), s1 = topo.cornerVertex(l.tile, l.edge + 1);
    return s0 == topo.cornerVertex(t, e) ? s1 : s0;
}

namespace detail {
/// (u, v) of tile edge e at edge parameter y (0 at corner e, 1 at corner e + 1).
inline glm::dvec2 tileEdgeUV(int e, double y) {
    switch (e) {
    case 0: return glm::dvec2(y, 0.0);
    case 1: return glm::dvec2(1.0, y);
    case 2: return glm::dvec2(1.0 - y, 1.0);
    default: return glm::dvec2(0.0, 1.0 - y);
    }
}
} // namespace detail

inline Tessellator::TileCounts Tessellator::tileCounts(int t) const {
    const TileTopology& topo = surface_->base().topology();
    TileCounts c;
    auto segments = [&](int A, int B) { return detail::spacingSegments(segmentFactor(std::min(A, B), std::max(A, B)), options_.spacing); };
    for (int e = 0; e < 4; ++e) {
        const int A = topo.cornerVertex(t, e), B = topo.cornerVertex(t, e + 1);
        const int M = tJunctionMidpoint(t, e);
        c.edgeSegments[static_cast<std::size_t>(e)] = M >= 0 ? segments(A, M) + segments(M, B) : segments(A, B);
    }
    const glm::dvec2 inner = innerFactors(t);
    c.allOne = options_.spacing == Spacing::Integer && inner.x <= 1.0 && inner.y <= 1.0;
    for (std::uint64_t k : c.edgeSegments) c.allOne = c.allOne && k == 1;
    if (c.allOne) {
        c.triangles = 2;
        return c;
    }
    c.nu = std::max<std::uint64_t>(detail::spacingSegments(std::max(inner.x, 1.0), options_.spacing), 2);
    c.nv = std::max<std::uint64_t>(detail::spacingSegments(std::max(inner.y, 1.0), options_.spacing), 2);
    const std::array<std::uint64_t, 4>& n = c.edgeSegments;
    c.triangles = 2 * (c.nu - 2) * (c.nv - 2) + (n[0] + c.nu - 2) + (n[1] + c.nv - 2) + (n[2] + c.nu - 2) + (n[3] + c.nv - 2);
    return c;
}

inline void Tessellator::plan(Build& b, int t) const {
    const TileTopology& topo = surface_->base().topology();
    Build::TilePlan& tp = b.tiles[static_cast<std::size_t>(t)];
    for (int c = 0; c < 4; ++c) {
        int& at = b.corner[static_cast<std::size_t>(topo.cornerVertex(t, c))];
        if (at < 0) at = b.add(t, TileTopology::cornerUV(c));
    }
    // Segments get their interior points from the first tile that reaches them.
    auto segment = [&](int A, int B) {
        const int lo = std::min(A, B), hi = std::max(A, B);
        const int segs = static_cast<int>(detail::spacingSegments(segmentFactor(lo, hi), options_.spacing));
        auto [it, fresh] = b.segments.try_emplace(Build::key(lo, hi));
        if (fresh) it->second = Build::Segment{b.reserve(segs - 1), segs, t};
    };
    for (int e = 0; e < 4; ++e) {
        const int A = topo.cornerVertex(t, e), B = topo.cornerVertex(t, e + 1);
        if (const int M = tJunctionMidpoint(t, e); M >= 0) {
            int& cM = b.corner[static_cast<std::size_t>(M)];
            if (cM < 0) cM = b.add(t, detail::tileEdgeUV(e, 0.5));
            segment(A, M);
            segment(M, B);
        } else {
            segment(A, B);
        }
    }
    const TileCounts c = tileCounts(t);
    tp.allOne = c.allOne;
    tp.triangles = b.triangleCount;
    b.triangleCount += static_cast<std::size_t>(c.triangles);
    if (c.allOne) return;
    tp.nu = static_cast<int>(c.nu);
    tp.nv = static_cast<int>(c.nv);
    tp.grid = b.reserve((tp.nu - 1) * (tp.nv - 1));
}

inline void Tessellator::emit(Build& b, int t) const {
    const TileTopology& topo = surface_->base().topology();
    const Build::TilePlan& tp = b.tiles[static_cast<std::size_t>(t)];
    auto cornerId = [&](int vertex) { return b.corner[static_cast<std::size_t>(vertex)]; };

    // Points of segment (A, B) on edge e, for edge parameters y0 (at A) to y1 (at B),
    // appended to `out` without the last one (B); the owner writes the interior points.
    auto segment = [&](int e, int A, int B, double y0, double y1, std::vector<Point>& out) {
        const int lo = std::min(A, B), hi = std::max(A, B);
        const std::vector<double> x = segmentSpacing(lo, hi);
        const std::size_t n = x.size() - 1;
        auto yAt = [&](std::size_t i) { // my edge parameter of canonical point i
            const double s = A == lo ? x[i] : 1.0 - x[i];
            return y0 == 0.0 && y1 == 1.0 ? s : y0 + (y1 - y0) * s;
        };
        const Build::Segment& seg = b.segments.at(Build::key(lo, hi));
        if (seg.owner == t)
            for (std::size_t i = 1; i < n; ++i)
                b.set(seg.first + static_cast<int>(i) - 1, t, detail::tileEdgeUV(e, yAt(i)));
        auto id = [&](std::size_t i) { return i == 0 ? cornerId(lo) : i == n ? cornerId(hi) : seg.first + static_cast<int>(i) - 1; };
        for (std::size_t j = 0; j < n; ++j) {
            const std::size_t i = A == lo ? j : n - j; // canonical index of my j-th point
            const double y = j == 0 ? y0 : yAt(i);
            out.push_back({id(i), detail::tileEdgeUV(e, y), y});
        }
    };

    std::array<std::vector<Point>, 4> edges;
    for (int e = 0; e < 4; ++e) {
        std::vector<Point>& pts = edges[static_cast<std::size_t>(e)];
        const int A = topo.cornerVertex(t, e), B = topo.cornerVertex(t, e + 1);
        if (const int M = tJunctionMidpoint(t, e); M >= 0) {
            segment(e, A, M, 0.0, 0.5, pts);
            segment(e, M, B, 0.5, 1.0, pts);
        } else {
            segment(e, A, B, 0.0, 1.0, pts);
        }
        pts.push_back({cornerId(B), TileTopology::cornerUV(e + 1), 1.0});
    }

    std::size_t tri = tp.triangles;
    TriangleMesh& mesh = b.mesh;
    auto put = [&](const Point& p0, const Point& p1, const Point& p2) {
        mesh.triangles[tri] = glm::ivec3(p0.id, p1.id, p2.id);
        mesh.triangleFaces[tri] = t;
        mesh.triangleUVs[tri] = {p0.uv, p1.uv, p2.uv};
        ++tri;
    };

    if (tp.allOne) {
        put(edges[0][0], edges[1][0], edges[2][0]);
        put(edges[0][0], edges[2][0], edges[3][0]);
        return;
    }
    const glm::dvec2 inner = innerFactors(t);
    std::vector<double> xu = edgeSpacing(std::max(inner.x, 1.0), options_.spacing);
    std::vector<double> xv = edgeSpacing(std::max(inner.y, 1.0), options_.spacing);
    if (xu.size() < 3) xu = {0.0, 0.5, 1.0};
    if (xv.size() < 3) xv = {0.0, 0.5, 1.0};
    const int nu = tp.nu, nvv = tp.nv;
    // Inner grid points (i, j), 1 <= i < nu, 1 <= j < nv, numbered row by row from tp.grid.
    auto g = [&](int i, int j) {
        const glm::dvec2 uv(xu[static_cast<std::size_t>(i)], xv[static_cast<std::size_t>(j)]);
        return Point{tp.grid + (j - 1) * (nu - 1) + (i - 1), uv, 0.0};
    };
    for (int j = 1; j < nvv; ++j)
        for (int i = 1; i < nu; ++i) {
            const Point p = g(i, j);
            b.set(p.id, t, p.uv);
        }
    for (int j = 1; j + 1 < nvv; ++j)
        for (int i = 1; i + 1 < nu; ++i) {
            put(g(i, j), g(i + 1, j), g(i + 1, j + 1));
            put(g(i, j), g(i + 1, j + 1), g(i, j + 1));
        }
    // Zippers: the inner ring side e runs in edge e's direction.
    std::vector<Point> q;
    for (int e = 0; e < 4; ++e) {
        q.clear();
        auto push = [&](int i, int j, double along) {
            Point p = g(i, j);
            p.along = along;
            q.push_back(p);
        };
        if (e == 0)
            for (int i = 1; i < nu; ++i) push(i, 1, xu[static_cast<std::size_t>(i)]);
        else if (e == 1)
            for (int j = 1; j < nvv; ++j) push(nu - 1, j, xv[static_cast<std::size_t>(j)]);
        else if (e == 2)
            for (int i = nu - 1; i >= 1; --i) push(i, nvv - 1, 1.0 - xu[static_cast<std::size_t>(i)]);
        else
            for (int j = nvv - 1; j >= 1; --j) push(1, j, 1.0 - xv[static_cast<std::size_t>(j)]);
        const std::vector<Point>& p = edges[static_cast<std::size_t>(e)];
        std::size_t i = 0, j = 0;
        while (i + 1 < p.size() || j + 1 < q.size()) {
            const bool advanceEdge =
                j + 1 >= q.size() || (i + 1 < p.size() && p[i + 1].along <= q[j + 1].along + 1e-12);
            if (advanceEdge) {
                put(p[i], p[i + 1], q[j]);
                ++i;
            } else {
                put(p[i], q[j + 1], q[j]);
                ++j;
            }
        }
    }
}

inline TessellationSize Tessellator::estimate() const {
    const BaseSurface& base = surface_->base();
    const TileTopology& topo = base.topology();
    TessellationSize out;
    for (int t = 0; t < topo.tileCount(); ++t) {
        if (base.isHole(t)) continue;
        const TileCounts c = tileCounts(t);
        out.triangles += c.triangles;
        const std::array<std::uint64_t, 4>& n = c.edgeSegments;
        out.vertices += c.allOne ? 4 : (c.nu - 1) * (c.nv - 1) + n[0] + n[1] + n[2] + n[3];
    }
    // Per vertex: the mesh's position, normal, face, uv and resolution (76 bytes); per triangle:
    // indices, face and corner uvs (64). tessellate() sizes its arrays from these counts (none
    // grows); the factor 2 on the triangles is a margin (a caller writing the mesh out copies
    // parts of it; the vertex count is already an upper bound).
    out.bytes = 2 * out.triangles * 64 + out.vertices * 76;
    return out;
}

inline TriangleMesh Tessellator::tessellate() const {
    TriangleMesh m;
    tessellate(m);
    return m;
}

inline void Tessellator::tessellate(TriangleMesh& out) const {
    const BaseSurface& base = surface_->base();
    const TileTopology& topo = base.topology();
    // On a throw every array is emptied, not freed: it keeps its capacity.
    auto clear = [&] {
        out.positions.clear();
        out.normals.clear();
        out.faces.clear();
        out.uvs.clear();
        out.resolutions.clear();
        out.triangles.clear();
        out.triangleFaces.clear();
        out.triangleUVs.clear();
    };
    // faces and uvs are appended to; the other arrays are resized to their counts below and
    // every element written, so they keep their contents meanwhile: each element is written once
    // (a MeshArray's resize does not zero its growth, core/triangle_mesh.h), and a new size
    // within the capacity writes over pages already touched.
    out.faces.clear();
    out.uvs.clear();
    const TessellationSize size = estimate();
    if (size.bytes > options_.maxBytes) {
        clear();
        throw ArgumentError("tessellation: " + std::to_string(size.triangles) + " triangles and up to " + std::to_string(size.vertices) +
                            " vertices would take about " + std::to_string(size.bytes >> 20) + " MiB, more than the limit of " +
                            std::to_string(options_.maxBytes >> 20) + " MiB: lower the factors or the maximum factor");
    }
    try {
        Build b(out);
        b.corner.assign(static_cast<std::size_t>(topo.vertexCount()), -1);
        b.tiles.resize(static_cast<std::size_t>(topo.tileCount()));
        b.segments.reserve(static_cast<std::size_t>(2 * topo.tileCount() + 8));
        std::vector<int> live;
        TriangleMesh& m = out;
        const Parallel par(options_.threads);
        // Sized to n, every element then written: kept where it fits (nothing written twice),
        // emptied first where it grows past its capacity (nothing copied into the new block).
        auto refill = [&](auto& v, std::size_t count) {
            if (v.capacity() < count) v.clear();
            resizeLarge(v, count, options_.hugePages);
        };
        // Sizing the output arrays is mostly the kernel's first touch of their pages (tens of MiB
        // at factor 32), so the arrays are sized side by side, as tasks of their own, with the
        // huge-page hint (core/memory.h). The triangle count is exact from the factors, so those
        // arrays are sized while plan() runs; the vertex count is an upper bound, reserved.
        const std::size_t triangles = static_cast<std::size_t>(size.triangles);
        par.each(4, 1, [&](std::size_t task) {
            if (task == 0) {
                reserveLarge(m.faces, static_cast<std::size_t>(size.vertices), options_.hugePages);
                reserveLarge(m.uvs, static_cast<std::size_t>(size.vertices), options_.hugePages);
                for (int t = 0; t < topo.tileCount(); ++t)
                    if (!base.isHole(t)) {
                        plan(b, t);
                        live.push_back(t);
                    }
            } else if (task == 1) {
                refill(m.triangles, triangles);
            } else if (task == 2) {
                refill(m.triangleFaces, triangles);
            } else {
                refill(m.triangleUVs, triangles);
            }
        });
        if (b.triangleCount != triangles)
            throw Error("tessellation: " + std::to_string(b.triangleCount) + " triangles planned, " + std::to_string(triangles) +
                        " counted from the factors (an internal inconsistency)");
        // Every triangle's place is known: the tiles fill theirs in parallel, while the vertex
        // arrays are sized.
        const std::size_t n = m.faces.size();
        par.each(4, 1, [&](std::size_t task) {
            switch (task) {
            case 0: par.each(live.size(), 8, [&](std::size_t i) { emit(b, live[i]); }); break;
            case 1: refill(m.positions, n); break;
            case 2: refill(m.normals, n); break;
            default: refill(m.resolutions, n); break;
            }
        });
        if (options_.normals == NormalMode::Auto) (void)surface_->autoFaces(); // the analysis, once, before the loop
        // Vertices are independent: each writes its own slot. A tile's inner grid goes through
        // DisplacedSurface::evaluateGrid (each patch collapsed once per row), and so do the
        // points of the tile edges' segments (the spans between the grids), a line at a time.
        std::vector<std::size_t> spans; // [begin, end) pairs of the vertices outside the grids
        std::size_t next = 0;
        for (int t : live) {
            const Build::TilePlan& tp = b.tiles[static_cast<std::size_t>(t)];
            if (tp.allOne) continue;
            spans.push_back(next);
            spans.push_back(static_cast<std::size_t>(tp.grid));
            next = static_cast<std::size_t>(tp.grid) + static_cast<std::size_t>(tp.nu - 1) * static_cast<std::size_t>(tp.nv - 1);
        }
        spans.push_back(next);
        spans.push_back(n);
        // Vertex i's position and normal; one that is not finite is flagged for the scan below.
        std::atomic<bool> nonFinite{false};
        auto store = [&](std::size_t i, const SurfaceSample<double>& s) {
            const glm::dvec3 &p = s.position, &q = s.normal;
            m.positions[i] = p;
            m.normals[i] = q;
            if (!std::isfinite(p.x + p.y + p.z + q.x + q.y + q.z)) nonFinite.store(true, std::memory_order_relaxed);
        };
        par.each(spans.size() / 2, 4, [&](std::size_t k) {
            // A span holds corners, T-junction midpoints and the interior points of edge segments,
            // each segment's points one after another in one face's frame, on a line u or v =
            // const: runs of them go through evaluateGrid as one line, single points through
            // evaluate().
            std::vector<double> xs;
            const std::size_t end = spans[2 * k + 1];
            for (std::size_t i = spans[2 * k]; i < end;) {
                const int face = m.faces[i];
                const glm::dvec2 uv = m.uvs[i];
                std::size_t r = i + 1;
                const bool row = r < end && m.faces[r] == face && m.uvs[r].y == uv.y;
                const bool column = !row && r < end && m.faces[r] == face && m.uvs[r].x == uv.x;
                while (r < end && m.faces[r] == face && (row ? m.uvs[r].y == uv.y : column && m.uvs[r].x == uv.x)) ++r;
                if (r - i == 1) {
                    const double rho = resolution(face, uv.x, uv.y);
                    store(i, surface_->evaluate<double>(face, uv.x, uv.y, options_.normals, rho));
                    m.resolutions[i] = rho;
                    i = r;
                    continue;
                }
                xs.clear();
                for (std::size_t q = i; q < r; ++q) xs.push_back(row ? m.uvs[q].x : m.uvs[q].y);
                const double fixed = row ? uv.y : uv.x;
                const std::span<const double> line(xs), one(&fixed, 1);
                const std::size_t first = i;
                surface_->evaluateGrid<double>(
                    face, row ? line : one, row ? one : line, options_.normals,
                    [&](std::size_t x, std::size_t y) {
                        return m.resolutions[first + (row ? x : y)] = resolution(face, row ? xs[x] : fixed, row ? fixed : xs[y]);
                    },
                    [&](std::size_t x, std::size_t y, const SurfaceSample<double>& s) { store(first + (row ? x : y), s); });
                i = r;
            }
        });
        par.each(live.size(), 1, [&](std::size_t k) {
            const int t = live[k];
            const Build::TilePlan& tp = b.tiles[static_cast<std::size_t>(t)];
            if (tp.allOne) return;
            // The grid's coordinates as emit() wrote them: u along its first row, v down its first column.
            const std::size_t first = static_cast<std::size_t>(tp.grid), row = static_cast<std::size_t>(tp.nu - 1);
            std::vector<double> us(row), vs(static_cast<std::size_t>(tp.nv - 1));
            for (std::size_t i = 0; i < us.size(); ++i) us[i] = m.uvs[first + i].x;
            for (std::size_t j = 0; j < vs.size(); ++j) vs[j] = m.uvs[first + j * row].y;
            surface_->evaluateGrid<double>(
                t, us, vs, options_.normals,
                [&](std::size_t i, std::size_t j) { return m.resolutions[first + j * row + i] = resolution(t, us[i], vs[j]); },
                [&](std::size_t i, std::size_t j, const SurfaceSample<double>& s) { store(first + j * row + i, s); });
        });
        // The first vertex in index order that is not finite is named, whatever the thread count
        // (looked for only when a task saw one).
        for (std::size_t i = 0; nonFinite.load(std::memory_order_relaxed) && i < n; ++i)
            if (const glm::dvec3 &p = m.positions[i], &q = m.normals[i]; !std::isfinite(p.x + p.y + p.z + q.x + q.y + q.z))
                throw Error("tessellation: the surface is not finite at Ptex face " + std::to_string(m.faces[i]) + ", (u, v) = (" +
                            std::to_string(m.uvs[i].x) + ", " + std::to_string(m.uvs[i].y) + ")");
    } catch (...) {
        clear();
        throw;
    }
}

/// Tessellates `surface` with `factors` (see the header). Throws as Tessellator.
inline TriangleMesh tessellate(const DisplacedSurface& surface, const TessFactors& factors,
                               const TessellateOptions& options = {}) {
    return Tessellator(surface, factors, options).tessellate();
}

/// Finds the triangle of a TriangleMesh that covers (face, u, v) in its face's domain: a
/// uniform bucket grid per face over the triangles' (u, v) boxes.
class TriangleLocator {
  public:
    /// `faceCount` Ptex faces; `cells` buckets per side of each face's grid (>= 1).
    TriangleLocator(const TriangleMesh& mesh, int faceCount, int cells = 16);
    /// The locator keeps a pointer to the mesh: a temporary would dangle.
    TriangleLocator(TriangleMesh&&, int, int = 16) = delete;
    /// The triangle covering (face, uv) and its barycentric weights, or -1 when no triangle of
    /// that face covers it (a hole). Points on shared edges pick the most interior triangle.
    int locate(int face, glm::dvec2 uv, glm::dvec3& bary) const;
    /// The piecewise-linear position at (face, uv). Throws ArgumentError where nothing covers it.
    glm::dvec3 position(int face, glm::dvec2 uv) const;

  private:
    std::size_t bucket(int face, int i, int j) const {
        return (static_cast<std::size_t>(face) * static_cast<std::size_t>(cells_) + static_cast<std::size_t>(j)) *
                   static_cast<std::size_t>(cells_) +
               static_cast<std::size_t>(i);
    }
    int cell(double x) const { return static_cast<int>(std::clamp(x * cells_, 0.0, double(cells_ - 1))); }
    const TriangleMesh* mesh_;
    int faces_, cells_;
    std::vector<std::vector<int>> buckets_;
};

inline TriangleLocator::TriangleLocator(const TriangleMesh& mesh, int faceCount, int cells)
    : mesh_(&mesh), faces_(faceCount), cells_(cells) {
    if (cells < 1 || cells > 4096 || faceCount < 0) throw ArgumentError("triangle locator: invalid grid");
    if (mesh.triangleFaces.size() != mesh.triangles.size() || mesh.triangleUVs.size() != mesh.triangles.size())
        throw ArgumentError("triangle locator: the mesh's triangle arrays disagree in size");
    for (const auto& t : mesh.triangleUVs)
        for (const glm::dvec2& q : t)
            if (!std::isfinite(q.x) || !std::isfinite(q.y)) throw ArgumentError("triangle locator: a triangle's (u, v) is not finite");
    buckets_.resize(static_cast<std::size_t>(faceCount) * static_cast<std::size_t>(cells) * static_cast<std::size_t>(cells));
    for (int tri = 0; tri < mesh.triangleCount(); ++tri) {
        const int f = mesh.triangleFaces[static_cast<std::size_t>(tri)];
        if (f < 0 || f >= faceCount) throw ArgumentError("triangle locator: triangle of face " + std::to_string(f) + " out of range");
        const auto& uv = mesh.triangleUVs[static_cast<std::size_t>(tri)];
        const glm::dvec2 lo = glm::min(uv[0], glm::min(uv[1], uv[2])), hi = glm::max(uv[0], glm::max(uv[1], uv[2]));
        const double eps = 1e-12;
        for (int j = cell(lo.y - eps); j <= cell(hi.y + eps); ++j)
            for (int i = cell(lo.x - eps); i <= cell(hi.x + eps); ++i) buckets_[bucket(f, i, j)].push_back(tri);
    }
}

inline int TriangleLocator::locate(int face, glm::dvec2 uv, glm::dvec3& bary) const {
    if (face < 0 || face >= faces_ || !std::isfinite(uv.x) || !std::isfinite(uv.y)) return -1;
    int best = -1;
    double bestMin = -1e-9;
    for (int tri : buckets_[bucket(face, cell(uv.x), cell(uv.y))]) {
        const auto& c = mesh_->triangleUVs[static_cast<std::size_t>(tri)];
        const glm::dvec2 e1 = c[1] - c[0], e2 = c[2] - c[0], d = uv - c[0];
        const double det = e1.x * e2.y - e1.y * e2.x;
        if (!(det > 0.0)) continue; // degenerate (zero-length fractional segment)
        const double b1 = (d.x * e2.y - d.y * e2.x) / det, b2 = (e1.x * d.y - e1.y * d.x) / det;
        const glm::dvec3 w(1.0 - b1 - b2, b1, b2);
        const double mn = std::min(w.x, std::min(w.y, w.z));
        if (mn > bestMin) {
            bestMin = mn;
            best = tri;
            bary = w;
        }
    }
    return best;
}

inline glm::dvec3 TriangleLocator::position(int face, glm::dvec2 uv) const {
    glm::dvec3 w(0.0);
    const int tri = locate(face, uv, w);
    if (tri < 0)
        throw ArgumentError("no triangle covers Ptex face " + std::to_string(face) + ", (u, v) = (" + std::to_string(uv.x) +
                            ", " + std::to_string(uv.y) + ")");
    const glm::ivec3 ix = mesh_->triangles[static_cast<std::size_t>(tri)];
    return w.x * mesh_->positions[static_cast<std::size_t>(ix.x)] + w.y * mesh_->positions[static_cast<std::size_t>(ix.y)] +
           w.z * mesh_->positions[static_cast<std::size_t>(ix.z)];
}

} // namespace dispmap
