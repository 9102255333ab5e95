// All cores, the same results: every parallel entry point (tile build and refit, the
// auto-normal analysis, tessellation, the mesostructure maps) gives bit-identical output for
// 1, 2 and 3 threads, on meshes with extraordinary vertices, N-gons (T-junctions), creases and
// mixed tile sizes; the thread count is checked; the auto-normal analysis runs only when auto
// normals are asked for; and the comparison-only cone test of the DDM builders never rejects a
// box that the atan2 form accepts.
#include <catch2/catch.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "dispmap/meso/ddm.h"
#include "dispmap/meso/distance_map.h"
#include "dispmap/meso/solid.h"
#include "dispmap/surface/tessellator.h"
#include "test_meso_support.h"
#include "test_support.h"

namespace dmtest_parallel {

using namespace dispmap;

namespace {

// Bit for bit: equal doubles and floats may still differ in sign of zero or NaN payload.
template <class T, class A, class B> bool sameBits(const std::vector<T, A>& a, const std::vector<T, B>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

bool sameTiles(const TileSet& a, const TileSet& b) {
    if (a.tileCount() != b.tileCount()) return false;
    for (int t = 0; t < a.tileCount(); ++t) {
        const Tile& x = a.tiles[static_cast<std::size_t>(t)];
        const Tile& y = b.tiles[static_cast<std::size_t>(t)];
        if (x.k != y.k || x.sizeDifferences != y.sizeDifferences || !sameBits(x.coefficients, y.coefficients)) return false;
    }
    return true;
}

// A test shape with rough tiles of 2^k a side and its displaced surface.
struct RoughSurface {
    ControlMesh mesh;
    BaseSurface base;
    TileSet tiles;
    DisplacedSurface surface;
    RoughSurface(const char* name, int k)
        : mesh(dmtest::shape(name)), base(mesh), tiles(buildTiles(mesh, uniformTileSizes(mesh, k), dmtest::roughSource)), surface(base, tiles) {}
};

bool sameMesh(const TriangleMesh& a, const TriangleMesh& b) {
    return sameBits(a.positions, b.positions) && sameBits(a.normals, b.normals) && a.faces == b.faces && sameBits(a.uvs, b.uvs) &&
           sameBits(a.resolutions, b.resolutions) && a.triangles == b.triangles && a.triangleFaces == b.triangleFaces &&
           sameBits(a.triangleUVs, b.triangleUVs);
}

// The pre-2026-12 cone test (atan2 of the box's corners), kept here as the reference the
// comparison-only test must contain: it may accept more, never less.
bool boxMeetsConeAtan2(const detail::Box& D, const double az[2], const double el[2]) {
    constexpr double pi = 3.14159265358979323846, slack = 1e-6;
    const double cx = std::clamp(0.0, D.lo.x, D.hi.x), cy = std::clamp(0.0, D.lo.y, D.hi.y);
    const double rhoMin = std::sqrt(cx * cx + cy * cy);
    const double mx = std::max(std::abs(D.lo.x), std::abs(D.hi.x)), my = std::max(std::abs(D.lo.y), std::abs(D.hi.y));
    const double rhoMax = std::sqrt(mx * mx + my * my);
    const double elMax = D.hi.z >= 0 ? std::atan2(D.hi.z, rhoMin) : std::atan2(D.hi.z, rhoMax);
    const double elMin = D.lo.z <= 0 ? std::atan2(D.lo.z, rhoMin) : std::atan2(D.lo.z, rhoMax);
    if (elMax < el[0] - slack || elMin > el[1] + slack) return false;
    if (rhoMin == 0 || az[1] - az[0] >= 2 * pi - slack) return true;
    auto wrap = [&](double a) {
        while (a <= -pi) a += 2 * pi;
        while (a > pi) a -= 2 * pi;
        return a;
    };
    const double centre = std::atan2(0.5 * (D.lo.y + D.hi.y), 0.5 * (D.lo.x + D.hi.x));
    double lo = 0, hi = 0;
    for (double x : {D.lo.x, D.hi.x})
        for (double y : {D.lo.y, D.hi.y}) {
            const double delta = wrap(std::atan2(y, x) - centre);
            lo = std::min(lo, delta);
            hi = std::max(hi, delta);
        }
    for (double shift : {-2 * pi, 0.0, 2 * pi})
        if (centre + lo + shift <= az[1] + slack && centre + hi + shift >= az[0] - slack) return true;
    return false;
}

} // namespace

TEST_CASE("parallel: thread counts are checked, every index runs once, 1 thread stays in the caller", "[parallel]") {
    CHECK_THROWS_WITH(Parallel(-1, "tile build"), Catch::Contains("tile build: thread count -1 out of range"));
    CHECK_THROWS_AS(Parallel(kMaxThreads + 1), ArgumentError);
    for (int threads : {0, 1, 2, 3}) {
        const Parallel par(threads);
        std::vector<std::atomic<int>> hits(10007);
        par.each(hits.size(), 7, [&](std::size_t i) { hits[i].fetch_add(1); });
        for (const std::atomic<int>& h : hits) REQUIRE(h.load() == 1);
    }
    int calls = 0;
    Parallel(1).ranges(1000, 1, [&](std::size_t b, std::size_t e) {
        ++calls; // not atomic: one thread only
        CHECK(b == 0);
        CHECK(e == 1000);
    });
    CHECK(calls == 1);
    CHECK_THROWS_AS(Parallel(2).each(100, 1, [](std::size_t i) {
        if (i == 57) throw ArgumentError("from a task");
    }), ArgumentError);
}

TEST_CASE("parallel: tile builds and refits are bit-identical for 1, 2 and 3 threads", "[parallel][tiles]") {
    // Extraordinary vertices and boundaries (Spot), N-gons with T-junctions and mixed sizes
    // (catmark_nonquads at k = 3 with every fourth quad larger is refused at T-junctions, so
    // the mixed sizes come from the pinned-quad rule), creases (the bishop). Mixed sizes sweep
    // in Jacobi order; uniform sizes of 8 x 8 and more (k = 4, sub-faces 3) in Gauss-Seidel
    // order over coloured tiles, each colour's tiles in parallel.
    for (const char* name : {"spot_control_mesh", "catmark_nonquads", "catmark_bishop"})
    for (const bool seidel : {false, true}) {
        INFO(name << (seidel ? ", uniform k = 4 (Gauss-Seidel)" : ", mixed sizes (Jacobi)"));
        const ControlMesh mesh = name == std::string("spot_control_mesh") ? ControlMesh::fromObjFile(dmtest::dataPath("spot_control_mesh.obj"))
                                                                          : dmtest::shape(name);
        std::vector<int> k = uniformTileSizes(mesh, seidel ? 4 : 3);
        const std::vector<char> pinned = quadsPinnedByNonQuads(mesh);
        bool mixed = false;
        for (int f = 0, t = 0; f < mesh.base().GetNumFaces() && !seidel; ++f) {
            const int n = mesh.base().GetFaceVertices(f).size();
            if (n == 4 && !pinned[static_cast<std::size_t>(f)] && f % 3 == 0) {
                k[static_cast<std::size_t>(t)] = 4;
                mixed = true;
            }
            t += n == 4 ? 1 : n;
        }
        if (name != std::string("catmark_nonquads") && !seidel) CHECK(mixed); // there every quad touches an N-gon
        BuildOptions one;
        one.threads = 1;
        one.filter = MipFilter::BWavelet;
        TileFitter serial(mesh, k, dmtest::roughSource, one);
        // A converged fit (test_tiles.cpp: the fit converges on boundaries, mesh corners, ...).
        REQUIRE(serial.report().maxResidualAwayFromConstraints < 1e-11);
        for (int threads : {2, 3}) {
            BuildOptions o = one;
            o.threads = threads;
            TileFitter par(mesh, k, dmtest::roughSource, o);
            CHECK(sameTiles(serial.tiles(), par.tiles()));
            CHECK(serial.report().sweeps == par.report().sweeps);
            CHECK(serial.report().maxResidual == par.report().maxResidual);
            // An edit of two faces: the same changed tiles, the same coefficients.
            const DisplacementFunction edited = [](int f, double u, double v) { return dmtest::roughSource(f, u, v) + (f == 1 ? 0.2 * u * v : 0.0); };
            TileFitter a(mesh, k, dmtest::roughSource, one);
            const std::vector<int> ca = a.refit({1, 2}, edited);
            const std::vector<int> cb = par.refit({1, 2}, edited);
            CHECK(ca == cb);
            CHECK(sameTiles(a.tiles(), par.tiles()));
        }
    }
}

TEST_CASE("parallel: the first non-finite sample is reported whatever the thread count", "[parallel][tiles]") {
    const ControlMesh mesh = dmtest::shape("catmark_cube");
    const DisplacementFunction bad = [](int f, double u, double) { return f >= 3 && u > 0.5 ? std::nan("") : 0.0; };
    for (int threads : {1, 2}) {
        BuildOptions o;
        o.threads = threads;
        CHECK_THROWS_WITH(buildTiles(mesh, uniformTileSizes(mesh, 2), bad, o), Catch::Contains("at Ptex face 3, (u, v) = (0.625"));
    }
    BuildOptions o;
    o.threads = -2;
    CHECK_THROWS_WITH(buildTiles(mesh, uniformTileSizes(mesh, 2), dmtest::roughSource, o), Catch::Contains("thread count -2"));
}

TEST_CASE("parallel: auto normals are analysed only when asked for, the same on every count", "[parallel][normals]") {
    const ControlMesh mesh = dmtest::shape("catmark_pole8");
    const BaseSurface base(mesh);
    // Displacement small enough that the bounds stay below their clamp at 1.
    const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 4), [](int f, double u, double v) { return 0.02 * dmtest::roughSource(f, u, v); });
    DisplacedSurfaceOptions o;
    o.threads = 1;
    // A tolerance between the faces' bounds, so that both outcomes occur.
    std::vector<double> bounds;
    const DisplacedSurface probe(base, tiles, o);
    for (int f = 0; f < base.faceCount(); ++f) bounds.push_back(probe.autoBound(f));
    std::sort(bounds.begin(), bounds.end());
    o.autoTolerance = std::asin(bounds[bounds.size() / 2]);
    const DisplacedSurface a(base, tiles, o);
    CHECK_FALSE(a.autoAnalysed());
    (void)a.evaluate<double>(0, 0.3, 0.4, NormalMode::Accurate);
    (void)a.evaluate<double>(0, 0.3, 0.4, NormalMode::Approximate);
    CHECK_FALSE(a.autoAnalysed()); // the other modes never need it
    (void)a.evaluate<double>(0, 0.3, 0.4, NormalMode::Auto);
    CHECK(a.autoAnalysed());
    o.threads = 3;
    const DisplacedSurface b(base, tiles, o);
    REQUIRE(a.autoAccurateCount() > 0); // the case has faces on both sides of the tolerance
    REQUIRE(a.autoAccurateCount() < base.faceCount());
    CHECK(a.autoFaces() == b.autoFaces());
    for (int f = 0; f < base.faceCount(); ++f) CHECK(a.autoBound(f) == b.autoBound(f));
    o.threads = -1;
    CHECK_THROWS_WITH(DisplacedSurface(base, tiles, o), Catch::Contains("thread count -1"));
}

TEST_CASE("parallel: evaluateBatch is evaluate() point for point, face by face, on any count", "[parallel][normals]") {
    const RoughSurface rough("catmark_hole_test1", 3);
    const BaseSurface& base = rough.base;
    const DisplacedSurface& surface = rough.surface;
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> uv(0, 1);
    std::vector<SurfacePoint<double>> points;
    int hole = -1;
    for (int i = 0; i < 3000; ++i) {
        const int f = static_cast<int>(rng() % static_cast<unsigned>(base.faceCount()));
        if (base.isHole(f)) {
            hole = f;
            continue;
        }
        points.push_back({f, uv(rng), uv(rng)});
    }
    REQUIRE(hole >= 0); // the mesh has holes: they are refused below
    for (NormalMode mode : {NormalMode::Approximate, NormalMode::Auto})
        for (int threads : {1, 3}) {
            std::vector<SurfaceSample<double>> out;
            surface.evaluateBatch(points, mode, out, threads, 3.5);
            REQUIRE(out.size() == points.size());
            bool same = true;
            for (std::size_t i = 0; i < points.size(); ++i) {
                const SurfaceSample<double> e = surface.evaluate<double>(points[i].face, points[i].u, points[i].v, mode, 3.5);
                same = same && std::memcmp(&e.position, &out[i].position, sizeof e.position) == 0 &&
                       std::memcmp(&e.normal, &out[i].normal, sizeof e.normal) == 0 && e.accurate == out[i].accurate;
            }
            CHECK(same);
        }
    std::vector<SurfaceSample<double>> out(2);
    std::vector<SurfacePoint<double>> bad = {points[0], {points[1].face, 1.5, 0.5}, {hole, 0.5, 0.5}};
    CHECK_THROWS_WITH(surface.evaluateBatch(bad, NormalMode::Approximate, out), Catch::Contains("(1.500000, 0.500000)"));
    CHECK(out.size() == 2); // nothing written
    bad.erase(bad.begin() + 1);
    CHECK_THROWS_WITH(surface.evaluateBatch(bad, NormalMode::Approximate, out), Catch::Contains("is a hole"));
    CHECK_THROWS_WITH(surface.evaluateBatch(points, NormalMode::Approximate, out, -4), Catch::Contains("thread count -4"));
}

TEST_CASE("parallel: tessellations are bit-identical for 1, 2 and 3 threads", "[parallel][tessellate]") {
    for (const char* name : {"catmark_nonquads", "catmark_bishop", "catmark_dart_edgecorner"}) {
        INFO(name);
        const RoughSurface rough(name, 4);
        const BaseSurface& base = rough.base;
        const DisplacedSurface& surface = rough.surface;
        TessellateOptions o;
        o.normals = NormalMode::Auto;
        o.mips = MipSelection::TessFactor;
        o.threads = 1;
        const TessFactors factors = uniformTessFactors(base, 7.3);
        const TriangleMesh serial = tessellate(surface, factors, o);
        REQUIRE(serial.triangleCount() > 1000);
        for (int threads : {2, 3}) {
            o.threads = threads;
            CHECK(sameMesh(serial, tessellate(surface, factors, o)));
        }
    }
}

TEST_CASE("tessellation into a used mesh: the same mesh bit for bit, in the same memory", "[parallel][tessellate]") {
    const RoughSurface rough("catmark_nonquads", 4);
    const BaseSurface& base = rough.base;
    const DisplacedSurface& surface = rough.surface;
    TessellateOptions o;
    o.mips = MipSelection::TexelRatio;
    const Tessellator small(surface, uniformTessFactors(base, 5.7), o), large(surface, uniformTessFactors(base, 23.0), o);
    const TriangleMesh fresh = small.tessellate();
    REQUIRE(fresh.triangleCount() > 1000);
    TriangleMesh used = large.tessellate();
    REQUIRE(used.triangleCount() > 4 * fresh.triangleCount());
    CHECK(sameMesh(used, large.tessellate())); // a fresh one again: deterministic
    const glm::dvec3* positions = used.positions.data();
    const int* faces = used.faces.data();
    const std::array<glm::dvec2, 3>* corners = used.triangleUVs.data();
    const std::size_t largeVertices = used.positions.size(), largeTriangles = used.triangleUVs.size();
    small.tessellate(used); // shrinks: every array stays where it was, with its capacity
    CHECK(sameMesh(fresh, used));
    CHECK(used.positions.data() == positions);
    CHECK(used.faces.data() == faces);
    CHECK(used.triangleUVs.data() == corners);
    CHECK(used.positions.capacity() >= largeVertices);
    CHECK(used.triangleUVs.capacity() >= largeTriangles);
    large.tessellate(used); // and grows back within its capacity
    CHECK(sameMesh(large.tessellate(), used));
    CHECK(used.positions.data() == positions);
    TriangleMesh grown = small.tessellate(); // grows past its capacity
    large.tessellate(grown);
    CHECK(sameMesh(used, grown));
    // Every element is written: a MeshArray's resize() leaves new elements as the memory held
    // them (core/triangle_mesh.h), so arrays emptied over poison (NaN, -1) show any element a
    // tessellation leaves unwritten: at the counts above, and on a mesh with holes, N-gons and
    // T-junctions at factors that vary from vertex to vertex, with Integer spacing and factor
    // 1 (tiles of two triangles, no grid).
    const auto poisonedIsFresh = [](const Tessellator& t) {
        const TriangleMesh made = t.tessellate();
        const double nan = std::numeric_limits<double>::quiet_NaN();
        TriangleMesh poisoned;
        auto poison = [](auto& v, std::size_t n, const auto& value) {
            v.assign(n, value);
            v.clear();
        };
        const std::size_t nv = made.positions.size() + 7, nt = made.triangles.size() + 7;
        poison(poisoned.positions, nv, glm::dvec3(nan));
        poison(poisoned.normals, nv, glm::dvec3(nan));
        poison(poisoned.faces, nv, -1);
        poison(poisoned.uvs, nv, glm::dvec2(nan));
        poison(poisoned.resolutions, nv, nan);
        poison(poisoned.triangles, nt, glm::ivec3(-1));
        poison(poisoned.triangleFaces, nt, -1);
        poison(poisoned.triangleUVs, nt, std::array<glm::dvec2, 3>{glm::dvec2(nan), glm::dvec2(nan), glm::dvec2(nan)});
        const glm::dvec3* held = poisoned.positions.data();
        t.tessellate(poisoned);
        return poisoned.positions.data() == held && sameMesh(made, poisoned); // the poisoned memory was the one used
    };
    CHECK(poisonedIsFresh(large));
    CHECK(poisonedIsFresh(small));
    {
        const RoughSurface holes("catmark_hole_test1", 3);
        const BaseSurface& holeBase = holes.base;
        const DisplacedSurface& holeSurface = holes.surface;
        std::mt19937 g(9);
        std::uniform_real_distribution<double> f(1.0, 9.0);
        TessFactors varied = uniformTessFactors(holeBase, 1.0);
        for (double& v : varied.values) v = f(g);
        for (const Spacing spacing : {Spacing::Integer, Spacing::FractionalEven}) {
            TessellateOptions p = o;
            p.spacing = spacing;
            INFO("spacing " << static_cast<int>(spacing));
            CHECK(poisonedIsFresh(Tessellator(holeSurface, varied, p)));
            CHECK(poisonedIsFresh(Tessellator(holeSurface, uniformTessFactors(holeBase, 1.0), p)));
        }
        TessFactors nonquads = uniformTessFactors(base, 1.0); // N-gons, T-junctions
        for (double& v : nonquads.values) v = f(g);
        CHECK(poisonedIsFresh(Tessellator(surface, nonquads, o)));
    }
    // And the allocator does not zero: a MeshArray of bytes emptied over a pattern and grown
    // again within its capacity still holds the pattern (std::vector's resize would write 0).
    MeshArray<unsigned char> bytes;
    bytes.assign(4096, static_cast<unsigned char>(0xA5));
    bytes.clear();
    bytes.resize(4096);
    CHECK(std::count(bytes.begin(), bytes.end(), static_cast<unsigned char>(0xA5)) == 4096);
    // The huge-page hint changes where the memory comes from, never the mesh.
    TessellateOptions plain = o;
    plain.hugePages = false;
    CHECK(sameMesh(used, Tessellator(surface, uniformTessFactors(base, 23.0), plain).tessellate()));
    // Refused (over the memory limit) or not, a mesh handed in is emptied, never half-written.
    o.maxBytes = 1 << 20;
    const Tessellator refused(surface, uniformTessFactors(base, 23.0), o);
    CHECK_THROWS_WITH(refused.tessellate(used), Catch::Contains("more than the limit of 1 MiB"));
    CHECK(used.positions.empty());
    CHECK(used.faces.empty());
    CHECK(used.triangles.empty());
    CHECK(used.triangleUVs.empty());
}

TEST_CASE("parallel: mesostructure maps are bit-identical for 1, 2 and 3 threads", "[parallel][meso]") {
    const MesoHeightField hf = dmtest::hardField(16, 12, 8);
    const ConeSet cones{4, 2, true, false};
    const DirectionalDistanceMap d1 = buildDdm(hf, cones, 2, 0, 1);
    const DistanceMap m1 = buildDistanceMap(hf, 4, 1);
    for (int threads : {2, 3}) {
        CHECK(sameBits(d1.d, buildDdm(hf, cones, 2, 0, threads).d));
        CHECK(sameBits(m1.d, buildDistanceMap(hf, 4, threads).d));
    }
    std::vector<glm::dvec3> v;
    std::vector<std::array<int, 3>> t;
    appendUvSphere({4, 4, 3}, 2.5, 12, v, t);
    const MesoSolid solid = mesoSolidFromMesh(v, t, 8, 8, 8);
    const DirectionalDistanceMap s1 = buildSolidDdm(solid, cones, 0, 1);
    CHECK(sameBits(s1.d, buildSolidDdm(solid, cones, 0, 3).d));
    CHECK_THROWS_WITH(buildDdm(hf, cones, 2, 0, -1), Catch::Contains("thread count -1"));
}

TEST_CASE("parallel: the comparison-only cone test contains the atan2 one", "[parallel][meso]") {
    // Random boxes around the origin at every scale the builders make (sub-voxels to the
    // floor's 1e9 box), against every cone of every supported set: wherever the atan2 form
    // says a box may meet a cone, so must the comparisons (the map stays conservative); they
    // may accept a few more boxes, within the slack, never many.
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> pos(-6, 6), ext(0.01, 3);
    long both = 0, onlyNew = 0, onlyOld = 0;
    for (int m : {1, 2, 4, 8})
        for (int n : {1, 2}) {
            const ConeSet cones{m, n, true, false};
            for (int c = 0; c < cones.count(); ++c) {
                double az[2], el[2];
                cones.range(c, az, el);
                const detail::ConeTest test = detail::coneTest(cones, c);
                for (int i = 0; i < 4000; ++i) {
                    glm::dvec3 lo(pos(rng), pos(rng), pos(rng));
                    // Boxes on the axes and the cone boundaries too: integers put corners there.
                    if (i % 4 == 0) lo = glm::round(lo);
                    const glm::dvec3 hi = lo + (i % 4 == 0 ? glm::round(glm::dvec3(ext(rng), ext(rng), ext(rng))) + 1.0
                                                           : glm::dvec3(ext(rng), ext(rng), ext(rng)));
                    const detail::Box box{lo, hi};
                    const bool old = boxMeetsConeAtan2(box, az, el), now = detail::boxMeetsCone(box, test);
                    both += old && now;
                    onlyOld += old && !now;
                    onlyNew += now && !old;
                }
            }
        }
    CHECK(onlyOld == 0);
    CHECK(both > 10000);
    CHECK(onlyNew <= both / 1000); // boundary cases within 1e-6 rad only
}

} // namespace dmtest_parallel
