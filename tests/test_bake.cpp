// Baking (bake/): dense meshes in every format, the ray and closest-point queries, the fitting
// stages, and whole bakes that must recover a known answer: a sphere and a torus of known
// radii, and displaced surfaces of our own baked back onto their own cage and onto a decimated
// one. Bad input gets a clear error or the documented fallback.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include "dispmap/bake/bake.h"
#include "dispmap/bake/simplify.h"
#include "dispmap/bake/skeleton.h"
#include "dispmap/io/mesh_writers.h"
#include "dispmap/surface/builtin.h"
#include "test_files.h"
#include "test_support.h"

namespace dmtest_bake {

using namespace dispmap;

namespace {

/// A UV sphere of radius r: n segments around, m rings (poles as single vertices).
TriangleMesh uvSphere(int n, int m, double r, glm::dvec3 centre = glm::dvec3(0.0)) {
    TriangleMesh t;
    const double pi = 3.14159265358979323846;
    t.positions.push_back(centre + glm::dvec3(0, 0, r));
    for (int j = 1; j < m; ++j)
        for (int i = 0; i < n; ++i) {
            const double th = pi * j / m, ph = 2 * pi * i / n;
            t.positions.push_back(centre + r * glm::dvec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)));
        }
    t.positions.push_back(centre + glm::dvec3(0, 0, -r));
    const int south = static_cast<int>(t.positions.size()) - 1;
    auto id = [&](int i, int j) { return 1 + (j - 1) * n + (i % n); };
    for (int i = 0; i < n; ++i) t.triangles.emplace_back(0, id(i, 1), id(i + 1, 1));
    for (int j = 1; j + 1 < m; ++j)
        for (int i = 0; i < n; ++i) {
            t.triangles.emplace_back(id(i, j), id(i, j + 1), id(i + 1, j + 1));
            t.triangles.emplace_back(id(i, j), id(i + 1, j + 1), id(i + 1, j));
        }
    for (int i = 0; i < n; ++i) t.triangles.emplace_back(south, id(i + 1, m - 1), id(i, m - 1));
    t.normals = t.positions;
    return t;
}

/// A torus around z, main radius R, tube radius r, n x m quads split into triangles.
TriangleMesh torusMesh(int n, int m, double R, double r) {
    TriangleMesh t;
    const double pi = 3.14159265358979323846;
    for (int j = 0; j < m; ++j)
        for (int i = 0; i < n; ++i) {
            const double a = 2 * pi * i / n, b = 2 * pi * j / m;
            t.positions.emplace_back((R + r * std::cos(b)) * std::cos(a), (R + r * std::cos(b)) * std::sin(a), r * std::sin(b));
        }
    auto id = [&](int i, int j) { return (j % m) * n + (i % n); };
    for (int j = 0; j < m; ++j)
        for (int i = 0; i < n; ++i) {
            t.triangles.emplace_back(id(i, j), id(i + 1, j), id(i + 1, j + 1));
            t.triangles.emplace_back(id(i, j), id(i + 1, j + 1), id(i, j + 1));
        }
    t.normals = t.positions;
    return t;
}

/// Bakes `dense` by the simplification route.
BakeResult bakeSimplified(const DenseMesh& dense, int faces, int density, BakeOptions o = {}) {
    const RayScene scene(dense.positions, dense.triangles);
    SimplifyOptions so;
    so.targetFaces = faces;
    o.density = density;
    return bakeFromControlMesh(dense, scene, simplifiedControlMesh(dense, so), o);
}

/// A smooth bump per face, 0 on the face's edges (|D| <= 0.05).
double bump(int, double u, double v) { return 0.05 * std::sin(3.14159265358979323846 * u) * std::sin(3.14159265358979323846 * v); }

/// A displaced surface of our own (the box cage with a bump per face), tessellated finely.
struct OwnSurface {
    ControlMesh mesh = builtin::builtinMesh("box");
    TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 4), bump);
    BaseSurface base{mesh};
    DisplacedSurface surface{base, tiles};
    TriangleMesh dense() const {
        TessellateOptions to;
        to.spacing = Spacing::Integer;
        return Tessellator(surface, uniformTessFactors(base, 48), to).tessellate();
    }
};

} // namespace

TEST_CASE("dense meshes read the same from OBJ, binary PLY, ASCII PLY and OFF", "[bake]") {
    const TriangleMesh sphere = uvSphere(24, 12, 1.0);
    dmtest::TempDir dir("dispmap_bake_read_");
    writeObj(sphere, dir.file("s.obj"));
    writePly(sphere, dir.file("s.ply"));
    std::string ascii = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(sphere.vertexCount()) +
                        "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                        std::to_string(sphere.triangleCount()) + "\nproperty list uchar int vertex_indices\nend_header\n";
    std::string off = "OFF\n" + std::to_string(sphere.vertexCount()) + " " + std::to_string(sphere.triangleCount()) + " 0\n";
    for (const glm::dvec3& p : sphere.positions) {
        const glm::vec3 f(p);
        const std::string line = std::to_string(f.x) + " " + std::to_string(f.y) + " " + std::to_string(f.z) + "\n";
        ascii += line;
        off += line;
    }
    for (const glm::ivec3& t : sphere.triangles) {
        const std::string line = "3 " + std::to_string(t.x) + " " + std::to_string(t.y) + " " + std::to_string(t.z) + "\n";
        ascii += line;
        off += line;
    }
    dmtest::writeBytes(dir.file("a.ply"), std::vector<unsigned char>(ascii.begin(), ascii.end()));
    dmtest::writeBytes(dir.file("s.OFF"), std::vector<unsigned char>(off.begin(), off.end()));
    const DenseMesh ref = readDenseMesh(dir.file("s.obj"));
    REQUIRE(ref.vertexCount() == sphere.vertexCount());
    REQUIRE(ref.triangleCount() == static_cast<std::size_t>(sphere.triangleCount()));
    for (const char* f : {"s.ply", "a.ply", "s.OFF"}) {
        CAPTURE(f);
        const DenseMesh m = readDenseMesh(dir.file(f));
        REQUIRE(m.vertexCount() == ref.vertexCount());
        REQUIRE(m.triangles == ref.triangles);
        for (std::size_t i = 0; i < m.positions.size(); ++i)
            // std::to_string writes 6 decimals: the ASCII files hold the floats to 5e-7
            REQUIRE(glm::length(m.positions[i] - ref.positions[i]) < 2e-6f);
    }
    // Polygons are fanned: a quad OFF gives two triangles.
    const std::string quad = "OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
    dmtest::writeBytes(dir.file("q.off"), std::vector<unsigned char>(quad.begin(), quad.end()));
    const DenseMesh q = readDenseMesh(dir.file("q.off"));
    CHECK(q.triangleCount() == 2);
    CHECK(q.stats.polygons == 1);
}

TEST_CASE("bad dense meshes get a clear error; degenerate triangles are dropped and counted", "[bake]") {
    dmtest::TempDir dir("dispmap_bake_bad_");
    auto file = [&](const std::string& name, const std::string& text) {
        dmtest::writeBytes(dir.file(name), std::vector<unsigned char>(text.begin(), text.end()));
        return dir.file(name);
    };
    using Catch::Contains;
    REQUIRE_THROWS_WITH(readDenseMesh(file("empty.off", "OFF\n0 0 0\n")), Contains("no faces") || Contains("cannot parse"));
    REQUIRE_THROWS_WITH(readDenseMesh(file("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n")), Contains("no faces"));
    REQUIRE_THROWS_WITH(readDenseMesh(file("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")), Contains("nan.obj"));
    REQUIRE_THROWS_WITH(readDenseMesh(file("nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n")),
                        Contains("vertex 2") || Contains("cannot parse"));
    REQUIRE_THROWS_WITH(readDenseMesh(file("huge.off", "OFF\n3 1 0\n0 0 0\n1e30 0 0\n0 1 0\n3 0 1 2\n")), Contains("beyond the limit"));
    REQUIRE_THROWS_WITH(readDenseMesh(file("index.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")),
                        Contains("out of range"));
    REQUIRE_THROWS_WITH(readDenseMesh(file("flat.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n3 0 0 1\n")),
                        Contains("degenerate"));
    REQUIRE_THROWS_WITH(readDenseMesh(file("garbage.ply", "ply\nthis is not a header\n")), Contains("garbage.ply"));
    REQUIRE_THROWS_WITH(readDenseMesh(file("cloud.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                                        "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n")),
                        Contains("no faces"));
    REQUIRE_THROWS_WITH(readDenseMesh(file("mesh.stl", "solid x\nendsolid x\n")), Contains("unknown dense mesh format"));
    REQUIRE_THROWS_WITH(readDenseMesh(dir.file("missing.obj")), Contains("missing.obj"));
    REQUIRE_THROWS_WITH(readDenseMesh(dir.path.string() + "/"), Contains("format") || Contains("regular file"));
    // A PLY shorter than its header says: assimp would pad it with zeros.
    REQUIRE_THROWS_WITH(readDenseMesh(file("short.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                                        "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                                        "end_header\n0 0 0\n1 0 0\n")),
                        Contains("truncated"));
    REQUIRE_THROWS_WITH(readDenseMesh(file("huge.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\n"
                                                       "property float x\nproperty float y\nproperty float z\nend_header\n")),
                        Contains("more than a file of"));
    {
        const TriangleMesh sphere = uvSphere(12, 6, 1.0);
        writePly(sphere, dir.file("full.ply"));
        std::vector<unsigned char> bytes = dmtest::readBytes(dir.file("full.ply"));
        bytes.resize(bytes.size() - 20);
        dmtest::writeBytes(dir.file("cut.ply"), bytes);
        REQUIRE_THROWS_WITH(readDenseMesh(dir.file("cut.ply")), Contains("truncated"));
    }
    // A triangle soup (every triangle with its own three vertices) is welded back together.
    {
        std::string soup = "OFF\n12 4 0\n";
        const char* tet[4] = {"0 0 0", "1 0 0", "0 1 0", "0 0 1"};
        const int faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
        for (const auto& f : faces)
            for (int c : f) soup += std::string(tet[c]) + "\n";
        for (int f = 0; f < 4; ++f) soup += "3 " + std::to_string(3 * f) + " " + std::to_string(3 * f + 1) + " " + std::to_string(3 * f + 2) + "\n";
        const DenseMesh w = readDenseMesh(file("soup.off", soup));
        CHECK(w.vertexCount() == 4);
        CHECK(w.stats.weldedVertices == 8);
        for (const glm::vec3& n : denseVertexNormals(w)) CHECK(glm::length(n) == Approx(1.0f)); // smooth again
    }
    // One good triangle, one with a repeated vertex, one of zero area, one unused vertex.
    const DenseMesh m = readDenseMesh(
        file("mixed.off", "OFF\n5 3 0\n0 0 0\n1 0 0\n0 1 0\n2 0 0\n9 9 9\n3 0 1 2\n3 0 0 1\n3 0 1 3\n"));
    CHECK(m.triangleCount() == 1);
    CHECK(m.stats.degenerateDropped == 2);
    CHECK(m.stats.unusedVertices == 2);
    CHECK(m.vertexCount() == 3);
}

TEST_CASE("closest point on a triangle matches a brute-force search", "[bake]") {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    for (int trial = 0; trial < 200; ++trial) {
        const glm::dvec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng)), p(u(rng), u(rng), u(rng));
        const glm::dvec3 q = closestPointOnTriangle(p, a, b, c);
        double best = 1e300;
        const int n = 300;
        for (int i = 0; i <= n; ++i)
            for (int j = 0; i + j <= n; ++j) {
                const double s = double(i) / n, t = double(j) / n;
                best = std::min(best, glm::length(a + s * (b - a) + t * (c - a) - p));
            }
        CAPTURE(trial);
        // The grid's spacing is at most 4 sqrt(3) / 300 ~ 0.023: the search can only be that much worse.
        REQUIRE(glm::length(q - p) <= best + 1e-12);
        REQUIRE(glm::length(q - p) >= best - 0.025);
        // q lies in the triangle's plane
        const glm::dvec3 nrm = glm::normalize(glm::cross(b - a, c - a));
        REQUIRE(std::abs(glm::dot(q - a, nrm)) < 1e-9);
    }
}

TEST_CASE("ray scene: hits and closest points on a sphere", "[bake]") {
    const DenseMesh s = denseMeshOf(uvSphere(96, 48, 1.0), "sphere");
    const RayScene scene(s.positions, s.triangles);
    std::mt19937 rng(3);
    std::normal_distribution<float> g;
    // chord error of 96 x 48 segments: 1 - cos(pi / 48) ~ 2.1e-3
    for (int i = 0; i < 200; ++i) {
        const glm::vec3 d = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
        const RayScene::Hit h = scene.intersect(glm::vec3(0.0f), d, 0.0f, 10.0f);
        REQUIRE(h.hit);
        CHECK(h.t == Approx(1.0f).margin(2.2e-3f));
        CHECK(glm::dot(h.normal, d) > 0.99f); // seen from inside: the outward normal
        const RayScene::Closest c = scene.closest(1.5f * d);
        REQUIRE(c.found);
        CHECK(c.distance == Approx(0.5f).margin(2.2e-3f));
        CHECK_FALSE(scene.intersect(glm::vec3(0.0f), d, 0.0f, 0.9f).hit);
        CHECK_FALSE(scene.closest(1.5f * d, 0.4f).found);
    }
}

TEST_CASE("fitting stages: the Catmull-Clark step keeps the limit surface, interpolation undoes the shrinkage", "[bake]") {
    const DenseMesh dense = denseMeshOf(uvSphere(64, 32, 1.0), "sphere");
    SimplifyOptions so;
    so.targetFaces = 60;
    const MeshDescription icm = simplifiedControlMesh(dense, so);
    const ControlMesh cm(icm);
    const LimitStencils st = vertexLimitStencils(cm, 4);
    auto limitOf = [&](const MeshDescription& d, const LimitStencils& s, int v) {
        glm::dvec3 p(0.0);
        for (int k = 0; k < s.sizes[static_cast<std::size_t>(v)]; ++k) {
            const std::size_t o = static_cast<std::size_t>(s.offsets[static_cast<std::size_t>(v)] + k);
            p += s.w[o] * d.positions[static_cast<std::size_t>(s.indices[o])];
        }
        return p;
    };
    // Far numbers the refined vertices from the base vertices first (then faces, then edges).
    const MeshDescription ibm = catmullClarkStep(icm);
    const ControlMesh im(ibm);
    const LimitStencils ist = vertexLimitStencils(im, 4);
    const int offset = 0;
    double gapBefore = 0.0, gapAfter = 0.0;
    const MeshDescription pi = progressiveInterpolation(icm, 2);
    const LimitStencils pst = vertexLimitStencils(ControlMesh(pi), 4);
    for (int v = 0; v < static_cast<int>(icm.positions.size()); ++v) {
        const glm::dvec3 a = limitOf(icm, st, v), b = limitOf(ibm, ist, offset + v);
        // the same limit point, up to the end caps of two different levels (Gregory patches
        // at isolation 4 of the ICM and of the IBM, one level deeper)
        REQUIRE(glm::length(a - b) < 1e-4);
        gapBefore = std::max(gapBefore, glm::length(a - icm.positions[static_cast<std::size_t>(v)]));
        gapAfter = std::max(gapAfter, glm::length(limitOf(pi, pst, v) - icm.positions[static_cast<std::size_t>(v)]));
    }
    CAPTURE(gapBefore, gapAfter);
    // Two steps of c += p - L(c) on a convex shape: the gap shrinks by the spectral radius of
    // (I - L) squared, well below a third (measured ~0.05).
    CHECK(gapAfter < gapBefore / 3.0);
}

TEST_CASE("bake recovers a sphere and a torus of known radii", "[bake]") {
    SECTION("sphere") {
        const DenseMesh dense = denseMeshOf(uvSphere(200, 100, 1.0), "sphere");
        const BakeResult r = bakeSimplified(dense, 64, 8);
        const BakeReport& rep = r.report;
        CAPTURE(rep.rmsDenseToResult, rep.maxDenseToResult, rep.rmsResultToDense, rep.maxResultToDense, rep.tiles.maxResidual,
                rep.tiles.maxResidualAwayFromConstraints);
        CHECK(rep.extract.misses == 0);
        CHECK(rep.extract.foldovers == 0);
        CHECK(rep.baseFaces == 3 * rep.icmFaces);
        // The result must lie on the sphere to the chord error of the dense mesh (1 - cos(pi/100)
        // = 4.9e-4 of the radius), the tiles' interpolation between samples (D varies smoothly;
        // ~2e-4), and the one place the tiles do not interpolate the rays' samples: the 2 x 2
        // corner blocks at extraordinary vertices, which the format holds flat (Doo-Sabin
        // constraint, D_u = D_v = 0). Away from those the fit interpolates exactly.
        double worst = 0.0;
        for (const glm::dvec3& p : r.result.positions) worst = std::max(worst, std::abs(glm::length(p) - 1.0));
        CHECK(rep.tiles.maxResidualAwayFromConstraints < 1e-9);
        CHECK(worst < rep.tiles.maxResidual + 1e-3);
        CHECK(worst < 5e-3); // measured 3.1e-3
        CHECK(rep.rmsResultToDense < 0.02);
        CHECK(rep.rmsDenseToResult < 0.02);
        // The fitting brought the base surface itself close: its error is in the report.
        REQUIRE(rep.fit.iterations.size() >= 2);
        CHECK(rep.fit.result().rmsPercent < rep.fit.iterations.front().rmsPercent);
    }
    SECTION("torus") {
        const double R = 1.0, rr = 0.3;
        const DenseMesh dense = denseMeshOf(torusMesh(240, 80, R, rr), "torus");
        const BakeResult r = bakeSimplified(dense, 200, 8);
        double worst = 0.0;
        for (const glm::dvec3& p : r.result.positions)
            worst = std::max(worst, std::abs(glm::length(glm::dvec2(glm::length(glm::dvec2(p.x, p.y)) - R, p.z)) - rr));
        CAPTURE(worst, r.report.rmsDenseToResult, r.report.rmsResultToDense, r.report.tiles.maxResidual, r.report.extract.misses);
        // chord error of the tube, 0.3 (1 - cos(pi/80)) = 2.3e-4, the interpolation, and the
        // corner blocks at extraordinary vertices, as for the sphere
        CHECK(r.report.tiles.maxResidualAwayFromConstraints < 1e-9);
        CHECK(worst < r.report.tiles.maxResidual + 1e-3);
        CHECK(worst < 8e-3); // measured 5.0e-3
        // A ray may pass through the dense mesh's edges where Embree's watertight test still
        // misses; such a sample is filled (measured: 1 of 38400).
        CHECK(r.report.extract.misses <= r.report.extract.samples / 1000);
        CHECK(r.report.rmsDenseToResult < 0.03);
    }
}

TEST_CASE("bake recovers a displaced surface of our own, on its own cage and on a decimated one", "[bake]") {
    const OwnSurface own;
    const DenseMesh dense = denseMeshOf(own.dense(), "own");
    const RayScene scene(dense.positions, dense.triangles);
    SECTION("its own cage: no interpolation, no fitting, the same limit surface") {
        BakeOptions o;
        o.density = 16;
        o.fit.interpolationSteps = 0;
        o.fit.maxIterations = 0;
        const BakeResult r = bakeFromControlMesh(dense, scene, own.mesh.description(), o);
        const BakeReport& rep = r.report;
        CAPTURE(rep.rmsDenseToResult, rep.maxDenseToResult, rep.rmsResultToDense, rep.maxResultToDense);
        // The base surface is the original's, so the rays find D up to the dense mesh's chord
        // error (factor 48 against the waves' 9 cycles per face); the result is the tile fit of
        // those samples. Measured: RMS ~0.01 %, max ~0.1 % of the diagonal.
        CHECK(rep.extract.misses == 0);
        CHECK(rep.rmsDenseToResult < 0.03);
        CHECK(rep.rmsResultToDense < 0.03);
        CHECK(rep.maxResultToDense < 0.3);
        // D itself: the baked D against the original's at the same base point. The base mesh
        // is the cage after one Catmull-Clark step; Far numbers the children face by face, and
        // child c of a quad covers the quadrant at corner c in the parent's own orientation,
        // child k of an N-gon is the Ptex sub-face k with the same parameters.
        const ControlMesh base(r.base);
        const BaseSurface bs(base);
        const DisplacedSurface ds(bs, r.tiles);
        double worstD = 0.0, worstS = 0.0;
        const Far::TopologyLevel& L0 = own.mesh.base();
        int child = 0;
        for (int f = 0; f < L0.GetNumFaces(); ++f) {
            const int n = L0.GetFaceVertices(f).size();
            for (int c = 0; c < n; ++c, ++child)
                for (double a : {0.1, 0.3, 0.55, 0.8})
                    for (double b : {0.15, 0.45, 0.7, 0.95}) {
                        static constexpr double cu[4] = {0, 1, 1, 0}, cv[4] = {0, 0, 1, 1};
                        const int pf = own.mesh.ptex().GetFaceId(f) + (n == 4 ? 0 : c);
                        const double pu = n == 4 ? 0.5 * (cu[c] + a) : a, pv = n == 4 ? 0.5 * (cv[c] + b) : b;
                        const glm::dvec3 so = own.base.evaluate<double>(pf, pu, pv, false).p;
                        const glm::dvec3 sb = bs.evaluate<double>(child, a, b, false).p;
                        worstS = std::max(worstS, glm::length(so - sb));
                        worstD = std::max(worstD, std::abs(own.surface.displacement<double>(pf, pu, pv).x -
                                                           ds.displacement<double>(child, a, b).x));
                    }
        }
        CAPTURE(worstS, worstD);
        // The same base point (the child parameterisation is right); the end caps around the
        // extraordinary vertices are another level's approximation, ~1e-6 of the size apart.
        REQUIRE(worstS < 1e-4);
        // D to the dense mesh's chord error: the waves' curvature at factor 48 (measured ~1e-3
        // of the 0.07 amplitude... see the report) -- 5 % of the amplitude is a wrong sample.
        CHECK(worstD < 3.5e-3);
    }
    SECTION("a decimated cage") {
        const BakeResult r = bakeSimplified(dense, 200, 16);
        const BakeReport& rep = r.report;
        CAPTURE(rep.rmsDenseToResult, rep.maxDenseToResult, rep.rmsResultToDense, rep.maxResultToDense, rep.extract.foldovers);
        // A base surface of its own: the displacement now carries the cube's shape as well as
        // the waves. Measured RMS ~0.05 %; the folds at the cube's corners stay below 1 %.
        CHECK(rep.rmsDenseToResult < 0.15);
        CHECK(rep.rmsResultToDense < 0.15);
    }
}

TEST_CASE("bake: holes, a disconnected piece, non-manifold edges, rays that miss", "[bake]") {
    // A sphere with its north cap cut away, a small separate sphere, and a fin of three
    // triangles on one edge of the big one.
    TriangleMesh t = uvSphere(96, 48, 1.0);
    std::vector<glm::ivec3> kept;
    for (const glm::ivec3& tri : t.triangles) {
        bool cap = true;
        for (int c = 0; c < 3; ++c) cap = cap && t.positions[static_cast<std::size_t>(tri[c])].z > 0.9;
        if (!cap) kept.push_back(tri);
    }
    t.triangles.assign(kept.begin(), kept.end());
    const TriangleMesh small = uvSphere(24, 12, 0.1, glm::dvec3(2.0, 0.0, 0.0));
    const int base = t.vertexCount();
    for (const glm::dvec3& p : small.positions) t.positions.push_back(p);
    for (const glm::ivec3& tri : small.triangles) t.triangles.push_back(tri + base);
    const int a = t.triangles[500].x, b = t.triangles[500].y;
    for (int k = 0; k < 2; ++k) {
        t.positions.push_back(t.positions[static_cast<std::size_t>(a)] * (1.1 + 0.1 * k));
        t.triangles.emplace_back(a, b, t.vertexCount() - 1);
    }
    t.normals = t.positions;
    const DenseMesh dense = denseMeshOf(t, "holey");
    const RayScene scene(dense.positions, dense.triangles);
    SimplifyOptions so;
    so.targetFaces = 150;
    SimplifyReport sr;
    const MeshDescription icm = simplifiedControlMesh(dense, so, &sr);
    CHECK(sr.faces > 0);
    BakeOptions o;
    o.density = 8;
    const BakeResult r = bakeFromControlMesh(dense, scene, icm, o);
    const BakeReport& rep = r.report;
    CAPTURE(rep.extract.misses, rep.extract.foldovers, rep.rmsDenseToResult, rep.rmsResultToDense, sr.droppedNonManifold);
    // every sample of every tile was cast and classified once: 8 x 8 per base face (no holes)
    CHECK(rep.extract.samples == static_cast<long>(rep.baseFaces) * 64);
    CHECK(rep.extract.hits + rep.extract.misses + rep.extract.foldovers == rep.extract.samples);
    for (const Tile& tile : r.tiles.tiles)
        for (float x : tile.coefficients) REQUIRE(std::isfinite(x));
    // Most of the surface is an ordinary sphere: its error stays small.
    CHECK(rep.rmsResultToDense < 0.5);

    SECTION("a shell too thin for any ray: every sample is a miss, filled by the closest point") {
        BakeOptions thin = o;
        thin.extract.shell = 1e-9;
        const BakeResult m = bakeFromControlMesh(dense, scene, icm, thin);
        CHECK(m.report.extract.misses > m.report.extract.samples * 9 / 10);
        // The closest-point height along N, clamped to the shell: D ~ 0, the base surface.
        CHECK(m.report.extract.maxAbs <= 1e-9 * dense.diagonal() * 1.0001);
    }
    SECTION("options out of range") {
        BakeOptions bad = o;
        bad.density = 6;
        REQUIRE_THROWS_WITH(bakeFromControlMesh(dense, scene, icm, bad), Catch::Contains("power of two"));
        bad = o;
        bad.extract.shell = 0.0;
        REQUIRE_THROWS_WITH(bakeFromControlMesh(dense, scene, icm, bad), Catch::Contains("shell"));
        bad = o;
        bad.fit.samplesPerEdge = 0;
        REQUIRE_THROWS_WITH(checkBakeOptions(bad), Catch::Contains("samples per edge"));
        bad = o;
        bad.adaptiveTolerance = std::nan("");
        REQUIRE_THROWS_WITH(checkBakeOptions(bad), Catch::Contains("adaptive tolerance"));
        SimplifyOptions few;
        few.targetFaces = 2;
        REQUIRE_THROWS_WITH(simplifiedControlMesh(dense, few), Catch::Contains("at least 4"));
    }
}

TEST_CASE("bake: tile sizes from the data save memory where the scan is smooth", "[bake]") {
    // A sphere with wrinkles on its northern half only.
    TriangleMesh t = uvSphere(320, 160, 1.0);
    for (glm::dvec3& p : t.positions) {
        const double th = std::acos(std::clamp(p.z, -1.0, 1.0)), ph = std::atan2(p.y, p.x);
        if (p.z > 0.1) p *= 1.0 + 0.01 * std::sin(24 * th) * std::sin(24 * ph) * std::min(1.0, (p.z - 0.1) * 10.0);
    }
    const DenseMesh dense = denseMeshOf(t, "wrinkled");
    const RayScene scene(dense.positions, dense.triangles);
    SimplifyOptions so;
    so.targetFaces = 80;
    const MeshDescription icm = simplifiedControlMesh(dense, so);
    BakeOptions o;
    o.density = 16;
    const BakeResult uniform = bakeFromControlMesh(dense, scene, icm, o);
    // of the diagonal (3.46): 1.4e-3, a seventh of the wrinkles' amplitude and above the dense
    // sphere's facets (chord error 1.9e-4) and the base surface's remaining mismatch
    o.adaptiveTolerance = 4e-4;
    const BakeResult adaptive = bakeFromControlMesh(dense, scene, icm, o);
    CAPTURE(uniform.report.tileTexels, adaptive.report.tileTexels, uniform.report.rmsDenseToResult, adaptive.report.rmsDenseToResult,
            uniform.report.maxDenseToResult, adaptive.report.maxDenseToResult);
    // Half the sphere is smooth: its tiles shrink, the wrinkled half keeps 16 x 16.
    CHECK(adaptive.report.tileTexels < 0.75 * uniform.report.tileTexels);
    int smallNorth = 0, smallSouth = 0, north = 0, south = 0;
    const ControlMesh base(adaptive.base);
    const BaseSurface bs(base);
    for (int f = 0; f < base.ptexFaceCount(); ++f) {
        const bool n = bs.evaluate<double>(f, 0.5, 0.5, false).p.z > 0.3;
        const bool small = adaptive.tiles.tiles[static_cast<std::size_t>(f)].k < 4;
        (n ? north : south) += 1;
        (n ? smallNorth : smallSouth) += small ? 1 : 0;
    }
    CAPTURE(north, south, smallNorth, smallSouth);
    CHECK(smallSouth > south * 7 / 10);
    CHECK(smallNorth < north / 10);
    // The error the smaller tiles add is bounded by the tolerance (4e-4 of the diagonal is 0.04 %).
    CHECK(adaptive.report.rmsDenseToResult < uniform.report.rmsDenseToResult + 0.04);
    CHECK(adaptive.report.compressionRatio > uniform.report.compressionRatio);
}

TEST_CASE("simplification cleans what a decimation can leave: pinched vertices, edges of three triangles", "[bake]") {
    // Two tetrahedra touching at vertex 0 (a bow-tie vertex), and a third triangle on edge 1-2.
    std::vector<glm::vec3> p = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3f, 0.3f, 1}, {-1, 0, 0}, {0, -1, 0}, {-0.3f, -0.3f, -1}, {1, 1, 1}};
    std::vector<glm::uvec3> t = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}, {0, 4, 5}, {0, 6, 4}, {4, 6, 5}, {0, 5, 6}, {1, 2, 7}};
    int dropped = 0, split = 0;
    const std::vector<glm::uvec3> kept = detail::manifoldTriangles(t, dropped);
    CHECK(dropped == 1); // the fin on edge 1-2 (a third triangle there)
    const std::vector<glm::uvec3> fixed = detail::splitPinchedVertices(kept, p, split);
    CHECK(split == 1);
    REQUIRE(p.size() == 9);
    CHECK(p[8] == p[0]);
    MeshDescription d;
    d.name = "two tetrahedra";
    for (const glm::vec3& x : p) d.positions.emplace_back(x);
    for (const glm::uvec3& f : fixed) {
        d.faceSizes.push_back(3);
        for (int c = 0; c < 3; ++c) d.faceVertices.push_back(static_cast<int>(f[c]));
    }
    d.positions.erase(d.positions.begin() + 7); // vertex 7 was only on the fin
    for (int& v : d.faceVertices) v -= v > 7 ? 1 : 0;
    CHECK_NOTHROW(ControlMesh(d));
    // and the original, pinched one is refused
    MeshDescription pinched = d;
    for (int& v : pinched.faceVertices) v = v == 7 ? 0 : v;
    pinched.positions.pop_back();
    CHECK_THROWS_WITH(ControlMesh(pinched), Catch::Contains("non-manifold vertex"));
}

TEST_CASE("bake: the skeleton route on a dense mesh facing outward and on one facing inward", "[bake]") {
    // A ring of six joints inside a torus; the same torus with every triangle reversed must bake
    // as well (the base mesh follows the dense mesh's orientation; rays and fit compare normals).
    Skeleton ring;
    ring.name = "ring";
    for (int i = 0; i < 6; ++i) {
        const double a = 6.283185307179586 * i / 6;
        ring.joints.emplace_back(std::cos(a), std::sin(a), 0.0);
        ring.segments.push_back({i, (i + 1) % 6});
    }
    for (const bool inward : {false, true}) {
        CAPTURE(inward);
        TriangleMesh t = torusMesh(160, 48, 1.0, 0.35);
        if (inward)
            for (glm::ivec3& tri : t.triangles) std::swap(tri.y, tri.z);
        const DenseMesh dense = denseMeshOf(t, inward ? "inward torus" : "torus");
        const RayScene scene(dense.positions, dense.triangles);
        BakeOptions o;
        o.density = 8;
        const BakeResult r = bakeFromControlMesh(dense, scene, skeletonControlMesh(dense, scene, ring), o);
        const BakeReport& rep = r.report;
        CAPTURE(rep.extract.hits, rep.extract.foldovers, rep.extract.misses, rep.rmsDenseToResult, rep.rmsResultToDense);
        CHECK(rep.extract.foldovers == 0);
        CHECK(rep.extract.misses <= rep.extract.samples / 1000); // as the torus above
        // chord error and the corner blocks at extraordinary vertices, as for the simplified torus
        CHECK(rep.rmsDenseToResult < 0.05);
        CHECK(rep.rmsResultToDense < 0.05);
    }
}

TEST_CASE("bake: the same result whatever the thread count", "[bake]") {
    const DenseMesh dense = denseMeshOf(torusMesh(120, 40, 1.0, 0.35), "torus");
    BakeResult one, all;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        one = bakeSimplified(dense, 100, 8);
    }
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 4);
        all = bakeSimplified(dense, 100, 8);
    }
    REQUIRE(one.base.positions == all.base.positions);
    REQUIRE(one.tiles.tiles.size() == all.tiles.tiles.size());
    for (std::size_t i = 0; i < one.tiles.tiles.size(); ++i) REQUIRE(one.tiles.tiles[i].coefficients == all.tiles.tiles[i].coefficients);
    CHECK(one.report.rmsResultToDense == all.report.rmsResultToDense);
}

TEST_CASE("a control mesh written as OBJ reads back with the same positions and topology", "[bake]") {
    MeshDescription d = dmtest::shape("catmark_cube_creases0").description();
    d.holes = {2};
    d.boundary = Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER;
    d.positions[3] += glm::dvec3(0.1 / 3.0, 1e-17, -2.0 / 7.0);
    dmtest::TempDir dir("dispmap_bake_obj_");
    writeObj(d, dir.file("c.obj"));
    const ControlMesh back = ControlMesh::fromObjFile(dir.file("c.obj"));
    const MeshDescription& e = back.description();
    CHECK(e.positions == d.positions);
    CHECK(e.faceVertices == d.faceVertices);
    CHECK(e.creaseVertexPairs == d.creaseVertexPairs);
    CHECK(e.creaseWeights == d.creaseWeights);
    CHECK(e.holes == d.holes);
    CHECK(e.boundary == d.boundary);
    CHECK(topologyHash(back) == topologyHash(ControlMesh(d)));
}

} // namespace dmtest_bake
