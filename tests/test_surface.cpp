// The base surface (BaseSurface over OpenSubdiv's feature-adaptive patch table) and the
// displaced surface (DisplacedSurface): positions and normals against independent routes,
// derivatives against finite differences, continuity across every tile edge and at
// extraordinary vertices, auto normals, hard cases and bad inputs.
//
// Two regions behave differently and every check states which one it is about:
//  * regular patches (bicubic B-spline): exact limit surface, derivatives exact to rounding;
//  * end caps (Gregory basis, the 2^-isolation patches touching an extraordinary vertex):
//    an approximation of the limit surface that interpolates it at the patch corners, whose
//    derivatives are OpenSubdiv's pseudo-derivatives (Debian builds libosd without
//    OPENSUBDIV_GREGORY_EVAL_TRUE_DERIVATIVES: the rational terms are left out).
// Set DISPMAP_SURFACE_REPORT=1 to print the measured worst errors of every check.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "dispmap/scene/build.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/tile_builder.h"
#include "test_support.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_surface {

using namespace dispmap;
using glm::dvec2;
using glm::dvec3;

namespace {

// ---------------------------------------------------------------------------------------
// Helpers

bool reportOn() {
    static const bool on = std::getenv("DISPMAP_SURFACE_REPORT") != nullptr;
    return on;
}
template <typename... A> void report(const char* format, A... args) {
    if (reportOn()) {
        std::printf(format, args...);
        std::fflush(stdout);
    }
}

/// Every shape in tests/data with a manifold cage (catmark_fan is the non-manifold one the
/// mesh tests reject).
const std::vector<std::string>& allShapes() {
    static const std::vector<std::string> shapes = {
        "catmark_bishop",        "catmark_cube",          "catmark_cube_creases0", "catmark_dart_edgecorner",
        "catmark_edgecorner",    "catmark_flap",          "catmark_gregory_test2", "catmark_helmet",
        "catmark_hole_test1",    "catmark_nonquads",      "catmark_pole8",         "catmark_pyramid",
        "catmark_quadstrips",    "catmark_tent_creases0", "catmark_toroidal_tet",  "catmark_torus",
        "catmark_xord_boundary", "spot_control_mesh"};
    return shapes;
}

using dmtest::extentOf;
/// Sine of the angle between two directions (0 when either is zero).
double sinBetween(dvec3 a, dvec3 b) {
    const double la = glm::length(a), lb = glm::length(b);
    if (!(la > 0) || !(lb > 0)) return 0;
    return glm::length(glm::cross(a / la, b / lb));
}
/// Angle between two unit-ish vectors, robust near 0 and pi.
double angleBetween(dvec3 a, dvec3 b) {
    return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}
template <typename V> bool finite3(const V& v) {
    return std::isfinite(static_cast<double>(v.x)) && std::isfinite(static_cast<double>(v.y)) &&
           std::isfinite(static_cast<double>(v.z));
}

/// The patch of the base surface's table that evaluates (face, u, v).
Far::PatchParam patchAt(const BaseSurface& base, const Far::PatchMap& map, int face, double u, double v) {
    const Far::PatchTable::PatchHandle* h = map.FindPatch(face, u, v);
    REQUIRE(h != nullptr);
    return base.patchTable().GetPatchParam(*h);
}

/// Limit positions and tangents from Far::PrimvarRefiner::Limit after `level` uniform
/// refinement steps, and, for every vertex of that level, the Ptex locations (face, u, v)
/// where the base surface passes through its limit point (one per incident Ptex face).
/// The Ptex location of a refined vertex follows from the refinement: the child of corner
/// i sits at the corner, the child of edge i at the edge's midpoint, the child of the face
/// at its centre; an N-gon's child face k is Ptex sub-face k with corners (0,0) at vertex
/// k, (1,0) at the midpoint of edge k, (1,1) at the centre, (0,1) at the midpoint of edge
/// k - 1.
struct LimitReference {
    struct Sample {
        int vertex, face;
        double u, v;
    };
    std::unique_ptr<Far::TopologyRefiner> refiner;
    int level = 0;
    std::vector<dvec3> position, tan1, tan2;
    std::vector<Sample> samples;
    const Far::TopologyLevel& last() const { return refiner->GetLevel(level); }
};

LimitReference limitReference(const ControlMesh& mesh, int level) {
    REQUIRE(level >= 1); // N-gons become Ptex sub-faces at level 1
    LimitReference r;
    r.level = level;
    r.refiner = mesh.createRefiner();
    Far::TopologyRefiner::UniformOptions uo(level);
    uo.fullTopologyInLastLevel = true;
    r.refiner->RefineUniform(uo);
    const Far::TopologyRefiner& R = *r.refiner;
    std::vector<detail::OsdPoint> pts(static_cast<std::size_t>(R.GetNumVerticesTotal()));
    const auto& d = mesh.description();
    for (std::size_t i = 0; i < d.positions.size(); ++i) pts[i].p = d.positions[i];
    Far::PrimvarRefinerReal<double> primvar(R);
    detail::OsdPoint* src = pts.data();
    for (int l = 1; l <= level; ++l) {
        detail::OsdPoint* dst = src + R.GetLevel(l - 1).GetNumVertices();
        primvar.Interpolate(l, src, dst);
        src = dst;
    }
    const std::size_t n = static_cast<std::size_t>(R.GetLevel(level).GetNumVertices());
    std::vector<detail::OsdPoint> lp(n), lt1(n), lt2(n);
    primvar.Limit(src, lp, lt1, lt2);
    for (std::size_t i = 0; i < n; ++i) {
        r.position.push_back(lp[i].p);
        r.tan1.push_back(lt1[i].p);
        r.tan2.push_back(lt2[i].p);
    }

    // Faces of the current level with the Ptex (u, v) of their corners.
    struct Region {
        int face, ptex;
        std::array<dvec2, 4> uv;
    };
    const Far::TopologyLevel& L0 = R.GetLevel(0);
    std::vector<Region> regions;
    for (int f = 0; f < L0.GetNumFaces(); ++f)
        if (L0.GetFaceVertices(f).size() == 4)
            regions.push_back({f, mesh.ptex().GetFaceId(f), {dvec2(0, 0), dvec2(1, 0), dvec2(1, 1), dvec2(0, 1)}});
    for (int l = 0; l < level; ++l) {
        const Far::TopologyLevel& P = R.GetLevel(l);
        const Far::TopologyLevel& C = R.GetLevel(l + 1);
        std::vector<Region> next;
        for (const Region& q : regions) {
            // The 9 child vertices of the face and where they sit: corners, edge midpoints,
            // centre; each child face's corners are among them.
            const auto fv = P.GetFaceVertices(q.face);
            const auto fe = P.GetFaceEdges(q.face);
            std::array<int, 9> vtx{};
            std::array<dvec2, 9> at{};
            for (std::size_t i = 0; i < 4; ++i) {
                vtx[i] = P.GetVertexChildVertex(fv[static_cast<int>(i)]);
                at[i] = q.uv[i];
                vtx[4 + i] = P.GetEdgeChildVertex(fe[static_cast<int>(i)]);
                at[4 + i] = 0.5 * (q.uv[i] + q.uv[(i + 1) % 4]);
            }
            vtx[8] = P.GetFaceChildVertex(q.face);
            at[8] = 0.25 * (q.uv[0] + q.uv[1] + q.uv[2] + q.uv[3]);
            for (const int child : P.GetFaceChildFaces(q.face)) {
                Region c{child, q.ptex, {}};
                const auto cv = C.GetFaceVertices(child);
                for (int j = 0; j < 4; ++j) {
                    std::size_t i = 0;
                    while (i < 9 && vtx[i] != cv[j]) ++i;
                    REQUIRE(i < 9);
                    c.uv[static_cast<std::size_t>(j)] = at[i];
                }
                next.push_back(c);
            }
        }
        if (l == 0)
            for (int f = 0; f < L0.GetNumFaces(); ++f) {
                const auto fv = L0.GetFaceVertices(f);
                const auto fe = L0.GetFaceEdges(f);
                const int N = fv.size();
                if (N == 4) continue;
                // Each child face k: its own corner set (vertex k, edge k, centre, edge k - 1).
                const auto children = L0.GetFaceChildFaces(f);
                for (int k = 0; k < N; ++k) {
                    const std::array<int, 4> corner = {L0.GetVertexChildVertex(fv[k]), L0.GetEdgeChildVertex(fe[k]),
                                                       L0.GetFaceChildVertex(f), L0.GetEdgeChildVertex(fe[(k + N - 1) % N])};
                    const std::array<dvec2, 4> uv = {dvec2(0, 0), dvec2(1, 0), dvec2(1, 1), dvec2(0, 1)};
                    Region c{children[k], mesh.ptex().GetFaceId(f) + k, {}};
                    const auto cv = C.GetFaceVertices(children[k]);
                    for (int j = 0; j < 4; ++j) {
                        std::size_t i = 0;
                        while (i < 4 && corner[i] != cv[j]) ++i;
                        REQUIRE(i < 4);
                        c.uv[static_cast<std::size_t>(j)] = uv[i];
                    }
                    next.push_back(c);
                }
            }
        regions.swap(next);
    }
    const Far::TopologyLevel& T = R.GetLevel(level);
    for (const Region& q : regions) {
        const auto cv = T.GetFaceVertices(q.face);
        for (int j = 0; j < 4; ++j)
            r.samples.push_back({cv[j], q.ptex, q.uv[static_cast<std::size_t>(j)].x, q.uv[static_cast<std::size_t>(j)].y});
    }
    return r;
}

/// How a refined vertex sits in the surface, for the choice of tolerance.
struct VertexClass {
    bool semiSharpLeft = false;   ///< a semi-sharp edge or vertex sharpness not yet decayed here
    bool smoothCorner = false;    ///< boundary vertex of one face with edge-only interpolation
    bool extraordinary = false;   ///< interior valence != 4 or boundary vertex of 3+ faces
    bool boundary = false;
};
VertexClass classify(const ControlMesh& mesh, const Far::TopologyLevel& T, int v) {
    VertexClass c;
    const float vs = T.GetVertexSharpness(v);
    c.semiSharpLeft = Sdc::Crease::IsSemiSharp(vs);
    for (int e : T.GetVertexEdges(v))
        if (Sdc::Crease::IsSemiSharp(T.GetEdgeSharpness(e))) c.semiSharpLeft = true;
    c.boundary = T.IsVertexBoundary(v);
    const int nf = T.GetVertexFaces(v).size();
    c.smoothCorner = c.boundary && nf == 1 && !Sdc::Crease::IsInfinite(vs) &&
                     mesh.description().boundary == Sdc::Options::VTX_BOUNDARY_EDGE_ONLY;
    c.extraordinary = c.boundary ? nf > 2 : nf != 4;
    return c;
}

/// A smooth displacement with features at about a third of a face.
double waves(int face, double u, double v) {
    return std::sin(3.0 * u + 0.7 * face) * std::cos(2.5 * v - 0.3 * face) + 0.3 * std::sin(4.0 * u * v + face);
}

/// A base surface with tiles of size 2^k holding amplitude * waves.
struct Scene {
    ControlMesh mesh;
    BaseSurface base;
    TileSet tiles;
    double extent;
    Scene(ControlMesh m, double amplitude, int k = 4, BaseSurfaceOptions bo = {})
        : mesh(std::move(m)), base(mesh, bo),
          tiles(buildTiles(mesh, uniformTileSizes(mesh, k),
                           [amplitude](int f, double u, double v) { return amplitude * waves(f, u, v); })),
          extent(extentOf(mesh)) {}
};

/// 4th-order central difference weights at -2h, -h, h, 2h (exact for quartics).
constexpr double kD4[4] = {1.0 / 12.0, -8.0 / 12.0, 8.0 / 12.0, -1.0 / 12.0};
constexpr double kOff4[4] = {-2.0, -1.0, 1.0, 2.0};

/// Derivatives of a function of (u, v) by central differences: first and mixed with the
/// 4th-order stencil, pure second with the 3-point one. All of them are exact for bicubic
/// polynomials (the error terms hold 5th, 4th and (4th in one variable) derivatives), so
/// in a regular patch only rounding remains.
template <typename F> struct FiniteDiff {
    dvec3 du{0}, dv{0}, duu{0}, duv{0}, dvv{0};
    FiniteDiff(F f, double u, double v, double h) {
        const dvec3 c = f(u, v);
        for (int i = 0; i < 4; ++i) {
            du += kD4[i] * f(u + kOff4[i] * h, v);
            dv += kD4[i] * f(u, v + kOff4[i] * h);
            for (int j = 0; j < 4; ++j) duv += kD4[i] * kD4[j] * f(u + kOff4[i] * h, v + kOff4[j] * h);
        }
        du /= h;
        dv /= h;
        duv /= h * h;
        duu = (f(u + h, v) - 2.0 * c + f(u - h, v)) / (h * h);
        dvv = (f(u, v + h) - 2.0 * c + f(u, v - h)) / (h * h);
    }
};
template <typename F> FiniteDiff<F> finiteDiff(F f, double u, double v, double h) { return FiniteDiff<F>(f, u, v, h); }

} // namespace

// ---------------------------------------------------------------------------------------
// 1, 5. Limit positions and normals against Far::PrimvarRefiner::Limit

TEST_CASE("base surface: limit positions and normals equal PrimvarRefiner::Limit on every shape", "[surface]") {
    // The reference: Limit after L uniform steps gives the limit point and two tangents of
    // every level-L vertex; the base surface must pass through that point at each Ptex
    // location of the vertex (vertices of level L are the Ptex corners, edge midpoints,
    // centres, ... on the 2^-L grid of every face). Patch corners of both regular patches and
    // end caps lie on that grid (L <= isolation level), where both are exact.
    //
    // Tolerances (positions relative to the cage's bounding-box diagonal):
    //  * 1e-12 everywhere else: two double evaluations of the same limit (measured <= 3e-15).
    //  * Smooth corners (boundary vertex of one face, edge-only interpolation): Far's legacy
    //    sharp-corner patches (PatchTableFactory::Options::generateLegacySharpCornerPatches, on
    //    by default) put a regular corner patch there at the isolation level, so the corner
    //    is interpolated where the true surface passes 0.1 x 4^-level of the extent away
    //    (measured 0.108 x 4^-L on catmark_flap for L = 2, 4, 6, 8): allowed 0.25 x 4^-L.
    //  * Vertices with semi-sharp sharpness not yet decayed at level L are skipped: Limit's
    //    masks treat it as infinite (they are checked after more refinement in the next test).
    // Normals, sine of the angle between normalize(du x dv) and normalize(tan1 x tan2):
    //  * regular vertices: 1e-9 (measured <= 8e-13).
    //  * interior extraordinary vertices: 0.25 x 2.5^-level (1e-3 at the default level 6).
    //    Far's Gregory end caps do not interpolate the exact tangent plane at every
    //    extraordinary vertex: valence-3 vertices born from an N-gon or next to a decayed dart
    //    are off by up to 2.3e-3, 3.2e-4, 4.4e-5 at isolation 4, 6, 8 (catmark_cube_creases0;
    //    2.7x per level); Bfr with approximation level 10 agrees with Limit, not the end cap.
    //  * boundary extraordinary vertices: 5e-2. Sdc's tangent masks for boundary vertices of
    //    valence > 3 are not invariant under refinement: Limit's normal there changes with the
    //    level it is taken at (3.7e-2 between levels 2 and 6 at catmark_xord_boundary's
    //    valence-7 corner), and the end cap uses the masks at the isolation level. Limit taken
    //    at the isolation level matches the end cap to 1e-14 (checked below).
    // Orientation: tan1 x tan2 and du x dv point the same way, and du x dv at each Ptex face's
    // centre agrees with the winding of its control face (Newell normal).
    for (const std::string& name : allShapes()) {
        CAPTURE(name);
        const ControlMesh mesh = dmtest::shape(name);
        const BaseSurface base(mesh);
        const int L = mesh.ptexFaceCount() > 500 ? 1 : 2;
        const LimitReference ref = limitReference(mesh, L);
        const double ext = extentOf(mesh);
        const double cornerTol = 0.25 * std::pow(4.0, -base.options().isolationLevel);
        const double interiorTol = 0.25 * std::pow(2.5, -base.options().isolationLevel);
        double worstPos = 0, worstCorner = 0, worstReg = 0, worstInt = 0, worstBnd = 0;
        int compared = 0, skipped = 0, wrongWay = 0;
        for (const LimitReference::Sample& s : ref.samples) {
            if (base.isHole(s.face)) continue;
            const VertexClass c = classify(mesh, ref.last(), s.vertex);
            if (c.semiSharpLeft) {
                ++skipped;
                continue;
            }
            ++compared;
            CAPTURE(s.vertex, s.face, s.u, s.v);
            const BaseSample<double> b = base.evaluate<double>(s.face, s.u, s.v, false);
            const std::size_t v = static_cast<std::size_t>(s.vertex);
            const double dp = glm::length(b.p - ref.position[v]) / ext;
            if (c.smoothCorner) {
                worstCorner = std::max(worstCorner, dp);
                CHECK(dp <= cornerTol);
            } else {
                worstPos = std::max(worstPos, dp);
                CHECK(dp <= 1e-12);
            }
            const dvec3 nb = glm::cross(b.du, b.dv), nl = glm::cross(ref.tan1[v], ref.tan2[v]);
            REQUIRE(glm::length(nb) > 0);
            REQUIRE(glm::length(nl) > 0);
            if (glm::dot(nb, nl) <= 0) ++wrongWay;
            const double sn = sinBetween(nb, nl);
            if (!c.extraordinary) {
                worstReg = std::max(worstReg, sn);
                CHECK(sn <= 1e-9);
            } else if (!c.boundary) {
                worstInt = std::max(worstInt, sn);
                CHECK(sn <= interiorTol);
            } else {
                worstBnd = std::max(worstBnd, sn);
                CHECK(sn <= 5e-2);
            }
        }
        CHECK(wrongWay == 0);
        CHECK(compared > 0);
        // Winding: du x dv at the centre of every Ptex face against its control face.
        const auto& d = mesh.description();
        int windingWrong = 0;
        for (int f = 0; f < base.faceCount(); ++f) {
            if (base.isHole(f)) continue;
            const int baseFace = base.topology().baseFace(f);
            const int off = mesh.faceOffset(baseFace), size = d.faceSizes[static_cast<std::size_t>(baseFace)];
            dvec3 newell(0);
            for (int j = 0; j < size; ++j) {
                const dvec3 a = d.positions[static_cast<std::size_t>(d.faceVertices[static_cast<std::size_t>(off + j)])];
                const dvec3 b = d.positions[static_cast<std::size_t>(d.faceVertices[static_cast<std::size_t>(off + (j + 1) % size)])];
                newell += glm::cross(a, b);
            }
            const BaseSample<double> b = base.evaluate<double>(f, 0.5, 0.5, false);
            if (glm::dot(glm::cross(b.du, b.dv), newell) <= 0) ++windingWrong;
        }
        CHECK(windingWrong == 0);
        report("limit %-24s L=%d samples %6d skipped(semi-sharp) %4d  pos %.2e  smooth-corner pos %.2e (tol %.2e)  "
               "normal sin: regular %.2e interior-EV %.2e boundary-EV %.2e  wrong-way %d winding %d\n",
               name.c_str(), L, compared, skipped, worstPos, worstCorner, cornerTol, worstReg, worstInt, worstBnd, wrongWay,
               windingWrong);
    }
}

TEST_CASE("base surface: boundary extraordinary normals equal Limit taken at the isolation level", "[surface]") {
    // The explanation of the loose boundary tolerance above: the end cap's corner tangents
    // are Sdc's limit tangent masks applied at the isolation level, so Limit after that many
    // uniform steps must give the same normal (rounding only: 1e-12).
    // (Isolation level 3 here, so that Limit needs only three uniform steps.)
    for (const char* name : {"catmark_xord_boundary", "catmark_quadstrips"}) {
        CAPTURE(name);
        const ControlMesh mesh = dmtest::shape(name);
        BaseSurfaceOptions bo;
        bo.isolationLevel = 3;
        const BaseSurface base(mesh, bo);
        const int L = base.options().isolationLevel;
        const LimitReference ref = limitReference(mesh, L);
        const Far::TopologyLevel& T = ref.last();
        double worst = 0;
        int n = 0;
        for (const LimitReference::Sample& s : ref.samples) {
            const VertexClass c = classify(mesh, T, s.vertex);
            if (!c.extraordinary || !c.boundary) continue;
            CAPTURE(s.vertex, s.face, s.u, s.v);
            const BaseSample<double> b = base.evaluate<double>(s.face, s.u, s.v, false);
            const std::size_t v = static_cast<std::size_t>(s.vertex);
            const double sn = sinBetween(glm::cross(b.du, b.dv), glm::cross(ref.tan1[v], ref.tan2[v]));
            worst = std::max(worst, sn);
            CHECK(sn <= 1e-12);
            ++n;
        }
        report("limit@iso %-24s boundary-EV samples %d normal sin %.2e\n", name, n, worst);
    }
}

TEST_CASE("base surface: creases, corners and boundaries against Limit, no NaN", "[surface]") {
    // Semi-sharp creases decay by one per level; Limit is exact once they have (L = ceil of
    // the sharpness). The base surface isolates them that deep whatever its isolation level
    // (base_surface.h), so positions agree to rounding (1e-12 of the extent) also on creases
    // sharper than the isolation level (3 here): a cube with sharpness 5.5 creases and a 4.5
    // corner (Limit after 6 steps, compared on the 1/4 grid of each face; without the deeper
    // isolation its positions are off by 9e-3 of the extent).
    // Normals at regular vertices: 1e-9 (see above); at the crease vertices themselves the
    // Limit masks and the patches agree as well once the sharpness has decayed.
    const std::string sharpCube = "v -1 -1 1\nv 1 -1 1\nv -1 1 1\nv 1 1 1\nv -1 1 -1\nv 1 1 -1\nv -1 -1 -1\nv 1 -1 -1\n"
                                  "f 1 2 4 3\nf 3 4 6 5\nf 5 6 8 7\nf 7 8 2 1\nf 2 8 6 4\nf 7 1 3 5\n"
                                  "t crease 2/1/0 0 1 5.5\nt crease 2/1/0 1 3 5.5\nt corner 1/1/0 6 4.5\n";
    struct Case {
        std::string name;
        ControlMesh mesh;
        int level;
    };
    std::vector<Case> cases;
    for (const char* name : {"catmark_cube_creases0", "catmark_edgecorner", "catmark_xord_boundary", "catmark_tent_creases0",
                             "catmark_dart_edgecorner"})
        cases.push_back({name, dmtest::shape(name), 2});
    cases.push_back({"sharp cube", ControlMesh::fromObjText(sharpCube, "sharp cube"), 6});
    for (const Case& c : cases) {
        CAPTURE(c.name);
        BaseSurfaceOptions bo;
        bo.isolationLevel = 3; // below the sharp cube's creases
        const BaseSurface base(c.mesh, bo);
        const LimitReference ref = limitReference(c.mesh, c.level);
        const double ext = extentOf(c.mesh);
        double worst = 0, worstN = 0;
        int skipped = 0;
        for (const LimitReference::Sample& s : ref.samples) {
            if (std::fmod(4 * s.u, 1.0) != 0 || std::fmod(4 * s.v, 1.0) != 0) continue;
            const VertexClass vc = classify(c.mesh, ref.last(), s.vertex);
            if (vc.semiSharpLeft) {
                ++skipped;
                continue;
            }
            CAPTURE(s.vertex, s.face, s.u, s.v);
            const BaseSample<double> b = base.evaluate<double>(s.face, s.u, s.v, true);
            const std::size_t v = static_cast<std::size_t>(s.vertex);
            const double dp = glm::length(b.p - ref.position[v]) / ext;
            worst = std::max(worst, dp);
            CHECK(dp <= 1e-12);
            if (!vc.extraordinary) {
                const double sn = sinBetween(glm::cross(b.du, b.dv), glm::cross(ref.tan1[v], ref.tan2[v]));
                worstN = std::max(worstN, sn);
                CHECK(sn <= 1e-9);
            }
        }
        CHECK(skipped == 0);
        // No NaN on a dense grid, base and displaced, both modes, float and double.
        const TileSet tiles = buildTiles(c.mesh, uniformTileSizes(c.mesh, 3),
                                         [ext](int f, double u, double v) { return 0.05 * ext * waves(f, u, v); });
        const DisplacedSurface ds(base, tiles);
        int bad = 0;
        for (int f = 0; f < base.faceCount(); ++f)
            for (int j = 0; j <= 8; ++j)
                for (int i = 0; i <= 8; ++i) {
                    const double u = i / 8.0, v = j / 8.0;
                    for (NormalMode m : {NormalMode::Approximate, NormalMode::Accurate}) {
                        const SurfaceSample<double> d = ds.evaluate<double>(f, u, v, m);
                        const SurfaceSample<float> g =
                            ds.evaluate<float>(f, static_cast<float>(u), static_cast<float>(v), m);
                        if (!finite3(d.position) || !finite3(d.normal) || !finite3(g.position) || !finite3(g.normal)) ++bad;
                        if (std::abs(glm::length(d.normal) - 1.0) > 1e-12) ++bad;
                    }
                }
        CHECK(bad == 0);
        report("creases %-24s L=%d pos %.2e normal(regular) %.2e\n", c.name.c_str(), c.level, worst, worstN);
    }
}

// ---------------------------------------------------------------------------------------
// 2. Derivatives against finite differences of the evaluator; float against double

namespace {
/// Points inside the patches of a base surface: two per patch, at most `perMesh` patches
/// (evenly strided through the table), each with its patch's parameters.
struct PatchPoint {
    int face;
    double u, v;
    Far::PatchParam param;
    Far::PatchTable::PatchHandle handle;
};
std::vector<PatchPoint> patchPoints(const BaseSurface& base, int perMesh) {
    const Far::PatchTable& T = base.patchTable();
    int total = 0;
    for (int a = 0; a < T.GetNumPatchArrays(); ++a) total += T.GetNumPatches(a);
    const int stride = std::max(1, total / perMesh);
    std::vector<PatchPoint> out;
    int index = 0;
    const Far::PatchMap map(T);
    for (int a = 0; a < T.GetNumPatchArrays(); ++a)
        for (int i = 0; i < T.GetNumPatches(a); ++i, ++index) {
            if (index % stride != 0) continue;
            const Far::PatchParam pp = T.GetPatchParam(a, i);
            const int face = pp.GetFaceId();
            if (base.isHole(face)) continue;
            for (const dvec2 local : {dvec2(0.3, 0.6), dvec2(0.8, 0.15)}) {
                double u = local.x, v = local.y;
                pp.Unnormalize(u, v);
                const Far::PatchTable::PatchHandle* h = map.FindPatch(face, u, v);
                REQUIRE(h != nullptr);
                out.push_back({face, u, v, pp, *h});
            }
        }
    return out;
}
} // namespace

TEST_CASE("base surface: derivatives equal finite differences, exactly in regular patches", "[surface]") {
    // Central differences of evaluate<double>(...).p inside one patch, step h = 2% of the
    // patch (the stencil reaches 2h, the points sit >= 15% inside). The stencils are exact
    // for bicubics (see FiniteDiff), so in a regular patch only rounding is left:
    // eps |p| / h for first derivatives (relative to max(|s_u|, |s_v|): <= 1e-12 here) and
    // eps |p| / h^2 for second ones (relative to max(|s_u|, |s_v|) / patch size): 1e-9 and
    // 1e-7 are the tolerances (measured 4e-11 and 4e-9).
    // End caps: OpenSubdiv's pseudo-derivatives of the Gregory basis leave out the rational
    // terms, so they are not the derivatives of the evaluated positions; measured worst
    // relative errors 1.8% (first) and 6% (second; the lead measured up to 60% elsewhere).
    // Asserted loosely (10%, 100%): enough to catch a wrong scale (a factor 2 on an N-gon
    // sub-face is 100% on the first derivatives), not the approximation.
    double worst1[2] = {0, 0}, worst2[2] = {0, 0};
    int count[2] = {0, 0};
    for (const char* name : {"catmark_nonquads", "catmark_pole8", "catmark_xord_boundary", "catmark_cube_creases0",
                             "catmark_torus", "catmark_gregory_test2", "catmark_edgecorner", "spot_control_mesh"}) {
        CAPTURE(name);
        const ControlMesh mesh = dmtest::shape(name);
        const BaseSurface base(mesh);
        for (const PatchPoint& pt : patchPoints(base, 150)) {
            CAPTURE(pt.face, pt.u, pt.v, pt.param.GetDepth(), pt.param.NonQuadRoot());
            const int r = pt.param.IsRegular() ? 0 : 1;
            const double frac = static_cast<double>(pt.param.GetParamFraction()), h = 0.02 * frac;
            const BaseSample<double> s = base.evaluate<double>(pt.face, pt.u, pt.v, true);
            const auto fd = finiteDiff([&](double u, double v) { return base.evaluate<double>(pt.face, u, v, false).p; },
                                       pt.u, pt.v, h);
            const double scale1 = std::max(glm::length(s.du), glm::length(s.dv));
            const double scale2 = scale1 / frac;
            const double e1 = std::max(glm::length(s.du - fd.du), glm::length(s.dv - fd.dv)) / scale1;
            const double e2 =
                std::max({glm::length(s.duu - fd.duu), glm::length(s.duv - fd.duv), glm::length(s.dvv - fd.dvv)}) / scale2;
            worst1[r] = std::max(worst1[r], e1);
            worst2[r] = std::max(worst2[r], e2);
            ++count[r];
            CHECK(e1 <= (r == 0 ? 1e-9 : 0.1));
            CHECK(e2 <= (r == 0 ? 1e-7 : 1.0));
        }
    }
    CHECK(count[0] > 100);
    CHECK(count[1] > 100);
    report("fd regular: %d points, first %.2e second %.2e | end caps: %d points, first %.2e second %.2e\n", count[0],
           worst1[0], worst2[0], count[1], worst1[1], worst2[1]);
}

TEST_CASE("base surface: moved control points refine like a surface built from the moved cage", "[surface]") {
    // Animation (paper §4.1): setControlPoints reuses the patch table and patch map and refines
    // the topology again (the constructor drops the refined levels), so it must give what a new
    // BaseSurface of the moved mesh gives, bit for bit (the same stencils applied to the same
    // positions), on its first call and the next. Shapes: extraordinary vertices, N-gons,
    // boundaries, creases and corners, Gregory and B-spline end caps.
    for (const char* name : {"catmark_pole8", "catmark_nonquads", "catmark_edgecorner", "catmark_tent_creases0", "catmark_helmet"})
        for (bool gregory : {true, false}) {
            CAPTURE(name, gregory);
            const ControlMesh mesh = dmtest::shape(name);
            BaseSurfaceOptions o;
            o.gregoryEndCaps = gregory;
            BaseSurface animated(mesh, o);
            CHECK(animated.refiner().GetNumLevels() == 1); // a still surface holds the base level only
            MeshDescription moved = mesh.description();
            for (std::size_t v = 0; v < moved.positions.size(); ++v) {
                const double t = double(v);
                moved.positions[v] += dvec3(0.1 * std::sin(t), 0.07 * std::cos(1.3 * t), 0.05 * std::sin(0.7 * t + 1.0));
            }
            animated.setControlPoints(moved.positions);
            // An animated one keeps the levels the points come from.
            CHECK(static_cast<std::size_t>(animated.refiner().GetNumVerticesTotal() + animated.patchTable().GetNumLocalPoints()) ==
                  animated.points().size());
            const BaseSurface fresh(ControlMesh(moved), o);
            REQUIRE(animated.points() == fresh.points());
            for (int f = 0; f < fresh.faceCount(); ++f) {
                if (fresh.isHole(f)) continue;
                for (int c = 0; c < 4; ++c) CHECK(animated.cornerNormal(f, c) == fresh.cornerNormal(f, c));
                const BaseSample<double> a = animated.evaluate<double>(f, 0.3, 0.6), b = fresh.evaluate<double>(f, 0.3, 0.6);
                CHECK(a.p == b.p);
                CHECK(a.duv == b.duv);
                const BaseSample<float> af = animated.evaluate<float>(f, 0.3f, 0.6f), bf = fresh.evaluate<float>(f, 0.3f, 0.6f);
                CHECK(af.p == bf.p);
            }
            // And back: the original positions give the original surface.
            animated.setControlPoints(mesh.description().positions);
            CHECK(animated.points() == BaseSurface(mesh, o).points());
        }
    BaseSurface s(dmtest::shape("catmark_cube"));
    std::vector<dvec3> p = dmtest::shape("catmark_cube").description().positions;
    const std::vector<dvec3> before = s.points();
    CHECK_THROWS_WITH(s.setControlPoints(std::vector<dvec3>(p.begin(), p.end() - 1)), Catch::Contains("7 control points given, the mesh has 8"));
    p[3].y = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH(s.setControlPoints(p), Catch::Contains("control point 4 has a NaN or infinite coordinate"));
    CHECK(s.points() == before); // nothing changed
}

TEST_CASE("base surface: float evaluation against double", "[surface]") {
    // evaluate<float> rounds the control points once (relative eps_f / 2) and computes the
    // basis and the sums in float. Its error is bounded by K eps_f times the condition of
    // each sum, sum_i |w_i| |x_i| (the size of the terms that cancel), with the weights and
    // points of the patch in double; positions also carry |s_u| |du| for the rounding of the
    // local parameter, derivatives the same with the next derivative. K = 8 (measured
    // worst 1.9 for positions, 0.9 for derivatives): rounding of 16 or 20 points, of their
    // weights and of one running sum.
    const double epsF = std::numeric_limits<float>::epsilon();
    double worst[3] = {0, 0, 0};
    for (const char* name : {"catmark_nonquads", "catmark_pole8", "catmark_xord_boundary", "catmark_torus", "spot_control_mesh"}) {
        CAPTURE(name);
        const ControlMesh mesh = dmtest::shape(name);
        const BaseSurface base(mesh);
        const Far::PatchTable& T = base.patchTable();
        const std::vector<dvec3>& P = base.points();
        for (const PatchPoint& pt : patchPoints(base, 200)) {
            const float uf = static_cast<float>(pt.u), vf = static_cast<float>(pt.v);
            const double u = uf, v = vf;
            CAPTURE(pt.face, u, v);
            const BaseSample<float> f = base.evaluate<float>(pt.face, uf, vf, true);
            const BaseSample<double> d = base.evaluate<double>(pt.face, u, v, true);
            const Far::PatchTable::PatchHandle* h = &pt.handle; // the float-rounded point is in the same patch
            double w[20], wu[20], wv[20], wuu[20], wuv[20], wvv[20];
            T.EvaluateBasis(*h, u, v, w, wu, wv, wuu, wuv, wvv);
            const auto cv = T.GetPatchVertices(*h);
            const double k1 = T.GetPatchParam(*h).NonQuadRoot() ? 0.5 : 1.0, k2 = k1 * k1;
            double c0 = 0, cu = 0, cv_ = 0, cuu = 0, cuv = 0, cvv = 0;
            for (int i = 0; i < cv.size(); ++i) {
                const double x = glm::length(P[static_cast<std::size_t>(cv[i])]);
                c0 += std::abs(w[i]) * x;
                cu += k1 * std::abs(wu[i]) * x;
                cv_ += k1 * std::abs(wv[i]) * x;
                cuu += k2 * std::abs(wuu[i]) * x;
                cuv += k2 * std::abs(wuv[i]) * x;
                cvv += k2 * std::abs(wvv[i]) * x;
            }
            const double lu = glm::length(d.du) + glm::length(d.dv);
            const double luu = glm::length(d.duu) + glm::length(d.duv) + glm::length(d.dvv);
            const double e0 = glm::length(dvec3(f.p) - d.p) / (epsF * (c0 + lu));
            const double e1 = std::max(glm::length(dvec3(f.du) - d.du) / (epsF * (cu + luu)),
                                       glm::length(dvec3(f.dv) - d.dv) / (epsF * (cv_ + luu)));
            const double e2 = std::max({glm::length(dvec3(f.duu) - d.duu) / (epsF * (cuu + luu)),
                                        glm::length(dvec3(f.duv) - d.duv) / (epsF * (cuv + luu)),
                                        glm::length(dvec3(f.dvv) - d.dvv) / (epsF * (cvv + luu))});
            worst[0] = std::max(worst[0], e0);
            worst[1] = std::max(worst[1], e1);
            worst[2] = std::max(worst[2], e2);
            CHECK(e0 <= 8);
            CHECK(e1 <= 8);
            CHECK(e2 <= 8);
        }
    }
    report("float vs double, error / (eps_f x condition): position %.2f first %.2f second %.2f\n", worst[0], worst[1], worst[2]);
}

// ---------------------------------------------------------------------------------------
// 3. Normals against finite differences of the displaced position

namespace {
/// Points for finite differences of f = s + N D: inside a regular base patch and inside one
/// sub-patch of the tile (D is a quadratic spline, C1 only across its knots), with the step
/// h that keeps the 4th-order stencil (reach 2h) inside both. At most `perMesh` patches.
struct SmoothPoint {
    int face;
    double u, v, h;
};
std::vector<SmoothPoint> smoothPoints(const BaseSurface& base, const TileSet& tiles, int perMesh, bool regularOnly) {
    std::vector<SmoothPoint> out;
    for (const PatchPoint& pt : patchPoints(base, perMesh)) {
        if (regularOnly && !pt.param.IsRegular()) continue;
        const double frac = static_cast<double>(pt.param.GetParamFraction());
        double u0 = 0, v0 = 0;
        pt.param.Unnormalize(u0, v0);
        const double s = tiles.tiles[static_cast<std::size_t>(pt.face)].size();
        auto room = [&](double x, double lo) {
            const double inPatch = std::min(x - lo, lo + frac - x);
            const double knot = std::abs(x * s - std::round(x * s)) / s;
            return std::min(inPatch, knot);
        };
        const double h = std::min(room(pt.u, u0), room(pt.v, v0)) / 40.0;
        if (h < 1e-5) continue;
        out.push_back({pt.face, pt.u, pt.v, h});
    }
    return out;
}
} // namespace

TEST_CASE("displaced normals: accurate equals finite differences of f in regular patches", "[surface]") {
    // f(u, v) = evaluate<double>(...).position; its normal by 4th-order central differences
    // (step h inside one base patch and one tile sub-patch, where f is smooth) is the true
    // normal of the displaced surface to about h^4 f^(5) + eps |f| / h (h is 1/40 of the room
    // to the nearest patch edge or knot: 5e-8 rad of truncation at 1/12, 9e-10 at 1/40).
    //  * Accurate mode (s_u + N_u D + N D_u, N_u from the Weingarten equations) must equal it:
    //    1e-8 rad (measured 9.3e-10 worst).
    //  * Approximate mode drops N_u D: a model error, reported, not bounded; where it is large
    //    (> 1e-4 rad) the accurate normal must be at least 100 times closer.
    // Only regular patches: in end caps the normal is the §5.4 blend and the derivatives are
    // pseudo-derivatives, neither of which is the derivative of the evaluated f.
    double worstAcc = 0, worstApprox = 0, worstRatio = 0;
    int n = 0, large = 0;
    struct Case {
        const char* name;
        double amplitude; // relative to the extent
    };
    for (const Case c : {Case{"catmark_torus", 0.02}, Case{"catmark_torus", 0.2}, Case{"spot_control_mesh", 0.03},
                         Case{"catmark_nonquads", 0.05}, Case{"catmark_xord_boundary", 0.05}}) {
        CAPTURE(c.name, c.amplitude);
        const ControlMesh mesh = dmtest::shape(c.name);
        const double ext = extentOf(mesh);
        const Scene sc(mesh, c.amplitude * ext);
        const DisplacedSurface ds(sc.base, sc.tiles);
        for (const SmoothPoint& p : smoothPoints(sc.base, sc.tiles, 120, true)) {
            CAPTURE(p.face, p.u, p.v, p.h);
            const auto fd = finiteDiff([&](double u, double v) { return ds.evaluate<double>(p.face, u, v, NormalMode::Approximate).position; },
                                       p.u, p.v, p.h);
            const dvec3 nfd = glm::normalize(glm::cross(fd.du, fd.dv));
            const SurfaceSample<double> acc = ds.evaluate<double>(p.face, p.u, p.v, NormalMode::Accurate);
            const SurfaceSample<double> app = ds.evaluate<double>(p.face, p.u, p.v, NormalMode::Approximate);
            const double eAcc = angleBetween(acc.normal, nfd), eApp = angleBetween(app.normal, nfd);
            worstAcc = std::max(worstAcc, eAcc);
            worstApprox = std::max(worstApprox, eApp);
            CHECK(eAcc <= 1e-8);
            if (eApp > 1e-4) {
                ++large;
                worstRatio = std::max(worstRatio, eAcc / eApp);
                CHECK(eAcc * 100 <= eApp);
            }
            ++n;
        }
    }
    CHECK(n > 200);
    CHECK(large > 20);
    report("normals vs fd(f), regular patches: %d points; accurate %.2e rad, approximate %.2e rad; "
           "%d points with approx > 1e-4, accurate/approx <= %.2e\n",
           n, worstAcc, worstApprox, large, worstRatio);
}

TEST_CASE("base normal derivatives: Weingarten route = cross route = finite differences", "[surface]") {
    // N_u, N_v of N = normalize(s_u x s_v), three ways, double:
    //  * dmNormalDerivWeingarten and dmNormalDerivCross are the same function of
    //    (s_u, s_v, s_uu, s_uv, s_vv) in exact arithmetic, so they agree everywhere, end caps
    //    included, to rounding: 1e-10 relative (measured 8e-16).
    //  * 4th-order central differences of N in regular patches (N is smooth there; step 0.5%
    //    of the patch): 1e-7 relative (the truncation h^4 N^(5): 3e-6 at a 2% step, 1.3e-8
    //    at 0.5%). Relative to |N_u| + |N_v|, or where N is flat to |s_uu| / |s_u|.
    double worstRoutes = 0, worstFd = 0;
    int n = 0;
    for (const char* name : {"catmark_torus", "spot_control_mesh", "catmark_nonquads", "catmark_pole8", "catmark_xord_boundary"}) {
        CAPTURE(name);
        const ControlMesh mesh = dmtest::shape(name);
        const BaseSurface base(mesh);
        auto normal = [&](int f, double u, double v) {
            const BaseSample<double> s = base.evaluate<double>(f, u, v, true);
            return kern::dmBaseNormal(s.du, s.dv, s.duu, s.duv, s.dvv, glm::dvec2(u, v), dvec3(0, 0, 1));
        };
        for (const PatchPoint& pt : patchPoints(base, 150)) {
            CAPTURE(pt.face, pt.u, pt.v);
            const BaseSample<double> s = base.evaluate<double>(pt.face, pt.u, pt.v, true);
            const dvec3 N = normal(pt.face, pt.u, pt.v);
            dvec3 wu, wv, cu, cv;
            kern::dmNormalDerivWeingarten(s.du, s.dv, s.duu, s.duv, s.dvv, N, kSinMin<double>, wu, wv);
            kern::dmNormalDerivCross(s.du, s.dv, s.duu, s.duv, s.dvv, N, kSinMin<double>, cu, cv);
            // N_u's own size, or where it vanishes (flat), the size it has for unit curvature.
            const double scale = glm::length(wu) + glm::length(wv) +
                                 (glm::length(s.duu) + glm::length(s.duv) + glm::length(s.dvv)) /
                                     (glm::length(s.du) + glm::length(s.dv));
            const double eRoutes = (glm::length(wu - cu) + glm::length(wv - cv)) / scale;
            worstRoutes = std::max(worstRoutes, eRoutes);
            CHECK(eRoutes <= 1e-10);
            if (!pt.param.IsRegular()) continue;
            const double h = 0.005 * static_cast<double>(pt.param.GetParamFraction());
            const auto fd = finiteDiff([&](double u, double v) { return normal(pt.face, u, v); }, pt.u, pt.v, h);
            const double eFd = (glm::length(wu - fd.du) + glm::length(wv - fd.dv)) / scale;
            worstFd = std::max(worstFd, eFd);
            CHECK(eFd <= 1e-7);
            ++n;
        }
    }
    report("N_u: Weingarten vs cross %.2e, vs fd (%d regular points) %.2e\n", worstRoutes, n, worstFd);
}

TEST_CASE("base surface: closed form on a paraboloid", "[surface]") {
    // A grid of control points z = a i^2 + b j^2 + c i j: uniform cubic B-splines reproduce
    // quadratics, Σ B(t - i) i^2 = t^2 + 1/3, so away from the boundary the limit surface is
    // exactly s(x, y) = (x, y, a (x^2 + 1/3) + b (y^2 + 1/3) + c x y) with x = i + u, y = j + v
    // on the face with corner (i, j). Its normal N = (-z_x, -z_y, 1) / w and N_u = dN/dx,
    // N_v = dN/dy are known in closed form. Tolerances: rounding of a few terms of size
    // |z| <= 20: 1e-12 for positions and derivatives; 1e-12 relative for N, N_u.
    // With a constant displacement D the displaced surface is a parallel surface: its
    // accurate normal is N exactly (1e-12) wherever 1 - D k > 0 (here |D k| < 0.3), while
    // the approximate one ignores N_u and equals N as well (D_u = D_v = 0).
    const int n = 8;
    const double a = 0.0625, b = -0.03125, c = 0.015625; // the OBJ reader rounds to float: keep z exact
    std::string obj;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const double x = i - n / 2.0, y = j - n / 2.0;
            char line[128];
            std::snprintf(line, sizeof line, "v %.17g %.17g %.17g\n", x, y, a * x * x + b * y * y + c * x * y);
            obj += line;
        }
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const int v0 = j * (n + 1) + i + 1;
            obj += "f " + std::to_string(v0) + " " + std::to_string(v0 + 1) + " " + std::to_string(v0 + n + 2) + " " +
                   std::to_string(v0 + n + 1) + "\n";
        }
    const ControlMesh mesh = ControlMesh::fromObjText(obj, "paraboloid");
    const BaseSurface base(mesh);
    const double D0 = 0.5;
    const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 3), [D0](int, double, double) { return D0; });
    const DisplacedSurface ds(base, tiles);
    double worstP = 0, worstN = 0, worstNu = 0, worstDisp = 0;
    for (int fj = 1; fj < n - 1; ++fj)
        for (int fi = 1; fi < n - 1; ++fi) {
            const int face = fj * n + fi;
            for (int q = 0; q < 5; ++q) {
                const double u = 0.1 + 0.2 * q, v = 0.9 - 0.17 * q;
                CAPTURE(face, u, v);
                const double x = fi - n / 2.0 + u, y = fj - n / 2.0 + v;
                const double zx = 2 * a * x + c * y, zy = 2 * b * y + c * x;
                const dvec3 p(x, y, a * (x * x + 1.0 / 3) + b * (y * y + 1.0 / 3) + c * x * y);
                const dvec3 m(-zx, -zy, 1.0);
                const double w = glm::length(m);
                const dvec3 N = m / w;
                // d/dx of m / |m| with m_x = (-2a, -c, 0), m_y = (-c, -2b, 0).
                auto dN = [&](dvec3 mx) { return mx / w - m * (glm::dot(m, mx) / (w * w * w)); };
                const dvec3 Nx = dN(dvec3(-2 * a, -c, 0)), Ny = dN(dvec3(-c, -2 * b, 0));
                const BaseSample<double> s = base.evaluate<double>(face, u, v, true);
                worstP = std::max({worstP, glm::length(s.p - p), glm::length(s.du - dvec3(1, 0, zx)),
                                   glm::length(s.dv - dvec3(0, 1, zy)), glm::length(s.duu - dvec3(0, 0, 2 * a)),
                                   glm::length(s.duv - dvec3(0, 0, c)), glm::length(s.dvv - dvec3(0, 0, 2 * b))});
                const dvec3 Ns = kern::dmBaseNormal(s.du, s.dv, s.duu, s.duv, s.dvv, glm::dvec2(u, v), dvec3(0, 0, 1));
                dvec3 Nu, Nv;
                kern::dmNormalDerivWeingarten(s.du, s.dv, s.duu, s.duv, s.dvv, Ns, kSinMin<double>, Nu, Nv);
                worstN = std::max(worstN, glm::length(Ns - N));
                worstNu = std::max(worstNu, (glm::length(Nu - Nx) + glm::length(Nv - Ny)) / (glm::length(Nx) + glm::length(Ny)));
                for (NormalMode mode : {NormalMode::Accurate, NormalMode::Approximate}) {
                    const SurfaceSample<double> f = ds.evaluate<double>(face, u, v, mode);
                    worstDisp = std::max({worstDisp, glm::length(f.normal - N), glm::length(f.position - (p + D0 * N))});
                }
            }
        }
    CHECK(worstP <= 1e-12);
    CHECK(worstN <= 1e-12);
    CHECK(worstNu <= 1e-12);
    CHECK(worstDisp <= 1e-12);
    report("paraboloid: position/derivatives %.2e, N %.2e, N_u rel %.2e, displaced (D = %.1f) %.2e\n", worstP, worstN,
           worstNu, D0, worstDisp);
}

// ---------------------------------------------------------------------------------------
// 4. Continuity across every tile edge and at extraordinary vertices

namespace {
/// Worst differences between the two sides of the tile edges of one surface, split into
/// edges where both sides evaluate regular patches and edges touching an end cap.
struct EdgeStats {
    double basePos = 0, baseNormal = 0, dispPos = 0, approx = 0, accurate = 0;
    int samples = 0;
    void add(const EdgeStats& o) {
        basePos = std::max(basePos, o.basePos);
        baseNormal = std::max(baseNormal, o.baseNormal);
        dispPos = std::max(dispPos, o.dispPos);
        approx = std::max(approx, o.approx);
        accurate = std::max(accurate, o.accurate);
        samples += o.samples;
    }
};

/// Evaluates both sides of every linked tile edge at 9 points along the link.
std::array<EdgeStats, 2> edgeContinuity(const Scene& sc, const DisplacedSurface& ds) {
    std::array<EdgeStats, 2> st{};
    const BaseSurface& base = sc.base;
    const TileTopology& topo = base.topology();
    const Far::PatchMap map(base.patchTable());
    for (int t = 0; t < topo.tileCount(); ++t) {
        if (base.isHole(t)) continue;
        for (int e = 0; e < 4; ++e)
            for (const TileTopology::Link& l : topo.links(t, e)) {
                if (base.isHole(l.tile)) continue;
                // Spread along the link, and inside the end caps at either end (2^-level).
                const double ec = std::pow(0.5, base.options().isolationLevel);
                for (double q : {0.0, 0.3 * ec, 0.8 * ec, 0.137, 0.5, 0.861, 1 - 0.8 * ec, 1 - 0.3 * ec, 1.0}) {
                    const double y = l.y0 + q * (l.y1 - l.y0), z = l.alpha - l.beta * y;
                    const dvec2 a = dmtest::edgePoint(e, y), b = dmtest::edgePoint(l.edge, z);
                    CAPTURE(t, e, l.tile, l.edge, y, z);
                    const bool cap = !patchAt(base, map, t, a.x, a.y).IsRegular() ||
                                     !patchAt(base, map, l.tile, b.x, b.y).IsRegular();
                    EdgeStats& s = st[cap ? 1 : 0];
                    const BaseSample<double> sa = base.evaluate<double>(t, a.x, a.y, false);
                    const BaseSample<double> sb = base.evaluate<double>(l.tile, b.x, b.y, false);
                    s.basePos = std::max(s.basePos, glm::length(sa.p - sb.p) / sc.extent);
                    s.baseNormal = std::max(s.baseNormal, angleBetween(glm::cross(sa.du, sa.dv), glm::cross(sb.du, sb.dv)));
                    const SurfaceSample<double> pa = ds.evaluate<double>(t, a.x, a.y, NormalMode::Approximate);
                    const SurfaceSample<double> pb = ds.evaluate<double>(l.tile, b.x, b.y, NormalMode::Approximate);
                    const SurfaceSample<double> ca = ds.evaluate<double>(t, a.x, a.y, NormalMode::Accurate);
                    const SurfaceSample<double> cb = ds.evaluate<double>(l.tile, b.x, b.y, NormalMode::Accurate);
                    s.dispPos = std::max(s.dispPos, glm::length(pa.position - pb.position) / sc.extent);
                    s.approx = std::max(s.approx, angleBetween(pa.normal, pb.normal));
                    s.accurate = std::max(s.accurate, angleBetween(ca.normal, cb.normal));
                    ++s.samples;
                }
            }
    }
    return st;
}
} // namespace

TEST_CASE("continuity: positions and normals across every tile edge", "[surface]") {
    // Both sides of every tile edge (TileTopology links, quads, N-gon sub-faces, T-junctions)
    // at 5 points, with tiles of a displacement of 3% of the extent. Tolerances:
    //  * regular patches on both sides: the bicubic patches share their boundary curve and
    //    are C2 across it, D is C1 (its overlap texels are copies): rounding only. Positions
    //    1e-12 of the extent, normals (base, approximate, accurate) 1e-9 rad (measured 2e-16
    //    for positions, 2e-15 displaced, and 1.7e-13, 2.5e-13, 1.6e-12 rad).
    //  * an end cap on either side (points within 2^-level of an extraordinary vertex, both
    //    ends of every edge are sampled there): Far's Gregory end caps share their boundary
    //    curves and are G1 across them (on an edge the pseudo-derivatives equal the true
    //    ones: the rational terms carry a factor that vanishes there), so positions, base
    //    normals and displaced positions are continuous to rounding: 1e-12, 1e-9 rad, 1e-12
    //    (measured 2e-16, 7e-12, 8e-14). The end caps are G1 but not parametrically C1 (the
    //    cross-boundary derivatives of the two sides point up to 45 degrees apart,
    //    catmark_pole8), while D is C1 in the tile parameters, so each face's own derivatives
    //    would tilt the displaced normal differently on the two sides (up to 0.34 rad
    //    approximate, 0.52 rad accurate on spot with the earlier §5.4 blend). The displaced
    //    normal across an end cap is interpolated from its corners instead (dmEndCapNormal;
    //    the corners away from the vertex evaluated in the regular patches beyond them), so
    //    both sides of an edge out of the vertex interpolate the same two corner normals: the
    //    goal is 1e-3 rad; measured 1e-11 (approximate) and 2e-11 rad (accurate), rounding.
    std::array<EdgeStats, 2> all{};
    std::vector<std::pair<std::string, ControlMesh>> meshes;
    for (const char* name : {"catmark_nonquads", "catmark_pole8", "catmark_xord_boundary", "catmark_cube_creases0",
                             "catmark_toroidal_tet", "catmark_edgecorner", "catmark_gregory_test2", "catmark_torus",
                             "catmark_helmet", "spot_control_mesh"})
        meshes.emplace_back(name, dmtest::shape(name));
    for (int n = 3; n <= 12; ++n)
        for (bool closed : {false, true}) {
            const std::string name = "fan " + std::to_string(n) + (closed ? " closed" : " open");
            meshes.emplace_back(name, ControlMesh::fromObjText(dmtest::fanObj(n, closed), name));
        }
    for (const auto& [name, mesh] : meshes) {
        CAPTURE(name);
        const Scene sc(mesh, 0.03 * extentOf(mesh));
        const DisplacedSurface ds(sc.base, sc.tiles);
        const std::array<EdgeStats, 2> st = edgeContinuity(sc, ds);
        CHECK(st[0].basePos <= 1e-12);
        CHECK(st[0].baseNormal <= 1e-9);
        CHECK(st[0].dispPos <= 1e-12);
        CHECK(st[0].approx <= 1e-9);
        CHECK(st[0].accurate <= 1e-9);
        CHECK(st[1].basePos <= 1e-12);
        CHECK(st[1].baseNormal <= 1e-9);
        CHECK(st[1].dispPos <= 1e-12);
        CHECK(st[1].approx <= 1e-3);
        CHECK(st[1].accurate <= 1e-3);
        all[0].add(st[0]);
        all[1].add(st[1]);
        report("edges %-18s regular %5d: pos %.1e N %.1e f %.1e approx %.1e acc %.1e | end caps %5d: pos %.1e N %.1e f %.1e "
               "approx %.1e acc %.1e\n",
               name.c_str(), st[0].samples, st[0].basePos, st[0].baseNormal, st[0].dispPos, st[0].approx, st[0].accurate,
               st[1].samples, st[1].basePos, st[1].baseNormal, st[1].dispPos, st[1].approx, st[1].accurate);
    }
    CHECK(all[0].samples > 1000);
    CHECK(all[1].samples > 1000);
    report("edges, all meshes: regular %d samples: pos %.1e N %.1e f %.1e approx %.1e acc %.1e | end caps %d: pos %.1e N "
           "%.1e f %.1e approx %.1e acc %.1e\n",
           all[0].samples, all[0].basePos, all[0].baseNormal, all[0].dispPos, all[0].approx, all[0].accurate, all[1].samples,
           all[1].basePos, all[1].baseNormal, all[1].dispPos, all[1].approx, all[1].accurate);
}

TEST_CASE("continuity: extraordinary vertices of valence 3 to 12 agree from every face", "[surface]") {
    // At the centre of a fan of n quads every incident face evaluates the same point (1e-12
    // of the extent) and the same base normal (du x dv of the end caps, which interpolate the
    // limit tangent plane: 1e-12 rad). For n != 4 the §5.4 blend (weight 1 there) makes the
    // displaced normal of both modes the face's cornerNormal, the base limit normal, the same
    // from every face (1e-12 rad). n = 4 (a regular vertex, no blend) is the control: the
    // displaced normals still agree across the faces. Measured: 4e-15 of the extent, 1.1e-13
    // rad (base and displaced normals).
    double worstP = 0, worstN = 0, worstD = 0;
    for (int n = 3; n <= 12; ++n)
        for (bool closed : {false, true}) {
            const std::string name = "fan " + std::to_string(n) + (closed ? " closed" : " open");
            CAPTURE(name);
            const ControlMesh mesh = ControlMesh::fromObjText(dmtest::fanObj(n, closed), name);
            const Scene sc(mesh, 0.05 * extentOf(mesh));
            const DisplacedSurface ds(sc.base, sc.tiles);
            const auto& inc = sc.base.topology().incidences(0); // the centre vertex
            REQUIRE(static_cast<int>(inc.size()) == n);
            const dvec2 corner[4] = {dvec2(0, 0), dvec2(1, 0), dvec2(1, 1), dvec2(0, 1)};
            double p = 0, nb = 0, nd = 0;
            const auto [t0, c0] = inc[0];
            const BaseSample<double> b0 = sc.base.evaluate<double>(t0, corner[c0].x, corner[c0].y, false);
            const NormalMode modes[2] = {NormalMode::Approximate, NormalMode::Accurate};
            SurfaceSample<double> s0[2];
            for (int m = 0; m < 2; ++m) s0[m] = ds.evaluate<double>(t0, corner[c0].x, corner[c0].y, modes[m]);
            for (const auto& [t, c] : inc) {
                CAPTURE(t, c);
                CHECK(sc.base.isExtraordinaryCorner(t, c) == (n != 4));
                const dvec2 uv = corner[c];
                const BaseSample<double> b = sc.base.evaluate<double>(t, uv.x, uv.y, false);
                nb = std::max(nb, angleBetween(glm::cross(b.du, b.dv), glm::cross(b0.du, b0.dv)));
                for (int m = 0; m < 2; ++m) {
                    const SurfaceSample<double> s = ds.evaluate<double>(t, uv.x, uv.y, modes[m]);
                    p = std::max(p, glm::length(s.position - s0[m].position) / sc.extent);
                    nd = std::max(nd, angleBetween(s.normal, s0[m].normal));
                    if (n != 4) nd = std::max(nd, angleBetween(s.normal, sc.base.cornerNormal(t, c)));
                }
            }
            CHECK(p <= 1e-12);
            CHECK(nb <= 1e-12);
            CHECK(nd <= 1e-12);
            worstP = std::max(worstP, p);
            worstN = std::max(worstN, nb);
            worstD = std::max(worstD, nd);
        }
    report("EV valence 3..12: position %.2e, base normal %.2e rad, displaced normal %.2e rad\n", worstP, worstN, worstD);
}

// ---------------------------------------------------------------------------------------
// 6. Auto normals

TEST_CASE("auto normals: unmarked faces keep the promise; counts follow the tolerance", "[surface]") {
    // For every face auto mode evaluates approximately, the angle between the approximate and
    // the accurate normal must stay within the tolerance at every point of a 12 x 12 grid of
    // cell centres (points the 17 x 17 grid of the bound never sampled) and the 4 corners.
    // The bound is an estimate between its samples (displaced_surface.h), so this is the
    // promise checked, tolerance as given (measured worst ratio angle / tolerance below 1).
    // As the tolerance shrinks the number of accurate faces never falls and does grow; at
    // tolerance 0 exactly the faces with nonzero D and nonzero curvature are accurate.
    struct Case {
        const char* name;
        double amplitude;
        bool curvedEverywhere; // catmark_nonquads has flat faces
    };
    const double tolerances[] = {0.1, 0.03, 0.01, 0.003, 0.0};
    double worstRatio = 0;
    for (const Case c : {Case{"spot_control_mesh", 0.001, true}, Case{"catmark_pole8", 0.01, true},
                         Case{"catmark_nonquads", 0.003, false}, Case{"catmark_torus", 0.003, true}}) {
        CAPTURE(c.name, c.amplitude);
        const ControlMesh mesh = dmtest::shape(c.name);
        const Scene sc(mesh, c.amplitude * extentOf(mesh));
        int previous = -1, first = -1;
        for (double tol : tolerances) {
            CAPTURE(tol);
            DisplacedSurfaceOptions o;
            o.autoTolerance = tol;
            const DisplacedSurface ds(sc.base, sc.tiles, o);
            const int count = ds.autoAccurateCount();
            CHECK(count >= previous);
            if (first < 0) first = count;
            previous = count;
            int marked = 0;
            for (int f = 0; f < sc.base.faceCount(); ++f) {
                if (ds.autoFaces()[static_cast<std::size_t>(f)]) {
                    ++marked;
                    continue;
                }
                if (sc.base.isHole(f)) continue;
                for (int j = -1; j <= 12; ++j)
                    for (int i = -1; i <= 12; ++i) {
                        const bool edgeI = i < 0 || i == 12, edgeJ = j < 0 || j == 12;
                        if (edgeI != edgeJ) continue; // cell centres and the 4 corners
                        const double u = edgeI ? (i < 0 ? 0.0 : 1.0) : (i + 0.5) / 12, v = edgeJ ? (j < 0 ? 0.0 : 1.0) : (j + 0.5) / 12;
                        CAPTURE(f, u, v);
                        const SurfaceSample<double> a = ds.evaluate<double>(f, u, v, NormalMode::Approximate);
                        const SurfaceSample<double> b = ds.evaluate<double>(f, u, v, NormalMode::Accurate);
                        const SurfaceSample<double> m = ds.evaluate<double>(f, u, v, NormalMode::Auto);
                        CHECK(!m.accurate);
                        CHECK(m.normal == a.normal);
                        const double angle = angleBetween(a.normal, b.normal);
                        if (tol > 0) worstRatio = std::max(worstRatio, angle / tol);
                        CHECK(angle <= tol);
                    }
            }
            CHECK(marked == count);
            report("auto %-20s D %.3f x extent, tolerance %.3f: %d of %d faces accurate\n", c.name, c.amplitude, tol, count,
                   sc.base.faceCount());
        }
        CHECK(previous > first);
        // Tolerance 0: the faces left approximate have bit-identical normals in both modes
        // (checked above: angle <= 0); on meshes curved everywhere that is none of them.
        if (c.curvedEverywhere) CHECK(previous == sc.base.faceCount());
    }
    report("auto: worst angle / tolerance on unmarked faces %.3f\n", worstRatio);

    // A flat grid with one raised control vertex: only the 4 x 4 faces whose B-spline patch
    // holds that vertex are curved; at tolerance 0 exactly those are accurate (elsewhere
    // s_uu, s_uv, s_vv have zero height and N_u = N_v = 0 exactly), whatever D is. With D = 0
    // no face is.
    std::string grid = dmtest::gridObj(6, 6);
    const std::size_t at = grid.find("v 3 3 0\n");
    REQUIRE(at != std::string::npos);
    grid.replace(at, 8, "v 3 3 1\n");
    const ControlMesh bump = ControlMesh::fromObjText(grid, "bump grid");
    const BaseSurface base(bump);
    DisplacedSurfaceOptions zero;
    zero.autoTolerance = 0;
    for (double amplitude : {0.1, 0.0}) {
        CAPTURE(amplitude);
        const TileSet tiles = buildTiles(bump, uniformTileSizes(bump, 3),
                                         [amplitude](int f, double u, double v) { return amplitude * (1.0 + waves(f, u, v)); });
        const DisplacedSurface ds(base, tiles, zero);
        for (int f = 0; f < base.faceCount(); ++f) {
            const int i = f % 6, j = f / 6;
            const bool curved = i >= 1 && i <= 4 && j >= 1 && j <= 4;
            CAPTURE(f, i, j);
            CHECK((ds.autoFaces()[static_cast<std::size_t>(f)] != 0) == (curved && amplitude != 0));
        }
    }
}

// ---------------------------------------------------------------------------------------
// 7. Hard cases

namespace {
/// The cage scaled and stretched: x by sx, y and z by s.
ControlMesh transformed(const ControlMesh& m, double sx, double s, const std::string& name) {
    MeshDescription d = m.description();
    d.name = name;
    for (dvec3& p : d.positions) p = dvec3(p.x * sx, p.y * s, p.z * s);
    return ControlMesh(d);
}

/// Evaluates a 9 x 9 grid of every face in both modes, float and double; counts results
/// that are not finite or not unit normals (1e-12 double, 1e-5 float).
int countBad(const DisplacedSurface& ds) {
    int bad = 0;
    const BaseSurface& base = ds.base();
    for (int f = 0; f < base.faceCount(); ++f) {
        if (base.isHole(f)) continue;
        for (int j = 0; j <= 8; ++j)
            for (int i = 0; i <= 8; ++i) {
                const double u = i / 8.0, v = j / 8.0;
                for (NormalMode m : {NormalMode::Approximate, NormalMode::Accurate, NormalMode::Auto}) {
                    const SurfaceSample<double> d = ds.evaluate<double>(f, u, v, m);
                    const SurfaceSample<float> g = ds.evaluate<float>(f, static_cast<float>(u), static_cast<float>(v), m);
                    const bool ok = finite3(d.position) && finite3(d.normal) && finite3(d.du) && finite3(d.dv) &&
                                    finite3(g.position) && finite3(g.normal) && finite3(g.du) && finite3(g.dv) &&
                                    std::abs(glm::length(d.normal) - 1.0) <= 1e-12 &&
                                    std::abs(static_cast<double>(glm::length(g.normal)) - 1.0) <= 1e-5;
                    if (!ok) {
                        ++bad;
                        UNSCOPED_INFO("face " << f << " (" << u << ", " << v << ") mode " << toString(m));
                    }
                }
            }
    }
    return bad;
}
} // namespace

TEST_CASE("hard cases: tiny, thin, folded, valence 12: finite everywhere, unit normals", "[surface]") {
    // No NaN or Inf in positions, frames or normals, in any mode, float or double, and unit
    // normals (the kernels fall back to N_s where a frame degenerates, e.g. where a folding
    // displacement crosses the focal surface).
    const ControlMesh spot = dmtest::shape("spot_control_mesh");
    const double ext = extentOf(spot);
    struct Case {
        std::string name;
        ControlMesh mesh;
        double amplitude; // absolute
    };
    std::vector<Case> cases;
    // Tiny faces: the cage scaled by 1e-6 (float: |s_u x s_v| ~ 1e-12, squared 1e-24).
    cases.push_back({"spot x 1e-6", transformed(spot, 1e-6, 1e-6, "spot x 1e-6"), 0.02 * ext * 1e-6});
    // Long thin faces: a curved grid stretched 1e4 : 1.
    {
        std::string grid = dmtest::gridObj(5, 5);
        const std::size_t at = grid.find("v 2 2 0\n");
        REQUIRE(at != std::string::npos);
        grid.replace(at, 8, "v 2 2 1\n");
        const ControlMesh bump = ControlMesh::fromObjText(grid, "bump");
        cases.push_back({"thin 1e4:1", transformed(bump, 1e4, 1.0, "thin 1e4:1"), 0.3});
    }
    // A displacement far larger than the radius of curvature: the surface folds.
    cases.push_back({"spot, D = 2 x extent", dmtest::shape("spot_control_mesh"), 2.0 * ext});
    // Valence 12 at both poles of a closed fan, large displacement.
    cases.push_back({"fan 12 closed", ControlMesh::fromObjText(dmtest::fanObj(12, true), "fan 12"), 0.5});
    for (const Case& c : cases) {
        CAPTURE(c.name);
        const BaseSurface base(c.mesh);
        const double amp = c.amplitude;
        const TileSet tiles = buildTiles(c.mesh, uniformTileSizes(c.mesh, 3), [amp](int f, double u, double v) { return amp * waves(f, u, v); });
        const DisplacedSurface ds(base, tiles);
        CHECK(countBad(ds) == 0);
    }
}

TEST_CASE("hard cases: zero displacement gives the base normal exactly in both modes", "[surface]") {
    // D = D_u = D_v = 0: f_u = s_u + N_u 0 + N 0 = s_u bit for bit, so both modes compute
    // exactly dmBaseNormal's normal and f = s; in end caps at extraordinary corners (§5.4) the
    // interpolation of the base normals at the end cap's corners (BaseSurface::endCapCorners,
    // the limit normal at the extraordinary one) blended back to the point's own.
    for (const char* name : {"spot_control_mesh", "catmark_nonquads", "catmark_xord_boundary"}) {
        CAPTURE(name);
        const ControlMesh mesh = dmtest::shape(name);
        const BaseSurface base(mesh);
        const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 3), [](int, double, double) { return 0.0; });
        const DisplacedSurface ds(base, tiles);
        int bad = 0;
        for (int f = 0; f < base.faceCount(); ++f)
            for (int j = 0; j <= 6; ++j)
                for (int i = 0; i <= 6; ++i) {
                    const double u = i / 6.0, v = j / 6.0;
                    const BaseSample<double> s = base.evaluate<double>(f, u, v, true);
                    dvec3 N = kern::dmBaseNormal(s.du, s.dv, s.duu, s.duv, s.dvv, glm::dvec2(u, v), dvec3(0, 0, 1));
                    if (s.endCap) {
                        EndCapCorners<double> ec;
                        REQUIRE(base.endCapCorners(f, u, v, ec));
                        dvec3 n[4];
                        int ev = 0;
                        for (int c = 3; c >= 0; --c) {
                            const BaseSample<double>& k = ec.corner[c];
                            n[c] = kern::dmBaseNormal(k.du, k.dv, k.duu, k.duv, k.dvv, ec.uv[c], dvec3(0, 0, 1));
                            if (base.isExtraordinaryCorner(f, c) && ec.uv[c] == TileTopology::cornerUV(c)) {
                                n[c] = base.cornerNormal(f, c);
                                ev = c;
                            }
                        }
                        N = kern::dmEndCapNormal(n[0], n[1], n[2], n[3], ec.local, N, ev);
                    }
                    for (NormalMode m : {NormalMode::Approximate, NormalMode::Accurate}) {
                        const SurfaceSample<double> d = ds.evaluate<double>(f, u, v, m);
                        if (d.normal != N || d.position != s.p || d.displacement != dvec3(0)) {
                            ++bad;
                            UNSCOPED_INFO("face " << f << " (" << u << ", " << v << ") mode " << toString(m));
                        }
                    }
                }
        CHECK(bad == 0);
        CHECK(ds.autoAccurateCount() == 0);
    }
}

TEMPLATE_TEST_CASE("hard cases: near-singular first fundamental form in the normal kernels", "[surface]", float, double) {
    // s(u, v) = g(x, y) with g the graph z = (a x^2 + b y^2) / 2 + c x y and the skew map
    // x = u + v cos(theta), y = v sin(theta): s_u and s_v meet at the angle theta, while the
    // surface and its curvature stay the same, so the true N_u = N_x and N_v = cos N_x +
    // sin N_y stay bounded as theta -> 0 (the problem is ill-conditioned, the answer is not).
    // Inputs are rounded to the precision, the reference is the closed form in long double.
    //  * Above the floor (theta >= 1e-2 in float, 1e-6 in double; kSinMin is 1e-3 / 1e-7):
    //    relative error of N_u, N_v within 8 eps / sin(theta)^2 (the inputs' rounding is
    //    amplified by up to 1/sin^2 through EG - F^2 and the cancelling sum; measured worst
    //    1.1 in those units, float and double), for both dmNormalDerivWeingarten and
    //    dmNormalDerivCross.
    //  * Below the floor the first fundamental form is bounded, so |N_u| never exceeds 2x its
    //    largest value above the floor (measured 1.0x); everything is finite and the displaced
    //    normal is a unit vector (theta down to 1e-9 and exactly 0).
    using T = TestType;
    using vec3 = glm::vec<3, T>;
    const long double a = 0.8L, b = -0.5L, c = 0.3L, x0 = 0.4L, y0 = -0.7L;
    const long double zx = a * x0 + c * y0, zy = b * y0 + c * x0;
    const T eps = std::numeric_limits<T>::epsilon();
    const double floorTheta = std::is_same_v<T, float> ? 1e-2 : 1e-6;
    using lvec3 = glm::vec<3, long double>;
    auto dN = [&](lvec3 m, lvec3 mx) {
        const long double w = std::sqrt(glm::dot(m, m));
        return mx / w - m * (glm::dot(m, mx) / (w * w * w));
    };
    const lvec3 m(-zx, -zy, 1.0L);
    const lvec3 Nx = dN(m, lvec3(-a, -c, 0)), Ny = dN(m, lvec3(-c, -b, 0));
    double worstAbove = 0, maxAbove = 0, maxBelow = 0;
    for (int e = 1; e <= 10; ++e) {
        const long double theta = e == 10 ? 0.0L : std::pow(10.0L, -static_cast<long double>(e));
        CAPTURE(static_cast<double>(theta));
        const long double ct = std::cos(theta), st = std::sin(theta);
        const vec3 su(T(1), T(0), static_cast<T>(zx));
        const vec3 sv(static_cast<T>(ct), static_cast<T>(st), static_cast<T>(zx * ct + zy * st));
        const vec3 suu(T(0), T(0), static_cast<T>(a));
        const vec3 suv(T(0), T(0), static_cast<T>(a * ct + c * st));
        const vec3 svv(T(0), T(0), static_cast<T>(a * ct * ct + 2 * c * ct * st + b * st * st));
        const vec3 N = kern::dmBaseNormal(su, sv, suu, suv, svv, glm::vec<2, T>(T(0.5)), vec3(T(0), T(0), T(1)));
        REQUIRE(finite3(N));
        const lvec3 refU = Nx, refV = ct * Nx + st * Ny;
        for (int route = 0; route < 2; ++route) {
            CAPTURE(route);
            vec3 Nu, Nv;
            if (route == 0)
                kern::dmNormalDerivWeingarten(su, sv, suu, suv, svv, N, kSinMin<T>, Nu, Nv);
            else
                kern::dmNormalDerivCross(su, sv, suu, suv, svv, N, kSinMin<T>, Nu, Nv);
            REQUIRE(finite3(Nu));
            REQUIRE(finite3(Nv));
            const double size = std::max(glm::length(glm::dvec3(Nu)), glm::length(glm::dvec3(Nv)));
            if (static_cast<double>(theta) >= floorTheta) {
                const double err = std::max(glm::length(glm::dvec3(Nu) - glm::dvec3(refU)) / glm::length(glm::dvec3(refU)),
                                            glm::length(glm::dvec3(Nv) - glm::dvec3(refV)) / glm::length(glm::dvec3(refV)));
                const double units = err / (static_cast<double>(eps) / static_cast<double>(st * st));
                worstAbove = std::max(worstAbove, units);
                CHECK(units <= 8);
                maxAbove = std::max(maxAbove, size);
            } else {
                maxBelow = std::max(maxBelow, size);
            }
            vec3 fu, fv;
            const vec3 d1(T(0.2), T(0.5), T(-0.3));
            const vec3 n = kern::dmDisplacedNormalAccurate(su, sv, N, Nu, Nv, d1, fu, fv);
            REQUIRE(finite3(n));
            CHECK(std::abs(static_cast<double>(glm::length(n)) - 1.0) <= 4 * static_cast<double>(eps));
            const vec3 n2 = kern::dmDisplacedNormalApprox(su, sv, N, d1, fu, fv);
            CHECK(std::abs(static_cast<double>(glm::length(n2)) - 1.0) <= 4 * static_cast<double>(eps));
        }
    }
    CHECK(maxBelow <= 2 * maxAbove);
    report("near-singular (%s): worst error above the floor %.2f eps/sin^2; max |N_u| above %.3f below %.3f\n",
           std::is_same_v<T, float> ? "float" : "double", worstAbove, maxAbove, maxBelow);
}

// ---------------------------------------------------------------------------------------
// 8. Bad inputs

// ---------------------------------------------------------------------------------------
// Grid evaluation (a tessellation's inner grid): BaseSurface::Row, TileSet::Row and
// DisplacedSurface::evaluateGrid against the point-by-point routes they stand in for.

namespace {
/// Grid coordinates: both ends, the midpoint and quarter points (patch boundaries at every
/// isolation level, where PatchMap's rule picks the upper patch), points a rounding away from
/// them, and points in between.
template <typename real> std::vector<real> gridCoordinates() {
    std::vector<real> x = {real(0), real(1), real(0.5), real(0.25), real(0.75), std::nextafter(real(0.5), real(0)),
                           std::nextafter(real(0.25), real(1)), std::nextafter(real(1), real(0))};
    for (int i = 1; i < 12; ++i) x.push_back(real(i) / real(12) + real(0.0137) * real(i % 3));
    return x;
}
} // namespace

TEMPLATE_TEST_CASE("base surface rows and columns: each regular patch collapsed once per line equals evaluate() to rounding", "[surface][grid]",
                   float, double) {
    // BaseSurface::Row sums the same products as evaluate() (the basis of kernels/patch.h,
    // which is EvaluateBasis to a few ulps) in another order: v first, then u. Each result is
    // then within K eps of the condition of its sum, sum_i |w_i| |P_i| with Far's weights
    // (the size of the terms that cancel; float rounds the points once more, eps / 2 of the
    // same sum). K = 16: a 4-term and a 4-term sum with the basis's own rounding, in each of
    // the two routes. Measured worst: 3.6 (float) and 4.0 (double) for positions, 2.1 and 2.2
    // for derivatives (DISPMAP_SURFACE_REPORT=1 prints them). Where an end cap holds the
    // point, at() returns false and touches nothing.
    using real = TestType;
    const double eps = std::numeric_limits<real>::epsilon(), K = 16;
    double worst[2] = {0, 0};
    for (const bool gregory : {true, false})
        for (const std::string& name : allShapes()) {
            CAPTURE(name, gregory);
            BaseSurfaceOptions bo;
            bo.gregoryEndCaps = gregory;
            bo.isolationLevel = 3;
            const ControlMesh mesh = dmtest::shape(name);
            const BaseSurface base(mesh, bo);
            const Far::PatchTable& T = base.patchTable();
            const Far::PatchMap map(T);
            const std::vector<dvec3>& P = base.points();
            const std::vector<real> xs = gridCoordinates<real>();
            int regular = 0, endCaps = 0, failures = 0;
            for (int face = 0; face < base.faceCount(); ++face) {
                if (base.isHole(face)) continue;
                for (const bool alongV : {false, true})
                    for (const real fixed : xs) {
                        typename BaseSurface::Row<real> row(base, face, fixed, alongV);
                        for (const real x : xs) {
                            const real u = alongV ? fixed : x, v = alongV ? x : fixed;
                            const Far::PatchTable::PatchHandle* h = map.FindPatch(face, double(u), double(v));
                            REQUIRE(h != nullptr);
                            const Far::PatchParam param = T.GetPatchParam(*h);
                            BaseSample<real> got;
                            got.evWeight = real(-1); // untouched where false
                            if (!row.at(x, got)) {
                                ++endCaps;
                                CHECK(!param.IsRegular());
                                CHECK(got.evWeight == real(-1));
                                continue;
                            }
                            ++regular;
                            CHECK(param.IsRegular());
                            const BaseSample<real> want = base.evaluate<real>(face, u, v, false);
                            double w[20], wu[20], wv[20];
                            T.EvaluateBasis(*h, double(u), double(v), w, wu, wv);
                            const Far::ConstIndexArray cv = T.GetPatchVertices(*h);
                            const double fix = param.NonQuadRoot() ? 0.5 : 1.0; // Far's 2^depth on sub-faces (base_surface.h)
                            double c0 = 0, cu = 0, cvv = 0;
                            for (int i = 0; i < cv.size(); ++i) {
                                const double len = glm::length(P[static_cast<std::size_t>(cv[i])]);
                                c0 += std::abs(w[i]) * len;
                                cu += std::abs(wu[i]) * fix * len;
                                cvv += std::abs(wv[i]) * fix * len;
                            }
                            const double e0 = glm::length(dvec3(got.p) - dvec3(want.p)) / (eps * c0);
                            const double e1 = std::max(glm::length(dvec3(got.du) - dvec3(want.du)) / (eps * cu),
                                                       glm::length(dvec3(got.dv) - dvec3(want.dv)) / (eps * cvv));
                            worst[0] = std::max(worst[0], e0);
                            worst[1] = std::max(worst[1], e1);
                            const bool ok = e0 <= K && e1 <= K && got.duu == glm::vec<3, real>(0) && got.evWeight == real(0) && !got.endCap;
                            if (!ok && failures++ == 0) {
                                CAPTURE(face, u, v, alongV, e0, e1);
                                CHECK(ok);
                            }
                        }
                    }
            }
            CHECK(failures == 0);
            CHECK(regular > 0);
            bool irregular = false; // some shapes are regular patches throughout (boundaries and creases included)
            for (int a = 0; a < T.GetNumPatchArrays(); ++a)
                for (int i = 0; i < T.GetNumPatches(a); ++i) irregular = irregular || !T.GetPatchParam(a, i).IsRegular();
            CHECK((endCaps > 0) == irregular);
        }
    report("base surface rows (%s) vs evaluate, worst in eps of the sum's condition: positions %.2f, derivatives %.2f\n",
           sizeof(real) == 8 ? "double" : "float", worst[0], worst[1]);

    const ControlMesh holes = dmtest::shape("catmark_hole_test1");
    const BaseSurface base(holes);
    int hole = 0;
    while (!base.isHole(hole)) ++hole;
    const real nan = std::numeric_limits<real>::quiet_NaN();
    using Catch::Matchers::Contains;
    CHECK_THROWS_WITH((typename BaseSurface::Row<real>(base, hole, real(0.5))), Contains("is a hole"));
    CHECK_THROWS_WITH((typename BaseSurface::Row<real>(base, base.faceCount(), real(0.5))), Contains("out of range"));
    CHECK_THROWS_WITH((typename BaseSurface::Row<real>(base, 0, real(1.5))), Contains("is not in [0, 1]^2"));
    CHECK_THROWS_AS((typename BaseSurface::Row<real>(base, 0, nan)), ArgumentError);
    typename BaseSurface::Row<real> row(base, 0, real(0.5));
    BaseSample<real> s;
    CHECK_THROWS_WITH(row.at(real(-0.25), s), Contains("is not in [0, 1]^2"));
    CHECK_THROWS_AS(row.at(nan, s), ArgumentError);
    CHECK_THROWS_WITH((typename BaseSurface::Row<real>(base, 0, real(-0.5), true)), Contains("(-0.500000, 0.000000)"));
    typename BaseSurface::Row<real> column(base, 0, real(0.5), true);
    CHECK_THROWS_WITH(column.at(real(2), s), Contains("(0.500000, 2.000000)"));
}

TEMPLATE_TEST_CASE("tile rows and columns: three coefficient lines collapsed once per line equal evaluateD1 to rounding", "[surface][grid]", float,
                   double) {
    // TileSet::Row sums the 9 products of evaluateD1 across the line first, then along it
    // (evaluateD1: u first, then v). Each result is within
    // K eps of its condition, sum |w_ij| |c_ij| (the biquadratic weights, derivatives with the
    // level size s), K = 8 (two 3-term sums in each route, the basis rounded alike). Measured
    // worst: 2.7 (float) and 2.2 (double).
    using real = TestType;
    const double eps = std::numeric_limits<real>::epsilon(), K = 8;
    const ControlMesh mesh = dmtest::shape("catmark_nonquads");
    const TileSet tiles = buildTiles(mesh, mixedTileSizes(mesh, 5), dmtest::roughSource);
    const std::vector<real> xs = gridCoordinates<real>();
    double worst = 0;
    int failures = 0;
    for (int t = 0; t < tiles.tileCount(); ++t)
        for (int m = 0; m < tiles.tiles[static_cast<std::size_t>(t)].k; ++m)
            for (const bool alongV : {false, true}) {
                typename TileSet::Row<real> row(tiles, t, m, alongV);
                for (const real fixed : xs) {
                    row.setRow(fixed, xs);
                    for (const real x : xs) {
                        const real u = alongV ? fixed : x, v = alongV ? x : fixed;
                        const glm::vec<3, real> got = row.at(x), want = tiles.evaluateD1(t, m, glm::vec<2, real>(u, v));
                        glm::vec<2, real> tl;
                        real size;
                        const glm::mat<3, 3, real> c = tiles.subpatch(t, m, glm::vec<2, real>(u, v), tl, size);
                        const glm::dvec3 bu(kern::dmBSpline2(double(tl.x))), bv(kern::dmBSpline2(double(tl.y)));
                        const glm::dvec3 du(kern::dmBSpline2D1(double(tl.x))), dv(kern::dmBSpline2D1(double(tl.y)));
                        double c0 = 0, cu = 0, cv = 0;
                        for (int i = 0; i < 3; ++i)
                            for (int j = 0; j < 3; ++j) {
                                const double a = std::abs(double(c[i][j]));
                                c0 += std::abs(bu[i] * bv[j]) * a;
                                cu += std::abs(du[i] * bv[j]) * a * double(size);
                                cv += std::abs(bu[i] * dv[j]) * a * double(size);
                            }
                        const double e = std::max({std::abs(double(got.x) - double(want.x)) / (eps * c0 + 1e-300),
                                                   std::abs(double(got.y) - double(want.y)) / (eps * cu + 1e-300),
                                                   std::abs(double(got.z) - double(want.z)) / (eps * cv + 1e-300)});
                        worst = std::max(worst, e);
                        if (!(e <= K) && failures++ == 0) {
                            CAPTURE(t, m, u, v, alongV, e);
                            CHECK(e <= K);
                        }
                    }
                }
            }
    CHECK(failures == 0);
    report("tile rows (%s) vs evaluateD1, worst in eps of the sum's condition: %.2f\n", sizeof(real) == 8 ? "double" : "float", worst);
    using Catch::Matchers::Contains;
    typename TileSet::Row<real> row(tiles, 0, 0);
    CHECK_THROWS_WITH(row.at(real(0.5)), Contains("did not collapse")); // before setRow
    const std::vector<real> some = {real(0.25), real(0.3)};
    row.setRow(real(0.5), some);
    CHECK_NOTHROW(row.at(real(0.3)));
    CHECK_THROWS_WITH(row.at(real(0.9)), Contains("did not collapse"));
    typename TileSet::Row<real> column(tiles, 0, 0, true);
    column.setRow(real(0.5), some);
    CHECK_THROWS_WITH(column.at(real(0.9)), Contains("did not collapse"));
    CHECK_THROWS_AS(row.at(std::numeric_limits<real>::quiet_NaN()), ArgumentError);
    CHECK_THROWS_AS(row.setRow(std::numeric_limits<real>::infinity(), some), ArgumentError);
    const std::vector<real> nan = {std::numeric_limits<real>::quiet_NaN()};
    CHECK_THROWS_AS(row.setRow(real(0.5), nan), ArgumentError);
    CHECK_THROWS_AS((typename TileSet::Row<real>(tiles, tiles.tileCount(), 0)), std::out_of_range);
}

TEST_CASE("grid evaluation equals evaluate() to rounding, and is evaluate() itself off the row route", "[surface][grid]") {
    // evaluateGrid routes approximate normals in regular patches through the two rows above
    // (rows, or columns where the grid has more rows than columns, as a tile's edges u = 0 and
    // 1) and evaluates every other point with evaluate(): those must be equal bit for bit, the
    // line-routed ones to rounding. Bounds: positions 1e-13 of the mesh's extent (measured
    // worst 4.4e-15: the rows' rounding, a few eps of coordinates of size ~extent); normals
    // 1e-10 rad (measured 7.1e-13: the normal's rounding error grows with |D_u| / |s_u| and
    // with 1 / sin of the angle between s_u and s_v).
    double worstP = 0, worstN = 0;
    int lineRouted = 0, pointRouted = 0, rowPoints = 0, columnPoints = 0;
    std::vector<ControlMesh> meshes;
    for (const char* name : {"catmark_nonquads", "catmark_pole8", "catmark_xord_boundary", "catmark_edgecorner", "catmark_helmet",
                             "catmark_dart_edgecorner", "catmark_hole_test1", "spot_control_mesh"})
        meshes.push_back(dmtest::shape(name));
    // Infinitely sharp creases and corners: D fades towards them (the row route's D is feathered too).
    meshes.push_back(dmtest::withSharpFeatures(dmtest::shape("catmark_nonquads"), 3));
    int sharpFaces = 0;
    for (const ControlMesh& mesh : meshes)
        for (const bool mixed : {false, true}) {
            const std::string& name = mesh.description().name;
            CAPTURE(name, mixed);
            const double extent = extentOf(mesh);
            const BaseSurface base(mesh);
            for (int f = 0; f < base.faceCount(); ++f) sharpFaces += base.sharpMask(f) != 0 ? 1 : 0;
            const TileSet tiles = buildTiles(mesh, mixed ? mixedTileSizes(mesh, 4) : uniformTileSizes(mesh, 4), [extent](int f, double u, double v) {
                return 0.02 * extent * waves(f, u, v);
            });
            const DisplacedSurface surface(base, tiles);
            const std::vector<double> xs = gridCoordinates<double>(), few = {0.0, 0.3, 0.5, 0.61, 1.0};
            // Resolutions: the finest level, and blends of coarser ones varying over the grid.
            const auto rhoOf = [&](int which, std::size_t i, std::size_t j) {
                return which == 0 ? kFinest : 1.3 + 0.21 * double(i % 7) + 0.17 * double(j % 5);
            };
            for (const NormalMode mode : {NormalMode::Approximate, NormalMode::Accurate, NormalMode::Auto})
                for (int which : {0, 1}) {
                    CAPTURE(toString(mode), which);
                    int failures = 0;
                    for (int face = 0; face < base.faceCount(); ++face) {
                        if (base.isHole(face)) {
                            CHECK_THROWS_WITH(surface.evaluateGrid<double>(
                                                  face, xs, xs, mode, [](std::size_t, std::size_t) { return kFinest; },
                                                  [](std::size_t, std::size_t, const SurfaceSample<double>&) {}),
                                              Catch::Contains("is a hole"));
                            continue;
                        }
                        // Square grids go row by row; grids with more rows than columns (a
                        // tile's edge u = 0 or 1 among them) column by column.
                        for (const auto& [us, vs] : {std::pair(xs, xs), std::pair(few, xs), std::pair(std::vector<double>{1.0}, xs),
                                                     std::pair(xs, std::vector<double>{0.0})}) {
                            std::size_t expected = 0;
                            const bool columns = vs.size() > us.size();
                            surface.evaluateGrid<double>(
                                face, us, vs, mode, [&](std::size_t i, std::size_t j) { return rhoOf(which, i, j); },
                                [&](std::size_t i, std::size_t j, const SurfaceSample<double>& got) {
                                    const bool inOrder = (columns ? i * vs.size() + j : j * us.size() + i) == expected++;
                                    const double u = us[i], v = vs[j], rho = rhoOf(which, i, j);
                                    const SurfaceSample<double> want = surface.evaluate<double>(face, u, v, mode, rho);
                                    const bool same = got.position == want.position && got.normal == want.normal && got.du == want.du &&
                                                      got.dv == want.dv && got.baseNormal == want.baseNormal &&
                                                      got.displacement == want.displacement && got.accurate == want.accurate;
                                    // The line route: approximate normals in a regular patch.
                                    BaseSample<double> probe;
                                    typename BaseSurface::Row<double> row(base, face, v);
                                    const bool routed = !want.accurate && row.at(u, probe);
                                    ++(columns ? columnPoints : rowPoints);
                                    const double dp = glm::length(got.position - want.position) / extent,
                                                 dn = angleBetween(got.normal, want.normal);
                                    bool ok = inOrder && got.accurate == want.accurate;
                                    if (routed) {
                                        ++lineRouted;
                                        worstP = std::max(worstP, dp);
                                        worstN = std::max(worstN, dn);
                                        ok = ok && dp <= 1e-13 && dn <= 1e-10;
                                    } else {
                                        ++pointRouted;
                                        ok = ok && same;
                                    }
                                    if (!ok && failures++ == 0) {
                                        CAPTURE(face, u, v, rho, routed, dp, dn, inOrder);
                                        CHECK(ok);
                                    }
                                });
                            CHECK(expected == us.size() * vs.size());
                        }
                    }
                    CHECK(failures == 0);
                }
        }
    CHECK(lineRouted > 0);
    CHECK(pointRouted > 0);
    CHECK(rowPoints > 0);
    CHECK(columnPoints > 0);
    CHECK(sharpFaces > 0);
    report("grid evaluation vs evaluate: %d points by lines (worst position %.3g of the extent, normal %.3g rad), %d by points, equal\n",
           lineRouted, worstP, worstN, pointRouted);

    // Bad input: the first bad point of a row throws before any point of that row is delivered.
    const ControlMesh mesh = dmtest::shape("catmark_nonquads");
    const BaseSurface base(mesh);
    const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 3), dmtest::roughSource);
    const DisplacedSurface surface(base, tiles);
    const std::vector<double> good = {0.0, 0.5, 1.0}, bad = {0.0, 1.25, 0.5};
    int delivered = 0;
    auto count = [&](std::size_t, std::size_t, const SurfaceSample<double>&) { ++delivered; };
    auto finest = [](std::size_t, std::size_t) { return kFinest; };
    using Catch::Matchers::Contains;
    CHECK_THROWS_WITH(surface.evaluateGrid<double>(0, bad, good, NormalMode::Approximate, finest, count), Contains("(1.250000, 0.000000)"));
    CHECK(delivered == 0);
    CHECK_THROWS_WITH(surface.evaluateGrid<double>(0, good, bad, NormalMode::Accurate, finest, count), Contains("(0.000000, 1.250000)"));
    CHECK(delivered == 3); // the first row
    delivered = 0;
    CHECK_THROWS_WITH(surface.evaluateGrid<double>(0, good, good, NormalMode::Approximate,
                                                   [](std::size_t i, std::size_t) { return i == 2 ? std::nan("") : kFinest; }, count),
                      Contains("rho is NaN"));
    CHECK(delivered == 0);
    CHECK_THROWS_WITH(surface.evaluateGrid<double>(base.faceCount(), good, good, NormalMode::Auto, finest, count), Contains("out of range"));
    // A NaN rho is named before the point's bad coordinate, as evaluate() names it; no points, nothing to check.
    CHECK_THROWS_WITH(surface.evaluateGrid<double>(0, bad, good, NormalMode::Accurate, [](std::size_t, std::size_t) { return std::nan(""); }, count),
                      Contains("rho is NaN"));
    const std::vector<double> none;
    for (const NormalMode mode : {NormalMode::Approximate, NormalMode::Accurate}) {
        CHECK_NOTHROW(surface.evaluateGrid<double>(0, none, bad, mode, finest, count));
        CHECK_NOTHROW(surface.evaluateGrid<double>(0, bad, none, mode, finest, count));
    }
    CHECK(delivered == 0);
}

TEST_CASE("bad inputs: clear errors", "[surface]") {
    using Catch::Matchers::Contains;
    const ControlMesh mesh = dmtest::shape("catmark_hole_test1");
    const BaseSurface base(mesh);
    const int n = base.faceCount();
    const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 2), [](int, double u, double v) { return 0.1 * u * v; });
    const DisplacedSurface ds(base, tiles);
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();

    // Face ids.
    CHECK_THROWS_WITH(base.evaluate<double>(-1, 0.5, 0.5), Contains("face id -1 out of range [0, 6)"));
    CHECK_THROWS_AS(base.evaluate<double>(n, 0.5, 0.5), ArgumentError);
    CHECK_THROWS_AS(base.evaluate<float>(n, 0.5f, 0.5f), ArgumentError);
    for (NormalMode m : {NormalMode::Approximate, NormalMode::Accurate, NormalMode::Auto}) {
        CAPTURE(toString(m));
        CHECK_THROWS_WITH(ds.evaluate<double>(n, 0.5, 0.5, m), Contains("out of range"));
        CHECK_THROWS_AS(ds.evaluate<double>(-7, 0.5, 0.5, m), ArgumentError);
    }
    CHECK_THROWS_AS(ds.displacement<double>(n, 0.5, 0.5), ArgumentError);

    // (u, v): NaN, Inf, outside [0, 1]^2, float and double, base and displaced.
    for (const dvec2 uv : {dvec2(nan, 0.5), dvec2(0.5, nan), dvec2(inf, 0.5), dvec2(0.5, -inf), dvec2(-1e-12, 0.5),
                           dvec2(0.5, 1.0 + 1e-12), dvec2(2, 2)}) {
        CAPTURE(uv.x, uv.y);
        CHECK_THROWS_WITH(base.evaluate<double>(0, uv.x, uv.y), Contains("is not in [0, 1]^2"));
        CHECK_THROWS_AS(ds.evaluate<double>(0, uv.x, uv.y, NormalMode::Accurate), ArgumentError);
        CHECK_THROWS_AS(ds.displacement<double>(0, uv.x, uv.y), ArgumentError);
        // In float, where the value survives the rounding (-1e-12 does, 1 + 1e-12 becomes 1).
        const float uf = static_cast<float>(uv.x), vf = static_cast<float>(uv.y);
        if (!(uf >= 0 && uf <= 1 && vf >= 0 && vf <= 1)) {
            CHECK_THROWS_AS(base.evaluate<float>(0, uf, vf), ArgumentError);
            CHECK_THROWS_AS(ds.evaluate<float>(0, uf, vf, NormalMode::Auto), ArgumentError);
        }
    }
    CHECK_NOTHROW(base.evaluate<double>(0, 0.0, 1.0));
    CHECK_NOTHROW(base.evaluate<float>(0, 1.0f, 0.0f));

    // A resolution that is NaN (would index a garbage mip level).
    CHECK_THROWS_WITH(ds.evaluate<double>(0, 0.5, 0.5, NormalMode::Approximate, nan), Contains("rho is NaN"));
    CHECK_THROWS_AS(ds.displacement<float>(0, 0.5f, 0.5f, std::numeric_limits<float>::quiet_NaN()), ArgumentError);
    CHECK_NOTHROW(ds.evaluate<double>(0, 0.5, 0.5, NormalMode::Approximate, inf));
    CHECK_NOTHROW(ds.evaluate<double>(0, 0.5, 0.5, NormalMode::Approximate, -inf));

    // A hole (face 1 of catmark_hole_test1).
    REQUIRE(base.isHole(1));
    CHECK_THROWS_WITH(base.evaluate<double>(1, 0.5, 0.5), Contains("hole"));
    CHECK_THROWS_WITH(ds.evaluate<double>(1, 0.5, 0.5, NormalMode::Auto), Contains("hole"));

    // Isolation level.
    for (int level : {0, 11, -1}) {
        BaseSurfaceOptions bo;
        bo.isolationLevel = level;
        CAPTURE(level);
        CHECK_THROWS_WITH(BaseSurface(mesh, bo), Contains("isolation level " + std::to_string(level) + " out of range [1, 10]"));
    }

    // Tiles of another mesh.
    const ControlMesh other = dmtest::shape("catmark_nonquads");
    const TileSet otherTiles = buildTiles(other, uniformTileSizes(other, 2), [](int, double, double) { return 0.0; });
    CHECK_THROWS_WITH(DisplacedSurface(base, otherTiles), Contains("built for another mesh"));
    // Same Ptex face count, other topology: the faces listed from the last (the hash differs).
    MeshDescription permuted = mesh.description();
    permuted.holes.clear();
    {
        std::vector<int> sizes(permuted.faceSizes.rbegin(), permuted.faceSizes.rend()), verts;
        for (std::size_t f = permuted.faceSizes.size(); f-- > 0;) {
            const auto at = permuted.faceVertices.begin() + mesh.faceOffset(static_cast<int>(f));
            verts.insert(verts.end(), at, at + permuted.faceSizes[f]);
        }
        permuted.faceSizes = sizes;
        permuted.faceVertices = verts;
    }
    const ControlMesh permutedMesh(permuted);
    REQUIRE(permutedMesh.ptexFaceCount() == mesh.ptexFaceCount());
    TileSet permutedTiles = buildTiles(permutedMesh, uniformTileSizes(permutedMesh, 2), [](int, double, double) { return 0.0; });
    CHECK_THROWS_WITH(DisplacedSurface(base, permutedTiles), Contains("topology hashes differ"));
    permutedTiles.topologyHash = 0; // a tile set without a fingerprint is taken on its count
    CHECK_NOTHROW(DisplacedSurface(base, permutedTiles));

    // Auto options.
    for (double tol : {nan, -0.01, inf, -inf}) {
        CAPTURE(tol);
        DisplacedSurfaceOptions o;
        o.autoTolerance = tol;
        CHECK_THROWS_WITH(DisplacedSurface(base, tiles, o), Contains("tolerance"));
    }
    for (int samples : {1, 0, -3, 1025}) {
        CAPTURE(samples);
        DisplacedSurfaceOptions o;
        o.autoSamples = samples;
        CHECK_THROWS_AS(DisplacedSurface(base, tiles, o), ArgumentError);
    }
}

// The fallback where s_u x s_v vanishes must point the way the normal does just inside the face,
// at every corner (the first-order term n_u + n_v alone is flipped at u = 1 or v = 1). Two
// surfaces whose normal changes sign across the line x = u - cu = 0 (resp. y = v - cv = 0), so
// only the side inside the face is right: s = (u, x (v - cv), 0) with s_v = 0 on that edge, and
// s = ((v - cv) u, v, 0) with s_u = 0 on the other. The reference is the normal a step of 1e-4
// inside; tolerance 1e-2 rad (the normal there is exactly +-z, so any flip fails by pi).
TEST_CASE("degenerate normal: the fallback points like the normal just inside", "[surface]") {
    for (int surface = 0; surface < 2; ++surface)
        for (int corner = 0; corner < 4; ++corner) {
            CAPTURE(surface, corner);
            const double cu = corner == 1 || corner == 2 ? 1.0 : 0.0, cv = corner >= 2 ? 1.0 : 0.0;
            auto eval = [&](double u, double v, dvec3& su, dvec3& sv, dvec3& suu, dvec3& suv, dvec3& svv) {
                const double x = u - cu, y = v - cv;
                suu = svv = dvec3(0);
                if (surface == 0) {
                    su = dvec3(1, y, 0);
                    sv = dvec3(0, x, 0);
                    suv = dvec3(0, 1, 0);
                } else {
                    su = dvec3(y, 0, 0);
                    sv = dvec3(x, 1, 0);
                    suv = dvec3(1, 0, 0);
                }
            };
            dvec3 su, sv, suu, suv, svv;
            eval(cu, cv, su, sv, suu, suv, svv);
            REQUIRE(glm::length(glm::cross(su, sv)) == 0.0);
            const dvec3 N = kern::dmBaseNormal(su, sv, suu, suv, svv, glm::dvec2(cu, cv), dvec3(1, 0, 0));
            const double iu = cu == 0 ? 1e-4 : 1 - 1e-4, iv = cv == 0 ? 1e-4 : 1 - 1e-4;
            eval(iu, iv, su, sv, suu, suv, svv);
            const dvec3 inside = glm::normalize(glm::cross(su, sv));
            CHECK(glm::dot(N, inside) > std::cos(1e-2));
        }
}

} // namespace dmtest_surface
