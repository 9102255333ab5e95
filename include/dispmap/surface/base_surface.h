#pragma once
// BaseSurface: the Catmull-Clark limit surface s(face, u, v) of a control mesh and its first
// and second derivatives, evaluated by OpenSubdiv (Nießner & Loop 2013, §5.4; docs/design.md).
//
// Route: Far feature-adaptive refinement and a Far::PatchTable (regular bicubic B-spline
// patches where the mesh is regular, Gregory-basis end caps around extraordinary vertices at
// the isolation level), located with Far::PatchMap and evaluated with
// PatchTable::EvaluateBasis. Chosen over Bfr because the GPU renderer uploads this very
// patch table: the CPU reference and the tessellation shaders then evaluate the same patches
// with the same end caps, and the same 2^-depth sub-domains carry the patch records' local
// offsets. Bfr would evaluate the irregular faces with other approximations.
//
// Parameterisation: (face, u, v) with face a Ptex face id (Far::PtexIndices: an N-gon, N != 4,
// is N faces, sub-face k having its corners at vertex k, the midpoint of edge k, the centre,
// the midpoint of edge k - 1), the numbering of TileSet; (u, v) in [0, 1]^2. Derivatives are
// with respect to that (u, v). Float and double: the refined and local points are computed
// in double (double-precision stencils) and rounded once for the float evaluator.
//
// Extraordinary corners (§5.4): a Ptex corner whose vertex carries the Doo-Sabin constraint of
// the tiles (TileTopology::VertexKind::Constrained: interior valence != 4, boundary vertices
// of 3 or more tiles, N-gon centres) is where s_u and s_v are not consistently defined. Every
// end-cap patch touching such a corner reports its bilinear weight and the corner's limit
// normal, for the blend of dmBlendLimitNormal.
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <opensubdiv/far/patchMap.h>
#include <opensubdiv/far/patchTable.h>
#include <opensubdiv/far/patchTableFactory.h>
#include <opensubdiv/far/primvarRefiner.h>

#include "dispmap/kernels/normal.h"
#include "dispmap/kernels/patch.h"
#include "dispmap/surface/mesh.h"
#include "dispmap/surface/tile_topology.h"

namespace dispmap {

struct BaseSurfaceOptions {
    /// Feature-adaptive isolation level (1..10): patches around extraordinary vertices shrink
    /// to 2^-level of a face before an end cap approximates the rest. 6 by default: near
    /// extraordinary vertices the normal is within about 0.1 degree of level 10 there, 4 would
    /// leave 1.6 degrees (`dispmap bench`, isolation table); deeper levels add patches only.
    /// Semi-sharp creases and corners are isolated deeper where they need it, until their
    /// sharpness has decayed (ceil of the largest finite sharpness, at most 10): the patch
    /// table treats whatever sharpness is left at its last level as infinite (bishop,
    /// sharpness 6, at level 4: positions off by 2e-3 of the mesh size, normals by 0.36 rad).
    int isolationLevel = 6;
    /// Gregory-basis end caps (OpenSubdiv's recommended default) or B-spline-basis ones.
    bool gregoryEndCaps = true;
};

/// s and its derivatives at one (face, u, v), plus the §5.4 blend data.
template <typename real> struct BaseSample {
    using vec3 = glm::vec<3, real>;
    vec3 p{0}, du{0}, dv{0}, duu{0}, duv{0}, dvv{0};
    vec3 evNormal{0}; ///< sum of (bilinear weight x limit normal) over extraordinary patch corners
    real evWeight = 0;
    bool endCap = false; ///< an end-cap patch that touches an extraordinary corner holds the point
};

/// An end-cap patch's corners (BaseSurface::endCapCorners): the samples there, their (u, v)
/// in the Ptex face (corner c of the patch: 0 at its (0,0), 1 (1,0), 2 (1,1), 3 (0,1)), and
/// the point's local coordinates in the patch.
template <typename real> struct EndCapCorners {
    BaseSample<real> corner[4];
    glm::vec<2, real> uv[4];
    glm::vec<2, real> local{0};
};

class BaseSurface {
  public:
    /// Refines `mesh` adaptively and builds the patch table. Throws ArgumentError for an
    /// isolation level outside [1, 10].
    explicit BaseSurface(const ControlMesh& mesh, BaseSurfaceOptions options = {});

    /// Number of Ptex faces (the valid face ids).
    int faceCount() const { return faceCount_; }
    /// True if the Ptex face lies in a face tagged as a hole (no surface there).
    bool isHole(int face) const { return hole_[checkedFace(face)] != 0; }
    const BaseSurfaceOptions& options() const { return options_; }
    /// topologyHash of the mesh it was built from (TileSet::topologyHash of matching tiles).
    std::uint64_t topologyHash() const { return topologyHash_; }
    const Far::PatchTable& patchTable() const { return *table_; }
    /// The refiner of the control mesh. Only its base level (GetLevel(0)) is kept: the refined
    /// levels the patch table was built from are dropped once the points are refined (they are
    /// most of the memory at deep isolation: 1.1 of 1.5 GiB on the 13k-triangle fandisk at
    /// level 6, `dispmap bench --only cages`), and setControlPoints brings them back. Until its
    /// first call the refiner has one level: GetNumLevels() is 1 and the refined levels' accessors
    /// (GetLevel(1..), GetNumVerticesTotal() counting them) must not be read for the points.
    const Far::TopologyRefiner& refiner() const { return *refiner_; }
    const TileTopology& topology() const { return topology_; }
    /// Refined vertices of every level followed by the patch table's local points (double): the
    /// indices the patch table's control vertices use. They stay whole after the refiner drops
    /// its levels (refiner()), so count them here, not through the refiner.
    const std::vector<glm::dvec3>& points() const { return pointsD_; }
    /// Whether Ptex corner c (0 at (0,0), 1 at (1,0), 2 at (1,1), 3 at (0,1)) of `face` is an
    /// extraordinary corner (see above), and the limit normal there.
    bool isExtraordinaryCorner(int face, int c) const { return evCorner_[checkedFace(face)][static_cast<std::size_t>(c & 3)] != 0; }
    glm::dvec3 cornerNormal(int face, int c) const { return cornerNormal_[checkedFace(face)][static_cast<std::size_t>(c & 3)]; }
    /// The infinitely sharp features of a Ptex face that the displacement fades out towards
    /// (kernels/sharp.h): bit i (0..3) its edge i (corner i to i + 1) lies on an interior
    /// infinitely sharp edge of the mesh; bit 4 + c its corner c is a base vertex on such an
    /// edge, or an infinitely sharp corner shared by two or more faces. Boundary edges and
    /// single-face corners need nothing (no second side), semi-sharp creases neither (the
    /// limit surface is smooth across them once their sharpness has decayed). Throws
    /// ArgumentError for a face id out of range.
    int sharpMask(int face) const { return sharp_[checkedFace(face)]; }
    /// Throws ArgumentError naming the mesh unless `face` is a Ptex face id and (u, v) a finite
    /// point of [0, 1]^2.
    template <typename real> void checkPoint(int face, real u, real v) const;
    /// Throws ArgumentError naming the mesh if `face` is a hole (no surface to evaluate).
    void checkNotHole(int face) const {
        if (isHole(face)) holeError(face);
    }
    /// `face` as an index; throws ArgumentError naming the mesh if it is not a Ptex face id.
    std::size_t checkedFace(int face) const {
        if (face < 0 || face >= faceCount_)
            throw ArgumentError(name_ + ": face id " + std::to_string(face) + " out of range [0, " + std::to_string(faceCount_) + ")");
        return static_cast<std::size_t>(face);
    }

    /// s, s_u, s_v and, if `second`, s_uu, s_uv, s_vv at (face, u, v). Throws ArgumentError
    /// for a face id out of range, a hole, or (u, v) outside [0, 1]^2 or not finite.
    template <typename real> BaseSample<real> evaluate(int face, real u, real v, bool second = true) const;

    /// s, s_u and s_v along one row v = const (or column u = const) of a Ptex face, for many
    /// points (a tessellation's grid and edges): see BaseSurface::Row below.
    template <typename real> class Row;

    /// §5.4: the four corners of the end-cap patch holding (face, u, v), each evaluated (with
    /// second derivatives) in the patch beyond that corner, for normals interpolated across the
    /// end cap (DisplacedSurface). False, with `out` untouched, where a regular patch holds the
    /// point. Throws as evaluate().
    template <typename real> bool endCapCorners(int face, real u, real v, EndCapCorners<real>& out) const;

    /// Animation (Nießner & Loop 2013, §4.1): new positions of the control mesh's vertices
    /// (same count and order as the mesh it was built from) refined through the refiner and
    /// the patch table's local-point stencils; the topology, patch table and patch map are
    /// kept. The first call refines the topology again (the constructor dropped its levels;
    /// the same options give the same levels) and keeps it for the next calls: an animated
    /// surface holds the refined levels, a still one does not. Afterwards points() and
    /// cornerNormal() describe the moved surface exactly as a BaseSurface built from the moved
    /// mesh would (bit for bit: the same arithmetic). Throws MeshError, with the levels dropped
    /// again and nothing changed, should OpenSubdiv refine to another vertex count than the
    /// patch table was built from.
    /// Throws ArgumentError for a wrong count or a NaN/Inf coordinate (nothing changes then).
    /// A DisplacedSurface built on this surface sees the moved surface; its auto-normal choice
    /// per face was made for the old shape.
    void setControlPoints(const std::vector<glm::dvec3>& positions);
    /// Number of control-mesh vertices setControlPoints expects.
    int controlPointCount() const { return refiner_->GetLevel(0).GetNumVertices(); }

  private:
    [[noreturn]] void holeError(int face) const {
        throw ArgumentError(name_ + ": face " + std::to_string(face) + " is a hole (no surface to evaluate)");
    }
    template <typename real> const Far::PatchTable::PatchHandle& findPatch(int face, real u, real v) const;
    template <typename real>
    BaseSample<real> evaluateIn(const Far::PatchTable::PatchHandle& patch, int face, real u, real v, bool second) const;
    /// Refines `positions` into points(); `dropLevels` unrefines the refiner as soon as it is no
    /// longer read (before the copies into pointsD_ and pointsF_, which lowers the peak).
    void refinePoints(const std::vector<glm::dvec3>& positions, bool dropLevels);
    void computeCornerNormals();
    void computeSharpMasks(const ControlMesh& mesh);
    template <typename real> const std::vector<glm::vec<3, real>>& points() const;
    BaseSurfaceOptions options_;
    int faceCount_ = 0;
    std::unique_ptr<Far::TopologyRefiner> refiner_;
    Far::TopologyRefiner::AdaptiveOptions adaptive_{0}; ///< the refinement the patch table was built from
    bool refined_ = false;                              ///< refiner_ holds its refined levels again
    int refinedVertexCount_ = 0;                        ///< GetNumVerticesTotal() of those levels
    std::unique_ptr<Far::PatchTable> table_;
    std::unique_ptr<Far::PatchMap> map_;
    TileTopology topology_;
    std::vector<glm::dvec3> pointsD_;
    std::vector<glm::vec3> pointsF_;
    std::vector<std::uint8_t> hole_;
    std::vector<std::array<std::uint8_t, 4>> evCorner_;
    std::vector<std::array<glm::dvec3, 4>> cornerNormal_;
    std::vector<std::uint8_t> sharp_;
    std::string name_;
    std::uint64_t topologyHash_ = 0;
};

/// s, s_u and s_v along one row v = const of a Ptex face, for many u, or along one column
/// u = const, for many v (alongV). Each regular patch the line crosses is collapsed once across
/// it: its 4 x 4 control points weighted by the basis of the fixed coordinate (kernels/patch.h,
/// boundary rule included) and by its derivative give 8 points, and each point of the line
/// then sums 4 of them with the basis along the line, where evaluate() gathers 16 control
/// points and runs OpenSubdiv's EvaluateBasis (a quarter of a tessellation's time). The result
/// is evaluate(face, u, v, false) to rounding, not bit for bit: the same products summed in
/// another order, and the basis of kernels/patch.h, which agrees with EvaluateBasis to a few
/// units in the last place (tests/test_packed_surface.cpp); tests/test_surface.cpp bounds the
/// difference. Points in end-cap patches are left to evaluate(): at() returns false there.
/// The row keeps a pointer to the surface; one row per thread.
template <typename real> class BaseSurface::Row {
  public:
    using vec3 = glm::vec<3, real>;
    /// The row v = `fixed` (or the column u = `fixed` if alongV). Throws ArgumentError for a
    /// face id out of range, a hole, or `fixed` outside [0, 1] or not finite.
    Row(const BaseSurface& surface, int face, real fixed, bool alongV = false)
        : surface_(&surface), face_(face), fixed_(fixed), alongV_(alongV) {
        surface.checkPoint(face, alongV ? fixed : real(0), alongV ? real(0) : fixed);
        surface.checkNotHole(face);
    }
    /// s, s_u, s_v at the line's point x (u along a row, v along a column) into out (second
    /// derivatives and the §5.4 blend data left 0), or false, with out untouched, where an
    /// end-cap patch holds the point. Throws ArgumentError for x outside [0, 1] or not finite.
    bool at(real x, BaseSample<real>& out);

  private:
    void collapse(const Far::PatchTable::PatchHandle& h);
    const BaseSurface* surface_;
    int face_;
    real fixed_;
    bool alongV_;
    const Far::PatchTable::PatchHandle* patch_ = nullptr; ///< the patch collapsed last
    bool regular_ = false;
    vec3 q_[4], qd_[4]; ///< per control line k along the line: sum_m b_m P and sum_m 2^L b'_m P across it
    real lo_ = 0, hi_ = 0; ///< the collapsed patch's span along the line
    real scale_ = 1;    ///< 2^L
    real offset_ = 0;   ///< the patch's U (V along a column)
    bool low_ = false, high_ = false; ///< boundary rule at the line's ends of the patch
};

template <typename real> void BaseSurface::Row<real>::collapse(const Far::PatchTable::PatchHandle& h) {
    patch_ = &h;
    const Far::PatchTable& table = *surface_->table_;
    const Far::PatchParam param = table.GetPatchParam(h);
    const Far::ConstIndexArray cv = table.GetPatchVertices(h);
    const glm::uvec2 packed(param.field0, param.field1);
    scale_ = real(1 << kern::dmPatchDomainLevel(packed));
    const real frac = real(1) / scale_; // a power of two: exact
    const glm::ivec2 offset = kern::dmPatchOffset(packed);
    offset_ = real(alongV_ ? offset.y : offset.x);
    lo_ = offset_ * frac;
    hi_ = lo_ + frac;
    regular_ = param.IsRegular() && cv.size() == 16;
    if (!regular_) return;
    // Boundary mask: bit 0 the edge v = 0, bit 1 u = 1, bit 2 v = 1, bit 3 u = 0.
    const int b = kern::dmPatchBoundary(packed);
    const bool u0 = (b & 8) != 0, u1 = (b & 2) != 0, v0 = (b & 1) != 0, v1 = (b & 4) != 0;
    low_ = alongV_ ? v0 : u0;
    high_ = alongV_ ? v1 : u1;
    const glm::vec<2, real> local = kern::dmPatchLocal(packed, glm::vec<2, real>(fixed_, fixed_));
    const real t = alongV_ ? local.x : local.y;
    const glm::vec<4, real> across = kern::dmFoldBoundary(kern::dmBSpline3(t), alongV_ ? u0 : v0, alongV_ ? u1 : v1);
    const glm::vec<4, real> dAcross = kern::dmFoldBoundary(kern::dmBSpline3D1(t), alongV_ ? u0 : v0, alongV_ ? u1 : v1) * scale_;
    const std::vector<vec3>& P = surface_->points<real>();
    // Control point 4i + j: column j along u, row i along v. Along a row the lines k are the
    // columns (summed over the rows m), along a column the rows.
    for (int k = 0; k < 4; ++k) {
        q_[k] = vec3(0);
        qd_[k] = vec3(0);
        for (int m = 0; m < 4; ++m) {
            const vec3& x = P[static_cast<std::size_t>(cv[alongV_ ? 4 * k + m : 4 * m + k])];
            q_[k] += across[m] * x;
            qd_[k] += dAcross[m] * x;
        }
    }
}

template <typename real> bool BaseSurface::Row<real>::at(real x, BaseSample<real>& out) {
    const real u = alongV_ ? fixed_ : x, v = alongV_ ? x : fixed_;
    surface_->checkPoint(face_, u, v);
    // The patch of the last point holds x too when x is in its square's span [lo, hi) (the
    // quadtree sends a point on a split to the upper half; hi = 1 is closed): PatchMap would
    // find the same patch.
    if (!(patch_ && x >= lo_ && (x < hi_ || (x == hi_ && hi_ == real(1))))) {
        const Far::PatchTable::PatchHandle* h = surface_->map_->FindPatch(face_, static_cast<double>(u), static_cast<double>(v));
        if (!h) surface_->holeError(face_);
        if (h != patch_) collapse(*h);
    }
    if (!regular_) return false;
    const real s = x * scale_ - offset_; // dmPatchLocal: exact
    const glm::vec<4, real> b = kern::dmFoldBoundary(kern::dmBSpline3(s), low_, high_);
    const glm::vec<4, real> db = kern::dmFoldBoundary(kern::dmBSpline3D1(s), low_, high_) * scale_;
    out = BaseSample<real>{};
    vec3 along(0), across(0);
    for (int k = 0; k < 4; ++k) {
        out.p += b[k] * q_[k];
        along += db[k] * q_[k];
        across += b[k] * qd_[k];
    }
    out.du = alongV_ ? across : along;
    out.dv = alongV_ ? along : across;
    return true;
}

namespace detail {
/// The vertex type OpenSubdiv's primvar refiner and stencils interpolate.
struct OsdPoint {
    glm::dvec3 p{0};
    void Clear(void* = nullptr) { p = glm::dvec3(0); }
    void AddWithWeight(const OsdPoint& src, double w) { p += w * src.p; }
};
} // namespace detail

template <> inline const std::vector<glm::dvec3>& BaseSurface::points<double>() const { return pointsD_; }
template <> inline const std::vector<glm::vec3>& BaseSurface::points<float>() const { return pointsF_; }

inline BaseSurface::BaseSurface(const ControlMesh& mesh, BaseSurfaceOptions options)
    : options_(options), faceCount_(mesh.ptexFaceCount()), topology_(mesh), name_(mesh.description().name),
      topologyHash_(dispmap::topologyHash(mesh)) {
    if (options.isolationLevel < 1 || options.isolationLevel > 10)
        throw ArgumentError("isolation level " + std::to_string(options.isolationLevel) + " out of range [1, 10]");
    refiner_ = mesh.createRefiner();
    // Sharp features to the level where the semi-sharp ones have decayed, smooth irregular
    // ones (extraordinary vertices) to the caller's level (OpenSubdiv's secondary level).
    float sharpest = 0.0f;
    const Far::TopologyLevel& level0 = refiner_->GetLevel(0);
    for (int e = 0; e < level0.GetNumEdges(); ++e) {
        const float s = level0.GetEdgeSharpness(e);
        if (Sdc::Crease::IsSemiSharp(s)) sharpest = std::max(sharpest, s);
    }
    for (int v = 0; v < level0.GetNumVertices(); ++v) {
        const float s = level0.GetVertexSharpness(v);
        if (Sdc::Crease::IsSemiSharp(s)) sharpest = std::max(sharpest, s);
    }
    const int sharpLevel = std::min(10, static_cast<int>(std::ceil(sharpest)));
    const int maxLevel = std::max(options.isolationLevel, sharpLevel);
    Far::PatchTableFactory::Options po(static_cast<unsigned>(maxLevel));
    po.SetEndCapType(options.gregoryEndCaps ? Far::PatchTableFactory::Options::ENDCAP_GREGORY_BASIS
                                            : Far::PatchTableFactory::Options::ENDCAP_BSPLINE_BASIS);
    po.SetPatchPrecision<double>();
    po.useInfSharpPatch = true;
    po.generateVaryingTables = false;
    po.generateVaryingLocalPoints = false;
    adaptive_ = po.GetRefineAdaptiveOptions();
    adaptive_.SetSecondaryLevel(options.isolationLevel);
    refiner_->RefineAdaptive(adaptive_);
    table_.reset(Far::PatchTableFactory::Create(*refiner_, po));
    if (!table_) throw MeshError(name_ + ": OpenSubdiv could not build a patch table");
    map_ = std::make_unique<Far::PatchMap>(*table_);

    refinePoints(mesh.description().positions, true); // the patch table and the points hold all evaluation needs

    // Holes: Ptex faces without patches.
    hole_.assign(static_cast<std::size_t>(faceCount_), 1);
    for (int a = 0; a < table_->GetNumPatchArrays(); ++a)
        for (int i = 0; i < table_->GetNumPatches(a); ++i) {
            const int f = table_->GetPatchParam(a, i).GetFaceId();
            if (f >= 0 && f < faceCount_) hole_[static_cast<std::size_t>(f)] = 0;
        }

    // Extraordinary corners (fixed by the topology) and their limit normals (moved by
    // setControlPoints).
    evCorner_.assign(static_cast<std::size_t>(faceCount_), {0, 0, 0, 0});
    for (int f = 0; f < faceCount_; ++f) {
        if (isHole(f)) continue;
        for (int c = 0; c < 4; ++c)
            evCorner_[static_cast<std::size_t>(f)][static_cast<std::size_t>(c)] =
                topology_.kind(topology_.cornerVertex(f, c)) == TileTopology::VertexKind::Constrained ? 1 : 0;
    }
    computeCornerNormals();
    computeSharpMasks(mesh);
}

inline void BaseSurface::computeSharpMasks(const ControlMesh& mesh) {
    const Far::TopologyLevel& L = mesh.base();
    const int nv = L.GetNumVertices(), ne = L.GetNumEdges();
    auto sharpEdge = [&](int e) { return L.IsEdgeInfSharp(e) && !L.IsEdgeBoundary(e); };
    std::vector<std::uint8_t> touched(static_cast<std::size_t>(nv), 0);
    for (int v = 0; v < nv; ++v) {
        bool t = L.IsVertexInfSharp(v) && L.GetVertexFaces(v).size() >= 2;
        for (int e : L.GetVertexEdges(v)) t = t || sharpEdge(e);
        touched[static_cast<std::size_t>(v)] = t ? 1 : 0;
    }
    // The base edge a tile edge lies on (TileTopology's vertex ids: base vertices, then edge
    // midpoints nv + e, then face centres), or -1 for a spoke inside an N-gon.
    auto baseEdge = [&](int a, int b) {
        if (a < nv && b < nv) return static_cast<int>(L.FindEdge(a, b));
        if (a < nv && b < nv + ne) return b - nv;
        if (b < nv && a < nv + ne) return a - nv;
        return -1;
    };
    sharp_.assign(static_cast<std::size_t>(faceCount_), 0);
    for (int f = 0; f < faceCount_; ++f) {
        int m = 0;
        for (int c = 0; c < 4; ++c) {
            const int a = topology_.cornerVertex(f, c), b = topology_.cornerVertex(f, (c + 1) & 3);
            const int e = baseEdge(a, b);
            if (e >= 0 && sharpEdge(e)) m |= 1 << c;
            if (a < nv && touched[static_cast<std::size_t>(a)]) m |= 16 << c;
        }
        sharp_[static_cast<std::size_t>(f)] = static_cast<std::uint8_t>(m);
    }
}

inline void BaseSurface::refinePoints(const std::vector<glm::dvec3>& positions, bool dropLevels) {
    // Refined vertices of all levels, then the local points of the end caps.
    const int total = refiner_->GetNumVerticesTotal();
    std::vector<detail::OsdPoint> pts(static_cast<std::size_t>(total + table_->GetNumLocalPoints()));
    for (std::size_t i = 0; i < positions.size(); ++i) pts[i].p = positions[i];
    Far::PrimvarRefinerReal<double> primvar(*refiner_);
    detail::OsdPoint* src = pts.data();
    for (int level = 1; level < refiner_->GetNumLevels(); ++level) {
        detail::OsdPoint* dst = src + refiner_->GetLevel(level - 1).GetNumVertices();
        primvar.Interpolate(level, src, dst);
        src = dst;
    }
    if (table_->GetNumLocalPoints() > 0)
        table_->GetLocalPointStencilTable<double>()->UpdateValues(pts.data(), pts.data() + total);
    if (dropLevels) {
        refinedVertexCount_ = total;
        refiner_->Unrefine();
    }
    pointsD_.clear();
    pointsF_.clear();
    pointsD_.reserve(pts.size());
    pointsF_.reserve(pts.size());
    for (const detail::OsdPoint& q : pts) {
        pointsD_.push_back(q.p);
        pointsF_.push_back(glm::vec3(q.p));
    }
}

inline void BaseSurface::computeCornerNormals() {
    // Gregory end caps interpolate the limit position and tangents at a patch corner, so
    // s_u x s_v there is the limit normal; B-spline end caps approximate it.
    cornerNormal_.assign(static_cast<std::size_t>(faceCount_), {});
    for (int f = 0; f < faceCount_; ++f) {
        if (isHole(f)) continue;
        for (int c = 0; c < 4; ++c) {
            const glm::dvec2 uv = TileTopology::cornerUV(c);
            const BaseSample<double> s = evaluate<double>(f, uv.x, uv.y, true);
            const glm::dvec3 fallback(0, 0, 1);
            cornerNormal_[static_cast<std::size_t>(f)][static_cast<std::size_t>(c)] =
                kern::dmBaseNormal(s.du, s.dv, s.duu, s.duv, s.dvv, uv, fallback);
        }
    }
}

inline void BaseSurface::setControlPoints(const std::vector<glm::dvec3>& positions) {
    if (static_cast<int>(positions.size()) != controlPointCount())
        throw ArgumentError(name_ + ": " + std::to_string(positions.size()) + " control points given, the mesh has " +
                            std::to_string(controlPointCount()));
    for (std::size_t i = 0; i < positions.size(); ++i)
        if (!std::isfinite(positions[i].x) || !std::isfinite(positions[i].y) || !std::isfinite(positions[i].z))
            throw ArgumentError(name_ + ": control point " + std::to_string(i + 1) + " has a NaN or infinite coordinate");
    if (!refined_) { // once: the same options on the same base level give the same levels
        refiner_->Unrefine();
        refiner_->RefineAdaptive(adaptive_);
        if (refiner_->GetNumVerticesTotal() != refinedVertexCount_) {
            const int got = refiner_->GetNumVerticesTotal();
            refiner_->Unrefine();
            throw MeshError(name_ + ": refining the topology again gave " + std::to_string(got) +
                            " vertices, the patch table was built from " + std::to_string(refinedVertexCount_));
        }
        refined_ = true;
    }
    refinePoints(positions, false);
    computeCornerNormals();
}

template <typename real> void BaseSurface::checkPoint(int face, real u, real v) const {
    checkedFace(face);
    if (!(u >= real(0) && u <= real(1) && v >= real(0) && v <= real(1)))
        throw ArgumentError(name_ + ": (u, v) = (" + std::to_string(static_cast<double>(u)) + ", " +
                            std::to_string(static_cast<double>(v)) + ") of face " + std::to_string(face) +
                            " is not in [0, 1]^2");
}

template <typename real> const Far::PatchTable::PatchHandle& BaseSurface::findPatch(int face, real u, real v) const {
    checkPoint(face, u, v);
    const Far::PatchTable::PatchHandle* h = map_->FindPatch(face, static_cast<double>(u), static_cast<double>(v));
    if (!h) holeError(face);
    return *h;
}

template <typename real> BaseSample<real> BaseSurface::evaluate(int face, real u, real v, bool second) const {
    return evaluateIn(findPatch(face, u, v), face, u, v, second);
}

template <typename real> bool BaseSurface::endCapCorners(int face, real u, real v, EndCapCorners<real>& out) const {
    const Far::PatchTable::PatchHandle& h = findPatch(face, u, v);
    const Far::PatchParam param = table_->GetPatchParam(h);
    if (param.IsRegular()) return false;
    const real frac = static_cast<real>(param.GetParamFraction());
    const real u0 = static_cast<real>(param.GetU()) * frac, v0 = static_cast<real>(param.GetV()) * frac;
    out.local = glm::vec<2, real>((u - u0) / frac, (v - v0) / frac);
    const glm::dvec2 centre(double(u0) + 0.5 * double(frac), double(v0) + 0.5 * double(frac));
    for (int c = 0; c < 4; ++c) {
        const glm::vec<2, real> uv(u0 + (c == 1 || c == 2 ? frac : real(0)), v0 + (c >= 2 ? frac : real(0)));
        out.uv[c] = uv;
        // Each corner from the patch beyond it (half a patch outwards, clamped to the face):
        // at the corners away from the extraordinary vertex that is, at isolation 2 and more and
        // away from other features, a regular B-spline patch, whose derivatives (second ones
        // included) agree with those of the face across the edge; the end cap's own Gregory
        // derivatives there agree only to first order and, in float, to the rounding of a
        // 2^-level patch. (Where it is another end cap, or a finer patch of a semi-sharp crease,
        // the corner is evaluated in that patch: still one value for both faces of the edge.)
        const glm::dvec2 q = glm::clamp(2.0 * glm::dvec2(uv) - centre, glm::dvec2(0.0), glm::dvec2(1.0));
        const Far::PatchTable::PatchHandle* beyond = map_->FindPatch(face, q.x, q.y);
        out.corner[c] = evaluateIn(beyond ? *beyond : h, face, uv.x, uv.y, true);
    }
    return true;
}

template <typename real>
BaseSample<real> BaseSurface::evaluateIn(const Far::PatchTable::PatchHandle& patch, int face, real u, real v, bool second) const {
    const Far::PatchTable::PatchHandle* h = &patch;
    real w[20], wu[20], wv[20], wuu[20], wuv[20], wvv[20];
    if (second)
        table_->EvaluateBasis(*h, u, v, w, wu, wv, wuu, wuv, wvv);
    else
        table_->EvaluateBasis(*h, u, v, w, wu, wv);
    const Far::ConstIndexArray cv = table_->GetPatchVertices(*h);
    const std::vector<glm::vec<3, real>>& P = points<real>();
    BaseSample<real> s;
    const int n = cv.size();
    for (int i = 0; i < n; ++i) {
        const glm::vec<3, real>& x = P[static_cast<std::size_t>(cv[i])];
        s.p += w[i] * x;
        s.du += wu[i] * x;
        s.dv += wv[i] * x;
    }
    if (second)
        for (int i = 0; i < n; ++i) {
            const glm::vec<3, real>& x = P[static_cast<std::size_t>(cv[i])];
            s.duu += wuu[i] * x;
            s.duv += wuv[i] * x;
            s.dvv += wvv[i] * x;
        }
    const Far::PatchParam param = table_->GetPatchParam(*h);
    if (param.NonQuadRoot()) {
        // EvaluateBasis scales derivatives by 2^depth, but a sub-face of an N-gon is already
        // a whole Ptex face at depth 1: its derivatives carry 2^(depth - 1).
        s.du *= real(0.5);
        s.dv *= real(0.5);
        s.duu *= real(0.25);
        s.duv *= real(0.25);
        s.dvv *= real(0.25);
    }
    // §5.4 blend data: only end-cap patches (irregular) that touch an extraordinary corner.
    if (!param.IsRegular() && !evCorner_.empty()) {
        const auto& ev = evCorner_[static_cast<std::size_t>(face)];
        if (ev[0] | ev[1] | ev[2] | ev[3]) {
            const real frac = static_cast<real>(param.GetParamFraction());
            const real u0 = static_cast<real>(param.GetU()) * frac, v0 = static_cast<real>(param.GetV()) * frac;
            const real lu = (u - u0) / frac, lv = (v - v0) / frac;
            const bool atU0 = param.GetU() == 0, atV0 = param.GetV() == 0;
            const bool atU1 = u0 + frac == real(1), atV1 = v0 + frac == real(1);
            const bool touches[4] = {atU0 && atV0, atU1 && atV0, atU1 && atV1, atU0 && atV1};
            const real weight[4] = {(1 - lu) * (1 - lv), lu * (1 - lv), lu * lv, (1 - lu) * lv};
            const auto& nrm = cornerNormal_[static_cast<std::size_t>(face)];
            for (int c = 0; c < 4; ++c)
                if (ev[static_cast<std::size_t>(c)] && touches[c]) {
                    s.endCap = true;
                    s.evWeight += weight[c];
                    s.evNormal += weight[c] * glm::vec<3, real>(nrm[static_cast<std::size_t>(c)]);
                }
        }
    }
    return s;
}

} // namespace dispmap
