// LOD kernels: tessellation factors and mip selection give every face around a vertex, and
// both faces of an edge, the same values.
#include <catch2/catch.hpp>

#include <random>

#include "dispmap/kernels/bspline.h"
#include "dispmap/kernels/lod.h"
#include "dispmap/kernels/tile.h"
#include "dispmap/surface/tile_builder.h"
#include "test_support.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_lod {

using namespace dispmap;

TEST_CASE("tessellation factors per vertex, edge and inner", "[lod]") {
    const glm::dvec3 eye(0, 0, 10);
    CHECK(kern::dmTessFactorDistance(eye, glm::dvec3(0, 0, 0), 40.0) == Approx(4.0));
    CHECK(kern::dmTessFactorDistance(eye, glm::dvec3(0, 0, -10), 40.0) == Approx(2.0)); // falls with distance
    CHECK(std::isfinite(kern::dmTessFactorDistance(eye, eye, 40.0)));                   // vertex at the eye
    // area: a unit square's one-ring of 4 edge vectors gives sum |e_i x e_i+1| = 4
    const glm::dvec2 e[4] = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}};
    double sum = 0;
    for (int i = 0; i < 4; ++i) sum += kern::dmTessAreaTerm(e[i], e[(i + 1) % 4]);
    CHECK(kern::dmTessFactorArea(sum, 2.0) == Approx(4.0));
    CHECK(kern::dmTessFactorEdge(3.0, 2.0) == Approx(6.0));
    CHECK(kern::dmClampTessFactor(0.2, 64.0) == 1.0);
    CHECK(kern::dmClampTessFactor(100.0, 64.0) == 64.0);
    const glm::dvec4 corner(1, 5, 2, 3);
    const glm::dvec4 edge = kern::dmEdgeTessFactors(corner);
    CHECK(edge == glm::dvec4(5, 5, 3, 3));
    CHECK(kern::dmInnerTessFactors(edge) == glm::dvec2(5, 5));
}

TEST_CASE("mip selection: blending weights, clamps, the texel-ratio rule's rule", "[lod]") {
    int mf = -1, mc = -1;
    double w = kern::dmSelectMips(2.25, 5.0, 5, mf, mc);
    CHECK(w == Approx(0.25));
    CHECK(mc == 3); // resolution 2 = level 5 - 2
    CHECK(mf == 2);
    w = kern::dmSelectMips(7.0, 3.5, 5, mf, mc); // clamped to the max resolution
    CHECK(w == Approx(0.5));
    CHECK(mc == 2);
    CHECK(mf == 1);
    w = kern::dmSelectMips(0.0, 5.0, 5, mf, mc); // never coarser than s = 2
    CHECK(w == 0.0);
    CHECK(mc == 4);
    w = kern::dmSelectMips(5.0, 5.0, 5, mf, mc); // finest: one level only
    CHECK(w == 0.0);
    CHECK(mc == 0);
    CHECK(mf == 0);
    CHECK(kern::dmResolutionFromTessFactor(8.0) == Approx(3.0));
    // M = log2(L/T) + 1: 64 texels with 8 segments -> level 4 (half a texel per segment at 2^4 coarser)
    CHECK(kern::dmMipLevelTexelRatio(64.0, 8.0) == Approx(4.0));
    CHECK(kern::dmMipLevelTexelRatio(8.0, 64.0) == 0.0);
    CHECK(kern::dmVertexResolutionTexelRatio(6, 8.0) == Approx(2.0));
}

TEST_CASE("crack-free LOD: both faces of every edge choose the same resolution, bit for bit", "[lod]") {
    // Per-vertex factors and texel-ratio resolutions, interpolated with dmBilerp over each face:
    // on a shared edge only that edge's two corners count, so at the same edge point both
    // faces compute identical values. Edge points are dyadic (k / 64) so that the neighbour's
    // parameter 1 - y is exact, as a tessellator's symmetric edge parameters are.
    for (const char* name : {"catmark_cube", "catmark_pole8", "spot_control_mesh", "catmark_edgecorner"}) {
        ControlMesh mesh = dmtest::shape(name);
        TileTopology topo(mesh);
        std::mt19937 rng(3);
        std::uniform_real_distribution<double> U(1, 64);
        std::vector<double> tf(std::size_t(topo.vertexCount()));
        for (double& x : tf) x = U(rng);
        int compared = 0;
        for (int t = 0; t < topo.tileCount(); ++t)
            for (int e = 0; e < 4; ++e)
                for (const auto& l : topo.links(t, e)) {
                    if (l.beta != 1.0) continue; // T-junctions: patch-level factors (renderer)
                    auto cornerTF = [&](int tile) {
                        return glm::dvec4(tf[std::size_t(topo.cornerVertex(tile, 0))], tf[std::size_t(topo.cornerVertex(tile, 1))],
                                          tf[std::size_t(topo.cornerVertex(tile, 2))], tf[std::size_t(topo.cornerVertex(tile, 3))]);
                    };
                    const glm::dvec4 ea = kern::dmEdgeTessFactors(cornerTF(t));
                    const glm::dvec4 eb = kern::dmEdgeTessFactors(cornerTF(l.tile));
                    CHECK(ea[e] == eb[l.edge]);
                    for (int i = 0; i <= 64; ++i) {
                        const double y = i / 64.0;
                        const glm::dvec2 p = dmtest::edgePoint(e, y), q = dmtest::edgePoint(l.edge, l.alpha - l.beta * y);
                        const double ra = kern::dmResolutionFromTessFactor(kern::dmBilerp(cornerTF(t), p));
                        const double rb = kern::dmResolutionFromTessFactor(kern::dmBilerp(cornerTF(l.tile), q));
                        CHECK(ra == rb);
                        // float too
                        CHECK(kern::dmBilerp(glm::vec4(cornerTF(t)), glm::vec2(p)) ==
                              kern::dmBilerp(glm::vec4(cornerTF(l.tile)), glm::vec2(q)));
                        ++compared;
                    }
                }
        INFO(name);
        CHECK(compared > 0);
    }
}

} // namespace dmtest_lod
