// The base surface as the GPU reads it: the patch kernels (kernels/patch.h) against
// OpenSubdiv's Far::PatchTable::EvaluateBasis, PackedSurface::evaluate (the CPU twin of the
// shader) against BaseSurface::evaluate, the quadtree against Far::PatchMap, and hard cases
// (N-gon sub-faces, boundary and corner masks, infinitely sharp creases, a valence-12 pole).
// Set DISPMAP_SURFACE_REPORT=1 to print the measured worst differences.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <type_traits>
#include <string>
#include <vector>

#include "dispmap/surface/packed_surface.h"
#include "test_support.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_packed_surface {

using namespace dispmap;

namespace {

bool packedReportOn() {
    const char* e = std::getenv("DISPMAP_SURFACE_REPORT");
    return e && *e && *e != '0';
}
template <typename... A> void packedReport(const char* format, A... args) {
    if (packedReportOn()) {
        std::printf(format, args...);
        std::fflush(stdout);
    }
}

double meshSize(const ControlMesh& mesh) {
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (const glm::dvec3& p : mesh.description().positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    return glm::length(hi - lo);
}

/// A closed valence-n pole: n quads around a top vertex over a ring, closed below.
std::string poleObj(int n) {
    std::string s;
    auto vtx = [&](double x, double y, double z) {
        s += "v " + std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(z) + "\n";
    };
    const double pi = 3.141592653589793;
    vtx(0.05, -0.03, 0.6);
    for (int i = 0; i < 2 * n; ++i) {
        const double a = pi * i / n, r = (i % 2 ? 1.3 : 1.0) * (1.0 + 0.15 * std::cos(a));
        vtx(r * std::cos(a), r * std::sin(a), 0.25 * std::sin(2 * a) * (i % 2 ? 0.5 : 1.0) + 0.1 * r);
    }
    for (int i = 0; i < 2 * n; ++i) {
        const double a = pi * i / n, r = (i % 2 ? 1.2 : 1.0);
        vtx(r * std::cos(a), r * std::sin(a), -0.9 - 0.1 * std::cos(a));
    }
    vtx(-0.04, 0.02, -1.5);
    auto A = [&](int i) { return 2 + ((i % (2 * n)) + 2 * n) % (2 * n); };
    auto B = [&](int i) { return 2 + 2 * n + ((i % (2 * n)) + 2 * n) % (2 * n); };
    const int bottom = 2 + 4 * n;
    auto face = [&](int a, int b, int c, int d) {
        s += "f " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(c) + " " + std::to_string(d) + "\n";
    };
    for (int k = 0; k < n; ++k) face(1, A(2 * k), A(2 * k + 1), A(2 * k + 2));
    for (int i = 0; i < 2 * n; ++i) face(A(i + 1), A(i), B(i), B(i + 1));
    for (int k = 0; k < n; ++k) face(bottom, B(2 * k + 2), B(2 * k + 1), B(2 * k));
    return s;
}

/// A cube with infinitely sharp creases along two edges and an infinitely sharp corner: with
/// useInfSharpPatch they become regular patches with boundary masks.
const char* const kInfSharpCube = "v -1 -1 1\nv 1 -1 1\nv -1 1 1\nv 1 1 1\nv -1 1 -1\nv 1 1 -1\nv -1 -1 -1\nv 1 -1 -1\n"
                                  "f 1 2 4 3\nf 3 4 6 5\nf 5 6 8 7\nf 7 8 2 1\nf 2 8 6 4\nf 7 1 3 5\n"
                                  "t crease 2/1/0 0 1 10\nt crease 2/1/0 1 3 10\nt corner 1/1/0 6 10\n";

struct Shape {
    std::string name;
    ControlMesh mesh;
};

std::vector<Shape> shapes() {
    std::vector<Shape> out;
    for (const char* name : {"catmark_bishop", "catmark_cube", "catmark_cube_creases0", "catmark_dart_edgecorner",
                             "catmark_edgecorner", "catmark_flap", "catmark_gregory_test2", "catmark_helmet",
                             "catmark_hole_test1", "catmark_nonquads", "catmark_pole8", "catmark_pyramid",
                             "catmark_quadstrips", "catmark_tent_creases0", "catmark_toroidal_tet", "catmark_torus",
                             "catmark_xord_boundary", "spot_control_mesh"})
        out.push_back({name, dmtest::shape(name)});
    out.push_back({"inf-sharp cube", ControlMesh::fromObjText(kInfSharpCube, "inf-sharp cube")});
    out.push_back({"pole 12", ControlMesh::fromObjText(poleObj(12), "pole 12")});
    return out;
}

Far::PatchTable::PatchHandle handleOf(const Far::PatchTable& table, int patch) {
    int first = 0;
    for (int a = 0; a < table.GetNumPatchArrays(); ++a) {
        const int n = table.GetNumPatches(a);
        if (patch < first + n) {
            Far::PatchTable::PatchHandle h;
            h.arrayIndex = a;
            h.patchIndex = patch;
            h.vertIndex = (patch - first) * table.GetPatchArrayDescriptor(a).GetNumControlVertices();
            return h;
        }
        first += n;
    }
    throw ArgumentError("no such patch");
}

/// Local (s, t) probes of a patch: corners, edge midpoints, the centre, points near the edges
/// and irrational-ish interior points.
const std::vector<glm::dvec2>& localProbes() {
    static const std::vector<glm::dvec2> probes = [] {
        std::vector<glm::dvec2> p;
        for (double s : {0.0, 1.0 / 1024, 0.25, 0.5, 0.8125, 1.0})
            for (double t : {0.0, 0.5, 1.0 - 1.0 / 512, 1.0}) p.emplace_back(s, t);
        p.emplace_back(0.3183098861837907, 0.7071067811865476);
        p.emplace_back(0.9, 0.1);
        p.emplace_back(0.123, 0.987);
        return p;
    }();
    return probes;
}

/// Kinds of patches the checks must have seen.
enum Kind { RegularInterior, RegularBoundary, Gregory, BSplineEndCap, NonQuad, KindCount };
const char* const kKindNames[] = {"regular interior", "regular boundary/corner", "Gregory end cap", "B-spline end cap",
                                  "NonQuadRoot"};

} // namespace

// ---------------------------------------------------------------------------------------
// Kernels against Far::PatchTable::EvaluateBasis.

TEMPLATE_TEST_CASE("patch kernels: weights equal Far::PatchTable::EvaluateBasis for every patch type", "[packed]", double,
                   float) {
    using real = TestType;
    // Tolerance: both sides evaluate the same polynomials (the B-spline / Bezier basis, the
    // Gregory rational blend, the boundary fold) in a different but equally short order of
    // operations, so the weights differ by a few rounding errors of their largest term. A
    // weight of order k carries the factor 2^(kL) (up to 4^10 at level 10), so the bound is
    // eps-relative to 2^(kL): 64 eps (measured: 1 eps for values, 3 for first and 16 for
    // second derivatives, in double and float; DISPMAP_SURFACE_REPORT=1 prints them).
    const real eps = std::numeric_limits<real>::epsilon();
    const real tol = real(64) * eps;
    std::array<int, KindCount> seen{};
    double worst[3] = {0, 0, 0};
    for (const bool gregory : {true, false}) {
        for (const Shape& sh : shapes()) {
            CAPTURE(sh.name, gregory);
            BaseSurfaceOptions opt;
            opt.gregoryEndCaps = gregory;
            const BaseSurface base(sh.mesh, opt);
            const Far::PatchTable& table = base.patchTable();
            const int patchCount = table.GetNumPatchesTotal();
            int failures = 0;
            for (int p = 0; p < patchCount; ++p) {
                const Far::PatchTable::PatchHandle h = handleOf(table, p);
                const Far::PatchParam param = table.GetPatchParam(h);
                const int n = table.GetPatchArrayDescriptor(h.arrayIndex).GetNumControlVertices();
                REQUIRE((n == 16 || n == 20));
                if (n == 20)
                    ++seen[Gregory];
                else if (!param.IsRegular())
                    ++seen[BSplineEndCap];
                else if (param.GetBoundary())
                    ++seen[RegularBoundary];
                else
                    ++seen[RegularInterior];
                if (param.NonQuadRoot()) ++seen[NonQuad];
                const glm::uvec2 packed(param.field0, param.field1);
                REQUIRE(kern::dmPatchDepth(packed) == param.GetDepth());
                REQUIRE(kern::dmPatchNonQuadRoot(packed) == param.NonQuadRoot());
                REQUIRE(kern::dmPatchRegular(packed) == param.IsRegular());
                REQUIRE(kern::dmPatchBoundary(packed) == (param.GetBoundary() & 15));
                REQUIRE(kern::dmPatchOffset(packed) == glm::ivec2(param.GetU(), param.GetV()));
                REQUIRE(kern::dmPatchFaceId(packed) == param.GetFaceId());
                REQUIRE(std::ldexp(1.0, -kern::dmPatchDomainLevel(packed)) == double(param.GetParamFraction()));
                const real scale = real(1 << kern::dmPatchDomainLevel(packed));
                // Far scales derivatives by 2^depth; a NonQuadRoot patch's are 2x too large.
                const real farFix = param.NonQuadRoot() ? real(0.5) : real(1);
                for (const glm::dvec2& st : localProbes()) {
                    real u = real(st.x), v = real(st.y);
                    param.Unnormalize(u, v);
                    real rw[20], ru[20], rv[20], ruu[20], ruv[20], rvv[20];
                    table.EvaluateBasis(h, u, v, rw, ru, rv, ruu, ruv, rvv);
                    real w[20], wu[20], wv[20], wuu[20], wuv[20], wvv[20];
                    kern::dmPatchBasis2(packed, n, glm::vec<2, real>(u, v), w, wu, wv, wuu, wuv, wvv);
                    real w1[20], wu1[20], wv1[20];
                    kern::dmPatchBasis1(packed, n, glm::vec<2, real>(u, v), w1, wu1, wv1);
                    // The local parameter is Far's Normalize exactly.
                    real lu = u, lv = v;
                    param.Normalize(lu, lv);
                    const glm::vec<2, real> local = kern::dmPatchLocal(packed, glm::vec<2, real>(u, v));
                    bool ok = local.x == lu && local.y == lv;
                    for (int i = 0; i < 20; ++i) {
                        // dmPatchBasis1 is dmPatchBasis2 without the second derivatives, bit for bit.
                        ok = ok && w1[i] == w[i] && wu1[i] == wu[i] && wv1[i] == wv[i];
                        if (i >= n) {
                            // 16-point patches: entries 16..19 are zero.
                            ok = ok && w[i] == real(0) && wu[i] == real(0) && wv[i] == real(0) && wuu[i] == real(0) &&
                                 wuv[i] == real(0) && wvv[i] == real(0);
                            continue;
                        }
                        const double e0 = std::abs(double(w[i]) - double(rw[i]));
                        const double e1 = std::max(std::abs(double(wu[i]) - double(ru[i] * farFix)),
                                                   std::abs(double(wv[i]) - double(rv[i] * farFix)));
                        const double e2 = std::max({std::abs(double(wuu[i]) - double(ruu[i] * farFix * farFix)),
                                                    std::abs(double(wuv[i]) - double(ruv[i] * farFix * farFix)),
                                                    std::abs(double(wvv[i]) - double(rvv[i] * farFix * farFix))});
                        worst[0] = std::max(worst[0], e0 / double(eps));
                        worst[1] = std::max(worst[1], e1 / double(scale) / double(eps));
                        worst[2] = std::max(worst[2], e2 / double(scale * scale) / double(eps));
                        ok = ok && e0 <= double(tol) && e1 <= double(tol * scale) && e2 <= double(tol * scale * scale);
                    }
                    if (!ok) {
                        // One failure per case is enough to read; the loop goes on counting.
                        if (failures++ == 0) {
                            CAPTURE(p, n, st.x, st.y, u, v);
                            for (int i = 0; i < n; ++i) {
                                CAPTURE(i, w[i], rw[i], wu[i], ru[i], wv[i], rv[i], wuu[i], ruu[i], wuv[i], ruv[i], wvv[i], rvv[i]);
                                CHECK(false);
                            }
                        }
                    }
                }
            }
            CHECK(failures == 0);
        }
    }
    packedReport("patch kernels (%s) vs EvaluateBasis, worst |diff| in eps of 2^(kL): w %.2f, d1 %.2f, d2 %.2f\n",
                 sizeof(real) == 8 ? "double" : "float", worst[0], worst[1], worst[2]);
    for (int k = 0; k < KindCount; ++k) {
        CAPTURE(kKindNames[k]);
        CHECK(seen[static_cast<std::size_t>(k)] > 0);
    }
}

TEST_CASE("patch kernels: quadtree step, local coordinates and end-cap corner weights", "[packed]") {
    // dmQuadTreeStep: Far::PatchMap's rule (>= 1/2 goes up), exact.
    glm::dvec2 uv(0.5, 0.49999999999999994);
    CHECK(kern::dmQuadTreeStep(uv) == 1);
    CHECK(uv == glm::dvec2(0.0, 0.99999999999999989));
    uv = glm::dvec2(1.0, 1.0);
    for (int k = 0; k < 12; ++k) {
        CHECK(kern::dmQuadTreeStep(uv) == 3);
        CHECK(uv == glm::dvec2(1.0, 1.0));
    }
    uv = glm::dvec2(0.0, 0.75);
    CHECK(kern::dmQuadTreeStep(uv) == 2);
    CHECK(uv == glm::dvec2(0.0, 0.5));
    glm::vec2 uf(0.75f, 0.25f);
    CHECK(kern::dmQuadTreeStep(uf) == 1);
    CHECK(uf == glm::vec2(0.5f, 0.5f));

    // End-cap corner weights: a depth-3 irregular patch at the face's corner 2 (U = V = 7)
    // touches corner 2 only; one spanning the whole face (NonQuadRoot at depth 1) all four.
    Far::PatchParam p;
    p.Set(5, 7, 7, 3, false, 0, 0, false);
    const glm::uvec2 a(p.field0, p.field1);
    CHECK(kern::dmEndCapCornerWeights(a, glm::dvec2(1.0, 1.0)) == glm::dvec4(0, 0, 1, 0));
    CHECK(kern::dmEndCapCornerWeights(a, glm::dvec2(0.875, 0.9375)) == glm::dvec4(0, 0, 0, 0));
    CHECK(kern::dmEndCapCornerWeights(a, glm::dvec2(0.9375, 0.9375)) == glm::dvec4(0, 0, 0.25, 0));
    p.Set(5, 0, 0, 1, true, 0, 0, false);
    const glm::uvec2 b(p.field0, p.field1);
    CHECK(kern::dmEndCapCornerWeights(b, glm::dvec2(0.25, 0.5)) == glm::dvec4(0.375, 0.125, 0.125, 0.375));
    p.Set(5, 0, 0, 1, true, 0, 0, true); // regular: no blend data
    CHECK(kern::dmEndCapCornerWeights(glm::uvec2(p.field0, p.field1), glm::dvec2(0.25, 0.5)) == glm::dvec4(0));
}

// ---------------------------------------------------------------------------------------
// PackedSurface against BaseSurface.

namespace {

/// Face (u, v) probes: corners, edge midpoints, the centre, dyadic points down to 2^-10 from the
/// edges (patch boundaries at every level) and a few non-dyadic ones.
const std::vector<double>& faceProbes() {
    static const std::vector<double> p = {0.0, 1.0 / 1024, 1.0 / 64, 0.125, 0.25, 0.3183098861837907, 0.5,
                                          0.5 - 1.0 / 4096, 0.5 + 1.0 / 4096, 0.75, 0.875, 1.0 - 1.0 / 64, 1.0 - 1.0 / 1024, 1.0};
    return p;
}

template <typename real> struct Agreement {
    double p = 0, d1 = 0, d2 = 0; // worst |diff| / mesh size (derivatives also / 2^(kL))
    long samples = 0;
};

template <typename real>
void compareSurfaces(const Shape& sh, bool gregory, Agreement<real>& agg, std::array<int, KindCount>& seen) {
    CAPTURE(sh.name, gregory);
    BaseSurfaceOptions opt;
    opt.gregoryEndCaps = gregory;
    const BaseSurface base(sh.mesh, opt);
    const PackedSurface packed(base);
    const Far::PatchMap map(base.patchTable());
    const double size = meshSize(sh.mesh);
    // Tolerances (relative to the mesh size, derivatives also to 2^(kL)): the two sides sum the
    // same control points with weights that differ by a few rounding errors (see the kernel
    // test), in the same order, so the results differ by a few eps of the largest term,
    // scaled by the control points' coordinates (up to about the mesh size from the origin).
    // double: 1e-12 (measured 5e-15); float: 64 float eps = 7.6e-6 (measured 2.8e-6, 24 eps).
    const double tol = std::is_same_v<real, double> ? 1e-12 : 64.0 * double(std::numeric_limits<float>::epsilon());
    for (int f = 0; f < base.faceCount(); ++f) {
        if (base.isHole(f)) {
            CHECK(packed.faceRoots[static_cast<std::size_t>(f)] == PackedSurface::kEmpty);
            CHECK_THROWS_AS(packed.evaluate<real>(f, real(0.5), real(0.5)), ArgumentError);
            continue;
        }
        for (double ud : faceProbes())
            for (double vd : faceProbes()) {
                const real u = real(ud), v = real(vd);
                CAPTURE(f, ud, vd);
                const Far::PatchTable::PatchHandle* h = map.FindPatch(f, double(u), double(v));
                REQUIRE(h);
                const std::uint32_t patch = packed.findPatch(f, u, v);
                REQUIRE(int(patch) == h->patchIndex);
                const Far::PatchParam param = base.patchTable().GetPatchParam(*h);
                if (!param.IsRegular()) ++seen[gregory ? Gregory : BSplineEndCap];
                else if (param.GetBoundary()) ++seen[RegularBoundary];
                else ++seen[RegularInterior];
                if (param.NonQuadRoot()) ++seen[NonQuad];
                const double s1 = std::ldexp(1.0, param.GetDepth() - (param.NonQuadRoot() ? 1 : 0));
                for (const bool second : {true, false}) {
                    const BaseSample<real> a = base.evaluate<real>(f, u, v, second);
                    const BaseSample<real> b = packed.evaluate<real>(f, u, v, second);
                    auto diff = [&](const glm::vec<3, real>& x, const glm::vec<3, real>& y) {
                        return double(glm::length(glm::dvec3(x) - glm::dvec3(y))) / size;
                    };
                    const double ep = diff(a.p, b.p);
                    const double e1 = std::max(diff(a.du, b.du), diff(a.dv, b.dv)) / s1;
                    const double e2 = std::max({diff(a.duu, b.duu), diff(a.duv, b.duv), diff(a.dvv, b.dvv)}) / (s1 * s1);
                    agg.p = std::max(agg.p, ep);
                    agg.d1 = std::max(agg.d1, e1);
                    agg.d2 = std::max(agg.d2, e2);
                    ++agg.samples;
                    REQUIRE(ep <= tol);
                    REQUIRE(e1 <= tol);
                    REQUIRE(e2 <= tol);
                    if (!second) {
                        CHECK(b.duu == glm::vec<3, real>(0));
                        CHECK(b.dvv == glm::vec<3, real>(0));
                    }
                    // §5.4 blend data: the same weights (both sides compute the local
                    // parameter exactly) and the same normals, summed in the same order.
                    REQUIRE(a.evWeight == b.evWeight);
                    REQUIRE(a.evNormal == b.evNormal);
                }
            }
    }
}

} // namespace

TEMPLATE_TEST_CASE("packed surface: evaluate equals BaseSurface::evaluate on every shape", "[packed]", double, float) {
    using real = TestType;
    Agreement<real> agg;
    std::array<int, KindCount> seen{};
    for (const bool gregory : {true, false})
        for (const Shape& sh : shapes()) compareSurfaces<real>(sh, gregory, agg, seen);
    packedReport("packed surface (%s) vs BaseSurface, %ld samples, worst |diff| / mesh size: p %.3g, d1 %.3g, d2 %.3g "
                 "(derivatives also / 2^(kL))\n",
                 sizeof(real) == 8 ? "double" : "float", agg.samples, agg.p, agg.d1, agg.d2);
    for (int k = 0; k < KindCount; ++k) {
        CAPTURE(kKindNames[k]);
        CHECK(seen[static_cast<std::size_t>(k)] > 0);
    }
}

TEST_CASE("packed surface: the quadtree reaches every patch once, holes are empty, bytes add up", "[packed]") {
    for (const Shape& sh : shapes()) {
        CAPTURE(sh.name);
        const BaseSurface base(sh.mesh);
        const PackedSurface packed(base);
        const Far::PatchTable& table = base.patchTable();
        REQUIRE(packed.faceCount() == base.faceCount());
        REQUIRE(int(packed.patches.size()) == table.GetNumPatchesTotal());
        REQUIRE(packed.points.size() == base.points().size());
        REQUIRE(packed.cornerNormals.size() == 4 * std::size_t(base.faceCount()));
        // Every patch appears as exactly one leaf; nodes have no empty child (the patches tile
        // each face) and every node is referenced exactly once.
        std::vector<int> leafCount(packed.patches.size(), 0);
        std::vector<int> nodeRefs(packed.nodes.size(), 0);
        auto visit = [&](std::uint32_t c) {
            REQUIRE(c != PackedSurface::kEmpty);
            if (c & PackedSurface::kLeaf) {
                REQUIRE((c & ~PackedSurface::kLeaf) < packed.patches.size());
                ++leafCount[c & ~PackedSurface::kLeaf];
            } else {
                REQUIRE(c < packed.nodes.size());
                ++nodeRefs[c];
            }
        };
        for (int f = 0; f < packed.faceCount(); ++f) {
            const std::uint32_t r = packed.faceRoots[std::size_t(f)];
            CHECK((r == PackedSurface::kEmpty) == base.isHole(f));
            if (r != PackedSurface::kEmpty) visit(r);
        }
        for (const glm::uvec4& n : packed.nodes)
            for (int q = 0; q < 4; ++q) visit(n[q]);
        CHECK(std::all_of(leafCount.begin(), leafCount.end(), [](int c) { return c == 1; }));
        CHECK(std::all_of(nodeRefs.begin(), nodeRefs.end(), [](int c) { return c == 1; }));
        // Each patch record: its control points, count and PatchParam; its centre finds it.
        std::size_t next = 0;
        for (std::size_t p = 0; p < packed.patches.size(); ++p) {
            const glm::uvec4& rec = packed.patches[p];
            const Far::PatchTable::PatchHandle h = handleOf(table, int(p));
            const Far::ConstIndexArray cv = table.GetPatchVertices(h);
            const Far::PatchParam param = table.GetPatchParam(h);
            REQUIRE(rec.x == next);
            REQUIRE(int(rec.y) == cv.size());
            REQUIRE(rec.z == param.field0);
            REQUIRE(rec.w == param.field1);
            for (int k = 0; k < cv.size(); ++k) REQUIRE(packed.patchIndices[rec.x + std::size_t(k)] == std::uint32_t(cv[k]));
            next += rec.y;
            double u = 0.5, v = 0.5;
            param.Unnormalize(u, v);
            CHECK(packed.findPatch(param.GetFaceId(), u, v) == p);
        }
        CHECK(next == packed.patchIndices.size());
        // Points and corner data.
        for (std::size_t i = 0; i < packed.points.size(); ++i) {
            REQUIRE(glm::vec3(packed.points[i].x, packed.points[i].y, packed.points[i].z) == glm::vec3(base.points()[i]));
            REQUIRE(packed.points[i].w == 0.0f);
        }
        for (int f = 0; f < base.faceCount(); ++f)
            for (int c = 0; c < 4; ++c) {
                const glm::vec4& n = packed.cornerNormals[std::size_t(f) * 4 + std::size_t(c)];
                CHECK(glm::vec3(n.x, n.y, n.z) == glm::vec3(base.cornerNormal(f, c)));
                CHECK(n.w == (base.isExtraordinaryCorner(f, c) ? 1.0f : 0.0f));
            }
        CHECK(packed.bytes() == 16 * packed.points.size() + 4 * packed.patchIndices.size() + 16 * packed.patches.size() +
                                    16 * packed.nodes.size() + 4 * packed.faceRoots.size() + 16 * packed.cornerNormals.size());
        packedReport("%-24s faces %4d patches %6zu nodes %5zu points %6zu: %zu bytes\n", sh.name.c_str(), packed.faceCount(),
                     packed.patches.size(), packed.nodes.size(), packed.points.size(), packed.bytes());
    }
}

TEST_CASE("packed surface: hard cases and bad inputs", "[packed]") {
    // N-gon sub-faces (NonQuadRoot patches, a whole Ptex face at depth 1): derivatives carry
    // 2^(depth - 1); B-spline end caps and Gregory ones on the same mesh.
    const ControlMesh nonquads = dmtest::shape("catmark_nonquads");
    for (const bool gregory : {true, false}) {
        BaseSurfaceOptions opt;
        opt.gregoryEndCaps = gregory;
        opt.isolationLevel = 2;
        const BaseSurface base(nonquads, opt);
        const PackedSurface packed(base);
        int nonQuad = 0;
        for (const glm::uvec4& rec : packed.patches)
            if (kern::dmPatchNonQuadRoot(glm::uvec2(rec.z, rec.w))) ++nonQuad;
        CHECK(nonQuad > 0);
        for (int f = 0; f < base.faceCount(); ++f)
            for (double u : {0.0, 0.5, 1.0})
                for (double v : {0.0, 0.5, 1.0}) {
                    const BaseSample<double> a = base.evaluate<double>(f, u, v);
                    const BaseSample<double> b = packed.evaluate<double>(f, u, v);
                    CHECK(glm::length(a.du - b.du) <= 1e-12 * (1 + glm::length(a.du)));
                    CHECK(glm::length(a.duv - b.duv) <= 1e-12 * (1 + glm::length(a.duv)));
                    CHECK(a.evWeight == b.evWeight);
                }
    }
    // Bad inputs: the errors of BaseSurface.
    const BaseSurface holes(dmtest::shape("catmark_hole_test1"));
    const PackedSurface packed(holes);
    CHECK_THROWS_AS(packed.evaluate<double>(-1, 0.5, 0.5), ArgumentError);
    CHECK_THROWS_AS(packed.evaluate<double>(packed.faceCount(), 0.5, 0.5), ArgumentError);
    CHECK_THROWS_AS(packed.evaluate<double>(0, 1.5, 0.5), ArgumentError);
    CHECK_THROWS_AS(packed.evaluate<float>(0, 0.5f, std::numeric_limits<float>::quiet_NaN()), ArgumentError);
    CHECK_THROWS_WITH(packed.evaluate<double>(1, 0.5, 0.5), Catch::Contains("hole"));
    CHECK_THROWS_AS(holes.evaluate<double>(1, 0.5, 0.5), ArgumentError);
}

} // namespace dmtest_packed_surface
